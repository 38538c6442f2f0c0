//! The wire format: key expressions, attachments and the payload codec
//! (the `peppy-wire` crate), and the `codec!` macro generated message
//! structs implement the codec by. docs/WIRE.md describes it for
//! implementers in other languages.

pub use peppy_wire::{attachment, codec, keys};
pub mod struct_codec;
