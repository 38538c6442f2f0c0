//! The peers peppy is measured against beside raw Zenoh, set up by the
//! benchmark itself: dora-rs (its CLI from PyPI, its Rust node API from
//! crates.io, both pinned to [`DORA_VERSION`]), the hand-off floor
//! (an iceoryx2 ping-pong, [`ICEORYX2_VERSION`]), and peppy's own Python
//! runtime (the source as a Python node, `peppy-bench/python`). Their nodes live in
//! `peppy-bench/peers`, a cargo workspace of its own that peppy's CI
//! never builds. What cannot be set up is said in one line, and its rows
//! are left out.

use std::collections::HashMap;
use std::ffi::OsString;
use std::io::{BufRead, BufReader, Write};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use crate::launch::target;
use crate::procs::Proc;
use crate::roles::Res;

/// The dora-rs release measured: the CLI (`dora-rs-cli` on PyPI) and the
/// node API (`dora-node-api` on crates.io, pinned in
/// `peppy-bench/peers/dora/Cargo.toml`) must match.
pub(crate) const DORA_VERSION: &str = "1.1.0";

/// The iceoryx2 release of the hand-off floor (pinned in
/// `peppy-bench/peers/iceoryx2/Cargo.toml`).
pub(crate) const ICEORYX2_VERSION: &str = "0.10.0";

/// dora-rs, installed and built.
pub(crate) struct Dora {
    /// The `dora` command.
    cli: PathBuf,
    /// What `dora` needs in its environment (a `pip --target` install
    /// needs `PYTHONPATH`).
    env: Vec<(OsString, OsString)>,
    /// The node binaries.
    source: PathBuf,
    sink: PathBuf,
}

/// The peers that could be set up, each set up once per benchmark run.
pub(crate) struct Peers {
    pub(crate) dora: Option<Dora>,
    /// The floor's binary.
    pub(crate) floor: Option<PathBuf>,
    /// The source as a Python node.
    pub(crate) python: Option<PythonSource>,
}

/// The benchmark's source as a Python node, ready to start.
pub(crate) struct PythonSource {
    /// The `uv` that runs it on peppy's Python runtime.
    pub(crate) uv: PathBuf,
    /// The directory holding its generated package, `bench_source_gen`.
    pub(crate) packages: PathBuf,
}

impl PythonSource {
    /// The command that starts it with the runtime config at `plan`.
    pub(crate) fn command(&self, plan: &Path) -> Command {
        let root = crate::workspace();
        let mut command = Command::new(&self.uv);
        command
            .args(["run", "--quiet", "--project"])
            .arg(root.join("python/peppy-runtime"))
            .arg("python")
            .arg(root.join("peppy-bench/python/bench_source.py"))
            .arg(plan)
            .env("PYTHONPATH", &self.packages);
        command
    }
}

static PEERS: OnceLock<Peers> = OnceLock::new();

/// The peers `--peers` chose.
static CHOSEN: OnceLock<Vec<Peer>> = OnceLock::new();

/// A peer `--peers` can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Peer {
    /// dora-rs.
    Dora,
    /// The hand-off floor (iceoryx2).
    Floor,
    /// The source as a Python node (peppy's Python runtime).
    Python,
    /// None of them.
    None,
}

/// Sets which peers are set up and measured (`--peers`).
pub(crate) fn choose(peers: &[Peer]) {
    let _ = CHOSEN.set(peers.to_vec());
}

fn chosen(peer: Peer) -> bool {
    CHOSEN.get().is_none_or(|c| c.contains(&peer))
}

/// The peers, set up on first use (printing one line for each that
/// cannot be, whose rows are then left out).
pub(crate) fn peers() -> &'static Peers {
    PEERS.get_or_init(|| Peers {
        dora: set_up(Peer::Dora, &format!("dora-rs {DORA_VERSION}"), set_up_dora),
        floor: set_up(
            Peer::Floor,
            &format!("hand-off floor (iceoryx2 {ICEORYX2_VERSION})"),
            || build("peppy-bench-iceoryx2", &["peppy-bench-iceoryx2"]).map(|mut b| b.remove(0)),
        ),
        python: set_up(Peer::Python, "Python source", set_up_python),
    })
}

/// `peer` set up by `how`, if `--peers` chose it; one line naming `what`
/// when it is left out or cannot be set up.
fn set_up<T>(peer: Peer, what: &str, how: impl FnOnce() -> Res<T>) -> Option<T> {
    if !chosen(peer) {
        eprintln!("peppy-bench: {what} rows left out (--peers)");
        return None;
    }
    how()
        .map_err(|e| eprintln!("peppy-bench: {what} rows skipped: {e}"))
        .ok()
}

/// Generates the source node's Python package and makes the runtime's
/// environment (`uv sync` of `python/peppy-runtime`, once).
fn set_up_python() -> Res<PythonSource> {
    let mut config = peppy_build::Config::new();
    config
        .manifest_dir(crate::workspace().join("peppy-bench/nodes/source"))
        .repositories_env(None);
    let generated = config.generate().map_err(|e| e.to_string())?;
    let files =
        peppy_build::python_package(&generated.check.resolved).map_err(|e| e.to_string())?;
    let packages = peers_dir().join("python-source");
    for (path, text) in files {
        let path = packages.join("bench_source_gen").join(path);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        std::fs::write(path, text)?;
    }
    let uv = uv();
    let synced = Command::new(&uv)
        .args(["sync", "--quiet", "--project"])
        .arg(crate::workspace().join("python/peppy-runtime"))
        .output()
        .map_err(|e| format!("cannot run {}: {e}", uv.display()))?;
    if !synced.status.success() {
        return Err(format!("uv sync: {}", last_line(&synced.stderr)).into());
    }
    Ok(PythonSource { uv, packages })
}

/// The `uv` to use: `UV`, else `uv` on `PATH`, else the one peppy-launch
/// installed for its Python nodes (under `~/.cache/peppy/tools`). Not
/// `peppy_launch::uv`, which also installs one: the benchmark does not
/// link the launcher (its release build would build all the launcher's
/// dependencies), and a machine that ran `up` of a Python node has it.
fn uv() -> PathBuf {
    if let Some(uv) = std::env::var_os("UV") {
        return PathBuf::from(uv);
    }
    let on_path = std::env::var_os("PATH")
        .is_some_and(|path| std::env::split_paths(&path).any(|dir| dir.join("uv").is_file()));
    if on_path {
        return PathBuf::from("uv");
    }
    let tools = std::env::var_os("HOME")
        .map(|home| PathBuf::from(home).join(".cache/peppy/tools"))
        .and_then(|dir| std::fs::read_dir(dir).ok());
    let mut installed: Vec<PathBuf> = tools
        .into_iter()
        .flatten()
        .filter_map(Result::ok)
        .map(|e| e.path().join("bin/uv"))
        .filter(|p| p.is_file())
        .collect();
    installed.sort();
    installed.pop().unwrap_or_else(|| PathBuf::from("uv"))
}

/// Where the peers are installed and built.
fn peers_dir() -> PathBuf {
    target().join("peers")
}

/// Builds a package of `peppy-bench/peers` in release (`--locked`: the
/// versions measured are the ones recorded); the paths of `bins`.
fn build(package: &str, bins: &[&str]) -> Res<Vec<PathBuf>> {
    eprintln!("peppy-bench: building {package} (peppy-bench/peers, release)…");
    let manifest = crate::workspace().join("peppy-bench/peers/Cargo.toml");
    let out = Command::new(crate::cargo())
        .args([
            "build",
            "--release",
            "--locked",
            "-p",
            package,
            "--manifest-path",
        ])
        .arg(&manifest)
        .arg("--target-dir")
        .arg(target())
        .output()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last: Vec<&str> = err.lines().rev().take(8).collect();
        let last: Vec<&str> = last.into_iter().rev().collect();
        return Err(format!("its build failed:\n{}", last.join("\n")).into());
    }
    Ok(bins
        .iter()
        .map(|b| target().join("release").join(b))
        .collect())
}

/// Installs the dora CLI (if not yet) and builds the dora nodes.
fn set_up_dora() -> Res<Dora> {
    let (cli, env) = install_dora_cli()?;
    let bins = build(
        "peppy-bench-dora",
        &["peppy-bench-dora-source", "peppy-bench-dora-sink"],
    )?;
    Ok(Dora {
        cli,
        env,
        source: bins[0].clone(),
        sink: bins[1].clone(),
    })
}

/// The `dora` command of [`DORA_VERSION`], installed under the target
/// directory: with uv (`uv tool install`) where there is one, else with
/// pip (`pip install --target`).
fn install_dora_cli() -> Res<(PathBuf, Vec<(OsString, OsString)>)> {
    let dir = peers_dir().join(format!("dora-cli-{DORA_VERSION}"));
    let package = format!("dora-rs-cli=={DORA_VERSION}");
    let (uv_bin, pip_dir) = (dir.join("bin"), dir.join("py"));
    let pip_env = vec![(
        OsString::from("PYTHONPATH"),
        pip_dir.clone().into_os_string(),
    )];
    let installed = [
        (uv_bin.join("dora"), Vec::new()),
        (pip_dir.join("bin").join("dora"), pip_env.clone()),
    ];
    for (cli, env) in &installed {
        if cli.exists() && dora_version(cli, env).is_ok() {
            return Ok((cli.clone(), env.clone()));
        }
    }
    eprintln!("peppy-bench: installing dora-rs-cli {DORA_VERSION} from PyPI…");
    let uv = uv();
    let by_uv = Command::new(&uv)
        .args(["tool", "install", "--force", &package])
        .env("UV_TOOL_DIR", dir.join("tools"))
        .env("UV_TOOL_BIN_DIR", &uv_bin)
        .output();
    let mut why = match by_uv {
        Ok(o) if o.status.success() => String::new(),
        Ok(o) => format!("uv: {}", last_line(&o.stderr)),
        Err(e) => format!("uv: {e}"),
    };
    if !why.is_empty() {
        let by_pip = Command::new("python3")
            .args(["-m", "pip", "install", "--quiet", "--upgrade", "--target"])
            .arg(&pip_dir)
            .arg(&package)
            .output();
        match by_pip {
            Ok(o) if o.status.success() => why.clear(),
            Ok(o) => why.push_str(&format!("; pip: {}", last_line(&o.stderr))),
            Err(e) => why.push_str(&format!("; pip: {e}")),
        }
    }
    for (cli, env) in installed {
        if cli.exists() {
            dora_version(&cli, &env)?;
            return Ok((cli, env));
        }
    }
    Err(format!("cannot install {package} ({why})").into())
}

fn last_line(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes)
        .lines()
        .rfind(|l| !l.trim().is_empty())
        .unwrap_or("")
        .to_string()
}

/// Checks that `cli` is dora [`DORA_VERSION`].
fn dora_version(cli: &Path, env: &[(OsString, OsString)]) -> Res<()> {
    let out = Command::new(cli)
        .arg("--version")
        .envs(env.iter().cloned())
        .output()?;
    let said = String::from_utf8_lossy(&out.stdout);
    if said.split_whitespace().any(|w| w == DORA_VERSION) {
        Ok(())
    } else {
        Err(format!(
            "`dora --version` said `{}`, not {DORA_VERSION}",
            said.trim()
        )
        .into())
    }
}

/// A node of a dataflow.
pub(crate) struct DoraNode {
    pub(crate) id: String,
    /// The sink (else the source binary).
    pub(crate) sink: bool,
    /// `input name` → `node/output`, with an optional queue size.
    pub(crate) inputs: Vec<(String, String, Option<usize>)>,
    pub(crate) outputs: Vec<String>,
    /// The arguments it is sent once linked to the benchmark; `None`: a
    /// node without a link (the launch group's cameras).
    pub(crate) args: Option<Vec<String>>,
}

/// A running `dora run` and the links of its nodes to the benchmark.
pub(crate) struct DoraRun {
    /// The `dora run` process.
    pub(crate) run: Proc,
    /// Each linked node, by id.
    pub(crate) nodes: HashMap<String, Proc>,
    _dir: tempfile::TempDir,
}

impl Dora {
    /// Starts `dora run` of a dataflow of `nodes` (no coordinator: the
    /// daemon runs in the CLI's process); returns once every linked node
    /// has said hello and got its arguments (an unlinked node is not
    /// waited for).
    pub(crate) fn run(&self, nodes: &[DoraNode]) -> Res<DoraRun> {
        let dir = tempfile::tempdir()?;
        let listener = TcpListener::bind("127.0.0.1:0")?;
        let control = listener.local_addr()?.to_string();
        let mut yaml = String::from("nodes:\n");
        for n in nodes {
            let path = if n.sink { &self.sink } else { &self.source };
            yaml.push_str(&format!("  - id: {}\n    path: {}\n", n.id, path.display()));
            if !n.inputs.is_empty() {
                yaml.push_str("    inputs:\n");
                for (name, from, queue) in &n.inputs {
                    match queue {
                        Some(q) => yaml.push_str(&format!(
                            "      {name}:\n        source: {from}\n        queue_size: {q}\n"
                        )),
                        None => yaml.push_str(&format!("      {name}: {from}\n")),
                    }
                }
            }
            if !n.outputs.is_empty() {
                yaml.push_str(&format!("    outputs: [{}]\n", n.outputs.join(", ")));
            }
            if n.args.is_some() {
                yaml.push_str(&format!(
                    "    env:\n      PEPPY_BENCH_CONTROL: \"{control}\"\n"
                ));
            }
        }
        let file = dir.path().join("dataflow.yml");
        std::fs::write(&file, yaml)?;
        let mut command = Command::new(&self.cli);
        command
            .arg("run")
            .arg(&file)
            .current_dir(dir.path())
            .envs(self.env.iter().cloned());
        let run = Proc::spawn(command, "dora run")?;
        let linked = nodes.iter().filter(|n| n.args.is_some()).count();
        let mut got = HashMap::new();
        listener.set_nonblocking(true)?;
        let deadline = Instant::now() + Duration::from_secs(60);
        while got.len() < linked {
            match listener.accept() {
                Ok((stream, _)) => {
                    stream.set_nonblocking(false)?;
                    stream.set_nodelay(true)?;
                    stream.set_read_timeout(Some(Duration::from_secs(30)))?;
                    // The node says who it is, then waits for its arguments:
                    // nothing follows the hello until they are sent.
                    let mut hello = String::new();
                    BufReader::new(&stream).read_line(&mut hello)?;
                    let hello: serde_json::Value = serde_json::from_str(&hello)?;
                    let id = hello["hello"].as_str().unwrap_or("").to_string();
                    let node = nodes
                        .iter()
                        .find(|n| n.id == id)
                        .ok_or_else(|| format!("an unknown dora node `{id}` linked"))?;
                    stream.set_read_timeout(None)?;
                    let args = serde_json::to_string(node.args.as_ref().unwrap_or(&Vec::new()))?;
                    writeln!(&stream, "{args}")?;
                    got.insert(
                        id.clone(),
                        Proc::remote(stream, &format!("dora node {id}"))?,
                    );
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    if Instant::now() > deadline {
                        return Err(format!(
                            "{} of {linked} dora nodes linked within 60 s; dora said:\n{}",
                            got.len(),
                            run.stderr()
                        )
                        .into());
                    }
                    std::thread::sleep(Duration::from_millis(5));
                }
                Err(e) => return Err(e.into()),
            }
        }
        Ok(DoraRun {
            run,
            nodes: got,
            _dir: dir,
        })
    }
}

impl DoraRun {
    /// Closes every link (the linked nodes end) and stops `dora run` as
    /// Ctrl-C does, which stops the dataflow's other nodes.
    pub(crate) fn stop(self) {
        for (_, mut node) in self.nodes {
            node.wait_or_kill(Duration::ZERO);
        }
        self.run.interrupt(Duration::from_secs(15));
    }
}
