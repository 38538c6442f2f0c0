//! Building Python source text: indentation, docstrings, identifiers and
//! string literals.

/// A Python identifier for a document name (names are ASCII identifiers
/// already; keywords get a trailing `_`, as PEP 8 suggests).
pub(crate) fn py_ident(name: &str) -> String {
    if peppy_schema::names::is_python_keyword(name) {
        format!("{name}_")
    } else {
        name.to_string()
    }
}

/// A Python string literal holding `s` exactly.
pub(crate) fn py_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 || c == '\u{7f}' => {
                out.push_str(&format!("\\x{:02x}", c as u32))
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// One Python file being written.
#[derive(Debug, Default)]
pub(crate) struct Source {
    text: String,
    depth: usize,
}

impl Source {
    pub(crate) fn line(&mut self, line: &str) {
        for l in line.lines() {
            if !l.is_empty() {
                self.text.push_str(&"    ".repeat(self.depth));
                self.text.push_str(l);
            }
            self.text.push('\n');
        }
    }

    pub(crate) fn blank(&mut self) {
        self.text.push('\n');
    }

    pub(crate) fn indent(&mut self) {
        self.depth += 1;
    }

    pub(crate) fn dedent(&mut self) {
        self.depth -= 1;
    }

    pub(crate) fn docstring(&mut self, doc: &str) {
        let doc = doc.replace('\\', "\\\\").replace("\"\"\"", "\\\"\\\"\\\"");
        self.line(&format!("\"\"\"{doc}\"\"\""));
    }

    pub(crate) fn finish(self) -> String {
        let mut t = self.text;
        while t.ends_with("\n\n") {
            t.pop();
        }
        t
    }
}
