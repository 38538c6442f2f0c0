//! Doc attributes as rustdoc writes them: one `#[doc = " line"]` per line
//! of text, which pretty-prints as `/// line`.

use proc_macro2::TokenStream;
use quote::{ToTokens, quote};

/// Documentation text, emitted as one doc attribute per line.
pub(crate) struct Doc(String);

impl Doc {
    pub(crate) fn new(text: impl Into<String>) -> Self {
        Doc(text.into())
    }
}

impl ToTokens for Doc {
    fn to_tokens(&self, tokens: &mut TokenStream) {
        for line in self.0.lines() {
            let line = if line.is_empty() {
                String::new()
            } else {
                format!(" {line}")
            };
            tokens.extend(quote!(#[doc = #line]));
        }
    }
}
