//! A place in a document that the model keeps for errors found later.

use std::sync::Arc;

use crate::diag::{Code, Diagnostic};
use crate::source::{SourceFile, Span};

/// A located place in a document, kept by the model for errors found later
/// (resolution, binding).
#[derive(Debug, Clone)]
pub struct Loc {
    /// The document.
    pub file: Arc<SourceFile>,
    /// The value's span.
    pub span: Span,
    /// The key path of the value.
    pub key_path: String,
}

impl Loc {
    /// An error at this place.
    pub fn error(&self, code: Code, message: impl Into<String>) -> Diagnostic {
        Diagnostic::error(code, message)
            .at(&self.file, self.span)
            .with_key_path(self.key_path.clone())
    }

    /// A warning at this place.
    pub fn warning(&self, code: Code, message: impl Into<String>) -> Diagnostic {
        Diagnostic::warning(code, message)
            .at(&self.file, self.span)
            .with_key_path(self.key_path.clone())
    }
}

impl Default for Loc {
    /// No place: what a model compiled into a binary carries (its
    /// documents stay with the build).
    fn default() -> Self {
        Loc {
            file: SourceFile::new("<compiled>", ""),
            span: Span::default(),
            key_path: String::new(),
        }
    }
}
