//! Remote sources (SPEC 6.2) through `peppy-launch check`: git at a commit,
//! a branch and a tag, an unknown ref, archives with a good and a bad hash
//! and one that tries to escape, and working offline from the cache. Local
//! repositories and `file://` URLs only.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::support::{Run, peppy_launch_with};

/// A node document that runs a shell command.
fn node_doc(name: &str) -> String {
    format!(
        r#"{{ peppy_schema: "node_v1", manifest: {{ name: "{name}", tag: "v1" }},
            execution: {{ language: "shell", run_cmd: ["sh", "-c", "echo {name}"] }} }}"#
    )
}

fn git(dir: &Path, args: &[&str]) -> String {
    let out = Command::new("git")
        .args([
            "-c",
            "user.name=peppy",
            "-c",
            "user.email=peppy@example.invalid",
        ])
        .args([
            "-c",
            "init.defaultBranch=main",
            "-c",
            "commit.gpgsign=false",
        ])
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "git {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}

/// A repository holding `nodes/cam` (first commit, tagged `v1`) and then
/// `nodes/cam2` too (second commit, on `main`). Returns the first commit.
fn repository(dir: &Path) -> String {
    std::fs::create_dir_all(dir.join("nodes/cam")).unwrap();
    std::fs::write(dir.join("nodes/cam/peppy.json5"), node_doc("cam")).unwrap();
    git(dir, &["init", "--quiet"]);
    git(dir, &["add", "."]);
    git(dir, &["commit", "--quiet", "-m", "cam"]);
    git(dir, &["tag", "v1"]);
    let first = git(dir, &["rev-parse", "HEAD"]);
    std::fs::create_dir_all(dir.join("nodes/cam2")).unwrap();
    std::fs::write(dir.join("nodes/cam2/peppy.json5"), node_doc("cam2")).unwrap();
    git(dir, &["add", "."]);
    git(dir, &["commit", "--quiet", "-m", "cam2"]);
    first
}

fn check(dir: &Path, cache: &Path, source: &str) -> Run {
    let text = format!(
        "{{ peppy_schema: \"launcher_v1\", deployments: [{{ source: {source}, instances: [{{ instance_id: \"a\" }}] }}] }}"
    );
    std::fs::write(dir.join("stack.json5"), text).unwrap();
    peppy_launch_with(
        dir,
        &["check", "stack.json5"],
        &[("PEPPY_CACHE_DIR", cache)],
    )
}

#[test]
fn git_sources_at_a_commit_a_branch_and_a_tag() {
    let tmp = tempfile::tempdir().unwrap();
    let (repo, work, cache) = (
        tmp.path().join("repo"),
        tmp.path().join("work"),
        tmp.path().join("cache"),
    );
    std::fs::create_dir_all(&repo).unwrap();
    std::fs::create_dir_all(&work).unwrap();
    let first = repository(&repo);
    let url = format!("file://{}", repo.display());

    // A full commit id pins exactly: cam2 does not exist there yet.
    let pinned = check(
        &work,
        &cache,
        &format!("{{ repo: \"{url}\", path: \"nodes/cam\", ref: \"{first}\" }}"),
    );
    assert_eq!(pinned.code, 0, "{}{}", pinned.stdout, pinned.stderr);
    assert!(pinned.stdout.contains("cam:v1"), "{}", pinned.stdout);
    assert!(
        pinned.stdout.contains(&first),
        "the checkout is named by its commit: {}",
        pinned.stdout
    );
    let missing = check(
        &work,
        &cache,
        &format!("{{ repo: \"{url}\", path: \"nodes/cam2\", ref: \"{first}\" }}"),
    );
    assert_eq!(missing.code, 2);
    assert!(
        missing.stderr.contains("has no `nodes/cam2`"),
        "{}",
        missing.stderr
    );

    // A branch is resolved (and said); a tag too.
    let head = git(&repo, &["rev-parse", "main"]);
    let branch = check(
        &work,
        &cache,
        &format!("{{ repo: \"{url}\", path: \"nodes/cam2\", ref: \"main\" }}"),
    );
    assert_eq!(branch.code, 0, "{}", branch.stderr);
    assert!(
        branch.stderr.contains(&format!("`main` is commit {head}")),
        "{}",
        branch.stderr
    );
    let tag = check(
        &work,
        &cache,
        &format!("{{ repo: \"{url}\", path: \"nodes/cam\", ref: \"v1\" }}"),
    );
    assert_eq!(tag.code, 0, "{}", tag.stderr);
    assert!(
        tag.stderr.contains(&format!("`v1` is commit {first}")),
        "{}",
        tag.stderr
    );

    // An unknown ref is a located error that lists what there is.
    let unknown = check(
        &work,
        &cache,
        &format!("{{ repo: \"{url}\", path: \"nodes/cam\", ref: \"nope\" }}"),
    );
    assert_eq!(unknown.code, 2);
    assert!(
        unknown
            .stderr
            .contains("`nope` is not a branch, tag or commit"),
        "{}",
        unknown.stderr
    );
    assert!(
        unknown.stderr.contains("`main`") && unknown.stderr.contains("`v1`"),
        "{}",
        unknown.stderr
    );
    assert!(
        unknown.stderr.contains("stack.json5:1:"),
        "located: {}",
        unknown.stderr
    );

    // Offline: the repository is gone, the cache still serves the branch.
    std::fs::remove_dir_all(&repo).unwrap();
    let offline = check(
        &work,
        &cache,
        &format!("{{ repo: \"{url}\", path: \"nodes/cam2\", ref: \"main\" }}"),
    );
    assert_eq!(offline.code, 0, "{}", offline.stderr);
    assert!(
        offline.stderr.contains("using its cached copy"),
        "{}",
        offline.stderr
    );
}

fn sha256(path: &Path) -> String {
    let out = Command::new("sha256sum").arg(path).output().unwrap();
    String::from_utf8(out.stdout)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .to_string()
}

/// `files` (path, text) as a `.tar.gz` written by Python's tarfile, which
/// (unlike tar(1)) writes any path it is given.
fn archive(path: &Path, files: &[(&str, &str)]) -> PathBuf {
    let script = r#"
import io, sys, tarfile, json
files = json.loads(sys.argv[2])
with tarfile.open(sys.argv[1], "w:gz") as t:
    for name, text in files:
        data = text.encode()
        info = tarfile.TarInfo(name)
        info.size = len(data)
        t.addfile(info, io.BytesIO(data))
"#;
    let files = serde_json::to_string(files).unwrap();
    let status = Command::new("python3")
        .args(["-c", script])
        .arg(path)
        .arg(files)
        .status()
        .unwrap();
    assert!(status.success());
    path.to_path_buf()
}

#[test]
fn archive_sources_are_checked_before_they_are_unpacked() {
    let tmp = tempfile::tempdir().unwrap();
    let (work, cache) = (tmp.path().join("work"), tmp.path().join("cache"));
    std::fs::create_dir_all(&work).unwrap();
    let doc = node_doc("packed");
    let good = archive(
        &tmp.path().join("packed.tar.gz"),
        &[("packed-1.0/peppy.json5", &doc)],
    );
    let hash = sha256(&good);
    let url = format!("file://{}", good.display());

    let ok = check(
        &work,
        &cache,
        &format!("{{ url: \"{url}\", sha256: \"{hash}\" }}"),
    );
    assert_eq!(ok.code, 0, "{}", ok.stderr);
    assert!(ok.stdout.contains("packed:v1"), "{}", ok.stdout);

    let wrong = "0".repeat(64);
    let bad = check(
        &work,
        &cache,
        &format!("{{ url: \"{url}\", sha256: \"{wrong}\" }}"),
    );
    assert_eq!(bad.code, 2);
    assert!(
        bad.stderr.contains(&format!(
            "has sha256 {hash}, but the launcher expects {wrong}"
        )),
        "{}",
        bad.stderr
    );
    assert!(
        !cache.join("archives").join(&wrong).exists(),
        "nothing unpacked"
    );

    // Offline from the cache: the file is gone, the hash names the copy.
    std::fs::remove_file(&good).unwrap();
    let cached = check(
        &work,
        &cache,
        &format!("{{ url: \"{url}\", sha256: \"{hash}\" }}"),
    );
    assert_eq!(cached.code, 0, "{}", cached.stderr);

    let evil = archive(
        &tmp.path().join("evil.tar.gz"),
        &[("peppy.json5", &doc), ("../../escaped.txt", "gotcha")],
    );
    let evil_hash = sha256(&evil);
    let refused = check(
        &work,
        &cache,
        &format!(
            "{{ url: \"file://{}\", sha256: \"{evil_hash}\" }}",
            evil.display()
        ),
    );
    assert_eq!(refused.code, 2);
    assert!(
        refused.stderr.contains("would land outside"),
        "{}",
        refused.stderr
    );
    assert!(!tmp.path().join("escaped.txt").exists());
    assert!(!cache.join("escaped.txt").exists());
    assert!(!cache.join("archives").join(&evil_hash).exists());
}
