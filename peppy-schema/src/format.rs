//! Message formats: the field types of topics, services and actions.
//!
//! Key order is kept: it is the field order of generated structs and of the
//! wire encoding.

use std::fmt::Write as _;

use sha2::{Digest, Sha256};

use crate::diag::{Code, did_you_mean, list};
use crate::json::{Node, Value};
use crate::names::check_field_name;
use crate::read::{Loc, Reader, join};

pub(crate) use crate::primitive::{MAX_FIXED_LENGTH, Primitive, TYPE_NAMES};

/// What else a message field's type may be, for `UnknownType` help.
const MESSAGE_TYPES: &str = "or an object, or an array";

/// A message format: the root object's fields, in declaration order.
#[derive(Debug, Clone)]
pub struct MessageFormat {
    /// Root fields, in order.
    pub fields: Vec<Field>,
}

/// One field of an object.
#[derive(Debug, Clone)]
pub struct Field {
    /// The field name as declared.
    pub name: String,
    /// Its type.
    pub ty: FieldType,
    /// `$optional: true` (root fields only).
    pub optional: bool,
    /// Where the field's key is.
    pub loc: Loc,
}

impl PartialEq for Field {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name && self.ty == other.ty && self.optional == other.optional
    }
}

impl PartialEq for MessageFormat {
    fn eq(&self, other: &Self) -> bool {
        self.fields == other.fields
    }
}

/// A field's type.
#[derive(Debug, Clone)]
pub enum FieldType {
    /// A primitive.
    Primitive(Primitive),
    /// An array of primitives or objects (never of arrays).
    Array {
        /// The item type.
        items: Box<FieldType>,
        /// `$length`: a fixed-size array.
        length: Option<u32>,
        /// A length this node pins on an open array with `refine` (the
        /// current `node/v1` spelling): the node's own generated type holds
        /// exactly that many items, while the wire, the canonical text and
        /// the fingerprint stay those of the open array the document
        /// declares, so every other node reads the same messages.
        pinned: Option<u32>,
    },
    /// A nested object.
    Object(Vec<Field>),
}

/// Types are equal when their wire encodings are: a `refine` pin is one
/// node's view of a message, not a different message.
impl PartialEq for FieldType {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (FieldType::Primitive(a), FieldType::Primitive(b)) => a == b,
            (
                FieldType::Array {
                    items: a,
                    length: la,
                    ..
                },
                FieldType::Array {
                    items: b,
                    length: lb,
                    ..
                },
            ) => a == b && la == lb,
            (FieldType::Object(a), FieldType::Object(b)) => a == b,
            _ => false,
        }
    }
}

impl FieldType {
    /// An array of `items`, fixed to `length` items when given, unpinned.
    pub fn array(items: FieldType, length: Option<u32>) -> FieldType {
        FieldType::Array {
            items: Box::new(items),
            length,
            pinned: None,
        }
    }
}

impl MessageFormat {
    /// The canonical text of the format: names, types, order, optionality,
    /// with aliases resolved and no whitespace, e.g.
    /// `{header:{stamp:time,frame_id:u32},frame:[u8],note:string?}`.
    pub fn canonical(&self) -> String {
        let mut out = String::new();
        write_fields(&mut out, &self.fields);
        out
    }

    /// The format's fingerprint: the first 8 bytes of the sha256 of
    /// [`canonical`](Self::canonical), big-endian. Two formats share a
    /// fingerprint exactly when their wire encodings agree.
    pub fn fingerprint(&self) -> u64 {
        let digest = Sha256::digest(self.canonical().as_bytes());
        let mut first = [0u8; 8];
        first.copy_from_slice(&digest[..8]);
        u64::from_be_bytes(first)
    }
}

/// Why a format's canonical text could not be read back.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid message format text at byte {offset}: {message}")]
pub struct CanonicalError {
    /// Byte offset of the problem in the text.
    pub offset: usize,
    /// What was wrong there.
    pub message: String,
}

/// How the runtime prints the format of a message without payload.
const NO_PAYLOAD: &str = "(no payload)";

impl MessageFormat {
    /// Reads a canonical text (docs/WIRE.md section 6) back into a format:
    /// the inverse of [`canonical`](Self::canonical). `(no payload)` and
    /// `{}` are the empty format.
    ///
    /// Only the canonical spelling is accepted (no whitespace, no type
    /// aliases): the text is what the fingerprint was computed from, so a
    /// second spelling of one format would make two fingerprints. The
    /// document rules that only matter to generated code (reserved names,
    /// `$optional` on scalars) are not enforced; `?` on a nested field,
    /// an empty nested object and a `$length` outside 1 to
    /// [`MAX_FIXED_LENGTH`] are refused.
    pub fn from_canonical(text: &str) -> Result<MessageFormat, CanonicalError> {
        if text == NO_PAYLOAD {
            return Ok(MessageFormat { fields: Vec::new() });
        }
        let mut c = Canonical {
            text,
            pos: 0,
            depth: 0,
            loc: Loc::default(),
        };
        let fields = c.object(true)?;
        if c.pos < text.len() {
            return Err(c.error(format!("unexpected {} after the format", c.found())));
        }
        Ok(MessageFormat { fields })
    }
}

/// A cursor over a canonical text.
struct Canonical<'a> {
    text: &'a str,
    pos: usize,
    /// Object and array nesting, bounded: the text may come off the wire.
    depth: usize,
    /// One shared unlocated place for every field.
    loc: Loc,
}

impl<'a> Canonical<'a> {
    fn error_at(&self, offset: usize, message: impl Into<String>) -> CanonicalError {
        CanonicalError {
            offset,
            message: message.into(),
        }
    }

    fn error(&self, message: impl Into<String>) -> CanonicalError {
        self.error_at(self.pos, message)
    }

    fn peek(&self) -> Option<u8> {
        self.text.as_bytes().get(self.pos).copied()
    }

    /// The next character, for messages.
    fn found(&self) -> String {
        match self.text[self.pos..].chars().next() {
            Some(c) => format!("`{c}`"),
            None => "the end of the text".to_string(),
        }
    }

    fn expect(&mut self, byte: u8, what: &str) -> Result<(), CanonicalError> {
        if self.peek() == Some(byte) {
            self.pos += 1;
            return Ok(());
        }
        Err(self.error(format!(
            "expected `{}` {what}, found {}",
            byte as char,
            self.found()
        )))
    }

    /// A run of ASCII letters, digits and `_`, and where it starts.
    fn word(&mut self) -> (usize, &'a str) {
        let start = self.pos;
        let len = self.text.as_bytes()[start..]
            .iter()
            .take_while(|b| b.is_ascii_alphanumeric() || **b == b'_')
            .count();
        self.pos += len;
        (start, &self.text[start..self.pos])
    }

    /// Enters one level of nesting, refusing texts nested deeper than any
    /// document can be.
    fn enter(&mut self) -> Result<(), CanonicalError> {
        self.depth += 1;
        if self.depth > crate::json::MAX_DEPTH {
            return Err(self.error(format!(
                "objects and arrays nest deeper than {} levels",
                crate::json::MAX_DEPTH
            )));
        }
        Ok(())
    }

    /// `{` field (`,` field)* `}`; only the root may be `{}`.
    fn object(&mut self, root: bool) -> Result<Vec<Field>, CanonicalError> {
        let open = self.pos;
        self.expect(b'{', "to open an object")?;
        self.enter()?;
        let mut fields: Vec<Field> = Vec::new();
        if self.peek() == Some(b'}') {
            if !root {
                return Err(self.error_at(open, "a nested object has no fields"));
            }
            self.pos += 1;
            self.depth -= 1;
            return Ok(fields);
        }
        loop {
            let at = self.pos;
            let field = self.field(root)?;
            if fields.iter().any(|f| f.name == field.name) {
                return Err(self.error_at(at, format!("duplicate field `{}`", field.name)));
            }
            fields.push(field);
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b'}') => break,
                _ => {
                    return Err(self.error(format!(
                        "expected `,` or `}}` after a field, found {}",
                        self.found()
                    )));
                }
            }
        }
        self.pos += 1;
        self.depth -= 1;
        Ok(fields)
    }

    /// `name:type`, then `?` on an optional root field.
    fn field(&mut self, root: bool) -> Result<Field, CanonicalError> {
        let (at, name) = self.word();
        if name.is_empty() || name.as_bytes()[0].is_ascii_digit() {
            return Err(self.error_at(at, format!("expected a field name, found {}", self.found())));
        }
        self.expect(b':', "after the field name")?;
        let ty = self.ty()?;
        let optional = self.peek() == Some(b'?');
        if optional {
            if !root {
                return Err(self.error("`?` (optional) is only allowed on root fields"));
            }
            self.pos += 1;
        }
        Ok(Field {
            name: name.to_string(),
            ty,
            optional,
            loc: self.loc.clone(),
        })
    }

    fn ty(&mut self) -> Result<FieldType, CanonicalError> {
        match self.peek() {
            Some(b'{') => Ok(FieldType::Object(self.object(false)?)),
            Some(b'[') => self.array(),
            _ => self.primitive().map(FieldType::Primitive),
        }
    }

    fn primitive(&mut self) -> Result<Primitive, CanonicalError> {
        let (at, word) = self.word();
        match Primitive::parse(word) {
            Some(p) if p.name() == word => Ok(p),
            Some(p) => Err(self.error_at(
                at,
                format!("`{word}` is an alias: canonical text writes `{}`", p.name()),
            )),
            None if word.is_empty() => {
                Err(self.error(format!("expected a type, found {}", self.found())))
            }
            None => Err(self.error_at(at, format!("unknown type `{word}`"))),
        }
    }

    /// `[type]` or `[type;N]`.
    fn array(&mut self) -> Result<FieldType, CanonicalError> {
        self.pos += 1;
        self.enter()?;
        let items = self.ty()?;
        let length = if self.peek() == Some(b';') {
            self.pos += 1;
            Some(self.length()?)
        } else {
            None
        };
        self.expect(b']', "to close the array")?;
        self.depth -= 1;
        Ok(FieldType::array(items, length))
    }

    /// A fixed length as `canonical` writes it: decimal, no leading zero.
    fn length(&mut self) -> Result<u32, CanonicalError> {
        let (at, digits) = self.word();
        let n = digits
            .parse::<u64>()
            .ok()
            .filter(|n| (1..=MAX_FIXED_LENGTH).contains(n) && !digits.starts_with('0'));
        match n {
            Some(n) => Ok(n as u32),
            None if digits.is_empty() => {
                Err(self.error(format!("expected a length, found {}", self.found())))
            }
            None => Err(self.error_at(
                at,
                format!("invalid array length `{digits}`: expected 1 to {MAX_FIXED_LENGTH}"),
            )),
        }
    }
}

fn write_fields(out: &mut String, fields: &[Field]) {
    out.push('{');
    for (i, f) in fields.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push_str(&f.name);
        out.push(':');
        write_type(out, &f.ty);
        if f.optional {
            out.push('?');
        }
    }
    out.push('}');
}

fn write_type(out: &mut String, ty: &FieldType) {
    match ty {
        FieldType::Primitive(p) => out.push_str(p.name()),
        FieldType::Array { items, length, .. } => {
            out.push('[');
            write_type(out, items);
            if let Some(n) = length {
                let _ = write!(out, ";{n}");
            }
            out.push(']');
        }
        FieldType::Object(fields) => write_fields(out, fields),
    }
}

#[derive(Clone, Copy)]
struct Place {
    /// A field of the root object.
    root: bool,
    /// The `$items` of an array.
    item: bool,
}

/// Parses a `message_format` value. Errors go to the reader; `None` when
/// the format is unusable.
pub(crate) fn parse_format(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<MessageFormat> {
    let Value::Object(members) = &node.value else {
        r.error(
            Code::WrongType,
            node.span,
            path,
            format!(
                "expected an object of fields for `{path}`, found {}",
                node.value.kind()
            ),
        );
        return None;
    };
    let mut ok = true;
    let mut fields = Vec::new();
    for m in members {
        let field_path = join(path, &m.key);
        if m.key.starts_with('$') {
            r.error_help(
                Code::UnknownKey,
                m.key_span,
                &field_path,
                format!("`{}` is not allowed at the root of a message format", m.key),
                "the root of a message format lists fields; `$type`, `$optional` and friends belong to a field",
            );
            ok = false;
            continue;
        }
        match parse_field(
            r,
            &m.key,
            m.key_span,
            &m.value,
            &field_path,
            Place {
                root: true,
                item: false,
            },
        ) {
            Some(f) => fields.push(f),
            None => ok = false,
        }
    }
    if members.is_empty() {
        r.error_help(
            Code::EmptyMessageFormat,
            node.span,
            path,
            "message format has no fields",
            "declare at least one field, or omit the key for a message with no payload",
        );
        return None;
    }
    ok.then_some(MessageFormat { fields })
}

fn parse_field(
    r: &mut Reader<'_>,
    name: &str,
    key_span: crate::source::Span,
    node: &Node,
    path: &str,
    place: Place,
) -> Option<Field> {
    let mut ok = true;
    if name == "instance_id" {
        r.error_help(
            Code::ReservedFieldName,
            key_span,
            path,
            "the field name `instance_id` is reserved",
            "every message already carries its sender's instance id; rename the field (e.g. `source_id`)",
        );
        ok = false;
    } else if let Err(why) = check_field_name(name) {
        r.error(
            Code::InvalidFieldName,
            key_span,
            path,
            format!("invalid field name `{name}`: {why}"),
        );
        ok = false;
    }
    let (ty, optional) = parse_type(r, node, path, place)?;
    ok.then(|| Field {
        name: name.to_string(),
        ty,
        optional,
        loc: r.loc(key_span, path),
    })
}

/// The grammar shared by message formats and parameters: a primitive type
/// name. An unknown one is a located `UnknownType` error with a
/// did-you-mean; `others` names what else may stand there.
pub(crate) fn primitive_name(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    found: &str,
    others: &str,
) -> Option<Primitive> {
    if let Some(p) = Primitive::parse(found) {
        return Some(p);
    }
    let help = match found {
        "array" => "an array is written `{ $type: \"array\", $items: \"u8\" }`".to_string(),
        "object" => "an object is written `{ field: \"u32\", ... }`".to_string(),
        _ => match did_you_mean(found, TYPE_NAMES.iter().copied()) {
            Some(s) => format!(
                "did you mean `{s}`? types: {}",
                list(TYPE_NAMES.iter().copied())
            ),
            None => format!("types: {}, {others}", list(TYPE_NAMES.iter().copied())),
        },
    };
    r.error_help(
        Code::UnknownType,
        node.span,
        path,
        format!("unknown type `{found}`"),
        help,
    );
    None
}

/// `$length`, from 1 to [`MAX_FIXED_LENGTH`]. `Err` when it was refused
/// (and reported).
fn fixed_length(r: &mut Reader<'_>, node: &Node, path: &str) -> Result<u32, ()> {
    match r.uint(node, path, MAX_FIXED_LENGTH) {
        Some(0) => {
            r.error(
                Code::LengthMisuse,
                node.span,
                path,
                "`$length` must be at least 1",
            );
            Err(())
        }
        Some(n) => Ok(n as u32),
        None => Err(()),
    }
}

/// An array's item type, as a message format or a parameter schema reads
/// it, for [`parse_array_shape`].
pub(crate) trait ArrayItem: Sized {
    /// Whether the items are numbers or `bool`, the only items a fixed
    /// array (`$length`) may hold: it is a packed run of scalars.
    fn is_scalar(&self) -> bool;
}

/// The array grammar shared by message formats and parameters: `$items`
/// (required, no arrays of arrays; read by `items`, each kind of document
/// its own way) and `$length` (1 to [`MAX_FIXED_LENGTH`], over numbers or
/// `bool` only). `None` when the array cannot be read at all; `ok` turns
/// false when only its `$length` is refused.
pub(crate) fn parse_array_shape<T: ArrayItem>(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    ok: &mut bool,
    items: impl FnOnce(&mut Reader<'_>, &Node, &str) -> Option<T>,
) -> Option<(T, Option<u32>)> {
    let items_path = join(path, "$items");
    let Some(items_node) = node.get("$items") else {
        r.error_help(
            Code::MissingKey,
            node.span,
            path,
            format!("missing required key `$items` in array `{path}`"),
            "write `{ $type: \"array\", $items: \"f64\" }`",
        );
        return None;
    };
    let is_nested_array = match &items_node.value {
        Value::Object(_) => items_node.get("$type").and_then(Node::as_str) == Some("array"),
        Value::String(s) => s == "array",
        _ => false,
    };
    if is_nested_array {
        r.error_help(
            Code::NestedArray,
            items_node.span,
            &items_path,
            "arrays of arrays are not supported",
            "wrap the inner array in an object: `$items: { values: { $type: \"array\", $items: \"f64\" } }`",
        );
        return None;
    }
    let items = items(r, items_node, &items_path)?;
    let length = node.get("$length").and_then(|l| {
        let lpath = join(path, "$length");
        let n = fixed_length(r, l, &lpath).ok();
        if n.is_some() && !items.is_scalar() {
            r.error_help(
                Code::LengthMisuse,
                l.span,
                &lpath,
                "`$length` is only allowed when the items are numbers or `bool`",
                "drop `$length` to get a variable-length array",
            );
        }
        if n.is_none() || !items.is_scalar() {
            *ok = false;
        }
        n
    });
    Some((items, length))
}

impl ArrayItem for FieldType {
    fn is_scalar(&self) -> bool {
        matches!(self, FieldType::Primitive(p) if p.is_scalar())
    }
}

/// What a type object describes, by its `$type`.
#[derive(Clone, Copy)]
enum Shape {
    Object,
    Array,
    Primitive(Primitive),
}

/// A field's type: a type name, or an object (a nested object, an array
/// or a primitive with `$optional`). Returns the type and whether it is
/// optional.
fn parse_type(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    place: Place,
) -> Option<(FieldType, bool)> {
    let members = match &node.value {
        Value::String(s) => {
            let p = primitive_name(r, node, path, s, MESSAGE_TYPES)?;
            return Some((FieldType::Primitive(p), false));
        }
        Value::Object(members) => members,
        other => {
            r.error(
                Code::WrongType,
                node.span,
                path,
                format!(
                    "expected a type name or an object for `{path}`, found {}",
                    other.kind()
                ),
            );
            return None;
        }
    };
    let shape = shape_of(r, node, path)?;
    let mut ok = check_type_keys(r, members, shape, path);
    let optional = match node.get("$optional") {
        None => false,
        Some(o) => {
            let (value, valid) = parse_optional(r, o, &join(path, "$optional"), place, shape);
            ok &= valid;
            value
        }
    };
    let ty = match shape {
        Shape::Primitive(p) => FieldType::Primitive(p),
        Shape::Object => parse_object(r, node, members, path, &mut ok),
        Shape::Array => parse_array(r, node, path, &mut ok)?,
    };
    ok.then_some((ty, optional))
}

/// The shape a type object's `$type` names (none: an object).
fn shape_of(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<Shape> {
    let Some(type_node) = node.get("$type") else {
        return Some(Shape::Object);
    };
    let Some(type_name) = type_node.as_str() else {
        r.error(
            Code::WrongType,
            type_node.span,
            &join(path, "$type"),
            format!(
                "expected a type name for `{path}.$type`, found {}",
                type_node.value.kind()
            ),
        );
        return None;
    };
    Some(match type_name {
        "object" => Shape::Object,
        "array" => Shape::Array,
        s => Shape::Primitive(primitive_name(
            r,
            type_node,
            &join(path, "$type"),
            s,
            MESSAGE_TYPES,
        )?),
    })
}

/// Reports keys a type object of this shape may not have; `false` if any.
fn check_type_keys(
    r: &mut Reader<'_>,
    members: &[crate::json::Member],
    shape: Shape,
    path: &str,
) -> bool {
    let allowed: &[&str] = match shape {
        Shape::Object => &["$type", "$optional"],
        Shape::Array => &["$type", "$items", "$length", "$optional"],
        Shape::Primitive(_) => &["$type", "$optional"],
    };
    let mut ok = true;
    for m in members {
        let is_dollar = m.key.starts_with('$');
        let accepted =
            allowed.contains(&m.key.as_str()) || (!is_dollar && matches!(shape, Shape::Object));
        if accepted {
            continue;
        }
        ok = false;
        let m_path = join(path, &m.key);
        match (shape, m.key.as_str()) {
            (_, "$length") => r.error_help(
                Code::LengthMisuse,
                m.key_span,
                &m_path,
                "`$length` is only allowed on arrays",
                "write `{ $type: \"array\", $items: \"f64\", $length: 3 }`",
            ),
            (_, "$items") => r.error_help(
                Code::UnknownKey,
                m.key_span,
                &m_path,
                "`$items` is only allowed on arrays",
                "add `$type: \"array\"`",
            ),
            (_, "$default") => r.error_help(
                Code::UnknownKey,
                m.key_span,
                &m_path,
                "`$default` is not allowed in message formats",
                "defaults belong to `execution.parameters`",
            ),
            (Shape::Object, _) => r.unknown_key(m, path, allowed),
            (_, _) if is_dollar => r.unknown_key(m, path, allowed),
            (_, _) => r.error_help(
                Code::UnknownKey,
                m.key_span,
                &m_path,
                format!(
                    "unknown key `{}`: a field whose `$type` is not `object` has no sub-fields",
                    m.key
                ),
                format!("accepted keys here: {}", list(allowed.iter().copied())),
            ),
        }
    }
    ok
}

/// `$optional`: its value, and whether it is allowed here (only on
/// root-level fields that are not scalars).
fn parse_optional(
    r: &mut Reader<'_>,
    o: &Node,
    opath: &str,
    place: Place,
    shape: Shape,
) -> (bool, bool) {
    let Some(value) = r.bool(o, opath) else {
        return (false, false);
    };
    let mut ok = true;
    if value {
        if place.item {
            r.error_help(
                Code::OptionalMisuse,
                o.span,
                opath,
                "`$optional` is not allowed on array items",
                "make the whole array optional instead (on a root-level field)",
            );
            ok = false;
        } else if !place.root {
            r.error_help(
                Code::OptionalMisuse,
                o.span,
                opath,
                "`$optional` is only allowed on root-level fields",
                "move the optional part to the root of the message format, or make its parent optional",
            );
            ok = false;
        } else if let Shape::Primitive(p) = shape
            && p.is_scalar()
        {
            r.error_help(
                Code::OptionalMisuse,
                o.span,
                opath,
                format!(
                    "`$optional` is not allowed on `{}`: scalars have no presence bit",
                    p.name()
                ),
                "`$optional` works on `string`, `bytes`, `time`, arrays and objects",
            );
            ok = false;
        }
    }
    (value, ok)
}

/// The fields of a nested object (at least one).
fn parse_object(
    r: &mut Reader<'_>,
    node: &Node,
    members: &[crate::json::Member],
    path: &str,
    ok: &mut bool,
) -> FieldType {
    let mut fields = Vec::new();
    for m in members.iter().filter(|m| !m.key.starts_with('$')) {
        match parse_field(
            r,
            &m.key,
            m.key_span,
            &m.value,
            &join(path, &m.key),
            Place {
                root: false,
                item: false,
            },
        ) {
            Some(f) => fields.push(f),
            None => *ok = false,
        }
    }
    if fields.is_empty() && *ok {
        r.error_help(
            Code::EmptyMessageFormat,
            node.span,
            path,
            "object has no fields",
            "declare at least one field, or remove the object",
        );
        *ok = false;
    }
    FieldType::Object(fields)
}

/// An array of a message format ([`parse_array_shape`]).
fn parse_array(r: &mut Reader<'_>, node: &Node, path: &str, ok: &mut bool) -> Option<FieldType> {
    let place = Place {
        root: false,
        item: true,
    };
    let (items, length) = parse_array_shape(r, node, path, ok, |r, items, ipath| {
        parse_type(r, items, ipath, place).map(|(ty, _)| ty)
    })?;
    Some(FieldType::array(items, length))
}

/// A `message_format` that may be absent. `{}` is rejected by the parser, so
/// `None` always means "no payload".
pub(crate) fn parse_optional_format(
    r: &mut Reader<'_>,
    node: Option<&Node>,
    path: &str,
    ok: &mut bool,
) -> Option<MessageFormat> {
    let node = node?;
    let f = parse_format(r, node, path);
    if f.is_none() {
        *ok = false;
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diag::Diagnostics;
    use crate::source::SourceFile;

    fn parse_text(text: &str) -> (Option<MessageFormat>, Diagnostics) {
        let file = SourceFile::new("f.json5", text);
        let (node, mut diags) = crate::json::parse(&file).unwrap();
        let f = {
            let mut r = Reader::new(&file, &mut diags);
            parse_format(&mut r, &node, "message_format")
        };
        (f, diags)
    }

    fn codes(text: &str) -> Vec<Code> {
        parse_text(text).1.iter().map(|d| d.code).collect()
    }

    #[test]
    fn parses_every_shape_in_order() {
        let (f, diags) = parse_text(
            r#"{
                header: { $type: "object", stamp: "time", frame_id: "u32" },
                encoding: "str",
                frame: { $type: "array", $items: "u8" },
                pose: { $type: "array", $items: "double", $length: 7 },
                points: { $type: "array", $items: { x: "float", y: "f32" } },
                note: { $type: "string", $optional: true },
                type: "bool",
            }"#,
        );
        assert!(diags.is_empty(), "{diags}");
        let f = f.unwrap();
        assert_eq!(
            f.canonical(),
            "{header:{stamp:time,frame_id:u32},encoding:string,frame:[u8],pose:[f64;7],points:[{x:f32,y:f32}],note:string?,type:bool}"
        );
    }

    #[test]
    fn fingerprint_follows_order_names_and_types() {
        let a = parse_text("{ a: 'u8', b: 'f64' }").0.unwrap();
        let b = parse_text("{ b: 'f64', a: 'u8' }").0.unwrap();
        let c = parse_text("{ a: 'u8', b: 'double' }").0.unwrap();
        assert_ne!(a.fingerprint(), b.fingerprint());
        assert_eq!(a.fingerprint(), c.fingerprint());
        assert_eq!(a, c);
    }

    #[test]
    fn rules_of_section_2_2() {
        assert_eq!(codes("{}"), [Code::EmptyMessageFormat]);
        assert_eq!(codes("{ a: {} }"), [Code::EmptyMessageFormat]);
        assert_eq!(codes("{ a: 'big' }"), [Code::UnknownType]);
        assert_eq!(codes("{ instance_id: 'u8' }"), [Code::ReservedFieldName]);
        assert_eq!(
            codes("{ h: { instance_id: 'u8' } }"),
            [Code::ReservedFieldName]
        );
        assert_eq!(codes("{ 'foo-bar': 'u8' }"), [Code::InvalidFieldName]);
        assert_eq!(
            codes("{ a: { $type: 'u8', $optional: true } }"),
            [Code::OptionalMisuse]
        );
        assert_eq!(
            codes("{ h: { s: { $type: 'string', $optional: true } } }"),
            [Code::OptionalMisuse]
        );
        assert_eq!(
            codes("{ a: { $type: 'array', $items: { $type: 'string', $optional: true } } }"),
            [Code::OptionalMisuse]
        );
        assert!(
            parse_text("{ a: { $type: 'string', $optional: true } }")
                .1
                .is_empty()
        );
        assert!(
            parse_text("{ a: { $type: 'array', $items: 'u8', $optional: true } }")
                .1
                .is_empty()
        );
        assert_eq!(
            codes("{ a: { $type: 'array', $items: 'string', $length: 2 } }"),
            [Code::LengthMisuse]
        );
        assert_eq!(
            codes("{ a: { $type: 'u8', $length: 2 } }"),
            [Code::LengthMisuse]
        );
        assert_eq!(
            codes("{ a: { $type: 'array', $items: 'u8', $length: 0 } }"),
            [Code::LengthMisuse]
        );
        assert_eq!(
            codes("{ a: { $type: 'array', $items: { $type: 'array', $items: 'u8' } } }"),
            [Code::NestedArray]
        );
        assert_eq!(codes("{ a: { $type: 'array' } }"), [Code::MissingKey]);
        assert_eq!(
            codes("{ a: { $type: 'u8', $bogus: 1 } }"),
            [Code::UnknownKey]
        );
        assert_eq!(codes("{ a: { $typo: 'u8', x: 'u8' } }"), [Code::UnknownKey]);
        assert_eq!(codes("{ a: 3 }"), [Code::WrongType]);
    }

    #[test]
    fn all_errors_are_collected() {
        let (f, diags) =
            parse_text("{ a: 'nope', instance_id: 'u8', c: { $type: 'u8', $optional: true } }");
        assert!(f.is_none());
        assert_eq!(diags.error_count(), 3);
    }

    #[test]
    fn canonical_text_reads_back() {
        let documents = [
            r#"{
                header: { $type: "object", stamp: "time", frame_id: "u32" },
                encoding: "str",
                frame: { $type: "array", $items: "u8" },
                pose: { $type: "array", $items: "double", $length: 7 },
                points: { $type: "array", $items: { x: "float", y: "f32" } },
                note: { $type: "string", $optional: true },
                type: "bool",
            }"#,
            "{ a: 'u8', b: 'f64' }",
            "{ a: { $type: 'array', $items: 'u8', $optional: true }, b: 'bytes', c: 'i64' }",
            "{ h: { s: { t: 'time', i: 'i8' }, u: 'u16' }, m: { $type: 'array', $items: 'bool', $length: 65536 } }",
        ];
        for text in documents {
            let f = parse_text(text).0.unwrap();
            let back = MessageFormat::from_canonical(&f.canonical()).unwrap();
            assert_eq!(back.canonical(), f.canonical());
            assert_eq!(back.fingerprint(), f.fingerprint());
            assert_eq!(back, f);
        }
    }

    #[test]
    fn no_payload_reads_as_the_empty_format() {
        for text in ["(no payload)", "{}"] {
            assert!(
                MessageFormat::from_canonical(text)
                    .unwrap()
                    .fields
                    .is_empty()
            );
        }
        // Root scalars may be optional on the wire (the golden bytes have one).
        let f = MessageFormat::from_canonical("{a:u8?,b:[[u8]]}").unwrap();
        assert!(f.fields[0].optional);
    }

    #[test]
    fn malformed_canonical_text_is_located() {
        let cases = [
            ("{a:u322}", 3, "unknown type `u322`"),
            ("{a:float}", 3, "alias"),
            ("{a:u8", 5, "expected `,` or `}`"),
            ("a:u8}", 0, "expected `{`"),
            ("{a:u8}x", 6, "unexpected `x`"),
            ("{a:u8},", 6, "unexpected `,`"),
            ("{a:[u8;0]}", 7, "invalid array length `0`"),
            ("{a:[u8;65537]}", 7, "invalid array length"),
            ("{a:[u8;07]}", 7, "invalid array length"),
            ("{a:[u8;]}", 7, "expected a length"),
            ("{a:[u8}", 6, "expected `]`"),
            ("{a:{}}", 3, "nested object has no fields"),
            ("{a:{b:u8?}}", 8, "only allowed on root fields"),
            ("{a:u8,a:u16}", 6, "duplicate field `a`"),
            ("{a: u8}", 3, "expected a type"),
            ("{1a:u8}", 1, "expected a field name"),
            ("{a:u8,}", 6, "expected a field name"),
            ("", 0, "expected `{`"),
            ("{é:u8}", 1, "expected a field name, found `é`"),
        ];
        for (text, offset, message) in cases {
            let err = MessageFormat::from_canonical(text).unwrap_err();
            assert_eq!(err.offset, offset, "{text}: {err}");
            assert!(err.message.contains(message), "{text}: {err}");
        }
        let deep = format!("{}u8{}", "{a:".repeat(100), "}".repeat(100));
        let err = MessageFormat::from_canonical(&deep).unwrap_err();
        assert!(err.message.contains("nest deeper"), "{err}");
    }

    #[test]
    fn did_you_mean_for_types() {
        let (_, diags) = parse_text("{ a: 'u322' }");
        let d = diags.iter().next().unwrap();
        assert!(
            d.help.as_deref().unwrap().contains("did you mean `u32`"),
            "{d}"
        );
        assert_eq!(d.key_path.as_deref(), Some("message_format.a"));
    }
}
