//! `peppy-launch sync PATH`: writes a Python node's generated `peppygen`
//! package (`up` and `run` do it before every build), and finds `uv` for
//! Python nodes' build and run commands.
//!
//! Two layouts. By default the package is `peppygen/` next to
//! `peppy.json5`, and the node's project lists it among its packages. A
//! node whose `pyproject.toml` takes `peppygen` from `.peppy/libs/peppygen`
//! (a `[tool.uv.sources]` path, as PeppyOS's nodes do), or that runs in a
//! container (`execution.container`: its image copies them), gets two small
//! projects there instead: `.peppy/libs/peppygen` (the generated package)
//! and `.peppy/libs/peppylib` (`peppylib`, PeppyOS's name for the `peppy`
//! runtime: a thin package re-exporting it). Both depend on the runtime
//! project `python/peppy-runtime` by path (see [`runtime_dir`]).

use std::path::{Path, PathBuf};

use peppy_schema::{ResolvedNode, check_node_with};

use crate::cli::SyncArgs;
use crate::error::{LaunchError, Result};
use crate::report;

/// The generated package's directory name, beside `peppy.json5`.
pub(crate) const PACKAGE: &str = "peppygen";

/// Where the `.peppy/libs` layout puts its projects, below the node's directory.
pub(crate) const LIBS: &str = ".peppy/libs";

/// Names the runtime project (`python/peppy-runtime`) the `.peppy/libs`
/// projects depend on, instead of the one this `peppy-launch` was built from.
pub const RUNTIME_ENV: &str = "PEPPY_PYTHON_RUNTIME";

pub(crate) fn run(args: &SyncArgs) -> Result {
    let options = crate::repositories::options(args.repos.clone())?;
    let file = crate::run_node::locate(&args.node.display().to_string(), &options)?;
    let check =
        check_node_with(&file, &options, &crate::sources::Fetcher::new()).map_err(|diags| {
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
    let written = if uses_libs(node, dir) {
        dir.join(LIBS)
    } else {
        dir.join(PACKAGE)
    };
    println!(
        "{}: {} ({} file(s) changed)",
        node.node.identity(),
        written.display(),
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
    /// The `peppy` runtime project the `.peppy/libs` projects depend on
    /// is not where it was looked for.
    #[error(
        "the peppy Python runtime is not at {}: set {RUNTIME_ENV} to the `python/peppy-runtime` directory of a peppy checkout",
        path.display()
    )]
    Runtime {
        /// Where it was looked for.
        path: PathBuf,
    },
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

/// Writes the generated package of `node`, whose documents are in `dir`:
/// `dir/peppygen`, or the `.peppy/libs` projects when the node's
/// `pyproject.toml` asks for them ([`uses_libs`]). Only files whose text
/// changed are written, and generated files the documents no longer
/// produce are removed. Returns how many files it wrote or removed.
pub(crate) fn write_package(
    node: &ResolvedNode,
    dir: &Path,
) -> std::result::Result<usize, PackageError> {
    let mut files = peppy_build::python_package(node).map_err(|diags| {
        report::print_human(&diags);
        PackageError::Invalid {
            errors: diags.error_count(),
        }
    })?;
    files.push(engine_file());
    if !uses_libs(node, dir) {
        return write_tree(&dir.join(PACKAGE), &files, true);
    }
    let runtime = runtime_dir()?;
    let libs = dir.join(LIBS);
    let identity = node.node.identity().to_string();
    let mut changed = write_tree(&libs.join(PACKAGE).join(PACKAGE), &files, true)?;
    let project = libs_project(
        PACKAGE,
        &format!("The generated API of peppy node `{identity}`"),
        &runtime,
        Some(&files),
    );
    changed += write_tree(
        &libs.join(PACKAGE),
        &[("pyproject.toml".into(), project)],
        false,
    )?;
    let lib = libs.join(PEPPYLIB);
    changed += write_tree(&lib.join(PEPPYLIB), &peppylib_files(), true)?;
    let project = libs_project(
        PEPPYLIB,
        "peppylib: the peppy runtime under the name PeppyOS's node code imports",
        &runtime,
        None,
    );
    changed += write_tree(&lib, &[("pyproject.toml".into(), project)], false)?;
    Ok(changed)
}

/// The thin runtime package's name in the `.peppy/libs` layout.
const PEPPYLIB: &str = "peppylib";

/// Writes `files` below `root` where their text changed; with `prune`,
/// removes the other `.py` files below it. Returns how many it touched.
/// A Rust node's `.peppy/libs` crates are written by it too.
pub(crate) fn write_tree(
    root: &Path,
    files: &[(PathBuf, String)],
    prune: bool,
) -> std::result::Result<usize, PackageError> {
    let io = |action: &'static str, path: &Path, source: std::io::Error| PackageError::Io {
        action,
        path: path.to_path_buf(),
        source,
    };
    let mut changed = 0;
    let mut wanted = Vec::new();
    for (relative, text) in files {
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
    if prune {
        for stale in python_files(root) {
            if !wanted.contains(&stale) {
                std::fs::remove_file(&stale).map_err(|e| io("remove", &stale, e))?;
                changed += 1;
            }
        }
    }
    Ok(changed)
}

/// `_engine.py`: this `peppy-launch`, which the generated package's
/// descriptor names so that a node started by hand (or its pytest under the
/// harness) plans with the engine that wrote it, with nothing on `PATH`.
fn engine_file() -> (PathBuf, String) {
    let exe = std::env::current_exe()
        .and_then(std::fs::canonicalize)
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    let text = format!(
        "# Generated by `peppy-launch sync`, which rewrites it. Do not edit.\n\"\"\"The `peppy-launch` that wrote this package: a node started by hand plans with it.\"\"\"\n\nPEPPY_LAUNCH = {}\n",
        python_string(&exe)
    );
    (PathBuf::from("_engine.py"), text)
}

/// A Python string literal of `s` (JSON's escapes are Python's too).
fn python_string(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into())
}

/// Whether the node in `dir` takes `peppygen` from `.peppy/libs/peppygen`:
/// it runs in a container (`execution.container`: PeppyOS builds it into an
/// image whose definition copies `.peppy/libs/peppygen` and
/// `.peppy/libs/peppylib`), or its `pyproject.toml` names that path (a
/// `[tool.uv.sources]` entry).
pub(crate) fn uses_libs(node: &ResolvedNode, dir: &Path) -> bool {
    if node.node.execution.container.is_some() {
        return true;
    }
    let Ok(text) = std::fs::read_to_string(dir.join("pyproject.toml")) else {
        return false;
    };
    let wanted = format!("{LIBS}/{PACKAGE}");
    text.lines()
        .map(|l| l.split('#').next().unwrap_or_default())
        .any(|l| {
            [
                format!("\"{wanted}\""),
                format!("'{wanted}'"),
                format!("\"./{wanted}\""),
                format!("'./{wanted}'"),
            ]
            .iter()
            .any(|quoted| l.contains(quoted.as_str()))
        })
}

/// The `peppy` runtime project (`python/peppy-runtime`) the `.peppy/libs`
/// projects depend on: [`RUNTIME_ENV`] when set, else the one in the
/// source tree this `peppy-launch` was built from (its path is compiled
/// in), which must still be there.
pub fn runtime_dir() -> std::result::Result<PathBuf, PackageError> {
    let path = match std::env::var_os(RUNTIME_ENV).filter(|v| !v.is_empty()) {
        Some(dir) => PathBuf::from(dir),
        None => Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join("python")
            .join("peppy-runtime"),
    };
    match std::fs::canonicalize(&path) {
        Ok(p) if p.join("pyproject.toml").is_file() => Ok(p),
        _ => Err(PackageError::Runtime { path }),
    }
}

/// A `file://` URL of an absolute path, for a PEP 508 direct reference.
fn file_url(path: &Path) -> String {
    let mut url = String::from("file://");
    for b in path.to_string_lossy().bytes() {
        match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'/' | b'-' | b'_' | b'.' | b'~' => {
                url.push(b as char)
            }
            other => url.push_str(&format!("%{other:02X}")),
        }
    }
    url
}

/// The `pyproject.toml` of one `.peppy/libs` project. `files` (the
/// generated package) are hashed into it, so that any change of them
/// changes this file too: uv reinstalls a path dependency when its
/// `pyproject.toml` changes, and with `cache-keys` when any of its files do.
fn libs_project(
    name: &str,
    description: &str,
    runtime: &Path,
    files: Option<&[(PathBuf, String)]>,
) -> String {
    let mut text = String::from(
        "# Generated by `peppy-launch sync` (also run by `up` and `run`); rewritten when it changes. Do not edit.\n",
    );
    if let Some(files) = files {
        let mut all = String::new();
        for (path, body) in files {
            all.push_str(&format!("{}\n{}\n{body}\n", path.display(), body.len()));
        }
        let hash = peppy_schema::sha256_hex(all.as_bytes());
        text.push_str(&format!("# generated code: sha256 {}\n", &hash[..16]));
    }
    let dependency = format!("peppy-runtime @ {}", file_url(runtime));
    text.push_str(&format!(
        "[project]\n\
         name = \"{name}\"\n\
         version = \"0.1.0\"\n\
         description = \"{description}\"\n\
         requires-python = \">=3.9\"\n\
         dependencies = [\"{dependency}\"]\n\
         \n\
         [build-system]\n\
         requires = [\"hatchling\"]\n\
         build-backend = \"hatchling.build\"\n\
         \n\
         [tool.hatch.metadata]\n\
         allow-direct-references = true\n\
         \n\
         [tool.hatch.build.targets.wheel]\n\
         packages = [\"{name}\"]\n\
         \n\
         [tool.uv]\n\
         cache-keys = [{{ file = \"pyproject.toml\" }}, {{ file = \"{name}/**/*.py\" }}]\n"
    ));
    text
}

/// The `peppylib` package: PeppyOS's name for the `peppy` runtime, and its
/// clock module. It holds no runtime of its own.
fn peppylib_files() -> Vec<(PathBuf, String)> {
    let init = "\"\"\"peppylib: the `peppy` runtime (python/peppy-runtime) under the names PeppyOS's\n\
node code imports (`from peppylib import CancellationToken`, `peppylib.clock`,\n\
`peppylib.datastore`, `from peppylib import info, stack`).\n\
Everything here is the runtime's own.\"\"\"\n\
# Generated by `peppy-launch sync`. Do not edit.\n\
from peppy import *  # noqa: F401,F403\n\
from peppy import __all__ as _all\n\
from peppy import clock  # noqa: F401\n\
from peppy.info import info  # noqa: F401\n\
\n\
from . import datastore, stack  # noqa: F401\n\
\n\
__all__ = list(_all) + [\"datastore\", \"info\", \"stack\"]\n";
    let module = |name: &str, what: &str| {
        format!(
            "\"\"\"{what}: `peppy.{name}` under PeppyOS's name.\"\"\"\n\
             # Generated by `peppy-launch sync`. Do not edit.\n\
             from peppy.{name} import *  # noqa: F401,F403\n\
             from peppy.{name} import __all__  # noqa: F401\n"
        )
    };
    vec![
        (PathBuf::from("__init__.py"), init.to_string()),
        (
            PathBuf::from("clock.py"),
            module("clock", "The stack clock"),
        ),
        (
            PathBuf::from("datastore.py"),
            module("datastore", "The core node's key/value store"),
        ),
        (
            PathBuf::from("stack.py"),
            module("stack", "The core node's stack listing"),
        ),
    ]
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

pub(crate) fn on_path(program: &str) -> Option<PathBuf> {
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
