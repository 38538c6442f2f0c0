//! `peppy-launch validate PATH...`

use std::path::{Path, PathBuf};

use peppy_schema::{
    Code, Diagnostic, Diagnostics, Document, SourceFile, detect_kind, parse_document,
};
use serde::Serialize;

use crate::cli::{Format, ValidateArgs};
use crate::error::{LaunchError, Result};
use crate::report::{self, JsonDiagnostic};

/// The outcome for one file.
struct Checked {
    path: PathBuf,
    kind: Option<&'static str>,
    diagnostics: Diagnostics,
}

#[derive(Serialize)]
struct JsonDocument {
    path: String,
    kind: Option<&'static str>,
    valid: bool,
    diagnostics: Vec<JsonDiagnostic>,
}

#[derive(Serialize)]
struct JsonReport {
    valid: bool,
    errors: usize,
    warnings: usize,
    documents: Vec<JsonDocument>,
    skipped: Vec<String>,
}

pub(crate) fn run(args: &ValidateArgs) -> Result {
    let mut checked = Vec::new();
    let mut skipped = Vec::new();
    let mut usage = Diagnostics::new();
    for path in &args.paths {
        if path.is_dir() {
            for file in documents_in(path, &mut usage) {
                match check_file(&file, false) {
                    Some(c) => checked.push(c),
                    None => skipped.push(file),
                }
            }
        } else if path.exists() {
            checked.extend(check_file(path, true));
        } else {
            usage.push(
                Diagnostic::error(
                    Code::CannotRead,
                    format!("`{}` does not exist", path.display()),
                )
                .with_file_path(path),
            );
        }
    }
    let mut all = usage.clone();
    for c in &checked {
        all.extend(c.diagnostics.clone());
    }
    let errors = all.error_count();
    let warnings = all.len() - errors;
    let valid = errors == 0;
    match args.format {
        Format::Json => {
            let base = report::cwd();
            let shown = |p: &Path| {
                base.as_deref()
                    .and_then(|b| p.strip_prefix(b).ok())
                    .unwrap_or(p)
                    .display()
                    .to_string()
            };
            let mut documents: Vec<JsonDocument> = checked
                .iter()
                .map(|c| JsonDocument {
                    path: shown(&c.path),
                    kind: c.kind,
                    valid: !c.diagnostics.has_errors(),
                    diagnostics: report::json_list(&c.diagnostics),
                })
                .collect();
            if !usage.is_empty() {
                documents.push(JsonDocument {
                    path: String::new(),
                    kind: None,
                    valid: false,
                    diagnostics: report::json_list(&usage),
                });
            }
            report::print_json(&JsonReport {
                valid,
                errors,
                warnings,
                documents,
                skipped: skipped.iter().map(|p| shown(p)).collect(),
            });
        }
        Format::Human => {
            if !all.is_empty() {
                report::print_human(&all);
            }
            let invalid = checked
                .iter()
                .filter(|c| c.diagnostics.has_errors())
                .count();
            eprintln!(
                "{}: {} checked, {} invalid; {}, {}",
                if valid { "valid" } else { "invalid" },
                report::count(checked.len(), "document"),
                invalid,
                report::count(errors, "error"),
                report::count(warnings, "warning"),
            );
        }
    }
    if valid {
        Ok(())
    } else {
        Err(LaunchError::Invalid { errors })
    }
}

/// Every `*.json5` under `dir`, skipping build and VCS directories.
fn documents_in(dir: &Path, problems: &mut Diagnostics) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in peppy_schema::json5_files(dir) {
        match entry {
            Ok(path) => out.push(path),
            Err(e) => problems.push(
                Diagnostic::error(
                    Code::CannotRead,
                    format!("cannot read `{}`: {e}", dir.display()),
                )
                .with_file_path(dir),
            ),
        }
    }
    out
}

/// Validates one file. Inside a directory walk, a well-formed JSON5 file
/// that is not a peppy document is skipped (`None`); named explicitly, it is
/// an error.
fn check_file(path: &Path, explicit: bool) -> Option<Checked> {
    let (file, sha) = match SourceFile::read(path) {
        Ok(v) => v,
        Err(d) => {
            return Some(Checked {
                path: path.to_path_buf(),
                kind: None,
                diagnostics: Diagnostics::from(*d),
            });
        }
    };
    if !explicit
        && !is_peppy_named(path)
        && let Ok((root, _)) = peppy_schema::json::parse(&file)
    {
        // A fragment is checked through the launchers that compose it.
        if root.get("peppy_schema").and_then(|n| n.as_str()) == Some("launcher_fragment/v1") {
            return None;
        }
        let claims = root.get("peppy_schema").is_some() || root.get("schema_version").is_some();
        if detect_kind(&root).is_none() && !claims {
            return None;
        }
    }
    let (kind, diagnostics) = match parse_document(&file, &sha) {
        Ok((doc, warnings)) => (Some(kind_name(&doc)), warnings),
        Err(d) => (None, d),
    };
    Some(Checked {
        path: path.to_path_buf(),
        kind,
        diagnostics,
    })
}

fn is_peppy_named(path: &Path) -> bool {
    path.file_name()
        .is_some_and(|n| n == "peppy.json5" || n == peppy_schema::REPOSITORIES_FILE)
}

fn kind_name(doc: &Document) -> &'static str {
    doc.kind().as_str()
}
