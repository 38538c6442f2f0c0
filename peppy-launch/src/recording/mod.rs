//! Recordings: a stack's topics in an MCAP file (`record`), and that file
//! published back into a stack (`replay`).
//!
//! A recording needs no generated code and no message package: every
//! producer describes its formats at run time, so the recorder decodes
//! each message from its format's canonical text and writes it as JSON,
//! beside a JSON Schema of the format (docs/RECORDING.md says why JSON).
//! Each channel's metadata keeps what replay needs to publish the message
//! again exactly: the producer, its topic's owner and QoS, and the format's
//! canonical text and fingerprint ([`ChannelMeta`]).

pub(crate) mod record;
pub(crate) mod replay;
pub(crate) mod schema;
pub(crate) mod view;

use std::collections::{BTreeMap, HashSet};
use std::path::PathBuf;
use std::time::Duration;

use peppy_runtime::describe::{InstanceInfo, OwnerInfo};
use peppy_runtime::wire::keys::split_entry_key;
use peppy_schema::{Identity, MessageFormat, QosProfile, SlotKind};

use crate::inspect::Observer;

/// The MCAP profile of peppy's recordings.
pub(crate) const PROFILE: &str = "peppy";
/// Every channel's message encoding.
pub(crate) const MESSAGE_ENCODING: &str = "json";
/// Every schema's encoding.
pub(crate) const SCHEMA_ENCODING: &str = "jsonschema";
/// The metadata record describing the recorded stack.
pub(crate) const STACK_METADATA: &str = "peppy.stack";

/// What a channel's metadata says of its messages: one producer instance's
/// topic in one format.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ChannelMeta {
    /// The topic name.
    pub(crate) topic: String,
    /// Whose topic it is (a node's or an interface's).
    pub(crate) owner: OwnerInfo,
    /// The producer's core node.
    pub(crate) core: String,
    /// The producer instance.
    pub(crate) instance: String,
    /// The producer's node, when it described itself.
    pub(crate) node: Option<Identity>,
    /// The format's canonical text.
    pub(crate) format: String,
    /// The format's fingerprint.
    pub(crate) fingerprint: u64,
    /// The topic's QoS profile, when the producer described it.
    pub(crate) qos: Option<QosProfile>,
}

/// Why a channel's metadata is not a peppy channel's.
#[derive(Debug, thiserror::Error)]
#[error("channel `{channel}`: {problem}")]
pub(crate) struct MetaError {
    /// The channel's topic string.
    pub(crate) channel: String,
    /// What is missing or wrong.
    pub(crate) problem: String,
}

impl ChannelMeta {
    /// The channel's topic string: `/<instance>/<topic>`, so each
    /// producer's messages are their own topic in a viewer.
    pub(crate) fn channel_topic(&self) -> String {
        format!("/{}/{}", self.instance, self.topic)
    }

    /// The channel's JSON Schema for `format`: its title (`owner:tag/topic`)
    /// and its text.
    pub(crate) fn schema(&self, format: &MessageFormat) -> (String, String) {
        let title = format!("{}:{}/{}", self.owner.name, self.owner.tag, self.topic);
        let text = schema::json_schema(format, &title, self.fingerprint).to_string();
        (title, text)
    }

    /// `kind/name:tag` of the owner.
    fn owner_text(&self) -> String {
        format!(
            "{}/{}:{}",
            self.owner.kind.as_str(),
            self.owner.name,
            self.owner.tag
        )
    }

    /// The metadata written on the channel.
    pub(crate) fn to_map(&self) -> BTreeMap<String, String> {
        let mut map = BTreeMap::from([
            ("peppy.topic".to_string(), self.topic.clone()),
            ("peppy.owner".to_string(), self.owner_text()),
            ("peppy.core".to_string(), self.core.clone()),
            ("peppy.instance".to_string(), self.instance.clone()),
            ("peppy.format".to_string(), self.format.clone()),
            (
                "peppy.fingerprint".to_string(),
                format!("{:016x}", self.fingerprint),
            ),
        ]);
        if let Some(qos) = self.qos {
            map.insert("peppy.qos".into(), qos.as_str().into());
        }
        if let Some(node) = &self.node {
            map.insert("peppy.node".into(), format!("{}:{}", node.name, node.tag));
        }
        map
    }

    /// Reads a channel's metadata back; `channel` names it in errors.
    pub(crate) fn from_map(
        channel: &str,
        map: &BTreeMap<String, String>,
    ) -> Result<ChannelMeta, MetaError> {
        let problem = |problem: String| MetaError {
            channel: channel.to_string(),
            problem,
        };
        let get = |key: &str| {
            map.get(key)
                .cloned()
                .ok_or_else(|| problem(format!("no `{key}` in its metadata")))
        };
        let segment = |key: &str| {
            let value = get(key)?;
            if peppy_runtime::wire::keys::is_segment(&value) {
                Ok(value)
            } else {
                Err(problem(format!("`{key}` is `{value}`, not a key segment")))
            }
        };
        let owner_text = get("peppy.owner")?;
        let owner = owner_text
            .split_once('/')
            .and_then(|(kind, id)| {
                let kind = match kind {
                    "node" => SlotKind::Node,
                    "interface" => SlotKind::Interface,
                    _ => return None,
                };
                let id = Identity::parse(id).filter(|id| {
                    peppy_runtime::wire::keys::is_segment(&id.name)
                        && peppy_runtime::wire::keys::is_segment(&id.tag)
                })?;
                Some(OwnerInfo {
                    kind,
                    name: id.name,
                    tag: id.tag,
                })
            })
            .ok_or_else(|| {
                problem(format!(
                    "`peppy.owner` is `{owner_text}`, not `node/NAME:TAG` or `interface/NAME:TAG`"
                ))
            })?;
        let fingerprint_text = get("peppy.fingerprint")?;
        let fingerprint = u64::from_str_radix(&fingerprint_text, 16).map_err(|_| {
            problem(format!(
                "`peppy.fingerprint` is `{fingerprint_text}`, not 16 hex digits"
            ))
        })?;
        let qos = match map.get("peppy.qos") {
            None => None,
            Some(q) => Some(
                QosProfile::parse(q)
                    .ok_or_else(|| problem(format!("`peppy.qos` is `{q}`, no QoS profile")))?,
            ),
        };
        let node = match map.get("peppy.node") {
            None => None,
            Some(n) => Some(
                Identity::parse(n)
                    .ok_or_else(|| problem(format!("`peppy.node` is `{n}`, not `NAME:TAG`")))?,
            ),
        };
        Ok(ChannelMeta {
            topic: segment("peppy.topic")?,
            owner,
            core: segment("peppy.core")?,
            instance: segment("peppy.instance")?,
            node,
            format: get("peppy.format")?,
            fingerprint,
            qos,
        })
    }
}

/// A topic sample as taken off the wire.
pub(crate) struct Sampled {
    /// Its key.
    pub(crate) key: String,
    /// The format fingerprint of its attachment (`None`: no valid one).
    pub(crate) fingerprint: Option<u64>,
    /// Its payload.
    pub(crate) payload: Vec<u8>,
    /// When it arrived, ns since the Unix epoch.
    pub(crate) log_time: u64,
    /// Its Zenoh timestamp, if it carries one (ns since the Unix epoch).
    pub(crate) publish_time: Option<u64>,
}

impl Sampled {
    /// Copies what a recording keeps of `sample`.
    pub(crate) fn of(sample: &zenoh::sample::Sample) -> Sampled {
        Sampled {
            key: sample.key_expr().as_str().to_string(),
            fingerprint: sample
                .attachment()
                .and_then(|a| peppy_runtime::wire::attachment::parse_topic(&a.to_bytes())),
            payload: sample.payload().to_bytes().into_owned(),
            log_time: peppy_runtime::clock::os_now_ns(),
            publish_time: sample.timestamp().map(|t| {
                let since = t
                    .get_time()
                    .to_system_time()
                    .duration_since(std::time::UNIX_EPOCH);
                since.map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
            }),
        }
    }
}

/// Subscribes to every topic of the observer's stack; `on_sample` runs in
/// Zenoh's callback, so it must not block.
pub(crate) async fn subscribe_topics(
    observer: &Observer,
    on_sample: impl Fn(zenoh::sample::Sample) + Send + Sync + 'static,
) -> Result<zenoh::pubsub::Subscriber<()>, crate::error::SetupError> {
    let selector = peppy_runtime::wire::keys::space_selector(
        &observer.reach.namespace,
        peppy_runtime::wire::keys::Space::Topic,
    );
    observer
        .session
        .declare_subscriber(selector.clone())
        .callback(on_sample)
        .await
        .map_err(|source| crate::error::SetupError::Subscribe { selector, source })
}

/// What the stack's instances said of themselves, and a new channel's
/// metadata and format learnt from it.
pub(crate) struct Learner {
    described: BTreeMap<String, InstanceInfo>,
    /// Instances already asked for their description after start.
    asked: HashSet<String>,
}

impl Learner {
    /// Starts from the descriptions gathered when the command joined.
    pub(crate) fn new(described: BTreeMap<String, InstanceInfo>) -> Learner {
        Learner {
            described,
            asked: HashSet::new(),
        }
    }

    /// A new channel's metadata and format: from the producer's description
    /// (asked for once if it started after the command), or its format
    /// queryable for a format it does not describe.
    pub(crate) async fn learn(
        &mut self,
        observer: &Observer,
        key: &str,
        fingerprint: u64,
    ) -> Option<(ChannelMeta, MessageFormat)> {
        let described = &mut self.described;
        let sender = split_entry_key(key)?;
        if !described.contains_key(sender.instance)
            && self.asked.insert(sender.instance.into())
            && let Some(info) = observer
                .describe_instance(sender.core, sender.instance)
                .await
        {
            described.insert(info.instance_id.clone(), info);
        }
        let emitted = described
            .get(sender.instance)
            .and_then(|i| i.emits.iter().find(|t| t.key == key));
        let text = match emitted {
            Some(t) if t.format.fingerprint == fingerprint => Some(t.format.canonical.clone()),
            _ => {
                peppy_runtime::describe::ask_format(
                    &observer.session,
                    &observer.reach.namespace,
                    fingerprint,
                    sender.instance,
                    Duration::from_secs(1),
                )
                .await
            }
        }?;
        let format = MessageFormat::from_canonical(&text).ok().filter(|f| {
            f.fingerprint() == fingerprint || (fingerprint == 0 && f.fields.is_empty())
        })?;
        let owner = peppy_runtime::describe::OwnerInfo {
            kind: match sender.kind {
                "node" => peppy_schema::SlotKind::Node,
                _ => peppy_schema::SlotKind::Interface,
            },
            name: sender.name.into(),
            tag: sender.tag.into(),
        };
        Some((
            ChannelMeta {
                topic: sender.entry.into(),
                owner,
                core: sender.core.into(),
                instance: sender.instance.into(),
                node: described.get(sender.instance).map(|i| i.node.clone()),
                format: text,
                fingerprint,
                qos: emitted.map(|t| t.qos),
            },
            format,
        ))
    }
}

/// Why a recording could not be made or replayed.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// `record -o FILE` names a file that exists (and no `--force`).
    #[error("{} exists; choose another file with -o, or overwrite it with --force", path.display())]
    Exists {
        /// The file.
        path: PathBuf,
    },
    /// The recording cannot be created.
    #[error("cannot create {}: {source}", path.display())]
    Create {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Writing the recording failed (a full disk, a removed file).
    #[error("writing {} failed: {}", path.display(), mcap_reason(source))]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: mcap::McapError,
    },
    /// The writer thread could not start.
    #[error("cannot start the recording's writer: {source}")]
    Thread {
        /// Why.
        source: std::io::Error,
    },
    /// The writer thread panicked (a bug): the file may lack its summary.
    #[error("the writer of {} stopped unexpectedly; `mcap recover` can read what it wrote", path.display())]
    WriterPanicked {
        /// The file.
        path: PathBuf,
    },
    /// The file to replay cannot be read.
    #[error("cannot read {}: {source}", path.display())]
    Open {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not an MCAP file.
    #[error("{} is not an MCAP file (it does not start with MCAP's magic bytes)", path.display())]
    NotMcap {
        /// The file.
        path: PathBuf,
    },
    /// The file is MCAP but cannot be read as one.
    #[error("{} is not a readable MCAP file: {}", path.display(), mcap_reason(source))]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// What the MCAP reader said.
        source: mcap::McapError,
    },
    /// A channel of the file is not one `record` writes.
    #[error("{}: {problem}; peppy replays the JSON channels `peppy-launch record` writes", path.display())]
    NotPeppy {
        /// The file.
        path: PathBuf,
        /// What is wrong with which channel.
        problem: String,
    },
    /// The file holds no message to replay (in the `--start`/`--end`
    /// window, of the topics named).
    #[error("{} holds no message to replay{}", path.display(), if *narrowed { " in the chosen window and topics" } else { "" })]
    Empty {
        /// The file.
        path: PathBuf,
        /// Whether topics or a window narrowed it.
        narrowed: bool,
    },
    /// Consumers in the stack read a recorded topic in another format.
    #[error("the stack reads recorded topics in other formats:\n{}", mismatches.join("\n"))]
    FormatMismatch {
        /// One line per consumer and channel.
        mismatches: Vec<String>,
    },
    /// `replay --rate` is out of range.
    #[error("--rate {rate} is out of range: give a speed factor from 0.001 to 1000")]
    Rate {
        /// The rate given.
        rate: f64,
    },
    /// Messages of the recording did not fit their own channel's format
    /// (the rest was replayed).
    #[error(
        "{messages} messages of the recording do not fit their channel's format; the rest was replayed"
    )]
    Unfit {
        /// How many were skipped.
        messages: u64,
    },
    /// `--as` is not `OLD=NEW` with two instance ids.
    #[error("--as `{arg}`: expected OLD=NEW, two instance ids")]
    BadRename {
        /// The argument.
        arg: String,
    },
    /// The recording ended in the middle (not at its end).
    #[error("{} is damaged after {replayed} messages: {}", path.display(), mcap_reason(source))]
    Damaged {
        /// The file.
        path: PathBuf,
        /// Messages replayed before the damage.
        replayed: u64,
        /// What the MCAP reader said.
        source: mcap::McapError,
    },
}

/// What an MCAP error says, with the system's own reason when it is an I/O
/// error: the crate's message for those ("I/O error from writing, or
/// reading a compression stream") does not say that the disk is full.
fn mcap_reason(e: &mcap::McapError) -> String {
    match e {
        mcap::McapError::Io(io) => io.to_string(),
        other => other.to_string(),
    }
}

/// Which samples to take: `NAME` matches a topic name, `INSTANCE/NAME` a
/// producer's topic; `*` and `?` are wildcards in either.
#[derive(Debug, Clone, Default)]
pub(crate) struct Patterns(Vec<String>);

impl Patterns {
    /// The patterns given on the command line.
    pub(crate) fn new(patterns: Vec<String>) -> Patterns {
        Patterns(patterns)
    }
}

impl Patterns {
    /// Whether `instance`'s `topic` is taken (every topic when no pattern
    /// was given).
    pub(crate) fn takes(&self, instance: &str, topic: &str) -> bool {
        self.0.is_empty()
            || self.0.iter().any(|p| match p.split_once('/') {
                Some((i, t)) => glob(i, instance) && glob(t, topic),
                None => glob(p, topic),
            })
    }
}

/// Whether `text` matches `pattern`, where `*` matches any run of
/// characters and `?` any one.
fn glob(pattern: &str, text: &str) -> bool {
    let (p, t): (Vec<char>, Vec<char>) = (pattern.chars().collect(), text.chars().collect());
    let (mut pi, mut ti) = (0, 0);
    // Where the last `*` was, and the text position it was tried at.
    let mut star: Option<(usize, usize)> = None;
    while ti < t.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == t[ti]) {
            pi += 1;
            ti += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some((pi, ti));
            pi += 1;
        } else if let Some((sp, st)) = star {
            pi = sp + 1;
            ti = st + 1;
            star = Some((sp, st + 1));
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta() -> ChannelMeta {
        ChannelMeta {
            topic: "video_stream".into(),
            owner: OwnerInfo {
                kind: SlotKind::Interface,
                name: "depth_camera".into(),
                tag: "v1".into(),
            },
            core: "core_1".into(),
            instance: "rs_left".into(),
            node: Some(Identity::new("realsense_d405", "v1")),
            format: "{width:u32}".into(),
            fingerprint: 0x0123_4567_89ab_cdef,
            qos: Some(QosProfile::SensorData),
        }
    }

    #[test]
    fn channel_metadata_reads_back() {
        let m = meta();
        let map = m.to_map();
        assert_eq!(map["peppy.owner"], "interface/depth_camera:v1");
        assert_eq!(map["peppy.fingerprint"], "0123456789abcdef");
        assert_eq!(
            ChannelMeta::from_map("/rs_left/video_stream", &map).unwrap(),
            m
        );
        assert_eq!(m.channel_topic(), "/rs_left/video_stream");
    }

    #[test]
    fn bad_channel_metadata_is_named() {
        for (key, value, says) in [
            ("peppy.owner", "camera", "not `node/NAME:TAG`"),
            ("peppy.fingerprint", "xyz", "not 16 hex digits"),
            ("peppy.instance", "a/b", "not a key segment"),
            ("peppy.qos", "fast", "no QoS profile"),
        ] {
            let mut map = meta().to_map();
            map.insert(key.into(), value.into());
            let e = ChannelMeta::from_map("/x/y", &map).unwrap_err().to_string();
            assert!(e.starts_with("channel `/x/y`: ") && e.contains(says), "{e}");
        }
        let mut map = meta().to_map();
        map.remove("peppy.format");
        let e = ChannelMeta::from_map("/x/y", &map).unwrap_err().to_string();
        assert!(e.contains("no `peppy.format`"), "{e}");
    }

    #[test]
    fn patterns_take_topics_and_producers() {
        let all = Patterns::default();
        assert!(all.takes("rs_left", "video_stream"));
        let some = Patterns::new(vec!["video_*".into(), "arm/joint_states".into()]);
        assert!(some.takes("rs_left", "video_stream"));
        assert!(some.takes("arm", "joint_states"));
        assert!(!some.takes("leader", "joint_states"));
        let producers = Patterns::new(vec!["rs_*/*".into()]);
        assert!(producers.takes("rs_right", "video_stream"));
        assert!(!producers.takes("zed_overhead", "video_stream"));
    }

    #[test]
    fn globs() {
        for (p, t, ok) in [
            ("*", "", true),
            ("a*c", "abbbc", true),
            ("a*c", "abbb", false),
            ("a?c", "abc", true),
            ("a?c", "ac", false),
            ("*_stream", "video_stream", true),
            ("*a*b", "xaxxb", true),
            ("exact", "exact", true),
            ("exact", "exactly", false),
        ] {
            assert_eq!(glob(p, t), ok, "{p} ~ {t}");
        }
    }
}
