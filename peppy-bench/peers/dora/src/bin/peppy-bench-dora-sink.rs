//! peppy-bench's measuring end as a dora node. It does what
//! `peppy-bench/src/roles.rs` does for raw Zenoh and peppy, with the same
//! counts, warm-ups and turns (a batch starts on the benchmark's `go` and
//! ends with `{"batch": n}`), and reports the same JSON lines.

use std::time::{Duration, Instant};

use dora_node_api::dora_core::config::DataId;
use dora_node_api::{DoraNode, Event, EventStream, MetadataParameters};
use peppy_bench_dora::{
    Control, HEADER, Res, arg, cpu_ms, flag, header, now_ns, put_header, spread,
};
use serde_json::json;

struct Sink {
    node: DoraNode,
    events: EventStream,
    control: Control,
}

impl Sink {
    /// The next input named `want` within `bound`: its header and length.
    fn next(&mut self, want: &str, bound: Duration) -> Res<Option<(u64, u64, usize)>> {
        let deadline = Instant::now() + bound;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(None);
            }
            match self.events.recv_timeout(left) {
                Some(Event::Input { id, data, .. }) if id.as_str() == want => {
                    // Decoded into owned data, as a typed consumer does.
                    let got: &[u8] = (&data).try_into()?;
                    let owned = got.to_vec();
                    let (seq, sent) = header(&owned).ok_or("a message without a header")?;
                    return Ok(Some((seq, sent, owned.len())));
                }
                Some(Event::Stop(_)) | None => return Err("dora stopped the dataflow".into()),
                // Another input, or the timeout (reported as an error event).
                Some(_) => {}
            }
        }
    }

    fn ping(&mut self, seq: u64, data: &[u8]) -> Res<()> {
        let payload = data.to_vec();
        self.node.send_output_raw(
            DataId::from("ping"),
            MetadataParameters::default(),
            HEADER + payload.len(),
            |buf| {
                put_header(buf, seq, now_ns());
                buf[HEADER..].copy_from_slice(&payload);
            },
        )?;
        Ok(())
    }

    /// Waits for pong `seq` within `bound`; `false` if it did not come.
    fn pong(&mut self, seq: u64, bound: Duration) -> Res<bool> {
        let deadline = Instant::now() + bound;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.next("pong", left)? {
                Some((s, _, _)) if s == seq => return Ok(true),
                Some(_) => {}
                None => return Ok(false),
            }
        }
    }

    /// Pings until a pong answers: until then the two have not matched.
    fn warm_up(&mut self, data: &[u8]) -> Res<()> {
        let deadline = Instant::now() + Duration::from_secs(20);
        let mut seq = 0;
        while Instant::now() < deadline {
            seq += 1;
            self.ping(seq, data)?;
            if self.pong(seq, Duration::from_millis(200))? {
                return Ok(());
            }
        }
        Err("no pong within 20 s: the two nodes never matched".into())
    }

    fn flood(&mut self, size: u64, count: u64, hz: f64) -> Res<()> {
        let mut ask = [0u8; 24];
        ask[..8].copy_from_slice(&size.to_le_bytes());
        ask[8..16].copy_from_slice(&count.to_le_bytes());
        ask[16..].copy_from_slice(&hz.to_bits().to_le_bytes());
        self.node.send_output_bytes(
            DataId::from("flood"),
            MetadataParameters::default(),
            ask.len(),
            &ask,
        )?;
        Ok(())
    }

    /// Waits for the benchmark's word to measure.
    fn go(&mut self) -> Res<()> {
        self.control
            .word()
            .map(|_| ())
            .ok_or_else(|| "the benchmark closed the link between batches".into())
    }
}

/// `roles::round_trips`: `count` ping-pongs of `size` bytes, one in
/// flight, in `turns` batches.
fn round_trips(s: &mut Sink, size: usize, count: usize, turns: usize) -> Res<()> {
    let data = vec![0xa5u8; size];
    let batch = |i: usize| i * turns / count.max(1);
    s.go()?;
    s.warm_up(&data)?;
    let (mut samples, mut lost) = (Vec::with_capacity(count), 0);
    for i in 0..count {
        if i > 0 && batch(i) != batch(i - 1) {
            s.go()?;
            s.warm_up(&data)?;
        }
        let seq = 1_000_000 + i as u64;
        let start = Instant::now();
        s.ping(seq, &data)?;
        if s.pong(seq, Duration::from_secs(2))? {
            samples.push(start.elapsed().as_secs_f64() * 1e6);
        } else {
            lost += 1;
        }
        if i + 1 == count || batch(i + 1) != batch(i) {
            s.control.say(&json!({ "batch": batch(i) }));
        }
    }
    s.control.say(&json!({
        "qos": "dora",
        "size": size,
        "spread": spread(&mut samples),
        "lost": lost,
    }));
    Ok(())
}

/// `roles::throughput`: a flood of `count` messages of `size` bytes; the
/// rate between the first and the last arrival.
fn throughput(s: &mut Sink, size: usize, count: u64) -> Res<()> {
    let deadline = Instant::now() + Duration::from_secs(20);
    'matched: loop {
        if Instant::now() > deadline {
            return Err("the stream never matched".into());
        }
        s.flood(8, 5, 0.0)?;
        while let Some((seq, _, _)) = s.next("stream", Duration::from_millis(300))? {
            if seq == 4 {
                break 'matched;
            }
        }
    }
    s.flood(size as u64, count, 0.0)?;
    let (mut first, mut last, mut received) = (None, Instant::now(), 0u64);
    while let Some((seq, _, _)) = s.next("stream", Duration::from_secs(10))? {
        last = Instant::now();
        first.get_or_insert(last);
        received += 1;
        if seq + 1 == count {
            break;
        }
    }
    let span = first.map_or(0.0, |f| (last - f).as_secs_f64());
    let rate = if span > 0.0 {
        received.saturating_sub(1) as f64 / span
    } else {
        0.0
    };
    s.control.say(&json!({
        "size": size,
        "sent": count,
        "received": received,
        "msgs_per_s": rate,
        "bytes_per_s": rate * size as f64,
    }));
    Ok(())
}

/// `roles::fan_out`: frames until `warmup + frames - 1`, latency from the
/// producer's clock; the trigger starts the producer on the word.
fn fan_out(s: &mut Sink, args: &[String]) -> Res<()> {
    let num = |name: &str| arg(args, name).and_then(|v| v.parse::<f64>().ok());
    let (warmup, frames) = (
        num("--warmup").unwrap_or(30.0) as u64,
        num("--frames").unwrap_or(150.0) as u64,
    );
    s.control.say(&json!({ "ready": true }));
    if flag(args, "--trigger") {
        s.go()?;
        let size = num("--size").unwrap_or(1048576.0) as u64;
        s.flood(size, warmup + frames, num("--hz").unwrap_or(30.0))?;
    }
    let (mut samples, mut cpu_from) = (Vec::new(), None);
    while let Some((seq, sent, _)) = s.next("stream", Duration::from_secs(10))? {
        let arrived = now_ns();
        if seq >= warmup {
            cpu_from.get_or_insert_with(cpu_ms);
            samples.push(arrived.saturating_sub(sent) as f64 / 1e3);
        }
        if seq + 1 >= warmup + frames {
            break;
        }
    }
    s.control.say(&json!({
        "received": samples.len(),
        "spread": spread(&mut samples),
        "cpu_ms": cpu_from.map_or(0.0, |from| cpu_ms() - from),
    }));
    Ok(())
}

/// The launch group: when the first frame came, and when every camera
/// had been heard.
fn launch(s: &mut Sink, expect: usize) -> Res<()> {
    let mut heard = std::collections::BTreeSet::new();
    let mut first = None;
    let deadline = Instant::now() + Duration::from_secs(120);
    while heard.len() < expect && Instant::now() < deadline {
        if let Some(Event::Input { id, .. }) = s.events.recv_timeout(Duration::from_secs(1)) {
            first.get_or_insert_with(now_ns);
            heard.insert(id.to_string());
        }
    }
    s.control.say(&json!({
        "first_ns": first,
        "all_ns": (heard.len() >= expect).then(now_ns),
        "heard": heard.len(),
    }));
    Ok(())
}

fn main() -> Res<()> {
    let (node, events) = DoraNode::init_from_env()?;
    let (control, args) = Control::connect(node.id().as_ref())?;
    let mut s = Sink {
        node,
        events,
        control,
    };
    let role = args.first().map(String::as_str).unwrap_or("");
    let result = match role {
        "round-trip" => {
            let count: usize = arg(&args, "--count")
                .and_then(|v| v.parse().ok())
                .unwrap_or(100);
            let turns: usize = arg(&args, "--turns")
                .and_then(|v| v.parse().ok())
                .unwrap_or(1);
            let sizes: Vec<usize> = arg(&args, "--sizes")
                .unwrap_or("64")
                .split(',')
                .filter_map(|v| v.parse().ok())
                .collect();
            sizes.iter().try_for_each(|&size| {
                let n = if size > 64 << 10 { count / 25 } else { count };
                round_trips(&mut s, size, n.max(10).max(turns), turns.max(1))
            })
        }
        "throughput" => arg(&args, "--cases")
            .unwrap_or("")
            .split(',')
            .filter_map(|c| {
                let (a, b) = c.split_once(':')?;
                Some((a.parse().ok()?, b.parse().ok()?))
            })
            .try_for_each(|(size, count)| throughput(&mut s, size, count)),
        "fan-out" => fan_out(&mut s, &args),
        "launch" => {
            let expect = arg(&args, "--expect")
                .and_then(|v| v.parse().ok())
                .unwrap_or(1);
            launch(&mut s, expect)
        }
        other => Err(format!("unknown role `{other}`").into()),
    };
    if let Err(e) = &result {
        s.control.say(&json!({ "error": e.to_string() }));
    }
    // Stay until the benchmark has read everything and closes the link.
    while s.control.word().is_some() {}
    result
}
