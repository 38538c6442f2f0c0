//! `peppy-launch up LAUNCHER`: check everything, build each node once, start
//! a Zenoh router and every instance, supervise, and stop cleanly.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use peppy_runtime::{Endpoints, StartupConfig};
use peppy_schema::{RepoOptions, StackCheck, check_launcher};

use crate::cli::UpArgs;
use crate::exit;
use crate::output::Output;
use crate::report;
use crate::supervise::{self, Ended, InstanceSpec, StopSignals};

pub(crate) fn run(args: &UpArgs) -> u8 {
    let options = RepoOptions {
        explicit: args.repos.clone(),
        env: None,
    };
    let stack = match check_launcher(&args.launcher, &options) {
        Ok(stack) => stack,
        Err(diags) => {
            report::print_human(&diags);
            eprintln!(
                "invalid: {}; nothing was built or started",
                report::count(diags.error_count(), "error")
            );
            return exit::INVALID;
        }
    };
    if !stack.warnings.is_empty() {
        report::print_human(&stack.warnings);
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            eprintln!("peppy-launch: cannot start the tokio runtime: {e}");
            return exit::FAILED;
        }
    };
    runtime.block_on(launch(stack, args))
}

/// The namespace of a launch: the launcher's file stem plus a short hash of
/// its absolute path, so two launchers never share one by accident.
pub(crate) fn default_namespace(launcher: &Path) -> String {
    let abs = std::fs::canonicalize(launcher).unwrap_or_else(|_| launcher.to_path_buf());
    let stem: String = launcher
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("stack")
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let hash = peppy_schema::sha256_hex(abs.to_string_lossy().as_bytes());
    format!("{stem}-{}", &hash[..6])
}

fn free_local_endpoint() -> std::io::Result<String> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    Ok(format!("tcp/127.0.0.1:{port}"))
}

pub(crate) async fn open_router(
    listen: &[String],
    connect: &[String],
) -> Result<zenoh::Session, String> {
    let mut config = zenoh::Config::default();
    let set = |c: &mut zenoh::Config, k: &str, v: serde_json::Value| {
        c.insert_json5(k, &v.to_string())
            .map_err(|e| format!("invalid zenoh setting `{k}`: {e}"))
    };
    set(&mut config, "mode", "router".into())?;
    set(&mut config, "listen/endpoints", listen.into())?;
    if !connect.is_empty() {
        set(&mut config, "connect/endpoints", connect.into())?;
    }
    set(&mut config, "scouting/multicast/enabled", false.into())?;
    zenoh::open(config)
        .await
        .map_err(|e| format!("cannot open the launch's zenoh router on {listen:?}: {e}"))
}

/// Runs every node's `build_cmd` once, in its directory; output is shown
/// only when a build fails.
async fn build_all(stack: &StackCheck, out: &Output) -> Result<(), String> {
    let mut seen = Vec::new();
    let builds: Vec<(&Path, &Vec<String>, String)> = stack
        .deployments
        .iter()
        .filter_map(|d| {
            let node = &d.resolved.node;
            node.execution
                .build_cmd
                .as_ref()
                .map(|cmd| (d.dir.as_path(), cmd, node.identity().to_string()))
        })
        .filter(|(dir, cmd, _)| {
            let key = (dir.to_path_buf(), (*cmd).clone());
            let new = !seen.contains(&key);
            seen.push(key);
            new
        })
        .collect();
    for (i, (dir, cmd, name)) in builds.iter().enumerate() {
        out.note(&format!(
            "building {name} ({}/{}): {}",
            i + 1,
            builds.len(),
            cmd.join(" ")
        ));
        let output = tokio::process::Command::new(&cmd[0])
            .args(&cmd[1..])
            .current_dir(dir)
            .stdin(std::process::Stdio::null())
            .output()
            .await
            .map_err(|e| {
                format!(
                    "cannot run the build of {name} (`{}` in {}): {e}",
                    cmd.join(" "),
                    dir.display()
                )
            })?;
        if !output.status.success() {
            let mut text = String::from_utf8_lossy(&output.stdout).into_owned();
            text.push_str(&String::from_utf8_lossy(&output.stderr));
            return Err(format!(
                "the build of {name} failed (`{}` in {}):\n{text}",
                cmd.join(" "),
                dir.display()
            ));
        }
    }
    Ok(())
}

async fn launch(stack: StackCheck, args: &UpArgs) -> u8 {
    let ids: Vec<&str> = stack
        .plan
        .instances
        .iter()
        .map(|i| i.instance_id.as_str())
        .collect();
    let out = Arc::new(Output::new(&ids));
    let namespace = args
        .namespace
        .clone()
        .unwrap_or_else(|| default_namespace(&args.launcher));
    if let Err(why) = peppy_schema::names::check_name(&namespace) {
        out.note(&format!("invalid --namespace `{namespace}`: {why}"));
        return exit::INVALID;
    }
    let core_node = format!("launch-{:x}", std::process::id());
    let run_dir = stack
        .launcher
        .base_dir()
        .join(".peppy")
        .join("runs")
        .join(format!(
            "{}-{}",
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs()),
            std::process::id()
        ));
    // Absolute: instances run in their own directories and read their
    // runtime config from here.
    let run_dir =
        match std::fs::create_dir_all(&run_dir).and_then(|()| std::fs::canonicalize(&run_dir)) {
            Ok(d) => d,
            Err(e) => {
                out.note(&format!(
                    "cannot create the run directory {}: {e}",
                    run_dir.display()
                ));
                return exit::FAILED;
            }
        };
    out.note(&format!(
        "namespace {namespace}; logs in {}",
        run_dir.display()
    ));

    if !args.no_build
        && let Err(e) = build_all(&stack, &out).await
    {
        out.note(&e);
        return exit::FAILED;
    }

    let listen = if args.listen.is_empty() {
        match free_local_endpoint() {
            Ok(e) => vec![e],
            Err(e) => {
                out.note(&format!("cannot find a free local port: {e}"));
                return exit::FAILED;
            }
        }
    } else {
        args.listen.clone()
    };
    let router = match open_router(&listen, &args.connect).await {
        Ok(r) => r,
        Err(e) => {
            out.note(&e);
            return exit::FAILED;
        }
    };
    // Nodes reach each other through the launch's router; a listen address
    // on all interfaces is still reached locally on loopback.
    let node_connect: Vec<String> = listen
        .iter()
        .map(|e| e.replace("0.0.0.0", "127.0.0.1").replace("[::]", "[::1]"))
        .collect();

    let planned: Vec<Result<Planned, String>> = stack
        .plan
        .instances
        .iter()
        .map(|inst| {
            let deployment = &stack.deployments[inst.deployment];
            let node = &deployment.resolved.node;
            let argv = node.execution.run_cmd.clone().ok_or_else(|| {
                format!(
                    "`{}` runs in a container, which peppy-launch does not run yet",
                    inst.instance_id
                )
            })?;
            Ok(Planned {
                config: StartupConfig {
                    instance_id: inst.instance_id.clone(),
                    core_node: core_node.clone(),
                    namespace: namespace.clone(),
                    bindings: inst
                        .slots
                        .iter()
                        .map(|s| (s.link_id.clone(), s.binding.clone()))
                        .collect::<BTreeMap<_, _>>(),
                    parameters: inst.parameters.clone(),
                    zenoh: Endpoints {
                        mode: None,
                        listen: Vec::new(),
                        connect: node_connect.clone(),
                        multicast_scouting: false,
                    },
                },
                node: node.identity().to_string(),
                dir: deployment.dir.clone(),
                argv,
                env: inst.env_vars.clone(),
                restart: inst.restart,
            })
        })
        .collect();
    let code = run_instances(planned, &run_dir, Duration::from_secs_f64(args.grace), out).await;
    let _ = router.close().await;
    code
}

/// One instance ready to start.
pub(crate) struct Planned {
    pub(crate) config: StartupConfig,
    pub(crate) node: String,
    pub(crate) dir: std::path::PathBuf,
    pub(crate) argv: Vec<String>,
    pub(crate) env: Vec<(String, String)>,
    pub(crate) restart: peppy_schema::RestartPolicy,
}

/// Starts every instance in order (stopping those started if one cannot
/// start), supervises them until they end or Ctrl-C, and returns the exit
/// code: 0 clean, 1 a failure.
pub(crate) async fn run_instances(
    planned: Vec<Result<Planned, String>>,
    run_dir: &Path,
    grace: Duration,
    out: Arc<Output>,
) -> u8 {
    let signals = StopSignals::default();
    let ctrl_c = {
        let signals = signals.clone();
        let out = out.clone();
        tokio::spawn(async move {
            wait_for_interrupt().await;
            out.note("stopping (press Ctrl-C again to kill at once)");
            signals.stop.cancel();
            wait_for_interrupt().await;
            out.note("killing every instance");
            signals.kill.cancel();
        })
    };
    let mut running = Vec::new();
    let mut start_failure = None;
    for p in planned {
        let p = match p {
            Ok(p) => p,
            Err(e) => {
                start_failure = Some(e);
                break;
            }
        };
        let id = p.config.instance_id.clone();
        let config_path = run_dir.join(format!("{id}.json"));
        if let Err(e) = std::fs::write(
            &config_path,
            serde_json::to_vec_pretty(&p.config).unwrap_or_default(),
        ) {
            start_failure = Some(format!("cannot write {}: {e}", config_path.display()));
            break;
        }
        let mut env = p.env;
        env.push((
            peppy_runtime::RUNTIME_CONFIG_ENV.to_string(),
            config_path.display().to_string(),
        ));
        let spec = InstanceSpec {
            id: id.clone(),
            dir: p.dir,
            argv: p.argv,
            env,
            restart: p.restart,
            log: run_dir.join(format!("{id}.log")),
        };
        match supervise::spawn(&spec, &out) {
            Ok((child, pumps)) => {
                out.note(&format!(
                    "started `{id}` ({}) as pid {}",
                    p.node,
                    child.id().unwrap_or(0)
                ));
                let task = tokio::spawn(supervise::supervise(
                    spec,
                    child,
                    pumps,
                    grace,
                    signals.clone(),
                    out.clone(),
                ));
                running.push((id, task));
            }
            Err(e) => {
                start_failure = Some(format!(
                    "instance `{id}` failed to start: {e} (log: {})",
                    spec.log.display()
                ));
                break;
            }
        }
    }
    if let Some(why) = &start_failure {
        out.note(why);
        out.note("stopping the instances already started");
        signals.stop.cancel();
    }
    let mut failed = start_failure.is_some();
    for (id, task) in running {
        match task.await {
            Ok(ended) => {
                failed |= ended.is_failure();
                if matches!(ended, Ended::Stopped) {
                    out.note(&format!("`{id}` stopped"));
                }
            }
            Err(e) => {
                out.note(&format!("supervising `{id}` failed: {e}"));
                failed = true;
            }
        }
    }
    ctrl_c.abort();
    if failed {
        out.note("done: an instance failed");
        exit::FAILED
    } else {
        out.note("done");
        exit::OK
    }
}

async fn wait_for_interrupt() {
    let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()).ok();
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        () = async {
            match term.as_mut() {
                Some(t) => { t.recv().await; }
                None => std::future::pending::<()>().await,
            }
        } => {}
    }
}
