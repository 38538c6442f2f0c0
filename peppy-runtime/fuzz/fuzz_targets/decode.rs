//! Decoding arbitrary bytes as any message shape must fail cleanly, never
//! panic or over-allocate.
#![no_main]

use std::time::SystemTime;

use libfuzzer_sys::fuzz_target;
use peppy_runtime::wire::codec::from_bytes;
use peppy_runtime::wire::attachment::{QueryHeader, parse_reply, parse_topic};

fuzz_target!(|data: &[u8]| {
    let _ = from_bytes::<String>(data);
    let _ = from_bytes::<Vec<Vec<u8>>>(data);
    let _ = from_bytes::<Option<[f64; 3]>>(data);
    let _ = from_bytes::<Vec<SystemTime>>(data);
    let _ = from_bytes::<Vec<Option<String>>>(data);
    let _ = QueryHeader::decode(data);
    let _ = parse_reply(data);
    let _ = parse_topic(data);
});
