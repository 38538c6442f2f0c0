//! What each fuzz target does with its input, kept out of the `fuzz_target!`
//! binaries so `fuzz/run` can replay a crash through the same code.
//!
//! Every target does what peppy does with such bytes from a user or a peer,
//! renders every diagnostic the way the CLI does (a span past the text, or
//! inside a UTF-8 character, would panic there), and checks the properties
//! its reader promises: a composed launcher's flat text reads back, a
//! decoded payload re-encodes to bytes that decode to the same value, the
//! direct JSON writer agrees with the `serde_json` one, a key read back by
//! its parts prints as it was.

use std::path::{Component, Path, PathBuf};

use peppy_schema::{Composition, Diagnostics, Document, MessageFormat, SourceFile, parse_document};
use peppy_wire::dynamic::{self, JsonForm};

/// Files a [`composition`] input may hold.
const MAX_FILES: usize = 8;

/// What separates the files of a [`composition`] input: the marker, then the
/// file's relative path up to the end of the line, then its text.
pub const FILE_MARKER: &str = "\n%%% ";

/// Renders every diagnostic as the CLI does, so a bad span panics here.
fn render(diags: &Diagnostics) {
    let handler =
        miette::GraphicalReportHandler::new_themed(miette::GraphicalTheme::unicode_nocolor());
    for d in diags.iter() {
        let mut out = String::new();
        handler
            .render_report(&mut out, d as &dyn miette::Diagnostic)
            .expect("rendering a diagnostic into a String cannot fail");
        let _ = d.jump_line(None);
        let _ = d.line_col();
    }
}

fn rendered<T>(result: Result<(T, Diagnostics), Diagnostics>) -> Option<T> {
    match result {
        Ok((value, warnings)) => {
            render(&warnings);
            Some(value)
        }
        Err(errors) => {
            render(&errors);
            None
        }
    }
}

/// One document of any kind, as `validate` reads a file: detected by its
/// `peppy_schema`, read, and (a launcher) composed.
pub fn document(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let file = SourceFile::new("fuzz.json5", text);
    let parsed = parse_document(&file, "0");
    let clean = parsed.is_ok();
    let Some(doc) = rendered(parsed) else {
        return;
    };
    if let Document::Launcher(_) = doc {
        compose(&Composition::parse("fuzz.json5", text), clean);
    }
}

/// A launcher's composition: every selection it lists, and the default
/// one resolved to the flat text `up` would run. That text is always
/// JSON5; for a launcher that read without errors and is flat (`clean`),
/// it reads back without errors too (a composed launcher's fragments are
/// checked with the stack, not by reading the flat text).
fn compose(composition: &Result<Composition, Diagnostics>, clean: bool) {
    let composition = match composition {
        Ok(c) => c,
        Err(errors) => return render(errors),
    };
    if let Err(errors) = composition.selections() {
        render(&errors);
    }
    let selection = match composition.select(&[]) {
        Ok(s) => s,
        Err(errors) => return render(&errors),
    };
    match composition.resolve(&selection) {
        Ok(resolved) => {
            render(&resolved.warnings);
            let _ = resolved.report.lines();
            let again = SourceFile::new("flat.json5", resolved.text.as_str());
            if let Err(errors) = peppy_schema::json::parse(&again) {
                panic!(
                    "a composition resolved to text that is not JSON5:\n{}\n{errors:?}",
                    resolved.text
                );
            }
            if !clean || composition.is_composed() {
                return;
            }
            if let Err(errors) = parse_document(&again, "0") {
                panic!(
                    "the flat launcher a composition resolves to does not read back:\n{}\n{errors:?}",
                    resolved.text
                );
            }
        }
        Err(errors) => render(&errors),
    }
}

/// A launcher (the first file, `launcher.json5`) and the fragments the
/// other files give, composed as `up --with` composes them: every
/// selection listed, the composition checked as `repo index --check`
/// checks it, and the default selection resolved.
pub fn composition(data: &[u8], dir: &Path) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let files = split_files(text);
    if std::fs::remove_dir_all(dir).is_err() && dir.exists() {
        return;
    }
    for (path, body) in &files {
        let path = dir.join(path);
        if let Some(parent) = path.parent()
            && std::fs::create_dir_all(parent).is_err()
        {
            return;
        }
        if std::fs::write(&path, body).is_err() {
            return;
        }
    }
    let launcher = dir.join("launcher.json5");
    let clean = parse_document(&SourceFile::new(&launcher, files[0].1), "0").is_ok();
    let composition = Composition::load(&launcher);
    if let Ok(c) = &composition {
        render(&c.check().problems);
    }
    compose(&composition, clean);
}

/// The files of a [`composition`] input: `launcher.json5` first, then each
/// marked file whose path is relative, plain and at most three deep.
pub fn split_files(text: &str) -> Vec<(PathBuf, &str)> {
    let mut parts = text.split(FILE_MARKER);
    let mut files = vec![(PathBuf::from("launcher.json5"), parts.next().unwrap_or(""))];
    for part in parts.take(MAX_FILES - 1) {
        let (name, body) = part.split_once('\n').unwrap_or((part, ""));
        let path = Path::new(name.trim());
        let plain = path.components().count() <= 3
            && path
                .components()
                .all(|c| matches!(c, Component::Normal(s) if s.len() <= 64));
        if plain && !name.trim().is_empty() {
            files.push((path.to_path_buf(), body));
        }
    }
    files
}

/// A format's canonical text (the first line) and a payload (the rest), as
/// `topic echo` and `record` meet them: the format read, the payload
/// decoded and shown in every form; a decoded value written as recording
/// JSON encodes again, and that encoding is a fixed point.
pub fn payload(data: &[u8]) {
    let Some(newline) = data.iter().position(|&b| b == b'\n') else {
        return;
    };
    let Ok(canonical) = std::str::from_utf8(&data[..newline]) else {
        return;
    };
    let Ok(format) = MessageFormat::from_canonical(canonical) else {
        return;
    };
    let Ok(value) = dynamic::decode(&format, &data[newline + 1..]) else {
        return;
    };
    let _ = dynamic::to_text(&value);
    let _ = dynamic::to_json(&value);
    let json = dynamic::to_recording_json(&value);
    let mut written = Vec::new();
    dynamic::write_recording_json(&value, &mut written);
    let reread: serde_json::Value = serde_json::from_slice(&written)
        .unwrap_or_else(|e| panic!("write_recording_json wrote invalid JSON ({e})"));
    assert_eq!(
        reread, json,
        "write_recording_json and to_recording_json disagree"
    );
    let bytes = dynamic::encode_as(&format, &json, JsonForm::Recording)
        .unwrap_or_else(|e| panic!("a decoded value does not encode again: {e:?}\n{json}"));
    let again = dynamic::decode(&format, &bytes)
        .unwrap_or_else(|e| panic!("an encoded value does not decode: {e}"));
    let bytes_again = dynamic::encode_as(
        &format,
        &dynamic::to_recording_json(&again),
        JsonForm::Recording,
    )
    .expect("a value that encoded once encodes again");
    assert_eq!(bytes, bytes_again, "encoding is not a fixed point");
}

/// A format's canonical text (the first line) and the JSON5 a user types
/// for `topic pub` or `service call` (the rest): parsed, encoded, errors
/// located; what encodes decodes.
pub fn message_text(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Some((canonical, written)) = text.split_once('\n') else {
        return;
    };
    let Ok(format) = MessageFormat::from_canonical(canonical) else {
        return;
    };
    match dynamic::encode_text(&format, "fuzz", written) {
        Ok(bytes) => {
            dynamic::decode(&format, &bytes)
                .unwrap_or_else(|e| panic!("typed text encoded to bytes that do not decode: {e}"));
        }
        Err(errors) => render(&errors),
    }
    if let Ok(parsed) = dynamic::parse_json5("fuzz", written) {
        let value = parsed.value();
        for form in [JsonForm::Cli, JsonForm::Recording] {
            match dynamic::encode_as(&format, &value, form) {
                Ok(bytes) => {
                    dynamic::decode(&format, &bytes).unwrap_or_else(|e| {
                        panic!("a value encoded as {form:?} does not decode: {e}")
                    });
                }
                Err(error) => render(&parsed.diagnostic(&error).into()),
            }
        }
    }
}

/// Keys and attachments as a peer sends them: every reader of a key, and
/// every attachment parser; what reads back by its parts prints as it was.
pub fn keys(data: &[u8]) {
    use peppy_wire::{attachment, keys};
    let _ = attachment::parse_topic(data);
    let _ = attachment::QueryHeader::decode(data);
    let _ = attachment::parse_reply(data);
    let Ok(key) = std::str::from_utf8(data) else {
        return;
    };
    if let Some(selector) = keys::EntrySelector::parse(key) {
        assert_eq!(selector.to_string(), key, "a selector does not print back");
    }
    let _ = keys::parse_entry_key(key);
    let _ = keys::split_entry_key(key);
    let _ = keys::parse_liveliness_key(key);
    let _ = keys::parse_core_key(key);
    let _ = keys::parse_pairing_topic_key(key);
    let _ = keys::Claim::parse(key);
    let _ = keys::is_segment(key);
}

/// A per-process scratch directory for [`composition`].
pub fn scratch_dir() -> PathBuf {
    std::env::temp_dir().join(format!("peppy-fuzz-composition-{}", std::process::id()))
}
