//! The wire format: key expressions, attachments and the payload codec.
//! docs/WIRE.md describes it for implementers in other languages.

pub mod attachment;
pub mod codec;
pub mod keys;
pub mod struct_codec;
