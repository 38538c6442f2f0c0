//! Writes the `.peppy/libs` crates of a Rust node in PeppyOS's layout (its
//! `Cargo.toml` depends on `.peppy/libs/peppygen` and
//! `.peppy/libs/peppylib`): `sync`, and `up` / `run` before a build.
//!
//! A node that generates its API from `build.rs` or `#[peppy::node]` does
//! not ask for them and is left alone.

use std::path::{Component, Path, PathBuf};

use peppy_schema::ResolvedNode;

use crate::python_sync::PackageError;

/// Overrides where the peppy checkout is (the directory holding the `peppy`
/// crate's `Cargo.toml`), for a `peppy-launch` installed away from it.
pub(crate) const PEPPY_SOURCE_ENV: &str = "PEPPY_SOURCE_DIR";

/// Whether the node in `dir` is written in Rust and its `Cargo.toml` takes
/// the generated crates from `.peppy/libs`.
pub(crate) fn wants_libs(node: &ResolvedNode, dir: &Path) -> bool {
    node.node.execution.language.eq_ignore_ascii_case("rust")
        && std::fs::read_to_string(dir.join("Cargo.toml"))
            .is_ok_and(|manifest| manifest.contains(".peppy/libs/peppygen"))
}

/// The peppy checkout the crates depend on.
pub(crate) fn peppy_source() -> PathBuf {
    match std::env::var_os(PEPPY_SOURCE_ENV) {
        Some(dir) if !dir.is_empty() => PathBuf::from(dir),
        // This binary's own checkout: peppy-launch sits one level below it.
        _ => Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default(),
    }
}

/// Writes `dir/.peppy/libs` for `node`: only files whose text changed, so
/// a second run writes nothing and cargo rebuilds nothing. Returns how many
/// files it wrote.
pub(crate) fn write_libs(node: &ResolvedNode, dir: &Path) -> Result<usize, PackageError> {
    let libs = dir.join(peppy_build::LIBS_DIR);
    let crate_dir = libs.join("peppygen");
    let peppy = spelled_from(&absolute(&crate_dir), &absolute(&peppy_source()));
    let document = node.node.file.path().file_name().map_or_else(
        || "peppy.json5".to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let files = peppy_build::rust_libs(node, &peppy, &document).map_err(|e| match e {
        peppy_build::Error::Schema { diagnostics, .. } => {
            crate::report::print_human(&diagnostics);
            PackageError::Invalid {
                errors: diagnostics.error_count(),
            }
        }
        other => PackageError::Generate(other.to_string()),
    })?;
    let files: Vec<(PathBuf, String)> = files.into_iter().map(|f| (f.path, f.text)).collect();
    crate::python_sync::write_tree(&libs, &files, false)
}

fn absolute(path: &Path) -> PathBuf {
    let joined = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    // Lexically: `..` and `.` out, without touching the file system (the
    // crate directory may not exist yet).
    let mut out = PathBuf::new();
    for c in joined.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// `target` as the crate in `from` should name it: relative when the node
/// lives inside the peppy checkout (the examples, which are committed with
/// their crates and must not name the machine they were written on),
/// absolute otherwise.
fn spelled_from(from: &Path, target: &Path) -> String {
    let Ok(inside) = from.strip_prefix(target) else {
        return target.display().to_string();
    };
    let ups = inside.components().count();
    if ups == 0 {
        return ".".to_string();
    }
    vec![".."; ups].join("/")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_inside_the_checkout_names_it_relatively() {
        assert_eq!(
            spelled_from(
                Path::new("/src/peppy/examples/nodes/cam/.peppy/libs/peppygen"),
                Path::new("/src/peppy")
            ),
            "../../../../../.."
        );
        assert_eq!(
            spelled_from(
                Path::new("/hub/arm/.peppy/libs/peppygen"),
                Path::new("/src/peppy")
            ),
            "/src/peppy"
        );
    }
}
