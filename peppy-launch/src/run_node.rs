//! `peppy-launch run NODE`: one node started from the command line, with
//! the same checks of its bindings and parameters as a launcher.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use peppy_runtime::StartupConfig;
use peppy_runtime::wire::keys::{Claim, claim_selector};
use peppy_schema::{
    DocumentKind, Identity, Launch, NodeCheck, NodeDoc, NodeModel, PairEnd, PairingSlot,
    RepoOptions, check_node_with, node_file,
};

use crate::cli::{PlanArgs, RunArgs};
use crate::error::{LaunchError, Result, SetupError, UsageError};
use crate::executable;
use crate::output::Output;
use crate::report;
use crate::runs::{self, LaunchRecord};
use crate::up::{Planned, open_router, run_instances};

/// The well-known local port: the first `run` listens here, later ones join.
use crate::inspect::LOCAL_HUB;

/// The node `node` names (a path or a `name:tag`), its documents checked;
/// its diagnostics are printed when they are not valid.
fn checked_node(node: &str, repos: &[PathBuf]) -> Result<(PathBuf, NodeCheck)> {
    let options = crate::repositories::options(repos.to_vec())?;
    let file = locate(node, &options)?;
    match check_node_with(&file, &options, &crate::sources::Fetcher::new()) {
        Ok(check) => Ok((file, check)),
        Err(diags) => {
            report::print_human(&diags);
            eprintln!(
                "invalid: {}; nothing was started",
                report::count(diags.error_count(), "error")
            );
            Err(LaunchError::Invalid {
                errors: diags.error_count(),
            })
        }
    }
}

/// `peppy-launch plan`: the plan a standalone command line gives a node,
/// decided by the engine a launch uses (`peppy_runtime::startup_from_flags`).
pub(crate) fn plan(args: &PlanArgs) -> Result {
    let model = match (&args.model, &args.node) {
        (Some(path), _) => read_model(path)?,
        (None, Some(node)) => NodeModel::of(&checked_node(node, &args.repos)?.1.resolved.node),
        (None, None) => return Err(UsageError::NoNodeOrModel.into()),
    };
    let flags = std::iter::once("peppy-launch plan".to_string())
        .chain(args.args.iter().cloned())
        .collect();
    let config = peppy_runtime::startup_from_flags(&model, flags)?;
    let text = serde_json::to_string_pretty(&config).map_err(SetupError::PlanJson)?;
    println!("{text}");
    Ok(())
}

/// A node model from `path` (`-`: standard input).
fn read_model(path: &std::path::Path) -> Result<NodeModel> {
    use std::io::Read;
    let mut text = String::new();
    let read = if path.as_os_str() == "-" {
        std::io::stdin().read_to_string(&mut text).map(drop)
    } else {
        std::fs::read_to_string(path).map(|t| text = t)
    };
    read.map_err(|source| UsageError::ReadModel {
        path: path.to_path_buf(),
        source,
    })?;
    NodeModel::from_json(&text).map_err(|source| {
        UsageError::NotAModel {
            path: path.to_path_buf(),
            source,
        }
        .into()
    })
}

pub(crate) fn run(args: &RunArgs) -> Result {
    let joined = match &args.join {
        Some(which) => Some(crate::manage::joinable(which, args.namespace.as_deref())?),
        None => None,
    };
    let (file, check) = checked_node(&args.node, &args.repos)?;
    let doc: &NodeDoc = &check.resolved.node;
    let mut flags = vec!["peppy-launch".to_string()];
    if let Some(launch) = &joined
        && args.namespace.is_none()
    {
        flags.extend(["--namespace".into(), launch.namespace.clone()]);
    }
    if let Some(id) = &args.instance_id {
        flags.extend(["--instance-id".into(), id.clone()]);
    }
    for b in &args.bind {
        flags.extend(["--bind".into(), b.clone()]);
    }
    for l in &args.link {
        flags.extend(["--link".into(), l.clone()]);
    }
    for v in &args.vacant_link {
        flags.extend(["--vacant-link".into(), v.clone()]);
    }
    if let Some(ns) = &args.namespace {
        flags.extend(["--namespace".into(), ns.clone()]);
    }
    if args.use_sim_time {
        flags.push("--use-sim-time".into());
    }
    flags.extend(args.overrides.iter().cloned());
    let model = NodeModel::of(doc);
    let mut config = peppy_runtime::startup_from_flags(&model, flags)?;
    config.core_node = format!("run-{:x}", std::process::id());
    config.shutdown_grace_secs = crate::up::inherited_grace()?.or(config.shutdown_grace_secs);
    if let Launch::Container(container) = doc.execution.launch() {
        let dir = file.parent().unwrap_or(std::path::Path::new("."));
        let node = doc.identity().to_string();
        match crate::container::plan(dir, container, &node) {
            Ok(plan) => eprintln!("peppy-launch: {}", crate::container::describe(&node, &plan)),
            Err(source) => {
                return Err(crate::executable::ExecutableError::Container { node, source }.into());
            }
        }
    }
    let dir = file.parent().map(PathBuf::from).unwrap_or_default();
    if crate::python_sync::is_python(&check.resolved) {
        // The generated package follows the documents before every start.
        crate::python_sync::write_package(&check.resolved, &dir)?;
    } else if crate::rust_libs::wants_libs(&check.resolved, &dir) {
        crate::rust_libs::write_libs(&check.resolved, &dir)?;
    }
    if let Some(launch) = &joined {
        crate::manage::check_links(launch, &config, &args.repos)?;
    }
    let runtime = crate::tokio_runtime(None)?;
    runtime.block_on(async move {
        let out = Arc::new(Output::new(&[config.instance_id.as_str()]));
        let build = !args.no_build;
        if build && let Some(cmd) = executable::build_of(&doc.execution) {
            out.note(&format!("building {}: {}", doc.identity(), cmd.join(" ")));
        }
        let argv = executable::prepare(
            &doc.identity().to_string(),
            &doc.identity().to_string(),
            &doc.name,
            &dir,
            &doc.execution,
            build,
        )
        .await?;
        if let Some(launch) = joined {
            // The launch starts and supervises it as one of its own.
            config.core_node = launch.core_node.clone();
            config.zenoh.connect = launch.connect.clone();
            config.zenoh.listen = args.listen.clone();
            refuse_held_peers(&model.pairings, &config).await?;
            let addition = crate::control::Addition {
                config,
                node: doc.identity().to_string(),
                dir,
                argv,
                has_hooks: crate::up::has_hooks(&doc.execution.language),
            };
            return crate::manage::add(&launch, addition);
        }
        // Join the given endpoints, or the local hub: the first `run` on a
        // machine hosts it, later ones connect to it.
        let mut _hub = None;
        config.zenoh.connect = if args.connect.is_empty() {
            if let Ok(session) = open_router(&[LOCAL_HUB.to_string()], &[], false, None).await {
                _hub = Some(session);
            }
            vec![LOCAL_HUB.to_string()]
        } else {
            args.connect.clone()
        };
        config.zenoh.listen = args.listen.clone();
        if _hub.is_none() {
            // A stack is already there: a linked peer slot may be taken.
            refuse_held_peers(&model.pairings, &config).await?;
        }
        let run_dir = std::env::temp_dir().join(format!("peppy-run-{}", std::process::id()));
        std::fs::create_dir_all(&run_dir).map_err(|source| SetupError::CreateDir {
            path: run_dir.clone(),
            source,
        })?;
        out.note(&format!(
            "namespace {}; log in {}",
            config.namespace,
            run_dir.display()
        ));
        let control = crate::control::Listener::bind()
            .map_err(|e| {
                out.note(&format!(
                    "no control socket (`stop` and `node stop` cannot reach this run): {e}"
                ))
            })
            .ok();
        let record = LaunchRecord {
            pid: std::process::id(),
            launcher: std::fs::canonicalize(&file).unwrap_or_else(|_| file.clone()),
            namespace: config.namespace.clone(),
            core_node: config.core_node.clone(),
            connect: config.zenoh.connect.clone(),
            run_dir: run_dir.clone(),
            started_at_ms: runs::now_ms(),
            instances: vec![(config.instance_id.clone(), doc.identity().to_string())],
            login: None,
            recorder_login: None,
            control: control.as_ref().map(|c| c.path().to_path_buf()),
        };
        let registration = runs::Registered::new(record)
            .map_err(|e| out.note(&e.to_string()))
            .ok();
        let planned = Planned {
            node: doc.identity().to_string(),
            dir,
            argv,
            env: Vec::new(),
            restart: peppy_schema::RestartPolicy::No,
            has_hooks: crate::up::has_hooks(&doc.execution.language),
            config,
        };
        // The first `run` hosts the hub, and is its nodes' core node: the
        // stack clock, the datastore, `info` and `stack::list`.
        let (mut _clock, mut _core, mut view) = (None, Vec::new(), None);
        if let Some(hub) = &_hub {
            let namespace = planned.config.namespace.clone();
            _clock = peppy_runtime::clock::serve(hub, &namespace)
                .await
                .map_err(|e| out.note(&format!("the stack clock is not served: {e}")))
                .ok();
            let core = planned.config.core_node.clone();
            let pairings = model.pairings.clone();
            let v = Arc::new(crate::core_view::LaunchView::new(
                &core,
                crate::core_view::port_of(&[LOCAL_HUB.to_string()]),
                &[&planned],
                &|_| pairings.clone(),
            ));
            _core = crate::up::serve_core(hub, &namespace, &core, &[&planned], &v, &out).await;
            view = Some(v);
        }
        run_instances(
            vec![Ok(planned)],
            &run_dir,
            args.grace,
            out,
            view,
            control,
            registration,
        )
        .await
    })
}

/// How long `run --link` waits for the stack's claim tokens.
const CLAIMS_WAIT: Duration = Duration::from_secs(2);

/// A pairing slot's claim as read from its token (docs/PAIRINGS.md §3).
#[derive(Debug, Clone, PartialEq, Eq)]
struct HeldClaim {
    role: String,
    instance: String,
    link_id: String,
    peer: Option<(String, String)>,
}

impl HeldClaim {
    fn read(key: &str) -> Option<HeldClaim> {
        let c = Claim::parse(key)?;
        Some(HeldClaim {
            role: c.role.into(),
            instance: c.instance.into(),
            link_id: c.link_id.into(),
            peer: c.peer.map(|(i, l)| (i.into(), l.into())),
        })
    }

    fn claims(&self, instance: &str, link_id: &str) -> bool {
        self.peer
            .as_ref()
            .is_some_and(|(i, l)| i == instance && l == link_id)
    }
}

/// `run --link SLOT@PEER[/PEER_SLOT]` starts only against a peer slot that
/// is free: a slot paired with another live instance (it claims that
/// instance's slot, which claims it back) refuses the link. A peer not up
/// yet, or a stack that cannot be reached, is left to the node: it waits.
async fn refuse_held_peers(slots: &[PairingSlot], config: &StartupConfig) -> Result {
    let linked: Vec<(&PairingSlot, &PairEnd)> = config
        .pairs
        .iter()
        .filter_map(|plan| {
            let slot = slots
                .iter()
                .find(|s| s.link_id == plan.link_id && !s.observer)?;
            match plan.peers.as_slice() {
                [peer] => Some((slot, peer)),
                _ => None,
            }
        })
        .collect();
    if linked.is_empty() {
        return Ok(());
    }
    let endpoints = peppy_runtime::Endpoints {
        mode: Some("client".into()),
        listen: Vec::new(),
        connect: config.zenoh.connect.clone(),
        multicast_scouting: false,
        login: None,
    };
    let Ok(zenoh_config) = endpoints.zenoh_config() else {
        return Ok(());
    };
    let session = match tokio::time::timeout(CLAIMS_WAIT, zenoh::open(zenoh_config)).await {
        Ok(Ok(session)) => session,
        _ => return Ok(()),
    };
    for (slot, peer) in linked {
        let claims = read_claims(&session, &config.namespace, slot).await;
        if let Some(held) = held_by_other(slot, peer, &config.instance_id, &claims) {
            let _ = session.close().await;
            return Err(held.into());
        }
    }
    let _ = session.close().await;
    Ok(())
}

/// Every claim of `slot`'s pairing alive now (bounded by [`CLAIMS_WAIT`]).
async fn read_claims(session: &zenoh::Session, ns: &str, slot: &PairingSlot) -> Vec<HeldClaim> {
    let selector = claim_selector(ns, &slot.pairing.name, &slot.pairing.tag);
    let Ok(replies) = session
        .liveliness()
        .get(selector)
        .timeout(CLAIMS_WAIT)
        .await
    else {
        return Vec::new();
    };
    let mut out = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result()
            && let Some(c) = HeldClaim::read(sample.key_expr().as_str())
        {
            out.push(c);
        }
    }
    out
}

/// The refusal when every slot of `peer` that `slot` could link to is
/// paired with someone other than `me/slot`; `None` when one is free (or
/// the peer is not up: there is nothing to refuse yet).
fn held_by_other(
    slot: &PairingSlot,
    peer: &PairEnd,
    me: &str,
    claims: &[HeldClaim],
) -> Option<PairLinkRefused> {
    let counterpart = |role: &str| {
        if slot.counterpart.is_empty() {
            role != slot.role
        } else {
            role == slot.counterpart
        }
    };
    let candidates: Vec<&HeldClaim> = claims
        .iter()
        .filter(|c| c.instance == peer.instance && counterpart(&c.role))
        .filter(|c| peer.link_id.as_ref().is_none_or(|l| *l == c.link_id))
        .collect();
    let mut held = Vec::new();
    for c in &candidates {
        let holder = c
            .peer
            .as_ref()
            .filter(|(i, l)| !(i == me && *l == slot.link_id));
        let (i, l) = holder?;
        // Paired only while the claimed slot claims it back.
        if !claims
            .iter()
            .any(|o| o.instance == *i && o.link_id == *l && o.claims(&c.instance, &c.link_id))
        {
            return None;
        }
        held.push((format!("{}/{}", c.instance, c.link_id), format!("{i}/{l}")));
    }
    let (peer_slot, holder) = held.into_iter().next()?;
    Some(PairLinkRefused {
        slot: slot.link_id.clone(),
        pairing: slot.pairing.to_string(),
        peer_slot,
        holder,
    })
}

/// `run --link` names a peer slot that is already paired with another
/// live instance (`PairingSlotAlreadyPaired`).
#[derive(Debug, thiserror::Error)]
#[error(
    "pairing slot `{slot}` cannot link to `{peer_slot}` ({pairing}): it is already paired with `{holder}`; link to a free slot, or stop the instance holding it first (PairingSlotAlreadyPaired)"
)]
pub struct PairLinkRefused {
    /// This node's pairing slot.
    pub slot: String,
    /// The pairing (`name:tag`).
    pub pairing: String,
    /// The peer's slot, `instance/link_id`.
    pub peer_slot: String,
    /// Who holds it, `instance/link_id`.
    pub holder: String,
}

/// Why `NODE` (of `run`, `plan`, `sync`) names no node.
#[derive(Debug, thiserror::Error)]
pub enum LocateError {
    /// `NODE` is no existing path, and no `name:tag` either.
    #[error("`{node}` is neither a path nor a `name:tag`")]
    NotANode {
        /// `NODE` as given.
        node: String,
    },
    /// The repositories list cannot be read.
    #[error(transparent)]
    Repositories(peppy_schema::Diagnostics),
    /// The node's document is in a repository but invalid.
    #[error("`{node}` is defined in {}, but that document is invalid", path.display())]
    Invalid {
        /// The node.
        node: Identity,
        /// Its document.
        path: PathBuf,
    },
    /// No repository provides the node.
    #[error("no repository provides node `{node}`; {searched}")]
    NotFound {
        /// The node.
        node: Identity,
        /// Where it was looked for.
        searched: String,
    },
}

/// `NODE` is a path to a node (directory or peppy.json5) or a `name:tag`
/// found in the repositories.
pub(crate) fn locate(
    node: &str,
    options: &RepoOptions,
) -> std::result::Result<PathBuf, LocateError> {
    let as_path = PathBuf::from(node);
    if as_path.exists() {
        // Absolute: the node's commands run in its own directory, where a
        // path relative to ours would name something else.
        let as_path = std::path::absolute(&as_path).unwrap_or(as_path);
        return Ok(node_file(&as_path));
    }
    let Some(id) = Identity::parse(node) else {
        return Err(LocateError::NotANode {
            node: node.to_string(),
        });
    };
    let cwd = std::env::current_dir().unwrap_or_default();
    let index =
        crate::repositories::index(&options.explicit, &cwd).map_err(LocateError::Repositories)?;
    if let Some(e) = index.node(&id) {
        return Ok(e.path.clone());
    }
    match index.broken(DocumentKind::Node, &id) {
        Some(b) => Err(LocateError::Invalid {
            path: b.path.clone(),
            node: id,
        }),
        None => Err(LocateError::NotFound {
            searched: index.searched(),
            node: id,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slot() -> PairingSlot {
        PairingSlot {
            link_id: "follower".into(),
            pairing: Identity::new("joint_link", "v1"),
            role: "leader".into(),
            counterpart: "follower".into(),
            observer: false,
            sha256: None,
            optional: false,
            cardinality: Default::default(),
            loc: Default::default(),
        }
    }

    fn claim(role: &str, instance: &str, link: &str, peer: Option<(&str, &str)>) -> HeldClaim {
        HeldClaim {
            role: role.into(),
            instance: instance.into(),
            link_id: link.into(),
            peer: peer.map(|(i, l)| (i.into(), l.into())),
        }
    }

    fn peer(target: &str) -> PairEnd {
        PairEnd::parse(target).unwrap()
    }

    #[test]
    fn a_slot_paired_with_another_instance_refuses_the_link() {
        let claims = [
            claim("follower", "arm", "leader", Some(("lead_1", "follower"))),
            claim("leader", "lead_1", "follower", Some(("arm", "leader"))),
        ];
        let refused = held_by_other(&slot(), &peer("arm"), "lead_2", &claims).unwrap();
        assert_eq!(
            (refused.peer_slot.as_str(), refused.holder.as_str()),
            ("arm/leader", "lead_1/follower")
        );
        assert!(refused.to_string().contains("(PairingSlotAlreadyPaired)"));
        assert!(held_by_other(&slot(), &peer("arm/leader"), "lead_2", &claims).is_some());
    }

    #[test]
    fn a_free_waiting_or_absent_slot_is_no_reason_to_refuse() {
        // Claims a slot that does not claim it back: not paired.
        let one_sided = [claim(
            "follower",
            "arm",
            "leader",
            Some(("gone", "follower")),
        )];
        assert!(held_by_other(&slot(), &peer("arm"), "lead_2", &one_sided).is_none());
        let free = [claim("follower", "arm", "leader", None)];
        assert!(held_by_other(&slot(), &peer("arm"), "lead_2", &free).is_none());
        assert!(held_by_other(&slot(), &peer("arm"), "lead_2", &[]).is_none());
        // Paired with this very instance (a restart): its own pair.
        let mine = [
            claim("follower", "arm", "leader", Some(("lead_2", "follower"))),
            claim("leader", "lead_2", "follower", Some(("arm", "leader"))),
        ];
        assert!(held_by_other(&slot(), &peer("arm"), "lead_2", &mine).is_none());
        // A slot of the same role is no candidate.
        let same_role = [
            claim("leader", "arm", "x", Some(("lead_1", "follower"))),
            claim("leader", "lead_1", "follower", Some(("arm", "x"))),
        ];
        assert!(held_by_other(&slot(), &peer("arm"), "lead_2", &same_role).is_none());
    }
}
