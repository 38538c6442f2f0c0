//! Bindings mean the same to a Python node as to a Rust one, because both
//! take their slots from one binding engine: a launch's plan, or, started
//! by hand, the plan of their command line (a Rust node's own flag parser;
//! `peppy-launch plan` for a Python node). A free-form key, an ambiguous
//! key and a dead key, under `up` and standalone.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::support::{COMMAND_BOUND, example_binary, peppy_launch, root, wait_bounded};

/// A finished command's exit code, stdout and stderr.
struct Ended {
    code: i32,
    stdout: String,
    stderr: String,
}

fn finish(mut command: Command, what: &str) -> Ended {
    let child = command
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .env("NO_COLOR", "1")
        .env_remove("PEPPY_RUNTIME_CONFIG")
        .env("PEPPY_LAUNCH", env!("CARGO_BIN_EXE_peppy-launch"))
        .spawn()
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    let out = wait_bounded(child, COMMAND_BOUND, what);
    Ended {
        code: out.status.code().expect("exited, not killed"),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// The binding errors of a report, one per line, with their help lines: the
/// part every front end words the same (the prefix before them is the
/// program's own, `peppy-launch:` or `error:`).
fn binding_errors(stderr: &str) -> Vec<String> {
    stderr
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with("- ") || l.starts_with("help:"))
        .map(String::from)
        .collect()
}

/// A Python node in `dir/name` whose setup prints its instance id and
/// slots as JSON and stops, with `slots` as its `depends_on`.
fn python_node(dir: &Path, name: &str, depends_on: serde_json::Value) -> PathBuf {
    let node = dir.join(name);
    std::fs::create_dir_all(&node).unwrap();
    let doc = serde_json::json!({
        "peppy_schema": "node_v1",
        "manifest": { "name": name, "tag": "v1", "depends_on": depends_on },
        "execution": { "language": "python", "run_cmd": ["python3", "main.py"] },
    });
    std::fs::write(node.join("peppy.json5"), doc.to_string()).unwrap();
    std::fs::write(
        node.join("main.py"),
        "import json\n\
         from peppygen import NodeBuilder\n\n\
         async def setup(params, node_runner):\n\
         \x20   slots = [s.to_json() for s in node_runner.slots]\n\
         \x20   print(json.dumps({'instance_id': node_runner.instance_id, 'slots': slots}), flush=True)\n\
         \x20   node_runner.stop()\n\n\
         NodeBuilder().run(setup)\n",
    )
    .unwrap();
    let synced = peppy_launch(dir, &["sync", node.to_str().unwrap()]);
    assert_eq!(synced.code, 0, "{}", synced.stderr);
    node
}

/// Runs the Python node in `node` by hand with `args`.
fn run_python(node: &Path, args: &[&str]) -> Ended {
    let mut command = Command::new(peppy_launch::uv().expect("uv"));
    command
        .args(["run", "--quiet", "--project"])
        .arg(root().join("python/peppy-runtime"))
        .args(["python", "main.py"])
        .args(args)
        .current_dir(node)
        .env("PYTHONPATH", node);
    finish(command, &format!("python node {args:?}"))
}

const ARGS: [&str; 8] = [
    "--instance-id",
    "c1",
    "--listen",
    "tcp/127.0.0.1:0",
    "--bind",
    "left_cam@rs_a",
    "--bind",
    "zed@zed_1",
];

/// Standalone: a Python node started by hand gets exactly the plan, or
/// exactly the refusal, that the engine gives the same command line.
#[test]
fn python_nodes_started_by_hand_bind_as_the_engine_says() {
    let dir = tempfile::tempdir().unwrap();
    let repos = format!(
        "[{{ type: \"fs\", path: {:?} }}]",
        root().join("examples").display().to_string()
    );
    std::fs::write(dir.path().join("peppy_repositories.json5"), repos).unwrap();
    let camera = |link_id: &str, from_any: bool| serde_json::json!({ "name": "depth_camera", "tag": "v1", "link_id": link_id, "from_any": from_any });
    let arms = serde_json::json!({ "name": "robot_arm", "tag": "v1", "link_id": "arms", "from_any": true });
    // `zed` is no slot: free-form. One from_any slot takes it; two that
    // want different producers make it ambiguous; none makes it dead.
    let cases = [
        (
            "solo",
            serde_json::json!({ "interfaces": [camera("left_cam", false), camera("cams", true)] }),
            None,
        ),
        (
            "mixer",
            serde_json::json!({ "interfaces": [camera("left_cam", false), camera("cams", true)], "nodes": [arms] }),
            Some("--bind arms@zed_1 or --bind cams@zed_1"),
        ),
        (
            "single",
            serde_json::json!({ "interfaces": [camera("left_cam", false)] }),
            Some("binding `zed` on instance `c1` matches no slot"),
        ),
    ];
    for (name, depends_on, refusal) in cases {
        let node = python_node(dir.path(), name, depends_on);
        let planned = peppy_launch(
            dir.path(),
            &[&["plan", node.to_str().unwrap(), "--"][..], &ARGS].concat(),
        );
        let python = run_python(&node, &ARGS);
        match refusal {
            None => {
                assert_eq!(planned.code, 0, "{}", planned.stderr);
                assert_eq!(python.code, 0, "{name}: {}", python.stderr);
                let plan: serde_json::Value = serde_json::from_str(&planned.stdout).unwrap();
                let ran: serde_json::Value =
                    serde_json::from_str(python.stdout.lines().last().unwrap_or_default())
                        .unwrap_or_else(|e| panic!("{e}: {}", python.stdout));
                assert_eq!(ran["slots"], plan["slots"], "{name}");
                assert_eq!(
                    plan["slots"][1]["filter"],
                    serde_json::json!({ "kind": "only_from", "producers": ["zed_1"] }),
                    "the free-form key joined the from_any slot"
                );
            }
            Some(words) => {
                assert_eq!((planned.code, python.code != 0), (2, true), "{name}");
                let errors = binding_errors(&planned.stderr);
                assert!(
                    errors.iter().any(|e| e.contains(words))
                        && errors[0].contains("(DeadBindingKey)"),
                    "{name}: {}",
                    planned.stderr
                );
                assert_eq!(binding_errors(&python.stderr), errors, "{name}");
            }
        }
    }
}

/// A Rust node's binary and its Python twin, started by hand with a dead
/// key, refuse it in the same words; a launcher binding either with it is
/// refused before anything starts, in the same words.
#[test]
fn a_rust_node_and_its_python_twin_refuse_a_dead_key_alike() {
    let arm_controller = example_binary("arm_controller");
    let args = [
        "--instance-id",
        "c1",
        "--listen",
        "tcp/127.0.0.1:0",
        "--bind",
        "robot_arm@arm",
        "--bind",
        "nope@arm",
    ];
    let rust = finish(
        {
            let mut c = Command::new(&arm_controller);
            c.args(args);
            c
        },
        "arm_controller",
    );
    let twin = root().join("examples/nodes/py_arm_controller");
    let synced = peppy_launch(&root(), &["sync", twin.to_str().unwrap()]);
    assert_eq!(synced.code, 0, "{}", synced.stderr);
    let python = finish(
        {
            let mut c = Command::new(peppy_launch::uv().expect("uv"));
            c.args(["run", "--quiet", "--project"])
                .arg(&twin)
                .arg("py_arm_controller")
                .args(args);
            c
        },
        "py_arm_controller",
    );
    let same = |e: &str| e.replace("py_arm_controller", "arm_controller");
    let rust_errors = binding_errors(&rust.stderr);
    assert!(
        rust.code != 0 && rust_errors.iter().any(|e| e.contains("binding `nope`")),
        "{}",
        rust.stderr
    );
    assert_ne!(python.code, 0);
    assert_eq!(
        binding_errors(&python.stderr)
            .iter()
            .map(|e| same(e))
            .collect::<Vec<_>>(),
        rust_errors
    );

    // Under `up`, the launcher decides, for both alike.
    let dir = tempfile::tempdir().unwrap();
    let launcher = dir.path().join("stack.json5");
    let consumer = |node: &str, id: &str| {
        serde_json::json!({
            "source": { "local": root().join("examples/nodes").join(node) },
            "instances": [{ "instance_id": id, "bindings": { "robot_arm": "arm", "nope": "arm" } }],
        })
    };
    let text = serde_json::json!({
        "peppy_schema": "launcher_v1",
        "deployments": [
            { "source": { "local": root().join("examples/nodes/robot_arm") }, "instances": [{ "instance_id": "arm" }] },
            consumer("arm_controller", "rust_c"),
            consumer("py_arm_controller", "py_c"),
        ],
    });
    std::fs::write(&launcher, text.to_string()).unwrap();
    let up = peppy_launch(dir.path(), &["up", launcher.to_str().unwrap()]);
    assert_eq!(up.code, 2, "{}", up.stderr);
    assert!(
        up.stderr.contains("nothing was built or started"),
        "{}",
        up.stderr
    );
    // The jump lines (`file:line:col: error: ...`), without their columns.
    let refused: Vec<&str> = up
        .stderr
        .lines()
        .filter(|l| l.contains("(DeadBindingKey)"))
        .filter_map(|l| l.split_once(": error: ").map(|(_, e)| e))
        .collect();
    assert_eq!(refused.len(), 2, "one refusal per consumer:\n{}", up.stderr);
    assert_eq!(
        refused[0].replace("rust_c", "X"),
        refused[1]
            .replace("py_c", "X")
            .replace("py_arm_controller", "arm_controller"),
        "{}",
        up.stderr
    );
}
