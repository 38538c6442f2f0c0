//! One cargo build directory for every Rust node peppy builds.
//!
//! Each Rust node is a cargo project of its own (PeppyOS lays them out
//! so), and each would build Zenoh, tokio and the rest of the runtime into
//! its own `target/`: a stack of four nodes built them four times. Cargo's
//! build directory (`build.build-dir`, stable since cargo 1.91) holds what
//! a build makes on the way (dependencies, build scripts, incremental
//! state), apart from the target directory that holds its products. peppy
//! gives every cargo build it runs one build directory, so a dependency
//! built once with the same version, features and profile is reused by
//! every node after it, while each node's binary still lands in its own
//! `target/`, where its `run_cmd` expects it. Nothing in the node changes.
//!
//! Left alone: a build that is not `cargo build`, an environment that
//! already chooses (`CARGO_TARGET_DIR`, `CARGO_BUILD_BUILD_DIR`,
//! `CARGO_BUILD_TARGET_DIR`), a node whose cargo configuration chooses,
//! and `PEPPY_BUILD_DIR=off`.

use std::ffi::OsString;
use std::path::{Path, PathBuf};

/// Where the shared build directory is, or `off` for each node's own.
pub(crate) const BUILD_DIR_ENV: &str = "PEPPY_BUILD_DIR";

/// The variables through which cargo's user already chose where builds go.
const CHOSEN_BY_CARGO_ENV: [&str; 3] = [
    "CARGO_TARGET_DIR",
    "CARGO_BUILD_TARGET_DIR",
    "CARGO_BUILD_BUILD_DIR",
];

/// The build directory to give `cmd`, run in `dir`, as cargo's
/// `CARGO_BUILD_BUILD_DIR`; `None` to leave the build as it is.
pub(crate) fn for_build(cmd: &[String], dir: &Path) -> Option<PathBuf> {
    for_build_in(cmd, dir, |key| std::env::var_os(key))
}

/// [`for_build`] with the environment read through `var`.
fn for_build_in(
    cmd: &[String],
    dir: &Path,
    var: impl Fn(&str) -> Option<OsString>,
) -> Option<PathBuf> {
    if !is_cargo_build(cmd) {
        return None;
    }
    let chosen = |key: &str| var(key).is_some_and(|v| !v.is_empty());
    let cargo_home = var("CARGO_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| var("HOME").map(|home| PathBuf::from(home).join(".cargo")));
    if CHOSEN_BY_CARGO_ENV.iter().any(|key| chosen(key)) || config_chooses(dir, cargo_home) {
        return None;
    }
    match var(BUILD_DIR_ENV) {
        Some(v) if v == "off" => None,
        Some(v) if !v.is_empty() => Some(PathBuf::from(v)),
        _ => Some(crate::sources::cache_dir().join("cargo-build")),
    }
}

/// Whether `cmd` is `cargo build` (`cargo b`, `cargo +toolchain build`,
/// with flags before the subcommand or not).
fn is_cargo_build(cmd: &[String]) -> bool {
    let Some((program, args)) = cmd.split_first() else {
        return false;
    };
    if Path::new(program).file_name().is_none_or(|n| n != "cargo") {
        return false;
    }
    args.iter()
        .find(|a| !a.starts_with('-') && !a.starts_with('+'))
        .is_some_and(|sub| sub == "build" || sub == "b")
}

/// Whether a cargo configuration file that applies in `dir` (its own or an
/// ancestor's `.cargo/config.toml`, or the user's in `cargo_home`) says
/// where builds go.
fn config_chooses(dir: &Path, cargo_home: Option<PathBuf>) -> bool {
    let places = dir.ancestors().map(|d| d.join(".cargo")).chain(cargo_home);
    places.into_iter().any(|place| {
        ["config.toml", "config"].iter().any(|name| {
            std::fs::read_to_string(place.join(name)).is_ok_and(|text| {
                text.lines().any(|line| {
                    let line = line.trim_start();
                    let line = line.strip_prefix("build.").unwrap_or(line);
                    line.starts_with("target-dir") || line.starts_with("build-dir")
                })
            })
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn argv(text: &str) -> Vec<String> {
        text.split_whitespace().map(str::to_string).collect()
    }

    fn env(pairs: &'static [(&'static str, &'static str)]) -> impl Fn(&str) -> Option<OsString> {
        move |key| {
            pairs
                .iter()
                .find(|(k, _)| *k == key)
                .map(|(_, v)| OsString::from(v))
        }
    }

    #[test]
    fn cargo_builds_share_one_directory_and_other_commands_are_left_alone() {
        let dir = tempfile::tempdir().unwrap();
        let shared = |cmd: &str| for_build_in(&argv(cmd), dir.path(), env(&[]));
        let default = crate::sources::cache_dir().join("cargo-build");
        for cmd in [
            "cargo build --release",
            "/usr/bin/cargo build",
            "cargo +stable build",
            "cargo --locked b --profile fast",
        ] {
            assert_eq!(shared(cmd), Some(default.clone()), "{cmd}");
        }
        for cmd in ["cargo run", "cargo test", "make", "uv sync", "cargo"] {
            assert_eq!(shared(cmd), None, "{cmd}");
        }
        assert_eq!(for_build_in(&[], dir.path(), env(&[])), None);
    }

    #[test]
    fn a_chosen_place_is_kept() {
        let dir = tempfile::tempdir().unwrap();
        let cmd = argv("cargo build");
        let with = |pairs| for_build_in(&cmd, dir.path(), env(pairs));
        assert_eq!(with(&[("CARGO_TARGET_DIR", "/t")]), None);
        assert_eq!(with(&[("CARGO_BUILD_BUILD_DIR", "/b")]), None);
        assert_eq!(with(&[("PEPPY_BUILD_DIR", "off")]), None);
        assert_eq!(
            with(&[("PEPPY_BUILD_DIR", "/shared")]),
            Some(PathBuf::from("/shared"))
        );
        // An empty variable is no choice.
        assert!(with(&[("CARGO_TARGET_DIR", "")]).is_some());

        let node = dir.path().join("nodes/cam");
        std::fs::create_dir_all(&node).unwrap();
        assert!(for_build_in(&cmd, &node, env(&[])).is_some());
        let home = tempfile::tempdir().unwrap();
        std::fs::write(
            home.path().join("config.toml"),
            "[build]\nbuild-dir = \"/b\"\n",
        )
        .unwrap();
        let in_home = |key: &str| (key == "CARGO_HOME").then(|| home.path().as_os_str().to_owned());
        assert_eq!(
            for_build_in(&cmd, &node, in_home),
            None,
            "the user's own cargo config"
        );
        std::fs::create_dir_all(dir.path().join(".cargo")).unwrap();
        std::fs::write(
            dir.path().join(".cargo/config.toml"),
            "[build]\ntarget-dir = \"/elsewhere\"\n",
        )
        .unwrap();
        assert_eq!(for_build_in(&cmd, &node, env(&[])), None);
    }
}
