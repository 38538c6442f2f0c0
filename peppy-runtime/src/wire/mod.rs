//! The wire format: key expressions, attachments and the payload codec
//! (the `peppy-wire` crate), and the `codec!` macro generated message
//! structs implement the codec by. docs/WIRE.md describes it for
//! implementers in other languages.

pub use peppy_wire::{attachment, keys};
pub mod struct_codec;

/// The payload codec (`peppy_wire::codec`), with [`MessageData`], the
/// runtime's mark of a generated message struct, where it has always been
/// found.
pub mod codec {
    pub use super::struct_codec::MessageData;
    pub use peppy_wire::codec::*;
}
