//! Reading a parameter schema from a document: `$type`, `$default`,
//! `$items`, `$length`, groups; every `$default` checked by the same
//! functions that check values later.

use crate::diag::Code;
use crate::format::{ArrayItem, parse_array_shape, primitive_name};
use crate::json::{Node, Value};
use crate::names::check_field_name;
use crate::primitive::Primitive;
use crate::read::{Reader, join};

use super::{
    ParamError, ParamErrorKind, ParamField, ParamItem, ParamKind, ParameterSchema, check_leaf,
    resolve_field,
};

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

/// What else a parameter's type may be, for `UnknownType` help.
const PARAMETER_TYPES: &str = "a group (an object) or an array";

fn parse_primitive_name(r: &mut Reader<'_>, node: &Node, path: &str, s: &str) -> Option<Primitive> {
    primitive_name(r, node, path, s, PARAMETER_TYPES)
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
        None | Some("object") => parse_group(r, node, members, path, in_item, &mut ok)?,
        Some("array") => parse_array(r, node, members, path, &mut ok)?,
        Some(s) => parse_leaf(r, node, members, path, s, in_item, &mut ok)?,
    };
    ok.then_some(kind)
}

/// A group of parameters (an object without `$type`, or `$type: "object"`).
fn parse_group(
    r: &mut Reader<'_>,
    node: &Node,
    members: &[crate::json::Member],
    path: &str,
    in_item: bool,
    ok: &mut bool,
) -> Option<ParamKind> {
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
            *ok = false;
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
    Some(ParamKind::Group(parse_fields(r, &children, path, in_item)?))
}

/// An array parameter: `$items`, `$length`, `$default` (primitive items).
fn parse_array(
    r: &mut Reader<'_>,
    node: &Node,
    members: &[crate::json::Member],
    path: &str,
    ok: &mut bool,
) -> Option<ParamKind> {
    if let Some(m) = members.iter().find(|m| !m.key.starts_with('$')) {
        r.unknown_key(m, path, &["$type", "$items", "$length", "$default"]);
        *ok = false;
    }
    let (items, length) = parse_array_shape(r, node, path, ok, |r, items_node, ipath| {
        match &items_node.value {
            Value::String(s) => Some(ParamItem::Primitive(parse_primitive_name(
                r, items_node, ipath, s,
            )?)),
            Value::Object(_) => match parse_param(r, items_node, ipath, true)? {
                ParamKind::Leaf { ty, default: None } => Some(ParamItem::Primitive(ty)),
                ParamKind::Group(fields) => Some(ParamItem::Object(fields)),
                // Arrays of arrays are refused before the items are read; an
                // item's `$default` is refused where it is read.
                ParamKind::Array { .. }
                | ParamKind::Leaf {
                    default: Some(_), ..
                } => None,
            },
            other => {
                r.error(
                    Code::WrongType,
                    items_node.span,
                    ipath,
                    format!(
                        "expected a type name or an object for `{ipath}`, found {}",
                        other.kind()
                    ),
                );
                None
            }
        }
    })?;
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
                    *ok = false;
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
                        *ok = false;
                    }
                    v
                }
            }
        }
    };
    Some(ParamKind::Array {
        items,
        length,
        default,
    })
}

/// A primitive parameter with its `$default`, checked like a value.
fn parse_leaf(
    r: &mut Reader<'_>,
    node: &Node,
    members: &[crate::json::Member],
    path: &str,
    type_name: &str,
    in_item: bool,
    ok: &mut bool,
) -> Option<ParamKind> {
    let type_node = node.get("$type").expect("present");
    let ty = parse_primitive_name(r, type_node, &join(path, "$type"), type_name)?;
    for m in members.iter().filter(|m| !m.key.starts_with('$')) {
        r.unknown_key(m, path, &["$type", "$default"]);
        *ok = false;
    }
    for key in ["$items", "$length"] {
        if let Some(m) = members.iter().find(|m| m.key == key) {
            r.error(
                Code::UnknownKey,
                m.key_span,
                &join(path, key),
                format!("`{key}` is only allowed on array parameters"),
            );
            *ok = false;
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
                *ok = false;
                None
            } else if matches!(ty, Primitive::Bytes | Primitive::Time) {
                r.error_help(
                    Code::InvalidDefault,
                    d.span,
                    &dpath,
                    format!("`$default` is not supported for `{}` parameters", ty.name()),
                    "pass the value at launch instead",
                );
                *ok = false;
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
                        *ok = false;
                        None
                    }
                }
            }
        }
    };
    Some(ParamKind::Leaf { ty, default })
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

impl ArrayItem for ParamItem {
    fn is_scalar(&self) -> bool {
        matches!(self, ParamItem::Primitive(p) if p.is_scalar())
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
