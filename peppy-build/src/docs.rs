//! Doc attributes as rustdoc writes them: the generator writes plain text
//! (`#[doc = "Line one.\n\nLine two."]`); this pass turns each into one
//! `#[doc = " line"]` per line, which pretty-prints as `/// line`.

use proc_macro2::{Delimiter, Group, Literal, Punct, Spacing, TokenStream, TokenTree};

/// Rewrites every `#[doc = "..."]` in `tokens`, at any depth.
pub(crate) fn format_docs(tokens: TokenStream) -> TokenStream {
    let mut out = Vec::new();
    let mut iter = tokens.into_iter().peekable();
    while let Some(tt) = iter.next() {
        match tt {
            TokenTree::Punct(p) if p.as_char() == '#' => {
                if let Some(TokenTree::Group(g)) = iter.peek()
                    && g.delimiter() == Delimiter::Bracket
                    && let Some(text) = doc_text(g.stream())
                {
                    iter.next();
                    for line in text.lines() {
                        let line = if line.is_empty() {
                            String::new()
                        } else {
                            format!(" {line}")
                        };
                        out.push(TokenTree::Punct(Punct::new('#', Spacing::Alone)));
                        out.push(TokenTree::Group(Group::new(
                            Delimiter::Bracket,
                            quote::quote!(doc = #line),
                        )));
                    }
                    continue;
                }
                out.push(TokenTree::Punct(p));
            }
            TokenTree::Group(g) => {
                let mut ng = Group::new(g.delimiter(), format_docs(g.stream()));
                ng.set_span(g.span());
                out.push(TokenTree::Group(ng));
            }
            other => out.push(other),
        }
    }
    out.into_iter().collect()
}

/// The text of `doc = "..."`, if that is what `attr` holds.
fn doc_text(attr: TokenStream) -> Option<String> {
    let tts: Vec<TokenTree> = attr.into_iter().collect();
    let [
        TokenTree::Ident(name),
        TokenTree::Punct(eq),
        TokenTree::Literal(lit),
    ] = tts.as_slice()
    else {
        return None;
    };
    if name != "doc" || eq.as_char() != '=' {
        return None;
    }
    string_value(lit)
}

fn string_value(lit: &Literal) -> Option<String> {
    let lit: syn::LitStr = syn::parse2(TokenTree::Literal(lit.clone()).into()).ok()?;
    Some(lit.value())
}
