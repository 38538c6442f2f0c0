//! # peppy-macros
//!
//! The `#[peppy::node("peppy.json5")]` attribute, re-exported by the
//! `peppy` crate: a thin front end over `peppy-build`'s generator.
//!
//! ```ignore
//! #[peppy::node("peppy.json5")] // relative to CARGO_MANIFEST_DIR
//! mod peppygen {}
//!
//! use peppygen::{NodeBuilder, Parameters, Result};
//! ```
//!
//! Schema errors become compile errors on the attribute's string, one per
//! error, as `peppy.json5:LINE:COL: message`; the module then holds stub
//! items so that code naming it does not add unresolved-name errors.

use proc_macro::TokenStream;

/// Generates a node's typed API into the module it annotates, from the
/// node document at the given path (relative to `CARGO_MANIFEST_DIR`).
/// The items are the same as `peppy_build::sync()` writes for
/// `peppy::include_generated!()`.
#[proc_macro_attribute]
pub fn node(attr: TokenStream, item: TokenStream) -> TokenStream {
    let attr = proc_macro2::TokenStream::from(attr);
    let item = proc_macro2::TokenStream::from(item);
    let dir = peppy_build::macro_support::manifest_dir();
    // The expansion never panics by design; a bug that does becomes a
    // located compile error instead of "proc-macro panicked".
    let expanded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        peppy_build::macro_support::expand(attr, item, dir.as_deref())
    }));
    match expanded {
        Ok(tokens) => tokens.into(),
        Err(panic) => {
            let why = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            let msg = format!("peppy-build failed unexpectedly (a bug, please report it): {why}");
            quote_error(&msg)
        }
    }
}

fn quote_error(msg: &str) -> TokenStream {
    format!("::core::compile_error!({msg:?});")
        .parse()
        .unwrap_or_default()
}
