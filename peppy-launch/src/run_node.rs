//! `peppy-launch run NODE`: one node, as in the seed's command-line example,
//! with the same checks of its bindings and parameters as a launcher.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use peppy_schema::{
    DocumentKind, Identity, NodeDoc, RepoIndex, RepoOptions, RepositoryList, check_node, node_file,
};

use crate::cli::RunArgs;
use crate::exit;
use crate::output::Output;
use crate::report;
use crate::up::{Planned, open_router, run_instances};

/// The well-known local port: the first `run` listens here, later ones join.
const LOCAL_HUB: &str = "tcp/127.0.0.1:7447";

pub(crate) fn run(args: &RunArgs) -> u8 {
    let options = RepoOptions {
        explicit: args.repos.clone(),
        env: None,
    };
    let file = match locate(&args.node, &options) {
        Ok(f) => f,
        Err(message) => {
            eprintln!("peppy-launch: {message}");
            return exit::INVALID;
        }
    };
    let check = match check_node(&file, &options) {
        Ok(c) => c,
        Err(diags) => {
            report::print_human(&diags);
            eprintln!(
                "invalid: {}; nothing was started",
                report::count(diags.error_count(), "error")
            );
            return exit::INVALID;
        }
    };
    let doc: &NodeDoc = &check.resolved.node;
    let mut flags = vec!["peppy-launch".to_string()];
    if let Some(id) = &args.instance_id {
        flags.extend(["--instance-id".into(), id.clone()]);
    }
    for b in &args.bind {
        flags.extend(["--bind".into(), b.clone()]);
    }
    if let Some(ns) = &args.namespace {
        flags.extend(["--namespace".into(), ns.clone()]);
    }
    flags.extend(args.overrides.iter().cloned());
    let mut config = match peppy_runtime::startup_from_flags(doc, flags) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("peppy-launch: {e}");
            return exit::INVALID;
        }
    };
    config.core_node = format!("run-{:x}", std::process::id());
    let Some(argv) = doc.execution.run_cmd.clone() else {
        eprintln!(
            "peppy-launch: `{}` runs in a container, which peppy-launch does not run yet",
            doc.identity()
        );
        return exit::INVALID;
    };
    let dir = file.parent().map(PathBuf::from).unwrap_or_default();
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
    runtime.block_on(async move {
        let out = Arc::new(Output::new(&[config.instance_id.as_str()]));
        if !args.no_build
            && let Some(cmd) = &doc.execution.build_cmd
        {
            out.note(&format!("building {}: {}", doc.identity(), cmd.join(" ")));
            match tokio::process::Command::new(&cmd[0])
                .args(&cmd[1..])
                .current_dir(&dir)
                .output()
                .await
            {
                Ok(o) if o.status.success() => {}
                Ok(o) => {
                    out.note(&format!(
                        "the build of {} failed:\n{}{}",
                        doc.identity(),
                        String::from_utf8_lossy(&o.stdout),
                        String::from_utf8_lossy(&o.stderr)
                    ));
                    return exit::FAILED;
                }
                Err(e) => {
                    out.note(&format!("cannot run the build of {}: {e}", doc.identity()));
                    return exit::FAILED;
                }
            }
        }
        // Join the given endpoints, or the local hub: the first `run` on a
        // machine hosts it, later ones connect to it.
        let mut _hub = None;
        config.zenoh.connect = if args.connect.is_empty() {
            if let Ok(session) = open_router(&[LOCAL_HUB.to_string()], &[]).await {
                _hub = Some(session);
            }
            vec![LOCAL_HUB.to_string()]
        } else {
            args.connect.clone()
        };
        config.zenoh.listen = args.listen.clone();
        let run_dir = std::env::temp_dir().join(format!("peppy-run-{}", std::process::id()));
        if let Err(e) = std::fs::create_dir_all(&run_dir) {
            out.note(&format!("cannot create {}: {e}", run_dir.display()));
            return exit::FAILED;
        }
        out.note(&format!(
            "namespace {}; log in {}",
            config.namespace,
            run_dir.display()
        ));
        let planned = Planned {
            node: doc.identity().to_string(),
            dir,
            argv,
            env: Vec::new(),
            restart: peppy_schema::RestartPolicy::No,
            config,
        };
        run_instances(
            vec![Ok(planned)],
            &run_dir,
            Duration::from_secs_f64(args.grace),
            out,
        )
        .await
    })
}

/// `NODE` is a path to a node (directory or peppy.json5) or a `name:tag`
/// found in the repositories.
fn locate(node: &str, options: &RepoOptions) -> Result<PathBuf, String> {
    let as_path = PathBuf::from(node);
    if as_path.exists() {
        return Ok(node_file(&as_path));
    }
    let Some(id) = Identity::parse(node) else {
        return Err(format!("`{node}` is neither a path nor a `name:tag`"));
    };
    let cwd = std::env::current_dir().unwrap_or_default();
    let env = std::env::var_os(peppy_schema::REPOSITORIES_ENV);
    let repos = RepositoryList::discover(&options.explicit, env.as_deref(), &cwd)
        .map_err(|d| d.to_string())?;
    let index = RepoIndex::scan(&repos.paths);
    if let Some(e) = index.node(&id) {
        return Ok(e.path.clone());
    }
    match index.broken(DocumentKind::Node, &id) {
        Some(b) => Err(format!(
            "`{id}` is defined in {}, but that document is invalid",
            b.path.display()
        )),
        None => Err(format!(
            "no repository provides node `{id}`; {}",
            index.searched()
        )),
    }
}
