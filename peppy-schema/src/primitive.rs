//! The primitive types of message formats and parameters.

use serde::{Deserialize, Serialize};

/// `$length` may be at most this (fixed arrays become `[T; N]` values).
pub const MAX_FIXED_LENGTH: u64 = 65_536;

/// A primitive type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Primitive {
    /// `bool`
    Bool,
    /// `u8`
    U8,
    /// `u16`
    U16,
    /// `u32`
    U32,
    /// `u64`
    U64,
    /// `i8`
    I8,
    /// `i16`
    I16,
    /// `i32`
    I32,
    /// `i64`
    I64,
    /// `f32` (alias `float`)
    F32,
    /// `f64` (alias `double`)
    F64,
    /// `string` (alias `str`)
    String,
    /// `bytes`
    Bytes,
    /// `time`: a point in time (`std::time::SystemTime`)
    Time,
}

/// Every accepted type spelling, aliases included.
pub const TYPE_NAMES: &[&str] = &[
    "bool", "u8", "u16", "u32", "u64", "i8", "i16", "i32", "i64", "f32", "f64", "float", "double",
    "string", "str", "bytes", "time",
];

impl Primitive {
    /// Parses a type name, aliases included.
    pub fn parse(s: &str) -> Option<Primitive> {
        Some(match s {
            "bool" => Primitive::Bool,
            "u8" => Primitive::U8,
            "u16" => Primitive::U16,
            "u32" => Primitive::U32,
            "u64" => Primitive::U64,
            "i8" => Primitive::I8,
            "i16" => Primitive::I16,
            "i32" => Primitive::I32,
            "i64" => Primitive::I64,
            "f32" | "float" => Primitive::F32,
            "f64" | "double" => Primitive::F64,
            "string" | "str" => Primitive::String,
            "bytes" => Primitive::Bytes,
            "time" => Primitive::Time,
            _ => return None,
        })
    }

    /// The canonical spelling.
    pub fn name(self) -> &'static str {
        match self {
            Primitive::Bool => "bool",
            Primitive::U8 => "u8",
            Primitive::U16 => "u16",
            Primitive::U32 => "u32",
            Primitive::U64 => "u64",
            Primitive::I8 => "i8",
            Primitive::I16 => "i16",
            Primitive::I32 => "i32",
            Primitive::I64 => "i64",
            Primitive::F32 => "f32",
            Primitive::F64 => "f64",
            Primitive::String => "string",
            Primitive::Bytes => "bytes",
            Primitive::Time => "time",
        }
    }

    /// Numbers and `bool`: fixed-size values with no presence bit.
    pub fn is_scalar(self) -> bool {
        !matches!(self, Primitive::String | Primitive::Bytes | Primitive::Time)
    }

    /// The inclusive integer range, for integer types.
    pub fn int_range(self) -> Option<(i128, i128)> {
        Some(match self {
            Primitive::U8 => (0, u8::MAX as i128),
            Primitive::U16 => (0, u16::MAX as i128),
            Primitive::U32 => (0, u32::MAX as i128),
            Primitive::U64 => (0, u64::MAX as i128),
            Primitive::I8 => (i8::MIN as i128, i8::MAX as i128),
            Primitive::I16 => (i16::MIN as i128, i16::MAX as i128),
            Primitive::I32 => (i32::MIN as i128, i32::MAX as i128),
            Primitive::I64 => (i64::MIN as i128, i64::MAX as i128),
            _ => return None,
        })
    }
}
