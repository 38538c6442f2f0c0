//! Source files and positions inside them.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[cfg(feature = "documents")]
use sha2::{Digest, Sha256};

#[cfg(feature = "documents")]
use crate::diag::{Code, Diagnostic};

/// Documents larger than this are refused before parsing.
///
/// Real peppy documents are a few kilobytes; the limit only exists so that a
/// stray multi-gigabyte file is a clean error rather than an allocation storm.
pub const MAX_DOCUMENT_BYTES: usize = 4 * 1024 * 1024;

/// A byte range into a [`SourceFile`]'s text.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Span {
    /// First byte.
    pub start: usize,
    /// One past the last byte.
    pub end: usize,
}

impl Span {
    /// A span from `start` to `end` (bytes).
    pub fn new(start: usize, end: usize) -> Self {
        Span { start, end }
    }
}

/// One document's text, with the path used to name it in diagnostics.
#[derive(Clone, PartialEq, Eq)]
pub struct SourceFile {
    path: PathBuf,
    text: String,
    line_starts: Vec<usize>,
}

impl fmt::Debug for SourceFile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SourceFile")
            .field("path", &self.path)
            .field("bytes", &self.text.len())
            .finish()
    }
}

/// A 1-based line and column (columns count characters, not bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct LineCol {
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
}

impl SourceFile {
    /// Wraps text that is already in memory. `path` is how diagnostics name it.
    pub fn new(path: impl Into<PathBuf>, text: impl Into<String>) -> Arc<Self> {
        let text = text.into();
        let line_starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Arc::new(SourceFile {
            path: path.into(),
            text,
            line_starts,
        })
    }

    /// Reads a document from disk, refusing files over [`MAX_DOCUMENT_BYTES`]
    /// and files that are not UTF-8.
    ///
    /// Returns the file and the sha256 of its exact bytes (lowercase hex),
    /// which is an interface document's revision.
    #[cfg(feature = "documents")]
    pub fn read(path: &Path) -> Result<(Arc<Self>, String), Box<Diagnostic>> {
        let fail = |message: String| {
            Box::new(Diagnostic::error(Code::CannotRead, message).with_file_path(path))
        };
        use std::io::Read as _;
        let too_large = |size: String| {
            Box::new(
                Diagnostic::error(
                    Code::DocumentTooLarge,
                    format!(
                        "document is {size} bytes; peppy documents may be at most {MAX_DOCUMENT_BYTES} bytes"
                    ),
                )
                .with_file_path(path),
            )
        };
        let file = std::fs::File::open(path)
            .map_err(|e| fail(format!("cannot read `{}`: {e}", path.display())))?;
        let meta = file
            .metadata()
            .map_err(|e| fail(format!("cannot read `{}`: {e}", path.display())))?;
        if meta.len() > MAX_DOCUMENT_BYTES as u64 {
            return Err(too_large(meta.len().to_string()));
        }
        // The size a file's metadata gives is not a bound: a device such as
        // /dev/zero, a pipe or a file still being written says less than it
        // holds. Reading stops one byte past the limit.
        let mut bytes = Vec::new();
        file.take(MAX_DOCUMENT_BYTES as u64 + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| fail(format!("cannot read `{}`: {e}", path.display())))?;
        if bytes.len() > MAX_DOCUMENT_BYTES {
            return Err(too_large(format!("more than {MAX_DOCUMENT_BYTES}")));
        }
        let sha = sha256_hex(&bytes);
        let text = String::from_utf8(bytes).map_err(|e| {
            Box::new(
                Diagnostic::error(
                    Code::Syntax,
                    format!(
                        "document is not valid UTF-8 (invalid byte at offset {})",
                        e.utf8_error().valid_up_to()
                    ),
                )
                .with_file_path(path),
            )
        })?;
        Ok((SourceFile::new(path, text), sha))
    }

    /// The path diagnostics print.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The whole text.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// Line and column of a byte offset (clamped to the text).
    pub fn line_col(&self, offset: usize) -> LineCol {
        let offset = offset.min(self.text.len());
        let line_index = match self.line_starts.binary_search(&offset) {
            Ok(i) => i,
            Err(i) => i - 1,
        };
        let line_start = self.line_starts[line_index];
        let mut column_bytes = offset - line_start;
        while !self.text.is_char_boundary(line_start + column_bytes) {
            column_bytes -= 1;
        }
        let column = self.text[line_start..line_start + column_bytes]
            .chars()
            .count()
            + 1;
        LineCol {
            line: line_index + 1,
            column,
        }
    }
}

/// sha256 of `bytes` as 64 lowercase hex characters.
#[cfg(feature = "documents")]
pub fn sha256_hex(bytes: &[u8]) -> String {
    format!("{:x}", Sha256::digest(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_characters_from_one() {
        let f = SourceFile::new("x.json5", "ab\ncé d\n");
        assert_eq!(f.line_col(0), LineCol { line: 1, column: 1 });
        assert_eq!(f.line_col(3), LineCol { line: 2, column: 1 });
        // `d` sits after a two-byte character.
        assert_eq!(f.line_col(7), LineCol { line: 2, column: 4 });
        assert_eq!(f.line_col(999), LineCol { line: 3, column: 1 });
    }

    #[test]
    fn sha256_is_lowercase_hex_of_raw_bytes() {
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
