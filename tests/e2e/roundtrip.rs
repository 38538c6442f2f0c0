//! Codec round trips of every generated message shape: values from a
//! seeded generator, encoded with the producer's generated types and
//! decoded with the consumer's (and the producer's); truncated payloads
//! are refused, never mis-decoded.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use peppy::codegen::{Decode, Encode};
use peppy::runtime::wire::codec::{from_bytes, to_bytes};

use crate::nodes::{shapes, shapes_client};

use shapes::emitted_topics as e;

/// Deterministic sample messages (xorshift), one generator per seed.
#[derive(Clone, Copy)]
pub(crate) struct Samples {
    seed: u64,
}

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    fn text(&mut self) -> String {
        let n = self.below(12);
        (0..n)
            .map(|_| ['a', 'é', '7', ' ', '漢', '\n'][self.below(6) as usize])
            .collect()
    }
    fn bytes(&mut self) -> Vec<u8> {
        (0..self.below(20)).map(|_| self.next() as u8).collect()
    }
    fn time(&mut self) -> SystemTime {
        let d = Duration::new(self.below(4_000_000_000), self.below(1_000_000_000) as u32);
        if self.below(4) == 0 {
            UNIX_EPOCH - d
        } else {
            UNIX_EPOCH + d
        }
    }
    fn f64(&mut self) -> f64 {
        (self.next() as i64) as f64 / 1024.0
    }
}

impl Samples {
    /// Publishes one message of every shape the `shapes` node emits.
    pub(crate) async fn emit_all(&self, s: &peppy::NodeRunner) -> peppy::Result<()> {
        let m = self.everything();
        e::everything::emit(
            s, m.flag, m.small, m.medium, m.large, m.huge, m.tiny, m.short, m.int, m.long,
            m.single, m.double, m.text, m.blob, m.when,
        )
        .await?;
        let m = self.nested();
        e::nested::emit(
            s, m.header, m.pose, m.mask, m.points, m.names, m.stamps, m.chunks,
        )
        .await?;
        let m = self.optionals();
        e::optionals::emit(s, m.note, m.raw, m.seen, m.samples, m.fixed, m.extra).await?;
        let m = self.keywords();
        e::keywords::emit(
            s,
            m.r#type,
            m.r#match,
            m.r#async,
            m.SPEC,
            m.node_runner,
            m.Mixed_Case,
            m.r#loop,
        )
        .await?;
        e::tick::emit(s).await?;
        e::video_stream::emit(s, vec![9; 3]).await
    }

    /// Reads one message of every shape on `client` (a `shapes_client`)
    /// and checks each is from `producer` and equal to what
    /// [`emit_all`](Self::emit_all) sends.
    pub(crate) async fn expect_all(&self, client: &peppy::NodeRunner, producer: &str) {
        use crate::support::WAIT;
        use shapes_client::consumed_topics as c;
        macro_rules! receive {
            ($module:ident, $expected:expr) => {{
                let (from, got) =
                    tokio::time::timeout(WAIT, c::$module::on_next_message_received(client, None))
                        .await
                        .expect(concat!("a message on ", stringify!($module)))
                        .unwrap();
                assert_eq!(from, producer, stringify!($module));
                assert_eq!(
                    format!("{got:?}"),
                    format!("{:?}", $expected),
                    stringify!($module)
                );
            }};
        }
        receive!(shapes_everything, self.everything());
        receive!(shapes_nested, self.nested());
        receive!(shapes_optionals, self.optionals());
        receive!(shapes_keywords, self.keywords());
        receive!(shapes_tick, e::tick::Message);
        receive!(
            shapes_video_stream,
            e::video_stream::Message { frame: vec![9; 3] }
        );
    }
}

impl Samples {
    pub(crate) fn new(seed: u64) -> Self {
        Samples { seed }
    }

    fn rng(&self, salt: u64) -> Rng {
        Rng((self.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ salt) | 1)
    }

    pub(crate) fn everything(&self) -> e::everything::Message {
        let mut r = self.rng(1);
        e::everything::Message {
            flag: r.below(2) == 1,
            small: r.next() as u8,
            medium: r.next() as u16,
            large: r.next() as u32,
            huge: r.next(),
            tiny: r.next() as i8,
            short: r.next() as i16,
            int: r.next() as i32,
            long: r.next() as i64,
            single: r.f64() as f32,
            double: r.f64(),
            text: r.text(),
            blob: r.bytes(),
            when: r.time(),
        }
    }

    pub(crate) fn nested(&self) -> e::nested::Message {
        let mut r = self.rng(2);
        e::nested::Message {
            header: e::nested::MessageHeader {
                stamp: r.time(),
                frame: e::nested::MessageHeaderFrame {
                    id: r.next() as u32,
                    parent: r.text(),
                },
            },
            pose: std::array::from_fn(|_| r.f64()),
            mask: std::array::from_fn(|_| r.below(2) == 0),
            points: (0..r.below(5))
                .map(|_| e::nested::MessagePointsItem {
                    x: r.f64() as f32,
                    y: r.f64() as f32,
                    label: r.text(),
                })
                .collect(),
            names: (0..r.below(4)).map(|_| r.text()).collect(),
            stamps: (0..r.below(4)).map(|_| r.time()).collect(),
            chunks: (0..r.below(4)).map(|_| r.bytes()).collect(),
        }
    }

    pub(crate) fn optionals(&self) -> e::optionals::Message {
        let mut r = self.rng(3);
        let mut some = || r.below(2) == 0;
        let (a, b, c, d, f, g) = (some(), some(), some(), some(), some(), some());
        e::optionals::Message {
            note: a.then(|| r.text()),
            raw: b.then(|| r.bytes()),
            seen: c.then(|| r.time()),
            samples: d.then(|| (0..r.below(6)).map(|_| r.next() as i16).collect()),
            fixed: f.then(|| std::array::from_fn(|_| r.next() as u8)),
            extra: g.then(|| e::optionals::MessageExtra {
                level: r.next() as u8,
            }),
        }
    }

    pub(crate) fn keywords(&self) -> e::keywords::Message {
        let mut r = self.rng(4);
        e::keywords::Message {
            r#type: r.text(),
            r#match: r.next() as u8,
            r#async: r.below(2) == 0,
            SPEC: r.next() as u8,
            node_runner: r.next() as u8,
            Mixed_Case: r.next() as u8,
            r#loop: e::keywords::MessageLoop {
                r#in: r.next() as u8,
                self_: r.next() as u8,
            },
        }
    }
}

/// Encodes `value`, decodes it as `Same` and as the consumer's `Other`,
/// checks both equal it, and that every strict prefix is refused.
fn round_trip<T, Other>(value: &T)
where
    T: Encode + Decode + PartialEq + std::fmt::Debug,
    Other: Decode + std::fmt::Debug,
{
    let bytes = to_bytes(value);
    let back: T = from_bytes(&bytes).unwrap_or_else(|e| panic!("{value:?}: {e}"));
    assert_eq!(&back, value);
    let other: Other = from_bytes(&bytes).unwrap();
    assert_eq!(format!("{other:?}"), format!("{value:?}"));
    assert!(bytes.len() >= T::MIN_SIZE, "{value:?}");
    for cut in 0..bytes.len() {
        assert!(
            from_bytes::<T>(&bytes[..cut]).is_err(),
            "{value:?} cut at {cut}"
        );
    }
}

#[test]
fn every_shape_round_trips_producer_to_consumer() {
    use shapes_client::consumed_topics as c;
    for seed in 0..300 {
        let s = Samples::new(seed);
        round_trip::<_, c::shapes_everything::Message>(&s.everything());
        round_trip::<_, c::shapes_nested::Message>(&s.nested());
        round_trip::<_, c::shapes_optionals::Message>(&s.optionals());
        round_trip::<_, c::shapes_keywords::Message>(&s.keywords());
    }
    round_trip::<_, c::shapes_tick::Message>(&e::tick::Message);
    round_trip::<_, c::shapes_video_stream::Message>(&e::video_stream::Message {
        frame: vec![1, 2],
    });
}

#[test]
fn service_payloads_round_trip() {
    use shapes::exposed_services::echo;
    use shapes_client::consumed_services::shapes_echo;
    let request = shapes_echo::Request::new("hi".into(), shapes_echo::EchoMeta { id: 7 });
    let bytes = to_bytes(&request);
    let served: echo::RequestData = from_bytes(&bytes).unwrap();
    assert_eq!((served.text.as_str(), served.meta.id), ("hi", 7));
    let response = echo::Response::new("ho".into(), echo::ResponseMeta { id: 8 });
    let data: shapes_echo::ResponseData = from_bytes(&to_bytes(&response)).unwrap();
    assert_eq!((data.text.as_str(), data.meta.id), ("ho", 8));
}

#[test]
fn fingerprints_match_across_sides_and_differ_across_formats() {
    // The same canonical format on both sides of the wire, and a golden
    // byte layout for one message (docs/WIRE.md).
    let m = e::video_stream::Message { frame: vec![5, 6] };
    assert_eq!(to_bytes(&m), [2, 0, 0, 0, 5, 6]);
    let header =
        crate::nodes::zed_2i::emitted_topics::depth_camera::v1::video_stream::MessageHeader {
            stamp: UNIX_EPOCH + Duration::new(1, 2),
            frame_id: 3,
        };
    assert_eq!(
        to_bytes(&header),
        [1, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0]
    );
}
