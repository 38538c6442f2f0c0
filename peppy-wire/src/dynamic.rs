//! Messages without generated code: decoding and encoding a payload from a
//! format's canonical text.
//!
//! The observer only knows what nodes publish about a format (its
//! canonical text, read back with `MessageFormat::from_canonical`), so it
//! walks the format at run time. Every primitive goes through the runtime's
//! own `Encode`/`Decode`, so this module and generated code cannot disagree
//! about bytes.

use std::fmt::{self, Write as _};
use std::sync::Arc;
use std::time::SystemTime;

use crate::codec::{Decode, DecodeError, Decoder, Encode, Writer};
use peppy_schema::json::{Node, Number, Value as J5};
use peppy_schema::{
    Code, Diagnostic, Diagnostics, Field, FieldType, MessageFormat, Primitive, SourceFile, Span,
    did_you_mean,
};
use serde_json::Value;

/// A decoded message value.
#[derive(Debug, Clone, PartialEq)]
pub enum Dyn {
    /// `bool`
    Bool(bool),
    /// `i8` to `i64`
    Int(i64),
    /// `u8` to `u64`
    UInt(u64),
    /// `f32` (as its shortest decimal) and `f64`
    Float(f64),
    /// `string`
    Str(String),
    /// `bytes`, and arrays of `u8`
    Bytes(Vec<u8>),
    /// `time`, as on the wire: floor seconds, positive nanoseconds.
    Time {
        /// Seconds since the Unix epoch.
        secs: i64,
        /// Nanoseconds, below 10^9.
        nanos: u32,
    },
    /// Any other array.
    Array(Vec<Dyn>),
    /// An object (or the message itself), fields in format order.
    Object(Vec<(String, Dyn)>),
    /// An optional field that is not there.
    Absent,
}

// ---------------------------------------------------------------------------
// Decoding

/// Decodes a payload as docs/WIRE.md section 5 lays it out; trailing
/// bytes are an error. Never panics, and no length allocates more than the
/// payload could hold.
pub fn decode(format: &MessageFormat, payload: &[u8]) -> Result<Dyn, DecodeError> {
    let mut d = Decoder::new(payload);
    let value = decode_fields(&mut d, &format.fields)?;
    d.finish()?;
    Ok(value)
}

fn decode_fields(d: &mut Decoder<'_>, fields: &[Field]) -> Result<Dyn, DecodeError> {
    let mut out = Vec::with_capacity(fields.len());
    for f in fields {
        let value = if f.optional && !presence(d)? {
            Dyn::Absent
        } else {
            decode_type(d, &f.ty)?
        };
        out.push((f.name.clone(), value));
    }
    Ok(Dyn::Object(out))
}

/// An optional's presence byte, refused unless `0` or `1`.
fn presence(d: &mut Decoder<'_>) -> Result<bool, DecodeError> {
    match u8::decode(d)? {
        0 => Ok(false),
        1 => Ok(true),
        b => {
            let mut e = d.error(format!("presence byte is {b}, expected 0 or 1"));
            e.offset -= 1;
            Err(e)
        }
    }
}

fn decode_type(d: &mut Decoder<'_>, ty: &FieldType) -> Result<Dyn, DecodeError> {
    match ty {
        FieldType::Primitive(p) => decode_primitive(d, *p),
        FieldType::Object(fields) => decode_fields(d, fields),
        FieldType::Array { items, length, .. } => decode_array(d, items, *length),
    }
}

fn decode_primitive(d: &mut Decoder<'_>, p: Primitive) -> Result<Dyn, DecodeError> {
    Ok(match p {
        Primitive::Bool => Dyn::Bool(bool::decode(d)?),
        Primitive::U8 => Dyn::UInt(u8::decode(d)?.into()),
        Primitive::U16 => Dyn::UInt(u16::decode(d)?.into()),
        Primitive::U32 => Dyn::UInt(u32::decode(d)?.into()),
        Primitive::U64 => Dyn::UInt(u64::decode(d)?),
        Primitive::I8 => Dyn::Int(i8::decode(d)?.into()),
        Primitive::I16 => Dyn::Int(i16::decode(d)?.into()),
        Primitive::I32 => Dyn::Int(i32::decode(d)?.into()),
        Primitive::I64 => Dyn::Int(i64::decode(d)?),
        Primitive::F32 => Dyn::Float(widen(f32::decode(d)?)),
        Primitive::F64 => Dyn::Float(f64::decode(d)?),
        Primitive::String => Dyn::Str(String::decode(d)?),
        Primitive::Bytes => Dyn::Bytes(Vec::<u8>::decode(d)?),
        Primitive::Time => decode_time(d)?,
    })
}

/// An `f32` as the `f64` of its shortest decimal, so `0.1f32` shows as
/// `0.1` rather than `0.10000000149011612`; it narrows back to the same
/// `f32`.
fn widen(x: f32) -> f64 {
    if !x.is_finite() {
        return x.into();
    }
    x.to_string().parse().unwrap_or(x.into())
}

/// A `time`, checked by the runtime's own `SystemTime` decoder (nanosecond
/// range, platform range) but kept as the raw seconds and nanoseconds.
fn decode_time(d: &mut Decoder<'_>) -> Result<Dyn, DecodeError> {
    let at = d.error("").offset;
    let raw = d.take(SystemTime::MIN_SIZE)?;
    let shift = |e: DecodeError| DecodeError {
        offset: at + e.offset,
        ..e
    };
    SystemTime::decode(&mut Decoder::new(raw)).map_err(shift)?;
    let mut r = Decoder::new(raw);
    Ok(Dyn::Time {
        secs: i64::decode(&mut r).map_err(shift)?,
        nanos: u32::decode(&mut r).map_err(shift)?,
    })
}

fn decode_array(
    d: &mut Decoder<'_>,
    items: &FieldType,
    length: Option<u32>,
) -> Result<Dyn, DecodeError> {
    // At least one byte per item, so a count can never outgrow the payload,
    // even for a (malformed) format whose items take no bytes.
    let min = min_size(items).max(1);
    let n = match length {
        None => d.count(min)?,
        Some(n) if (n as usize).saturating_mul(min) > d.remaining() => {
            return Err(d.error(format!(
                "fixed array of {n} needs more bytes than the {} left",
                d.remaining()
            )));
        }
        Some(n) => n as usize,
    };
    if *items == FieldType::Primitive(Primitive::U8) {
        return Ok(Dyn::Bytes(u8::decode_vec(d, n)?));
    }
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        out.push(decode_type(d, items)?);
    }
    Ok(Dyn::Array(out))
}

/// The fewest bytes a value of `ty` takes, from the runtime's own bounds.
fn min_size(ty: &FieldType) -> usize {
    match ty {
        FieldType::Primitive(p) => match p {
            Primitive::Bool | Primitive::U8 | Primitive::I8 => u8::MIN_SIZE,
            Primitive::U16 | Primitive::I16 => u16::MIN_SIZE,
            Primitive::U32 | Primitive::I32 | Primitive::F32 => u32::MIN_SIZE,
            Primitive::U64 | Primitive::I64 | Primitive::F64 => u64::MIN_SIZE,
            Primitive::String => String::MIN_SIZE,
            Primitive::Bytes => Vec::<u8>::MIN_SIZE,
            Primitive::Time => SystemTime::MIN_SIZE,
        },
        FieldType::Array { length: None, .. } => u32::MIN_SIZE,
        FieldType::Array {
            items,
            length: Some(n),
            ..
        } => min_size(items).saturating_mul(*n as usize),
        FieldType::Object(fields) => fields
            .iter()
            .map(|f| if f.optional { 1 } else { min_size(&f.ty) })
            .fold(0, usize::saturating_add),
    }
}

// ---------------------------------------------------------------------------
// Encoding

/// What kind of mistake a [`FieldError`] is; it picks the diagnostic code
/// and what to underline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldErrorKind {
    /// A field the format does not have (the key is underlined).
    UnknownField,
    /// A required field is not given (its object is underlined).
    MissingField,
    /// A value of the wrong JSON type.
    WrongType,
    /// The right JSON type, but out of range or the wrong length.
    InvalidValue,
}

/// Why a value does not fit a message format.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldError {
    /// Where, e.g. `header.stamp` or `points[2].x`; empty for the message
    /// itself.
    pub path: String,
    /// What is wrong there.
    pub message: String,
    /// The kind of mistake.
    pub kind: FieldErrorKind,
    /// `path` as steps, to find the value in the text the user wrote (a
    /// key may itself hold `.` or `[`).
    steps: Vec<Step>,
}

/// One step of a [`FieldError`] path.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Step {
    Key(String),
    Index(usize),
}

impl fmt::Display for FieldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.path.is_empty() {
            f.write_str(&self.message)
        } else {
            write!(f, "`{}`: {}", self.path, self.message)
        }
    }
}

impl std::error::Error for FieldError {}

impl FieldError {
    fn new(kind: FieldErrorKind, message: impl Into<String>) -> Self {
        FieldError {
            path: String::new(),
            message: message.into(),
            kind,
            steps: Vec::new(),
        }
    }

    fn invalid(message: impl Into<String>) -> Self {
        Self::new(FieldErrorKind::InvalidValue, message)
    }

    fn wrong_type(expected: &str, found: &Value) -> Self {
        Self::new(
            FieldErrorKind::WrongType,
            format!("expected {expected}, found {}", kind_of(found)),
        )
    }

    /// Adds the step the error happened under. Steps are collected
    /// innermost first while the error travels up, so paths are built only
    /// for errors, not for every field encoded.
    fn under(mut self, step: Step) -> Self {
        self.steps.push(step);
        self
    }

    fn under_key(self, key: &str) -> Self {
        self.under(Step::Key(key.to_string()))
    }

    /// Puts the steps in order and spells the path.
    fn finish(mut self) -> Self {
        self.steps.reverse();
        for step in &self.steps {
            match step {
                Step::Key(k) if self.path.is_empty() => self.path.push_str(k),
                Step::Key(k) => {
                    self.path.push('.');
                    self.path.push_str(k);
                }
                Step::Index(i) => {
                    let _ = write!(self.path, "[{i}]");
                }
            }
        }
        self
    }
}

/// `null`, `a string`, ... for messages.
fn kind_of(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

/// How a type is named in messages: `` `u8` ``, `` `[f64;3]` ``, `an object`.
fn type_name(ty: &FieldType) -> String {
    fn spell(ty: &FieldType, out: &mut String) {
        match ty {
            FieldType::Primitive(p) => out.push_str(p.name()),
            FieldType::Object(_) => out.push_str("{…}"),
            FieldType::Array { items, length, .. } => {
                out.push('[');
                spell(items, out);
                if let Some(n) = length {
                    let _ = write!(out, ";{n}");
                }
                out.push(']');
            }
        }
    }
    match ty {
        FieldType::Object(_) => "an object".to_string(),
        _ => {
            let mut out = String::from("`");
            spell(ty, &mut out);
            out.push('`');
            out
        }
    }
}

/// Encodes a JSON value as a payload of `format`.
///
/// Fields are matched by name; optional root fields may be absent or
/// `null`; integers are range-checked, floats accept integers, `bytes` and
/// `[u8]` take an array of 0 to 255 or a string (its UTF-8 bytes), and
/// `time` takes `{secs, nanos}`, seconds since the epoch or `"now"`. A
/// message with no fields takes `{}` or `null`.
pub fn encode(format: &MessageFormat, value: &Value) -> Result<Vec<u8>, FieldError> {
    encode_as(format, value, JsonForm::Cli)
}

/// Which JSON a message is written in: what a user types (and `topic echo
/// --format json` prints), or what a recording holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JsonForm {
    /// `bytes` and `[u8]` as arrays of 0 to 255 or a string's UTF-8 bytes;
    /// `time` as `{secs, nanos}`, seconds since the epoch or `"now"`.
    Cli,
    /// `bytes` and `[u8]` as base64 strings (arrays also read); `time` as
    /// `{sec, nsec}`: the JSON Foxglove and the MCAP tools read
    /// ([`to_recording_json`]).
    Recording,
}

/// [`encode`] of a value written in `form`.
pub fn encode_as(
    format: &MessageFormat,
    value: &Value,
    form: JsonForm,
) -> Result<Vec<u8>, FieldError> {
    let mut out = Vec::new();
    let empty_ok = matches!(value, Value::Null) || value.as_object().is_some_and(|m| m.is_empty());
    if format.fields.is_empty() && !empty_ok {
        return Err(FieldError::invalid(format!(
            "this message has no payload: write `{{}}`, found {}",
            kind_of(value)
        ))
        .finish());
    }
    if !format.fields.is_empty() {
        encode_fields(&format.fields, value, &mut Writer::new(&mut out), form)
            .map_err(FieldError::finish)?;
    }
    Ok(out)
}

fn encode_fields(
    fields: &[Field],
    value: &Value,
    out: &mut Writer<'_>,
    form: JsonForm,
) -> Result<(), FieldError> {
    let Value::Object(map) = value else {
        return Err(FieldError::wrong_type("an object", value));
    };
    // Unknown keys first: a misspelt field would otherwise be reported as
    // the missing one, away from the typo.
    if let Some(key) = map.keys().find(|k| !fields.iter().any(|f| &f.name == *k)) {
        return Err(unknown_field(key, fields).under_key(key));
    }
    for f in fields {
        match map.get(&f.name) {
            None | Some(Value::Null) if f.optional => out.put_u8(0),
            None => {
                let message = format!("missing field `{}` ({})", f.name, type_name(&f.ty));
                return Err(
                    FieldError::new(FieldErrorKind::MissingField, message).under_key(&f.name)
                );
            }
            Some(v) => {
                // The presence byte of `Option`'s encoding.
                if f.optional {
                    out.put_u8(1);
                }
                encode_type(&f.ty, v, out, form).map_err(|e| e.under_key(&f.name))?;
            }
        }
    }
    Ok(())
}

fn unknown_field(key: &str, fields: &[Field]) -> FieldError {
    let names = || fields.iter().map(|f| f.name.as_str());
    let expected: Vec<String> = names().map(|n| format!("`{n}`")).collect();
    let hint = did_you_mean(key, names())
        .map(|s| format!("did you mean `{s}`? "))
        .unwrap_or_default();
    FieldError::new(
        FieldErrorKind::UnknownField,
        format!(
            "unknown field `{key}`; {hint}expected fields: {}",
            expected.join(", ")
        ),
    )
}

fn encode_type(
    ty: &FieldType,
    v: &Value,
    out: &mut Writer<'_>,
    form: JsonForm,
) -> Result<(), FieldError> {
    match ty {
        FieldType::Primitive(p) => encode_primitive(*p, v, out, form),
        FieldType::Object(fields) => encode_fields(fields, v, out, form),
        FieldType::Array { items, length, .. } => encode_array(items, *length, v, out, form),
    }
}

fn encode_array(
    items: &FieldType,
    length: Option<u32>,
    v: &Value,
    out: &mut Writer<'_>,
    form: JsonForm,
) -> Result<(), FieldError> {
    let is_bytes = *items == FieldType::Primitive(Primitive::U8);
    if let (true, Value::String(s)) = (is_bytes, v) {
        let bytes = string_bytes(s, form)?;
        put_count(bytes.len(), length, out)?;
        u8::encode_slice(&bytes, out);
        return Ok(());
    }
    let Value::Array(list) = v else {
        let what = format!("an array of {}", type_name(items));
        return Err(FieldError::wrong_type(&what, v));
    };
    put_count(list.len(), length, out)?;
    for (i, item) in list.iter().enumerate() {
        encode_type(items, item, out, form).map_err(|e| e.under(Step::Index(i)))?;
    }
    Ok(())
}

/// A variable array's `u32` count; a fixed array's length is checked and
/// not written.
fn put_count(n: usize, length: Option<u32>, out: &mut Writer<'_>) -> Result<(), FieldError> {
    match length {
        Some(fixed) if n != fixed as usize => Err(FieldError::invalid(format!(
            "expected exactly {fixed} items, found {n}"
        ))),
        Some(_) => Ok(()),
        None => {
            let n = u32::try_from(n)
                .map_err(|_| FieldError::invalid(format!("{n} items is more than a u32 count")))?;
            n.encode(out);
            Ok(())
        }
    }
}

fn encode_primitive(
    p: Primitive,
    v: &Value,
    out: &mut Writer<'_>,
    form: JsonForm,
) -> Result<(), FieldError> {
    match p {
        Primitive::Bool => match v {
            Value::Bool(b) => b.encode(out),
            _ => return Err(FieldError::wrong_type("`bool`", v)),
        },
        Primitive::F32 => (float(p, v)? as f32).encode(out),
        Primitive::F64 => float(p, v)?.encode(out),
        Primitive::String => match v {
            Value::String(s) => s.encode(out),
            _ => return Err(FieldError::wrong_type("`string`", v)),
        },
        Primitive::Bytes => bytes(v, form)?.encode(out),
        Primitive::Time => encode_time(v, out, form)?,
        _ => encode_int(p, v, out)?,
    }
    Ok(())
}

fn encode_int(p: Primitive, v: &Value, out: &mut Writer<'_>) -> Result<(), FieldError> {
    let n = integer(p, v)?;
    // `integer` checked the range, so these casts keep the value.
    match p {
        Primitive::U8 => (n as u8).encode(out),
        Primitive::U16 => (n as u16).encode(out),
        Primitive::U32 => (n as u32).encode(out),
        Primitive::U64 => (n as u64).encode(out),
        Primitive::I8 => (n as i8).encode(out),
        Primitive::I16 => (n as i16).encode(out),
        Primitive::I32 => (n as i32).encode(out),
        _ => (n as i64).encode(out),
    }
    Ok(())
}

/// An integer of type `p`, range-checked. Whole floats (`1e3`) count.
fn integer(p: Primitive, v: &Value) -> Result<i128, FieldError> {
    let name = p.name();
    let Value::Number(num) = v else {
        return Err(FieldError::wrong_type(&format!("`{name}`"), v));
    };
    let n = num
        .as_i64()
        .map(i128::from)
        .or_else(|| num.as_u64().map(i128::from))
        .or_else(|| {
            num.as_f64()
                .filter(|f| f.fract() == 0.0 && f.abs() < 1e38)
                .map(|f| f as i128)
        })
        .ok_or_else(|| {
            FieldError::invalid(format!("expected an integer (`{name}`), found {num}"))
        })?;
    let (lo, hi) = p.int_range().unwrap_or((i128::MIN, i128::MAX));
    if !(lo..=hi).contains(&n) {
        return Err(FieldError::invalid(format!(
            "{n} is out of range for `{name}` ({lo}..={hi})"
        )));
    }
    Ok(n)
}

/// A float; integers are fine, and so are `"NaN"`, `"Infinity"` and
/// `"-Infinity"`, which JSON cannot write as numbers.
fn float(p: Primitive, v: &Value) -> Result<f64, FieldError> {
    let x = match v {
        Value::Number(n) => n.as_f64().unwrap_or(f64::NAN),
        Value::String(s) => match s.as_str() {
            "NaN" => f64::NAN,
            "Infinity" => f64::INFINITY,
            "-Infinity" => f64::NEG_INFINITY,
            _ => return Err(FieldError::wrong_type(&format!("`{}`", p.name()), v)),
        },
        _ => return Err(FieldError::wrong_type(&format!("`{}`", p.name()), v)),
    };
    // Out of range is what rounds to no finite `f32`: the shortest text of
    // `f32::MAX` (3.4028235e38) reads as an `f64` just above it, and must
    // still encode as the value it was written from.
    if p == Primitive::F32 && x.is_finite() && !(x as f32).is_finite() {
        return Err(FieldError::invalid(format!(
            "{x} is out of range for `f32`"
        )));
    }
    Ok(x)
}

/// `bytes`: an array of 0 to 255, or a string (its UTF-8 bytes, or in a
/// recording its base64).
fn bytes(v: &Value, form: JsonForm) -> Result<Vec<u8>, FieldError> {
    match v {
        Value::String(s) => string_bytes(s, form),
        Value::Array(items) => items
            .iter()
            .enumerate()
            .map(|(i, item)| {
                integer(Primitive::U8, item)
                    .map(|n| n as u8)
                    .map_err(|e| e.under(Step::Index(i)))
            })
            .collect(),
        _ => Err(FieldError::wrong_type(
            "`bytes` (an array of 0 to 255, or a string)",
            v,
        )),
    }
}

/// The bytes a string stands for in `form`.
fn string_bytes(s: &str, form: JsonForm) -> Result<Vec<u8>, FieldError> {
    use base64::Engine as _;
    match form {
        JsonForm::Cli => Ok(s.as_bytes().to_vec()),
        JsonForm::Recording => base64::engine::general_purpose::STANDARD
            .decode(s)
            .map_err(|e| FieldError::invalid(format!("not base64: {e}"))),
    }
}

/// A `time`: `{secs, nanos}` (nanos may be left out), seconds since the
/// Unix epoch (fractions are fine), or `"now"`; in a recording `{sec,
/// nsec}`.
fn encode_time(v: &Value, out: &mut Writer<'_>, form: JsonForm) -> Result<(), FieldError> {
    let (secs, nanos) = match v {
        Value::String(s) if s == "now" => {
            SystemTime::now().encode(out);
            return Ok(());
        }
        Value::Number(n) => match n.as_i64() {
            Some(secs) => (secs, 0),
            None => seconds(n.as_f64().unwrap_or(f64::NAN)).ok_or_else(|| {
                FieldError::invalid(format!("{n} seconds is out of range for `time`"))
            })?,
        },
        Value::Object(_) => time_parts(v, form)?,
        _ => {
            return Err(FieldError::wrong_type(
                "`time` ({secs, nanos}, seconds since the Unix epoch, or \"now\")",
                v,
            ));
        }
    };
    let mut time = [0u8; 12];
    let mut w = Writer::fill(&mut time);
    secs.encode(&mut w);
    nanos.encode(&mut w);
    // What the runtime's decoder refuses (times this platform cannot
    // hold) is refused here too.
    SystemTime::decode(&mut Decoder::new(&time)).map_err(|e| FieldError::invalid(e.reason))?;
    out.put(&time);
    Ok(())
}

/// Whole and fractional seconds as floor seconds and positive nanoseconds.
fn seconds(x: f64) -> Option<(i64, u32)> {
    let floor = x.floor();
    // `i64::MAX as f64` rounds up to 2^63, which is out of range itself.
    if !x.is_finite() || !(i64::MIN as f64..i64::MAX as f64).contains(&floor) {
        return None;
    }
    let nanos = ((x - floor) * 1e9).round() as u32;
    if nanos >= 1_000_000_000 {
        return Some(((floor as i64).checked_add(1)?, 0));
    }
    Some((floor as i64, nanos))
}

/// `{secs, nanos}` (`{sec, nsec}` in a recording), read with the field
/// rules (unknown keys, ranges) of a `{secs: i64, nanos: u32?}` object.
fn time_parts(v: &Value, form: JsonForm) -> Result<(i64, u32), FieldError> {
    let (secs_key, nanos_key) = match form {
        JsonForm::Cli => ("secs", "nanos"),
        JsonForm::Recording => ("sec", "nsec"),
    };
    let fields = [
        field(secs_key, Primitive::I64, false),
        field(nanos_key, Primitive::U32, true),
    ];
    let mut parts = Vec::new();
    encode_fields(&fields, v, &mut Writer::new(&mut parts), form)?;
    let mut d = Decoder::new(&parts);
    let secs = i64::decode(&mut d).unwrap_or_default();
    let nanos = match presence(&mut d) {
        Ok(true) => u32::decode(&mut d).unwrap_or_default(),
        _ => 0,
    };
    if nanos >= 1_000_000_000 {
        let message = format!("{nanos} is out of range for nanoseconds (0..=999999999)");
        return Err(FieldError::invalid(message).under_key(nanos_key));
    }
    Ok((secs, nanos))
}

fn field(name: &str, p: Primitive, optional: bool) -> Field {
    Field {
        name: name.to_string(),
        ty: FieldType::Primitive(p),
        optional,
        loc: peppy_schema::Loc::default(),
    }
}

// ---------------------------------------------------------------------------
// Values the user wrote

/// A JSON5 value the user wrote, kept with its text so that a
/// [`FieldError`] can be shown under the field it is about.
#[derive(Debug)]
pub struct Written {
    file: Arc<SourceFile>,
    root: Node,
}

/// Parses the JSON5 text a user gave for a message. `origin` names the
/// text in diagnostics (e.g. `request`, `goal`).
pub fn parse_json5(origin: &str, text: &str) -> Result<Written, Diagnostics> {
    let file = SourceFile::new(origin, text);
    let (root, diags) = peppy_schema::json::parse(&file)?;
    // Duplicate keys are reported without failing the parse.
    if diags.has_errors() {
        return Err(diags);
    }
    Ok(Written { file, root })
}

impl Written {
    /// The value as JSON. Unlike `Node::to_json`, `NaN` and `±Infinity`
    /// become the strings that [`encode`] reads as those floats, rather than
    /// `null`.
    pub fn value(&self) -> Value {
        fn convert(node: &Node) -> Value {
            match &node.value {
                J5::Number(Number::Float(f)) if !f.is_finite() => float_word(*f).into(),
                J5::Array(items) => items.iter().map(convert).collect(),
                J5::Object(members) => Value::Object(
                    members
                        .iter()
                        .map(|m| (m.key.clone(), convert(&m.value)))
                        .collect(),
                ),
                _ => node.to_json(),
            }
        }
        convert(&self.root)
    }

    /// The text to underline for an error: the value at its path, the key
    /// of an unknown field, or the nearest enclosing value that exists
    /// (the object a missing field belongs in).
    pub fn span_of(&self, error: &FieldError) -> Span {
        let mut node = &self.root;
        for (i, step) in error.steps.iter().enumerate() {
            let last = i + 1 == error.steps.len();
            let next = match (step, &node.value) {
                (Step::Key(k), J5::Object(members)) => {
                    let Some(m) = members.iter().find(|m| &m.key == k) else {
                        break;
                    };
                    if last && error.kind == FieldErrorKind::UnknownField {
                        return m.key_span;
                    }
                    &m.value
                }
                (Step::Index(i), J5::Array(items)) => match items.get(*i) {
                    Some(item) => item,
                    None => break,
                },
                _ => break,
            };
            node = next;
        }
        node.span
    }

    /// A located diagnostic for an error in this text.
    pub fn diagnostic(&self, error: &FieldError) -> Diagnostic {
        let code = match error.kind {
            FieldErrorKind::UnknownField => Code::UnknownKey,
            FieldErrorKind::MissingField => Code::MissingKey,
            FieldErrorKind::WrongType => Code::WrongType,
            FieldErrorKind::InvalidValue => Code::InvalidValue,
        };
        Diagnostic::error(code, error.message.clone())
            .at(&self.file, self.span_of(error))
            .with_key_path(error.path.clone())
    }
}

/// Parses and encodes the JSON5 text a user wrote for a message of
/// `format`. Errors are located in the text (print them with
/// `report::print_human`): a syntax error, or the field that does not fit
/// underlined.
pub fn encode_text(
    format: &MessageFormat,
    origin: &str,
    text: &str,
) -> Result<Vec<u8>, Diagnostics> {
    let written = parse_json5(origin, text)?;
    encode(format, &written.value()).map_err(|e| written.diagnostic(&e).into())
}

// ---------------------------------------------------------------------------
// Rendering

/// Inline arrays of scalars longer than this go one item per line.
const INLINE_WIDTH: usize = 72;

/// Items of a long array [`to_text`] shows one per line before it says how
/// many more there are.
const TEXT_ITEMS: usize = 16;

/// Bytes shown in full in [`to_text`]; longer ones are summarised.
const TEXT_BYTES: usize = 8;

/// Bytes [`to_json`] shows of a byte array.
const JSON_BYTES: usize = 16;

/// A value for people: YAML-like, two-space indent, one `field: value` per
/// line, absent optionals as `~`, byte arrays summarised, times in RFC 3339
/// UTC.
pub fn to_text(value: &Dyn) -> String {
    let mut out = String::new();
    match value {
        Dyn::Object(fields) if !fields.is_empty() => write_fields(&mut out, fields, 0),
        Dyn::Array(items) if inline(value).is_none() => write_items(&mut out, items, 0),
        _ => {
            out.push_str(&inline(value).unwrap_or_default());
            out.push('\n');
        }
    }
    out
}

fn write_fields(out: &mut String, fields: &[(String, Dyn)], indent: usize) {
    for (name, value) in fields {
        let _ = write!(out, "{:indent$}{name}:", "");
        match inline(value) {
            Some(text) => {
                let _ = writeln!(out, " {text}");
            }
            None => {
                out.push('\n');
                write_block(out, value, indent + 2);
            }
        }
    }
}

/// An object or array that does not fit on its parent's line.
fn write_block(out: &mut String, value: &Dyn, indent: usize) {
    match value {
        Dyn::Object(fields) => write_fields(out, fields, indent),
        Dyn::Array(items) => write_items(out, items, indent),
        _ => {}
    }
}

fn write_items(out: &mut String, items: &[Dyn], indent: usize) {
    // A point cloud or a long trajectory would bury everything else: show
    // its first items and how many more there are.
    let (shown, hidden) = if items.len() > TEXT_ITEMS {
        (&items[..TEXT_ITEMS], items.len() - TEXT_ITEMS)
    } else {
        (items, 0)
    };
    for item in shown {
        if let Some(text) = inline(item) {
            let _ = writeln!(out, "{:indent$}- {text}", "");
            continue;
        }
        // The block is indented two more, and `- ` takes the place of the
        // first line's last two spaces.
        let mut block = String::new();
        write_block(&mut block, item, indent + 2);
        if matches!(item, Dyn::Array(_)) {
            let _ = writeln!(out, "{:indent$}-", "");
            out.push_str(&block);
        } else {
            block.replace_range(indent..indent + 2, "- ");
            out.push_str(&block);
        }
    }
    if hidden > 0 {
        let _ = writeln!(
            out,
            "{:indent$}- … {hidden} more items ({} in all)",
            "",
            items.len()
        );
    }
}

/// The value on one line, when it fits there: scalars, empty objects and
/// short arrays of scalars.
fn inline(value: &Dyn) -> Option<String> {
    Some(match value {
        Dyn::Bool(b) => b.to_string(),
        Dyn::Int(i) => i.to_string(),
        Dyn::UInt(u) => u.to_string(),
        Dyn::Float(f) => float_text(*f),
        Dyn::Str(s) => quoted(s),
        Dyn::Bytes(b) => bytes_summary(b),
        Dyn::Time { secs, nanos } => rfc3339(*secs, *nanos),
        Dyn::Absent => "~".to_string(),
        Dyn::Object(fields) if fields.is_empty() => "{}".to_string(),
        Dyn::Object(_) => return None,
        Dyn::Array(items) => {
            let parts = items
                .iter()
                .map(|i| match i {
                    Dyn::Array(_) | Dyn::Object(_) => None,
                    scalar => inline(scalar),
                })
                .collect::<Option<Vec<_>>>()?;
            let text = format!("[{}]", parts.join(", "));
            if text.chars().count() > INLINE_WIDTH {
                return None;
            }
            text
        }
    })
}

/// `1.0`, `1e-7`, and JSON5's `NaN`, `Infinity`, `-Infinity`.
fn float_text(f: f64) -> String {
    if f.is_finite() {
        format!("{f:?}")
    } else {
        float_word(f).to_string()
    }
}

fn float_word(f: f64) -> &'static str {
    if f.is_nan() {
        "NaN"
    } else if f > 0.0 {
        "Infinity"
    } else {
        "-Infinity"
    }
}

/// A string as is, or JSON-quoted when it could be read as something else
/// (a number, `true`, `~`, a byte summary) or would not read back the same.
fn quoted(s: &str) -> String {
    const WORDS: &[&str] = &["true", "false", "null", "~", "NaN", "Infinity", "-Infinity"];
    let first_is_special = s
        .chars()
        .next()
        .is_some_and(|c| "-?:,[]{}#&*!|>'\"%@`<".contains(c));
    let ambiguous = s.is_empty()
        || s.trim() != s
        || WORDS.contains(&s)
        || s.parse::<f64>().is_ok()
        || first_is_special
        || s.contains(": ")
        || s.contains(" #")
        || s.chars().any(char::is_control);
    if ambiguous {
        serde_json::to_string(s).unwrap_or_default()
    } else {
        s.to_string()
    }
}

/// `<3 bytes: 01 02 03>`, or the length and the first bytes.
fn bytes_summary(b: &[u8]) -> String {
    let head: Vec<String> = b
        .iter()
        .take(TEXT_BYTES)
        .map(|x| format!("{x:02x}"))
        .collect();
    let unit = if b.len() == 1 { "byte" } else { "bytes" };
    match (b.len(), b.len() > TEXT_BYTES) {
        (0, _) => "<0 bytes>".to_string(),
        (n, false) => format!("<{n} {unit}: {}>", head.join(" ")),
        (n, true) => format!("<{n} {unit}: {} …>", head.join(" ")),
    }
}

/// RFC 3339 in UTC with nanoseconds, e.g. `2026-12-01T23:00:00.000000123Z`.
pub fn rfc3339(secs: i64, nanos: u32) -> String {
    let (y, m, d) = civil_from_days(secs.div_euclid(86_400));
    let s = secs.rem_euclid(86_400);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{nanos:09}Z",
        s / 3600,
        s % 3600 / 60,
        s % 60
    )
}

/// The proleptic Gregorian date of a day count from 1970-01-01 (Howard
/// Hinnant's `civil_from_days`), valid over every `i64` second count.
fn civil_from_days(days: i64) -> (i64, i64, i64) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

/// A value for machines: objects keep field order, integers stay exact,
/// bytes are `{"len", "head"}` (the first 16 in hex), times are
/// `{"secs", "nanos"}`, absent optionals `null`, and non-finite floats the
/// strings `"NaN"`, `"Infinity"`, `"-Infinity"`.
pub fn to_json(value: &Dyn) -> Value {
    match value {
        Dyn::Bool(b) => Value::Bool(*b),
        Dyn::Int(i) => (*i).into(),
        Dyn::UInt(u) => (*u).into(),
        Dyn::Float(f) => {
            serde_json::Number::from_f64(*f).map_or_else(|| float_word(*f).into(), Value::Number)
        }
        Dyn::Str(s) => Value::String(s.clone()),
        Dyn::Bytes(b) => {
            let head: String = b
                .iter()
                .take(JSON_BYTES)
                .map(|x| format!("{x:02x}"))
                .collect();
            serde_json::json!({ "len": b.len(), "head": head })
        }
        Dyn::Time { secs, nanos } => serde_json::json!({ "secs": secs, "nanos": nanos }),
        Dyn::Array(items) => items.iter().map(to_json).collect(),
        Dyn::Object(fields) => Value::Object(
            fields
                .iter()
                .map(|(k, v)| (k.clone(), to_json(v)))
                .collect(),
        ),
        Dyn::Absent => Value::Null,
    }
}

/// A value as a recording holds it ([`JsonForm::Recording`]): as
/// [`to_json`], but `bytes` and `[u8]` whole, in base64, times as
/// `{sec, nsec}` (which Foxglove reads as times), and absent optional
/// fields left out (the schema does not require them).
pub fn to_recording_json(value: &Dyn) -> Value {
    use base64::Engine as _;
    match value {
        Dyn::Bytes(b) => Value::String(base64::engine::general_purpose::STANDARD.encode(b)),
        Dyn::Time { secs, nanos } => serde_json::json!({ "sec": secs, "nsec": nanos }),
        Dyn::Array(items) => items.iter().map(to_recording_json).collect(),
        Dyn::Object(fields) => Value::Object(
            fields
                .iter()
                .filter(|(_, v)| *v != Dyn::Absent)
                .map(|(k, v)| (k.clone(), to_recording_json(v)))
                .collect(),
        ),
        other => to_json(other),
    }
}

/// [`to_recording_json`]'s text, written straight into `out`: a camera
/// frame's base64 goes into the buffer without a string of its own, and no
/// JSON value is built (what a recorder does ninety times a second with a
/// megabyte each time).
pub fn write_recording_json(value: &Dyn, out: &mut Vec<u8>) {
    use base64::Engine as _;
    use std::io::Write as _;
    match value {
        Dyn::Bool(b) => out.extend_from_slice(if *b { b"true" } else { b"false" }),
        Dyn::Int(i) => {
            let _ = write!(out, "{i}");
        }
        Dyn::UInt(u) => {
            let _ = write!(out, "{u}");
        }
        Dyn::Float(f) if f.is_finite() => {
            let _ = serde_json::to_writer(&mut *out, f);
        }
        Dyn::Float(f) => {
            let _ = write!(out, "\"{}\"", float_word(*f));
        }
        Dyn::Str(s) => {
            let _ = serde_json::to_writer(&mut *out, s);
        }
        Dyn::Bytes(b) => {
            let engine = base64::engine::general_purpose::STANDARD;
            out.push(b'"');
            let start = out.len();
            out.resize(start + base64::encoded_len(b.len(), true).unwrap_or(0), 0);
            let written = engine.encode_slice(b, &mut out[start..]).unwrap_or(0);
            out.truncate(start + written);
            out.push(b'"');
        }
        Dyn::Time { secs, nanos } => {
            let _ = write!(out, "{{\"sec\":{secs},\"nsec\":{nanos}}}");
        }
        Dyn::Array(items) => {
            out.push(b'[');
            for (i, item) in items.iter().enumerate() {
                if i > 0 {
                    out.push(b',');
                }
                write_recording_json(item, out);
            }
            out.push(b']');
        }
        Dyn::Object(fields) => {
            out.push(b'{');
            let mut first = true;
            for (name, v) in fields.iter().filter(|(_, v)| *v != Dyn::Absent) {
                if !first {
                    out.push(b',');
                }
                first = false;
                let _ = serde_json::to_writer(&mut *out, name);
                out.push(b':');
                write_recording_json(v, out);
            }
            out.push(b'}');
        }
        Dyn::Absent => out.extend_from_slice(b"null"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;
    use std::collections::BTreeSet;

    fn format(text: &str) -> MessageFormat {
        MessageFormat::from_canonical(text).unwrap()
    }

    fn round_trip(f: &MessageFormat, value: &Value) -> Dyn {
        let bytes = encode(f, value).unwrap();
        decode(f, &bytes).unwrap()
    }

    fn object(fields: Vec<(&str, Dyn)>) -> Dyn {
        Dyn::Object(
            fields
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect(),
        )
    }

    fn encode_err(f: &str, value: Value) -> FieldError {
        encode(&format(f), &value).unwrap_err()
    }

    /// The golden vectors the Rust and Python runtimes share
    /// (`tests/golden/wire.json`; its keys, attachments and fingerprints
    /// are checked by peppy-runtime's `tests/runtime/golden.rs`).
    fn golden() -> Value {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/golden/wire.json");
        let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    /// A vector's `"01 0a ff"` as bytes.
    fn hex(v: &Value) -> Vec<u8> {
        let digits: String = v.as_str().unwrap().split_whitespace().collect();
        (0..digits.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&digits[i..i + 2], 16).unwrap())
            .collect()
    }

    /// A decoded value written as the golden file writes values: unlike
    /// [`to_json`], every byte of a byte array.
    fn as_written(value: &Dyn) -> Value {
        match value {
            Dyn::Bytes(b) => b.iter().map(|&x| Value::from(x)).collect(),
            Dyn::Array(items) => items.iter().map(as_written).collect(),
            Dyn::Object(fields) => Value::Object(
                fields
                    .iter()
                    .map(|(k, v)| (k.clone(), as_written(v)))
                    .collect(),
            ),
            other => to_json(other),
        }
    }

    /// What a value of `ty` exercises of the codec, named as
    /// [`codec_features`] names it.
    fn cover(ty: &FieldType, value: &Value, seen: &mut BTreeSet<String>) {
        let mut saw = |what: &str| seen.insert(what.to_string());
        match ty {
            FieldType::Primitive(p) => {
                saw(p.name());
            }
            FieldType::Object(fields) => {
                saw("object");
                cover_fields(fields, value, seen);
            }
            FieldType::Array { items, length, .. } => {
                let items_are = match &**items {
                    FieldType::Primitive(Primitive::U8) => Some("of u8"),
                    FieldType::Object(_) => Some("of objects"),
                    FieldType::Array { .. } => Some("of arrays"),
                    FieldType::Primitive(_) => None,
                };
                let array = if length.is_some() {
                    "$length array"
                } else {
                    "array"
                };
                saw(array);
                if let Some(of) = items_are {
                    saw(&format!("{array} {of}"));
                }
                let list = value.as_array().map(Vec::as_slice).unwrap_or_default();
                if list.is_empty() {
                    saw("empty array");
                }
                for item in list {
                    cover(items, item, seen);
                }
            }
        }
    }

    fn cover_fields(fields: &[Field], value: &Value, seen: &mut BTreeSet<String>) {
        if fields.is_empty() {
            seen.insert("no payload".into());
        }
        for f in fields {
            let v = &value[&f.name];
            if f.optional {
                seen.insert(format!(
                    "$optional {}",
                    if v.is_null() { "absent" } else { "present" }
                ));
                if v.is_null() {
                    continue;
                }
            }
            cover(&f.ty, v, seen);
        }
    }

    /// Everything the codec encodes: every primitive (as the schema names
    /// them), arrays counted and of a `$length` (of bytes, objects and
    /// arrays too), empty arrays, nested objects, `$optional` both ways, no
    /// payload.
    fn codec_features() -> BTreeSet<String> {
        let primitives = peppy_schema::TYPE_NAMES
            .iter()
            .filter_map(|name| Primitive::parse(name))
            .map(|p| p.name().to_string());
        let shapes = [
            "object",
            "array",
            "array of u8",
            "array of objects",
            "array of arrays",
            "$length array",
            "$length array of u8",
            "$length array of objects",
            "$length array of arrays",
            "empty array",
            "$optional present",
            "$optional absent",
            "no payload",
        ];
        primitives.chain(shapes.map(String::from)).collect()
    }

    /// Every message vector encodes from its value to exactly its bytes
    /// and decodes back to the value; every refused payload is refused;
    /// and the vectors leave no type of the codec out.
    #[test]
    fn every_golden_message_encodes_and_decodes_as_written() {
        let golden = golden();
        let mut seen = BTreeSet::new();
        for m in golden["messages"].as_array().unwrap() {
            let name = m["name"].as_str().unwrap();
            let f = format(m["format"].as_str().unwrap());
            let (value, bytes) = (&m["value"], hex(&m["hex"]));
            let encoded = encode(&f, value).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(encoded, bytes, "{name}");
            let decoded = decode(&f, &bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(&as_written(&decoded), value, "{name}");
            cover_fields(&f.fields, value, &mut seen);
        }
        let missing: Vec<_> = codec_features().difference(&seen).cloned().collect();
        assert!(missing.is_empty(), "no golden message has {missing:?}");
        for r in golden["rejected"].as_array().unwrap() {
            let f = format(r["format"].as_str().unwrap());
            assert!(decode(&f, &hex(&r["hex"])).is_err(), "{r}");
        }
    }

    /// What `--format json` prints reads back as the same message (bytes
    /// as their first 16 in hex, and times, as `{secs, nanos}`).
    #[test]
    fn printed_json_encodes_back() {
        let golden = golden();
        let m = &golden["messages"][0];
        let f = format(m["format"].as_str().unwrap());
        let bytes = hex(&m["hex"]);
        let mut printed = to_json(&decode(&f, &bytes).unwrap());
        // Bytes are summarised in print; what was sent is written again.
        for (k, v) in m["value"].as_object().unwrap() {
            if printed[k].get("head").is_some() {
                printed[k] = v.clone();
            }
        }
        assert_eq!(encode(&f, &printed).unwrap(), bytes);
    }

    #[test]
    fn every_primitive_round_trips() {
        let f = format(
            "{b:bool,u1:u8,u2:u16,u4:u32,u8:u64,i1:i8,i2:i16,i4:i32,i8:i64,\
             f4:f32,f8:f64,s:string,y:bytes,t:time}",
        );
        let value = json!({
            "b": false, "u1": 255, "u2": 65535, "u4": 4_294_967_295u32, "u8": u64::MAX,
            "i1": -128, "i2": -32768, "i4": i32::MIN, "i8": i64::MIN, "f4": 0.1,
            "f8": 1e-300, "s": "", "y": [0, 255], "t": { "secs": -2, "nanos": 250 },
        });
        let back = round_trip(&f, &value);
        let mut expected = value.clone();
        expected["y"] = json!({ "len": 2, "head": "00ff" });
        assert_eq!(to_json(&back), expected);
        let Dyn::Object(fields) = &back else {
            panic!("an object")
        };
        assert_eq!(fields[3].1, Dyn::UInt(4_294_967_295));
        assert_eq!(fields[12].1, Dyn::Bytes(vec![0, 255]));
    }

    #[test]
    fn nested_objects_arrays_and_optionals_round_trip() {
        let f = format(
            "{header:{stamp:time,frame_id:u32},points:[{x:f32,y:f32}],pose:[f64;3],\
             frame:[u8;4],note:string?,tags:[string]?,blob:bytes?}",
        );
        let value = json!({
            "header": { "stamp": { "secs": 1_796_166_000, "nanos": 123 }, "frame_id": 7 },
            "points": [{ "x": 1.5, "y": -2.0 }, { "x": 0.25, "y": 3.0 }],
            "pose": [1.0, 2.0, 3.0],
            "frame": [1, 2, 3, 4],
            "note": "hi",
            "tags": ["a", "b"],
        });
        let back = round_trip(&f, &value);
        let mut expected = value.clone();
        expected["frame"] = json!({ "len": 4, "head": "01020304" });
        expected["blob"] = Value::Null;
        assert_eq!(to_json(&back), expected);
        // Optionals may also be written as null.
        let mut none = value.clone();
        none["note"] = Value::Null;
        none["tags"] = Value::Null;
        let Dyn::Object(fields) = round_trip(&f, &none) else {
            panic!("an object")
        };
        assert_eq!(fields[4].1, Dyn::Absent);
        assert_eq!(fields[5].1, Dyn::Absent);
    }

    #[test]
    fn friendly_spellings_encode() {
        let f = format("{data:[u8],blob:bytes,x:f64,t:time}");
        let bytes = encode(&f, &json!({ "data": "hé", "blob": "ab", "x": 3, "t": 1.5 })).unwrap();
        let value = decode(&f, &bytes).unwrap();
        assert_eq!(
            value,
            object(vec![
                ("data", Dyn::Bytes("hé".as_bytes().to_vec())),
                ("blob", Dyn::Bytes(b"ab".to_vec())),
                ("x", Dyn::Float(3.0)),
                (
                    "t",
                    Dyn::Time {
                        secs: 1,
                        nanos: 500_000_000
                    }
                ),
            ])
        );
        let t = |v: Value| {
            let bytes = encode(&format("{t:time}"), &json!({ "t": v })).unwrap();
            match decode(&format("{t:time}"), &bytes).unwrap() {
                Dyn::Object(mut f) => f.remove(0).1,
                other => other,
            }
        };
        assert_eq!(
            t(json!(-0.5)),
            Dyn::Time {
                secs: -1,
                nanos: 500_000_000
            }
        );
        assert_eq!(t(json!({ "secs": 4 })), Dyn::Time { secs: 4, nanos: 0 });
        let Dyn::Time { secs, .. } = t(json!("now")) else {
            panic!("a time")
        };
        assert!(secs > 1_700_000_000);
        let nan = encode(&format("{x:f32}"), &json!({ "x": "NaN" })).unwrap();
        assert!(f32::from_le_bytes(nan.try_into().unwrap()).is_nan());
        for empty in [json!({}), Value::Null] {
            assert_eq!(encode(&format("(no payload)"), &empty).unwrap(), b"");
        }
    }

    #[test]
    fn encode_errors_name_the_field() {
        let f = "{header:{stamp:time,frame_id:u32},points:[{x:f32,y:f32}],pose:[f64;3],\
                 frame:[u8],small:u8,note:string?}";
        let ok = json!({
            "header": { "stamp": 0, "frame_id": 1 }, "points": [{ "x": 1, "y": 2 }],
            "pose": [1, 2, 3], "frame": [], "small": 1,
        });
        assert!(encode(&format(f), &ok).is_ok());
        let with = |pointer: &str, v: Value| {
            let mut value = ok.clone();
            *value.pointer_mut(pointer).unwrap() = v;
            encode_err(f, value)
        };
        let cases = [
            (
                with("/header", json!({ "stamp": 0, "frame_idd": 1 })),
                "header.frame_idd",
                FieldErrorKind::UnknownField,
                "did you mean `frame_id`? expected fields: `stamp`, `frame_id`",
            ),
            (
                with("/header", json!({ "stamp": 0 })),
                "header.frame_id",
                FieldErrorKind::MissingField,
                "missing field `frame_id` (`u32`)",
            ),
            (
                with("/small", json!(300)),
                "small",
                FieldErrorKind::InvalidValue,
                "300 is out of range for `u8` (0..=255)",
            ),
            (
                with("/small", json!(1.5)),
                "small",
                FieldErrorKind::InvalidValue,
                "expected an integer",
            ),
            (
                with("/small", json!("1")),
                "small",
                FieldErrorKind::WrongType,
                "expected `u8`, found a string",
            ),
            (
                with("/pose", json!([1, 2])),
                "pose",
                FieldErrorKind::InvalidValue,
                "expected exactly 3 items, found 2",
            ),
            (
                with("/points/0/x", json!(true)),
                "points[0].x",
                FieldErrorKind::WrongType,
                "expected `f32`, found a boolean",
            ),
            (
                with("/points/0/x", json!(1e39)),
                "points[0].x",
                FieldErrorKind::InvalidValue,
                "out of range for `f32`",
            ),
            (
                with("/frame", json!([1, 2, 256])),
                "frame[2]",
                FieldErrorKind::InvalidValue,
                "(0..=255)",
            ),
            (
                with("/frame", json!(3)),
                "frame",
                FieldErrorKind::WrongType,
                "expected an array of `u8`, found a number",
            ),
            (
                with(
                    "/header/stamp",
                    json!({ "secs": 1, "nanos": 1_000_000_000 }),
                ),
                "header.stamp.nanos",
                FieldErrorKind::InvalidValue,
                "out of range for nanoseconds",
            ),
            (
                with("/header/stamp", json!({ "sec": 1 })),
                "header.stamp.sec",
                FieldErrorKind::UnknownField,
                "did you mean `secs`?",
            ),
            (
                with("/header/stamp", json!("yesterday")),
                "header.stamp",
                FieldErrorKind::WrongType,
                "expected `time`",
            ),
            (
                with("/header/stamp", json!(1e300)),
                "header.stamp",
                FieldErrorKind::InvalidValue,
                "out of range for `time`",
            ),
            (
                with("/header", json!(null)),
                "header",
                FieldErrorKind::WrongType,
                "expected an object, found null",
            ),
            (
                encode_err(f, json!([])),
                "",
                FieldErrorKind::WrongType,
                "expected an object",
            ),
            (
                encode_err("(no payload)", json!({ "a": 1 })),
                "",
                FieldErrorKind::InvalidValue,
                "no payload",
            ),
        ];
        for (err, path, kind, message) in cases {
            assert_eq!((err.path.as_str(), err.kind), (path, kind), "{err}");
            assert!(err.message.contains(message), "{err}");
        }
    }

    #[test]
    fn errors_are_located_in_the_text() {
        let f = format("{header:{stamp:time,frame_id:u8},note:string?}");
        let text = "{\n  header: {\n    stamp: 'now',\n    frame_id: 300,\n  },\n}";
        let diags = encode_text(&f, "request", text).unwrap_err();
        let d = diags.iter().next().unwrap();
        assert_eq!(d.code, Code::InvalidValue);
        assert!(
            d.jump_line(None)
                .starts_with("request:4:15: error: 300 is out of range"),
            "{}",
            d.jump_line(None)
        );
        let mut rendered = String::new();
        miette::GraphicalReportHandler::new_themed(miette::GraphicalTheme::unicode_nocolor())
            .render_report(&mut rendered, d as &dyn miette::Diagnostic)
            .unwrap();
        assert!(rendered.contains("frame_id: 300"), "{rendered}");
        assert!(rendered.contains("header.frame_id"), "{rendered}");

        let at = |text: &str| {
            let diags = encode_text(&f, "goal", text).unwrap_err();
            let d = diags.iter().next().unwrap();
            let span = d.span().unwrap();
            (d.code, text[span.start..span.end].to_string())
        };
        let unknown = at("{ header: { stamp: 0, frame_id: 1 }, notes: 'x' }");
        assert_eq!(unknown, (Code::UnknownKey, "notes".to_string()));
        let missing = at("{ header: { stamp: 0 } }");
        assert_eq!(missing, (Code::MissingKey, "{ stamp: 0 }".to_string()));
        let syntax = at("{ header: ");
        assert_eq!(syntax.0, Code::Syntax);
        let duplicate = at("{ note: 'a', note: 'b' }");
        assert_eq!(duplicate.0, Code::DuplicateKey);
        // JSON5's `Infinity` reaches a float field as a float, not null.
        let g = format("{x:f64}");
        let bytes = encode_text(&g, "request", "{ x: -Infinity }").unwrap();
        assert_eq!(bytes, f64::NEG_INFINITY.to_le_bytes());
    }

    /// Found by the `payload` fuzz target (fuzz/regressions/payload): the
    /// extreme finite `f32`s, written as their shortest text, read back as
    /// themselves; only what rounds past them is out of range.
    #[test]
    fn the_extreme_f32s_read_back_from_their_shortest_text() {
        let f = format("{a:f32,b:f32}");
        let mut bytes = f32::MAX.to_le_bytes().to_vec();
        bytes.extend(f32::MIN.to_le_bytes());
        let value = decode(&f, &bytes).unwrap();
        for json in [to_json(&value), to_recording_json(&value)] {
            assert_eq!(json, json!({"a": 3.4028235e38, "b": -3.4028235e38}));
            assert_eq!(encode_as(&f, &json, JsonForm::Recording).unwrap(), bytes);
        }
        let err = encode_err("{a:f32,b:f32}", json!({"a": 3.5e38, "b": 0}));
        assert_eq!(err.kind, FieldErrorKind::InvalidValue, "{err:?}");
    }

    #[test]
    fn hostile_payloads_are_errors_not_panics() {
        let f = format("{a:[{s:string,t:time}],b:[u64;4]?,c:bytes,d:[[u8]],e:{x:[f32;2]},g:bool}");
        let value = json!({
            "a": [{ "s": "x", "t": 1 }], "b": [1, 2, 3, 4], "c": [9], "d": [[1], []],
            "e": { "x": [1, 2] }, "g": true,
        });
        let bytes = encode(&f, &value).unwrap();
        assert!(decode(&f, &bytes).is_ok());
        for cut in 0..bytes.len() {
            assert!(decode(&f, &bytes[..cut]).is_err(), "cut at {cut}");
        }
        let mut trailing = bytes.clone();
        trailing.push(0);
        assert!(
            decode(&f, &trailing)
                .unwrap_err()
                .reason
                .contains("trailing")
        );
        // A count of 4 billion allocates nothing.
        let huge = decode(&format("{a:[u64]}"), &[0xff, 0xff, 0xff, 0xff, 1]).unwrap_err();
        assert!(huge.reason.contains("exceeds"), "{huge}");
        let fixed = decode(&format("{a:[u64;65536]}"), &[0; 16]).unwrap_err();
        assert!(fixed.reason.contains("fixed array"), "{fixed}");
        let presence = decode(&format("{a:u8,b:string?}"), &[1, 2]).unwrap_err();
        assert_eq!(presence.offset, 1);
        assert!(decode(&format("{a:bool}"), &[2]).is_err());
        assert!(
            decode(
                &format("{t:time}"),
                &[0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff, 0xff, 0xff]
            )
            .is_err()
        );
        // Every byte string of a pseudo-random sequence, against every shape
        // (and every golden message's).
        let golden = golden();
        let shapes: Vec<MessageFormat> = golden["messages"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| format(m["format"].as_str().unwrap()))
            .collect();
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..2000 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let len = (seed % 48) as usize;
            let garbage: Vec<u8> = (0..len).map(|i| (seed >> (i % 8 * 8)) as u8).collect();
            let _ = decode(&f, &garbage);
            for shape in &shapes {
                let _ = decode(shape, &garbage);
            }
        }
    }

    fn camera_frame() -> Dyn {
        let f = format(
            "{header:{stamp:time,frame_id:u32},encoding:string,width:u32,height:u32,frame:[u8]}",
        );
        let pixels: Vec<u8> = (0..921_600u32).map(|i| i as u8).collect();
        let value = json!({
            "header": { "stamp": { "secs": 1_796_166_000, "nanos": 123 }, "frame_id": 7 },
            "encoding": "rgb8", "width": 640, "height": 480, "frame": pixels,
        });
        round_trip(&f, &value)
    }

    #[test]
    fn camera_frame_as_text() {
        assert_eq!(
            to_text(&camera_frame()),
            "header:\n\
             \x20 stamp: 2026-12-01T23:00:00.000000123Z\n\
             \x20 frame_id: 7\n\
             encoding: rgb8\n\
             width: 640\n\
             height: 480\n\
             frame: <921600 bytes: 00 01 02 03 04 05 06 07 …>\n"
        );
        let json = to_json(&camera_frame());
        assert_eq!(
            json["frame"],
            json!({ "len": 921_600, "head": "000102030405060708090a0b0c0d0e0f" })
        );
        assert_eq!(
            json["header"]["stamp"],
            json!({ "secs": 1_796_166_000, "nanos": 123 })
        );
        let keys: Vec<&String> = json.as_object().unwrap().keys().collect();
        assert_eq!(keys, ["header", "encoding", "width", "height", "frame"]);
    }

    #[test]
    fn text_of_arrays_strings_and_absent_fields() {
        let f = format(
            "{points:[{x:f32,y:f32}],ids:[u16],long:[u32],words:[string],note:string?,\
             s:[string],b:bytes,empty:[u8]}",
        );
        let value = json!({
            "points": [{ "x": 1, "y": 0.1 }, { "x": -2.5, "y": 3 }],
            "ids": [1, 2, 3], "long": (0..40).collect::<Vec<u32>>(), "words": [],
            "s": ["plain", "", "42", "~", "a: b", " pad", "<3 bytes>", "line\nbreak"],
            "b": [1, 2, 3], "empty": [],
        });
        let text = to_text(&round_trip(&f, &value));
        let long: String = (0..16).map(|i| format!("  - {i}\n")).collect::<String>()
            + "  - … 24 more items (40 in all)\n";
        let expected = format!(
            "points:\n  - x: 1.0\n    y: 0.1\n  - x: -2.5\n    y: 3.0\nids: [1, 2, 3]\nlong:\n{long}\
             words: []\nnote: ~\n\
             s: [plain, \"\", \"42\", \"~\", \"a: b\", \" pad\", \"<3 bytes>\", \"line\\nbreak\"]\n\
             b: <3 bytes: 01 02 03>\nempty: <0 bytes>\n"
        );
        assert_eq!(text, expected);
        assert_eq!(to_text(&object(vec![])), "{}\n");
        assert_eq!(quoted("true"), "\"true\"");
        assert_eq!(quoted("NaN"), "\"NaN\"");
        assert_eq!(quoted("rgb8"), "rgb8");
    }

    #[test]
    fn times_in_rfc3339() {
        assert_eq!(rfc3339(0, 0), "1970-01-01T00:00:00.000000000Z");
        assert_eq!(rfc3339(-1, 999_999_999), "1969-12-31T23:59:59.999999999Z");
        assert_eq!(rfc3339(951_782_400, 5), "2000-02-29T00:00:00.000000005Z");
        assert_eq!(rfc3339(4_107_542_399, 0), "2100-02-28T23:59:59.000000000Z");
        assert_eq!(
            rfc3339(253_402_300_799, 0),
            "9999-12-31T23:59:59.000000000Z"
        );
        // Absurd times still print without overflowing.
        let _ = rfc3339(i64::MIN, 0);
        let _ = rfc3339(i64::MAX, 999_999_999);
    }

    #[test]
    fn json_keeps_exact_integers_and_marks_absent() {
        let value = object(vec![
            ("big", Dyn::UInt(u64::MAX)),
            ("low", Dyn::Int(i64::MIN)),
            ("nan", Dyn::Float(f64::NAN)),
            ("gone", Dyn::Absent),
            ("few", Dyn::Bytes(vec![0xab])),
        ]);
        assert_eq!(
            to_json(&value).to_string(),
            r#"{"big":18446744073709551615,"low":-9223372036854775808,"nan":"NaN","gone":null,"few":{"len":1,"head":"ab"}}"#
        );
    }

    #[test]
    fn long_arrays_show_their_first_items_and_a_count() {
        let points = Dyn::Array((0..1000).map(|i| Dyn::Float(f64::from(i) + 0.5)).collect());
        let text = to_text(&Dyn::Object(vec![("xs".into(), points)]));
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 1 + TEXT_ITEMS + 1, "{text}");
        assert_eq!(lines[1], "  - 0.5");
        assert_eq!(lines.last().unwrap(), &"  - … 984 more items (1000 in all)");
    }

    #[test]
    fn a_recording_writes_the_json_it_describes() {
        let value = object(vec![
            ("flag", Dyn::Bool(true)),
            ("n", Dyn::Int(-3)),
            ("big", Dyn::UInt(u64::MAX)),
            ("x", Dyn::Float(0.1)),
            ("nan", Dyn::Float(f64::NAN)),
            ("text", Dyn::Str("quote \" and \\ and \u{1}".into())),
            ("frame", Dyn::Bytes(vec![0, 1, 2, 250, 255])),
            ("stamp", Dyn::Time { secs: -1, nanos: 5 }),
            ("list", Dyn::Array(vec![Dyn::UInt(1), object(vec![])])),
            ("gone", Dyn::Absent),
        ]);
        let mut written = Vec::new();
        write_recording_json(&value, &mut written);
        let parsed: Value = serde_json::from_slice(&written).unwrap();
        assert_eq!(parsed, to_recording_json(&value));
        assert_eq!(parsed["frame"], "AAEC+v8=");
        assert_eq!(parsed["stamp"], json!({ "sec": -1, "nsec": 5 }));
        assert!(parsed.get("gone").is_none());
    }

    #[test]
    fn a_recorded_message_encodes_back_to_its_bytes() {
        let f = format(
            "{flag:bool,n:i8,x:f64,nan:f32,text:string,frame:[u8],blob:bytes,stamp:time,list:[u32;2],inner:{y:f32},opt:u8?,none:u8?}",
        );
        let sent = encode(
            &f,
            &json!({
                "flag": true, "n": -7, "x": 0.1, "nan": "NaN", "text": "h\u{e9}",
                "frame": [0, 255, 7], "blob": "raw", "stamp": { "secs": 1_700_000_000, "nanos": 9 },
                "list": [1, 2], "inner": { "y": 1.5 }, "opt": 3,
            }),
        )
        .unwrap();
        let mut written = Vec::new();
        write_recording_json(&decode(&f, &sent).unwrap(), &mut written);
        let read: Value = serde_json::from_slice(&written).unwrap();
        assert_eq!(encode_as(&f, &read, JsonForm::Recording).unwrap(), sent);
    }
}
