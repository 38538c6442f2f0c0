//! `peppy-launch up LAUNCHER`: check everything, build each node once, start
//! a Zenoh router and every instance, supervise, and stop cleanly.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use peppy_runtime::{Endpoints, StartupConfig};
use peppy_schema::{Identity, StackCheck, check_launcher_selection};

use crate::cli::UpArgs;
use crate::error::{LaunchError, SetupError, UsageError};
use crate::executable::{self, ExecutableError};
use crate::output::Output;
use crate::placement;
use crate::presence;
use crate::report;
use crate::runs::{self, LaunchRecord};
use crate::supervise::{self, Ended, InstanceSpec, StopSignals};

pub(crate) fn run(args: &UpArgs) -> Outcome {
    // `--detach`: this process shows the launch start in the background
    // and returns; the launch is this command again, as the supervisor.
    if args.detach && !crate::detach::take_role() {
        return crate::detach::launch();
    }
    // Under `--place`, this launch is the machine `@self` names, and it
    // starts what is placed there.
    let placed_args;
    let args = if args.placing.place.is_empty() {
        args
    } else {
        placed_args = UpArgs {
            core_node: Some(placement::up_machine(args)?),
            ..args.clone()
        };
        &placed_args
    };
    let options = crate::repositories::options(args.repos.clone())?;
    let stack = match check_launcher_selection(
        &args.launcher,
        &args.with,
        &options,
        &crate::sources::Fetcher::new(),
    ) {
        Ok(stack) => stack,
        Err(diags) => {
            report::print_human(&diags);
            eprintln!(
                "invalid: {}; nothing was built or started",
                report::count(diags.error_count(), "error")
            );
            return Err(LaunchError::Invalid {
                errors: diags.error_count(),
            });
        }
    };
    // What `check` only warns about, `up` cannot do: a node it has no way
    // to start is an error here.
    let mut warnings = peppy_schema::Diagnostics::new();
    let mut unstartable = 0;
    let (container_notes, container_warnings) = crate::container::assess(&stack);
    for d in stack.warnings.iter().chain(container_warnings.iter()) {
        let mut d = d.clone();
        if d.code == peppy_schema::Code::UnsupportedExecution {
            d.severity = peppy_schema::Severity::Error;
            unstartable += 1;
        }
        warnings.push(d);
    }
    if !warnings.is_empty() {
        report::print_human(&warnings);
    }
    if unstartable > 0 {
        eprintln!(
            "invalid: {}; nothing was built or started",
            report::count(unstartable, "error")
        );
        return Err(LaunchError::Invalid {
            errors: unstartable,
        });
    }
    if let Some(selection) = &stack.selection {
        eprintln!("components: {selection}");
    }
    for note in container_notes {
        eprintln!("peppy-launch: {note}");
    }
    let stack = place(stack, args)?;
    let runtime = crate::tokio_runtime(None)?;
    runtime.block_on(launch(stack, args))
}

/// `--place` applied: the stack's core nodes become the machines, and one
/// of them must be this launch's.
fn place(stack: StackCheck, args: &UpArgs) -> Result<StackCheck, LaunchError> {
    let Some(here) = args
        .core_node
        .clone()
        .filter(|_| !args.placing.place.is_empty())
    else {
        return Ok(stack);
    };
    let stack = placement::place(stack, &args.placing.place, &mut || Ok(here.clone()))?;
    if stack.launcher.core_node(&here).is_none() {
        return Err(placement::PlaceError::NothingHere {
            core: here,
            machines: stack
                .launcher
                .core_nodes
                .iter()
                .map(|c| c.name.clone())
                .collect(),
        }
        .into());
    }
    Ok(stack)
}

/// The namespace of a launch: the launcher's file stem plus a short hash of
/// its absolute path, so two launchers never share one by accident. A
/// launcher that places its instances on several machines is one stack
/// wherever its file is checked out: its hash is of the file's contents,
/// so every machine's share lands in the same namespace.
pub(crate) fn default_namespace(launcher: &Path) -> String {
    let abs = std::fs::canonicalize(launcher).unwrap_or_else(|_| launcher.to_path_buf());
    let text = std::fs::read_to_string(launcher).unwrap_or_default();
    let placed = peppy_schema::LauncherDoc::parse(launcher.display().to_string(), &text)
        .is_ok_and(|(doc, _)| !doc.core_nodes.is_empty());
    let hashed = if placed {
        text.into_bytes()
    } else {
        abs.to_string_lossy().as_bytes().to_vec()
    };
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
    let hash = peppy_schema::sha256_hex(&hashed);
    format!("{stem}-{}", &hash[..6])
}

fn free_local_endpoint() -> std::io::Result<String> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    Ok(format!("tcp/127.0.0.1:{port}"))
}

/// `peppy-launch router`: a bare router until Ctrl-C or SIGTERM.
pub(crate) fn router(args: &crate::cli::RouterArgs) -> Outcome {
    let runtime = crate::tokio_runtime(None)?;
    runtime.block_on(async {
        let router = open_router(&args.listen, &args.connect, true, None).await?;
        let stop = interrupts_from_now();
        eprintln!(
            "peppy-launch: router {} on {}{}",
            router.zid(),
            args.listen.join(", "),
            if args.connect.is_empty() {
                String::new()
            } else {
                format!(", linked to {}", args.connect.join(", "))
            }
        );
        stop.await;
        let _ = router.close().await;
        eprintln!("peppy-launch: router stopped");
        Ok(())
    })
}

/// Why a launch's Zenoh router did not open.
#[derive(Debug, thiserror::Error)]
pub enum RouterError {
    /// Zenoh refused a setting of the router's configuration.
    #[error("invalid zenoh setting `{key}`: {source}")]
    Setting {
        /// The configuration key.
        key: String,
        /// Zenoh's error.
        source: zenoh::Error,
    },
    /// The router's endpoints do not fit a Zenoh configuration.
    #[error(transparent)]
    Config(peppy_runtime::Error),
    /// The router's own login (for the routers it links to) does not fit
    /// the configuration.
    #[error(transparent)]
    Login(peppy_runtime::Error),
    /// Zenoh did not open the router (an endpoint taken or unreachable, a
    /// certificate unreadable).
    #[error("cannot open the launch's zenoh router on {listen:?}: {source}")]
    Open {
        /// The endpoints it was to listen on.
        listen: Vec<String>,
        /// Zenoh's error.
        source: zenoh::Error,
    },
}

/// Sets `key` of a router's configuration to `value`.
pub(crate) fn set_router_option(
    config: &mut zenoh::Config,
    key: &str,
    value: serde_json::Value,
) -> Result<(), RouterError> {
    config
        .insert_json5(key, &value.to_string())
        .map_err(|source| RouterError::Setting {
            key: key.to_string(),
            source,
        })
}

/// How soon a router of a stack placed over several machines declares a
/// silent link lost (Zenoh's default is 10 s): a dropped link between
/// machines is reported, and its traffic rerouted, within a few seconds.
const LINKED_LEASE_MS: u64 = 3000;

pub(crate) async fn open_router(
    listen: &[String],
    connect: &[String],
    linked: bool,
    guard: Option<&crate::security::RouterGuard>,
) -> Result<zenoh::Session, RouterError> {
    // Mode, endpoints and scouting as every session of peppy's gets them.
    let endpoints = Endpoints {
        mode: Some("router".into()),
        listen: listen.to_vec(),
        connect: connect.to_vec(),
        multicast_scouting: false,
        login: None,
    };
    let mut config = endpoints.zenoh_config().map_err(RouterError::Config)?;
    if listen.is_empty() {
        // A router listens on Zenoh's default port unless told otherwise.
        set_router_option(&mut config, "listen/endpoints", listen.into())?;
    }
    if linked {
        set_router_option(
            &mut config,
            "transport/link/tx/lease",
            LINKED_LEASE_MS.into(),
        )?;
    }
    if let Some(guard) = guard {
        guard.apply(&mut config)?;
    }
    zenoh::open(config)
        .await
        .map_err(|source| RouterError::Open {
            listen: listen.to_vec(),
            source,
        })
}

type Outcome = crate::error::Result;

/// A secured launch's credentials and its router's guard.
struct Secured {
    secrets: crate::security::Secrets,
    guard: crate::security::RouterGuard,
}

/// The stack's keys, when this launch's router links to other core nodes
/// (a share started with `--core-node`; `--local` runs one router).
fn stack_keys(
    stack: &StackCheck,
    share: &placement::Share,
    args: &UpArgs,
) -> Result<Option<crate::security::keys::StackKeys>, LaunchError> {
    use crate::security::keys;
    if args.core_node.is_none() || stack.launcher.core_nodes.is_empty() {
        return Ok(None);
    }
    let names: Vec<&str> = stack
        .launcher
        .core_nodes
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    keys::StackKeys::load(
        &keys::dir_for(&stack.launcher),
        &share.name,
        &names,
        &args.launcher,
    )
    .map(Some)
    .map_err(LaunchError::from)
}

/// Generates this launch's credentials, writes the router's dictionary and
/// the policy (for reviewers) into the run directory, and starts reporting
/// what the router refuses.
fn secure(
    stack: &StackCheck,
    share: &placement::Share,
    namespace: &str,
    run_dir: &Path,
    keys: Option<&crate::security::keys::StackKeys>,
    out: Arc<Output>,
) -> Result<Secured, LaunchError> {
    use crate::security::{Secrets, denials, policy, write_private};
    let cannot_write = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SetupError::Write { path, source }
    };
    if let Some(taken) = share
        .instances
        .iter()
        .map(|&i| stack.plan.instances[i].instance_id.as_str())
        .find(|id| Secrets::reserved(id))
    {
        return Err(SetupError::ReservedInstanceId {
            instance: taken.to_string(),
        }
        .into());
    }
    let secrets = Secrets::generate(
        share
            .instances
            .iter()
            .map(|&i| stack.plan.instances[i].instance_id.as_str()),
    )
    .map_err(SetupError::Credentials)?;
    let policy = policy::derive(stack, namespace, &|inst| {
        Some(
            stack
                .launcher
                .core_node_of(inst.core_node.as_deref())
                .map_or_else(|| share.name.clone(), str::to_string),
        )
    });
    let dictionary = run_dir.join("router.users");
    let routers = keys.map(|k| k.router_logins()).unwrap_or_default();
    write_private(&dictionary, secrets.dictionary(&routers).as_bytes())
        .map_err(cannot_write(&dictionary))?;
    let access_control = policy.access_control(keys.map_or(&[], |k| k.core_nodes()));
    let policy_file = run_dir.join("policy.json");
    std::fs::write(
        &policy_file,
        serde_json::to_vec_pretty(&serde_json::json!({
            "policy": &policy,
            "access_control": &access_control,
        }))
        .unwrap_or_default(),
    )
    .map_err(cannot_write(&policy_file))?;
    denials::listen(Arc::new(move |d: &denials::Denial| out.note(&d.message())));
    Ok(Secured {
        secrets,
        guard: crate::security::RouterGuard {
            access_control,
            dictionary,
            login: keys.map(|k| k.router_login(&share.name)),
            tls: keys.map(|k| k.tls_settings()).unwrap_or_default(),
        },
    })
}

/// Builds every deployed node once, in its directory (output is shown only
/// when a build fails), and returns the argv that starts each node.
async fn prepare_all(
    stack: &StackCheck,
    wanted: &[usize],
    out: &Output,
    build: bool,
) -> Result<HashMap<Identity, Vec<String>>, ExecutableError> {
    // Only the deployments this machine runs instances of.
    let here = || {
        stack
            .deployments
            .iter()
            .enumerate()
            .filter(|(i, _)| wanted.contains(i))
            .map(|(_, d)| d)
    };
    let total = here()
        .filter(|d| build && executable::build_of(&d.resolved.node.execution).is_some())
        .count();
    let mut programs = HashMap::new();
    let mut built = 0;
    let mut shared_noted = false;
    for d in here() {
        let node = &d.resolved.node;
        let identity = node.identity();
        let mut label = identity.to_string();
        if build && let Some(cmd) = executable::build_of(&node.execution) {
            built += 1;
            label = format!("{identity} ({built}/{total})");
            if !shared_noted && let Some(dir) = crate::shared_build::for_build(&cmd, &d.dir) {
                shared_noted = true;
                out.note(&format!(
                    "Rust nodes build what they share once, in {} ({}=off: each in its own target/)",
                    dir.display(),
                    crate::shared_build::BUILD_DIR_ENV
                ));
            }
            out.note(&format!("building {label}: {}", cmd.join(" ")));
        }
        if crate::python_sync::is_python(&d.resolved) {
            // The generated package follows the documents before every start.
            crate::python_sync::write_package(&d.resolved, &d.dir).map_err(|source| {
                ExecutableError::Package {
                    node: identity.to_string(),
                    source,
                }
            })?;
        } else if crate::rust_libs::wants_libs(&d.resolved, &d.dir) {
            // So do the `.peppy/libs` crates, before cargo builds them.
            crate::rust_libs::write_libs(&d.resolved, &d.dir).map_err(|source| {
                ExecutableError::Package {
                    node: identity.to_string(),
                    source,
                }
            })?;
        }
        let argv = executable::prepare(
            &identity.to_string(),
            &label,
            &node.name,
            &d.dir,
            &node.execution,
            build,
        )
        .await?;
        programs.insert(identity, argv);
    }
    Ok(programs)
}

async fn launch(stack: StackCheck, args: &UpArgs) -> Outcome {
    let share = placement::share(&stack, args)?;
    let ids: Vec<&str> = share
        .instances
        .iter()
        .map(|&i| stack.plan.instances[i].instance_id.as_str())
        .collect();
    let out = Arc::new(Output::new(&ids));
    let namespace = launch_namespace(args)?;
    let inherited_grace = inherited_grace()?;
    let run_dir = create_run_dir(&stack)?;
    out.note(&format!(
        "namespace {namespace}; logs in {}",
        run_dir.display()
    ));
    let deployments: Vec<usize> = share
        .instances
        .iter()
        .map(|&i| stack.plan.instances[i].deployment)
        .collect();
    let programs = prepare_all(&stack, &deployments, &out, !args.no_build).await?;
    let links = choose_links(&stack, &share, args)?;
    let secured = if links.security.on {
        let keys = links.keys.as_ref();
        Some(secure(
            &stack,
            &share,
            &namespace,
            &run_dir,
            keys,
            out.clone(),
        )?)
    } else {
        None
    };
    note_security(&out, &stack, args, &links);
    // The instances of this launch reach the router, and each other, over
    // Unix sockets; the router's own endpoints stay for everything else.
    let local_links = crate::local_links::LocalLinks::create();
    let router_listen: Vec<String> = links
        .listen
        .iter()
        .cloned()
        .chain(local_links.as_ref().map(|l| l.router()))
        .collect();
    let router = open_router(
        &router_listen,
        &links.connect,
        !stack.launcher.core_nodes.is_empty(),
        secured.as_ref().map(|s| &s.guard),
    )
    .await?;
    let _presence =
        announce_core_node(&router, &stack, args, &share, &links, &namespace, &out).await;
    // The stack clock: wall ticks and sync answers for this namespace
    // while the launch runs (docs/WIRE.md, "Clock").
    let _clock = peppy_runtime::clock::serve(&router, &namespace)
        .await
        .map_err(|e| out.note(&format!("the stack clock is not served: {e}")))
        .ok();
    let cores = stack
        .plan
        .instances
        .iter()
        .map(|i| {
            let core = if stack.launcher.core_nodes.is_empty() {
                share.name.clone()
            } else {
                stack
                    .launcher
                    .core_node_of(i.core_node.as_deref())
                    .unwrap_or(&share.name)
                    .to_string()
            };
            (i.instance_id.clone(), core)
        })
        .collect();
    let instances = Instances {
        inherited_grace,
        namespace: &namespace,
        connect: links.node_endpoints(),
        local: local_links.as_ref(),
        secured: secured.as_ref(),
        cores,
    };
    let planned = instances.plan(&stack, &share, &programs);
    let control = crate::control::Listener::bind()
        .map_err(|e| {
            out.note(&format!(
                "no control socket (`stop` and `node stop` cannot reach this launch): {e}"
            ))
        })
        .ok();
    let mut record = launch_record(args, &share, &namespace, &instances, &run_dir, &planned);
    record.control = control.as_ref().map(|c| c.path().to_path_buf());
    let registration = runs::Registered::new(record)
        .map_err(|e| out.note(&e.to_string()))
        .ok();
    // The launch is its instances' core node: the datastore, `info` and
    // `stack::list` (docs/WIRE.md, "Core node functions").
    let starting: Vec<&Planned> = planned.iter().flatten().collect();
    let view = Arc::new(crate::core_view::LaunchView::new(
        &share.name,
        crate::core_view::port_of(&links.listen),
        &starting,
        &|node| {
            stack
                .deployments
                .iter()
                .find(|d| d.resolved.node.identity().to_string() == node)
                .map(|d| d.resolved.node.pairings.clone())
                .unwrap_or_default()
        },
    ));
    let _core = serve_core(&router, &namespace, &share.name, &starting, &view, &out).await;
    if let Some(port) = args.view {
        serve_view(&registration, port, out.clone());
    }
    let code = if planned.is_empty() {
        // A machine with only a router still links the others: it stays up.
        let stop = interrupts_from_now();
        out.note("nothing to start here; the router runs until Ctrl-C");
        crate::detach::started(&run_dir);
        stop.await;
        out.note("done");
        Ok(())
    } else {
        run_instances(
            planned,
            &run_dir,
            args.grace,
            out,
            Some(view),
            control,
            registration,
        )
        .await
    };
    let _ = router.close().await;
    code
}

/// `up --view`: the launch served to Foxglove beside it, found through its
/// own record (so a secured launch is viewed with its recorder's login).
fn serve_view(registration: &Option<runs::Registered>, port: u16, out: Arc<Output>) {
    let Some(registration) = registration else {
        out.note("no Foxglove view: this launch is not registered, so the view cannot find it");
        return;
    };
    let record = registration.record();
    let args = crate::cli::ViewArgs {
        topics: Vec::new(),
        host: "127.0.0.1".into(),
        port,
        stack: crate::cli::StackArgs {
            launcher: Some(record.launcher.clone()),
            namespace: Some(record.namespace.clone()),
            connect: Vec::new(),
            wait: Duration::from_secs(10),
        },
    };
    tokio::spawn(async move {
        if let Err(e) = crate::recording::view::run(args).await {
            out.note(&format!("the Foxglove view stopped: {e}"));
        }
    });
}

/// Serves the core node functions of `core` (and of any other core node
/// an instance of this launch names) on `router` while the launch runs; a
/// failure is said and the launch goes on without them.
pub(crate) async fn serve_core(
    router: &zenoh::Session,
    namespace: &str,
    core: &str,
    starting: &[&Planned],
    view: &Arc<crate::core_view::LaunchView>,
    out: &Output,
) -> Vec<peppy_runtime::core_functions::CoreFunctions> {
    let mut cores = vec![core.to_string()];
    for p in starting {
        if !cores.contains(&p.config.core_node) {
            cores.push(p.config.core_node.clone());
        }
    }
    let mut served = Vec::new();
    for core in cores {
        let view: Arc<dyn peppy_runtime::core_functions::CoreView> = view.clone();
        match peppy_runtime::core_functions::serve(router, namespace, &core, view).await {
            Ok(s) => served.push(s),
            Err(e) => out.note(&format!(
                "the datastore, info and stack list of core node `{core}` are not served: {e}"
            )),
        }
    }
    served
}

/// `--namespace`, or the launcher's own ([`default_namespace`]).
fn launch_namespace(args: &UpArgs) -> Result<String, LaunchError> {
    let namespace = args
        .namespace
        .clone()
        .unwrap_or_else(|| default_namespace(&args.launcher));
    match peppy_schema::names::check_name(&namespace) {
        Ok(()) => Ok(namespace),
        Err(why) => Err(UsageError::Namespace { namespace, why }.into()),
    }
}

/// `.peppy/runs/<start>-<pid>` beside the launcher, absolute: instances
/// run in their own directories and read their runtime config from here.
fn create_run_dir(stack: &StackCheck) -> Result<std::path::PathBuf, LaunchError> {
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
    std::fs::create_dir_all(&run_dir)
        .and_then(|()| std::fs::canonicalize(&run_dir))
        .map_err(|source| {
            SetupError::RunDir {
                path: run_dir.clone(),
                source,
            }
            .into()
        })
}

/// How this launch's router is reached, and whether it is secured.
struct Links {
    /// Where the router listens.
    listen: Vec<String>,
    /// What the router connects to.
    connect: Vec<String>,
    /// Secured and linked to other core nodes: the loopback endpoint the
    /// launch's own instances and tools reach the router on.
    local: Option<String>,
    /// Whether security is on, and why.
    security: crate::security::Decision,
    /// The stack's keys, when this router links securely to other core nodes.
    keys: Option<crate::security::keys::StackKeys>,
}

impl Links {
    /// Where the launch's instances connect: its router, reached locally
    /// on loopback even when it listens on all interfaces.
    fn node_endpoints(&self) -> Vec<String> {
        match &self.local {
            Some(local) => vec![local.clone()],
            None => self
                .listen
                .iter()
                .map(|e| e.replace("0.0.0.0", "127.0.0.1").replace("[::]", "[::1]"))
                .collect(),
        }
    }
}

/// The router's endpoints (a free loopback port unless the share names
/// some), whether security is on, and, secured between core nodes, the
/// keys and TLS endpoints it links with.
fn choose_links(
    stack: &StackCheck,
    share: &placement::Share,
    args: &UpArgs,
) -> Result<Links, LaunchError> {
    let free = || free_local_endpoint().map_err(SetupError::FreePort);
    let listen = if share.listen.is_empty() {
        vec![free()?]
    } else {
        share.listen.clone()
    };
    let security = crate::security::decide(&stack.launcher, &listen, &share.connect, args.insecure);
    let keys = if security.on {
        stack_keys(stack, share, args)?
    } else {
        None
    };
    if security.on && keys.is_none() && !share.connect.is_empty() {
        return Err(SetupError::NoKeysToLink {
            reason: security.reason,
            connect: share.connect.clone(),
        }
        .into());
    }
    if keys.is_none() {
        let connect = share.connect.clone();
        return Ok(Links {
            listen,
            connect,
            local: None,
            security,
            keys,
        });
    }
    // Secured, the core node's own endpoints are for other core nodes
    // (TLS); its instances and tools reach the router on a loopback port of
    // their own (the free one taken above when it has no endpoints).
    let local = if share.listen.is_empty() {
        listen[0].clone()
    } else {
        free()?
    };
    let over_tls = |e: &String| crate::security::keys::over_tls(e);
    let mut tls: Vec<String> = share.listen.iter().map(over_tls).collect();
    tls.push(local.clone());
    Ok(Links {
        listen: tls,
        connect: share.connect.iter().map(over_tls).collect(),
        local: Some(local),
        security,
        keys,
    })
}

/// Tells the user whether the launch is secured, and warns when it is
/// not and could be reached from beyond this machine.
fn note_security(out: &Output, stack: &StackCheck, args: &UpArgs, links: &Links) {
    let reason = &links.security.reason;
    if links.security.on {
        out.note(&format!(
            "security on ({reason}): each instance may only publish its own topics and receive and call what its bindings name; `check --security` shows the policy"
        ));
    } else if args.insecure
        || matches!(stack.launcher.security, Some((false, _)))
        || !links
            .listen
            .iter()
            .chain(&links.connect)
            .all(|e| crate::security::is_loopback(e))
    {
        out.note(&format!(
            "WARNING: security is OFF ({reason}): any process that reaches {} can read and write every topic of this stack and answer its services",
            links.listen.join(", ")
        ));
    }
}

/// For a launcher with core nodes: says which share this is and where its
/// router is, warns when no other machine can reach it, and announces the
/// core node to the others (the returned handle keeps it announced).
async fn announce_core_node(
    router: &zenoh::Session,
    stack: &StackCheck,
    args: &UpArgs,
    share: &placement::Share,
    links: &Links,
    namespace: &str,
    out: &Arc<Output>,
) -> Option<presence::Presence> {
    if stack.launcher.core_nodes.is_empty() {
        return None;
    }
    let (listen, connect) = (&links.listen, &links.connect);
    if stack.launcher.core_nodes.len() > 1
        && !args.local
        && connect.is_empty()
        && listen.iter().all(|e| crate::security::is_loopback(e))
    {
        out.note(&format!(
            "note: core node {} listens on loopback only and connects nowhere, so no other machine can link to it; give it endpoints in `core_nodes` or --listen / --connect",
            share.name
        ));
    }
    let presence = presence::announce(router, namespace, &share.name, out.clone())
        .await
        .map_err(|e| out.note(&e.to_string()))
        .ok();
    let ids: Vec<&str> = share
        .instances
        .iter()
        .map(|&i| stack.plan.instances[i].instance_id.as_str())
        .collect();
    out.note(&format!(
        "core node {}: {} (router on {}{})",
        share.name,
        if ids.is_empty() {
            "no instances, the router only".to_string()
        } else {
            ids.join(", ")
        },
        listen.join(", "),
        if connect.is_empty() {
            String::new()
        } else {
            format!(", linked to {}", connect.join(", "))
        }
    ));
    presence
}

/// What every instance of this launch shares in its plan.
struct Instances<'a> {
    /// The grace window this process's environment sets (every instance
    /// inherits it), for instances whose `env_vars` set none.
    inherited_grace: Option<f64>,
    namespace: &'a str,
    /// Where instances connect (the launch's router).
    connect: Vec<String>,
    /// The Unix sockets instances use instead, when this host has them.
    local: Option<&'a crate::local_links::LocalLinks>,
    secured: Option<&'a Secured>,
    /// The core node of every instance of the stack (its machine's name,
    /// or this launch's when the launcher names no machines).
    cores: HashMap<String, String>,
}

impl Instances<'_> {
    /// Each instance of `share`, ready to start: its plan (runtime config)
    /// and its program.
    fn plan(
        &self,
        stack: &StackCheck,
        share: &placement::Share,
        programs: &HashMap<Identity, Vec<String>>,
    ) -> Vec<Result<Planned, StartError>> {
        share
            .instances
            .iter()
            .zip(&share.core_of)
            .enumerate()
            .map(|(index, (&i, core_node))| {
                let inst = &stack.plan.instances[i];
                let deployment = &stack.deployments[inst.deployment];
                let node = deployment.resolved.node.identity();
                let argv = programs
                    .get(&node)
                    .cloned()
                    .ok_or_else(|| StartError::NoProgram {
                        instance: inst.instance_id.clone(),
                    })?;
                let use_sim_time = stack
                    .launcher
                    .instances()
                    .find(|(_, i)| i.instance_id == inst.instance_id)
                    .and_then(|(_, i)| i.framework.use_sim_time)
                    .unwrap_or(false);
                Ok(Planned {
                    config: self.config(inst, index, core_node, use_sim_time),
                    node: node.to_string(),
                    dir: deployment.dir.clone(),
                    argv,
                    env: inst.env_vars.clone(),
                    restart: inst.restart,
                    has_hooks: has_hooks(&deployment.resolved.node.execution.language),
                })
            })
            .collect()
    }

    /// One instance's runtime config: the launcher's decisions for it
    /// (`index`: its place among the launch's instances).
    fn config(
        &self,
        inst: &peppy_schema::InstancePlan,
        index: usize,
        core_node: &str,
        use_sim_time: bool,
    ) -> StartupConfig {
        let login = self
            .secured
            .and_then(|s| s.secrets.instances.get(&inst.instance_id).cloned());
        // On this host's Unix sockets: the router's, and (a peer, links to
        // other peers directly) one of its own. A client (secured) only
        // reaches the router, which checks what it sends, over any link.
        let (listen, connect) = match self.local {
            Some(local) => (
                match self.secured {
                    Some(_) => Vec::new(),
                    None => local.instance(index).into_iter().collect(),
                },
                vec![local.router()],
            ),
            None => (Vec::new(), self.connect.clone()),
        };
        // The producers on other machines, for the slots' ProducerRefs.
        let producer_cores = inst
            .slots
            .iter()
            .flat_map(|s| crate::core_view::producers(&s.binding))
            .filter_map(|p| {
                let core = self.cores.get(p.as_str())?;
                (core != core_node).then(|| (p.clone(), core.clone()))
            })
            .collect();
        StartupConfig {
            producer_cores,
            instance_id: inst.instance_id.clone(),
            core_node: core_node.to_string(),
            namespace: self.namespace.to_string(),
            slots: inst.slots.clone(),
            pairs: inst.pairs.clone(),
            parameters: inst.parameters.clone(),
            // Secured, every instance is a client of the router, which
            // checks everything it sends and receives; a peer would link to
            // other peers directly, past the router.
            zenoh: Endpoints {
                mode: self.secured.map(|_| "client".to_string()),
                listen,
                connect,
                multicast_scouting: false,
                login,
            },
            use_sim_time,
            // The one the instance's environment sets, which the node reads
            // too; none leaves it to the node's code (else 5 s).
            shutdown_grace_secs: inst.shutdown_grace_secs.or(self.inherited_grace),
            // Secured, every message goes through the router, which checks
            // it: no link past it.
            direct_links: match self.secured {
                Some(_) => None,
                None => self.local.and_then(|l| l.direct()),
            },
        }
    }
}

/// What `ps`, `logs` and the inspection commands read about this launch.
fn launch_record(
    args: &UpArgs,
    share: &placement::Share,
    namespace: &str,
    instances: &Instances<'_>,
    run_dir: &Path,
    planned: &[Result<Planned, StartError>],
) -> LaunchRecord {
    LaunchRecord {
        pid: std::process::id(),
        launcher: std::fs::canonicalize(&args.launcher).unwrap_or_else(|_| args.launcher.clone()),
        namespace: namespace.to_string(),
        core_node: share.name.clone(),
        connect: instances.connect.clone(),
        run_dir: run_dir.to_path_buf(),
        started_at_ms: runs::now_ms(),
        instances: planned
            .iter()
            .flatten()
            .map(|p| (p.config.instance_id.clone(), p.node.clone()))
            .collect(),
        login: instances.secured.map(|s| s.secrets.operator.clone()),
        recorder_login: instances.secured.map(|s| s.secrets.recorder.clone()),
        control: None,
    }
}

/// One instance ready to start.
pub(crate) struct Planned {
    pub(crate) config: StartupConfig,
    pub(crate) node: String,
    pub(crate) dir: std::path::PathBuf,
    pub(crate) argv: Vec<String>,
    pub(crate) env: Vec<(String, String)>,
    pub(crate) restart: peppy_schema::RestartPolicy,
    /// Whether the node runs on a peppy runtime (Rust or Python), whose
    /// shutdown hooks get their window before SIGTERM.
    pub(crate) has_hooks: bool,
}

/// Whether a node of `language` runs on a peppy runtime, with shutdown
/// hooks; a shell node's `run_cmd` is anything.
pub(crate) fn has_hooks(language: &str) -> bool {
    ["rust", "python"]
        .iter()
        .any(|l| language.eq_ignore_ascii_case(l))
}

/// Why one instance could not be started (the launch then stops the
/// instances already started).
#[derive(Debug, thiserror::Error)]
pub(crate) enum StartError {
    /// No program was prepared for the instance's node.
    #[error("no program for `{instance}`")]
    NoProgram {
        /// The instance id.
        instance: String,
    },
    /// The instance's runtime config could not be written.
    #[error("cannot write {}: {source}", path.display())]
    WriteConfig {
        /// The runtime config file.
        path: std::path::PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The instance's program did not start.
    #[error("instance `{instance}` failed to start: {source} (log: {})", log.display())]
    Spawn {
        /// The instance id.
        instance: String,
        /// Its log.
        log: std::path::PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// Starts every instance in order (stopping those started if one cannot
/// start), supervises them until they end or Ctrl-C: clean, or
/// `InstanceFailed`. With a control socket, instances can be stopped,
/// started and added while the launch runs (`registration` then follows
/// what it runs).
pub(crate) async fn run_instances(
    planned: Vec<Result<Planned, StartError>>,
    run_dir: &Path,
    grace: Duration,
    out: Arc<Output>,
    view: Option<Arc<crate::core_view::LaunchView>>,
    control: Option<crate::control::Listener>,
    mut registration: Option<runs::Registered>,
) -> Outcome {
    let signals = StopSignals::default();
    let ctrl_c = tokio::spawn(stop_on_interrupts(signals.clone(), out.clone()));
    let (add_tx, mut additions) = tokio::sync::mpsc::unbounded_channel();
    let controls = Arc::new(crate::control::Controls {
        signals: signals.clone(),
        instances: Default::default(),
        additions: add_tx,
    });
    let order: Arc<std::sync::Mutex<Vec<Stopping>>> = Default::default();
    let mut running = tokio::task::JoinSet::new();
    // One instance started and supervised: in the launch's stop order,
    // reachable by the control socket, awaited with the others. Returns
    // its id.
    let start =
        |p: Planned,
         running: &mut tokio::task::JoinSet<(String, Result<Ended, tokio::task::JoinError>)>|
         -> Result<String, StartError> {
            let takes_from = producers_of(&p.config);
            let own = signals.instance();
            let stop = own.stop.clone();
            let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
            let (id, finished, task, instance_grace) =
                start_instance(p, run_dir, grace, &own, &out, view.clone(), rx)?;
            lock(&order).push(Stopping {
                id: id.clone(),
                takes_from,
                stop,
                finished,
            });
            controls.add(&id, tx, instance_grace);
            let ended_id = id.clone();
            running.spawn(async move { (ended_id, task.await) });
            Ok(id)
        };
    // An instance added later (`run --join`) reads and serves the others
    // over the launch's direct links as they do (none for a secured launch,
    // whose instances have none).
    let direct_links = planned
        .iter()
        .filter_map(|p| p.as_ref().ok())
        .find_map(|p| p.config.direct_links.clone());
    let mut start_failure = None;
    for p in planned {
        match p.and_then(|p| start(p, &mut running)) {
            Ok(_) => {}
            Err(why) => {
                out.note(&why.to_string());
                out.note("stopping the instances already started");
                signals.stopping.cancel();
                start_failure = Some(why);
                break;
            }
        }
    }
    let in_order = tokio::spawn(stop_in_order(signals.stopping.clone(), order.clone()));
    let controlled =
        control.map(|listener| tokio::spawn(crate::control::serve(listener, controls.clone())));
    if start_failure.is_none() {
        // A detached launch's foreground process returns now.
        crate::detach::started(run_dir);
    }
    let mut failed = start_failure.is_some();
    loop {
        tokio::select! {
            joined = running.join_next() => match joined {
                None => break,
                Some(Ok((id, Ok(ended)))) => {
                    failed |= ended.is_failure();
                    if matches!(ended, Ended::Stopped) {
                        out.note(&format!("`{id}` stopped"));
                    }
                }
                Some(Ok((id, Err(e)))) => {
                    out.note(&format!("supervising `{id}` failed: {e}"));
                    failed = true;
                }
                Some(Err(e)) => {
                    out.note(&format!("supervising an instance failed: {e}"));
                    failed = true;
                }
            },
            Some((addition, reply)) = additions.recv() => {
                let addition: crate::control::Addition = addition;
                // Checked here, where additions are taken one at a time: two
                // joiners of one id cannot both pass.
                let id = addition.config.instance_id.clone();
                let refusal = if signals.stopping.is_cancelled() {
                    Some("the launch is stopping".to_string())
                } else if lock(&order).iter().any(|i| i.id == id) {
                    Some(format!("the launch has an instance `{id}` already; give another `--instance-id`"))
                } else {
                    None
                };
                if let Some(why) = refusal {
                    let _ = reply.send(Err(why));
                    continue;
                }
                let node = addition.node.clone();
                let mut config = addition.config;
                config.direct_links = direct_links.clone();
                let planned = Planned {
                    config,
                    node: addition.node,
                    dir: addition.dir,
                    argv: addition.argv,
                    env: Vec::new(),
                    restart: peppy_schema::RestartPolicy::No,
                    has_hooks: addition.has_hooks,
                };
                let answer = start(planned, &mut running)
                    .map(|id| {
                        if let Some(r) = registration.as_mut() {
                            r.add_instance(&id, &node, &out);
                        }
                        let pid = std::fs::read_to_string(run_dir.join(format!("{id}.pid")))
                            .unwrap_or_default();
                        format!("`{id}` ({node}) started in the launch as pid {}", pid.trim())
                    })
                    .map_err(|why| why.to_string());
                let _ = reply.send(answer);
            }
        }
    }
    ctrl_c.abort();
    in_order.abort();
    if let Some(task) = controlled {
        task.abort();
    }
    drop(registration);
    if failed {
        out.note("done: an instance failed");
        Err(LaunchError::InstanceFailed)
    } else {
        out.note("done");
        Ok(())
    }
}

fn lock<T>(m: &std::sync::Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// One started instance, as the launch stops it.
#[derive(Clone)]
struct Stopping {
    id: String,
    /// The instances its slots take from.
    takes_from: Vec<String>,
    /// Its turn to stop.
    stop: tokio_util::sync::CancellationToken,
    /// Fired when its supervisor has returned.
    finished: tokio_util::sync::CancellationToken,
}

/// The producers an instance's slots are bound to.
fn producers_of(config: &StartupConfig) -> Vec<String> {
    use peppy_schema::SlotBinding;
    config
        .slots
        .iter()
        .flat_map(|slot| match &slot.binding {
            SlotBinding::Pinned { producer } => vec![producer.clone()],
            SlotBinding::Set { producers, .. } | SlotBinding::FromAnyBound { producers } => {
                producers.clone()
            }
            SlotBinding::FromAnyUnbound => Vec::new(),
        })
        .collect()
}

/// Once the launch stops, stops its instances in waves: first those no
/// running instance takes from, and once they have ended, the producers
/// they took from. A controller's shutdown hooks can then still reach the
/// arm it drives (to cancel a goal, to send a last command), as it would
/// on a robot stopped by hand. Instances that take from each other stop
/// together.
async fn stop_in_order(
    stopping: tokio_util::sync::CancellationToken,
    instances: Arc<std::sync::Mutex<Vec<Stopping>>>,
) {
    stopping.cancelled().await;
    loop {
        // Instances added while the launch ran are in the list too; none
        // is added once it stops.
        let mut left: Vec<Stopping> = lock(&instances).clone();
        left.retain(|i| !i.finished.is_cancelled());
        if left.is_empty() {
            return;
        }
        let taken_from: std::collections::HashSet<&str> = left
            .iter()
            .flat_map(|i| i.takes_from.iter().map(String::as_str))
            .collect();
        let mut wave: Vec<&Stopping> = left
            .iter()
            .filter(|i| !taken_from.contains(i.id.as_str()))
            .collect();
        if wave.is_empty() {
            // What is left takes from itself in a circle.
            wave = left.iter().collect();
        }
        for i in &wave {
            i.stop.cancel();
        }
        for i in wave {
            i.finished.cancelled().await;
        }
    }
}

/// A first Ctrl-C (or SIGTERM) stops the instances (consumers first), a
/// second kills them.
async fn stop_on_interrupts(signals: StopSignals, out: Arc<Output>) {
    wait_for_interrupt().await;
    out.note("stopping (press Ctrl-C again to kill at once)");
    signals.stopping.cancel();
    wait_for_interrupt().await;
    out.note("killing every instance");
    signals.kill.cancel();
}

/// Writes an instance's runtime config, starts it and hands it to its
/// supervisor: the instance's id, a token fired when its supervisor
/// returns, and its supervising task.
fn start_instance(
    p: Planned,
    run_dir: &Path,
    grace: Duration,
    signals: &StopSignals,
    out: &Arc<Output>,
    view: Option<Arc<crate::core_view::LaunchView>>,
    commands: tokio::sync::mpsc::UnboundedReceiver<supervise::InstanceCommand>,
) -> Result<
    (
        String,
        tokio_util::sync::CancellationToken,
        tokio::task::JoinHandle<Ended>,
        Duration,
    ),
    StartError,
> {
    let id = p.config.instance_id.clone();
    let config_path = run_dir.join(format!("{id}.json"));
    // It may hold the instance's password: readable by this user only.
    crate::security::write_private(
        &config_path,
        &serde_json::to_vec_pretty(&p.config).unwrap_or_default(),
    )
    .map_err(|source| StartError::WriteConfig {
        path: config_path.clone(),
        source,
    })?;
    // Never SIGTERM a node while its shutdown hooks may still run: the
    // node would take it as a second signal and exit at once.
    let grace = if p.has_hooks {
        grace.max(hooks_window(&p.config) + HOOKS_MARGIN)
    } else {
        grace
    };
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
    let (child, pumps) = supervise::spawn(&spec, out).map_err(|source| StartError::Spawn {
        instance: id.clone(),
        log: spec.log.clone(),
        source,
    })?;
    out.note(&format!(
        "started `{id}` ({}) as pid {}",
        p.node,
        child.id().unwrap_or(0)
    ));
    let supervisor = supervise::supervise(
        spec,
        child,
        pumps,
        grace,
        signals.clone(),
        out.clone(),
        commands,
    );
    let finished = tokio_util::sync::CancellationToken::new();
    let done = finished.clone();
    let ended_id = id.clone();
    let task = tokio::spawn(async move {
        let ended = supervisor.await;
        if let Some(view) = view {
            view.ended(&ended_id, ended.is_failure());
        }
        done.cancel();
        ended
    });
    Ok((id, finished, task, grace))
}

/// What a stopping node is given beyond its hooks' window, to close
/// messaging and exit.
pub(crate) const HOOKS_MARGIN: Duration = Duration::from_secs(2);

/// The window a node's shutdown hooks may take, as its plan carries it
/// (decided by [`peppy_schema::grace_window`] from the instance's
/// `env_vars` or this process's environment), else 5 s. A window set only
/// in the node's code is not known here: `--grace` covers it.
pub(crate) fn hooks_window(config: &StartupConfig) -> Duration {
    config.shutdown_grace_secs.map_or(
        peppy_runtime::DEFAULT_SHUTDOWN_GRACE,
        Duration::from_secs_f64,
    )
}

/// This process's `PEPPY_SHUTDOWN_GRACE_SECS`, which every node it starts
/// inherits: checked once, before anything starts.
pub(crate) fn inherited_grace() -> Result<Option<f64>, UsageError> {
    let set = std::env::var(peppy_schema::SHUTDOWN_GRACE_ENV).ok();
    peppy_schema::grace_window_env(set.as_deref())
        .map(|window| window.map(|w| w.as_secs_f64()))
        .map_err(UsageError::ShutdownGrace)
}

async fn wait_for_interrupt() {
    interrupts_from_now().await
}

/// Ctrl-C or SIGTERM, listened to from this call on (not from the first
/// poll), so a signal sent right after a "ready" message is not lost.
fn interrupts_from_now() -> impl std::future::Future<Output = ()> {
    use tokio::signal::unix::{SignalKind, signal};
    let mut int = signal(SignalKind::interrupt()).ok();
    let mut term = signal(SignalKind::terminate()).ok();
    async move {
        tokio::select! {
            () = next_signal(int.as_mut()) => {}
            () = next_signal(term.as_mut()) => {}
        }
    }
}

/// The next delivery of a signal, or never when it could not be listened to.
async fn next_signal(s: Option<&mut tokio::signal::unix::Signal>) {
    match s {
        Some(s) => {
            s.recv().await;
        }
        None => std::future::pending::<()>().await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn instance(id: &str, takes_from: &[&str]) -> Stopping {
        Stopping {
            id: id.to_string(),
            takes_from: takes_from.iter().map(|s| s.to_string()).collect(),
            stop: tokio_util::sync::CancellationToken::new(),
            finished: tokio_util::sync::CancellationToken::new(),
        }
    }

    /// Consumers stop first; a producer's turn comes once every running
    /// instance that takes from it has ended; a circle stops together.
    #[tokio::test]
    async fn a_launch_stops_consumers_before_their_producers() {
        let brain = instance("brain", &["controller", "camera"]);
        let controller = instance("controller", &["left_arm", "right_arm"]);
        let (left, right, camera) = (
            instance("left_arm", &[]),
            instance("right_arm", &[]),
            instance("camera", &[]),
        );
        let a = instance("a", &["b"]);
        let b = instance("b", &["a"]);
        let tokens = |i: &Stopping| (i.stop.clone(), i.finished.clone());
        let (brain_stop, brain_done) = tokens(&brain);
        let (controller_stop, controller_done) = tokens(&controller);
        let (left_stop, left_done) = tokens(&left);
        let (right_stop, right_done) = tokens(&right);
        let (camera_stop, camera_done) = tokens(&camera);
        let (a_stop, a_done) = tokens(&a);
        let (b_stop, b_done) = tokens(&b);
        // The right arm has ended already (crashed): it is not waited for.
        right_done.cancel();
        let stopping = tokio_util::sync::CancellationToken::new();
        let task = tokio::spawn(stop_in_order(
            stopping.clone(),
            Arc::new(std::sync::Mutex::new(vec![
                left, brain, right, camera, controller, a, b,
            ])),
        ));
        let settle = || tokio::time::sleep(Duration::from_millis(50));
        settle().await;
        assert!(
            !brain_stop.is_cancelled(),
            "nothing stops before the launch does"
        );
        stopping.cancel();
        settle().await;
        // Wave 1: the brain, which nothing takes from. The circle (each of
        // `a` and `b` takes from the other) waits until nothing else is left.
        assert!(brain_stop.is_cancelled());
        assert!(!a_stop.is_cancelled());
        assert!(!controller_stop.is_cancelled() && !camera_stop.is_cancelled());
        assert!(!left_stop.is_cancelled());
        brain_done.cancel();
        settle().await;
        assert!(controller_stop.is_cancelled() && camera_stop.is_cancelled());
        assert!(
            !left_stop.is_cancelled(),
            "the arm outlives its controller's stop"
        );
        controller_done.cancel();
        camera_done.cancel();
        settle().await;
        assert!(left_stop.is_cancelled());
        assert!(
            !right_stop.is_cancelled(),
            "an ended instance is not stopped again"
        );
        left_done.cancel();
        settle().await;
        assert!(a_stop.is_cancelled() && b_stop.is_cancelled());
        a_done.cancel();
        b_done.cancel();
        tokio::time::timeout(Duration::from_secs(5), task)
            .await
            .expect("the stop ends once every instance has")
            .unwrap();
    }

    #[test]
    fn the_hooks_window_is_the_one_the_node_will_read() {
        let config = |grace: Option<f64>| StartupConfig {
            instance_id: "a".into(),
            core_node: "c".into(),
            namespace: "n".into(),
            slots: Vec::new(),
            pairs: Vec::new(),
            parameters: serde_json::Value::Null,
            zenoh: Endpoints::default(),
            use_sim_time: false,
            shutdown_grace_secs: grace,
            direct_links: None,
            producer_cores: Default::default(),
        };
        assert_eq!(hooks_window(&config(None)), Duration::from_secs(5));
        assert_eq!(
            hooks_window(&config(Some(7200.0))),
            Duration::from_secs(7200)
        );
        assert!(has_hooks("rust") && has_hooks("Python") && !has_hooks("shell"));
    }
}
