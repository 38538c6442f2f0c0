//! Message structs: one struct per message format plus one per nested
//! object, each with `Encode` / `Decode` impls that write and read the
//! fields in declaration order (docs/WIRE.md).

use peppy_schema::{Diagnostics, Field, FieldType, Loc, MessageFormat, Primitive};
use proc_macro2::{Literal, TokenStream};
use quote::quote;

use crate::naming::short_location;
use crate::naming::{NameKind, Names, field_ident, ident, is_snake_case, nested_type};

/// The Rust type of a primitive, by absolute path.
pub(crate) fn primitive_type(p: Primitive) -> TokenStream {
    match p {
        Primitive::Bool => quote!(bool),
        Primitive::U8 => quote!(u8),
        Primitive::U16 => quote!(u16),
        Primitive::U32 => quote!(u32),
        Primitive::U64 => quote!(u64),
        Primitive::I8 => quote!(i8),
        Primitive::I16 => quote!(i16),
        Primitive::I32 => quote!(i32),
        Primitive::I64 => quote!(i64),
        Primitive::F32 => quote!(f32),
        Primitive::F64 => quote!(f64),
        Primitive::String => quote!(::std::string::String),
        Primitive::Bytes => quote!(::std::vec::Vec<u8>),
        Primitive::Time => quote!(::std::time::SystemTime),
    }
}

/// How a field's declared type reads in documentation.
pub(crate) fn describe(ty: &FieldType) -> String {
    match ty {
        FieldType::Primitive(p) => format!("`{}`", p.name()),
        FieldType::Array {
            items,
            length,
            pinned,
        } => {
            let item = match items.as_ref() {
                FieldType::Object(_) => "objects".to_string(),
                other => describe(other),
            };
            match (length, pinned) {
                (Some(n), _) => format!("array of {n} {item}"),
                (None, Some(n)) => format!(
                    "array of {n} {item} (pinned by this node's `refine`; the document leaves the length open)"
                ),
                (None, None) => format!("array of {item}"),
            }
        }
        FieldType::Object(_) => "object".to_string(),
    }
}

/// The documentation line of one field.
fn field_doc(f: &Field) -> String {
    let optional = if f.optional { ", optional" } else { "" };
    format!(
        "`{}`: {}{optional} (declared at `{}`).",
        f.name,
        describe(&f.ty),
        short_location(&f.loc)
    )
}

/// Generates message structs into `out` and reports type-name collisions.
pub(crate) struct Structs<'a> {
    /// Type names of the module being generated.
    pub(crate) names: &'a mut Names,
    /// Where collisions are reported.
    pub(crate) diags: &'a mut Diagnostics,
    /// Generated items.
    pub(crate) out: TokenStream,
}

/// `#[allow(non_snake_case)]` when some field name needs it.
pub(crate) fn snake_allow(fields: &[Field]) -> TokenStream {
    if fields.iter().all(|f| is_snake_case(&f.name)) {
        TokenStream::new()
    } else {
        quote!(#[allow(non_snake_case)])
    }
}

/// `#[allow(clippy::too_many_arguments)]` for functions taking more than
/// clippy's limit of seven arguments.
pub(crate) fn many_args_allow(count: usize) -> TokenStream {
    if count > 7 {
        quote!(#[allow(clippy::too_many_arguments)])
    } else {
        TokenStream::new()
    }
}

impl Structs<'_> {
    /// The struct `name` holding `format`'s fields (a unit struct when the
    /// format is absent), nested types named from `prefix`. `name` itself
    /// must already be claimed.
    pub(crate) fn message(
        &mut self,
        name: &str,
        prefix: &str,
        format: Option<&MessageFormat>,
        doc: &str,
    ) {
        match format {
            Some(f) => self.object(name, prefix, &f.fields, doc),
            None => self.unit(name, doc),
        }
    }

    fn unit(&mut self, name: &str, doc: &str) {
        let name = ident(name);
        let doc = crate::docs::Doc::new(format!("{doc}\n\nThis message has no payload."));
        self.out.extend(quote! {
            #doc
            #[derive(::core::fmt::Debug, ::core::clone::Clone, ::core::marker::Copy, ::core::cmp::PartialEq, ::core::cmp::Eq, ::core::default::Default)]
            pub struct #name;

            ::peppy::codegen::codec!(#name {});
        });
    }

    /// A struct with `fields`, and its codec impls from the runtime's
    /// `codec!` macro (one copy of the impls' code, not one per struct).
    fn object(&mut self, name: &str, prefix: &str, fields: &[Field], doc: &str) {
        let doc = crate::docs::Doc::new(doc);
        let mut decls = Vec::new();
        let mut ids = Vec::new();
        for f in fields {
            let ty = self.field_type(prefix, f);
            let id = field_ident(&f.name);
            let fdoc = crate::docs::Doc::new(field_doc(f));
            decls.push(quote! {
                #fdoc
                pub #id: #ty,
            });
            // A pinned array keeps the open array's wire encoding.
            ids.push(if is_pinned(&f.ty) {
                quote!(#id as counted)
            } else {
                quote!(#id)
            });
        }
        let allow = snake_allow(fields);
        let name = ident(name);
        self.out.extend(quote! {
            #doc
            #[derive(::core::fmt::Debug, ::core::clone::Clone, ::core::cmp::PartialEq)]
            #allow
            pub struct #name {
                #(#decls)*
            }

            ::peppy::codegen::codec!(#name { #(#ids),* });
        });
    }

    /// The Rust type of field `f` of a struct whose nested types are named
    /// from `prefix`; nested structs are generated on the way.
    pub(crate) fn field_type(&mut self, prefix: &str, f: &Field) -> TokenStream {
        let inner = self.type_of(prefix, &f.name, &f.ty, &f.loc);
        if f.optional {
            quote!(::core::option::Option<#inner>)
        } else {
            inner
        }
    }

    fn type_of(&mut self, prefix: &str, field: &str, ty: &FieldType, loc: &Loc) -> TokenStream {
        match ty {
            FieldType::Primitive(p) => primitive_type(*p),
            FieldType::Object(fields) => {
                let name = nested_type(prefix, field);
                self.nested(&name, fields, field, loc, "the object field")
            }
            FieldType::Array {
                items,
                length,
                pinned,
            } => {
                let item = match items.as_ref() {
                    FieldType::Object(fields) => {
                        let name = format!("{}Item", nested_type(prefix, field));
                        self.nested(&name, fields, field, loc, "the items of array field")
                    }
                    other => self.type_of(prefix, field, other, loc),
                };
                match length.or(*pinned) {
                    Some(n) => {
                        let n = Literal::usize_unsuffixed(n as usize);
                        quote!([#item; #n])
                    }
                    None => quote!(::std::vec::Vec<#item>),
                }
            }
        }
    }

    fn nested(
        &mut self,
        name: &str,
        fields: &[Field],
        field: &str,
        loc: &Loc,
        role: &str,
    ) -> TokenStream {
        let what = format!("{role} `{field}`");
        if self
            .names
            .claim(NameKind::Type, name, &what, loc, self.diags)
        {
            let doc = format!(
                "The object of field `{field}` (declared at `{}`).",
                short_location(loc)
            );
            self.object(name, name, fields, &doc);
        }
        let id = ident(name);
        quote!(#id)
    }
}

/// Whether a field is an open array this node pins with `refine`: its
/// Rust type is fixed-size, its wire encoding the open array's.
pub(crate) fn is_pinned(ty: &FieldType) -> bool {
    matches!(
        ty,
        FieldType::Array {
            length: None,
            pinned: Some(_),
            ..
        }
    )
}

/// `FormatSpec` of a format: its fingerprint and canonical text, or
/// `FormatSpec::EMPTY` for no payload.
pub(crate) fn format_spec(format: Option<&MessageFormat>) -> TokenStream {
    match format {
        None => quote!(::peppy::codegen::FormatSpec::EMPTY),
        Some(f) => {
            let fingerprint = Literal::u64_unsuffixed(f.fingerprint());
            let canonical = f.canonical();
            quote! {
                ::peppy::codegen::FormatSpec {
                    fingerprint: #fingerprint,
                    canonical: #canonical,
                }
            }
        }
    }
}

/// Constructor arguments and the struct literal fields for `fields`.
pub(crate) struct Args {
    /// `name: Type` pairs.
    pub(crate) params: Vec<TokenStream>,
    /// `field: name` initialisers.
    pub(crate) inits: Vec<TokenStream>,
}

/// Arguments named after the fields, renamed when a name is `reserved`
/// (another argument or an item the function body uses).
pub(crate) fn args(prefix: &str, fields: &[Field], reserved: &[&str]) -> Args {
    let mut params = Vec::new();
    let mut inits = Vec::new();
    let taken: Vec<&str> = fields.iter().map(|f| f.name.as_str()).collect();
    for f in fields {
        // The type tokens only: nested structs are generated by the struct itself.
        let ty = quiet_type(prefix, f);
        let id = field_ident(&f.name);
        let mut arg = f.name.clone();
        while reserved.contains(&arg.as_str()) || (arg != f.name && taken.contains(&arg.as_str())) {
            arg.push('_');
        }
        let arg_id = field_ident(&arg);
        params.push(quote!(#arg_id: #ty));
        if arg == f.name {
            inits.push(quote!(#id));
        } else {
            inits.push(quote!(#id: #arg_id));
        }
    }
    Args { params, inits }
}

/// The type of a field, naming nested structs without generating them
/// (the struct holding the field generates them).
fn quiet_type(prefix: &str, f: &Field) -> TokenStream {
    fn type_of(prefix: &str, field: &str, ty: &FieldType) -> TokenStream {
        match ty {
            FieldType::Primitive(p) => primitive_type(*p),
            FieldType::Object(_) => {
                let id = ident(&nested_type(prefix, field));
                quote!(#id)
            }
            FieldType::Array {
                items,
                length,
                pinned,
            } => {
                let item = match items.as_ref() {
                    FieldType::Object(_) => {
                        let id = ident(&format!("{}Item", nested_type(prefix, field)));
                        quote!(#id)
                    }
                    other => type_of(prefix, field, other),
                };
                match length.or(*pinned) {
                    Some(n) => {
                        let n = Literal::usize_unsuffixed(n as usize);
                        quote!([#item; #n])
                    }
                    None => quote!(::std::vec::Vec<#item>),
                }
            }
        }
    }
    let inner = type_of(prefix, &f.name, &f.ty);
    if f.optional {
        quote!(::core::option::Option<#inner>)
    } else {
        inner
    }
}
