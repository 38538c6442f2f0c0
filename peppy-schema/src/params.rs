//! Parameter schemas (`execution.parameters`) and filling in values.
//!
//! One implementation checks `$default`s at parse time and launcher
//! `arguments` / runtime values later: everything goes through
//! [`check_leaf`] on a `serde_json::Value`.

use serde_json::{Map, Value as Json};

use crate::diag::{Code, did_you_mean, list};
use crate::format::{MAX_FIXED_LENGTH, Primitive, TYPE_NAMES};
use crate::json::{Node, Value};
use crate::names::check_field_name;
use crate::read::{Loc, Reader, join};

/// The parameters a node takes: the root group's fields, in order.
#[derive(Debug, Clone, Default)]
pub struct ParameterSchema {
    /// Root parameters and groups.
    pub fields: Vec<ParamField>,
}

/// One parameter or group.
#[derive(Debug, Clone)]
pub struct ParamField {
    /// Its key.
    pub name: String,
    /// What it holds.
    pub kind: ParamKind,
    /// Where it is declared.
    pub loc: Loc,
}

/// What a parameter holds.
#[derive(Debug, Clone)]
pub enum ParamKind {
    /// A primitive value.
    Leaf {
        /// Its type.
        ty: Primitive,
        /// `$default`, already checked against the type.
        default: Option<Json>,
    },
    /// An array.
    Array {
        /// Item type.
        items: ParamItem,
        /// `$length`.
        length: Option<u32>,
        /// `$default` (primitive items only), already checked.
        default: Option<Json>,
    },
    /// A nested group of parameters.
    Group(Vec<ParamField>),
}

/// The items of an array parameter.
#[derive(Debug, Clone)]
pub enum ParamItem {
    /// Primitive items.
    Primitive(Primitive),
    /// Object items, each with these fields (no defaults inside).
    Object(Vec<ParamField>),
}

/// Why a parameter value was refused.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParamError {
    /// Dot-path of the parameter (`video.fps`, `limits[2]`).
    pub path: String,
    /// What went wrong.
    pub kind: ParamErrorKind,
}

/// What went wrong with a parameter value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ParamErrorKind {
    /// A required parameter (no `$default`) was not given.
    Missing {
        /// The expected type.
        expected: String,
    },
    /// A key the schema does not declare.
    Unknown {
        /// A close declared name, if any.
        suggestion: Option<String>,
        /// Declared names at that level.
        accepted: Vec<String>,
    },
    /// A value of the wrong type or out of range.
    TypeMismatch {
        /// What was expected.
        expected: String,
        /// What was given.
        found: String,
    },
}

impl ParamError {
    /// The diagnostic code for this error.
    pub fn code(&self) -> Code {
        match self.kind {
            ParamErrorKind::Missing { .. } => Code::MissingParameter,
            ParamErrorKind::Unknown { .. } => Code::UnknownParameter,
            ParamErrorKind::TypeMismatch { .. } => Code::ParameterTypeMismatch,
        }
    }

    /// What would be accepted.
    pub fn help(&self) -> Option<String> {
        match &self.kind {
            ParamErrorKind::Missing { .. } => Some(format!(
                "pass it (`{}=...` on the command line, or under `arguments` in a launcher) or give it a `$default`",
                self.path
            )),
            ParamErrorKind::Unknown {
                suggestion,
                accepted,
            } => Some(match suggestion {
                Some(s) => format!(
                    "did you mean `{s}`? parameters here: {}",
                    list(accepted.iter().map(String::as_str))
                ),
                None => format!(
                    "parameters here: {}",
                    list(accepted.iter().map(String::as_str))
                ),
            }),
            ParamErrorKind::TypeMismatch { .. } => None,
        }
    }
}

impl std::fmt::Display for ParamError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.kind {
            ParamErrorKind::Missing { expected } => {
                write!(f, "missing required parameter `{}` ({expected})", self.path)
            }
            ParamErrorKind::Unknown { .. } => write!(f, "unknown parameter `{}`", self.path),
            ParamErrorKind::TypeMismatch { expected, found } => write!(
                f,
                "parameter `{}` expects {expected}, found {found}",
                self.path
            ),
        }
    }
}

impl std::error::Error for ParamError {}

/// Human description of a primitive's accepted values.
pub fn describe(ty: Primitive) -> String {
    match ty {
        Primitive::Bool => "a `bool` (true or false)".into(),
        Primitive::F32 => "an `f32` (a finite number)".into(),
        Primitive::F64 => "an `f64` (a number)".into(),
        Primitive::String => "a `string`".into(),
        Primitive::Bytes => "`bytes` (a string or an array of 0..=255)".into(),
        Primitive::Time => "a `time` (seconds since the Unix epoch)".into(),
        p => {
            let (lo, hi) = p.int_range().expect("integer type");
            format!("a `{}` (an integer from {lo} to {hi})", p.name())
        }
    }
}

fn describe_found(v: &Json) -> String {
    match v {
        Json::Null => "null".into(),
        Json::Bool(b) => format!("`{b}`"),
        Json::Number(n) => format!("`{n}`"),
        Json::String(s) => format!("the string {s:?}"),
        Json::Array(_) => "an array".into(),
        Json::Object(_) => "an object".into(),
    }
}

/// Checks one primitive value; returns it normalised (`bytes` as an array).
pub fn check_leaf(ty: Primitive, v: &Json) -> Result<Json, String> {
    let mismatch = || {
        Err(format!(
            "expects {}, found {}",
            describe(ty),
            describe_found(v)
        ))
    };
    match ty {
        Primitive::Bool => match v {
            Json::Bool(_) => Ok(v.clone()),
            _ => mismatch(),
        },
        Primitive::F32 => match v.as_f64() {
            Some(f) if f.is_finite() && f.abs() <= f32::MAX as f64 => Ok(v.clone()),
            _ => mismatch(),
        },
        Primitive::F64 => match v.as_f64() {
            Some(_) => Ok(v.clone()),
            None => mismatch(),
        },
        Primitive::Time => match v.as_f64() {
            Some(f) if f.is_finite() => Ok(v.clone()),
            _ => mismatch(),
        },
        Primitive::String => match v {
            Json::String(_) => Ok(v.clone()),
            _ => mismatch(),
        },
        Primitive::Bytes => match v {
            Json::String(s) => Ok(s.bytes().map(Json::from).collect()),
            Json::Array(items) if items.iter().all(|i| i.as_u64().is_some_and(|b| b <= 255)) => {
                Ok(v.clone())
            }
            _ => mismatch(),
        },
        int => {
            let (lo, hi) = int.int_range().expect("integer type");
            let value = v
                .as_i64()
                .map(i128::from)
                .or_else(|| v.as_u64().map(i128::from));
            match value {
                Some(i) if i >= lo && i <= hi => Ok(v.clone()),
                _ => mismatch(),
            }
        }
    }
}

impl ParameterSchema {
    /// Whether the node takes no parameters.
    pub fn is_empty(&self) -> bool {
        self.fields.is_empty()
    }

    /// Checks `provided` (an object, or `null` for none) against the schema
    /// and fills in defaults, including whole groups whose leaves all have
    /// defaults. Every problem is returned, each naming its dot-path.
    pub fn resolve(&self, provided: &Json) -> Result<Json, Vec<ParamError>> {
        let mut errors = Vec::new();
        let map = match provided {
            Json::Null => None,
            Json::Object(m) => Some(m),
            other => {
                errors.push(ParamError {
                    path: String::new(),
                    kind: ParamErrorKind::TypeMismatch {
                        expected: "an object of parameters".into(),
                        found: describe_found(other),
                    },
                });
                return Err(errors);
            }
        };
        let out = resolve_group(&self.fields, map, "", &mut errors);
        if errors.is_empty() {
            Ok(Json::Object(out))
        } else {
            Err(errors)
        }
    }
}

fn dot(parent: &str, key: &str) -> String {
    if parent.is_empty() {
        key.to_string()
    } else {
        format!("{parent}.{key}")
    }
}

fn resolve_group(
    fields: &[ParamField],
    provided: Option<&Map<String, Json>>,
    path: &str,
    errors: &mut Vec<ParamError>,
) -> Map<String, Json> {
    let mut out = Map::new();
    if let Some(map) = provided {
        for key in map.keys() {
            if !fields.iter().any(|f| &f.name == key) {
                let accepted: Vec<String> = fields.iter().map(|f| f.name.clone()).collect();
                errors.push(ParamError {
                    path: dot(path, key),
                    kind: ParamErrorKind::Unknown {
                        suggestion: did_you_mean(key, accepted.iter().map(String::as_str))
                            .map(str::to_string),
                        accepted,
                    },
                });
            }
        }
    }
    for f in fields {
        let fpath = dot(path, &f.name);
        let given = provided.and_then(|m| m.get(&f.name));
        if let Some(v) = resolve_field(&f.kind, given, &fpath, errors) {
            out.insert(f.name.clone(), v);
        }
    }
    out
}

fn resolve_field(
    kind: &ParamKind,
    given: Option<&Json>,
    path: &str,
    errors: &mut Vec<ParamError>,
) -> Option<Json> {
    let mismatch = |errors: &mut Vec<ParamError>, expected: String, found: &Json| {
        errors.push(ParamError {
            path: path.to_string(),
            kind: ParamErrorKind::TypeMismatch {
                expected,
                found: describe_found(found),
            },
        });
    };
    match (kind, given) {
        (ParamKind::Leaf { ty, .. }, Some(v)) => match check_leaf(*ty, v) {
            Ok(v) => Some(v),
            Err(_) => {
                mismatch(errors, describe(*ty), v);
                None
            }
        },
        (
            ParamKind::Leaf {
                default: Some(d), ..
            },
            None,
        ) => Some(d.clone()),
        (ParamKind::Leaf { ty, default: None }, None) => {
            errors.push(ParamError {
                path: path.to_string(),
                kind: ParamErrorKind::Missing {
                    expected: describe(*ty),
                },
            });
            None
        }
        (ParamKind::Array { items, length, .. }, Some(v)) => {
            let Json::Array(values) = v else {
                mismatch(errors, describe_array(items, *length), v);
                return None;
            };
            if let Some(n) = length
                && values.len() != *n as usize
            {
                mismatch(errors, describe_array(items, *length), v);
                return None;
            }
            let mut out = Vec::with_capacity(values.len());
            for (i, item) in values.iter().enumerate() {
                let ipath = format!("{path}[{i}]");
                match items {
                    ParamItem::Primitive(p) => match check_leaf(*p, item) {
                        Ok(v) => out.push(v),
                        Err(_) => mismatch_at(errors, &ipath, describe(*p), item),
                    },
                    ParamItem::Object(fields) => match item {
                        Json::Object(m) => {
                            out.push(Json::Object(resolve_group(fields, Some(m), &ipath, errors)))
                        }
                        other => mismatch_at(errors, &ipath, "an object".into(), other),
                    },
                }
            }
            Some(Json::Array(out))
        }
        (
            ParamKind::Array {
                default: Some(d), ..
            },
            None,
        ) => Some(d.clone()),
        (
            ParamKind::Array {
                items,
                length,
                default: None,
            },
            None,
        ) => {
            errors.push(ParamError {
                path: path.to_string(),
                kind: ParamErrorKind::Missing {
                    expected: describe_array(items, *length),
                },
            });
            None
        }
        (ParamKind::Group(fields), Some(Json::Object(m))) => {
            Some(Json::Object(resolve_group(fields, Some(m), path, errors)))
        }
        (ParamKind::Group(_), Some(other)) => {
            mismatch(errors, "an object (a parameter group)".into(), other);
            None
        }
        (ParamKind::Group(fields), None) => {
            Some(Json::Object(resolve_group(fields, None, path, errors)))
        }
    }
}

fn mismatch_at(errors: &mut Vec<ParamError>, path: &str, expected: String, found: &Json) {
    errors.push(ParamError {
        path: path.to_string(),
        kind: ParamErrorKind::TypeMismatch {
            expected,
            found: describe_found(found),
        },
    });
}

fn describe_array(items: &ParamItem, length: Option<u32>) -> String {
    let item = match items {
        ParamItem::Primitive(p) => p.name().to_string(),
        ParamItem::Object(_) => "object".to_string(),
    };
    match length {
        Some(n) => format!("an array of exactly {n} `{item}`"),
        None => format!("an array of `{item}`"),
    }
}

/// Parses `execution.parameters`.
pub(crate) fn parse_parameters(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
) -> Option<ParameterSchema> {
    let Value::Object(members) = &node.value else {
        r.error(
            Code::WrongType,
            node.span,
            path,
            format!(
                "expected an object of parameters for `{path}`, found {}",
                node.value.kind()
            ),
        );
        return None;
    };
    let fields = parse_fields(r, members, path, false)?;
    Some(ParameterSchema { fields })
}

fn parse_fields(
    r: &mut Reader<'_>,
    members: &[crate::json::Member],
    path: &str,
    in_item: bool,
) -> Option<Vec<ParamField>> {
    let mut ok = true;
    let mut fields = Vec::new();
    for m in members {
        let fpath = join(path, &m.key);
        if m.key.starts_with('$') {
            r.error_help(
                Code::UnknownKey,
                m.key_span,
                &fpath,
                format!("`{}` is not allowed here", m.key),
                "a group lists parameters; `$type` and `$default` belong to a parameter",
            );
            ok = false;
            continue;
        }
        if let Err(why) = check_field_name(&m.key) {
            r.error(
                Code::InvalidFieldName,
                m.key_span,
                &fpath,
                format!("invalid parameter name `{}`: {why}", m.key),
            );
            ok = false;
            continue;
        }
        match parse_param(r, &m.value, &fpath, in_item) {
            Some(kind) => fields.push(ParamField {
                name: m.key.clone(),
                kind,
                loc: r.loc(m.key_span, &fpath),
            }),
            None => ok = false,
        }
    }
    ok.then_some(fields)
}

fn parse_primitive_name(r: &mut Reader<'_>, node: &Node, path: &str, s: &str) -> Option<Primitive> {
    let p = Primitive::parse(s);
    if p.is_none() {
        let help = match did_you_mean(s, TYPE_NAMES.iter().copied()) {
            Some(c) => format!(
                "did you mean `{c}`? types: {}",
                list(TYPE_NAMES.iter().copied())
            ),
            None => format!(
                "types: {}, a group (an object) or an array",
                list(TYPE_NAMES.iter().copied())
            ),
        };
        r.error_help(
            Code::UnknownType,
            node.span,
            path,
            format!("unknown type `{s}`"),
            help,
        );
    }
    p
}

fn parse_param(r: &mut Reader<'_>, node: &Node, path: &str, in_item: bool) -> Option<ParamKind> {
    let members = match &node.value {
        Value::String(s) => {
            let ty = parse_primitive_name(r, node, path, s)?;
            return Some(ParamKind::Leaf { ty, default: None });
        }
        Value::Object(m) => m,
        other => {
            r.error(
                Code::WrongType,
                node.span,
                path,
                format!("expected a type name, a `{{ $type, $default }}` object or a group for `{path}`, found {}", other.kind()),
            );
            return None;
        }
    };
    let type_name = match node.get("$type") {
        None => None,
        Some(t) => Some(r.string(t, &join(path, "$type"))?),
    };
    let mut ok = true;
    for m in members.iter().filter(|m| m.key.starts_with('$')) {
        let mpath = join(path, &m.key);
        match m.key.as_str() {
            "$type" => {}
            "$optional" => {
                r.error_help(
                    Code::OptionalMisuse,
                    m.key_span,
                    &mpath,
                    "`$optional` is not supported on parameters",
                    "give the parameter a `$default` instead",
                );
                ok = false;
            }
            "$default" | "$items" | "$length" => {}
            _ => {
                r.unknown_key(m, path, &["$type", "$default", "$items", "$length"]);
                ok = false;
            }
        }
    }
    let kind = match type_name.as_deref() {
        None | Some("object") => {
            for key in ["$default", "$items", "$length"] {
                if let Some(m) = members.iter().find(|m| m.key == key) {
                    let code = if key == "$default" {
                        Code::InvalidDefault
                    } else {
                        Code::UnknownKey
                    };
                    r.error_help(
                        code,
                        m.key_span,
                        &join(path, key),
                        format!("`{key}` is not allowed on a parameter group"),
                        "set defaults on the group's parameters; a group is filled in when all of them have defaults",
                    );
                    ok = false;
                }
            }
            let children: Vec<crate::json::Member> = members
                .iter()
                .filter(|m| !m.key.starts_with('$'))
                .cloned()
                .collect();
            if children.is_empty() {
                r.error(
                    Code::InvalidValue,
                    node.span,
                    path,
                    format!("parameter group `{path}` has no parameters"),
                );
                return None;
            }
            ParamKind::Group(parse_fields(r, &children, path, in_item)?)
        }
        Some("array") => {
            if let Some(m) = members.iter().find(|m| !m.key.starts_with('$')) {
                r.unknown_key(m, path, &["$type", "$items", "$length", "$default"]);
                ok = false;
            }
            let Some(items_node) = node.get("$items") else {
                r.error_help(
                    Code::MissingKey,
                    node.span,
                    path,
                    format!("missing required key `$items` in array parameter `{path}`"),
                    "write `{ $type: \"array\", $items: \"f64\" }`",
                );
                return None;
            };
            let ipath = join(path, "$items");
            let items = match &items_node.value {
                Value::String(s) => {
                    ParamItem::Primitive(parse_primitive_name(r, items_node, &ipath, s)?)
                }
                Value::Object(_) => match parse_param(r, items_node, &ipath, true)? {
                    ParamKind::Leaf { ty, default: None } => ParamItem::Primitive(ty),
                    ParamKind::Group(fields) => ParamItem::Object(fields),
                    ParamKind::Array { .. } => {
                        r.error(
                            Code::NestedArray,
                            items_node.span,
                            &ipath,
                            "arrays of arrays are not supported",
                        );
                        return None;
                    }
                    ParamKind::Leaf {
                        default: Some(_), ..
                    } => return None,
                },
                other => {
                    r.error(
                        Code::WrongType,
                        items_node.span,
                        &ipath,
                        format!(
                            "expected a type name or an object for `{ipath}`, found {}",
                            other.kind()
                        ),
                    );
                    return None;
                }
            };
            let length = match node.get("$length") {
                None => None,
                Some(l) => {
                    let lpath = join(path, "$length");
                    match r.uint(l, &lpath, MAX_FIXED_LENGTH) {
                        Some(0) | None => {
                            r.error(
                                Code::LengthMisuse,
                                l.span,
                                &lpath,
                                "`$length` must be a positive integer",
                            );
                            ok = false;
                            None
                        }
                        Some(n) => Some(n as u32),
                    }
                }
            };
            let default = match node.get("$default") {
                None => None,
                Some(d) => {
                    let dpath = join(path, "$default");
                    match &items {
                        ParamItem::Object(_) => {
                            r.error(
                                Code::InvalidDefault,
                                d.span,
                                &dpath,
                                "`$default` is not supported on arrays of objects",
                            );
                            ok = false;
                            None
                        }
                        ParamItem::Primitive(p) => {
                            let mut errors = Vec::new();
                            let v = resolve_field(
                                &ParamKind::Array {
                                    items: ParamItem::Primitive(*p),
                                    length,
                                    default: None,
                                },
                                Some(&d.to_json()),
                                "$default",
                                &mut errors,
                            );
                            for e in &errors {
                                let at = item_node(d, &e.path).unwrap_or(d);
                                r.error(
                                    Code::InvalidDefault,
                                    at.span,
                                    &dpath,
                                    format!("invalid `$default`: {}", e_message(e)),
                                );
                            }
                            if !errors.is_empty() {
                                ok = false;
                            }
                            v
                        }
                    }
                }
            };
            ParamKind::Array {
                items,
                length,
                default,
            }
        }
        Some(s) => {
            let type_node = node.get("$type").expect("present");
            let ty = parse_primitive_name(r, type_node, &join(path, "$type"), s)?;
            for m in members.iter().filter(|m| !m.key.starts_with('$')) {
                r.unknown_key(m, path, &["$type", "$default"]);
                ok = false;
            }
            for key in ["$items", "$length"] {
                if let Some(m) = members.iter().find(|m| m.key == key) {
                    r.error(
                        Code::UnknownKey,
                        m.key_span,
                        &join(path, key),
                        format!("`{key}` is only allowed on array parameters"),
                    );
                    ok = false;
                }
            }
            let default = match node.get("$default") {
                None => None,
                Some(d) => {
                    let dpath = join(path, "$default");
                    if in_item {
                        r.error(
                            Code::InvalidDefault,
                            d.span,
                            &dpath,
                            "`$default` is not allowed inside array items",
                        );
                        ok = false;
                        None
                    } else if matches!(ty, Primitive::Bytes | Primitive::Time) {
                        r.error_help(
                            Code::InvalidDefault,
                            d.span,
                            &dpath,
                            format!("`$default` is not supported for `{}` parameters", ty.name()),
                            "pass the value at launch instead",
                        );
                        ok = false;
                        None
                    } else {
                        match check_leaf(ty, &d.to_json()) {
                            Ok(v) => Some(v),
                            Err(why) => {
                                r.error(
                                    Code::InvalidDefault,
                                    d.span,
                                    &dpath,
                                    format!("invalid `$default`: `{path}` {why}"),
                                );
                                ok = false;
                                None
                            }
                        }
                    }
                }
            };
            ParamKind::Leaf { ty, default }
        }
    };
    ok.then_some(kind)
}

fn e_message(e: &ParamError) -> String {
    match &e.kind {
        ParamErrorKind::TypeMismatch { expected, found } => {
            format!("expects {expected}, found {found}")
        }
        _ => e.to_string(),
    }
}

/// The array element a `$default[i]` error path points at.
fn item_node<'n>(d: &'n Node, path: &str) -> Option<&'n Node> {
    let i: usize = path
        .strip_prefix("$default[")?
        .strip_suffix(']')?
        .parse()
        .ok()?;
    match &d.value {
        Value::Array(items) => items.get(i),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diag::Diagnostics;
    use crate::source::SourceFile;
    use serde_json::json;

    fn schema(text: &str) -> (Option<ParameterSchema>, Diagnostics) {
        let file = SourceFile::new("p.json5", text);
        let (node, mut diags) = crate::json::parse(&file).unwrap();
        let s = {
            let mut r = Reader::new(&file, &mut diags);
            parse_parameters(&mut r, &node, "execution.parameters")
        };
        (s, diags)
    }

    fn codes(text: &str) -> Vec<Code> {
        schema(text).1.iter().map(|d| d.code).collect()
    }

    #[test]
    fn defaults_are_type_and_range_checked() {
        assert_eq!(
            codes("{ a: { $type: 'u8', $default: 300 } }"),
            [Code::InvalidDefault]
        );
        assert_eq!(
            codes("{ a: { $type: 'u16', $default: -1 } }"),
            [Code::InvalidDefault]
        );
        assert_eq!(
            codes("{ a: { $type: 'u16', $default: 'x' } }"),
            [Code::InvalidDefault]
        );
        assert_eq!(
            codes("{ a: { $type: 'f32', $default: 1e300 } }"),
            [Code::InvalidDefault]
        );
        assert_eq!(
            codes("{ a: { $type: 'bytes', $default: 'x' } }"),
            [Code::InvalidDefault]
        );
        assert_eq!(
            codes("{ a: { $type: 'time', $default: 1 } }"),
            [Code::InvalidDefault]
        );
        assert_eq!(
            codes("{ g: { $default: 1, x: 'u8' } }"),
            [Code::InvalidDefault]
        );
        assert_eq!(
            codes("{ a: { $type: 'u8', $optional: true } }"),
            [Code::OptionalMisuse]
        );
        assert_eq!(codes("{ a: 'u9' }"), [Code::UnknownType]);
        assert_eq!(
            codes("{ a: { $type: 'array', $items: 'u8', $length: 2, $default: [1, 2, 3] } }"),
            [Code::InvalidDefault]
        );
        assert_eq!(
            codes("{ a: { $type: 'array', $items: 'u8', $default: [1, 256] } }"),
            [Code::InvalidDefault]
        );
        assert!(codes("{ a: { $type: 'f64', $default: 3 }, b: { $type: 'array', $items: 'f64', $length: 2, $default: [1, 2.5] } }").is_empty());
    }

    #[test]
    fn resolve_fills_defaults_and_names_missing_paths() {
        let (s, diags) = schema(
            "{ fps: { $type: 'u16', $default: 30 }, video: { width: { $type: 'u32', $default: 640 }, height: { $type: 'u32', $default: 480 } }, \
             device: { serial: 'string', port: { $type: 'u16', $default: 1 } } }",
        );
        assert!(diags.is_empty(), "{diags}");
        let s = s.unwrap();
        let out = s
            .resolve(&json!({ "device": { "serial": "abc" } }))
            .unwrap();
        assert_eq!(
            out,
            json!({ "fps": 30, "video": { "width": 640, "height": 480 }, "device": { "serial": "abc", "port": 1 } })
        );
        let errs = s
            .resolve(&json!({ "fps": 70000, "devise": {} }))
            .unwrap_err();
        let paths: Vec<(&str, Code)> = errs.iter().map(|e| (e.path.as_str(), e.code())).collect();
        assert_eq!(
            paths,
            [
                ("devise", Code::UnknownParameter),
                ("fps", Code::ParameterTypeMismatch),
                ("device.serial", Code::MissingParameter)
            ]
        );
        assert!(errs[0].help().unwrap().contains("did you mean `device`"));
    }

    #[test]
    fn arrays_and_bytes_values() {
        let (s, _) = schema(
            "{ l: { $type: 'array', $items: 'f64', $length: 3 }, b: 'bytes', o: { $type: 'array', $items: { x: 'u8' } } }",
        );
        let s = s.unwrap();
        let out = s
            .resolve(&json!({ "l": [1, 2, 3.5], "b": "hi", "o": [{ "x": 1 }] }))
            .unwrap();
        assert_eq!(out["b"], json!([104, 105]));
        let errs = s
            .resolve(&json!({ "l": [1, 2], "b": [300], "o": [{ "x": 999 }] }))
            .unwrap_err();
        let paths: Vec<&str> = errs.iter().map(|e| e.path.as_str()).collect();
        assert_eq!(paths, ["l", "b", "o[0].x"]);
    }
}
