use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The workspace root, where `examples/` lives.
pub(crate) fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace root")
        .to_path_buf()
}

pub(crate) struct Run {
    pub(crate) code: i32,
    pub(crate) stdout: String,
    pub(crate) stderr: String,
}

/// Runs `peppy-launch args...` in `dir` with no colour and no inherited
/// repository list.
pub(crate) fn peppy_launch(dir: &Path, args: &[&str]) -> Run {
    peppy_launch_with(dir, args, &[])
}

/// [`peppy_launch`] with extra environment variables.
pub(crate) fn peppy_launch_with(dir: &Path, args: &[&str], env: &[(&str, &Path)]) -> Run {
    let Output {
        status,
        stdout,
        stderr,
    } = Command::new(env!("CARGO_BIN_EXE_peppy-launch"))
        .args(args)
        .current_dir(dir)
        .env("NO_COLOR", "1")
        .env_remove("PEPPY_REPOSITORIES")
        .envs(env.iter().copied())
        .output()
        .expect("run peppy-launch");
    Run {
        code: status.code().expect("exited normally, not by a signal"),
        stdout: String::from_utf8(stdout).expect("utf-8 stdout"),
        stderr: String::from_utf8(stderr).expect("utf-8 stderr"),
    }
}

/// The `path:line:col: ...` lines of a human report.
pub(crate) fn jump_lines(stderr: &str) -> Vec<&str> {
    stderr
        .lines()
        .filter(|l| l.contains(": error: ") || l.contains(": warning: "))
        .filter(|l| !l.trim_start().starts_with(['×', '⚠', '│', '·', '╭']))
        .collect()
}
