//! `peppy-launch record`: every topic of a running stack (or those named)
//! into one MCAP file, until Ctrl-C, `--duration` or `--max-size`.
//!
//! Three stages, so that nothing waits on anything slower than itself:
//!
//! - Zenoh's callback copies each sample into an unbounded queue and
//!   returns (a recorder never holds a publisher back; a backlog beyond
//!   [`MAX_BACKLOG`] bytes is dropped and counted, never silently);
//! - the command's task reads the queue, learns each new producer's format
//!   and QoS from its description (a producer that starts later, or changes
//!   format, gets a channel of its own), and hands messages on;
//! - a writer thread decodes each message with its format, writes it as
//!   JSON and compresses chunks, closing a chunk at least every
//!   [`CHUNK_PERIOD`] so that a killed recorder leaves a file readable up to
//!   its last second.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, IsTerminal, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use peppy_runtime::wire::keys::split_entry_key;
use peppy_schema::MessageFormat;

use super::{
    ChannelMeta, Learner, MESSAGE_ENCODING, PROFILE, Patterns, RecordingError, SCHEMA_ENCODING,
    STACK_METADATA, Sampled, subscribe_topics,
};
use crate::cli::RecordArgs;
use crate::error::Result;
use crate::inspect::{Observer, Role, dynamic, interrupted};

/// Bytes of samples waiting for the writer beyond which new ones are
/// dropped (and counted): a recorder that cannot keep up must not take the
/// machine's memory with it.
const MAX_BACKLOG: u64 = 1 << 30;
/// The longest a chunk stays open: what a `kill -9` can lose at most.
const CHUNK_PERIOD: Duration = Duration::from_secs(1);
/// How often the progress line is redrawn on a terminal (and `--max-size`
/// checked).
const PROGRESS_PERIOD: Duration = Duration::from_millis(500);
/// How often a progress line is printed when stderr is not a terminal.
const LOG_PERIOD: Duration = Duration::from_secs(5);

/// What the command's task tells the writer thread.
enum Op {
    Channel {
        id: u16,
        meta: ChannelMeta,
        format: MessageFormat,
    },
    Message {
        channel: u16,
        log_time: u64,
        publish_time: u64,
        payload: Vec<u8>,
    },
}

/// One channel's counts, shared with the writer thread.
#[derive(Debug, Default, Clone)]
struct ChannelCount {
    topic: String,
    messages: u64,
    bytes: u64,
    undecodable: u64,
}

/// What the writer has done so far.
#[derive(Debug, Default)]
struct Progress {
    channels: std::sync::Mutex<BTreeMap<u16, ChannelCount>>,
    /// Bytes in the file.
    written: AtomicU64,
    /// Bytes of samples received and not yet written (or dropped).
    backlog: AtomicU64,
}

impl Progress {
    fn snapshot(&self) -> BTreeMap<u16, ChannelCount> {
        self.channels
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    fn messages(&self) -> u64 {
        self.snapshot().values().map(|c| c.messages).sum()
    }
}

/// `record`.
pub(crate) async fn run(args: RecordArgs) -> Result {
    let patterns = Patterns::new(args.topics.clone());
    // A file that may not be written is said before the stack is looked
    // for; a default name needs the stack's namespace first.
    let mut file = match &args.output {
        Some(path) => Some((path.clone(), open_output(path, args.force)?)),
        None => None,
    };
    let reached = async {
        let observer = Observer::open_as(&args.stack, Role::Recorder).await?;
        let described = observer.describe_all().await?;
        Ok::<_, crate::error::LaunchError>((observer, described))
    }
    .await;
    let (observer, described) = match reached {
        Ok(reached) => reached,
        Err(e) => {
            // Nothing was recorded: the empty file just made goes too.
            if let Some((path, _)) = file.take() {
                let _ = std::fs::remove_file(path);
            }
            return Err(e);
        }
    };
    let mut learner = Learner::new(described);
    let (path, file) = match file.take() {
        Some(opened) => opened,
        None => {
            let path = default_path(&observer.reach.namespace);
            let file = open_output(&path, args.force)?;
            (path, file)
        }
    };
    let progress = Arc::new(Progress::default());
    let stack = BTreeMap::from([
        ("namespace".to_string(), observer.reach.namespace.clone()),
        ("stack".to_string(), observer.reach.what.clone()),
        (
            "started_at_ns".to_string(),
            peppy_runtime::clock::os_now_ns().to_string(),
        ),
    ]);
    let (ops, writer) = spawn_writer(file, &path, stack, progress.clone())?;

    let (tx, rx) = flume::unbounded::<Sampled>();
    let overflowed = Arc::new(AtomicU64::new(0));
    let subscriber = {
        let (progress, overflowed) = (progress.clone(), overflowed.clone());
        subscribe_topics(&observer, move |sample| {
            let size = sample.payload().len() as u64;
            let backlog = &progress.backlog;
            if backlog.fetch_add(size, Ordering::Relaxed) + size > MAX_BACKLOG {
                backlog.fetch_sub(size, Ordering::Relaxed);
                overflowed.fetch_add(1, Ordering::Relaxed);
                return;
            }
            let _ = tx.send(Sampled::of(&sample));
        })
        .await?
    };

    eprintln!(
        "recording {} into {} (Ctrl-C ends it{})",
        observer.reach.what,
        path.display(),
        if std::io::stdin().is_terminal() {
            "; Enter shows each topic's rate"
        } else {
            ""
        }
    );
    let mut channels = Channels::default();
    let started = Instant::now();
    let deadline = args.duration.map(|d| tokio::time::Instant::now() + d);
    let stop = interrupted();
    let terminal = std::io::stderr().is_terminal();
    let mut tick = tokio::time::interval(PROGRESS_PERIOD);
    tick.tick().await;
    let mut logged = Instant::now();
    let mut enter = enter_presses();
    let mut rates = Rates::new(&progress);
    let why = loop {
        tokio::select! {
            sample = rx.recv_async() => {
                let Ok(sample) = sample else { break "the stack's session closed" };
                let size = sample.payload.len() as u64;
                // Learning a new producer asks the stack (up to --wait):
                // Ctrl-C and the limits do not wait behind it.
                let taken = tokio::select! {
                    op = channels.take(sample, &patterns, &observer, &mut learner, &ops) => op,
                    () = until(deadline) => break "--duration is over",
                    () = stop.cancelled() => break "interrupted",
                };
                let Some(op) = taken else {
                    progress.backlog.fetch_sub(size, Ordering::Relaxed);
                    continue;
                };
                if ops.send(op).is_err() {
                    break "the writer stopped";
                }
            }
            _ = tick.tick() => {
                let line = progress_line(started.elapsed(), &progress, channels.count());
                if terminal {
                    eprint!("\r\x1b[K{line}");
                } else if logged.elapsed() >= LOG_PERIOD {
                    eprintln!("{line}");
                    logged = Instant::now();
                }
                if args.max_size.is_some_and(|max| progress.written.load(Ordering::Relaxed) >= max) {
                    break "the file reached --max-size";
                }
                if writer.is_finished() {
                    break "the writer stopped";
                }
            }
            Some(()) = enter.recv() => {
                if terminal {
                    eprint!("\r\x1b[K");
                }
                eprint!("{}", rates.table(&progress));
            }
            () = until(deadline) => break "--duration is over",
            () = stop.cancelled() => break "interrupted",
        }
    };
    // What was received before the end is recorded: the queue is drained
    // once the subscription is gone.
    drop(subscriber);
    while let Ok(sample) = rx.try_recv() {
        if let Some(op) = channels
            .take(sample, &patterns, &observer, &mut learner, &ops)
            .await
            && ops.send(op).is_err()
        {
            break;
        }
    }
    drop(ops);
    if terminal {
        eprint!("\r\x1b[K");
    }
    let outcome = writer
        .join()
        .unwrap_or_else(|_| Err(RecordingError::WriterPanicked { path: path.clone() }));
    let written = progress.written.load(Ordering::Relaxed);
    let counts = progress.snapshot();
    eprint!("{}", summary_table(&counts));
    // After a failed write the writer was handed messages the file never
    // got: the count is what was taken, not what was recorded.
    let (verb, whole) = if outcome.is_ok() {
        ("recorded", "")
    } else {
        ("took", "; the file holds those written before the failure")
    };
    eprintln!(
        "{verb} {} messages on {} channels in {:.1} s into {} ({}{whole}); stopped: {why}",
        counts.values().map(|c| c.messages).sum::<u64>(),
        counts.len(),
        started.elapsed().as_secs_f64(),
        path.display(),
        human_bytes(written),
    );
    let lost = overflowed.load(Ordering::Relaxed);
    if lost > 0 {
        eprintln!(
            "warning: {lost} messages were dropped because writing fell {} behind the stack",
            human_bytes(MAX_BACKLOG)
        );
    }
    channels.report_skipped();
    outcome?;
    Ok(())
}

/// Resolves at `deadline` (never without one).
async fn until(deadline: Option<tokio::time::Instant>) {
    match deadline {
        Some(d) => tokio::time::sleep_until(d).await,
        None => std::future::pending().await,
    }
}

/// `<namespace>-<UTC date and time>.mcap` in the current directory.
fn default_path(namespace: &str) -> PathBuf {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    let stamp = dynamic::rfc3339(now.as_secs() as i64, 0);
    // `2026-12-05T08:30:00.000000000Z` -> `2026-12-05T08-30-00Z`.
    let stamp = format!("{}Z", stamp[..19].replace(':', "-"));
    PathBuf::from(format!("{namespace}-{stamp}.mcap"))
}

fn open_output(path: &Path, force: bool) -> std::result::Result<File, RecordingError> {
    let mut options = std::fs::OpenOptions::new();
    options.write(true).read(true);
    if force {
        options.create(true).truncate(true);
    } else {
        options.create_new(true);
    }
    options.open(path).map_err(|source| {
        if source.kind() == std::io::ErrorKind::AlreadyExists {
            RecordingError::Exists {
                path: path.to_path_buf(),
            }
        } else {
            RecordingError::Create {
                path: path.to_path_buf(),
                source,
            }
        }
    })
}

/// A file that counts what is written to it, for `--max-size` and the
/// progress line.
struct Counted {
    inner: BufWriter<File>,
    written: Arc<Progress>,
}

impl Write for Counted {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.written.written.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl Seek for Counted {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.inner.seek(pos)
    }
}

/// The writer thread: what it returns once the file is finished.
type Writer = std::thread::JoinHandle<std::result::Result<(), RecordingError>>;

/// Starts the writer thread; it ends when `ops` is dropped, finishing the
/// file (its summary and index), or at its first error.
fn spawn_writer(
    file: File,
    path: &Path,
    stack: BTreeMap<String, String>,
    progress: Arc<Progress>,
) -> std::result::Result<(flume::Sender<Op>, Writer), RecordingError> {
    let failed = |source: mcap::McapError| RecordingError::Write {
        path: path.to_path_buf(),
        source,
    };
    let options = mcap::WriteOptions::new()
        .profile(PROFILE)
        .library(format!("peppy-launch {}", env!("CARGO_PKG_VERSION")))
        .compression(Some(mcap::Compression::Zstd))
        // Level 1: a recorder shares the machine with the stack it records.
        .compression_level(1)
        .compression_threads(0);
    let counted = Counted {
        inner: BufWriter::with_capacity(1 << 20, file),
        written: progress.clone(),
    };
    let mut out = options.create(counted).map_err(failed)?;
    out.write_metadata(&mcap::records::Metadata {
        name: STACK_METADATA.into(),
        metadata: stack,
    })
    .map_err(failed)?;
    let (tx, rx) = flume::unbounded::<Op>();
    let path = path.to_path_buf();
    let thread = std::thread::Builder::new()
        .name("peppy-record".into())
        .spawn(move || write_all(out, rx, &path, &progress))
        .map_err(|source| RecordingError::Thread { source })?;
    Ok((tx, thread))
}

fn write_all(
    mut out: mcap::Writer<Counted>,
    rx: flume::Receiver<Op>,
    path: &Path,
    progress: &Progress,
) -> std::result::Result<(), RecordingError> {
    let failed = |source: mcap::McapError| RecordingError::Write {
        path: path.to_path_buf(),
        source,
    };
    let mut formats: HashMap<u16, (MessageFormat, u32)> = HashMap::new();
    let mut chunk_opened: Option<Instant> = None;
    // One buffer for every message's JSON, grown to the largest once.
    let mut json = Vec::new();
    loop {
        // An open chunk is closed a period after it opened, whether or not
        // more messages come.
        let wake = chunk_opened.map_or_else(|| Instant::now() + CHUNK_PERIOD, |t| t + CHUNK_PERIOD);
        let op = match rx.recv_deadline(wake) {
            Ok(op) => op,
            Err(flume::RecvTimeoutError::Timeout) => {
                if chunk_opened.take().is_some() {
                    out.flush().map_err(failed)?;
                }
                continue;
            }
            Err(flume::RecvTimeoutError::Disconnected) => break,
        };
        match op {
            Op::Channel { id, meta, format } => {
                let (title, schema) = meta.schema(&format);
                let schema_id = out
                    .add_schema(&title, SCHEMA_ENCODING, schema.as_bytes())
                    .map_err(failed)?;
                out.add_channel_with_id(
                    id,
                    schema_id,
                    &meta.channel_topic(),
                    MESSAGE_ENCODING,
                    &meta.to_map(),
                )
                .map_err(failed)?;
                progress
                    .channels
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .insert(
                        id,
                        ChannelCount {
                            topic: meta.channel_topic(),
                            ..Default::default()
                        },
                    );
                formats.insert(id, (format, 0));
            }
            Op::Message {
                channel,
                log_time,
                publish_time,
                payload,
            } => {
                let size = payload.len() as u64;
                let decoded = formats
                    .get_mut(&channel)
                    .map(|(format, sequence)| (dynamic::decode(format, &payload), sequence));
                let (value, sequence) = match decoded {
                    Some((Ok(value), sequence)) => (value, sequence),
                    Some((Err(_), _)) => {
                        count(progress, channel, |c| c.undecodable += 1);
                        progress.backlog.fetch_sub(size, Ordering::Relaxed);
                        continue;
                    }
                    None => {
                        progress.backlog.fetch_sub(size, Ordering::Relaxed);
                        continue;
                    }
                };
                json.clear();
                dynamic::write_recording_json(&value, &mut json);
                *sequence = sequence.wrapping_add(1);
                out.write_to_known_channel(
                    &mcap::records::MessageHeader {
                        channel_id: channel,
                        sequence: *sequence,
                        log_time,
                        publish_time,
                    },
                    &json,
                )
                .map_err(failed)?;
                count(progress, channel, |c| {
                    c.messages += 1;
                    c.bytes += size;
                });
                progress.backlog.fetch_sub(size, Ordering::Relaxed);
                let opened = *chunk_opened.get_or_insert_with(Instant::now);
                if opened.elapsed() >= CHUNK_PERIOD {
                    out.flush().map_err(failed)?;
                    chunk_opened = None;
                }
            }
        }
    }
    out.finish().map_err(failed)?;
    Ok(())
}

fn count(progress: &Progress, channel: u16, f: impl FnOnce(&mut ChannelCount)) {
    if let Some(c) = progress
        .channels
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .get_mut(&channel)
    {
        f(c);
    }
}

/// Why samples of a key were not recorded, said once per key and counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Skip {
    /// No valid peppy attachment.
    NoAttachment,
    /// A format nobody describes.
    UnknownFormat,
    /// MCAP's 65 535 channels are all taken.
    TooManyChannels,
}

/// The channels opened so far, by key and fingerprint.
#[derive(Default)]
struct Channels {
    ids: HashMap<(String, u64), u16>,
    next: u16,
    skipped: BTreeMap<(String, u64), (Skip, u64)>,
}

impl Channels {
    fn count(&self) -> usize {
        self.ids.len()
    }

    /// The writer's operation for `sample`: a message on its channel, after
    /// the channel itself when it is new. `None` for a sample not taken.
    async fn take(
        &mut self,
        sample: Sampled,
        patterns: &Patterns,
        observer: &Observer,
        learner: &mut Learner,
        ops: &flume::Sender<Op>,
    ) -> Option<Op> {
        let sender = split_entry_key(&sample.key)?;
        if !patterns.takes(sender.instance, sender.entry) {
            return None;
        }
        let Some(fingerprint) = sample.fingerprint else {
            self.skip(&sample.key, 0, Skip::NoAttachment);
            return None;
        };
        let id = match self.ids.get(&(sample.key.clone(), fingerprint)) {
            Some(id) => *id,
            // Learnt once: a format nobody describes is not asked for at
            // every message (the skip keeps its first reason).
            None if self
                .skipped
                .contains_key(&(sample.key.clone(), fingerprint)) =>
            {
                self.skip(&sample.key, fingerprint, Skip::UnknownFormat);
                return None;
            }
            None => {
                let Some((meta, format)) = learner.learn(observer, &sample.key, fingerprint).await
                else {
                    self.skip(&sample.key, fingerprint, Skip::UnknownFormat);
                    return None;
                };
                let id = self.next;
                let Some(next) = self.next.checked_add(1) else {
                    self.skip(&sample.key, fingerprint, Skip::TooManyChannels);
                    return None;
                };
                self.next = next;
                self.ids.insert((sample.key.clone(), fingerprint), id);
                ops.send(Op::Channel { id, meta, format }).ok()?;
                id
            }
        };
        Some(Op::Message {
            channel: id,
            log_time: sample.log_time,
            publish_time: sample.publish_time.unwrap_or(sample.log_time),
            payload: sample.payload,
        })
    }

    fn skip(&mut self, key: &str, fingerprint: u64, why: Skip) {
        let entry = self
            .skipped
            .entry((key.to_string(), fingerprint))
            .or_insert((why, 0));
        if entry.1 == 0 {
            match why {
                Skip::NoAttachment => {
                    eprintln!("\nnote: not recording samples on {key}: no peppy attachment")
                }
                Skip::UnknownFormat => eprintln!(
                    "\nnote: not recording samples on {key}: format {fingerprint:016x} is described by nobody"
                ),
                Skip::TooManyChannels => eprintln!(
                    "\nnote: not recording samples on {key}: the file holds as many channels as MCAP allows"
                ),
            }
        }
        entry.1 += 1;
    }

    fn report_skipped(&self) {
        for ((key, _), (why, n)) in &self.skipped {
            let why = match why {
                Skip::NoAttachment => "without a peppy attachment",
                Skip::UnknownFormat => "in a format nobody describes",
                Skip::TooManyChannels => "beyond MCAP's channel limit",
            };
            eprintln!("note: {n} samples on {key} were not recorded: {why}");
        }
    }
}

/// One line: time, messages, file size, channels.
fn progress_line(elapsed: Duration, progress: &Progress, channels: usize) -> String {
    let secs = elapsed.as_secs();
    format!(
        "recording {:02}:{:02}:{:02}  {} messages  {} on disk  {channels} channels",
        secs / 3600,
        secs / 60 % 60,
        secs % 60,
        progress.messages(),
        human_bytes(progress.written.load(Ordering::Relaxed)),
    )
}

/// Each channel's rate since the table was last shown.
struct Rates {
    since: Instant,
    before: BTreeMap<u16, ChannelCount>,
}

impl Rates {
    fn new(progress: &Progress) -> Rates {
        Rates {
            since: Instant::now(),
            before: progress.snapshot(),
        }
    }

    fn table(&mut self, progress: &Progress) -> String {
        let now = progress.snapshot();
        let secs = self.since.elapsed().as_secs_f64().max(1e-3);
        let mut out = format!(
            "{:<48} {:>10} {:>10} {:>12}\n",
            "CHANNEL", "MESSAGES", "MSG/S", "PAYLOAD/S"
        );
        for (id, c) in &now {
            let before = self.before.get(id).cloned().unwrap_or_default();
            let rate = (c.messages - before.messages) as f64 / secs;
            let bytes = ((c.bytes - before.bytes) as f64 / secs) as u64;
            out.push_str(&format!(
                "{:<48} {:>10} {:>10.1} {:>10}/s\n",
                c.topic,
                c.messages,
                rate,
                human_bytes(bytes)
            ));
        }
        self.since = Instant::now();
        self.before = now;
        out
    }
}

/// The channels at the end, with what was not decodable.
fn summary_table(counts: &BTreeMap<u16, ChannelCount>) -> String {
    let mut out = String::new();
    for c in counts.values() {
        out.push_str(&format!(
            "  {:<48} {:>8} messages  {:>10}",
            c.topic,
            c.messages,
            human_bytes(c.bytes)
        ));
        if c.undecodable > 0 {
            out.push_str(&format!(
                "  ({} did not decode with their format)",
                c.undecodable
            ));
        }
        out.push('\n');
    }
    out
}

/// `12.3 MiB`.
pub(crate) fn human_bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut value = n as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{n} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

/// A message each time Enter is pressed on a terminal (never otherwise).
fn enter_presses() -> tokio::sync::mpsc::Receiver<()> {
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    if std::io::stdin().is_terminal() {
        std::thread::spawn(move || {
            let mut line = String::new();
            while std::io::stdin().read_line(&mut line).is_ok_and(|n| n > 0) {
                line.clear();
                if tx.blocking_send(()).is_err() {
                    break;
                }
            }
        });
    }
    rx
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_as_people_write_them() {
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(3 << 20), "3.0 MiB");
    }
}
