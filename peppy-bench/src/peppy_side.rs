//! The work over peppy: two nodes generated from `nodes/*.json5`, talking
//! through the sink's pinned slot `source`, with the generated functions a
//! node's code calls.

use std::sync::Arc;
use std::time::{Duration, Instant};

use peppy::{NodeBuilder, NodeRunner, QoSProfile, SharedMemory};

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
    use source_node::consumed_topics::{ping_reliable, ping_sensor};
    use source_node::emitted_topics::{pong_reliable, pong_sensor, stream};
    use source_node::exposed_services::{echo, flood};

    let runner = start::<source_node::Parameters>("source", ns, &["--listen", listen]).await?;
    let r = runner.clone();
    tokio::spawn(async move {
        while let Ok((_, m)) = ping_reliable::on_next_message_received(&r, None, None).await {
            let _ = pong_reliable::emit(&r, m.seq, m.sent_ns, m.data).await;
        }
    });
    let r = runner.clone();
    tokio::spawn(async move {
        while let Ok((_, m)) = ping_sensor::on_next_message_received(&r, None, None).await {
            let _ = pong_sensor::emit(&r, m.seq, m.sent_ns, m.data).await;
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
