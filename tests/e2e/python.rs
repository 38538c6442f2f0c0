//! Python and Rust nodes on one wire: every message shape of the `shapes`
//! fixture goes Rust -> Python -> Rust (decoded into Python dataclasses and
//! encoded again), with the fingerprints of both languages compared; and a
//! Python emitter whose format differs is dropped by a Rust consumer with
//! the warning two Rust nodes get.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use crate::nodes::{shapes, shapes_client};
use crate::support::{Hub, hub, namespace, start};

/// `peppy-build/tests/fixtures/<name>`'s Python package, written as the
/// top-level package `package` under `dir`.
fn python_package(fixture: &str, dir: &Path, package: &str) {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("peppy-build/tests/fixtures");
    let mut config = peppy_build::Config::new();
    config
        .manifest_dir(fixtures.join(fixture))
        .repositories_env(None);
    let generated = config.generate().expect("the fixture resolves");
    let files = peppy_build::python_package(&generated.check.resolved).expect("a package");
    for (path, text) in files {
        let path = dir.join(package).join(path);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }
}

/// A Python program on the peppy runtime package, with `dir` importable.
struct Python {
    child: Child,
    lines: mpsc::Receiver<String>,
}

impl Python {
    fn start(dir: &Path, script: &Path, args: &[&str]) -> Python {
        let runtime = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/peppy-runtime");
        let mut child = Command::new(peppy_launch::uv().expect("uv"))
            .args(["run", "--quiet", "--project"])
            .arg(&runtime)
            .arg("python")
            .arg(script)
            .args(args)
            .env("PYTHONPATH", dir)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("uv run");
        let stdout: ChildStdout = child.stdout.take().unwrap();
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Python { child, lines }
    }

    /// The next line it prints, within a bound that covers `uv`'s first
    /// environment set-up.
    fn line(&self) -> String {
        self.lines
            .recv_timeout(Duration::from_secs(300))
            .expect("a line from the python program")
    }
}

impl Drop for Python {
    fn drop(&mut self) {
        drop(self.child.stdin.take());
        for _ in 0..100 {
            if self.child.try_wait().ok().flatten().is_some() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The plan a standalone command line gives node `P`, as `peppy-launch
/// plan` gives a Python node's (the binding engine and the parameter
/// checker every node is planned by), written to `dir/<instance>.json`.
fn plan<P: peppy::codegen::NodeParameters>(dir: &Path, instance: &str, args: &[&str]) -> String {
    let model = peppy_schema::NodeModel::from_json(P::descriptor().model).expect("a model");
    let flags = ["plan", "--instance-id", instance]
        .iter()
        .chain(args)
        .map(|a| a.to_string())
        .collect();
    let config = peppy_runtime::startup_from_flags(&model, flags).expect("a plan");
    let path = dir.join(format!("{instance}.json"));
    std::fs::write(&path, serde_json::to_string(&config).unwrap()).unwrap();
    path.display().to_string()
}

async fn relay(hub: &Hub, ns: &str, upstream: &str) -> (Python, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    python_package("shapes", dir.path(), "shapes_gen");
    python_package("shapes_client", dir.path(), "client_gen");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/e2e/python_relay.py");
    let common = ["--namespace", ns, "--connect", &hub.endpoint];
    let bind = format!("shapes@{upstream}");
    let client = plan::<shapes_client::Parameters>(
        dir.path(),
        "py_client",
        &[&["--bind", bind.as_str()][..], &common].concat(),
    );
    let server = plan::<shapes::Parameters>(
        dir.path(),
        "shapes_py",
        &[&crate::params::SHAPES_ARGS[..], &common].concat(),
    );
    let python = Python::start(dir.path(), &script, &[&client, &server]);
    (python, dir)
}

/// Every fixture's Python package imports, every module of it: its
/// syntax, its codec layouts and its fingerprints (checked against the
/// canonical texts at import) are what the runtime accepts.
#[test]
fn every_fixture_python_package_imports() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("peppy-build/tests/fixtures");
    let dir = tempfile::tempdir().unwrap();
    let mut packages = Vec::new();
    for entry in std::fs::read_dir(&fixtures).unwrap() {
        let path = entry.unwrap().path();
        if path.join("peppy.json5").is_file() {
            let name = format!("gen_{}", path.file_name().unwrap().to_string_lossy());
            python_package(
                &path.file_name().unwrap().to_string_lossy(),
                dir.path(),
                &name,
            );
            packages.push(name);
        }
    }
    assert!(packages.len() >= 6, "{packages:?}");
    let script = dir.path().join("import_all.py");
    std::fs::write(
        &script,
        [
            "import importlib, pkgutil, sys",
            "count = 0",
            "for name in sys.argv[1:]:",
            "    package = importlib.import_module(name)",
            "    for info in pkgutil.walk_packages(package.__path__, name + '.'):",
            "        importlib.import_module(info.name)",
            "        count += 1",
            "print(count, flush=True)",
        ]
        .join("\n"),
    )
    .unwrap();
    let args: Vec<&str> = packages.iter().map(String::as_str).collect();
    let python = Python::start(dir.path(), &script, &args);
    let modules: usize = python.line().parse().expect("a module count");
    assert!(modules > 50, "only {modules} modules imported");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_message_shape_crosses_from_rust_through_python_and_back() {
    let hub = hub().await;
    let ns = namespace("python-shapes");
    let (_, server) =
        start::<shapes::Parameters>(&hub, &ns, "shapes_rs", &crate::params::SHAPES_ARGS).await;
    let (_, client) =
        start::<shapes_client::Parameters>(&hub, &ns, "client_rs", &["--bind", "shapes@shapes_py"])
            .await;
    let (python, _dir) = relay(&hub, &ns, "shapes_rs").await;
    let prints: serde_json::Value = serde_json::from_str(&python.line()).unwrap();
    assert_eq!(python.line(), "ready");

    // The same document gives the same fingerprints in both languages.
    use shapes::emitted_topics as e;
    for (name, rust) in [
        ("everything", e::everything::SPEC.format.fingerprint),
        ("nested", e::nested::SPEC.format.fingerprint),
        ("optionals", e::optionals::SPEC.format.fingerprint),
        ("keywords", e::keywords::SPEC.format.fingerprint),
        ("tick", e::tick::SPEC.format.fingerprint),
        ("video_stream", e::video_stream::SPEC.format.fingerprint),
    ] {
        assert_eq!(prints[name][0], rust, "{name}: consumed in python");
        assert_eq!(prints[name][1], rust, "{name}: emitted by python");
    }

    let sample = crate::roundtrip::Samples::new(1);
    let sender = tokio::spawn({
        let server = server.clone();
        async move {
            loop {
                let _ = sample.emit_all(&server).await;
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        }
    });
    sample.expect_all(&client, "shapes_py").await;
    sender.abort();
    drop(python);
    client.shutdown().await;
    server.shutdown().await;
}
