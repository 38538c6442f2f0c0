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
    let file = crate::run_node::locate(&args.node.display().to_string(), &options)
        .map_err(LaunchError::Usage)?;
    let check = check_node(&file, &options).map_err(|diags| {
        report::print_human(&diags);
        LaunchError::Invalid {
            errors: diags.error_count(),
        }
    })?;
    let node = &check.resolved;
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

/// Writes `dir/peppygen` for `node`: files whose text changed, and removes
/// generated files the documents no longer produce. Returns how many files
/// it wrote or removed.
pub(crate) fn write_package(node: &ResolvedNode, dir: &Path) -> Result<usize> {
    let files = peppy_build::python_package(node).map_err(|diags| {
        report::print_human(&diags);
        LaunchError::Invalid {
            errors: diags.error_count(),
        }
    })?;
    let root = dir.join(PACKAGE);
    let io = |what: &str, path: &Path, e: std::io::Error| {
        LaunchError::Setup(format!("cannot {what} {}: {e}", path.display()))
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
pub(crate) fn with_uv(argv: &[String]) -> std::result::Result<Vec<String>, String> {
    let mut argv = argv.to_vec();
    if argv.first().is_some_and(|p| p == "uv") {
        argv[0] = uv()?.display().to_string();
    }
    Ok(argv)
}

/// The `uv` that runs Python nodes' `uv` commands: the one on `PATH`, else
/// peppy's own copy under the user's cache directory, installed there from
/// PyPI with `python3 -m pip` on first use (once per machine).
pub fn uv() -> std::result::Result<PathBuf, String> {
    if let Some(found) = on_path("uv") {
        return Ok(found);
    }
    let dir = tools_dir().join("uv");
    let exe = dir.join("bin").join("uv");
    if exe.is_file() {
        return Ok(exe);
    }
    eprintln!(
        "peppy-launch: uv is not installed; installing it for peppy into {} (once)",
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
    let status = std::process::Command::new("python3")
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            // Root in CI and containers: a private target directory is fine.
            "--root-user-action=ignore",
            "--target",
        ])
        .arg(&partial)
        .arg("uv")
        .status()
        .map_err(|e| format!("cannot run `python3 -m pip` to install uv: {e}"))?;
    if status.success() && partial.join("bin").join("uv").is_file() {
        if std::fs::rename(&partial, &dir).is_err() {
            // Another installation finished first; theirs is as good.
            let _ = std::fs::remove_dir_all(&partial);
        }
    } else {
        let _ = std::fs::remove_dir_all(&partial);
    }
    if !exe.is_file() {
        return Err(format!(
            "installing uv with `python3 -m pip install --target {} uv` failed; install uv (https://docs.astral.sh/uv/) and retry",
            dir.display()
        ));
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
