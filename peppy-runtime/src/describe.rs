//! What a running instance says about itself. Every node answers a query
//! on `peppy/<ns>/describe/<core>/<instance>` with one JSON document, an
//! [`InstanceInfo`]: its identity, process, slots with their bindings and
//! routing, and every entry it emits, consumes, serves, with the canonical
//! text of each message format. Inspection tools (`peppy-launch node`,
//! `topic`, `service`, `action`, `graph --live`) read it, so they decode
//! and route exactly as the node does without any generated code.

use peppy_schema::{Identity, QosProfile, RouteFilter, SlotBinding, SlotKind};
use serde::{Deserialize, Serialize};

use crate::spec::{FormatSpec, OwnerSpec};
use crate::wire::keys::{Owner, format_key};

/// Version of the [`InstanceInfo`] document; bumped on incompatible change.
pub const DESCRIBE_VERSION: u32 = 1;

/// One instance, as it describes itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InstanceInfo {
    /// [`DESCRIBE_VERSION`].
    pub version: u32,
    /// The instance id.
    pub instance_id: String,
    /// The core node that started it.
    pub core_node: String,
    /// The namespace it runs in.
    pub namespace: String,
    /// Its node's `name:tag`.
    pub node: Identity,
    /// Its process id, on its core node's host.
    pub pid: u32,
    /// When it came up, in milliseconds since the Unix epoch.
    pub started_at_ms: u64,
    /// Its slots (`depends_on`), in order, with their bindings.
    pub slots: Vec<SlotInfo>,
    /// Topics it publishes.
    pub emits: Vec<EmittedTopic>,
    /// Topics it receives (slots' topics and external topics).
    pub consumes: Vec<ConsumedTopic>,
    /// Services it serves.
    pub services: Vec<ServedService>,
    /// Actions it serves.
    pub actions: Vec<ServedAction>,
    /// Its pairing slots, participants and observers, with their state
    /// when the description was asked for.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pairings: Vec<PairingSlotInfo>,
}

/// A pairing slot and its state (docs/PAIRINGS.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairingSlotInfo {
    /// The slot's `link_id`.
    pub link_id: String,
    /// The pairing document.
    pub pairing: Identity,
    /// The role the slot plays (a participant) or watches (an observer).
    pub role: String,
    /// Whether it observes rather than takes part.
    pub observer: bool,
    /// A participant: the slot it claims, `instance/link_id` (or only the
    /// instance while its slot is being looked up); `None` while it
    /// claims nobody.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub claiming: Option<String>,
    /// A participant: its peer while paired.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peer: Option<PeerEndInfo>,
    /// An observer: its sources, in link order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sources: Vec<SourceInfo>,
}

/// The other end of a pair.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PeerEndInfo {
    /// The peer's core node.
    pub core_node: String,
    /// The peer instance.
    pub instance_id: String,
    /// The peer's pairing slot.
    pub link_id: String,
}

/// A source an observer slot watches.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SourceInfo {
    /// Its core node (this node's until its presence was seen).
    pub core_node: String,
    /// The source instance.
    pub instance_id: String,
    /// Its pairing slot, once known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub link_id: Option<String>,
    /// Whether its presence token is up.
    pub live: bool,
}

/// A slot and what fills it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SlotInfo {
    /// The slot's `link_id`.
    pub link_id: String,
    /// Node or interface slot.
    pub kind: SlotKind,
    /// The node or interface the slot takes.
    pub target: Identity,
    /// The binding from the launcher or the command line.
    pub binding: SlotBinding,
    /// Which producers' samples the slot keeps.
    pub filter: RouteFilter,
}

/// Whose contract an entry belongs to.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct OwnerInfo {
    /// `node` or `interface`.
    pub kind: SlotKind,
    /// Its name.
    pub name: String,
    /// Its tag.
    pub tag: String,
}

impl OwnerInfo {
    pub(crate) fn of(owner: &Owner<'_>) -> OwnerInfo {
        let (kind, name, tag) = match owner {
            Owner::Node { name, tag } => (SlotKind::Node, name, tag),
            Owner::Interface { name, tag } => (SlotKind::Interface, name, tag),
        };
        OwnerInfo {
            kind,
            name: name.to_string(),
            tag: tag.to_string(),
        }
    }

    /// The owner as a key segment triple, e.g. `interface/depth_camera/v1`.
    pub fn as_owner(&self) -> Owner<'_> {
        match self.kind {
            SlotKind::Node => Owner::Node {
                name: &self.name,
                tag: &self.tag,
            },
            SlotKind::Interface => Owner::Interface {
                name: &self.name,
                tag: &self.tag,
            },
        }
    }
}

/// A message format: its canonical text and fingerprint.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FormatInfo {
    /// Canonical text (docs/WIRE.md section 6); `(no payload)` for none.
    pub canonical: String,
    /// Its fingerprint.
    pub fingerprint: u64,
}

impl From<&FormatSpec> for FormatInfo {
    fn from(f: &FormatSpec) -> Self {
        FormatInfo {
            canonical: f.canonical.to_string(),
            fingerprint: f.fingerprint,
        }
    }
}

/// A topic the instance publishes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EmittedTopic {
    /// Its owner.
    pub owner: OwnerInfo,
    /// Topic name.
    pub name: String,
    /// QoS profile.
    pub qos: QosProfile,
    /// Payload format.
    pub format: FormatInfo,
    /// The key it publishes on.
    pub key: String,
}

/// A topic the instance receives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConsumedTopic {
    /// The slot it belongs to; `None` for an external topic.
    pub slot: Option<String>,
    /// The producers' owner; `None` for an external topic (any owner).
    pub owner: Option<OwnerInfo>,
    /// Topic name.
    pub name: String,
    /// The producers' QoS profile.
    pub qos: QosProfile,
    /// Payload format.
    pub format: FormatInfo,
    /// The key expression it subscribes to.
    pub selector: String,
    /// The per-sample producer filter.
    pub filter: RouteFilter,
    /// For a node slot on an interface's key: only live instances of this
    /// node are kept.
    pub members_of: Option<Identity>,
}

/// A service the instance serves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ServedService {
    /// Its owner.
    pub owner: OwnerInfo,
    /// Service name.
    pub name: String,
    /// Request format.
    pub request: FormatInfo,
    /// Response format.
    pub response: FormatInfo,
    /// The key its queryable answers on.
    pub key: String,
}

/// An action the instance serves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ServedAction {
    /// Its owner.
    pub owner: OwnerInfo,
    /// Action name.
    pub name: String,
    /// Goal format.
    pub goal: FormatInfo,
    /// Feedback format (`(no payload)` when it has none).
    pub feedback: FormatInfo,
    /// Result format.
    pub result: FormatInfo,
    /// The action's base key (its goal, cancel and result keys hang below).
    pub key: String,
}

impl InstanceInfo {
    /// The document as sent on the wire.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("an instance description serializes")
    }

    /// Reads a description received from an instance.
    pub fn from_json(bytes: &[u8]) -> Result<InstanceInfo, serde_json::Error> {
        serde_json::from_slice(bytes)
    }

    /// Whether the description, received in namespace `ns` on
    /// `reply_key`, can be trusted as a map of the wire: the version this
    /// build reads, the namespace asked, the describe key of the instance
    /// it names, every key exactly the one its owner, name, core and
    /// instance make (a key with a wildcard would reach every server), and
    /// every subscription inside the namespace's topics.
    pub fn check(&self, ns: &str, reply_key: &str) -> Result<(), String> {
        use crate::wire::keys::{Channel, EntrySelector, describe_key, entry_key, is_segment};
        if self.version != DESCRIBE_VERSION {
            return Err(format!(
                "description version {} (this build reads {DESCRIBE_VERSION})",
                self.version
            ));
        }
        for segment in [&self.namespace, &self.core_node, &self.instance_id] {
            if !is_segment(segment) {
                return Err(format!("`{segment}` is not a key segment"));
            }
        }
        if self.namespace != ns || reply_key != describe_key(ns, &self.core_node, &self.instance_id)
        {
            return Err(format!(
                "a description of `{}` in namespace `{}` answered on `{reply_key}`",
                self.instance_id, self.namespace
            ));
        }
        // What `entry_selector` builds for a topic of this namespace, and
        // nothing wider: a tool subscribes to it (narrowed to a producer).
        let subscription = |s: &str| {
            EntrySelector::parse(s)
                .is_some_and(|e| e.ns == ns && e.channel == Channel::Topic && e.part.is_none())
        };
        if let Some(c) = self.consumes.iter().find(|c| !subscription(&c.selector)) {
            return Err(format!("`{}` is not a topic subscription", c.selector));
        }
        let expect = |channel, owner: &OwnerInfo, name: &str, key: &str| {
            let ok = is_segment(name)
                && is_segment(&owner.name)
                && is_segment(&owner.tag)
                && key
                    == entry_key(
                        &self.namespace,
                        channel,
                        &owner.as_owner(),
                        name,
                        &self.core_node,
                        &self.instance_id,
                    );
            if ok {
                Ok(())
            } else {
                Err(format!("`{key}` is not the key of `{name}`"))
            }
        };
        for t in &self.emits {
            expect(Channel::Topic, &t.owner, &t.name, &t.key)?;
        }
        for s in &self.services {
            expect(Channel::Service, &s.owner, &s.name, &s.key)?;
        }
        for a in &self.actions {
            expect(Channel::Action, &a.owner, &a.name, &a.key)?;
        }
        Ok(())
    }

    /// When it has been up since, as a duration up to `now_ms`.
    pub fn uptime(&self, now_ms: u64) -> std::time::Duration {
        std::time::Duration::from_millis(now_ms.saturating_sub(self.started_at_ms))
    }
}

/// The owner of a consumed entry, if it has one.
pub(crate) fn owner_info(spec: &OwnerSpec, own: &Identity) -> Option<OwnerInfo> {
    spec.resolve(&own.name, &own.tag)
        .as_ref()
        .map(OwnerInfo::of)
}

/// Milliseconds since the Unix epoch.
pub(crate) fn now_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

/// Asks instance `producer` for the text of the format whose fingerprint is
/// `fingerprint` (its format queryable, docs/WIRE.md §1): the one way a
/// node naming a mismatched producer's format and a tool decoding a
/// stranger's messages learn it. `None` when nobody answers within
/// `timeout`, or the answer is not text.
pub async fn ask_format(
    session: &zenoh::Session,
    namespace: &str,
    fingerprint: u64,
    producer: &str,
    timeout: std::time::Duration,
) -> Option<String> {
    let replies = session
        .get(format_key(namespace, fingerprint, producer))
        .timeout(timeout)
        .await
        .ok()?;
    let reply = replies.recv_async().await.ok()?;
    let sample = reply.result().ok()?;
    String::from_utf8(sample.payload().to_bytes().into_owned()).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info() -> InstanceInfo {
        let owner = OwnerInfo {
            kind: SlotKind::Node,
            name: "arm".into(),
            tag: "v1".into(),
        };
        let format = FormatInfo {
            canonical: "{x:f64}".into(),
            fingerprint: 7,
        };
        InstanceInfo {
            version: DESCRIBE_VERSION,
            instance_id: "arm_1".into(),
            core_node: "c".into(),
            namespace: "lab".into(),
            node: Identity::new("arm", "v1"),
            pid: 1,
            started_at_ms: 5,
            slots: Vec::new(),
            emits: vec![EmittedTopic {
                owner: owner.clone(),
                name: "state".into(),
                qos: QosProfile::SensorData,
                format: format.clone(),
                key: "peppy/lab/topic/node/arm/v1/state/c/arm_1".into(),
            }],
            consumes: Vec::new(),
            services: vec![ServedService {
                owner,
                name: "home".into(),
                request: format.clone(),
                response: format,
                key: "peppy/lab/service/node/arm/v1/home/c/arm_1".into(),
            }],
            actions: Vec::new(),
            pairings: Vec::new(),
        }
    }

    #[test]
    fn descriptions_round_trip_and_are_checked() {
        let i = info();
        let key = "peppy/lab/describe/c/arm_1";
        assert_eq!(i.check("lab", key), Ok(()));
        assert!(i.check("other", key).is_err(), "another namespace");
        assert!(i.check("lab", "peppy/lab/describe/c/someone_else").is_err());
        let back = InstanceInfo::from_json(i.to_json().as_bytes()).unwrap();
        assert_eq!(back, i);
        assert_eq!(i.uptime(1005), std::time::Duration::from_secs(1));

        let mut wild = info();
        wild.services[0].key = "peppy/lab/service/node/arm/v1/home/*/*".into();
        assert!(
            wild.check("lab", key)
                .unwrap_err()
                .contains("is not the key of `home`")
        );
        let mut newer = info();
        newer.version = DESCRIBE_VERSION + 1;
        assert!(newer.check("lab", key).is_err());
        let mut odd = info();
        odd.instance_id = "a/b".into();
        assert!(odd.check("lab", key).is_err());
        let mut greedy = info();
        greedy.consumes.push(ConsumedTopic {
            slot: None,
            owner: None,
            name: "x".into(),
            qos: QosProfile::Standard,
            format: FormatInfo {
                canonical: "{}".into(),
                fingerprint: 0,
            },
            selector: "peppy/lab/**".into(),
            filter: RouteFilter::Any,
            members_of: None,
        });
        assert!(greedy.check("lab", key).is_err());
        assert!(InstanceInfo::from_json(b"{\"version\": 1}").is_err());
    }
}
