//! Rendering diagnostics: snippets for people, one `path:line:col` line per
//! finding for editors, JSON for tools.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

use miette::{GraphicalReportHandler, GraphicalTheme};
use peppy_schema::{Diagnostic, Diagnostics};
use serde::Serialize;

/// Where relative paths are shown from.
pub(crate) fn cwd() -> Option<PathBuf> {
    std::env::current_dir().ok()
}

fn colour() -> bool {
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}

/// Prints every finding with its snippet, then the compact list editors jump
/// through, to stderr.
pub(crate) fn print_human(diags: &Diagnostics) {
    let theme = if colour() {
        GraphicalTheme::unicode()
    } else {
        GraphicalTheme::unicode_nocolor()
    };
    let handler = GraphicalReportHandler::new_themed(theme).with_context_lines(2);
    let base = cwd();
    let mut out = String::new();
    for d in diags.sorted() {
        let mut rendered = String::new();
        if handler
            .render_report(&mut rendered, d as &dyn miette::Diagnostic)
            .is_ok()
        {
            out.push_str(&rendered);
        }
        if let (None, Some(path)) = (d.source(), d.file_path()) {
            out.push_str(&format!(
                "  in {}\n",
                shown(path, base.as_deref()).display()
            ));
        }
        out.push('\n');
    }
    for d in diags.sorted() {
        out.push_str(&d.jump_line(base.as_deref()));
        out.push('\n');
    }
    let _ = std::io::stderr().write_all(out.as_bytes());
}

fn shown<'a>(path: &'a Path, base: Option<&Path>) -> &'a Path {
    base.and_then(|b| path.strip_prefix(b).ok()).unwrap_or(path)
}

/// A finding as JSON.
#[derive(Debug, Serialize)]
pub(crate) struct JsonDiagnostic {
    code: &'static str,
    severity: &'static str,
    message: String,
    help: Option<String>,
    file: Option<String>,
    line: Option<usize>,
    column: Option<usize>,
    key_path: Option<String>,
}

impl JsonDiagnostic {
    pub(crate) fn new(d: &Diagnostic) -> Self {
        let base = cwd();
        let lc = d.line_col();
        JsonDiagnostic {
            code: d.code.as_str(),
            severity: d.severity.as_str(),
            message: d.message.clone(),
            help: d.help.clone(),
            file: d
                .file_path()
                .map(|p| shown(p, base.as_deref()).display().to_string()),
            line: lc.map(|l| l.line),
            column: lc.map(|l| l.column),
            key_path: d.key_path.clone(),
        }
    }
}

/// Every finding as JSON, sorted by position.
pub(crate) fn json_list(diags: &Diagnostics) -> Vec<JsonDiagnostic> {
    diags
        .sorted()
        .into_iter()
        .map(JsonDiagnostic::new)
        .collect()
}

/// Writes one JSON value and a newline to stdout.
pub(crate) fn print_json(value: &impl Serialize) {
    let mut stdout = std::io::stdout().lock();
    let _ = serde_json::to_writer_pretty(&mut stdout, value);
    let _ = writeln!(stdout);
}

/// `1 error`, `2 warnings`.
pub(crate) fn count(n: usize, what: &str) -> String {
    format!("{n} {what}{}", if n == 1 { "" } else { "s" })
}
