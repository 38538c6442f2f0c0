//! `--pair INSTANCE.SLOT` of `topic echo`, `hz` and `bw`: a pairing topic
//! as one pair carries it (docs/PAIRINGS.md §3). A pair's messages are
//! published under the sending instance *and its pairing slot*, so the
//! samples taken are those of the named slot (the topics its role emits),
//! of its peer (the counterpart's), or of an observer's sources. Running
//! instances do not describe their pairing topics' formats, so the format
//! is read from the pairing document in the repositories.

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::Arc;

use peppy_runtime::describe::{InstanceInfo, PairingSlotInfo};
use peppy_runtime::wire::keys::{Sender, pairing_topic_selector, parse_pairing_topic_key};
use peppy_schema::Identity;

use super::SelectError;
use super::stream::Selection;
use crate::cli::TopicSelect;
use crate::error::Result;

/// The pairing slots whose sends a `--pair` selection takes: `(instance,
/// link_id)`, `link_id` `None` for an observer's source whose slot is not
/// known yet (any of its slots).
pub(crate) type Senders = Arc<Vec<(String, Option<String>)>>;

/// Why a `--pair` selection cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum PairSelectError {
    /// `--pair` is not `INSTANCE.SLOT`.
    #[error("--pair takes `INSTANCE.SLOT` (a pairing slot of a running instance), not `{arg}`")]
    NotASlot {
        /// The argument.
        arg: String,
    },
    /// The instance has no pairing slot of that name.
    #[error(
        "`{instance}` has no pairing slot `{slot}`; its pairing slots: {}",
        super::listed(slots)
    )]
    NoSuchSlot {
        /// The instance.
        instance: String,
        /// The slot asked for.
        slot: String,
        /// Its pairing slots.
        slots: Vec<String>,
    },
    /// The pairing document is in no repository.
    #[error(
        "pairing `{pairing}` (slot `{slot}`) is in no repository, so its topics' formats are unknown; {searched}"
    )]
    NoDocument {
        /// The slot, `INSTANCE.SLOT`.
        slot: String,
        /// The pairing.
        pairing: Identity,
        /// Where it was looked for.
        searched: String,
    },
    /// The pairing has no topic of that name.
    #[error(
        "pairing `{pairing}` has no topic `{topic}`; its topics: {}",
        super::listed(topics)
    )]
    NoSuchTopic {
        /// The topic asked for.
        topic: String,
        /// The pairing.
        pairing: Identity,
        /// Its topics.
        topics: Vec<String>,
    },
    /// The slot's peer sends the topic, and the slot has none now.
    #[error(
        "`{slot}` is not paired now, so nobody sends it `{topic}`; its own topics: {}",
        super::listed(own)
    )]
    NotPaired {
        /// The slot, `INSTANCE.SLOT`.
        slot: String,
        /// The topic.
        topic: String,
        /// The topics the slot's role sends.
        own: Vec<String>,
    },
    /// An observer slot watches one role, and the topic is the other's.
    #[error(
        "observer slot `{slot}` watches role `{role}`, and `{topic}` is emitted by `{emitted_by}`"
    )]
    NotObserved {
        /// The slot, `INSTANCE.SLOT`.
        slot: String,
        /// The role it watches.
        role: String,
        /// The topic.
        topic: String,
        /// Who emits it.
        emitted_by: String,
    },
}

/// The selection of `TOPIC --pair INSTANCE.SLOT`.
pub(crate) fn selection(
    args: &TopicSelect,
    pair: &str,
    ns: &str,
    all: &BTreeMap<String, InstanceInfo>,
) -> Result<Selection> {
    let Some((instance, link)) = pair.split_once('.') else {
        return Err(SelectError::from(PairSelectError::NotASlot { arg: pair.into() }).into());
    };
    let Some(info) = all.get(instance) else {
        return Err(SelectError::NoSuchInstance {
            instance: instance.to_string(),
            stack: ns.to_string(),
            answering: all.keys().cloned().collect(),
        }
        .into());
    };
    let Some(slot) = info.pairings.iter().find(|p| p.link_id == link) else {
        return Err(SelectError::from(PairSelectError::NoSuchSlot {
            instance: instance.into(),
            slot: link.into(),
            slots: info.pairings.iter().map(|p| p.link_id.clone()).collect(),
        })
        .into());
    };
    let doc = pairing_document(&args.repos, pair, &slot.pairing)?;
    let Some(topic) = doc.topics.iter().find(|t| t.decl.name == args.topic) else {
        return Err(SelectError::from(PairSelectError::NoSuchTopic {
            topic: args.topic.clone(),
            pairing: slot.pairing.clone(),
            topics: doc.topics.iter().map(|t| t.decl.name.clone()).collect(),
        })
        .into());
    };
    let senders = senders_of(slot, instance, pair, topic, || {
        doc.topics
            .iter()
            .filter(|t| t.emitted_by == slot.role)
            .map(|t| t.decl.name.clone())
            .collect()
    })
    .map_err(SelectError::from)?;
    let (canonical, fingerprint) = match &topic.decl.format {
        Some(f) => (f.canonical(), f.fingerprint()),
        None => ("(no payload)".to_string(), 0),
    };
    // One sender: its own key; several: every sender's, kept by the reader.
    let (inst, link) = match senders.as_slice() {
        [(i, l)] => (Some(i.as_str()), l.as_deref()),
        _ => (None, None),
    };
    let selector = pairing_topic_selector(
        ns,
        &slot.pairing.name,
        &slot.pairing.tag,
        &topic.decl.name,
        None,
        inst,
        link,
    );
    Ok(Selection::of_pair(
        topic.decl.name.clone(),
        selector,
        HashMap::from([(fingerprint, canonical)]),
        Arc::new(senders),
    ))
}

/// Whose sends of a topic emitted by `emitted_by` the slot's pair carries.
fn senders_of(
    slot: &PairingSlotInfo,
    instance: &str,
    pair: &str,
    topic: &peppy_schema::PairingTopic,
    own: impl FnOnce() -> Vec<String>,
) -> std::result::Result<Vec<(String, Option<String>)>, PairSelectError> {
    let emitted_by = topic.emitted_by.as_str();
    if slot.observer {
        if emitted_by != slot.role {
            return Err(PairSelectError::NotObserved {
                slot: pair.into(),
                role: slot.role.clone(),
                topic: topic.decl.name.clone(),
                emitted_by: emitted_by.into(),
            });
        }
        return Ok(slot
            .sources
            .iter()
            .map(|s| (s.instance_id.clone(), s.link_id.clone()))
            .collect());
    }
    if emitted_by == slot.role {
        return Ok(vec![(instance.to_string(), Some(slot.link_id.clone()))]);
    }
    match &slot.peer {
        Some(p) => Ok(vec![(p.instance_id.clone(), Some(p.link_id.clone()))]),
        None => Err(PairSelectError::NotPaired {
            slot: pair.into(),
            topic: topic.decl.name.clone(),
            own: own(),
        }),
    }
}

/// The pairing document, from the repositories `--repo` (or the
/// environment, or the current directory) names.
fn pairing_document(
    repos: &[PathBuf],
    pair: &str,
    pairing: &Identity,
) -> Result<Arc<peppy_schema::PairingDoc>> {
    let cwd = std::env::current_dir().unwrap_or_default();
    let index = crate::repositories::index(repos, &cwd).unwrap_or_default();
    match index.pairing(pairing) {
        Some(e) => Ok(e.doc.clone()),
        None => Err(SelectError::from(PairSelectError::NoDocument {
            slot: pair.into(),
            pairing: pairing.clone(),
            searched: index.searched(),
        })
        .into()),
    }
}

/// Who sent a pair's sample, if it is one of `senders`': its pairing,
/// topic and sender as a [`Sender`] (`kind` `pairing`).
pub(crate) fn sender(key: &str, senders: &[(String, Option<String>)]) -> Option<Sender> {
    let s = parse_pairing_topic_key(key)?;
    senders
        .iter()
        .any(|(i, l)| i == s.instance && l.as_deref().is_none_or(|l| l == s.link_id))
        .then(|| Sender {
            kind: "pairing".into(),
            name: s.pairing.into(),
            tag: s.tag.into(),
            entry: s.topic.into(),
            core: s.core.into(),
            instance: s.instance.into(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_pairs_senders_are_taken() {
        let senders = vec![("follower".to_string(), Some("leader".to_string()))];
        let key = "peppy/ns/topic/pairing/joint_link/v1/joint_state/c1/follower/leader";
        let s = sender(key, &senders).unwrap();
        assert_eq!(
            (
                s.kind.as_str(),
                s.name.as_str(),
                s.entry.as_str(),
                s.instance.as_str()
            ),
            ("pairing", "joint_link", "joint_state", "follower")
        );
        let other_slot = "peppy/ns/topic/pairing/joint_link/v1/joint_state/c1/follower/other";
        assert!(sender(other_slot, &senders).is_none());
        let any_slot = vec![("follower".to_string(), None)];
        assert!(sender(other_slot, &any_slot).is_some());
        assert!(sender("peppy/ns/topic/node/a/v1/t/c/i", &any_slot).is_none());
    }
}
