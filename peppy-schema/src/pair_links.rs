//! A launcher's links on pairing slots, turned into each instance's
//! [`PairPlan`]s (docs/PAIRINGS.md §2): a participant's link names its
//! peer and covers both ends; an observer's names the sources it watches.
//! Every rule is checked here, before anything starts.

use std::collections::BTreeMap;

use crate::diag::{Code, Diagnostics, list};
use crate::launcher::{Instance, LauncherDoc, LinkTarget, LinkValue};
use crate::loc::Loc;
use crate::model::Cardinality;
use crate::node::{NodeDoc, PairingSlot};
use crate::pairs::{PairEnd, PairPlan};

/// Whether `key` names one of the node's pairing slots: such links are
/// planned here, not by the binding engine.
pub(crate) fn is_pairing_link(node: &NodeDoc, key: &str) -> bool {
    node.pairings.iter().any(|p| p.link_id == key)
}

/// One end of a pair being planned: who set it, for error messages.
struct Claim {
    peer: PairEnd,
    /// The instance whose link made it.
    by: String,
    loc: Loc,
}

/// Plans every pairing slot of every instance. `nodes[d]` is the node of
/// deployment `d`. Returns, per instance id, its plans in slot order.
pub(crate) fn plan_pairs(
    launcher: &LauncherDoc,
    nodes: &[Option<&NodeDoc>],
    diags: &mut Diagnostics,
) -> BTreeMap<String, Vec<PairPlan>> {
    let node_of = |id: &str| -> Option<&NodeDoc> {
        launcher
            .instances()
            .find(|(_, i)| i.instance_id == id)
            .and_then(|(d, _)| nodes[d])
    };
    // (instance, slot) -> the participant's peer.
    let mut peers: BTreeMap<(String, String), Claim> = BTreeMap::new();
    // (instance, slot) -> an observer's sources, or a vacancy.
    let mut sources: BTreeMap<(String, String), Vec<PairEnd>> = BTreeMap::new();
    let mut vacant: BTreeMap<(String, String), String> = BTreeMap::new();

    for (d, inst) in launcher.instances() {
        let Some(node) = nodes[d] else { continue };
        for link in &inst.links {
            let Some(slot) = node.pairings.iter().find(|p| p.link_id == link.key) else {
                continue;
            };
            let key = (inst.instance_id.clone(), slot.link_id.clone());
            let targets = match &link.value {
                LinkValue::Vacant { reason, loc } => {
                    if slot.admits_empty() {
                        vacant.insert(key, reason.clone());
                    } else {
                        diags.push(
                            loc.error(
                                Code::LinkVacantInvalid,
                                format!(
                                    "pairing slot `{}` of instance `{}` may not be left vacant",
                                    slot.link_id, inst.instance_id
                                ),
                            )
                            .with_help(if slot.observer {
                                "only an observer slot of `zero_or_one` or `zero_or_more` may be vacant"
                            } else {
                                "only a slot declared `optional: true` may be vacant; link it to a peer"
                            }),
                        );
                    }
                    continue;
                }
                LinkValue::One(t) => vec![t],
                // A `launcher_v1` binding never names a pairing slot: the
                // engine reports it like any key naming no producer slot.
                LinkValue::Bound(_) => continue,
                LinkValue::Many(ts, loc) => {
                    if !slot.observer || slot.cardinality.is_scalar() {
                        diags.push(
                            loc.error(
                                Code::BindingArrayOnScalarSlot,
                                format!(
                                    "pairing slot `{}` of instance `{}` takes one {}, and is given a list",
                                    slot.link_id,
                                    inst.instance_id,
                                    if slot.observer { "source" } else { "peer" }
                                ),
                            )
                            .with_help("write the one instance as a string"),
                        );
                        continue;
                    }
                    ts.iter().collect()
                }
            };
            for t in targets {
                // Unknown instances were reported with the launcher.
                let Some(target_node) = node_of(&t.instance) else {
                    continue;
                };
                if slot.observer {
                    let Some(source) = observed_slot(inst, slot, t, target_node, diags) else {
                        continue;
                    };
                    if !pins_agree(inst, slot, t, target_node, source.link_id.as_deref(), diags) {
                        continue;
                    }
                    let list = sources.entry(key.clone()).or_default();
                    if list.contains(&source) {
                        diags.push(
                            t.loc
                                .error(
                                    Code::DuplicateObservationTarget,
                                    format!(
                                        "observer slot `{}` of instance `{}` lists `{source}` twice",
                                        slot.link_id, inst.instance_id
                                    ),
                                )
                                .with_help("list each source once"),
                        );
                    } else {
                        list.push(source);
                    }
                    continue;
                }
                let Some(peer_slot) = complementary_slot(inst, slot, t, target_node, diags) else {
                    continue;
                };
                if !pins_agree(inst, slot, t, target_node, Some(&peer_slot), diags) {
                    continue;
                }
                let here = PairEnd {
                    instance: inst.instance_id.clone(),
                    link_id: Some(slot.link_id.clone()),
                };
                let there = PairEnd {
                    instance: t.instance.clone(),
                    link_id: Some(peer_slot),
                };
                for (end, peer) in [(&here, &there), (&there, &here)] {
                    let end_key = (
                        end.instance.clone(),
                        end.link_id.clone().unwrap_or_default(),
                    );
                    match peers.get(&end_key) {
                        Some(existing) if existing.peer == *peer => {}
                        Some(existing) => {
                            // Our own slot already taken by another link: the
                            // two ends disagree. The peer's slot taken: it
                            // would hold two peers.
                            let (code, what) = if std::ptr::eq(end, &here) {
                                (
                                    Code::PairingConflict,
                                    format!(
                                        "`{end}` is paired with `{}` by the link of `{}`, and with `{peer}` here",
                                        existing.peer, existing.by
                                    ),
                                )
                            } else {
                                (
                                    Code::PairingSlotAlreadyPaired,
                                    format!(
                                        "`{end}` holds one peer, and is already paired with `{}` (linked by `{}`)",
                                        existing.peer, existing.by
                                    ),
                                )
                            };
                            let lc = existing.loc.file.line_col(existing.loc.span.start);
                            diags.push(t.loc.error(code, what).with_help(format!(
                                "a pairing slot holds one peer; the other link is at line {}, column {}",
                                lc.line, lc.column
                            )));
                            break;
                        }
                        None => {
                            peers.insert(
                                end_key,
                                Claim {
                                    peer: peer.clone(),
                                    by: inst.instance_id.clone(),
                                    loc: t.loc.clone(),
                                },
                            );
                        }
                    }
                }
            }
        }
    }

    let mut out = BTreeMap::new();
    for (d, inst) in launcher.instances() {
        let Some(node) = nodes[d] else { continue };
        let mut plans = Vec::new();
        for slot in &node.pairings {
            let key = (inst.instance_id.clone(), slot.link_id.clone());
            let vacancy = vacant.get(&key).cloned();
            let ends: Vec<PairEnd> = if slot.observer {
                sources.remove(&key).unwrap_or_default()
            } else {
                peers
                    .get(&key)
                    .map(|c| c.peer.clone())
                    .into_iter()
                    .collect()
            };
            let plan = PairPlan {
                link_id: slot.link_id.clone(),
                peers: ends,
                vacant: vacancy,
            };
            // What the node will check of its plan, checked before anything
            // starts (a peer linking to a slot this instance left vacant).
            // The other rules of `check_pair_plan` were reported above, each
            // where it is written.
            if !uncovered(inst, slot, plan.peers.len(), plan.vacant.is_some(), diags)
                && let Err(e @ crate::pairs::PairPlanError::LinkedAndVacant { .. }) =
                    crate::pairs::check_pair_plan(slot, &plan)
            {
                diags.push(
                    inst.id_loc
                        .error(
                            Code::LinkVacantInvalid,
                            format!("instance `{}`: {e}", inst.instance_id),
                        )
                        .with_help("a slot is either linked to peers or left vacant"),
                );
            }
            plans.push(plan);
        }
        out.insert(inst.instance_id.clone(), plans);
    }
    out
}

/// Whether the two ends of a link pin the same revision of their pairing
/// (a pin missing on either side agrees with anything): PeppyOS's
/// `PairingSha256Mismatch` otherwise, since each end would read the
/// pairing's topics from a different document.
fn pins_agree(
    inst: &Instance,
    slot: &PairingSlot,
    t: &LinkTarget,
    target_node: &NodeDoc,
    target_link: Option<&str>,
    diags: &mut Diagnostics,
) -> bool {
    let Some(theirs) =
        target_link.and_then(|l| target_node.pairings.iter().find(|p| p.link_id == l))
    else {
        return true;
    };
    match (&slot.sha256, &theirs.sha256) {
        (Some(a), Some(b)) if !a.eq_ignore_ascii_case(b) => {
            diags.push(
                t.loc
                    .error(
                        Code::PairingSha256Mismatch,
                        format!(
                            "slot `{}` of `{}` pins pairing `{}` at sha256 {a}, and slot `{}` of `{}` at {b}",
                            slot.link_id, inst.instance_id, slot.pairing, theirs.link_id, t.instance
                        ),
                    )
                    .with_help("both ends of a pair read the same pairing document: pin the same sha256 on both slots, or drop one pin"),
            );
            false
        }
        _ => true,
    }
}

/// The peer's slot a participant's link names: the one given after `/`,
/// or the peer's only free slot of the same pairing and the other role.
fn complementary_slot(
    inst: &Instance,
    slot: &PairingSlot,
    t: &LinkTarget,
    peer: &NodeDoc,
    diags: &mut Diagnostics,
) -> Option<String> {
    let fits: Vec<&PairingSlot> = peer
        .pairings
        .iter()
        .filter(|p| !p.observer && p.pairing == slot.pairing && p.role != slot.role)
        .collect();
    if t.instance == inst.instance_id {
        diags.push(
            t.loc
                .error(
                    Code::PairingTargetNotComplementary,
                    format!(
                        "instance `{}` pairs slot `{}` with itself",
                        inst.instance_id, slot.link_id
                    ),
                )
                .with_help("a pair is two instances"),
        );
        return None;
    }
    let chosen = match &t.peer_slot {
        Some(s) => fits.iter().find(|p| &p.link_id == s).copied(),
        None if fits.len() == 1 => Some(fits[0]),
        None if fits.len() > 1 => {
            diags.push(
                t.loc
                    .error(
                        Code::PairingTargetAmbiguous,
                        format!(
                            "instance `{}` takes part in `{}` through several slots: {}",
                            t.instance,
                            slot.pairing,
                            list(fits.iter().map(|p| p.link_id.as_str()))
                        ),
                    )
                    .with_help(format!(
                        "name the slot: `\"{}/{}\"`",
                        t.instance, fits[0].link_id
                    )),
            );
            return None;
        }
        None => None,
    };
    if let Some(c) = chosen {
        return Some(c.link_id.clone());
    }
    let help = if fits.is_empty() {
        format!(
            "pair it with an instance of a node that declares `depends_on.pairings: [{{ name: \"{}\", tag: \"{}\", role: \"<the other role>\", ... }}]`",
            slot.pairing.name, slot.pairing.tag
        )
    } else {
        format!(
            "its slots of the other role are {}",
            list(fits.iter().map(|p| p.link_id.as_str()))
        )
    };
    diags.push(
        t.loc
            .error(
                Code::PairingTargetNotComplementary,
                format!(
                    "slot `{}` of instance `{}` plays `{}` of `{}`, and `{t}` has no slot of the other role of that pairing",
                    slot.link_id, inst.instance_id, slot.role, slot.pairing
                ),
            )
            .with_help(help),
    );
    None
}

/// The source's slot an observer's link names: the one given after `/`,
/// or the source's only slot playing the watched role.
fn observed_slot(
    inst: &Instance,
    slot: &PairingSlot,
    t: &LinkTarget,
    source: &NodeDoc,
    diags: &mut Diagnostics,
) -> Option<PairEnd> {
    let fits: Vec<&PairingSlot> = source
        .pairings
        .iter()
        .filter(|p| !p.observer && p.pairing == slot.pairing && p.role == slot.role)
        .collect();
    let chosen = match &t.peer_slot {
        Some(s) => fits.iter().find(|p| &p.link_id == s).copied(),
        None if fits.len() > 1 => {
            diags.push(
                t.loc
                    .error(
                        Code::ObservationTargetAmbiguous,
                        format!(
                            "instance `{}` plays `{}` of `{}` through several slots: {}",
                            t.instance,
                            slot.role,
                            slot.pairing,
                            list(fits.iter().map(|p| p.link_id.as_str()))
                        ),
                    )
                    .with_help(format!(
                        "name the slot: `\"{}/{}\"`",
                        t.instance, fits[0].link_id
                    )),
            );
            return None;
        }
        None => fits.first().copied(),
    };
    match chosen {
        Some(c) => Some(PairEnd {
            instance: t.instance.clone(),
            link_id: Some(c.link_id.clone()),
        }),
        None => {
            diags.push(
                t.loc
                    .error(
                        Code::ObservationTargetNotObservable,
                        format!(
                            "observer slot `{}` of instance `{}` watches role `{}` of `{}`, and `{t}` does not play it",
                            slot.link_id, inst.instance_id, slot.role, slot.pairing
                        ),
                    )
                    .with_help(if fits.is_empty() {
                        "link the observer to an instance taking part in that pairing in the watched role".to_string()
                    } else {
                        format!(
                            "its slots playing `{}` are {}",
                            slot.role,
                            list(fits.iter().map(|p| p.link_id.as_str()))
                        )
                    }),
            );
            None
        }
    }
}

/// A participant left without a peer, or an observer without the sources
/// its cardinality asks for; true when it reported one.
fn uncovered(
    inst: &Instance,
    slot: &PairingSlot,
    count: usize,
    vacant: bool,
    diags: &mut Diagnostics,
) -> bool {
    if slot.observer {
        let short = match slot.cardinality {
            Cardinality::One | Cardinality::OneOrMore => count == 0,
            Cardinality::ZeroOrOne | Cardinality::ZeroOrMore => false,
        };
        if short {
            diags.push(
                inst.id_loc
                    .error(
                        Code::BindingSlotUnfulfilled,
                        format!(
                            "instance `{}` leaves observer slot `{}` ({}) without a source",
                            inst.instance_id, slot.link_id, slot.cardinality
                        ),
                    )
                    .with_help(format!(
                        "add `links: {{ {}: \"<instance playing {}>\" }}`",
                        slot.link_id, slot.role
                    )),
            );
        }
        return short;
    }
    let short = count == 0 && !vacant && !slot.optional;
    if short {
        diags.push(
            inst.id_loc
                .error(
                    Code::PairingSlotUncovered,
                    format!(
                        "instance `{}` leaves pairing slot `{}` ({} of `{}`) without a peer",
                        inst.instance_id, slot.link_id, slot.role, slot.pairing
                    ),
                )
                .with_help(format!(
                    "add `links: {{ {}: \"<instance playing the other role>\" }}` here or on the peer",
                    slot.link_id
                )),
        );
    }
    short
}
