//! `peppy-launch replay FILE`: a recording's messages published into a
//! running stack as their recorded producers (or renamed with `--as`), at
//! the recorded pace (`--rate`), once or `--loop`ed, within `--start` and
//! `--end`; with `--clock`, the stack's sim time follows the recording.
//!
//! Nothing is published before every channel has been checked: the file is
//! a recording `record` wrote (JSON with peppy's metadata), its formats
//! read back to their fingerprints, and every consumer in the stack that
//! would receive a channel reads it in the recorded format.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use peppy_runtime::clock::ClockSource;
use peppy_runtime::describe::InstanceInfo;
use peppy_runtime::wire::attachment;
use peppy_runtime::wire::keys::{Channel as KeyChannel, clock_tick_key, entry_key, liveliness_key};
use peppy_schema::{MessageFormat, QosProfile};
use tokio::time::Instant;

use super::{ChannelMeta, MESSAGE_ENCODING, Patterns, RecordingError, SCHEMA_ENCODING};
use crate::cli::ReplayArgs;
use crate::error::{InspectError, Result, SetupError};
use crate::inspect::dynamic::{self, JsonForm};
use crate::inspect::{Observer, interrupted};

/// How often `--clock` publishes the recording's time between messages
/// (a launch's wall tick has the same period).
const CLOCK_PERIOD: Duration = peppy_runtime::clock::WALL_TICK_PERIOD;

/// One channel of the file, checked and ready to publish.
struct Replayed {
    meta: ChannelMeta,
    format: MessageFormat,
    /// Whether the topics named take it.
    taken: bool,
}

/// The file, mapped, and what its channels are.
pub(crate) struct Recording {
    path: PathBuf,
    map: memmap2::Mmap,
    channels: BTreeMap<u16, Replayed>,
    /// First and last log time of the whole file.
    span: Option<(u64, u64)>,
    /// The file has no summary (its recorder was stopped hard): it ends
    /// inside its last chunk, which is expected, not damage.
    truncated: bool,
}

/// How the file's messages are read: chunk checksums checked, so a damaged
/// chunk is an error rather than wrong messages.
fn messages(map: &[u8]) -> mcap::McapResult<mcap::MessageStream<'_>> {
    mcap::MessageStream::new_with_options(map, mcap::read::Options::ValidateChunkCrcs.into())
}

impl Recording {
    /// Opens and checks `path`: an MCAP file whose every channel is a
    /// peppy channel. A file without a summary (a recorder that was
    /// killed) is read through to find its channels.
    pub(crate) fn open(
        path: &Path,
        renames: &BTreeMap<String, String>,
        patterns: &Patterns,
    ) -> std::result::Result<Recording, RecordingError> {
        let file = std::fs::File::open(path).map_err(|source| RecordingError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        // SAFETY: the map is only read, and nothing in this process writes
        // the file. Another process truncating it meanwhile (`record
        // --force` onto the file being replayed) would make reads past the
        // new end fault: replaying a file while it is rewritten is not
        // supported, as with any memory-mapped reader.
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|source| RecordingError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        if !map.starts_with(mcap::MAGIC) {
            return Err(RecordingError::NotMcap {
                path: path.to_path_buf(),
            });
        }
        let unreadable = |source| RecordingError::Unreadable {
            path: path.to_path_buf(),
            source,
        };
        let mut truncated = false;
        let (channels, span) = match mcap::Summary::read(&map) {
            // A summary with statistics (as `record` writes) says it all.
            Ok(Some(summary)) if summary.stats.is_some() => {
                let span = summary
                    .stats
                    .as_ref()
                    .filter(|s| s.message_count > 0)
                    .map(|s| (s.message_start_time, s.message_end_time));
                let channels: Vec<Arc<mcap::Channel<'_>>> =
                    summary.channels.values().cloned().collect();
                (read_channels(path, &channels, renames, patterns)?, span)
            }
            // No summary (a recording whose recorder was stopped hard), or
            // none with statistics: every message is read once to find the
            // channels and the span.
            Ok(_) | Err(_) => {
                truncated = true;
                let mut seen: BTreeMap<u16, Arc<mcap::Channel<'_>>> = BTreeMap::new();
                let mut span: Option<(u64, u64)> = None;
                for message in messages(&map).map_err(unreadable)? {
                    // A file cut short ends at its last whole chunk; one
                    // that is damaged before any message is no recording.
                    let message = match message {
                        Ok(m) => m,
                        Err(e) if seen.is_empty() => return Err(unreadable(e)),
                        Err(_) => break,
                    };
                    seen.entry(message.channel.id)
                        .or_insert_with(|| message.channel.clone());
                    let t = message.log_time;
                    span = Some(span.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
                }
                let channels: Vec<_> = seen.into_values().collect();
                (read_channels(path, &channels, renames, patterns)?, span)
            }
        };
        Ok(Recording {
            path: path.to_path_buf(),
            map,
            channels,
            span,
            truncated,
        })
    }
}

/// Checks every channel and reads its metadata (renamed by `--as`).
fn read_channels(
    path: &Path,
    channels: &[Arc<mcap::Channel<'_>>],
    renames: &BTreeMap<String, String>,
    patterns: &Patterns,
) -> std::result::Result<BTreeMap<u16, Replayed>, RecordingError> {
    let not_peppy = |problem: String| RecordingError::NotPeppy {
        path: path.to_path_buf(),
        problem,
    };
    let mut out = BTreeMap::new();
    for channel in channels {
        let topic = &channel.topic;
        if channel.message_encoding != MESSAGE_ENCODING {
            return Err(not_peppy(format!(
                "channel `{topic}` is encoded as `{}`",
                channel.message_encoding
            )));
        }
        if let Some(schema) = &channel.schema
            && schema.encoding != SCHEMA_ENCODING
        {
            return Err(not_peppy(format!(
                "channel `{topic}` has a `{}` schema",
                schema.encoding
            )));
        }
        let mut meta = ChannelMeta::from_map(topic, &channel.metadata)
            .map_err(|e| not_peppy(e.to_string()))?;
        let format = MessageFormat::from_canonical(&meta.format)
            .map_err(|e| not_peppy(format!("channel `{topic}`: its format does not read: {e}")))?;
        let fingerprint = if format.fields.is_empty() {
            0
        } else {
            format.fingerprint()
        };
        if fingerprint != meta.fingerprint {
            return Err(not_peppy(format!(
                "channel `{topic}`: its format's fingerprint is {fingerprint:016x}, not the {:016x} it names",
                meta.fingerprint
            )));
        }
        let taken = patterns.takes(&meta.instance, &meta.topic);
        if let Some(new) = renames.get(&meta.instance) {
            meta.instance = new.clone();
        }
        out.insert(
            channel.id,
            Replayed {
                meta,
                format,
                taken,
            },
        );
    }
    Ok(out)
}

/// `--as OLD=NEW`, each checked.
fn renames(args: &[String]) -> std::result::Result<BTreeMap<String, String>, RecordingError> {
    args.iter()
        .map(|arg| {
            arg.split_once('=')
                .filter(|(old, new)| {
                    peppy_runtime::wire::keys::is_segment(old)
                        && peppy_runtime::wire::keys::is_segment(new)
                })
                .map(|(old, new)| (old.to_string(), new.to_string()))
                .ok_or_else(|| RecordingError::BadRename { arg: arg.clone() })
        })
        .collect()
}

/// One line per consumer that reads a channel in another format.
type Mismatches = Vec<String>;

/// Every consumer entry in the stack that would receive `meta`'s messages
/// and reads them in another format, one line each.
fn mismatches(meta: &ChannelMeta, all: &BTreeMap<String, InstanceInfo>) -> Vec<String> {
    let mut out = Vec::new();
    for info in all.values() {
        for consumed in &info.consumes {
            let same_topic = consumed.name == meta.topic
                && consumed.owner.as_ref().is_none_or(|o| {
                    o.kind == meta.owner.kind
                        && o.name == meta.owner.name
                        && o.tag == meta.owner.tag
                });
            // A node slot on an interface's key keeps only its node's
            // instances: a recording that does not name its producer's node
            // is checked against it too.
            let kept = consumed.filter.accepts(&meta.instance)
                && consumed
                    .members_of
                    .as_ref()
                    .is_none_or(|m| meta.node.as_ref().is_none_or(|n| n == m));
            if !same_topic || !kept {
                continue;
            }
            if consumed.format.fingerprint != meta.fingerprint {
                let slot = match &consumed.slot {
                    Some(s) => format!("{}.{s}", info.instance_id),
                    None => format!("{} (external topic)", info.instance_id),
                };
                out.push(format!(
                    "  {slot} reads `{}` as {} ({:016x}); {} recorded it as {} ({:016x})",
                    meta.topic,
                    consumed.format.canonical,
                    consumed.format.fingerprint,
                    meta.channel_topic(),
                    meta.format,
                    meta.fingerprint
                ));
            }
        }
    }
    out
}

/// `replay`.
pub(crate) async fn run(args: ReplayArgs) -> Result {
    // Below a thousandth a day of recording would take years, and the due
    // times would overflow.
    if !(args.rate.is_finite() && (0.001..=1000.0).contains(&args.rate)) {
        return Err(RecordingError::Rate { rate: args.rate }.into());
    }
    let renames = renames(&args.renames)?;
    let patterns = Patterns::new(args.topics.clone());
    let recording = Recording::open(&args.file, &renames, &patterns)?;
    let Some((first, last)) = recording.span else {
        return Err(RecordingError::Empty {
            path: recording.path.clone(),
            narrowed: false,
        }
        .into());
    };
    let from = first.saturating_add(nanos(args.start));
    let to = args
        .end
        .map_or(last, |end| first.saturating_add(nanos(end)).min(last));
    let taken: Vec<&Replayed> = recording.channels.values().filter(|c| c.taken).collect();
    if taken.is_empty() || from > to {
        return Err(RecordingError::Empty {
            path: recording.path.clone(),
            narrowed: true,
        }
        .into());
    }

    let observer = Observer::open(&args.stack).await?;
    let all = observer.describe_all().await?;
    // A producer whose format changed mid-recording has a channel per
    // format: the stack must read one of them, and the others are left out.
    let mut refused: BTreeMap<(&str, &str), Vec<(u16, Mismatches)>> = BTreeMap::new();
    for (id, c) in recording.channels.iter().filter(|(_, c)| c.taken) {
        refused
            .entry((c.meta.instance.as_str(), c.meta.topic.as_str()))
            .or_default()
            .push((*id, mismatches(&c.meta, &all)));
    }
    let mut problems = Vec::new();
    let mut skipped = BTreeSet::new();
    for formats in refused.values() {
        if formats.iter().all(|(_, m)| !m.is_empty()) {
            problems.extend(formats.iter().flat_map(|(_, m)| m.iter().cloned()));
        } else {
            for (id, m) in formats.iter().filter(|(_, m)| !m.is_empty()) {
                skipped.insert(*id);
                eprintln!(
                    "note: leaving out {} in its format {:016x}: the stack reads another format of it, which is replayed\n{}",
                    recording.channels[id].meta.channel_topic(),
                    recording.channels[id].meta.fingerprint,
                    m.join("\n")
                );
            }
        }
    }
    if !problems.is_empty() {
        return Err(RecordingError::FormatMismatch {
            mismatches: problems,
        }
        .into());
    }
    let live: BTreeSet<&str> = taken
        .iter()
        .filter(|c| {
            all.get(&c.meta.instance).is_some_and(|i| {
                i.emits
                    .iter()
                    .any(|t| t.name == c.meta.topic && t.owner == c.meta.owner)
            })
        })
        .map(|c| c.meta.instance.as_str())
        .collect();
    for instance in &live {
        eprintln!(
            "note: `{instance}` is running in the stack and publishes what it replays too; its consumers get both (rename the replayed producer with --as {instance}=OTHER)"
        );
    }

    let namespace = observer.reach.namespace.clone();
    let mut publishers = HashMap::new();
    // A node slot on an interface's key keeps only the instances of its
    // node that are alive: each replayed producer whose node is known holds
    // the liveliness token its node would.
    let mut tokens = Vec::new();
    let mut alive = BTreeSet::new();
    for (id, c) in recording
        .channels
        .iter()
        .filter(|(id, c)| c.taken && !skipped.contains(*id))
    {
        let m = &c.meta;
        if let Some(node) = &m.node
            && alive.insert((m.core.as_str(), m.instance.as_str()))
            && !live.contains(m.instance.as_str())
        {
            let token = observer
                .session
                .liveliness()
                .declare_token(liveliness_key(
                    &namespace,
                    &m.core,
                    &m.instance,
                    &node.name,
                    &node.tag,
                ))
                .await
                .map_err(|e| SetupError::Publisher(e.into()))?;
            tokens.push(token);
        }
        let key = entry_key(
            &namespace,
            KeyChannel::Topic,
            &m.owner.as_owner(),
            &m.topic,
            &m.core,
            &m.instance,
        );
        let publisher = peppy_runtime::tool::publisher(
            &observer.session,
            key,
            m.qos.unwrap_or(QosProfile::Standard),
        )
        .await
        .map_err(SetupError::Publisher)?;
        publishers.insert(*id, publisher);
    }
    wait_for_consumers(&recording, &publishers).await;
    let clock = if args.clock {
        Some(
            observer
                .session
                .declare_publisher(clock_tick_key(&namespace, ClockSource::Sim))
                .await
                .map_err(|e| SetupError::Publisher(e.into()))?,
        )
    } else {
        None
    };

    eprintln!(
        "replaying {} ({} channels, {:.1} s{}) into {}",
        recording.path.display(),
        taken.len(),
        (to - from) as f64 / 1e9,
        if args.rate == 1.0 {
            String::new()
        } else {
            format!(" at x{}", args.rate)
        },
        observer.reach.what
    );
    let stop = interrupted();
    let started = std::time::Instant::now();
    let mut totals = Totals::default();
    loop {
        let pass = play(
            &recording,
            &publishers,
            clock.as_ref(),
            (from, to),
            args.rate,
            &mut totals,
        );
        let ended = tokio::select! {
            r = pass => r?,
            () = stop.cancelled() => Ended::Interrupted,
        };
        if ended == Ended::Interrupted || !args.r#loop {
            break;
        }
    }
    drop(tokens);
    eprintln!(
        "replayed {} messages in {:.1} s",
        totals.published,
        started.elapsed().as_secs_f64()
    );
    let unfit: u64 = totals.unencodable.values().sum();
    if unfit > 0 {
        for (channel, n) in &totals.unencodable {
            eprintln!(
                "warning: {n} messages of {channel} were skipped: they do not fit its format"
            );
        }
        return Err(RecordingError::Unfit { messages: unfit }.into());
    }
    if totals.published == 0 && !stop.is_cancelled() {
        return Err(RecordingError::Empty {
            path: recording.path.clone(),
            narrowed: true,
        }
        .into());
    }
    Ok(())
}

/// Waits (2 s at most, for all of them together) until every channel's
/// key has a subscriber, so the first messages are not published before
/// the stack's routes reach this session; names the channels nobody
/// consumes.
async fn wait_for_consumers(
    recording: &Recording,
    publishers: &HashMap<u16, zenoh::pubsub::Publisher<'static>>,
) {
    let deadline = Instant::now() + Duration::from_secs(2);
    let mut waiting: Vec<u16> = publishers.keys().copied().collect();
    while !waiting.is_empty() && Instant::now() < deadline {
        let mut still = Vec::new();
        for id in waiting {
            let matched = publishers[&id]
                .matching_status()
                .await
                .is_ok_and(|s| s.matching());
            if !matched {
                still.push(id);
            }
        }
        waiting = still;
        if !waiting.is_empty() {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
    if !waiting.is_empty() {
        let names: Vec<String> = waiting
            .iter()
            .map(|id| recording.channels[id].meta.channel_topic())
            .collect();
        eprintln!(
            "note: nothing in the stack consumes {} yet; publishing anyway",
            names.join(", ")
        );
    }
}

fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

/// What replay did.
#[derive(Default)]
struct Totals {
    published: u64,
    unencodable: BTreeMap<String, u64>,
}

/// How one pass through the file ended.
#[derive(Debug, PartialEq)]
enum Ended {
    /// At the file's end (or `--end`).
    Done,
    /// By Ctrl-C.
    Interrupted,
}

/// One pass through the file's window, at its pace.
async fn play(
    recording: &Recording,
    publishers: &HashMap<u16, zenoh::pubsub::Publisher<'static>>,
    clock: Option<&zenoh::pubsub::Publisher<'static>>,
    (from, to): (u64, u64),
    rate: f64,
    totals: &mut Totals,
) -> Result<Ended> {
    let unreadable = |source| RecordingError::Unreadable {
        path: recording.path.clone(),
        source,
    };
    let began = Instant::now();
    // Due times come from the recording's log times, not from how long
    // publishing took, so a slow put does not shift every later message.
    let due = |t: u64| began + Duration::from_secs_f64(t.saturating_sub(from) as f64 / 1e9 / rate);
    // The sim clock never goes back: each tick is later than the last.
    let mut next_tick = began + CLOCK_PERIOD;
    let mut last_tick: Option<u64> = None;
    for message in messages(&recording.map).map_err(unreadable)? {
        let message = match message {
            Ok(m) => m,
            // A recording cut short ends inside its last chunk: what
            // precedes it is whole.
            Err(_) if recording.truncated => {
                eprintln!(
                    "note: {} ends early (its recorder was stopped hard); replayed up to its last whole chunk",
                    recording.path.display()
                );
                break;
            }
            Err(source) => {
                return Err(RecordingError::Damaged {
                    path: recording.path.clone(),
                    replayed: totals.published,
                    source,
                }
                .into());
            }
        };
        let t = message.log_time;
        if t < from || t > to {
            continue;
        }
        let Some(publisher) = publishers.get(&message.channel.id) else {
            continue;
        };
        let Some(channel) = recording.channels.get(&message.channel.id) else {
            continue;
        };
        let at = due(t);
        // Between messages, the sim clock keeps moving at its period.
        if let Some(clock) = clock {
            while next_tick < at {
                tokio::time::sleep_until(next_tick).await;
                let played = next_tick.duration_since(began).as_secs_f64() * rate;
                let now = from + (played * 1e9) as u64;
                if last_tick.is_none_or(|last| now > last) {
                    put_time(clock, now).await?;
                    last_tick = Some(now);
                }
                next_tick += CLOCK_PERIOD;
            }
        }
        tokio::time::sleep_until(at).await;
        let payload = serde_json::from_slice(&message.data)
            .map_err(|e| e.to_string())
            .and_then(|json| {
                dynamic::encode_as(&channel.format, &json, JsonForm::Recording)
                    .map_err(|e| e.to_string())
            });
        let payload = match payload {
            Ok(p) => p,
            Err(reason) => {
                let topic = channel.meta.channel_topic();
                let n = totals.unencodable.entry(topic.clone()).or_insert(0);
                if *n == 0 {
                    eprintln!(
                        "note: message {} of {topic} does not fit its format: {reason}",
                        message.sequence
                    );
                }
                *n += 1;
                continue;
            }
        };
        if let Some(clock) = clock
            && last_tick.is_none_or(|last| t > last)
        {
            put_time(clock, t).await?;
            last_tick = Some(t);
        }
        publisher
            .put(payload)
            .attachment(attachment::topic(channel.meta.fingerprint))
            .await
            .map_err(InspectError::Publish)?;
        totals.published += 1;
    }
    // Let the last messages leave before the session closes.
    tokio::time::sleep(Duration::from_millis(100)).await;
    Ok(Ended::Done)
}

async fn put_time(clock: &zenoh::pubsub::Publisher<'static>, t: u64) -> Result {
    clock
        .put(t.to_le_bytes().to_vec())
        .await
        .map_err(InspectError::Publish)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renames_are_two_instance_ids() {
        let ok = renames(&["rs_left=cam_a".into()]).unwrap();
        assert_eq!(ok["rs_left"], "cam_a");
        for bad in ["rs_left", "=x", "a=b/c", "a=*"] {
            assert!(renames(&[bad.into()]).is_err(), "{bad}");
        }
    }
}
