//! `node init`: a new node, in either toolchain, passes its own tests as
//! written, with nothing set up by hand.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::support::{COMMAND_BOUND, peppy_launch, root, wait_bounded};

/// A node's first build compiles the runtime for it; that takes a while on
/// two cores, once.
const FIRST_BUILD_BOUND: Duration = Duration::from_secs(900);

fn init(dir: &Path, args: &[&str]) -> PathBuf {
    let mut all = vec!["node", "init"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--to-dir", dir.to_str().unwrap()]);
    let run = peppy_launch(dir, &all);
    assert_eq!(run.code, 0, "node init: {}", run.stderr);
    assert!(run.stdout.contains("created node"), "{}", run.stdout);
    dir.join(args[0])
}

fn passes(mut command: Command, what: &str, bound: Duration) -> String {
    let child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    let out = wait_bounded(child, bound, what);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{what} failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// `node init --toolchain cargo NAME && cd NAME && cargo test`: the node
/// builds against the `.peppy/libs` crates `init` wrote, and its harness
/// test sees it greet and count a mock peer's greeting.
#[test]
fn a_new_cargo_node_passes_its_harness_test() {
    let dir = tempfile::tempdir().unwrap();
    let node = init(dir.path(), &["hello-world", "--toolchain", "cargo"]);
    for file in [
        "peppy.json5",
        "Cargo.toml",
        "Cargo.lock",
        ".gitignore",
        "src/lib.rs",
        "src/main.rs",
        "tests/harness.rs",
        ".peppy/libs/peppygen/Cargo.toml",
        ".peppy/libs/peppylib/Cargo.toml",
    ] {
        assert!(node.join(file).is_file(), "{file}");
    }
    let mut test = Command::new(env!("CARGO"));
    // Every core: the build holds the shared target directory's lock, and
    // the tests beside this one wait for it to build their own nodes. With
    // one job the CLI tests took 164 s warm on two cores; with both, 86 s.
    test.args(["test", "--quiet"]).current_dir(&node);
    // The workspace's target directory: the runtime's dependencies are
    // built once for the workspace and the node alike (the node's
    // Cargo.lock is peppy's).
    test.env(
        "CARGO_TARGET_DIR",
        std::env::var_os("CARGO_TARGET_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| root().join("target")),
    );
    let stdout = passes(test, "cargo test of the new node", FIRST_BUILD_BOUND);
    assert!(
        stdout.contains("greets_and_counts_the_greetings_it_hears ... ok")
            || stdout.contains("1 passed"),
        "{stdout}"
    );
}

/// `node init --toolchain uv NAME && cd NAME && uv run --group dev pytest`.
#[test]
fn a_new_uv_node_passes_its_harness_test() {
    let dir = tempfile::tempdir().unwrap();
    let node = init(dir.path(), &["hello_py", "--toolchain", "uv"]);
    for file in [
        "peppy.json5",
        "pyproject.toml",
        ".gitignore",
        "src/hello_py/__main__.py",
        "tests/test_harness.py",
        ".peppy/libs/peppygen/pyproject.toml",
        ".peppy/libs/peppylib/pyproject.toml",
    ] {
        assert!(node.join(file).is_file(), "{file}");
    }
    let mut test = Command::new(peppy_launch::uv().expect("uv"));
    test.args([
        "run",
        "--group",
        "dev",
        "pytest",
        "-q",
        "-p",
        "no:cacheprovider",
    ])
    .current_dir(&node)
    // The harness finds the `peppy-launch` that synced the node.
    .env_remove("PEPPY_LAUNCH");
    let stdout = passes(test, "pytest of the new node", COMMAND_BOUND);
    assert!(stdout.contains("1 passed"), "{stdout}");
}

/// `init` writes only new folders: a second `init` of the same name, or a
/// name no crate can have, changes nothing and says why.
#[test]
fn init_refuses_to_overwrite_or_to_take_a_bad_name() {
    let dir = tempfile::tempdir().unwrap();
    let node = dir.path().join("cam");
    std::fs::create_dir(&node).unwrap();
    std::fs::write(node.join("peppy.json5"), "// mine\n").unwrap();
    let to_dir = dir.path().to_str().unwrap();
    let again = peppy_launch(dir.path(), &["node", "init", "cam", "--to-dir", to_dir]);
    assert_eq!(again.code, 2, "{}", again.stderr);
    assert!(again.stderr.contains("already exists"), "{}", again.stderr);
    assert_eq!(
        std::fs::read_to_string(node.join("peppy.json5")).unwrap(),
        "// mine\n"
    );

    let bad = peppy_launch(dir.path(), &["node", "init", "9lives", "--to-dir", to_dir]);
    assert_eq!(bad.code, 2, "{}", bad.stderr);
    assert!(
        bad.stderr.contains("must start with a letter"),
        "{}",
        bad.stderr
    );
    assert!(!dir.path().join("9lives").exists());
}

/// A node that declares `execution.container` runs natively where no
/// container runtime is used: built by its definition's `%post` (`uv
/// sync`), started by its `%runscript`, with a line saying so. Two such
/// greeters in one launch hear each other.
#[test]
fn a_container_node_runs_natively_from_its_definition() {
    let dir = tempfile::tempdir().unwrap();
    let node = init(dir.path(), &["boxed", "--toolchain", "uv"]);
    let doc = std::fs::read_to_string(node.join("peppy.json5")).unwrap();
    let execution = doc.find("  execution: {").expect("an execution section");
    let doc = format!(
        "{}  execution: {{\n    language: \"python\",\n    container: {{ def_file: \"apptainer.def\" }},\n    parameters: {{ period_ms: {{ $type: \"u32\", $default: 100 }} }},\n  }},\n}}\n",
        &doc[..execution]
    );
    std::fs::write(node.join("peppy.json5"), doc).unwrap();
    std::fs::write(
        node.join("apptainer.def"),
        "Bootstrap: docker\nFrom: peppybot/python-uv-base:latest\n\n%files\n    . /opt/boxed\n\n%post\n    set -eux\n    export UV_PYTHON_INSTALL_DIR=/opt/uv-python\n    apt-get update && apt-get install -y --no-install-recommends ffmpeg\n    cd /opt/boxed\n    uv python install\n    uv sync --no-editable\n\n%runscript\n    cd /opt/boxed\n    exec ./.venv/bin/python -m boxed \"$@\"\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("stack.json5"),
        r#"{ peppy_schema: "launcher/v1", deployments: [{
              source: { local: "boxed" },
              instances: [
                { instance_id: "a", links: { peers: ["b"] } },
                { instance_id: "b", links: { peers: ["a"] } },
              ],
            }] }"#,
    )
    .unwrap();
    let output = dir.path().join("up.log");
    let child = crate::support::peppy_launch_command(&[])
        .args(["up", "stack.json5"])
        .current_dir(dir.path())
        .env("NO_COLOR", "1")
        .env("PEPPY_CONTAINERS", "native")
        .env_remove("PEPPY_REPOSITORIES")
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(dir.path().join("up.out")).unwrap())
        .stderr(std::fs::File::create(&output).unwrap())
        .spawn()
        .unwrap();
    let deadline = std::time::Instant::now() + COMMAND_BOUND;
    let log = || std::fs::read_to_string(&output).unwrap_or_default();
    while !(log().contains("[a] b: hello from b") && log().contains("[b] a: hello from a")) {
        assert!(
            std::time::Instant::now() < deadline,
            "the greeters did not hear each other:\n{}",
            log()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    // SAFETY: kill only sends a signal to the test's own child.
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGINT);
    }
    let ended = wait_bounded(child, COMMAND_BOUND, "up of the container nodes");
    let log = log();
    assert!(ended.status.success(), "{log}");
    assert!(
        log.contains("`boxed:v1` declares a container; no container runtime is used here, so it runs natively: build `uv sync --no-editable`, run `./.venv/bin/python -m boxed`"),
        "{log}"
    );
    assert!(
        log.contains("apt-get update"),
        "the skipped set-up is named: {log}"
    );
}
