//! `peppygen::parameters`: typed structs for `execution.parameters` (groups
//! as nested structs) and the node descriptor the runtime starts from.

use peppy_schema::{Diagnostics, ParamField, ParamItem, ParamKind, Primitive, ResolvedNode};
use proc_macro2::{Literal, TokenStream};
use quote::quote;

use crate::naming::short_location;
use crate::naming::{NameKind, Names, field_ident, ident, is_snake_case, nested_type};
use crate::types::primitive_type;

/// The `SPEC` statics the descriptor lists, as paths from `parameters`.
pub(crate) struct Descriptor {
    pub(crate) document_path: String,
    /// The node's run-time model as JSON (`NodeModel::to_json`).
    pub(crate) model: String,
    pub(crate) emitted_topics: Vec<TokenStream>,
    pub(crate) consumed_topics: Vec<TokenStream>,
    pub(crate) exposed_services: Vec<TokenStream>,
    pub(crate) exposed_actions: Vec<TokenStream>,
}

/// The items of the `parameters` module.
pub(crate) fn parameters(
    node: &ResolvedNode,
    descriptor: &Descriptor,
    diags: &mut Diagnostics,
) -> TokenStream {
    let mut names = Names::with_fixed(&["Parameters"]);
    let mut out = TokenStream::new();
    let identity = node.node.identity();
    let doc = format!(
        "The parameters of node `{identity}`: `execution.parameters` of `{}`, with defaults filled in by the runtime. Deserialize it from JSON to supply values in standalone runs.",
        short_location(&node.node.name_loc)
    );
    let fields = &node.node.execution.parameters.fields;
    let mut generator = ParamGen {
        names: &mut names,
        diags,
        out: &mut out,
    };
    generator.group("Parameters", "", fields, &doc);
    out.extend(group_modules(fields));

    let path = &descriptor.document_path;
    let model = &descriptor.model;
    let emitted = &descriptor.emitted_topics;
    let consumed = &descriptor.consumed_topics;
    let services = &descriptor.exposed_services;
    let actions = &descriptor.exposed_actions;
    out.extend(quote! {
        impl ::peppy::codegen::NodeParameters for Parameters {
            fn descriptor() -> &'static ::peppy::codegen::NodeDescriptor {
                static DESCRIPTOR: ::peppy::codegen::NodeDescriptor = ::peppy::codegen::NodeDescriptor {
                    model: #model,
                    document_path: #path,
                    emitted_topics: &[#(#emitted),*],
                    consumed_topics: &[#(#consumed),*],
                    exposed_services: &[#(#services),*],
                    exposed_actions: &[#(#actions),*],
                };
                &DESCRIPTOR
            }
        }
    });
    out
}

/// One module per top-level group holding that group's types, as PeppyOS
/// names them: group `camera` is `parameters::camera::Camera`, its group
/// `intrinsics` is `parameters::camera::CameraIntrinsics`. The types stay
/// at the top of `parameters` too, where this generator has always put
/// them.
fn group_modules(fields: &[ParamField]) -> TokenStream {
    // A module shares the type namespace: a group spelled like a type
    // (`Camera`) keeps its types at the top only.
    let mut taken = vec!["Parameters".to_string()];
    group_types("", fields, &mut taken);
    let mut out = TokenStream::new();
    for f in fields {
        let ParamKind::Group(inner) = &f.kind else {
            continue;
        };
        let module = ident(&f.name);
        if taken.contains(&module.to_string()) {
            continue;
        }
        let root = nested_type("", &f.name);
        let mut types = vec![root.clone()];
        group_types(&root, inner, &mut types);
        let types = types.iter().map(|t| ident(t));
        let doc = crate::docs::Doc::new(format!(
            "The types of parameter group `{}` (declared at `{}`).",
            f.name,
            short_location(&f.loc)
        ));
        out.extend(quote! {
            #doc
            #[allow(non_snake_case)]
            pub mod #module {
                pub use super::{#(#types),*};
            }
        });
    }
    out
}

/// The names `ParamGen::field_type` gives the types nested in a group whose
/// own type is `prefix`.
fn group_types(prefix: &str, fields: &[ParamField], out: &mut Vec<String>) {
    for f in fields {
        match &f.kind {
            ParamKind::Group(inner) => {
                let name = nested_type(prefix, &f.name);
                out.push(name.clone());
                group_types(&name, inner, out);
            }
            ParamKind::Array {
                items: ParamItem::Object(inner),
                ..
            } => {
                let name = format!("{}Item", nested_type(prefix, &f.name));
                out.push(name.clone());
                group_types(&name, inner, out);
            }
            _ => {}
        }
    }
}

struct ParamGen<'a> {
    names: &'a mut Names,
    diags: &'a mut Diagnostics,
    out: &'a mut TokenStream,
}

/// How a parameter's declared type reads in documentation.
fn describe(kind: &ParamKind) -> String {
    fn default<T: std::fmt::Display>(d: &Option<T>) -> String {
        match d {
            Some(d) => format!(", default `{d}`"),
            None => String::new(),
        }
    }
    match kind {
        ParamKind::Leaf { ty, default: d } => format!("`{}`{}", ty.name(), default(d)),
        ParamKind::Array {
            items,
            length,
            default: d,
        } => {
            let item = match items {
                ParamItem::Primitive(p) => format!("`{}`", p.name()),
                ParamItem::Object(_) => "objects".to_string(),
            };
            let n = length.map(|n| format!("{n} ")).unwrap_or_default();
            format!("array of {n}{item}{}", default(d))
        }
        ParamKind::Group(_) => "group".to_string(),
    }
}

impl ParamGen<'_> {
    /// The struct `name` for a group's `fields`; nested groups and array
    /// items are named from `prefix` (empty for the root).
    fn group(&mut self, name: &str, prefix: &str, fields: &[ParamField], doc: &str) {
        let doc = crate::docs::Doc::new(doc);
        let mut decls = Vec::new();
        for f in fields {
            let (ty, with) = self.field_type(prefix, f);
            let id = field_ident(&f.name);
            let fdoc = crate::docs::Doc::new(format!(
                "`{}`: {} (declared at `{}`).",
                f.name,
                describe(&f.kind),
                short_location(&f.loc)
            ));
            let with = with.map(|w| {
                let path = format!("::peppy::codegen::params::{w}");
                quote!(#[serde(with = #path)])
            });
            decls.push(quote! {
                #fdoc
                #with
                pub #id: #ty,
            });
        }
        let allow = if fields.iter().all(|f| is_snake_case(&f.name)) {
            quote!()
        } else {
            quote!(#[allow(non_snake_case)])
        };
        let id = ident(name);
        self.out.extend(quote! {
            #doc
            #[derive(
                ::core::fmt::Debug,
                ::core::clone::Clone,
                ::core::cmp::PartialEq,
                ::peppy::codegen::serde::Deserialize,
                ::peppy::codegen::serde::Serialize,
            )]
            #[serde(crate = "::peppy::codegen::serde")]
            #allow
            pub struct #id {
                #(#decls)*
            }
        });
    }

    /// The Rust type of a parameter and the `params` serde helper it needs.
    fn field_type(&mut self, prefix: &str, f: &ParamField) -> (TokenStream, Option<&'static str>) {
        match &f.kind {
            ParamKind::Leaf { ty, .. } => {
                let with = (*ty == Primitive::Time).then_some("time");
                (primitive_type(*ty), with)
            }
            ParamKind::Group(fields) => {
                let name = nested_type(prefix, &f.name);
                let what = format!("parameter group `{}`", f.name);
                if self
                    .names
                    .claim(NameKind::Type, &name, &what, &f.loc, self.diags)
                {
                    let doc = format!(
                        "Parameter group `{}` (declared at `{}`).",
                        f.name,
                        short_location(&f.loc)
                    );
                    self.group(&name, &name, fields, &doc);
                }
                let id = ident(&name);
                (quote!(#id), None)
            }
            ParamKind::Array { items, length, .. } => {
                let (item, time) = match items {
                    ParamItem::Primitive(p) => (primitive_type(*p), *p == Primitive::Time),
                    ParamItem::Object(fields) => {
                        let name = format!("{}Item", nested_type(prefix, &f.name));
                        let what = format!("the items of array parameter `{}`", f.name);
                        if self
                            .names
                            .claim(NameKind::Type, &name, &what, &f.loc, self.diags)
                        {
                            let doc = format!(
                                "An item of array parameter `{}` (declared at `{}`).",
                                f.name,
                                short_location(&f.loc)
                            );
                            self.group(&name, &name, fields, &doc);
                        }
                        let id = ident(&name);
                        (quote!(#id), false)
                    }
                };
                match (length, time) {
                    (Some(n), _) => {
                        let n = Literal::usize_unsuffixed(*n as usize);
                        let with = if time { "time_array" } else { "array" };
                        (quote!([#item; #n]), Some(with))
                    }
                    (None, true) => (quote!(::std::vec::Vec<#item>), Some("time_vec")),
                    (None, false) => (quote!(::std::vec::Vec<#item>), None),
                }
            }
        }
    }
}
