//! Attachments: the small binary header that travels beside each payload.
//!
//! Every attachment starts with the protocol version byte [`VERSION`]. A
//! sample or query without a valid attachment is dropped and logged. The
//! golden bytes of every attachment are shared with the Python runtime
//! (`tests/golden/wire.json`, checked by `tests/runtime/golden.rs`).

/// Wire protocol version carried in every attachment.
pub const VERSION: u8 = 1;

/// On a topic publication: the format fingerprint of the payload.
pub fn topic(fingerprint: u64) -> Vec<u8> {
    let mut out = Vec::with_capacity(9);
    out.push(VERSION);
    out.extend_from_slice(&fingerprint.to_be_bytes());
    out
}

/// The attachment of the empty publication that ends a goal's feedback
/// stream (docs/WIRE.md §4): no fingerprint, so no feedback reader takes it
/// for a message.
pub const END_OF_FEEDBACK: [u8; 2] = [VERSION, 0xEE];

/// Reads a topic attachment's fingerprint.
pub fn parse_topic(bytes: &[u8]) -> Option<u64> {
    match bytes {
        [VERSION, rest @ ..] if rest.len() == 8 => Some(u64::from_be_bytes(rest.try_into().ok()?)),
        _ => None,
    }
}

/// What a query asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QueryKind {
    /// Run the handler.
    Request = 0,
    /// Only say you are there (discovery for unbound `from_any` slots).
    Probe = 1,
}

/// A query's header: kind, request fingerprint and the caller's identity.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct QueryHeader {
    /// Request or probe.
    pub kind: QueryKind,
    /// Fingerprint of the request payload's format.
    pub fingerprint: u64,
    /// The caller's core node.
    pub core: String,
    /// The caller's instance id.
    pub instance: String,
}

impl QueryHeader {
    /// Encodes the header.
    pub fn encode(&self) -> Vec<u8> {
        Self::encode_parts(self.kind, self.fingerprint, &self.core, &self.instance)
    }

    /// Encodes a header from its parts, as [`QueryHeader::encode`] does,
    /// without owning them first.
    pub fn encode_parts(kind: QueryKind, fingerprint: u64, core: &str, instance: &str) -> Vec<u8> {
        let text = |s: &str| s.len().min(255);
        let mut out = Vec::with_capacity(12 + text(core) + text(instance));
        out.extend_from_slice(&[VERSION, kind as u8]);
        out.extend_from_slice(&fingerprint.to_be_bytes());
        for s in [core, instance] {
            let bytes = &s.as_bytes()[..text(s)];
            out.push(bytes.len() as u8);
            out.extend_from_slice(bytes);
        }
        out
    }

    /// Decodes a header; `None` for anything malformed.
    pub fn decode(bytes: &[u8]) -> Option<QueryHeader> {
        let [VERSION, kind, rest @ ..] = bytes else {
            return None;
        };
        let kind = match kind {
            0 => QueryKind::Request,
            1 => QueryKind::Probe,
            _ => return None,
        };
        let fingerprint = u64::from_be_bytes(rest.get(..8)?.try_into().ok()?);
        let mut rest = &rest[8..];
        let mut text = || -> Option<String> {
            let (&n, tail) = rest.split_first()?;
            let s = std::str::from_utf8(tail.get(..n as usize)?)
                .ok()?
                .to_string();
            rest = &tail[n as usize..];
            Some(s)
        };
        let core = text()?;
        let instance = text()?;
        rest.is_empty().then_some(QueryHeader {
            kind,
            fingerprint,
            core,
            instance,
        })
    }
}

/// What a reply carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplyStatus {
    /// The request was received and the handler is running.
    Ack = 0,
    /// The handler's response (payload: the response).
    Ok = 1,
    /// The handler failed (payload: its message, UTF-8).
    HandlerError = 2,
    /// The request's format does not match the server's (payload: the
    /// server's canonical request format, UTF-8).
    FormatMismatch = 3,
    /// Answer to a probe.
    Present = 4,
}

/// Encodes a reply header.
pub fn reply(status: ReplyStatus, fingerprint: u64) -> Vec<u8> {
    let mut out = vec![VERSION, status as u8];
    out.extend_from_slice(&fingerprint.to_be_bytes());
    out
}

/// Decodes a reply header.
pub fn parse_reply(bytes: &[u8]) -> Option<(ReplyStatus, u64)> {
    let [VERSION, status, rest @ ..] = bytes else {
        return None;
    };
    let status = match status {
        0 => ReplyStatus::Ack,
        1 => ReplyStatus::Ok,
        2 => ReplyStatus::HandlerError,
        3 => ReplyStatus::FormatMismatch,
        4 => ReplyStatus::Present,
        _ => return None,
    };
    let fp: [u8; 8] = rest.try_into().ok()?;
    Some((status, u64::from_be_bytes(fp)))
}
