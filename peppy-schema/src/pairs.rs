//! What each pairing slot of an instance starts with: the peer a
//! participant is linked with, or the sources an observer watches
//! (docs/PAIRINGS.md). The launcher's plan and a node started on its own
//! both produce these; the node's runtime turns them into pairs on the
//! wire, where a pair holds only while both ends claim each other.

use serde::{Deserialize, Serialize};

use crate::model::PairingSlot;

/// One end of a pair, or an observed source: an instance and its pairing
/// slot.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct PairEnd {
    /// The instance.
    pub instance: String,
    /// Its pairing slot. `None`: the instance's one slot of the matching
    /// pairing and role, found on the wire once the instance is up (a
    /// command line may name a peer without its slot; the launcher always
    /// names it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub link_id: Option<String>,
}

impl PairEnd {
    /// Reads a link target: `instance` or `instance/link_id`.
    pub fn parse(target: &str) -> Option<PairEnd> {
        match target.split_once('/') {
            None if !target.is_empty() => Some(PairEnd {
                instance: target.to_string(),
                link_id: None,
            }),
            Some((instance, link)) if !instance.is_empty() && !link.is_empty() => Some(PairEnd {
                instance: instance.to_string(),
                link_id: Some(link.to_string()),
            }),
            _ => None,
        }
    }
}

impl std::fmt::Display for PairEnd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.link_id {
            Some(link) => write!(f, "{}/{link}", self.instance),
            None => f.write_str(&self.instance),
        }
    }
}

/// One pairing slot of one instance, as it starts.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PairPlan {
    /// The slot's link_id.
    pub link_id: String,
    /// A participant: the peer it is linked with (at most one; none while
    /// it waits for a peer to link to it, or when left vacant). An
    /// observer: the sources it watches, in link order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub peers: Vec<PairEnd>,
    /// Why an optional participant (or an observer that admits none) is
    /// left empty on purpose (`{ vacant: "why" }`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vacant: Option<String>,
}

/// Why a node's pairing slots cannot start as given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PairPlanError {
    /// A participant slot linked to more than one peer.
    #[error("pairing slot `{link_id}` holds one peer, and is linked to {count}")]
    SeveralPeers {
        /// The slot.
        link_id: String,
        /// How many peers it was given.
        count: usize,
    },
    /// An observer slot given a number of sources its cardinality refuses.
    #[error("observer slot `{link_id}` is `{cardinality}`, and is linked to {count} source(s)")]
    ObserverCardinality {
        /// The slot.
        link_id: String,
        /// Its cardinality.
        cardinality: crate::model::Cardinality,
        /// How many sources it was given.
        count: usize,
    },
    /// A slot left vacant that may not stay empty.
    #[error("pairing slot `{link_id}` may not be left vacant")]
    VacantRequired {
        /// The slot.
        link_id: String,
    },
    /// A slot given peers and a vacancy at once.
    #[error("pairing slot `{link_id}` is both linked and left vacant")]
    LinkedAndVacant {
        /// The slot.
        link_id: String,
    },
    /// A plan for a slot the node does not have.
    #[error("the node has no pairing slot `{link_id}`")]
    UnknownSlot {
        /// The link_id given.
        link_id: String,
    },
    /// The same source watched twice through one observer slot.
    #[error("observer slot `{link_id}` lists `{instance}` twice")]
    DuplicateSource {
        /// The slot.
        link_id: String,
        /// The source.
        instance: String,
    },
}

/// Checks one slot's plan against the slot: what the launcher hands a node
/// and what a command line gives are held to the same rules here. A
/// participant with no peer and no vacancy is legal: it waits for a peer
/// to link to it.
pub fn check_pair_plan(slot: &PairingSlot, plan: &PairPlan) -> Result<(), PairPlanError> {
    let count = plan.peers.len();
    if plan.vacant.is_some() && count > 0 {
        return Err(PairPlanError::LinkedAndVacant {
            link_id: slot.link_id.clone(),
        });
    }
    if plan.vacant.is_some() && !slot.admits_empty() {
        return Err(PairPlanError::VacantRequired {
            link_id: slot.link_id.clone(),
        });
    }
    if !slot.observer {
        if count > 1 {
            return Err(PairPlanError::SeveralPeers {
                link_id: slot.link_id.clone(),
                count,
            });
        }
        return Ok(());
    }
    let fits = match slot.cardinality {
        crate::model::Cardinality::One => count == 1,
        crate::model::Cardinality::ZeroOrOne => count <= 1,
        crate::model::Cardinality::OneOrMore => count >= 1,
        crate::model::Cardinality::ZeroOrMore => true,
    };
    if !fits {
        return Err(PairPlanError::ObserverCardinality {
            link_id: slot.link_id.clone(),
            cardinality: slot.cardinality,
            count,
        });
    }
    for (i, p) in plan.peers.iter().enumerate() {
        if plan.peers[..i].contains(p) {
            return Err(PairPlanError::DuplicateSource {
                link_id: slot.link_id.clone(),
                instance: p.to_string(),
            });
        }
    }
    Ok(())
}

/// Checks a node's whole set of pair plans and fills in the slots the plan
/// leaves out (a participant waiting for a peer; an observer of
/// `zero_or_more` with no source), in the node's slot order.
pub fn fit_pair_plans(
    slots: &[PairingSlot],
    mut plans: Vec<PairPlan>,
) -> Result<Vec<PairPlan>, PairPlanError> {
    if let Some(p) = plans
        .iter()
        .find(|p| !slots.iter().any(|s| s.link_id == p.link_id))
    {
        return Err(PairPlanError::UnknownSlot {
            link_id: p.link_id.clone(),
        });
    }
    let mut out = Vec::with_capacity(slots.len());
    for slot in slots {
        let plan = match plans.iter().position(|p| p.link_id == slot.link_id) {
            Some(i) => plans.swap_remove(i),
            None => PairPlan {
                link_id: slot.link_id.clone(),
                peers: Vec::new(),
                vacant: None,
            },
        };
        check_pair_plan(slot, &plan)?;
        out.push(plan);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Cardinality, Identity};

    fn slot(link: &str, observer: bool, cardinality: Cardinality, optional: bool) -> PairingSlot {
        PairingSlot {
            link_id: link.into(),
            pairing: Identity::new("arm_link", "v1"),
            role: "follower".into(),
            counterpart: "leader".into(),
            observer,
            sha256: None,
            optional,
            cardinality,
            loc: Default::default(),
        }
    }

    fn plan(link: &str, peers: &[&str]) -> PairPlan {
        PairPlan {
            link_id: link.into(),
            peers: peers.iter().map(|p| PairEnd::parse(p).unwrap()).collect(),
            vacant: None,
        }
    }

    #[test]
    fn a_link_target_names_an_instance_and_maybe_its_slot() {
        assert_eq!(PairEnd::parse("arm").unwrap().link_id, None);
        let end = PairEnd::parse("arm/leader").unwrap();
        assert_eq!(
            (end.instance.as_str(), end.link_id.as_deref()),
            ("arm", Some("leader"))
        );
        assert_eq!(end.to_string(), "arm/leader");
        for bad in ["", "/x", "x/", "/"] {
            assert_eq!(PairEnd::parse(bad), None, "{bad}");
        }
    }

    #[test]
    fn participants_hold_one_peer_and_may_wait_for_one() {
        let s = slot("cmd", false, Cardinality::One, false);
        assert!(check_pair_plan(&s, &plan("cmd", &["a"])).is_ok());
        assert!(check_pair_plan(&s, &plan("cmd", &[])).is_ok());
        assert!(matches!(
            check_pair_plan(&s, &plan("cmd", &["a", "b"])),
            Err(PairPlanError::SeveralPeers { count: 2, .. })
        ));
        let mut vacant = plan("cmd", &[]);
        vacant.vacant = Some("bench".into());
        assert!(matches!(
            check_pair_plan(&s, &vacant),
            Err(PairPlanError::VacantRequired { .. })
        ));
        assert!(check_pair_plan(&slot("cmd", false, Cardinality::One, true), &vacant).is_ok());
        let both = PairPlan {
            vacant: Some("bench".into()),
            ..plan("cmd", &["a"])
        };
        assert_eq!(
            check_pair_plan(&slot("cmd", false, Cardinality::One, true), &both),
            Err(PairPlanError::LinkedAndVacant {
                link_id: "cmd".into()
            })
        );
    }

    #[test]
    fn observers_take_as_many_sources_as_their_cardinality_says() {
        let one = slot("w", true, Cardinality::One, false);
        assert!(check_pair_plan(&one, &plan("w", &["a"])).is_ok());
        assert!(check_pair_plan(&one, &plan("w", &[])).is_err());
        let many = slot("w", true, Cardinality::OneOrMore, false);
        assert!(check_pair_plan(&many, &plan("w", &["a", "b/x"])).is_ok());
        assert!(matches!(
            check_pair_plan(&many, &plan("w", &["a", "a"])),
            Err(PairPlanError::DuplicateSource { .. })
        ));
    }

    #[test]
    fn fitting_fills_unplanned_slots_in_slot_order_and_refuses_strangers() {
        let slots = [
            slot("cmd", false, Cardinality::One, false),
            slot("w", true, Cardinality::ZeroOrMore, false),
        ];
        let fitted = fit_pair_plans(&slots, vec![plan("w", &["a"])]).unwrap();
        assert_eq!(fitted, vec![plan("cmd", &[]), plan("w", &["a"])]);
        assert!(matches!(
            fit_pair_plans(&slots, vec![plan("nope", &[])]),
            Err(PairPlanError::UnknownSlot { .. })
        ));
    }
}
