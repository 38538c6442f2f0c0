//! The work over peppy: two nodes generated from `nodes/*.json5`, talking
//! through the sink's pinned slot `source`, with the generated functions a
//! node's code calls.

use std::sync::Arc;
use std::time::{Duration, Instant};

use peppy::codegen::{Decode, DecodeError, Decoder, Encode, TopicSpec, Writer};
use peppy::{NodeBuilder, NodeRunner, Payload, QoSProfile, SharedMemory};

use crate::roles::{Qos, Res, Sink, cpu_ms, flood_done, now_ns};
use crate::stats::Spread;
use crate::{sink_node, source_node};

const CALL_TIMEOUT: Duration = Duration::from_secs(5);

/// Starts a node of parameters `P` as `instance` with these endpoint flags.
async fn start<P: peppy::codegen::NodeParameters>(
    instance: &str,
    ns: &str,
    endpoint: &[&str],
) -> Res<Arc<NodeRunner>> {
    let mut args = vec!["peppy-bench", "--instance-id", instance, "--namespace", ns];
    args.extend_from_slice(endpoint);
    let direct = crate::children::direct_links().map(|d| d.display().to_string());
    if let Some(dir) = &direct {
        args.extend(["--direct-links", dir.as_str()]);
    }
    let shm = if crate::children::shared_memory() {
        SharedMemory::default()
    } else {
        SharedMemory::off()
    };
    let (_, runner) = NodeBuilder::<P>::new()
        .with_runtime_config(None)
        .shared_memory(shm)
        .with_args(args)
        .start()
        .await?;
    Ok(runner)
}

/// Serves pings, echo, flood and the work action until `stop` resolves.
pub(crate) async fn source(ns: &str, listen: &str, stop: impl Future<Output = ()>) -> Res<()> {
    use source_node::consumed_topics::{
        sink_ping_reliable as ping_reliable, sink_ping_sensor as ping_sensor,
    };
    use source_node::emitted_topics::{pong_reliable, pong_sensor, stream};
    use source_node::exposed_services::{echo, flood};

    let runner = start::<source_node::Parameters>(
        "source",
        ns,
        &["--listen", listen, "--bind", "sink@sink"],
    )
    .await?;
    let r = runner.clone();
    tokio::spawn(async move {
        if crate::children::in_place() {
            while let Ok((_, p)) = ping_reliable::on_next_payload_received(&r, None).await {
                let _ = answer_in_place(&r, &pong_reliable::SPEC, &p).await;
            }
        } else {
            while let Ok((_, m)) = ping_reliable::on_next_message_received(&r, None).await {
                let _ = pong_reliable::emit(&r, m.seq, m.sent_ns, m.data).await;
            }
        }
    });
    let r = runner.clone();
    tokio::spawn(async move {
        if crate::children::in_place() {
            while let Ok((_, p)) = ping_sensor::on_next_payload_received(&r, None).await {
                let _ = answer_in_place(&r, &pong_sensor::SPEC, &p).await;
            }
        } else {
            while let Ok((_, m)) = ping_sensor::on_next_message_received(&r, None).await {
                let _ = pong_sensor::emit(&r, m.seq, m.sent_ns, m.data).await;
            }
        }
    });
    let r = runner.clone();
    tokio::spawn(async move {
        while echo::handle_next_request(&r, |request| Ok(echo::Response::new(request.data.data)))
            .await
            .is_ok()
        {}
    });
    let r = runner.clone();
    tokio::spawn(async move {
        loop {
            let mut asked = None;
            let served = flood::handle_next_request(&r, |request| {
                asked = Some((request.data.size, request.data.count, request.data.hz));
                Ok(flood::Response::new(true))
            })
            .await;
            if served.is_err() {
                return;
            }
            if let Some((size, count, hz)) = asked {
                let r = r.clone();
                tokio::spawn(async move {
                    let (cpu_from, started) = (cpu_ms(), Instant::now());
                    let data = vec![3u8; size as usize];
                    let mut tick = (hz > 0.0)
                        .then(|| tokio::time::interval(Duration::from_secs_f64(1.0 / hz)));
                    for seq in 0..u64::from(count) {
                        if let Some(t) = &mut tick {
                            t.tick().await;
                        }
                        if stream::emit(&r, seq, now_ns(), data.clone()).await.is_err() {
                            return;
                        }
                    }
                    flood_done(cpu_from, started);
                });
            }
        }
    });
    let r = runner.clone();
    tokio::spawn(async move {
        use source_node::exposed_actions::work;
        let Ok(mut server) = work::ActionHandle::expose(&r).await else {
            return;
        };
        while let Ok(Some(goal)) = server
            .handle_goal_next_request(|_| Ok(peppy::codegen::GoalResponse::accept()))
            .await
        {
            let n = goal.request().data.n;
            let _ = goal.complete(n).await;
        }
    });
    stop.await;
    runner.shutdown().await;
    Ok(())
}

/// A round-trip message (`seq`, `sent_ns`, `data: bytes`) with its data
/// borrowed, encoded as the generated message is (WIRE.md §5: the fields
/// in order, bytes as a `u32` count and the bytes).
struct FrameView<'a> {
    seq: u64,
    sent_ns: u64,
    data: &'a [u8],
}

impl Encode for FrameView<'_> {
    fn encode(&self, out: &mut Writer<'_>) {
        self.seq.encode(out);
        self.sent_ns.encode(out);
        (self.data.len() as u32).encode(out);
        u8::encode_slice(self.data, out);
    }
}

impl<'a> FrameView<'a> {
    /// The message in `bytes`, its data where it is.
    fn read(bytes: &'a [u8]) -> Result<FrameView<'a>, DecodeError> {
        let mut d = Decoder::new(bytes);
        let seq = u64::decode(&mut d)?;
        let sent_ns = u64::decode(&mut d)?;
        let n = d.count(1)?;
        let data = d.take(n)?;
        Ok(FrameView { seq, sent_ns, data })
    }
}

/// Answers a ping read in place: the pong is encoded from the ping's bytes
/// where they arrived (one copy, into the pong's shared memory).
async fn answer_in_place(r: &NodeRunner, pong: &'static TopicSpec, ping: &Payload) -> Res<()> {
    let bytes = ping.bytes();
    let frame = FrameView::read(&bytes)?;
    Ok(peppy::codegen::emit(r, pong, &frame).await?)
}

/// The measuring end over peppy.
pub(crate) struct PeppySink {
    runner: Arc<NodeRunner>,
}

impl PeppySink {
    /// Starts the sink node as `instance`, its slot pinned to `source`.
    pub(crate) async fn connect(ns: &str, connect: &str, instance: &str) -> Res<PeppySink> {
        let runner = start::<sink_node::Parameters>(
            instance,
            ns,
            &["--connect", connect, "--bind", "source@source"],
        )
        .await?;
        Ok(PeppySink { runner })
    }

    /// Goal to result of the work action, `count` times.
    pub(crate) async fn action_round_trips(&self, count: usize) -> Res<Option<Spread>> {
        use sink_node::consumed_actions::source_work as work;
        let goal = || async {
            let handle = work::ActionHandle::fire_goal(
                &self.runner,
                CALL_TIMEOUT,
                work::GoalRequest::new(1),
                QoSProfile::Standard,
            )
            .await?;
            handle.get_result(CALL_TIMEOUT).await?;
            Res::Ok(())
        };
        let deadline = Instant::now() + Duration::from_secs(20);
        while goal().await.is_err() {
            if Instant::now() > deadline {
                return Err("the work action never answered".into());
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let mut samples = Vec::with_capacity(count);
        for _ in 0..count {
            let start = Instant::now();
            goal().await?;
            samples.push(start.elapsed().as_secs_f64() * 1e6);
        }
        Ok(Spread::of(&mut samples))
    }

    /// Stops the node.
    pub(crate) async fn stop(self) {
        self.runner.shutdown().await;
    }
}

impl Sink for PeppySink {
    async fn ping(&self, qos: Qos, seq: u64, data: Vec<u8>) -> Res<()> {
        use sink_node::emitted_topics::{ping_reliable, ping_sensor};
        let r = &self.runner;
        match qos {
            Qos::Reliable => ping_reliable::emit(r, seq, now_ns(), data).await?,
            Qos::Sensor => ping_sensor::emit(r, seq, now_ns(), data).await?,
        }
        Ok(())
    }

    async fn pong(&self, qos: Qos) -> Res<u64> {
        use sink_node::consumed_topics::{source_pong_reliable, source_pong_sensor};
        let r = &self.runner;
        if crate::children::in_place() {
            let payload = match qos {
                Qos::Reliable => source_pong_reliable::on_next_payload_received(r, None).await?,
                Qos::Sensor => source_pong_sensor::on_next_payload_received(r, None).await?,
            }
            .1;
            return Ok(FrameView::read(&payload.bytes())?.seq);
        }
        Ok(match qos {
            Qos::Reliable => {
                source_pong_reliable::on_next_message_received(r, None)
                    .await?
                    .1
                    .seq
            }
            Qos::Sensor => {
                source_pong_sensor::on_next_message_received(r, None)
                    .await?
                    .1
                    .seq
            }
        })
    }

    async fn flood(&self, size: u32, count: u32, hz: f64) -> Res<()> {
        use sink_node::consumed_services::source_flood;
        source_flood::poll(
            &self.runner,
            CALL_TIMEOUT,
            source_flood::Request::new(size, count, hz),
        )
        .await?;
        Ok(())
    }

    async fn stream(&self) -> Res<(u64, u64, usize)> {
        use sink_node::consumed_topics::source_stream;
        let (_, m) = source_stream::on_next_message_received(&self.runner, None).await?;
        Ok((m.seq, m.sent_ns, m.data.len()))
    }

    async fn echo(&self, data: Vec<u8>) -> Res<usize> {
        use sink_node::consumed_services::source_echo;
        let response =
            source_echo::poll(&self.runner, CALL_TIMEOUT, source_echo::Request::new(data)).await?;
        Ok(response.data.data.len())
    }
}
