//! peppy-bench's source as a dora node: answers each `ping` with a `pong`
//! of the same bytes (decoded into owned data first, as a typed node
//! does), streams `stream` messages when asked on `flood`, and sends a
//! small `frame` on each `tick` (the launch group's cameras).

use dora_node_api::dora_core::config::DataId;
use dora_node_api::{DoraNode, Event, MetadataParameters};
use peppy_bench_dora::{Control, HEADER, Res, cpu_ms, now_ns, put_header};

fn main() -> Res<()> {
    let (mut node, mut events) = DoraNode::init_from_env()?;
    // The launch group's cameras run without a link to the benchmark.
    let mut control = match std::env::var_os("PEPPY_BENCH_CONTROL") {
        Some(_) => Some(Control::connect(node.id().as_ref())?.0),
        None => None,
    };
    let (pong, stream, frame) = (
        DataId::from("pong"),
        DataId::from("stream"),
        DataId::from("frame"),
    );
    let mut frames = 0u64;
    while let Some(event) = events.recv() {
        match event {
            Event::Input { id, data, .. } => match id.as_str() {
                "ping" => {
                    let got: &[u8] = (&data).try_into()?;
                    let owned = got.to_vec();
                    node.send_output_bytes(
                        pong.clone(),
                        MetadataParameters::default(),
                        owned.len(),
                        &owned,
                    )?;
                }
                "flood" => {
                    let ask: &[u8] = (&data).try_into()?;
                    let word = |i: usize| {
                        ask.get(i * 8..i * 8 + 8)
                            .and_then(|b| b.try_into().ok())
                            .map_or(0, u64::from_le_bytes)
                    };
                    let (size, count, hz) = (word(0) as usize, word(1), f64::from_bits(word(2)));
                    let body = vec![0x5au8; size];
                    let (cpu_from, started) = (cpu_ms(), std::time::Instant::now());
                    let period = (hz > 0.0).then(|| std::time::Duration::from_secs_f64(1.0 / hz));
                    for seq in 0..count {
                        if let Some(p) = period {
                            let due = started + p * seq as u32;
                            if let Some(wait) =
                                due.checked_duration_since(std::time::Instant::now())
                            {
                                std::thread::sleep(wait);
                            }
                        }
                        node.send_output_raw(
                            stream.clone(),
                            MetadataParameters::default(),
                            HEADER + size,
                            |buf| {
                                put_header(buf, seq, now_ns());
                                buf[HEADER..].copy_from_slice(&body);
                            },
                        )?;
                    }
                    if let Some(c) = control.as_mut() {
                        c.say(&serde_json::json!({ "flood": {
                            "cpu_ms": cpu_ms() - cpu_from,
                            "secs": started.elapsed().as_secs_f64(),
                        }}));
                    }
                }
                "tick" => {
                    node.send_output_raw(
                        frame.clone(),
                        MetadataParameters::default(),
                        64,
                        |buf| put_header(buf, frames, now_ns()),
                    )?;
                    frames += 1;
                }
                _ => {}
            },
            Event::Stop(_) => break,
            _ => {}
        }
    }
    Ok(())
}
