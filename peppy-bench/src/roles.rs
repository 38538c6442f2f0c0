//! What a measuring process does, the same for both systems: the loops
//! here drive a [`Sink`], which raw Zenoh and peppy each implement, so the
//! two are timed by the same code doing the same work.

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use serde::Serialize;
use tokio::time::timeout;

use crate::stats::Spread;

/// How a measuring loop takes turns with the other systems' measuring
/// processes: its samples fall into `turns` batches, each started by a
/// line on stdin and followed by `{"batch": n}` on stdout, so the parent
/// lets one process measure at a time, switching every few milliseconds.
/// On this machine speed drifts by a fifth within seconds; taking turns
/// that often lets a drift reach every system alike.
pub(crate) struct Pace {
    turns: Option<(
        usize,
        tokio::io::Lines<tokio::io::BufReader<tokio::io::Stdin>>,
    )>,
}

impl Pace {
    /// Never waits: the loop runs through.
    pub(crate) fn free() -> Pace {
        Pace { turns: None }
    }

    /// `turns` batches per loop, each on the parent's word.
    pub(crate) fn turns(turns: usize) -> Pace {
        let stdin = tokio::io::BufReader::new(tokio::io::stdin());
        Pace {
            turns: Some((turns.max(1), tokio::io::AsyncBufReadExt::lines(stdin))),
        }
    }

    /// The batch of sample `i` of `count` (`count` at least the turns, so
    /// none is empty).
    fn batch(&self, i: usize, count: usize) -> Option<usize> {
        let (turns, _) = self.turns.as_ref()?;
        Some(i * turns / count.max(1))
    }

    /// Before sample `i` of `count` (and before a loop's warm-up, as
    /// sample 0): waits for the parent's word if a batch starts here, and
    /// says whether one did. The first exchange after a pause is not
    /// steady state (the threads parked, the caches and a large message's
    /// pages cold; with five round trips a batch at 1 MiB it was a fifth
    /// of the samples and moved the median), so the loops send one untimed
    /// exchange first.
    async fn before(&mut self, i: usize, count: usize) -> Res<bool> {
        let starts = match self.batch(i, count) {
            Some(b) => i == 0 || self.batch(i - 1, count) != Some(b),
            None => false,
        };
        if let (true, Some((_, lines))) = (starts, &mut self.turns)
            && lines.next_line().await?.is_none()
        {
            return Err("the parent closed stdin between batches".into());
        }
        Ok(starts)
    }

    /// After sample `i` of `count`: reports a finished batch.
    fn after(&self, i: usize, count: usize) {
        if let Some(b) = self.batch(i, count)
            && (i + 1 == count || self.batch(i + 1, count) != Some(b))
        {
            report(&serde_json::json!({ "batch": b }));
        }
    }
}

/// Errors of a benchmark process: reported, never recovered from.
pub(crate) type Res<T> = Result<T, Box<dyn std::error::Error + Send + Sync>>;

/// The two topic profiles measured, as WIRE.md §7 defines them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum Qos {
    /// `reliable`: congestion blocks, DataHigh, every message queued.
    Reliable,
    /// `sensor_data`: congestion drops, DataLow, express, newest kept.
    Sensor,
}

impl Qos {
    /// The profile's name in a document.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Qos::Reliable => "reliable",
            Qos::Sensor => "sensor_data",
        }
    }
}

/// The measuring end of a benchmark, over one system.
pub(crate) trait Sink {
    /// Sends ping `seq` carrying `data`.
    async fn ping(&self, qos: Qos, seq: u64, data: Vec<u8>) -> Res<()>;
    /// The sequence number of the next pong.
    async fn pong(&self, qos: Qos) -> Res<u64>;
    /// Asks the source to stream `count` messages of `size` bytes at `hz`
    /// (0: as fast as it can).
    async fn flood(&self, size: u32, count: u32, hz: f64) -> Res<()>;
    /// The next streamed message: `(seq, sent_ns, data length)`.
    async fn stream(&self) -> Res<(u64, u64, usize)>;
    /// One call of the echo service; the length of what came back.
    async fn echo(&self, data: Vec<u8>) -> Res<usize>;
}

/// Nanoseconds since the epoch: comparable across processes of one host.
pub(crate) fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// CPU time this process has used (user + system), in milliseconds.
pub(crate) fn cpu_ms() -> f64 {
    cpu_ms_of("self")
}

/// CPU time process `pid` (a number, or `self`) has used (user + system),
/// in milliseconds; 0 for one that is gone.
pub(crate) fn cpu_ms_of(pid: &str) -> f64 {
    // Fields 14 and 15 of /proc/<pid>/stat, after the parenthesised name,
    // in clock ticks of USER_HZ (100 on Linux).
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    let after = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|f| f.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) * 10.0
}

/// What each of this process's threads has run so far (Linux's
/// per-thread `schedstat`; empty where there is none).
pub(crate) fn thread_cpu() -> ThreadCpu {
    let mut threads = std::collections::HashMap::new();
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return ThreadCpu(threads);
    };
    for task in tasks.flatten() {
        let path = task.path();
        let (Ok(name), Ok(stat)) = (
            std::fs::read_to_string(path.join("comm")),
            std::fs::read_to_string(path.join("schedstat")),
        ) else {
            continue; // The thread ended meanwhile.
        };
        let ns: u64 = stat
            .split_whitespace()
            .next()
            .and_then(|v| v.parse().ok())
            .unwrap_or(0);
        threads.insert(task.file_name(), (is_zenoh_thread(name.trim()), ns));
    }
    ThreadCpu(threads)
}

/// Whether a thread of this name is one of Zenoh's: its runtimes' `app`,
/// `acc`, `tx`, `rx` and `net` threads and its shared memory's watchdogs.
fn is_zenoh_thread(name: &str) -> bool {
    let runtime = name.split_once('-').is_some_and(|(runtime, index)| {
        matches!(runtime, "app" | "acc" | "tx" | "rx" | "net")
            && index.bytes().all(|b| b.is_ascii_digit())
    });
    runtime || name.starts_with("Watchdog")
}

/// CPU time of each of a process's threads (by thread id): whether it is
/// one of Zenoh's, and the nanoseconds it has run.
#[derive(Debug, Default)]
pub(crate) struct ThreadCpu(std::collections::HashMap<std::ffi::OsString, (bool, u64)>);

impl ThreadCpu {
    /// What the threads ran since `before` (a thread started since counts
    /// from 0; one that ended meanwhile is not counted), in nanoseconds:
    /// Zenoh's threads, then the others.
    fn since(&self, before: &ThreadCpu) -> (u64, u64) {
        let mut used = (0, 0);
        for (id, &(zenoh, now)) in &self.0 {
            let then = before.0.get(id).map_or(0, |&(_, ns)| ns);
            let ran = now.saturating_sub(then);
            if zenoh {
                used.0 += ran;
            } else {
                used.1 += ran;
            }
        }
        used
    }
}

/// CPU time per operation (µs), Zenoh's threads apart.
#[derive(Debug, Serialize)]
pub(crate) struct CpuPer {
    pub(crate) zenoh_us: f64,
    pub(crate) other_us: f64,
}

impl CpuPer {
    /// `used` nanoseconds (Zenoh's threads, the others) per one of `n`.
    fn of(used: (u64, u64), n: usize) -> CpuPer {
        let per = |ns: u64| ns as f64 / 1e3 / n.max(1) as f64;
        CpuPer {
            zenoh_us: per(used.0),
            other_us: per(used.1),
        }
    }
}

/// A source's report that a flood has been sent: its CPU time and wall
/// time meanwhile.
pub(crate) fn flood_done(cpu_from: f64, started: Instant) {
    report(&serde_json::json!({ "flood": {
        "cpu_ms": cpu_ms() - cpu_from,
        "secs": started.elapsed().as_secs_f64(),
    }}));
}

/// Prints one JSON line for the parent process.
pub(crate) fn report(value: &impl Serialize) {
    println!("{}", serde_json::to_string(value).expect("serialisable"));
}

/// Pings until a pong answers: until then the two sides have not matched.
async fn warm_up<S: Sink>(s: &S, qos: Qos, data: &[u8]) -> Res<()> {
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut seq = 0;
    while Instant::now() < deadline {
        seq += 1;
        s.ping(qos, seq, data.to_vec()).await?;
        let answered = timeout(Duration::from_millis(200), async {
            loop {
                if s.pong(qos).await? == seq {
                    return Res::Ok(());
                }
            }
        });
        if let Ok(r) = answered.await {
            return r;
        }
    }
    Err("no pong within 20 s: the two processes never matched".into())
}

/// Round trips of `size` bytes: what one measured, and how many pings got
/// no answer within 2 s (possible only under `sensor_data`).
#[derive(Debug, Serialize)]
pub(crate) struct RoundTrips {
    pub(crate) qos: Qos,
    pub(crate) size: usize,
    pub(crate) spread: Option<Spread>,
    pub(crate) lost: usize,
    /// This process's CPU time per round trip (the warm-ups before each
    /// batch left out).
    pub(crate) cpu: CpuPer,
}

/// `count` ping-pongs of `size` bytes, one in flight at a time, paced by
/// `pace` (its first batch includes the warm-up).
pub(crate) async fn round_trips<S: Sink>(
    s: &S,
    qos: Qos,
    size: usize,
    count: usize,
    pace: &mut Pace,
) -> Res<RoundTrips> {
    let data = vec![0xa5u8; size];
    pace.before(0, count).await?;
    warm_up(s, qos, &data).await?;
    let cpu_from = thread_cpu();
    // CPU the later batches' warm-ups used, taken out of the figure.
    let mut warming = (0, 0);
    let (mut samples, mut lost) = (Vec::with_capacity(count), 0);
    for i in 0..count {
        if i > 0 && pace.before(i, count).await? {
            let before = thread_cpu();
            warm_up(s, qos, &data).await?;
            let used = thread_cpu().since(&before);
            warming = (warming.0 + used.0, warming.1 + used.1);
        }
        let seq = 1_000_000 + i as u64;
        let payload = data.clone();
        let start = Instant::now();
        s.ping(qos, seq, payload).await?;
        let answer = timeout(Duration::from_secs(2), async {
            loop {
                if s.pong(qos).await? == seq {
                    return Res::Ok(());
                }
            }
        });
        match answer.await {
            Ok(r) => {
                r?;
                samples.push(start.elapsed().as_secs_f64() * 1e6);
            }
            Err(_) => lost += 1,
        }
        pace.after(i, count);
    }
    Ok(RoundTrips {
        qos,
        size,
        spread: Spread::of(&mut samples),
        lost,
        cpu: {
            let used = thread_cpu().since(&cpu_from);
            let used = (
                used.0.saturating_sub(warming.0),
                used.1.saturating_sub(warming.1),
            );
            CpuPer::of(used, count)
        },
    })
}

/// One producer to one consumer, as fast as the producer can.
#[derive(Debug, Serialize)]
pub(crate) struct Throughput {
    pub(crate) size: usize,
    pub(crate) sent: u32,
    pub(crate) received: u32,
    pub(crate) msgs_per_s: f64,
    pub(crate) bytes_per_s: f64,
}

/// Receives a flood of `count` messages of `size` bytes; the rate is
/// between the first and the last arrival.
pub(crate) async fn throughput<S: Sink>(s: &S, size: usize, count: u32) -> Res<Throughput> {
    // A small flood first, so the stream is matched before it counts.
    let deadline = Instant::now() + Duration::from_secs(20);
    'matched: loop {
        if Instant::now() > deadline {
            return Err("the stream never matched".into());
        }
        // Until the two have matched, the request itself may go unanswered.
        if s.flood(8, 5, 0.0).await.is_err() {
            tokio::time::sleep(Duration::from_millis(100)).await;
            continue;
        }
        while let Ok(next) = timeout(Duration::from_millis(300), s.stream()).await {
            if next?.0 == 4 {
                break 'matched;
            }
        }
    }
    // Read while the request is answered: the source's stream (DataHigh)
    // can overtake its reply (Data), and a raw subscriber's bounded channel
    // that nobody reads stalls the session's delivery, reply included.
    let read = async {
        let (mut first, mut last, mut received) = (None, Instant::now(), 0u32);
        while let Ok(next) = timeout(Duration::from_secs(10), s.stream()).await {
            let (seq, _, _) = next?;
            last = Instant::now();
            first.get_or_insert(last);
            received += 1;
            if seq + 1 == u64::from(count) {
                break;
            }
        }
        Res::Ok((first, last, received))
    };
    let (asked, read) = tokio::join!(s.flood(size as u32, count, 0.0), read);
    asked?;
    let (first, last, received) = read?;
    let span = first.map_or(0.0, |f| (last - f).as_secs_f64());
    let msgs_per_s = if span > 0.0 {
        f64::from(received.saturating_sub(1)) / span
    } else {
        0.0
    };
    Ok(Throughput {
        size,
        sent: count,
        received,
        msgs_per_s,
        bytes_per_s: msgs_per_s * size as f64,
    })
}

/// One consumer's view of a fan-out: latency of every frame from the
/// producer's clock to this process, and this process's CPU meanwhile.
#[derive(Debug, Serialize)]
pub(crate) struct FanOut {
    pub(crate) spread: Option<Spread>,
    pub(crate) received: u64,
    pub(crate) cpu_ms: f64,
}

/// Reads frames until frame `warmup + frames - 1`; the first `warmup`
/// frames are not counted. `trigger` starts the producer.
pub(crate) async fn fan_out<S: Sink>(
    s: &S,
    trigger: Option<(u32, u32, f64)>,
    warmup: u64,
    frames: u64,
) -> Res<FanOut> {
    if let Some((size, count, hz)) = trigger {
        s.flood(size, count, hz).await?;
    }
    let (mut samples, mut cpu_from) = (Vec::new(), None);
    let bound = Duration::from_secs(10);
    while let Ok(next) = timeout(bound, s.stream()).await {
        let (seq, sent_ns, _) = next?;
        let arrived = now_ns();
        if seq >= warmup {
            cpu_from.get_or_insert_with(cpu_ms);
            samples.push(arrived.saturating_sub(sent_ns) as f64 / 1e3);
        }
        if seq + 1 >= warmup + frames {
            break;
        }
    }
    Ok(FanOut {
        received: samples.len() as u64,
        spread: Spread::of(&mut samples),
        cpu_ms: cpu_from.map_or(0.0, |from| cpu_ms() - from),
    })
}

/// `count` calls of the echo service with `size` bytes, paced by `pace`
/// (its first batch includes finding the server).
pub(crate) async fn service_calls<S: Sink>(
    s: &S,
    size: usize,
    count: usize,
    pace: &mut Pace,
) -> Res<Option<Spread>> {
    let data = vec![7u8; size];
    pace.before(0, count).await?;
    // The first call finds the server (and waits for it to be up).
    let deadline = Instant::now() + Duration::from_secs(20);
    while s.echo(data.clone()).await.is_err() {
        if Instant::now() > deadline {
            return Err("the echo service never answered".into());
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let mut samples = Vec::with_capacity(count);
    for call in 0..count {
        if call > 0 && pace.before(call, count).await? {
            s.echo(data.clone()).await?;
        }
        let payload = data.clone();
        let start = Instant::now();
        let n = s.echo(payload).await?;
        samples.push(start.elapsed().as_secs_f64() * 1e6);
        if n != size {
            return Err(format!("the echo returned {n} bytes for {size}").into());
        }
        pace.after(call, count);
    }
    Ok(Spread::of(&mut samples))
}
