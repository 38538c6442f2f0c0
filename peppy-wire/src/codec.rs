//! The payload encoding: fields in declaration order, little-endian, no
//! field names, no padding. See docs/WIRE.md for the byte layout.
//!
//! Generated message structs implement [`Encode`] and [`Decode`] by
//! encoding their fields in order; everything schema-independent is here.
//! Decoding never panics and never allocates more than the input could
//! hold: every length is checked against the bytes that remain.

use std::fmt;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Why bytes could not be decoded as a message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DecodeError {
    /// Byte offset where decoding failed.
    pub offset: usize,
    /// What was wrong there.
    pub reason: String,
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "invalid payload at byte {}: {}",
            self.offset, self.reason
        )
    }
}

impl std::error::Error for DecodeError {}

/// Reads values from a payload.
#[derive(Debug)]
pub struct Decoder<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Decoder<'a> {
    /// Starts at the first byte.
    pub fn new(bytes: &'a [u8]) -> Self {
        Decoder { bytes, pos: 0 }
    }

    /// Bytes not yet read.
    pub fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    /// An error at the current position.
    pub fn error(&self, reason: impl Into<String>) -> DecodeError {
        DecodeError {
            offset: self.pos,
            reason: reason.into(),
        }
    }

    /// The next `n` bytes.
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], DecodeError> {
        if n > self.remaining() {
            return Err(self.error(format!("needs {n} more bytes, {} left", self.remaining())));
        }
        let out = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], DecodeError> {
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(N)?);
        Ok(out)
    }

    /// A `u32` element count, checked against what the remaining bytes can hold.
    pub fn count(&mut self, min_item_size: usize) -> Result<usize, DecodeError> {
        let at = self.pos;
        let n = u32::from_le_bytes(self.array()?) as usize;
        if n.saturating_mul(min_item_size.max(1)) > self.remaining() && min_item_size > 0 {
            return Err(DecodeError {
                offset: at,
                reason: format!(
                    "length {n} exceeds the {} bytes that remain",
                    self.remaining()
                ),
            });
        }
        Ok(n)
    }

    /// Fails unless every byte was consumed.
    pub fn finish(self) -> Result<(), DecodeError> {
        if self.remaining() == 0 {
            Ok(())
        } else {
            Err(self.error(format!("{} unexpected trailing bytes", self.remaining())))
        }
    }
}

/// Where an encoder writes: a growing `Vec`, a buffer sized in advance
/// (a shared-memory chunk, written in place), or nowhere, only counting,
/// to size that buffer.
#[derive(Debug)]
pub struct Writer<'a> {
    target: Target<'a>,
}

#[derive(Debug)]
enum Target<'a> {
    Grow(&'a mut Vec<u8>),
    Fill {
        buf: &'a mut [u8],
        at: usize,
        overflow: bool,
    },
    Count(usize),
}

impl<'a> Writer<'a> {
    /// Appends to `out`.
    pub fn new(out: &'a mut Vec<u8>) -> Self {
        Writer {
            target: Target::Grow(out),
        }
    }

    /// Writes into `buf` from its first byte; see [`Writer::filled`].
    pub fn fill(buf: &'a mut [u8]) -> Self {
        Writer {
            target: Target::Fill {
                buf,
                at: 0,
                overflow: false,
            },
        }
    }

    /// Counts the bytes written without storing them.
    pub fn count() -> Writer<'static> {
        Writer {
            target: Target::Count(0),
        }
    }

    /// Writes `bytes`.
    #[inline]
    pub fn put(&mut self, bytes: &[u8]) {
        match &mut self.target {
            Target::Grow(out) => out.extend_from_slice(bytes),
            Target::Fill { buf, at, overflow } => match buf.get_mut(*at..*at + bytes.len()) {
                Some(dst) => {
                    dst.copy_from_slice(bytes);
                    *at += bytes.len();
                }
                None => *overflow = true,
            },
            Target::Count(n) => *n += bytes.len(),
        }
    }

    /// Writes one byte.
    #[inline]
    pub fn put_u8(&mut self, byte: u8) {
        match &mut self.target {
            Target::Grow(out) => out.push(byte),
            _ => self.put(&[byte]),
        }
    }

    /// Bytes written (or counted) so far.
    pub fn len(&self) -> usize {
        match &self.target {
            Target::Grow(out) => out.len(),
            Target::Fill { at, .. } => *at,
            Target::Count(n) => *n,
        }
    }

    /// Whether nothing has been written yet.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// For a [`Writer::fill`]: whether the value filled the buffer exactly.
    /// An `Encode` impl that writes more (or less) than it counted leaves
    /// the buffer unusable; the caller then encodes into a `Vec` instead.
    pub fn filled(&self) -> bool {
        match &self.target {
            Target::Fill { buf, at, overflow } => !overflow && *at == buf.len(),
            _ => false,
        }
    }
}

/// A value that can be written to a payload.
pub trait Encode {
    /// Writes the value's bytes.
    fn encode(&self, out: &mut Writer<'_>);

    /// Writes a slice of values (bytes are copied in one go).
    fn encode_slice(items: &[Self], out: &mut Writer<'_>)
    where
        Self: Sized,
    {
        for item in items {
            item.encode(out);
        }
    }
}

/// A value that can be read from a payload.
pub trait Decode: Sized {
    /// The fewest bytes an encoded value takes (bounds allocations).
    const MIN_SIZE: usize;

    /// Reads one value.
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError>;

    /// Reads `n` values (bytes are copied in one go).
    fn decode_vec(d: &mut Decoder<'_>, n: usize) -> Result<Vec<Self>, DecodeError> {
        let mut out = Vec::with_capacity(n);
        for _ in 0..n {
            out.push(Self::decode(d)?);
        }
        Ok(out)
    }
}

/// An already encoded message body: written as is and read as every
/// remaining byte. Lets tools that encode and decode from a format's text
/// (no generated types) use the typed request paths.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Raw(pub Vec<u8>);

impl Encode for Raw {
    fn encode(&self, out: &mut Writer<'_>) {
        out.put(&self.0);
    }
}

impl Decode for Raw {
    const MIN_SIZE: usize = 0;

    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        Ok(Raw(d.take(d.remaining())?.to_vec()))
    }
}

/// Encodes a whole message.
pub fn to_bytes<T: Encode + ?Sized>(value: &T) -> Vec<u8> {
    let mut out = Vec::new();
    value.encode(&mut Writer::new(&mut out));
    out
}

/// The number of bytes [`to_bytes`] would return, without encoding.
pub fn encoded_len<T: Encode + ?Sized>(value: &T) -> usize {
    let mut w = Writer::count();
    value.encode(&mut w);
    w.len()
}

/// Decodes a whole message; trailing bytes are an error.
pub fn from_bytes<T: Decode>(bytes: &[u8]) -> Result<T, DecodeError> {
    let mut d = Decoder::new(bytes);
    let v = T::decode(&mut d)?;
    d.finish()?;
    Ok(v)
}

macro_rules! numbers {
    ($($t:ty),*) => {$(
        impl Encode for $t {
            #[inline]
            fn encode(&self, out: &mut Writer<'_>) {
                out.put(&self.to_le_bytes());
            }
        }
        impl Decode for $t {
            const MIN_SIZE: usize = std::mem::size_of::<$t>();
            fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
                Ok(<$t>::from_le_bytes(d.array()?))
            }
        }
    )*};
}
numbers!(u16, u32, u64, i8, i16, i32, i64, f32, f64);

impl Encode for u8 {
    fn encode(&self, out: &mut Writer<'_>) {
        out.put_u8(*self);
    }
    fn encode_slice(items: &[Self], out: &mut Writer<'_>) {
        out.put(items);
    }
}

impl Decode for u8 {
    const MIN_SIZE: usize = 1;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        Ok(d.take(1)?[0])
    }
    fn decode_vec(d: &mut Decoder<'_>, n: usize) -> Result<Vec<Self>, DecodeError> {
        Ok(d.take(n)?.to_vec())
    }
}

impl Encode for bool {
    fn encode(&self, out: &mut Writer<'_>) {
        out.put_u8(u8::from(*self));
    }
}

impl Decode for bool {
    const MIN_SIZE: usize = 1;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        match d.take(1)?[0] {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(DecodeError {
                offset: d.pos - 1,
                reason: format!("bool byte is {b}, expected 0 or 1"),
            }),
        }
    }
}

impl Encode for String {
    fn encode(&self, out: &mut Writer<'_>) {
        self.as_str().encode(out);
    }
}

impl Encode for str {
    fn encode(&self, out: &mut Writer<'_>) {
        (self.len() as u32).encode(out);
        out.put(self.as_bytes());
    }
}

impl Decode for String {
    const MIN_SIZE: usize = 4;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        let n = d.count(1)?;
        let at = d.pos;
        let bytes = d.take(n)?;
        String::from_utf8(bytes.to_vec()).map_err(|e| DecodeError {
            offset: at + e.utf8_error().valid_up_to(),
            reason: "string is not valid UTF-8".into(),
        })
    }
}

impl Encode for SystemTime {
    fn encode(&self, out: &mut Writer<'_>) {
        let (secs, nanos) = match self.duration_since(UNIX_EPOCH) {
            Ok(d) => (d.as_secs() as i64, d.subsec_nanos()),
            Err(e) => {
                // Before the epoch: floor seconds, positive nanoseconds.
                let d = e.duration();
                // Wrapping: 2^63 seconds before the epoch is `i64::MIN`,
                // whose negation overflows (a time the decoder gives).
                let secs = (d.as_secs() as i64).wrapping_neg();
                match d.subsec_nanos() {
                    0 => (secs, 0),
                    n => (secs - 1, 1_000_000_000 - n),
                }
            }
        };
        secs.encode(out);
        nanos.encode(out);
    }
}

impl Decode for SystemTime {
    const MIN_SIZE: usize = 12;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        let at = d.pos;
        let secs = i64::decode(d)?;
        let nanos = u32::decode(d)?;
        let bad = |reason: &str| DecodeError {
            offset: at,
            reason: reason.into(),
        };
        if nanos >= 1_000_000_000 {
            return Err(bad("time nanoseconds out of range"));
        }
        let t = if secs >= 0 {
            UNIX_EPOCH.checked_add(Duration::new(secs as u64, nanos))
        } else {
            UNIX_EPOCH
                .checked_sub(Duration::from_secs(secs.unsigned_abs()))
                .and_then(|t| t.checked_add(Duration::from_nanos(u64::from(nanos))))
        };
        t.ok_or_else(|| bad("time out of range for this platform"))
    }
}

impl<T: Encode> Encode for Vec<T> {
    fn encode(&self, out: &mut Writer<'_>) {
        (self.len() as u32).encode(out);
        T::encode_slice(self, out);
    }
}

impl<T: Decode> Decode for Vec<T> {
    const MIN_SIZE: usize = 4;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        let n = d.count(T::MIN_SIZE)?;
        T::decode_vec(d, n)
    }
}

impl<T: Encode, const N: usize> Encode for [T; N] {
    fn encode(&self, out: &mut Writer<'_>) {
        T::encode_slice(self, out);
    }
}

impl<T: Decode, const N: usize> Decode for [T; N] {
    const MIN_SIZE: usize = T::MIN_SIZE * N;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        if T::MIN_SIZE.saturating_mul(N) > d.remaining() {
            return Err(d.error(format!(
                "fixed array of {N} needs more bytes than the {} left",
                d.remaining()
            )));
        }
        let items = T::decode_vec(d, N)?;
        items.try_into().map_err(|_| d.error("fixed array length"))
    }
}

impl<T: Encode> Encode for Option<T> {
    fn encode(&self, out: &mut Writer<'_>) {
        match self {
            None => out.put_u8(0),
            Some(v) => {
                out.put_u8(1);
                v.encode(out);
            }
        }
    }
}

impl<T: Decode> Decode for Option<T> {
    const MIN_SIZE: usize = 1;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        match d.take(1)?[0] {
            0 => Ok(None),
            1 => T::decode(d).map(Some),
            b => Err(DecodeError {
                offset: d.pos - 1,
                reason: format!("presence byte is {b}, expected 0 or 1"),
            }),
        }
    }
}

/// A fixed-size array that travels as a variable one: a field whose length
/// a node pins with `refine` (the current `node/v1` spelling). The node's
/// type is `[T; N]`, the wire that of the open array the document declares
/// (a `u32` count, then the items), so every other node reads it; a count
/// other than `N` does not decode.
pub trait Counted: Sized {
    /// The fewest bytes a value takes.
    const MIN_COUNTED_SIZE: usize;
    /// Writes the value as a counted array.
    fn encode_counted(&self, out: &mut Writer<'_>);
    /// Reads a counted array of exactly the pinned length.
    fn decode_counted(d: &mut Decoder<'_>) -> Result<Self, DecodeError>;
}

impl<T: Encode + Decode, const N: usize> Counted for [T; N] {
    const MIN_COUNTED_SIZE: usize = 4 + T::MIN_SIZE * N;

    fn encode_counted(&self, out: &mut Writer<'_>) {
        (N as u32).encode(out);
        T::encode_slice(self, out);
    }

    fn decode_counted(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        let at = d.pos;
        let n = d.count(T::MIN_SIZE)?;
        if n != N {
            return Err(DecodeError {
                offset: at,
                reason: format!("{n} items where this node's `refine` pins {N}"),
            });
        }
        let items = T::decode_vec(d, N)?;
        items.try_into().map_err(|_| d.error("fixed array length"))
    }
}

impl<C: Counted> Counted for Option<C> {
    const MIN_COUNTED_SIZE: usize = 1;

    fn encode_counted(&self, out: &mut Writer<'_>) {
        match self {
            None => out.put_u8(0),
            Some(v) => {
                out.put_u8(1);
                v.encode_counted(out);
            }
        }
    }

    fn decode_counted(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        match d.take(1)?[0] {
            0 => Ok(None),
            1 => C::decode_counted(d).map(Some),
            b => Err(DecodeError {
                offset: d.pos - 1,
                reason: format!("presence byte is {b}, expected 0 or 1"),
            }),
        }
    }
}

/// Two values, one after the other (a reply made of a status and a detail).
impl<A: Encode, B: Encode> Encode for (A, B) {
    fn encode(&self, out: &mut Writer<'_>) {
        self.0.encode(out);
        self.1.encode(out);
    }
}

/// Three values, one after the other (a record of the core node's replies).
impl<A: Encode, B: Encode, C: Encode> Encode for (A, B, C) {
    fn encode(&self, out: &mut Writer<'_>) {
        self.0.encode(out);
        self.1.encode(out);
        self.2.encode(out);
    }
}

impl<A: Decode, B: Decode, C: Decode> Decode for (A, B, C) {
    const MIN_SIZE: usize = A::MIN_SIZE + B::MIN_SIZE + C::MIN_SIZE;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        Ok((A::decode(d)?, B::decode(d)?, C::decode(d)?))
    }
}

/// A message with no payload.
impl Encode for () {
    fn encode(&self, _: &mut Writer<'_>) {}
}

impl Decode for () {
    const MIN_SIZE: usize = 0;
    fn decode(_: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bytes of a message of the golden vectors the Rust and Python
    /// runtimes share (`tests/golden/wire.json`).
    fn golden_bytes(name: &str) -> Vec<u8> {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/golden/wire.json");
        let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let golden: serde_json::Value = serde_json::from_str(&text).unwrap();
        let message = golden["messages"]
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["name"] == name)
            .unwrap_or_else(|| panic!("no golden message `{name}`"));
        let digits: String = message["hex"]
            .as_str()
            .unwrap()
            .split_whitespace()
            .collect();
        (0..digits.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&digits[i..i + 2], 16).unwrap())
            .collect()
    }

    /// docs/WIRE.md's example through the typed codec generated code uses
    /// (the launcher's tests check every golden message from its format
    /// text).
    #[test]
    fn golden_bytes_of_every_primitive() {
        let mut bytes = Vec::new();
        let mut out = Writer::new(&mut bytes);
        true.encode(&mut out);
        7u8.encode(&mut out);
        0x0102u16.encode(&mut out);
        (-2i32).encode(&mut out);
        1.5f32.encode(&mut out);
        "hé".encode(&mut out);
        vec![1u8, 2].encode(&mut out);
        [1u16, 2].encode(&mut out);
        Some(3u8).encode(&mut out);
        None::<u8>.encode(&mut out);
        (UNIX_EPOCH + Duration::new(2, 5)).encode(&mut out);
        let golden = golden_bytes("wire_md_example");
        assert_eq!(bytes, golden);
        let mut d = Decoder::new(&golden);
        assert!(bool::decode(&mut d).unwrap());
        assert_eq!(u8::decode(&mut d).unwrap(), 7);
        assert_eq!(u16::decode(&mut d).unwrap(), 0x0102);
        assert_eq!(i32::decode(&mut d).unwrap(), -2);
        assert_eq!(f32::decode(&mut d).unwrap(), 1.5);
        assert_eq!(String::decode(&mut d).unwrap(), "hé");
        assert_eq!(Vec::<u8>::decode(&mut d).unwrap(), [1, 2]);
        assert_eq!(<[u16; 2]>::decode(&mut d).unwrap(), [1, 2]);
        assert_eq!(Option::<u8>::decode(&mut d).unwrap(), Some(3));
        assert_eq!(Option::<u8>::decode(&mut d).unwrap(), None);
        let time = SystemTime::decode(&mut d).unwrap();
        assert_eq!(time, UNIX_EPOCH + Duration::new(2, 5));
        d.finish().unwrap();
    }

    #[test]
    fn time_before_the_epoch_round_trips() {
        let t = UNIX_EPOCH - Duration::new(1, 250);
        let bytes = to_bytes(&t);
        assert_eq!(&bytes[..8], &(-2i64).to_le_bytes());
        assert_eq!(from_bytes::<SystemTime>(&bytes).unwrap(), t);
        // The earliest time the wire holds, where this platform holds it.
        let earliest: Vec<u8> = i64::MIN.to_le_bytes().into_iter().chain([0; 4]).collect();
        if let Ok(t) = from_bytes::<SystemTime>(&earliest) {
            assert_eq!(to_bytes(&t), earliest);
        }
    }

    #[test]
    fn hostile_lengths_fail_without_allocating() {
        let err = from_bytes::<Vec<u64>>(&[0xff, 0xff, 0xff, 0xff, 1, 2]).unwrap_err();
        assert!(err.reason.contains("exceeds"), "{err}");
        assert!(from_bytes::<String>(&[2, 0, 0, 0, 0xff, 0xfe]).is_err());
        assert!(from_bytes::<bool>(&[2]).is_err());
        assert!(from_bytes::<Option<u8>>(&[9, 1]).is_err());
        assert!(from_bytes::<[u32; 4]>(&[1, 2, 3]).is_err());
        assert!(
            from_bytes::<SystemTime>(&[0; 8].iter().chain(&[0xff; 4]).copied().collect::<Vec<_>>())
                .is_err()
        );
        let trailing = from_bytes::<u8>(&[1, 2]).unwrap_err();
        assert!(trailing.reason.contains("trailing"));
    }
}

#[cfg(test)]
mod properties {
    use super::*;
    use proptest::prelude::*;

    #[derive(Debug, Clone, PartialEq)]
    struct Frame {
        stamp: SystemTime,
        id: u32,
        encoding: String,
        pose: [f64; 3],
        data: Vec<u8>,
        points: Vec<(f32, i16)>,
        note: Option<String>,
        flag: bool,
    }

    impl Encode for Frame {
        fn encode(&self, out: &mut Writer<'_>) {
            self.stamp.encode(out);
            self.id.encode(out);
            self.encoding.encode(out);
            self.pose.encode(out);
            self.data.encode(out);
            (self.points.len() as u32).encode(out);
            for (x, y) in &self.points {
                x.encode(out);
                y.encode(out);
            }
            self.note.encode(out);
            self.flag.encode(out);
        }
    }

    impl Decode for Frame {
        const MIN_SIZE: usize = 12 + 4 + 4 + 24 + 4 + 4 + 1 + 1;
        fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
            let stamp = Decode::decode(d)?;
            let id = Decode::decode(d)?;
            let encoding = Decode::decode(d)?;
            let pose = Decode::decode(d)?;
            let data = Decode::decode(d)?;
            let n = d.count(6)?;
            let mut points = Vec::with_capacity(n);
            for _ in 0..n {
                points.push((f32::decode(d)?, i16::decode(d)?));
            }
            Ok(Frame {
                stamp,
                id,
                encoding,
                pose,
                data,
                points,
                note: Decode::decode(d)?,
                flag: Decode::decode(d)?,
            })
        }
    }

    fn frame() -> impl Strategy<Value = Frame> {
        (
            (any::<u32>(), 0u32..1_000_000_000, any::<bool>()),
            any::<u32>(),
            ".{0,16}",
            proptest::array::uniform3(-1e9f64..1e9),
            proptest::collection::vec(any::<u8>(), 0..64),
            proptest::collection::vec((-1e6f32..1e6, any::<i16>()), 0..8),
            proptest::option::of(".{0,8}"),
            any::<bool>(),
        )
            .prop_map(
                |((secs, nanos, before), id, encoding, pose, data, points, note, flag)| {
                    let offset = Duration::new(u64::from(secs), nanos);
                    let stamp = if before {
                        UNIX_EPOCH - offset
                    } else {
                        UNIX_EPOCH + offset
                    };
                    Frame {
                        stamp,
                        id,
                        encoding,
                        pose,
                        data,
                        points,
                        note,
                        flag,
                    }
                },
            )
    }

    proptest! {
        #[test]
        fn every_message_round_trips(f in frame()) {
            prop_assert_eq!(from_bytes::<Frame>(&to_bytes(&f)).unwrap(), f);
        }

        #[test]
        fn counting_and_filling_agree_with_a_vec(f in frame()) {
            let bytes = to_bytes(&f);
            prop_assert_eq!(encoded_len(&f), bytes.len());
            let mut buf = vec![0xAA; bytes.len()];
            let mut w = Writer::fill(&mut buf);
            f.encode(&mut w);
            prop_assert!(w.filled());
            prop_assert_eq!(&buf, &bytes);
            // One byte short: the writer says so instead of panicking.
            let mut short = vec![0; bytes.len() - 1];
            let mut w = Writer::fill(&mut short);
            f.encode(&mut w);
            prop_assert!(!w.filled());
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
            let _ = from_bytes::<Frame>(&bytes);
            let _ = from_bytes::<Vec<String>>(&bytes);
            let _ = from_bytes::<Option<Vec<[u64; 2]>>>(&bytes);
            let _ = from_bytes::<SystemTime>(&bytes);
        }

        #[test]
        fn truncated_messages_are_errors(f in frame(), cut in any::<prop::sample::Index>()) {
            let bytes = to_bytes(&f);
            let at = cut.index(bytes.len());
            prop_assert!(from_bytes::<Frame>(&bytes[..at]).is_err());
        }
    }
}
