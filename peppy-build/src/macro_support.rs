//! The `#[peppy::node("peppy.json5")]` front end, as a library function so
//! that it is tested without rustc (the proc-macro crate only forwards).

use std::path::{Path, PathBuf};

use peppy_schema::{Diagnostic, RepoOptions, check_node};
use proc_macro2::{Span, TokenStream};
use quote::quote;

use crate::generate::{generate, stub};

/// Test-only override of the directory the attribute's path is relative to
/// (trybuild compiles cases away from their fixture files).
pub const MANIFEST_DIR_OVERRIDE: &str = "PEPPY_MACRO_MANIFEST_DIR";

/// The directory the attribute's path is relative to: the override, else
/// `CARGO_MANIFEST_DIR`.
pub fn manifest_dir() -> Option<PathBuf> {
    std::env::var_os(MANIFEST_DIR_OVERRIDE)
        .or_else(|| std::env::var_os("CARGO_MANIFEST_DIR"))
        .map(PathBuf::from)
}

/// Expands `#[peppy::node(attr)] item`: the module gets the generated items,
/// plus `include_bytes!` of every file read so rustc rebuilds when one
/// changes. Schema errors become `compile_error!`s on the attribute's
/// string (`peppy.json5:LINE:COL: message`), next to stub items. Never
/// panics.
pub fn expand(attr: TokenStream, item: TokenStream, manifest_dir: Option<&Path>) -> TokenStream {
    let lit: syn::LitStr = match syn::parse2(attr) {
        Ok(l) => l,
        Err(e) => {
            let msg = "expected the node document's path: `#[peppy::node(\"peppy.json5\")]`";
            let mut err = syn::Error::new(e.span(), msg).to_compile_error();
            err.extend(item);
            return err;
        }
    };
    let module: syn::ItemMod = match syn::parse2(item) {
        Ok(m) => m,
        Err(e) => {
            return syn::Error::new(
                e.span(),
                "`#[peppy::node]` goes on a module: `#[peppy::node(\"peppy.json5\")] mod peppygen {}`",
            )
            .to_compile_error();
        }
    };
    let Some((_, user_items)) = &module.content else {
        return syn::Error::new_spanned(
            &module,
            "`#[peppy::node]` needs an inline module: write `mod peppygen {}`",
        )
        .to_compile_error();
    };
    let Some(base) = manifest_dir else {
        return syn::Error::new(lit.span(), "`CARGO_MANIFEST_DIR` is not set").to_compile_error();
    };
    let path = absolute(&base.join(lit.value()));

    let (body, files) = match check_node(&path, &RepoOptions::default()) {
        Ok(check) => {
            let files = crate::config::files_read(&check);
            match generate(&check.resolved) {
                Ok(tokens) => (tokens, files),
                Err(diags) => (errors(diags.sorted(), base, lit.span()), files),
            }
        }
        Err(diags) => {
            let files = if path.is_file() { vec![path] } else { vec![] };
            (errors(diags.sorted(), base, lit.span()), files)
        }
    };
    let tracking = files.iter().filter_map(|f| {
        let f = f.to_str()?;
        Some(quote!(
            const _: &[u8] = ::core::include_bytes!(#f);
        ))
    });

    let (inner, outer): (Vec<&syn::Attribute>, Vec<&syn::Attribute>) = module
        .attrs
        .iter()
        .partition(|a| matches!(a.style, syn::AttrStyle::Inner(_)));
    let vis = &module.vis;
    let ident = &module.ident;
    let unsafety = &module.unsafety;
    quote! {
        #(#outer)*
        #vis #unsafety mod #ident {
            #(#inner)*
            #(#tracking)*
            #body
            #(#user_items)*
        }
    }
}

/// Each error as a `compile_error!` on `span`, then the stub items.
fn errors(diags: Vec<&Diagnostic>, base: &Path, span: Span) -> TokenStream {
    let mut out = TokenStream::new();
    for d in diags.into_iter().filter(|d| d.is_error()) {
        out.extend(syn::Error::new(span, message(d, base)).to_compile_error());
    }
    out.extend(stub());
    out
}

/// `peppy.json5:LINE:COL: message (Code)`, then the help on its own line.
pub fn message(d: &Diagnostic, base: &Path) -> String {
    let mut out = String::new();
    if let Some(path) = d.file_path() {
        let shown = path.strip_prefix(base).unwrap_or(path);
        out.push_str(&shown.display().to_string());
        if let Some(lc) = d.line_col() {
            out.push_str(&format!(":{}:{}", lc.line, lc.column));
        }
        out.push_str(": ");
    }
    out.push_str(&format!("{} ({})", d.message, d.code));
    if let Some(help) = &d.help {
        out.push_str(&format!("\nhelp: {help}"));
    }
    out
}

fn absolute(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}
