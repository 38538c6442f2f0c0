//! The datastore: a small key/value store each core node (a launch, or the
//! hub of `peppy-launch run`) keeps for its nodes, as PeppyOS's
//! `peppylib::datastore` offers it.
//!
//! A node leaves a value under a key and any node of the same core node
//! reads it later, also after a restart of the node that wrote it (a
//! restarted instance reads back what it stored before). Values are bytes
//! with an encoding tag the store never reads, and the store records which
//! instance wrote each key last. The store lives as long as its core node:
//! a lock a crashed node leaves behind goes with the stack, not into the
//! next one.
//!
//! ```ignore
//! use peppylib::datastore::{self, Encoding};
//! datastore::store(&runner, "calibration/wrist", b"0.1".to_vec(), Encoding::TEXT_PLAIN, None).await?;
//! if let Some(v) = datastore::get(&runner, "calibration/wrist", None).await? {
//!     println!("{} wrote {:?}", v.last_modified_by, v.value);
//! }
//! ```
//!
//! The wire (docs/WIRE.md, "Core node functions"): a query on
//! `peppy/<ns>/stack/<core>/datastore` whose payload is one request.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fmt;
use std::sync::Mutex;
use std::time::Duration;

use crate::error::{Error, Result};
use crate::node::NodeRunner;
use crate::wire::codec::{Decode, DecodeError, Decoder, Encode, Writer};
use crate::wire::keys::CoreFunction;

/// How long a call waits for its core node by default.
pub use crate::core_functions::DEFAULT_RESPONSE_TIMEOUT;

/// The largest value the store keeps (16 MiB): it is for small shared
/// state, not a file store.
pub const MAX_VALUE_BYTES: usize = 16 << 20;

/// The most bytes of keys and values one store holds (256 MiB).
pub const MAX_STORE_BYTES: usize = 256 << 20;

/// A content-type tag saying how a value's bytes read (`text/plain`,
/// `application/json`, ...). An open set, as Zenoh's encodings: the
/// constants name the common ones and any string is a tag. The store keeps
/// it beside the bytes and never reads it.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Encoding(Cow<'static, str>);

impl Encoding {
    /// UTF-8 text (`text/plain`).
    pub const TEXT_PLAIN: Self = Encoding(Cow::Borrowed("text/plain"));
    /// A JSON document (`application/json`).
    pub const APPLICATION_JSON: Self = Encoding(Cow::Borrowed("application/json"));
    /// Opaque bytes (`application/octet-stream`).
    pub const APPLICATION_OCTET_STREAM: Self = Encoding(Cow::Borrowed("application/octet-stream"));

    /// The tag.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl From<String> for Encoding {
    fn from(tag: String) -> Self {
        Encoding(Cow::Owned(tag))
    }
}

impl From<&str> for Encoding {
    fn from(tag: &str) -> Self {
        Encoding(Cow::Owned(tag.to_owned()))
    }
}

impl From<Encoding> for String {
    fn from(encoding: Encoding) -> Self {
        encoding.0.into_owned()
    }
}

impl AsRef<str> for Encoding {
    fn as_ref(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for Encoding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl PartialEq<str> for Encoding {
    fn eq(&self, other: &str) -> bool {
        self.as_str() == other
    }
}

impl PartialEq<&str> for Encoding {
    fn eq(&self, other: &&str) -> bool {
        self.as_str() == *other
    }
}

/// A value read from the store.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredValue {
    /// The bytes, as stored.
    pub value: Vec<u8>,
    /// The tag they were stored with.
    pub encoding: Encoding,
    /// The instance id of the node that wrote the key last.
    pub last_modified_by: String,
}

/// One key of [`list`]: its tag and last writer, without the value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DatastoreEntry {
    /// The key.
    pub key: String,
    /// The tag of its value.
    pub encoding: Encoding,
    /// The instance id of the node that wrote it last.
    pub last_modified_by: String,
}

/// Stores `value` under `key` on this node's core node, tagged with
/// `encoding`; a key already there is overwritten (value, tag and writer).
/// `response_timeout` is `None` for 10 s. An empty key, or a value over
/// [`MAX_VALUE_BYTES`], is refused before anything is sent.
pub async fn store(
    node_runner: &NodeRunner,
    key: impl Into<String>,
    value: impl Into<Vec<u8>>,
    encoding: impl Into<Encoding>,
    response_timeout: impl Into<Option<Duration>> + Send,
) -> Result<()> {
    let key = checked_key(key.into())?;
    let value = value.into();
    if value.len() > MAX_VALUE_BYTES {
        return Err(Error::InvalidServiceRequest {
            identifier: "datastore store".into(),
            reason: format!(
                "the value of `{key}` is {} bytes; the datastore keeps values of at most {MAX_VALUE_BYTES} bytes",
                value.len()
            ),
        });
    }
    let request = Request::Store {
        key,
        value,
        encoding: encoding.into().into(),
        writer: node_runner.instance_id().to_string(),
    };
    match ask(node_runner, &request, response_timeout.into()).await? {
        Reply::Done => Ok(()),
        other => Err(unexpected(&other)),
    }
}

/// The value stored under `key` on this node's core node, `None` when no
/// node stored one. `response_timeout` is `None` for 10 s.
pub async fn get(
    node_runner: &NodeRunner,
    key: impl Into<String>,
    response_timeout: impl Into<Option<Duration>> + Send,
) -> Result<Option<StoredValue>> {
    let request = Request::Get {
        key: checked_key(key.into())?,
    };
    match ask(node_runner, &request, response_timeout.into()).await? {
        Reply::Value(v) => Ok(v.map(|(value, encoding, writer)| StoredValue {
            value,
            encoding: encoding.into(),
            last_modified_by: writer,
        })),
        other => Err(unexpected(&other)),
    }
}

/// Every key of this node's core node's store with its tag and last
/// writer (not the values: [`get`] reads one), in key order.
/// `response_timeout` is `None` for 10 s.
pub async fn list(
    node_runner: &NodeRunner,
    response_timeout: impl Into<Option<Duration>> + Send,
) -> Result<Vec<DatastoreEntry>> {
    match ask(node_runner, &Request::List, response_timeout.into()).await? {
        Reply::Entries(entries) => Ok(entries
            .into_iter()
            .map(|(key, encoding, writer)| DatastoreEntry {
                key,
                encoding: encoding.into(),
                last_modified_by: writer,
            })
            .collect()),
        other => Err(unexpected(&other)),
    }
}

/// Removes `key` from this node's core node's store: `true` when it was
/// there. `response_timeout` is `None` for 10 s.
pub async fn remove(
    node_runner: &NodeRunner,
    key: impl Into<String>,
    response_timeout: impl Into<Option<Duration>> + Send,
) -> Result<bool> {
    let request = Request::Remove {
        key: checked_key(key.into())?,
    };
    match ask(node_runner, &request, response_timeout.into()).await? {
        Reply::Removed(was) => Ok(was),
        other => Err(unexpected(&other)),
    }
}

/// A key is any non-empty string (it rides in the payload, not in a Zenoh
/// key, so `/`, `*` and spaces are fine).
fn checked_key(key: String) -> Result<String> {
    if key.is_empty() {
        return Err(Error::InvalidServiceRequest {
            identifier: "datastore".into(),
            reason: "a datastore key cannot be empty".into(),
        });
    }
    Ok(key)
}

fn unexpected(reply: &Reply) -> Error {
    Error::Deserialization(format!(
        "the datastore answered with a reply of another kind ({})",
        reply.kind()
    ))
}

async fn ask(runner: &NodeRunner, request: &Request, timeout: Option<Duration>) -> Result<Reply> {
    let body = crate::core_functions::ask(
        runner,
        CoreFunction::Datastore,
        crate::wire::codec::to_bytes(request),
        timeout,
    )
    .await?;
    crate::wire::codec::from_bytes::<Reply>(&body).map_err(|source| Error::Decode {
        what: "datastore reply".into(),
        source,
    })
}

/// One call of the datastore, as it travels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Request {
    Store {
        key: String,
        value: Vec<u8>,
        encoding: String,
        writer: String,
    },
    Get {
        key: String,
    },
    List,
    Remove {
        key: String,
    },
}

/// The datastore's answer to one [`Request`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Reply {
    Done,
    /// `(value, encoding, writer)`, when the key is there.
    Value(Option<(Vec<u8>, String, String)>),
    /// `(key, encoding, writer)` of every key.
    Entries(Vec<(String, String, String)>),
    Removed(bool),
}

impl Reply {
    fn kind(&self) -> &'static str {
        match self {
            Reply::Done => "done",
            Reply::Value(_) => "value",
            Reply::Entries(_) => "entries",
            Reply::Removed(_) => "removed",
        }
    }
}

impl Encode for Request {
    fn encode(&self, out: &mut Writer<'_>) {
        match self {
            Request::Store {
                key,
                value,
                encoding,
                writer,
            } => {
                0u8.encode(out);
                key.encode(out);
                value.encode(out);
                encoding.encode(out);
                writer.encode(out);
            }
            Request::Get { key } => {
                1u8.encode(out);
                key.encode(out);
            }
            Request::List => 2u8.encode(out),
            Request::Remove { key } => {
                3u8.encode(out);
                key.encode(out);
            }
        }
    }
}

impl Decode for Request {
    const MIN_SIZE: usize = 1;

    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        Ok(match u8::decode(d)? {
            0 => Request::Store {
                key: String::decode(d)?,
                value: Vec::<u8>::decode(d)?,
                encoding: String::decode(d)?,
                writer: String::decode(d)?,
            },
            1 => Request::Get {
                key: String::decode(d)?,
            },
            2 => Request::List,
            3 => Request::Remove {
                key: String::decode(d)?,
            },
            op => return Err(d.error(format!("unknown datastore operation {op}"))),
        })
    }
}

impl Encode for Reply {
    fn encode(&self, out: &mut Writer<'_>) {
        match self {
            Reply::Done => 0u8.encode(out),
            Reply::Value(v) => {
                1u8.encode(out);
                v.encode(out);
            }
            Reply::Entries(entries) => {
                2u8.encode(out);
                entries.encode(out);
            }
            Reply::Removed(was) => {
                3u8.encode(out);
                was.encode(out);
            }
        }
    }
}

impl Decode for Reply {
    const MIN_SIZE: usize = 1;

    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        Ok(match u8::decode(d)? {
            0 => Reply::Done,
            1 => Reply::Value(Option::decode(d)?),
            2 => Reply::Entries(Vec::decode(d)?),
            3 => Reply::Removed(bool::decode(d)?),
            kind => return Err(d.error(format!("unknown datastore reply {kind}"))),
        })
    }
}

/// One core node's store.
#[derive(Debug, Default)]
pub(crate) struct Store {
    keys: Mutex<StoreKeys>,
}

#[derive(Debug, Default)]
struct StoreKeys {
    values: BTreeMap<String, Stored>,
    bytes: usize,
}

#[derive(Debug)]
struct Stored {
    value: Vec<u8>,
    encoding: String,
    writer: String,
}

impl Stored {
    fn size(&self, key: &str) -> usize {
        key.len() + self.value.len() + self.encoding.len() + self.writer.len()
    }
}

impl Store {
    /// Answers one request's payload: the reply's payload, or why the
    /// request is refused.
    pub(crate) fn answer(&self, payload: &[u8]) -> std::result::Result<Vec<u8>, String> {
        let request = crate::wire::codec::from_bytes::<Request>(payload)
            .map_err(|e| format!("not a datastore request: {e}"))?;
        let reply = self.apply(request)?;
        Ok(crate::wire::codec::to_bytes(&reply))
    }

    fn apply(&self, request: Request) -> std::result::Result<Reply, String> {
        let mut keys = self.keys.lock().unwrap_or_else(|p| p.into_inner());
        Ok(match request {
            Request::Store {
                key,
                value,
                encoding,
                writer,
            } => {
                if key.is_empty() {
                    return Err("a datastore key cannot be empty".into());
                }
                if value.len() > MAX_VALUE_BYTES {
                    return Err(format!(
                        "the value of `{key}` is {} bytes; the datastore keeps values of at most {MAX_VALUE_BYTES} bytes",
                        value.len()
                    ));
                }
                let stored = Stored {
                    value,
                    encoding,
                    writer,
                };
                let freed = keys.values.get(&key).map_or(0, |old| old.size(&key));
                let after = keys.bytes - freed + stored.size(&key);
                if after > MAX_STORE_BYTES {
                    return Err(format!(
                        "storing `{key}` would make the datastore hold {after} bytes, over its {MAX_STORE_BYTES}"
                    ));
                }
                keys.bytes = after;
                keys.values.insert(key, stored);
                Reply::Done
            }
            Request::Get { key } => Reply::Value(
                keys.values
                    .get(&key)
                    .map(|s| (s.value.clone(), s.encoding.clone(), s.writer.clone())),
            ),
            Request::List => Reply::Entries(
                keys.values
                    .iter()
                    .map(|(k, s)| (k.clone(), s.encoding.clone(), s.writer.clone()))
                    .collect(),
            ),
            Request::Remove { key } => match keys.values.remove(&key) {
                Some(old) => {
                    keys.bytes -= old.size(&key);
                    Reply::Removed(true)
                }
                None => Reply::Removed(false),
            },
        })
    }
}

/// The golden datastore vectors (`tests/golden/wire.json`, `datastore`):
/// each step's request as this client encodes it, and the reply a fresh
/// store gives, in order. Checked by the runtime's golden tests.
#[doc(hidden)]
pub fn golden_steps(requests: &[Vec<u8>]) -> Vec<std::result::Result<Vec<u8>, String>> {
    let store = Store::default();
    requests.iter().map(|r| store.answer(r)).collect()
}

/// What [`store`] sends, for the golden vectors.
#[doc(hidden)]
pub fn golden_store_request(key: &str, value: &[u8], encoding: &str, writer: &str) -> Vec<u8> {
    crate::wire::codec::to_bytes(&Request::Store {
        key: key.into(),
        value: value.to_vec(),
        encoding: encoding.into(),
        writer: writer.into(),
    })
}

/// What [`get`], [`list`] and [`remove`] send, for the golden vectors
/// (`op`: `get`, `list` or `remove`; another is `None`).
#[doc(hidden)]
pub fn golden_request(op: &str, key: &str) -> Option<Vec<u8>> {
    let r = match op {
        "get" => Request::Get { key: key.into() },
        "list" => Request::List,
        "remove" => Request::Remove { key: key.into() },
        _ => return None,
    };
    Some(crate::wire::codec::to_bytes(&r))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::codec::{from_bytes, to_bytes};

    fn store(s: &Store, key: &str, value: &[u8], writer: &str) -> Reply {
        let r = Request::Store {
            key: key.into(),
            value: value.to_vec(),
            encoding: "text/plain".into(),
            writer: writer.into(),
        };
        from_bytes(&s.answer(&to_bytes(&r)).unwrap()).unwrap()
    }

    fn ask(s: &Store, r: Request) -> Reply {
        from_bytes(&s.answer(&to_bytes(&r)).unwrap()).unwrap()
    }

    #[test]
    fn stores_overwrites_lists_and_removes_with_the_last_writer() {
        let s = Store::default();
        assert_eq!(store(&s, "lock", b"a", "arm_left"), Reply::Done);
        assert_eq!(store(&s, "lock", b"bb", "arm_right"), Reply::Done);
        assert_eq!(store(&s, "a/b*{1}", b"", "arm_left"), Reply::Done);
        assert_eq!(
            ask(&s, Request::Get { key: "lock".into() }),
            Reply::Value(Some((
                b"bb".to_vec(),
                "text/plain".into(),
                "arm_right".into()
            )))
        );
        assert_eq!(
            ask(&s, Request::List),
            Reply::Entries(vec![
                ("a/b*{1}".into(), "text/plain".into(), "arm_left".into()),
                ("lock".into(), "text/plain".into(), "arm_right".into()),
            ])
        );
        assert_eq!(
            ask(&s, Request::Remove { key: "lock".into() }),
            Reply::Removed(true)
        );
        assert_eq!(
            ask(&s, Request::Remove { key: "lock".into() }),
            Reply::Removed(false)
        );
        assert_eq!(
            ask(&s, Request::Get { key: "lock".into() }),
            Reply::Value(None)
        );
        assert_eq!(s.keys.lock().unwrap().bytes, "a/b*{1}".len() + 10 + 8);
    }

    #[test]
    fn refuses_what_it_cannot_keep_and_bytes_that_are_no_request() {
        let s = Store::default();
        let empty = Request::Store {
            key: String::new(),
            value: vec![],
            encoding: String::new(),
            writer: "w".into(),
        };
        assert!(
            s.answer(&to_bytes(&empty))
                .unwrap_err()
                .contains("cannot be empty")
        );
        let big = Request::Store {
            key: "k".into(),
            value: vec![0; MAX_VALUE_BYTES + 1],
            encoding: String::new(),
            writer: "w".into(),
        };
        assert!(s.answer(&to_bytes(&big)).unwrap_err().contains("at most"));
        assert!(
            s.answer(&[9])
                .unwrap_err()
                .contains("unknown datastore operation 9")
        );
        assert!(
            s.answer(&[])
                .unwrap_err()
                .starts_with("not a datastore request")
        );
        // Trailing bytes are not a request either.
        let mut get = to_bytes(&Request::Get { key: "k".into() });
        get.push(0);
        assert!(s.answer(&get).is_err());
    }

    /// The datastore lives in its launch's memory (no disk to fill): a
    /// store that would take it past [`MAX_STORE_BYTES`] is refused with
    /// the figures, the values already kept stay readable, and overwriting
    /// or removing a key gives its room back.
    #[test]
    fn a_full_store_refuses_more_and_keeps_what_it_holds() {
        let s = Store::default();
        let value = vec![7u8; MAX_VALUE_BYTES];
        let fits = MAX_STORE_BYTES / (MAX_VALUE_BYTES + 16);
        for i in 0..fits {
            assert_eq!(store(&s, &format!("k{i:02}"), &value, "w"), Reply::Done);
        }
        let over = Request::Store {
            key: "one_more".into(),
            value: value.clone(),
            encoding: "text/plain".into(),
            writer: "w".into(),
        };
        let refusal = s.answer(&to_bytes(&over)).unwrap_err();
        assert!(
            refusal.contains("would make the datastore hold")
                && refusal.contains(&MAX_STORE_BYTES.to_string()),
            "{refusal}"
        );
        let Reply::Value(Some((kept, _, _))) = ask(&s, Request::Get { key: "k00".into() }) else {
            panic!("a value stored before the store filled is gone");
        };
        assert_eq!(kept, value);
        // Overwriting with a smaller value frees room the refused one fits.
        assert_eq!(store(&s, "k00", b"small", "w"), Reply::Done);
        assert_eq!(store(&s, "one_more", &value, "w"), Reply::Done);
        assert_eq!(
            ask(
                &s,
                Request::Remove {
                    key: "one_more".into()
                }
            ),
            Reply::Removed(true)
        );
        assert_eq!(store(&s, "one_more", &value, "w"), Reply::Done);
    }

    #[test]
    fn encodings_compare_with_their_tags() {
        assert_eq!(Encoding::APPLICATION_JSON, "application/json");
        assert_eq!(
            Encoding::from("text/plain".to_string()),
            Encoding::TEXT_PLAIN
        );
        assert_eq!(String::from(Encoding::from("x/y")), "x/y");
    }
}
