//! Message formats as Python dataclasses, each registered with the runtime
//! codec (`peppy.codec.describe`) so it encodes exactly as docs/WIRE.md §5.

use peppy_schema::names::nested_type;
use peppy_schema::{Field, FieldType, MessageFormat, Primitive};

use super::source::{Source, py_ident, py_string};

/// Writes the dataclass `name` for `format` (no fields when `None`), with
/// nested object types named from `prefix` as the Rust API names them,
/// and returns `FORMAT` text: `_c.Format(<name>, <canonical>, <fingerprint>)`.
pub(super) fn message(
    out: &mut Source,
    name: &str,
    prefix: &str,
    format: Option<&MessageFormat>,
    doc: &str,
) -> String {
    let fields = format.map(|f| f.fields.as_slice()).unwrap_or(&[]);
    object(out, name, prefix, fields, doc);
    match format {
        Some(f) => format!(
            "_c.Format({name}, {}, 0x{:016x})",
            py_string(&f.canonical()),
            f.fingerprint()
        ),
        None => format!("_c.Format({name}, \"(no payload)\", 0)"),
    }
}

fn object(out: &mut Source, name: &str, prefix: &str, fields: &[Field], doc: &str) {
    // Nested types first: a dataclass's annotations name them.
    let mut layout = Vec::new();
    let mut annotations = Vec::new();
    for f in fields {
        let (descriptor, hint) = field_type(out, prefix, f);
        layout.push(format!("({}, {descriptor})", py_string(&py_ident(&f.name))));
        annotations.push(format!("{}: {hint}", py_ident(&f.name)));
    }
    out.line("@dataclass");
    out.line(&format!("class {name}:"));
    out.indent();
    out.docstring(doc);
    for (a, f) in annotations.iter().zip(fields) {
        out.line(&format!("{a}  # {}", describe(&f.ty, f.optional)));
    }
    out.dedent();
    out.blank();
    out.line(&format!("_c.describe({name}, [{}])", layout.join(", ")));
    out.blank();
    out.blank();
}

/// The codec descriptor and the type hint of field `f`.
fn field_type(out: &mut Source, prefix: &str, f: &Field) -> (String, String) {
    let (d, h) = type_of(out, prefix, &f.name, &f.ty);
    if f.optional {
        (format!("_c.Optional({d})"), format!("Optional[{h}]"))
    } else {
        (d, h)
    }
}

fn type_of(out: &mut Source, prefix: &str, field: &str, ty: &FieldType) -> (String, String) {
    match ty {
        FieldType::Primitive(p) => primitive(*p),
        FieldType::Object(fields) => {
            let name = nested_type(prefix, field);
            let doc = format!("The object of field `{field}`.");
            object(out, &name, &name, fields, &doc);
            (format!("_c.Obj({name})"), name)
        }
        FieldType::Array {
            items,
            length,
            pinned,
        } => {
            let (d, h) = match items.as_ref() {
                FieldType::Object(fields) => {
                    let name = format!("{}Item", nested_type(prefix, field));
                    let doc = format!("An item of array field `{field}`.");
                    object(out, &name, &name, fields, &doc);
                    (format!("_c.Obj({name})"), name)
                }
                other => type_of(out, prefix, field, other),
            };
            let descriptor = match (length, pinned) {
                (Some(n), _) => format!("_c.Array({d}, {n})"),
                // Pinned by `refine`: counted on the wire, checked here.
                (None, Some(n)) => format!("_c.Array({d}, pinned={n})"),
                (None, None) => format!("_c.Array({d})"),
            };
            // Bytes, not a list of ints: camera frames are arrays of u8.
            let hint = if matches!(items.as_ref(), FieldType::Primitive(Primitive::U8)) {
                "bytes".to_string()
            } else {
                format!("List[{h}]")
            };
            (descriptor, hint)
        }
    }
}

fn primitive(p: Primitive) -> (String, String) {
    let (d, h) = match p {
        Primitive::Bool => ("BOOL", "bool"),
        Primitive::U8 => ("U8", "int"),
        Primitive::U16 => ("U16", "int"),
        Primitive::U32 => ("U32", "int"),
        Primitive::U64 => ("U64", "int"),
        Primitive::I8 => ("I8", "int"),
        Primitive::I16 => ("I16", "int"),
        Primitive::I32 => ("I32", "int"),
        Primitive::I64 => ("I64", "int"),
        Primitive::F32 => ("F32", "float"),
        Primitive::F64 => ("F64", "float"),
        Primitive::String => ("STRING", "str"),
        Primitive::Bytes => ("BYTES", "bytes"),
        Primitive::Time => ("TIME", "float"),
    };
    (format!("_c.{d}"), h.to_string())
}

/// The declared type, as a comment beside the field.
fn describe(ty: &FieldType, optional: bool) -> String {
    let base = crate::types::describe(ty);
    if optional {
        format!("{base}, optional")
    } else {
        base
    }
}

/// The annotated parameters (`name: Hint`) of a function taking
/// `fields`, nested types named from `prefix`, and the argument names in
/// order.
pub(super) fn fields_args(prefix: &str, fields: &[Field]) -> (Vec<String>, Vec<String>) {
    // Names the functions' bodies use (their own parameters, the module's
    // `SPEC` and types); a field so named gets a trailing `_`.
    const RESERVED: &[&str] = &["node_runner", "self", "SPEC", "Message", "inspect"];
    let taken: Vec<String> = fields.iter().map(|f| py_ident(&f.name)).collect();
    fields
        .iter()
        .map(|f| {
            let id = py_ident(&f.name);
            let mut arg = id.clone();
            while RESERVED.contains(&arg.as_str())
                || arg == prefix
                || (arg != id && taken.contains(&arg))
            {
                arg.push('_');
            }
            let mut h = hint(prefix, &f.name, &f.ty);
            if f.optional {
                h = format!("Optional[{h}]");
            }
            (format!("{arg}: {h}"), arg)
        })
        .unzip()
}

/// The type hint of a field, as [`type_of`] names it (without writing
/// the nested types again).
fn hint(prefix: &str, field: &str, ty: &FieldType) -> String {
    match ty {
        FieldType::Primitive(p) => primitive(*p).1,
        FieldType::Object(_) => nested_type(prefix, field),
        FieldType::Array { items, .. } => match items.as_ref() {
            FieldType::Primitive(Primitive::U8) => "bytes".into(),
            FieldType::Object(_) => format!("List[{}Item]", nested_type(prefix, field)),
            other => format!("List[{}]", hint(prefix, field, other)),
        },
    }
}

/// The fields of a format (none without one).
pub(super) fn fields_of(format: Option<&MessageFormat>) -> &[Field] {
    format.map(|f| f.fields.as_slice()).unwrap_or(&[])
}
