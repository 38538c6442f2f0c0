//! The hand-off floor: two processes handing a message back and forth
//! through shared memory, each woken by an event when the other has sent,
//! on iceoryx2 (the reference implementation of that in Rust). No
//! serialisation, no network stack: each side writes its message into a
//! shared-memory sample (the ping from its buffer, the pong from the
//! ping's bytes where they arrived) and notifies the other.
//!
//! `peppy-bench-iceoryx2 pong --name N` answers until stdin closes;
//! `peppy-bench-iceoryx2 ping --name N --sizes 64,1048576 --count C
//! [--turns T]` measures as peppy-bench's sinks do (`roles.rs`): a batch
//! starts on a line on stdin and ends with `{"batch": n}` on stdout.

use std::io::BufRead;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

type Res<T> = Result<T, Box<dyn std::error::Error + Send + Sync>>;

/// The largest message the floor is asked for, plus its header.
const MAX: usize = (4 << 20) + 8;

struct Side {
    publisher: Publisher<ipc::Service, [u8], ()>,
    subscriber: Subscriber<ipc::Service, [u8], ()>,
    notifier: Notifier<ipc::Service>,
    listener: Listener<ipc::Service>,
}

impl Side {
    /// One direction's services are `<name>/<out>`, with the event
    /// `<name>/<out>/ev` that wakes its reader.
    fn open(node: &Node<ipc::Service>, name: &str, out: &str, into: &str) -> Res<Side> {
        let data = |dir: &str| -> Res<_> {
            Ok(node
                .service_builder(&format!("peppy-bench/{name}/{dir}").as_str().try_into()?)
                .publish_subscribe::<[u8]>()
                .max_publishers(1)
                .max_subscribers(1)
                .history_size(0)
                .subscriber_max_buffer_size(4)
                .open_or_create()?)
        };
        let event = |dir: &str| -> Res<_> {
            Ok(node
                .service_builder(&format!("peppy-bench/{name}/{dir}/ev").as_str().try_into()?)
                .event()
                .open_or_create()?)
        };
        let publisher = data(out)?
            .publisher_builder()
            .initial_max_slice_len(MAX)
            .create()?;
        let subscriber = data(into)?.subscriber_builder().create()?;
        let notifier = event(out)?.notifier_builder().create()?;
        let listener = event(into)?.listener_builder().create()?;
        Ok(Side {
            publisher,
            subscriber,
            notifier,
            listener,
        })
    }

    fn send(&self, bytes: &[u8]) -> Res<()> {
        let sample = self.publisher.loan_slice_uninit(bytes.len())?;
        sample.write_from_slice(bytes).send()?;
        self.notifier.notify()?;
        Ok(())
    }

    /// The next message's sequence number, within `bound`.
    fn next_seq(&self, bound: Duration) -> Res<Option<u64>> {
        let deadline = Instant::now() + bound;
        loop {
            if let Some(sample) = self.subscriber.receive()? {
                let head: [u8; 8] = sample.payload()[..8].try_into()?;
                return Ok(Some(u64::from_le_bytes(head)));
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(None);
            }
            self.listener.timed_wait(|_| {}, left)?;
        }
    }
}

fn arg<'a>(args: &'a [String], name: &str) -> Option<&'a str> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map(String::as_str)
}

fn pong(node: &Node<ipc::Service>, name: &str) -> Res<()> {
    let side = Side::open(node, name, "b2a", "a2b")?;
    let stop = Arc::new(AtomicBool::new(false));
    let stopping = stop.clone();
    std::thread::spawn(move || {
        for _ in std::io::stdin().lock().lines() {}
        stopping.store(true, Ordering::Relaxed);
    });
    println!("{}", serde_json::json!({ "ready": true }));
    while !stop.load(Ordering::Relaxed) {
        while let Some(ping) = side.subscriber.receive()? {
            // Answered from the ping's bytes where they arrived.
            side.send(ping.payload())?;
        }
        side.listener
            .timed_wait(|_| {}, Duration::from_millis(100))?;
    }
    Ok(())
}

fn ping(node: &Node<ipc::Service>, name: &str, args: &[String]) -> Res<()> {
    let side = Side::open(node, name, "a2b", "b2a")?;
    let count: usize = arg(args, "--count")
        .and_then(|v| v.parse().ok())
        .unwrap_or(100);
    let turns: usize = arg(args, "--turns")
        .and_then(|v| v.parse().ok())
        .unwrap_or(1)
        .max(1);
    let sizes: Vec<usize> = arg(args, "--sizes")
        .unwrap_or("64")
        .split(',')
        .filter_map(|v| v.parse().ok())
        .collect();
    let mut words = std::io::stdin().lock().lines();
    let mut go = || -> Res<()> {
        match words.next() {
            Some(Ok(_)) => Ok(()),
            _ => Err("the benchmark closed stdin between batches".into()),
        }
    };
    for size in sizes {
        if size + 8 > MAX {
            return Err(format!("{size} B is above the floor's {MAX} B").into());
        }
        let n = if size > 64 << 10 { count / 25 } else { count };
        let n = n.max(10).max(turns);
        let batch = |i: usize| i * turns / n;
        let mut data = vec![0xa5u8; size + 8];
        let warm_up = |data: &mut Vec<u8>| -> Res<()> {
            let deadline = Instant::now() + Duration::from_secs(20);
            let mut seq = 0u64;
            while Instant::now() < deadline {
                seq += 1;
                data[..8].copy_from_slice(&seq.to_le_bytes());
                side.send(data)?;
                while let Some(got) = side.next_seq(Duration::from_millis(200))? {
                    if got == seq {
                        return Ok(());
                    }
                }
            }
            Err("no pong within 20 s: the two processes never matched".into())
        };
        go()?;
        warm_up(&mut data)?;
        let (mut samples, mut lost) = (Vec::with_capacity(n), 0);
        for i in 0..n {
            if i > 0 && batch(i) != batch(i - 1) {
                go()?;
                warm_up(&mut data)?;
            }
            let seq = 1_000_000 + i as u64;
            data[..8].copy_from_slice(&seq.to_le_bytes());
            let start = Instant::now();
            side.send(&data)?;
            let mut answered = false;
            while let Some(got) = side.next_seq(Duration::from_secs(2))? {
                if got == seq {
                    answered = true;
                    break;
                }
            }
            if answered {
                samples.push(start.elapsed().as_secs_f64() * 1e6);
            } else {
                lost += 1;
            }
            if i + 1 == n || batch(i + 1) != batch(i) {
                println!("{}", serde_json::json!({ "batch": batch(i) }));
            }
        }
        println!(
            "{}",
            serde_json::json!({
                "qos": "iceoryx2",
                "size": size,
                "spread": spread(&mut samples),
                "lost": lost,
            })
        );
    }
    Ok(())
}

/// p50, p99 and max (µs) as peppy-bench's `Spread::of` computes them.
fn spread(samples: &mut [f64]) -> serde_json::Value {
    if samples.is_empty() {
        return serde_json::Value::Null;
    }
    samples.sort_by(f64::total_cmp);
    let at = |q: f64| samples[((samples.len() - 1) as f64 * q).round() as usize];
    serde_json::json!({
        "p50": at(0.50),
        "p99": at(0.99),
        "max": samples[samples.len() - 1],
        "n": samples.len(),
    })
}

fn main() -> std::process::ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let run = || -> Res<()> {
        set_log_level(LogLevel::Error);
        let name = arg(&args, "--name").ok_or("--name is required")?;
        let node = NodeBuilder::new().create::<ipc::Service>()?;
        match args.first().map(String::as_str) {
            Some("pong") => pong(&node, name),
            Some("ping") => ping(&node, name, &args),
            _ => Err("usage: peppy-bench-iceoryx2 ping|pong --name N …".into()),
        }
    };
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("peppy-bench-iceoryx2: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
