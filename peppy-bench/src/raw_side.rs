//! The same work over raw Zenoh, the baseline every peppy figure is divided
//! by: the same session mode and endpoints, the same QoS settings per
//! profile (WIRE.md §7), and the same decoding into owned data and encoding
//! back that a typed consumer does.

use std::sync::Arc;

use tokio::sync::Mutex;
use zenoh::Session;
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::query::ConsolidationMode;
use zenoh::sample::Sample;

use crate::roles::{Qos, Res, Sink, cpu_ms, flood_done, now_ns};

/// A peer session on explicit loopback endpoints, no scouting; Zenoh's
/// shared-memory transport on or off as the run asks.
pub(crate) async fn open(listen: Option<&str>, connect: Option<&str>) -> Res<Session> {
    let mut c = zenoh::Config::default();
    c.insert_json5("mode", "\"peer\"")?;
    c.insert_json5("scouting/multicast/enabled", "false")?;
    c.insert_json5(
        "transport/shared_memory/enabled",
        &crate::children::shared_memory().to_string(),
    )?;
    if crate::children::lowlatency() {
        c.insert_json5("transport/unicast/lowlatency", "true")?;
        c.insert_json5("transport/unicast/qos/enabled", "false")?;
    }
    if let Some(l) = listen {
        c.insert_json5("listen/endpoints", &format!("[\"{l}\"]"))?;
    }
    if let Some(e) = connect {
        c.insert_json5("connect/endpoints", &format!("[\"{e}\"]"))?;
    }
    zenoh::open(c).await
}

/// The baseline's own keys: raw Zenoh with no peppy in it, so not
/// `wire::keys` (a peppy key's owner, core and instance mean nothing here).
fn key(ns: &str, what: &str) -> String {
    format!("bench/{ns}/{what}")
}

fn qos_key(qos: Qos) -> &'static str {
    match qos {
        Qos::Reliable => "reliable",
        Qos::Sensor => "sensor",
    }
}

/// A publisher with the profile's settings, as peppy's runtime declares it.
async fn publisher(s: &Session, key: String, qos: Qos) -> Res<Publisher<'static>> {
    let (congestion, priority, express) = match qos {
        Qos::Reliable => (CongestionControl::Block, Priority::DataHigh, false),
        Qos::Sensor => (CongestionControl::Drop, Priority::DataLow, true),
    };
    s.declare_publisher(key)
        .congestion_control(congestion)
        .priority(priority)
        .express(express)
        .await
}

/// `seq`, `sent_ns`, then the data.
fn encode(seq: u64, sent_ns: u64, data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(16 + data.len());
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&sent_ns.to_le_bytes());
    out.extend_from_slice(data);
    out
}

/// The message back, its data owned, as a typed consumer holds it.
fn decode(sample: &Sample) -> Res<(u64, u64, Vec<u8>)> {
    let bytes = sample.payload().to_bytes();
    let (seq, sent, data) = split(&bytes)?;
    Ok((seq, sent, data.to_vec()))
}

/// The message's header and its data where they are (in the sender's
/// shared memory when it came that way).
fn split(bytes: &[u8]) -> Res<(u64, u64, &[u8])> {
    if bytes.len() < 16 {
        return Err("a message shorter than its header".into());
    }
    let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"));
    Ok((word(0), word(8), &bytes[16..]))
}

/// Serves pings, the echo and flood queries until `stop` resolves.
pub(crate) async fn source(ns: &str, listen: &str, stop: impl Future<Output = ()>) -> Res<()> {
    let session = open(Some(listen), None).await?;
    for qos in [Qos::Reliable, Qos::Sensor] {
        let pong = publisher(&session, key(ns, &format!("pong/{}", qos_key(qos))), qos).await?;
        let pings = session
            .declare_subscriber(key(ns, &format!("ping/{}", qos_key(qos))))
            .await?;
        tokio::spawn(async move {
            while let Ok(sample) = pings.recv_async().await {
                let answer = if crate::children::in_place() {
                    let bytes = sample.payload().to_bytes();
                    split(&bytes).map(|(seq, sent, data)| encode(seq, sent, data))
                } else {
                    decode(&sample).map(|(seq, sent, data)| encode(seq, sent, &data))
                };
                if let Ok(answer) = answer {
                    let _ = pong.put(answer).await;
                }
            }
        });
    }
    let stream = Arc::new(publisher(&session, key(ns, "stream"), Qos::Reliable).await?);
    let echo = session.declare_queryable(key(ns, "echo")).await?;
    let echo_key = key(ns, "echo");
    tokio::spawn(async move {
        while let Ok(query) = echo.recv_async().await {
            let data = query
                .payload()
                .map(|p| p.to_bytes().to_vec())
                .unwrap_or_default();
            let _ = query.reply(echo_key.as_str(), data).await;
        }
    });
    let flood = session.declare_queryable(key(ns, "flood")).await?;
    let flood_key = key(ns, "flood");
    tokio::spawn(async move {
        while let Ok(query) = flood.recv_async().await {
            let asked = query
                .payload()
                .map(|p| p.to_bytes().to_vec())
                .unwrap_or_default();
            let Some((size, count, hz)) = parse_flood(&asked) else {
                continue;
            };
            let _ = query.reply(flood_key.as_str(), vec![1u8]).await;
            tokio::spawn(stream_frames(stream.clone(), size, count, hz));
        }
    });
    stop.await;
    session.close().await?;
    Ok(())
}

/// A flood request: size (u32), count (u32), rate (f64), little-endian.
fn flood_request(size: u32, count: u32, hz: f64) -> Vec<u8> {
    let mut b = size.to_le_bytes().to_vec();
    b.extend_from_slice(&count.to_le_bytes());
    b.extend_from_slice(&hz.to_le_bytes());
    b
}

fn parse_flood(b: &[u8]) -> Option<(u32, u32, f64)> {
    Some((
        u32::from_le_bytes(b.get(0..4)?.try_into().ok()?),
        u32::from_le_bytes(b.get(4..8)?.try_into().ok()?),
        f64::from_le_bytes(b.get(8..16)?.try_into().ok()?),
    ))
}

async fn stream_frames(stream: Arc<Publisher<'static>>, size: u32, count: u32, hz: f64) {
    let (cpu_from, started) = (cpu_ms(), std::time::Instant::now());
    let data = vec![3u8; size as usize];
    let mut tick =
        (hz > 0.0).then(|| tokio::time::interval(std::time::Duration::from_secs_f64(1.0 / hz)));
    for seq in 0..u64::from(count) {
        if let Some(t) = &mut tick {
            t.tick().await;
        }
        if stream.put(encode(seq, now_ns(), &data)).await.is_err() {
            return;
        }
    }
    flood_done(cpu_from, started);
}

/// The measuring end over raw Zenoh.
pub(crate) struct RawSink {
    session: Session,
    ns: String,
    pings: [Publisher<'static>; 2],
    pongs: [Mutex<Subscriber<FifoChannelHandler<Sample>>>; 2],
    stream: Mutex<Subscriber<FifoChannelHandler<Sample>>>,
}

impl RawSink {
    /// Connects to the source at `connect`.
    pub(crate) async fn connect(ns: &str, connect: &str) -> Res<RawSink> {
        let session = open(None, Some(connect)).await?;
        let ping = |qos| publisher(&session, key(ns, &format!("ping/{}", qos_key(qos))), qos);
        let pong = |qos| session.declare_subscriber(key(ns, &format!("pong/{}", qos_key(qos))));
        let pings = [ping(Qos::Reliable).await?, ping(Qos::Sensor).await?];
        let pongs = [
            Mutex::new(pong(Qos::Reliable).await?),
            Mutex::new(pong(Qos::Sensor).await?),
        ];
        let stream = Mutex::new(session.declare_subscriber(key(ns, "stream")).await?);
        Ok(RawSink {
            ns: ns.to_string(),
            pings,
            pongs,
            stream,
            session,
        })
    }

    fn at(qos: Qos) -> usize {
        match qos {
            Qos::Reliable => 0,
            Qos::Sensor => 1,
        }
    }

    async fn query(&self, what: &str, payload: Vec<u8>) -> Res<Vec<u8>> {
        let replies = self
            .session
            .get(key(&self.ns, what))
            .payload(payload)
            // As peppy's requests: replies as they come, not held for the
            // query's end.
            .consolidation(ConsolidationMode::None)
            .timeout(std::time::Duration::from_secs(5))
            .await?;
        let reply = replies.recv_async().await?;
        let sample = reply.result().map_err(|e| format!("error reply: {e:?}"))?;
        Ok(sample.payload().to_bytes().to_vec())
    }
}

impl Sink for RawSink {
    async fn ping(&self, qos: Qos, seq: u64, data: Vec<u8>) -> Res<()> {
        self.pings[Self::at(qos)]
            .put(encode(seq, now_ns(), &data))
            .await
    }

    async fn pong(&self, qos: Qos) -> Res<u64> {
        let sample = self.pongs[Self::at(qos)].lock().await.recv_async().await?;
        if crate::children::in_place() {
            return Ok(split(&sample.payload().to_bytes())?.0);
        }
        Ok(decode(&sample)?.0)
    }

    async fn flood(&self, size: u32, count: u32, hz: f64) -> Res<()> {
        self.query("flood", flood_request(size, count, hz)).await?;
        Ok(())
    }

    async fn stream(&self) -> Res<(u64, u64, usize)> {
        let sample = self.stream.lock().await.recv_async().await?;
        let (seq, sent, data) = decode(&sample)?;
        Ok((seq, sent, data.len()))
    }

    async fn echo(&self, data: Vec<u8>) -> Res<usize> {
        Ok(self.query("echo", data).await?.len())
    }
}
