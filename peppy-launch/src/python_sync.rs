//! `peppy-launch sync PATH`: writes a Python node's generated `peppygen`
//! package next to its `peppy.json5` (`up` runs it before every build), and
//! finds `uv` for Python nodes' build and run commands.

use std::path::{Path, PathBuf};

use peppy_schema::{RepoOptions, ResolvedNode, check_node};

use crate::cli::SyncArgs;
use crate::error::{LaunchError, Result};
use crate::report;

/// The generated package's directory name, beside `peppy.json5`.
pub(crate) const PACKAGE: &str = "peppygen";

pub(crate) fn run(args: &SyncArgs) -> Result {
    let options = RepoOptions {
        explicit: args.repos.clone(),
        env: None,
    };
    let file = crate::run_node::locate(&args.node.display().to_string(), &options)?;
    let check = check_node(&file, &options).map_err(|diags| {
        report::print_human(&diags);
        LaunchError::Invalid {
            errors: diags.error_count(),
        }
    })?;
    let node = &check.resolved;
    if crate::rust_libs::wants_libs(node, file.parent().unwrap_or(Path::new("."))) {
        let dir = file.parent().unwrap_or(Path::new("."));
        let changed = crate::rust_libs::write_libs(node, dir)?;
        println!(
            "{}: {} ({} file(s) changed)",
            node.node.identity(),
            dir.join(peppy_build::LIBS_DIR).display(),
            changed
        );
        return Ok(());
    }
    if !is_python(node) {
        println!(
            "{} is a {} node: its API is generated when it builds (peppy_build::sync() or #[peppy::node]); nothing to write",
            node.node.identity(),
            node.node.execution.language
        );
        return Ok(());
    }
    let dir = file.parent().unwrap_or(Path::new("."));
    let changed = write_package(node, dir)?;
    println!(
        "{}: {} ({} file(s) changed)",
        node.node.identity(),
        dir.join(PACKAGE).display(),
        changed
    );
    Ok(())
}

/// Whether the node is written in Python.
pub(crate) fn is_python(node: &ResolvedNode) -> bool {
    node.node.execution.language.eq_ignore_ascii_case("python")
}

/// Why a Python node's `peppygen` package was not written.
#[derive(Debug, thiserror::Error)]
pub enum PackageError {
    /// The generator refused the node; its diagnostics were printed.
    #[error("invalid: {errors} error(s), reported above")]
    Invalid {
        /// How many errors were reported.
        errors: usize,
    },
    /// The generator failed for another reason than the documents.
    #[error("{0}")]
    Generate(String),
    /// A file or directory of the package could not be written or removed.
    #[error("cannot {action} {}: {source}", path.display())]
    Io {
        /// What was done: `create` (a directory), `write`, `remove`.
        action: &'static str,
        /// The file or directory.
        path: PathBuf,
        /// Why it failed.
        source: std::io::Error,
    },
}

/// Writes `dir/peppygen` for `node`: files whose text changed, and removes
/// generated files the documents no longer produce. Returns how many files
/// it wrote or removed.
pub(crate) fn write_package(
    node: &ResolvedNode,
    dir: &Path,
) -> std::result::Result<usize, PackageError> {
    let files = peppy_build::python_package(node).map_err(|diags| {
        report::print_human(&diags);
        PackageError::Invalid {
            errors: diags.error_count(),
        }
    })?;
    let root = dir.join(PACKAGE);
    let io = |action: &'static str, path: &Path, source: std::io::Error| PackageError::Io {
        action,
        path: path.to_path_buf(),
        source,
    };
    let mut changed = 0;
    let mut wanted = Vec::new();
    for (relative, text) in &files {
        let path = root.join(relative);
        wanted.push(path.clone());
        if std::fs::read_to_string(&path).is_ok_and(|old| old == *text) {
            continue;
        }
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| io("create", parent, e))?;
        }
        std::fs::write(&path, text).map_err(|e| io("write", &path, e))?;
        changed += 1;
    }
    for stale in python_files(&root) {
        if !wanted.contains(&stale) {
            std::fs::remove_file(&stale).map_err(|e| io("remove", &stale, e))?;
            changed += 1;
        }
    }
    Ok(changed)
}

/// Every `.py` file below `root` (caches left alone).
fn python_files(root: &Path) -> Vec<PathBuf> {
    walkdir::WalkDir::new(root)
        .into_iter()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_type().is_file() && e.path().extension().is_some_and(|x| x == "py"))
        .map(|e| e.into_path())
        .collect()
}

/// `argv` with a leading `uv` replaced by the `uv` this machine has, or
/// one installed for peppy from PyPI on first use, so a Python node's
/// `["uv", "sync"]` works on a machine that never installed uv.
pub(crate) fn with_uv(argv: &[String]) -> std::result::Result<Vec<String>, UvError> {
    let mut argv = argv.to_vec();
    if argv.first().is_some_and(|p| p == "uv") {
        argv[0] = uv()?.display().to_string();
    }
    Ok(argv)
}

/// Why no `uv` could be had for a Python node.
#[derive(Debug, thiserror::Error)]
pub enum UvError {
    /// pip's requirements file (uv's version and hashes) could not be
    /// written.
    #[error("cannot write uv's requirements file {}: {source}", path.display())]
    Requirements {
        /// The requirements file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// `python3 -m pip` could not be started.
    #[error("cannot run `python3 -m pip` to install uv: {0}")]
    Pip(#[source] std::io::Error),
    /// pip ran but left no uv (no wheel for this platform, no network, a
    /// hash mismatch).
    #[error(
        "installing uv {UV_VERSION} with `python3 -m pip install --require-hashes --target {}` failed \
         (peppy pins the wheels for Linux on x86_64 and aarch64); install uv \
         (https://docs.astral.sh/uv/) on PATH and retry",
        dir.display()
    )]
    Install {
        /// Where uv was to be installed.
        dir: PathBuf,
    },
}

/// The uv version peppy installs when none is on `PATH`.
pub const UV_VERSION: &str = "0.13.9";

/// The sha256 of each PyPI wheel of uv [`UV_VERSION`] pip may pick on Linux
/// x86_64 and aarch64, glibc and musl (each checked against a download of
/// the wheel): pip installs these bytes or nothing (`--require-hashes`).
/// Another platform has no listed wheel, so the install fails and asks for
/// uv on `PATH`.
const UV_WHEEL_SHA256: [(&str, &str); 4] = [
    (
        "manylinux_2_17_x86_64",
        "d7f459fe4fd247d830351c75686d3996ace3c6f3f728eb0e85a30b7ada0cef19",
    ),
    (
        "musllinux_1_1_x86_64",
        "2c45530751517d6c3bbc69a19473f6effe47cce047bede01ffd8af7ea7b36b25",
    ),
    (
        "manylinux_2_17_aarch64 and musllinux_1_1_aarch64",
        "5435c5ce14a56431208ca0996416d310f1598e8c2c8ba707688985a16bb82dbe",
    ),
    (
        "manylinux_2_28_aarch64",
        "ecb6028d79dc96fbeafffe5c8af62a7099487ebc05a701e76714eebcffd06375",
    ),
];

/// The requirements file pinning uv: its version and its wheels' hashes.
fn uv_requirements() -> String {
    let mut line = format!("uv=={UV_VERSION}");
    for (_, sha256) in UV_WHEEL_SHA256 {
        line.push_str(&format!(" --hash=sha256:{sha256}"));
    }
    line.push('\n');
    line
}

/// The `uv` that runs Python nodes' `uv` commands: the one on `PATH`, used
/// as it is (whatever its version: the user chose it), else peppy's own
/// copy of uv [`UV_VERSION`] under the user's cache directory, installed
/// there from PyPI with `python3 -m pip` on first use, its wheel checked
/// against the sha256 listed here for each Linux x86_64 and aarch64 wheel
/// (pip's `--require-hashes`). The directory names the version, so a
/// release of peppy that pins another installs that one beside it.
pub fn uv() -> std::result::Result<PathBuf, UvError> {
    if let Some(found) = on_path("uv") {
        return Ok(found);
    }
    let dir = tools_dir().join(format!("uv-{UV_VERSION}"));
    let exe = dir.join("bin").join("uv");
    if exe.is_file() {
        return Ok(exe);
    }
    eprintln!(
        "peppy-launch: uv is not installed; installing uv {UV_VERSION} for peppy into {} (once)",
        dir.display()
    );
    // Installed beside its place and moved in at once: several launches (or
    // tests, several threads of one process among them) may install it at
    // the same time, and none may see half of it or remove another's.
    static INSTALLS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let partial = dir.with_extension(format!(
        "partial.{}.{}",
        std::process::id(),
        INSTALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&partial);
    // The hashes go to pip in a requirements file (it takes them nowhere
    // else), written in the user's own cache rather than a shared /tmp,
    // where another user could swap it before pip reads it.
    let requirements = partial.with_extension("requirements.txt");
    std::fs::create_dir_all(tools_dir())
        .and_then(|()| std::fs::write(&requirements, uv_requirements()))
        .map_err(|source| UvError::Requirements {
            path: requirements.clone(),
            source,
        })?;
    let status = std::process::Command::new("python3")
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            // Root in CI and containers: a private target directory is fine.
            "--root-user-action=ignore",
            "--require-hashes",
            // A wheel or nothing: no source build, whose hash is not listed.
            "--only-binary=:all:",
            "--no-deps",
            "--target",
        ])
        .arg(&partial)
        .arg("-r")
        .arg(&requirements)
        .status();
    let _ = std::fs::remove_file(&requirements);
    let status = status.map_err(UvError::Pip)?;
    if status.success() && partial.join("bin").join("uv").is_file() {
        if std::fs::rename(&partial, &dir).is_err() {
            // Another installation finished first; theirs is as good.
            let _ = std::fs::remove_dir_all(&partial);
        }
    } else {
        let _ = std::fs::remove_dir_all(&partial);
    }
    if !exe.is_file() {
        return Err(UvError::Install { dir });
    }
    Ok(exe)
}

fn on_path(program: &str) -> Option<PathBuf> {
    std::env::split_paths(&std::env::var_os("PATH")?)
        .map(|d| d.join(program))
        .find(|p| p.is_file())
}

/// `tools` under peppy's cache directory.
fn tools_dir() -> PathBuf {
    crate::sources::cache_dir().join("tools")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_install_says_what_to_do() {
        let e = UvError::Install {
            dir: PathBuf::from("/cache/tools/uv-x"),
        };
        assert_eq!(
            e.to_string(),
            format!(
                "installing uv {UV_VERSION} with `python3 -m pip install --require-hashes --target /cache/tools/uv-x` failed \
                 (peppy pins the wheels for Linux on x86_64 and aarch64); install uv \
                 (https://docs.astral.sh/uv/) on PATH and retry"
            )
        );
    }

    #[test]
    fn uv_is_pinned_to_one_version_and_its_wheels_hashes() {
        let text = uv_requirements();
        assert_eq!(text.lines().count(), 1, "{text}");
        assert!(text.starts_with(&format!("uv=={UV_VERSION} ")), "{text}");
        let hashes: Vec<&str> = text
            .split_whitespace()
            .filter_map(|word| word.strip_prefix("--hash=sha256:"))
            .collect();
        assert_eq!(hashes.len(), UV_WHEEL_SHA256.len(), "{text}");
        for hash in hashes {
            assert!(
                hash.len() == 64 && hash.bytes().all(|b| b.is_ascii_hexdigit()),
                "{hash}"
            );
        }
    }
}
