//! `peppy-launch repo index DIR [--check]`: the index written, and every
//! kind of drift `--check` catches.

use std::path::Path;

use crate::support::{jump_lines, peppy_launch};

fn write(root: &Path, rel: &str, text: &str) {
    let p = root.join(rel);
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(p, text).unwrap();
}

fn node(name: &str, tag: &str) -> String {
    format!(
        r#"{{ peppy_schema: "node_v1", manifest: {{ name: "{name}", tag: "{tag}" }}, execution: {{ language: "rust", run_cmd: ["./{name}"] }} }}"#
    )
}

fn contract(name: &str, tag: &str) -> String {
    format!(
        r#"{{ peppy_schema: "contract/v1", manifest: {{ name: "{name}", tag: "{tag}" }}, interfaces: {{ topics: [{{ name: "frame", message_format: {{ w: "u32" }} }}] }} }}"#
    )
}

/// A repository of one node, one contract, one pairing (a kind peppy does
/// not read yet), one launcher and one fragment, with a hidden directory
/// and a JSON5 file that is no peppy document.
fn repository() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    write(root, "cam/peppy.json5", &node("cam", "v1"));
    write(root, "contracts/rgb.json5", &contract("rgb", "v1"));
    write(
        root,
        "robot/joint_link.json5",
        r#"{ peppy_schema: "pairing/v1", manifest: { name: "joint_link", tag: "v1" }, roles: ["leader", "follower"], topics: [] }"#,
    );
    write(
        root,
        "stacks/demo.json5",
        r#"{ peppy_schema: "launcher_v1", deployments: [] }"#,
    );
    write(
        root,
        "stacks/parts/arm.json5",
        r#"{ peppy_schema: "launcher_fragment/v1" }"#,
    );
    write(root, ".github/ci/peppy.json5", &node("ci_only", "v1"));
    write(root, "notes.json5", "{ hello: 1 }");
    dir
}

const WRITTEN: &str = r#"{
  peppy_schema: "repository/v1",
  nodes: {
    cam: {
      v1: {
        path: "cam/peppy.json5"
      }
    }
  },
  launchers: {
    demo: {
      path: "stacks/demo.json5"
    }
  },
  contracts: {
    rgb: {
      v1: {
        path: "contracts/rgb.json5"
      }
    }
  },
  pairings: {
    joint_link: {
      v1: {
        path: "robot/joint_link.json5"
      }
    }
  }
}
"#;

fn index_text(root: &Path) -> String {
    std::fs::read_to_string(root.join("peppy_repository.json5")).unwrap()
}

#[test]
fn repo_index_writes_the_index_and_check_then_passes() {
    let dir = repository();
    let root = dir.path();
    let run = peppy_launch(root, &["repo", "index", "."]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert_eq!(
        run.stdout,
        "wrote ./peppy_repository.json5 (1 node, 1 launcher, 1 contract, 1 pairing)\n"
    );
    assert_eq!(run.stderr, "");
    assert_eq!(index_text(root), WRITTEN);
    // No temporary file is left behind.
    let names: Vec<String> = std::fs::read_dir(root)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("tmp"))
        .collect();
    assert!(names.is_empty(), "{names:?}");

    // The same content again is not rewritten.
    let again = peppy_launch(root, &["repo", "index", "."]);
    assert_eq!(again.code, 0, "{}", again.stderr);
    assert!(
        again.stdout.contains(": up to date (1 node,"),
        "{}",
        again.stdout
    );

    // A comment and other formatting do not make the index drift.
    let reformatted = format!("// the index\n{}", WRITTEN.replace("  ", "    "));
    std::fs::write(root.join("peppy_repository.json5"), &reformatted).unwrap();
    let check = peppy_launch(root, &["repo", "index", "--check", "."]);
    assert_eq!(check.code, 0, "{}", check.stderr);
    assert_eq!(
        check.stdout,
        "./peppy_repository.json5: up to date (1 node, 1 launcher, 1 contract, 1 pairing)\n"
    );
    assert_eq!(index_text(root), reformatted, "--check writes nothing");

    // The written index is a valid document of its own kind.
    let valid = peppy_launch(
        root,
        &["validate", "--format", "json", "peppy_repository.json5"],
    );
    assert_eq!(valid.code, 0, "{}", valid.stderr);
    let v: serde_json::Value = serde_json::from_str(&valid.stdout).unwrap();
    assert_eq!(v["documents"][0]["kind"], "repository_index");
}

#[test]
fn check_reports_every_drift_and_writes_nothing() {
    let dir = repository();
    let root = dir.path();
    assert_eq!(peppy_launch(root, &["repo", "index", "."]).code, 0);
    // Moved: the node's directory is renamed.
    std::fs::rename(root.join("cam"), root.join("camera")).unwrap();
    // Unlisted: a new node.
    write(root, "lidar/peppy.json5", &node("lidar", "v1"));
    // Unmatched (another identity) and Unlisted: the contract's tag changes.
    write(root, "contracts/rgb.json5", &contract("rgb", "v2"));
    // Unmatched (missing): the pairing is deleted.
    std::fs::remove_file(root.join("robot/joint_link.json5")).unwrap();
    // Unmatched (another kind): the launcher becomes a fragment.
    write(
        root,
        "stacks/demo.json5",
        r#"{ peppy_schema: "launcher_fragment/v1" }"#,
    );

    let run = peppy_launch(root, &["repo", "index", "--check", "."]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert_eq!(run.stdout, "");
    let lines: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(
        lines,
        [
            "./peppy_repository.json5 is out of date: 6 drifts",
            "  Moved: node `cam:v1` is listed at `cam/peppy.json5` (line 6), declared in `camera/peppy.json5`",
            "  Unlisted: node `lidar:v1` is declared in `lidar/peppy.json5`, not listed",
            "  Unmatched: launcher `demo` is listed at `stacks/demo.json5` (line 12), which is a `launcher_fragment/v1` document (fragments are never listed)",
            "  Unmatched: contract `rgb:v1` is listed at `contracts/rgb.json5` (line 18), which declares `rgb:v2`",
            "  Unlisted: contract `rgb:v2` is declared in `contracts/rgb.json5`, not listed",
            "  Unmatched: pairing `joint_link:v1` is listed at `robot/joint_link.json5` (line 25), which does not exist",
            "Run `peppy-launch repo index .` and commit the result.",
        ]
    );
    assert_eq!(index_text(root), WRITTEN, "--check writes nothing");

    // Writing brings it back in line.
    assert_eq!(peppy_launch(root, &["repo", "index", "."]).code, 0);
    let check = peppy_launch(root, &["repo", "index", "--check", "."]);
    assert_eq!(check.code, 0, "{}", check.stderr);
}

#[test]
fn check_without_an_index_fails_and_says_so() {
    let dir = repository();
    let run = peppy_launch(dir.path(), &["repo", "index", "--check"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    let lines: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(lines[0], "./peppy_repository.json5 does not exist");
    assert!(
        lines.contains(&"  Unlisted: node `cam:v1` is declared in `cam/peppy.json5`, not listed"),
        "{}",
        run.stderr
    );
    assert_eq!(
        lines.last(),
        Some(&"Run `peppy-launch repo index .` and commit the result.")
    );
    assert!(!dir.path().join("peppy_repository.json5").exists());
}

#[test]
fn one_identity_claimed_by_two_files_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    write(root, "a/peppy.json5", &node("cam", "v1"));
    write(root, "b/peppy.json5", &node("cam", "v1"));
    for args in [
        &["repo", "index", "."][..],
        &["repo", "index", "--check", "."],
    ] {
        let run = peppy_launch(root, args);
        assert_eq!(run.code, 2, "{}", run.stderr);
        assert_eq!(
            jump_lines(&run.stderr),
            [
                "./b/peppy.json5: error: 2 node manifests claim `cam:v1`: a/peppy.json5, b/peppy.json5 (DuplicateIdentity)"
            ],
            "{}",
            run.stderr
        );
    }
    assert!(!root.join("peppy_repository.json5").exists());
}

#[test]
fn an_invalid_index_is_reported_where_it_is_wrong() {
    let dir = repository();
    let root = dir.path();
    write(
        root,
        "peppy_repository.json5",
        "{\n  peppy_schema: \"repository/v1\",\n  nodes: { cam: { v1: { path: \"./cam/peppy.json5\" } } },\n}\n",
    );
    let run = peppy_launch(root, &["repo", "index", "--check", "."]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    let lines = jump_lines(&run.stderr);
    assert_eq!(lines.len(), 1, "{}", run.stderr);
    assert!(
        lines[0].starts_with(
            "./peppy_repository.json5:3:31: error: `path` `./cam/peppy.json5` is not canonical: it has a `.` segment"
        ),
        "{}",
        lines[0]
    );

    let missing = peppy_launch(root, &["repo", "index", "no/such/dir"]);
    assert_eq!(missing.code, 2, "{}", missing.stderr);
    assert!(
        missing
            .stderr
            .contains("error: `no/such/dir` is not a directory (CannotRead)"),
        "{}",
        missing.stderr
    );
}
