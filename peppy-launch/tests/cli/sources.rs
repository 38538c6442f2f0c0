//! Remote sources (SPEC 6.2) through `peppy-launch check`: git at a commit,
//! a branch and a tag, an unknown ref, archives with a good and a bad hash
//! and one that tries to escape, and working offline from the cache. Local
//! repositories, `file://` URLs, and `http://` from a server on loopback in
//! the test itself.

use std::io::{BufRead as _, BufReader, Write as _};
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

pub(crate) fn git(dir: &Path, args: &[&str]) -> String {
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

/// An HTTP server on a loopback port of its own for the rest of the test
/// process: `/<name>` answers that file's bytes, `/moved/<name>` redirects
/// there, anything else is 404. Returns its base URL.
fn http_server(files: Vec<(&'static str, Vec<u8>)>) -> String {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            let mut reader = BufReader::new(stream.try_clone().unwrap());
            let mut request = String::new();
            if reader.read_line(&mut request).is_err() {
                continue;
            }
            loop {
                let mut header = String::new();
                match reader.read_line(&mut header) {
                    Ok(0) | Err(_) => break,
                    Ok(_) if header == "\r\n" => break,
                    Ok(_) => {}
                }
            }
            let path = request.split_whitespace().nth(1).unwrap_or("/");
            let (status, extra, body): (&str, String, &[u8]) =
                if let Some(name) = path.strip_prefix("/moved/") {
                    ("302 Found", format!("Location: /{name}\r\n"), b"")
                } else if let Some((_, bytes)) = files
                    .iter()
                    .find(|(name, _)| path.strip_prefix('/') == Some(*name))
                {
                    ("200 OK", String::new(), bytes)
                } else {
                    ("404 Not Found", String::new(), b"")
                };
            let head = format!(
                "HTTP/1.1 {status}\r\n{extra}Content-Length: {}\r\nConnection: close\r\n\r\n",
                body.len()
            );
            let _ = stream.write_all(head.as_bytes());
            let _ = stream.write_all(body);
        }
    });
    base
}

/// Over HTTP the launcher follows a redirect to the bytes, refuses them
/// when they do not hash to the launcher's sha256 (naming both, leaving
/// nothing in the cache), unpacks them when they do, and reports a missing
/// file with its status.
#[test]
fn archive_sources_over_http() {
    let tmp = tempfile::tempdir().unwrap();
    let (work, cache) = (tmp.path().join("work"), tmp.path().join("cache"));
    std::fs::create_dir_all(&work).unwrap();
    let good = archive(
        &tmp.path().join("packed.tar.gz"),
        &[("packed-1.0/peppy.json5", &node_doc("packed"))],
    );
    let hash = sha256(&good);
    let base = http_server(vec![("packed.tar.gz", std::fs::read(&good).unwrap())]);
    let url = format!("{base}/moved/packed.tar.gz");

    let wrong = "f".repeat(64);
    let bad = check(
        &work,
        &cache,
        &format!("{{ url: \"{url}\", sha256: \"{wrong}\" }}"),
    );
    assert_eq!(bad.code, 2, "{}", bad.stderr);
    assert!(
        bad.stderr.contains(&format!(
            "{url} has sha256 {hash}, but the launcher expects {wrong}; refusing to unpack it"
        )),
        "{}",
        bad.stderr
    );
    let left: Vec<_> = std::fs::read_dir(cache.join("archives"))
        .map(|entries| entries.map(|e| e.unwrap().file_name()).collect())
        .unwrap_or_default();
    assert!(left.is_empty(), "nothing kept: {left:?}");

    let ok = check(
        &work,
        &cache,
        &format!("{{ url: \"{url}\", sha256: \"{hash}\" }}"),
    );
    assert_eq!(ok.code, 0, "{}", ok.stderr);
    assert!(ok.stdout.contains("packed:v1"), "{}", ok.stdout);
    assert!(cache.join("archives").join(&hash).is_dir());

    let missing = check(
        &work,
        &cache,
        &format!("{{ url: \"{base}/gone.tar.gz\", sha256: \"{wrong}\" }}"),
    );
    assert_eq!(missing.code, 2, "{}", missing.stderr);
    assert!(
        missing
            .stderr
            .contains(&format!("cannot download {base}/gone.tar.gz"))
            && missing.stderr.contains("404"),
        "{}",
        missing.stderr
    );
}
