//! Start-up inputs: identity, bindings, parameters, namespace and Zenoh
//! endpoints, from the launcher's runtime-config file or, in a standalone
//! `cargo run`, from command-line flags and [`StandaloneConfig`].

use std::hash::{BuildHasher, Hasher};
use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::Parser;
use peppy_schema::{
    BindForm, BindRequest, NodeModel, PairEnd, PairPlan, ParamKind, ParameterSchema, Primitive,
    SlotPlan, assign, fit_pair_plans, fit_plan,
};
use serde::{Deserialize, Serialize};
use serde_json::Value as Json;

use crate::error::{Error, Result};

/// The environment variable naming the launcher's runtime-config file.
pub const RUNTIME_CONFIG_ENV: &str = "PEPPY_RUNTIME_CONFIG";

/// The namespace of nodes started without one.
pub const DEFAULT_NAMESPACE: &str = "default";

/// The core node of a plain `cargo run`.
pub const STANDALONE_CORE: &str = "standalone";

/// What a node is told at start-up: its plan. The launcher writes it as
/// JSON and names the file in `PEPPY_RUNTIME_CONFIG`; `peppy-launch plan`
/// prints the one a standalone command line gives. Its slots and
/// parameters were decided by the binding engine and the parameter checker
/// (`peppy_schema`): a node applies them as they are.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StartupConfig {
    /// This instance's id.
    pub instance_id: String,
    /// The launch (core node) that started it.
    pub core_node: String,
    /// The namespace every key lives under.
    pub namespace: String,
    /// Every slot of the node, in `depends_on` order: what fills it and the
    /// filter its consumers apply.
    #[serde(default)]
    pub slots: Vec<SlotPlan>,
    /// Every pairing slot of the node, in order: the peer a participant
    /// is linked with, the sources an observer watches
    /// (docs/PAIRINGS.md).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pairs: Vec<PairPlan>,
    /// Parameter values, checked and with every default filled in.
    #[serde(default)]
    pub parameters: Json,
    /// How to reach the other nodes.
    #[serde(default)]
    pub zenoh: Endpoints,
    /// Whether the node follows simulated time (the stack's sim ticks)
    /// rather than the OS clock: the instance's `framework.use_sim_time`,
    /// or `--use-sim-time` standalone (see [`crate::clock`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub use_sim_time: bool,
    /// Seconds the node's shutdown hooks may take, all of them together
    /// (above 0). Absent: [`NodeBuilder::shutdown_grace`], else 5 s.
    /// `PEPPY_SHUTDOWN_GRACE_SECS` in the environment overrides both.
    ///
    /// [`NodeBuilder::shutdown_grace`]: crate::NodeBuilder::shutdown_grace
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shutdown_grace_secs: Option<f64>,
    /// The directory of this launch's direct links: instances of one
    /// launch on one host hand small topic messages to each other over
    /// Unix sockets there, beside Zenoh (docs/WIRE.md, "Direct links").
    /// Absent: Zenoh alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direct_links: Option<PathBuf>,
    /// The core node of each producer its slots are bound to that runs on
    /// another core node than this instance, by instance id: what the
    /// slots' `bound_producer(s)` say of it. A producer not listed runs on
    /// this instance's core node.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub producer_cores: std::collections::BTreeMap<String, String>,
}

pub use peppy_schema::{DEFAULT_SHUTDOWN_GRACE, SHUTDOWN_GRACE_ENV};

/// `secs` as a grace window, by the one rule ([`peppy_schema::grace_window`]).
/// `what` names where the value came from, for the error.
fn grace_window(secs: f64, what: &str) -> Result<Duration> {
    peppy_schema::grace_window(secs).map_err(|why| Error::Startup(format!("invalid {what}: {why}")))
}

/// The shutdown grace window of a node: `PEPPY_SHUTDOWN_GRACE_SECS`, else
/// the runtime config's `shutdown_grace_secs`, else the builder's, else 5 s.
pub(crate) fn shutdown_grace(
    config: &StartupConfig,
    builder: Option<Duration>,
) -> Result<Duration> {
    let set = std::env::var_os(SHUTDOWN_GRACE_ENV);
    let set = set.as_ref().map(|raw| raw.to_string_lossy());
    if let Some(window) = peppy_schema::grace_window_env(set.as_deref())
        .map_err(|why| Error::Startup(format!("invalid {SHUTDOWN_GRACE_ENV}: {why}")))?
    {
        return Ok(window);
    }
    match (config.shutdown_grace_secs, builder) {
        (Some(secs), _) => grace_window(secs, "runtime config: `shutdown_grace_secs`"),
        (None, Some(grace)) => grace_window(grace.as_secs_f64(), "NodeBuilder::shutdown_grace"),
        (None, None) => Ok(DEFAULT_SHUTDOWN_GRACE),
    }
}

/// Zenoh connection settings.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct Endpoints {
    /// `peer` (default) or `client`.
    #[serde(default)]
    pub mode: Option<String>,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:0`.
    #[serde(default)]
    pub listen: Vec<String>,
    /// Endpoints to connect to, e.g. `tcp/127.0.0.1:7447`.
    #[serde(default)]
    pub connect: Vec<String>,
    /// Whether to find peers by UDP multicast (off when endpoints are given).
    #[serde(default)]
    pub multicast_scouting: bool,
    /// The credentials to authenticate with, when the router asks for them
    /// (a stack with security on: see docs/SECURITY.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub login: Option<Login>,
}

/// A Zenoh user name and password. `Debug` never shows the password.
#[derive(Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Login {
    /// The user name: an instance's id, or a launch's tools and routers.
    pub user: String,
    /// The password, generated by the launch.
    pub password: String,
}

impl Login {
    /// Makes a Zenoh session authenticate with this login (user-password
    /// authentication). An error never shows the password.
    pub fn apply(&self, config: &mut zenoh::Config) -> Result<()> {
        config
            .insert_json5(
                "transport/auth/usrpwd/user",
                &Json::from(self.user.clone()).to_string(),
            )
            .map_err(|e| Error::Startup(format!("invalid zenoh user `{}`: {e}", self.user)))?;
        config
            .insert_json5(
                "transport/auth/usrpwd/password",
                &Json::from(self.password.clone()).to_string(),
            )
            .map_err(|_| Error::Startup("invalid zenoh password setting".into()))
    }
}

impl std::fmt::Debug for Login {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Login")
            .field("user", &self.user)
            .field("password", &"<redacted>")
            .finish()
    }
}

impl Endpoints {
    /// The Zenoh configuration for these settings.
    pub fn zenoh_config(&self) -> Result<zenoh::Config> {
        let mut c = zenoh::Config::default();
        let set = |c: &mut zenoh::Config, key: &str, value: Json| {
            c.insert_json5(key, &value.to_string()).map_err(|e| {
                Error::Startup(format!("invalid zenoh setting `{key}` = {value}: {e}"))
            })
        };
        set(
            &mut c,
            "mode",
            Json::from(self.mode.clone().unwrap_or_else(|| "peer".into())),
        )?;
        if !self.listen.is_empty() {
            set(&mut c, "listen/endpoints", Json::from(self.listen.clone()))?;
        }
        if !self.connect.is_empty() {
            set(
                &mut c,
                "connect/endpoints",
                Json::from(self.connect.clone()),
            )?;
        }
        set(
            &mut c,
            "scouting/multicast/enabled",
            Json::from(self.multicast_scouting),
        )?;
        // Zenoh copies every ordinary payload of 3 KiB or more that a
        // session sends over a connection with shared memory (a router
        // forwarding a Python node's frame, say) into a pool of its own,
        // whose allocator frees a chunk once its reader's watchdog
        // lapses, even while the reader still holds it; on a loaded host
        // the watchdogs of held chunks were seen to lapse (docs/FAULTS.md,
        // L2). A node's own pool (crate::shm) frees a chunk only once no
        // one holds it.
        set(
            &mut c,
            "transport/shared_memory/transport_optimization/enabled",
            Json::from(false),
        )?;
        if let Some(login) = &self.login {
            login.apply(&mut c)?;
        }
        Ok(c)
    }
}

/// Fallbacks for a plain `cargo run` (no launcher).
#[derive(Debug, Clone, Default)]
pub struct StandaloneConfig {
    pub(crate) parameters: Option<Json>,
    pub(crate) instance_id: Option<String>,
    pub(crate) namespace: Option<String>,
    pub(crate) endpoints: Option<Endpoints>,
    pub(crate) use_sim_time: bool,
    pub(crate) core_node: Option<String>,
    /// `(link_id, instance)`, in order: as `--link` flags.
    pub(crate) links: Vec<(String, String)>,
    /// Slots left vacant: as `--vacant-link` flags.
    pub(crate) vacant: Vec<String>,
    /// The core node of each producer the links name, by instance id.
    pub(crate) cores: Vec<(String, String)>,
}

impl StandaloneConfig {
    /// No fallbacks.
    pub fn new() -> Self {
        Self::default()
    }

    /// Parameter values to use when none are given on the command line.
    pub fn with_parameters<T: Serialize>(mut self, parameters: &T) -> Self {
        self.parameters = serde_json::to_value(parameters).ok();
        self
    }

    /// Parameter values as JSON.
    pub fn with_parameters_json(mut self, parameters: Json) -> Self {
        self.parameters = Some(parameters);
        self
    }

    /// The instance id to use when `--instance-id` is not given.
    pub fn with_instance_id(mut self, id: impl Into<String>) -> Self {
        self.instance_id = Some(id.into());
        self
    }

    /// The namespace to use when `--namespace` is not given.
    pub fn with_namespace(mut self, ns: impl Into<String>) -> Self {
        self.namespace = Some(ns.into());
        self
    }

    /// Zenoh endpoints to use when `--listen` / `--connect` are not given.
    pub fn with_endpoints(mut self, endpoints: Endpoints) -> Self {
        self.endpoints = Some(endpoints);
        self
    }

    /// The core node the instance says it belongs to (default
    /// `standalone`); the test harness runs its node and mocks as
    /// `standalone-core`.
    pub fn with_core_node(mut self, core_node: impl Into<String>) -> Self {
        self.core_node = Some(core_node.into());
        self
    }

    /// Follow simulated time (as `--use-sim-time` does): the stack clock
    /// gives the latest sim tick instead of the OS clock.
    pub fn with_use_sim_time(mut self, use_sim_time: bool) -> Self {
        self.use_sim_time = use_sim_time;
        self
    }

    /// Connects to the Zenoh endpoint `tcp/<host>:<port>` (as `--connect`
    /// does), with no multicast scouting.
    pub fn with_messaging(mut self, host: impl AsRef<str>, port: u16) -> Self {
        let host = host.as_ref();
        // An IPv6 address goes in brackets in an endpoint.
        let host = if host.contains(':') && !host.starts_with('[') {
            format!("[{host}]")
        } else {
            host.to_string()
        };
        self.endpoints = Some(Endpoints {
            connect: vec![format!("tcp/{host}:{port}")],
            ..Endpoints::default()
        });
        self
    }

    /// Links slot `link_id` to producer `instance_id` of core node
    /// `core_node` (as `--link link_id@instance_id` does; repeat it for a
    /// list slot, in order). Instance ids name producers in a stack;
    /// `core_node` is where the producer runs, as the slot's
    /// `bound_producer(s)` tell it. Used when the command line links no slot.
    pub fn with_bound_producer(
        mut self,
        link_id: impl Into<String>,
        core_node: impl Into<String>,
        instance_id: impl Into<String>,
    ) -> Self {
        let instance_id = instance_id.into();
        self.cores.push((instance_id.clone(), core_node.into()));
        self.links.push((link_id.into(), instance_id));
        self
    }

    /// Leaves the `zero_or_one` slot `link_id` empty on purpose (as
    /// `--vacant-link` does). Used when the command line links no slot.
    pub fn with_vacant_producer_slot(mut self, link_id: impl Into<String>) -> Self {
        self.vacant.push(link_id.into());
        self
    }

    /// Pins pairing slot `link_id` to its peer: slot `peer_link_id` of
    /// instance `instance_id` (as `--link link_id@instance_id/peer_link_id`
    /// does). The pair forms once both sides run. Used when the command
    /// line links no slot. `core_node` is taken as PeppyOS takes it, and
    /// not needed: a pair learns its peer's core node as it forms.
    pub fn with_peer_pin(
        self,
        link_id: impl Into<String>,
        core_node: impl Into<String>,
        instance_id: impl Into<String>,
        peer_link_id: impl Into<String>,
    ) -> Self {
        let _ = core_node.into();
        self.with_pair_end(link_id.into(), instance_id.into(), peer_link_id.into())
    }

    /// Adds a source to observer slot `link_id`: slot `source_link_id` of
    /// instance `instance_id` (as `--link link_id@instance_id/source_link_id`
    /// does; repeat it for a slot of several sources, in order). Used when
    /// the command line links no slot. `core_node` is taken as PeppyOS
    /// takes it, and not needed: an observer learns its sources' core nodes
    /// from what they publish.
    pub fn with_observed_source(
        self,
        link_id: impl Into<String>,
        core_node: impl Into<String>,
        instance_id: impl Into<String>,
        source_link_id: impl Into<String>,
    ) -> Self {
        let _ = core_node.into();
        self.with_pair_end(link_id.into(), instance_id.into(), source_link_id.into())
    }

    /// Links pairing slot `link_id` to slot `end_link_id` of `instance_id`,
    /// as `--link link_id@instance_id/end_link_id` does.
    fn with_pair_end(mut self, link_id: String, instance_id: String, end_link_id: String) -> Self {
        self.links
            .push((link_id, format!("{instance_id}/{end_link_id}")));
        self
    }

    /// The host of the Zenoh endpoint [`with_messaging`](Self::with_messaging)
    /// connects to (port 7447 until [`with_messaging_port`](Self::with_messaging_port)).
    pub fn with_messaging_host(self, host: impl AsRef<str>) -> Self {
        let port = self.messaging().1;
        self.with_messaging(host, port)
    }

    /// The port of the Zenoh endpoint [`with_messaging`](Self::with_messaging)
    /// connects to (on 127.0.0.1 until [`with_messaging_host`](Self::with_messaging_host)).
    pub fn with_messaging_port(self, port: u16) -> Self {
        let host = self.messaging().0;
        self.with_messaging(host, port)
    }

    /// The host and port of the one TCP endpoint this configuration
    /// connects to, or `127.0.0.1:7447`.
    fn messaging(&self) -> (String, u16) {
        let endpoint = self
            .endpoints
            .as_ref()
            .and_then(|e| e.connect.first())
            .and_then(|c| c.strip_prefix("tcp/"))
            .and_then(|a| a.rsplit_once(':'))
            .and_then(|(h, p)| Some((h.trim_matches(['[', ']']).to_string(), p.parse().ok()?)));
        endpoint.unwrap_or_else(|| ("127.0.0.1".to_string(), 7447))
    }
}

/// Flags of a standalone run.
#[derive(Debug, Parser)]
#[command(about = "A peppy node. Started by `peppy-launch`, or standalone with these flags.")]
struct Flags {
    /// This instance's id (default: a readable random id).
    #[arg(short = 'i', long, value_name = "ID")]
    instance_id: Option<String>,
    /// Bind a slot: `--bind left_cam@rs_left` (repeatable, or
    /// comma-separated).
    #[arg(long = "bind", value_name = "KEY@INSTANCE", value_delimiter = ',')]
    bind: Vec<String>,
    /// Link a slot to a producer, as PeppyOS's `node/v1` links:
    /// `--link camera@cam_1` (repeat it, or separate with commas, to give
    /// a list slot several producers, in order: `--link a@p1,b@p2`).
    #[arg(long = "link", value_name = "SLOT@TARGET", value_delimiter = ',')]
    link: Vec<String>,
    /// Leave a `zero_or_one` slot empty on purpose: `--vacant-link 'logger=not needed on the bench'`.
    #[arg(long = "vacant-link", value_name = "SLOT=WHY")]
    vacant_link: Vec<String>,
    /// Parameter values from a JSON file.
    #[arg(long, value_name = "FILE.json")]
    params: Option<PathBuf>,
    /// The namespace to join (default: `default`).
    #[arg(long, value_name = "NS")]
    namespace: Option<String>,
    /// A Zenoh endpoint to connect to (repeatable), e.g. `tcp/10.0.0.2:7447`.
    #[arg(long, value_name = "ENDPOINT")]
    connect: Vec<String>,
    /// A Zenoh endpoint to listen on (repeatable).
    #[arg(long, value_name = "ENDPOINT")]
    listen: Vec<String>,
    /// Follow simulated time: the stack clock gives the latest sim tick
    /// (`peppy/<ns>/clock/tick/sim`) instead of the OS clock.
    #[arg(long)]
    use_sim_time: bool,
    /// Hand small topic messages to other nodes started with the same
    /// directory over Unix sockets there, beside Zenoh (what `up` gives the
    /// instances of one launch on one host; docs/WIRE.md, "Direct links").
    #[arg(long, value_name = "DIR")]
    direct_links: Option<PathBuf>,
    /// Parameter overrides, `key=value`, dot-paths for groups (`video.fps=30`).
    #[arg(value_name = "KEY=VALUE")]
    overrides: Vec<String>,
}

/// Reads the start-up inputs: the runtime-config file when the launcher set
/// `PEPPY_RUNTIME_CONFIG`, else `args` (the command line) and `standalone`.
pub(crate) fn load(
    doc: &NodeModel,
    args: Vec<String>,
    env_file: Option<PathBuf>,
    standalone: &StandaloneConfig,
) -> Result<StartupConfig> {
    let (mut config, binds_given) = match env_file {
        Some(path) => (read_config_file(&path)?, None),
        None => {
            let flags = Flags::try_parse_from(args).map_err(|e| Error::Startup(e.to_string()))?;
            standalone_config(doc, flags, standalone)?
        }
    };
    if let Some(secs) = config.shutdown_grace_secs {
        grace_window(secs, "runtime config: `shutdown_grace_secs`")?;
    }
    for (what, value) in [
        ("instance id", &config.instance_id),
        ("core node", &config.core_node),
        ("namespace", &config.namespace),
    ] {
        if let Err(why) = peppy_schema::names::check_name(value) {
            return Err(Error::Startup(format!("invalid {what} `{value}`: {why}")));
        }
    }
    let (binds_given, pair_plans) = match binds_given {
        Some(binds) => {
            let (pairs, rest) = pairs_from_flags(doc, binds)?;
            (Some(rest), pairs)
        }
        None => (None, std::mem::take(&mut config.pairs)),
    };
    config.pairs = fit_pair_plans(&doc.pairings, pair_plans).map_err(|e| {
        Error::Startup(format!(
            "{e} (`{}`){}",
            doc.identity,
            if binds_given.is_some() {
                ""
            } else {
                "; was this binary built from another peppy.json5 than the launcher read?"
            }
        ))
    })?;
    let slots = match binds_given {
        Some(binds) => slots_from_flags(doc, &config.instance_id, &binds)?,
        None => fit_plan(&doc.dependencies, std::mem::take(&mut config.slots)).map_err(|e| {
            Error::Startup(format!(
                "the runtime config does not fit `{}`: {e}; was this binary built from another peppy.json5 than the launcher read?",
                doc.identity
            ))
        })?,
    };
    // The launcher filled the parameters already; a binary built from other
    // documents than the launcher read is caught here, by the same checker.
    config.parameters = doc
        .parameters
        .resolve(&config.parameters)
        .map_err(Error::Parameters)?;
    config.slots = slots;
    Ok(config)
}

/// What a standalone command line (`--instance-id`, `--bind`, `--params`,
/// `key=value`, ...) means for the node `doc`: the start-up config it
/// describes, with bindings checked and parameters filled. `peppy-launch run`
/// hands this to the node it starts.
pub fn startup_from_flags(doc: &NodeModel, args: Vec<String>) -> Result<StartupConfig> {
    load(doc, args, None, &StandaloneConfig::default())
}

fn read_config_file(path: &Path) -> Result<StartupConfig> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        Error::Startup(format!(
            "cannot read the runtime config `{}` ({RUNTIME_CONFIG_ENV}): {e}",
            path.display()
        ))
    })?;
    serde_json::from_str(&text).map_err(|e| {
        Error::Startup(format!(
            "invalid runtime config `{}` ({RUNTIME_CONFIG_ENV}): {e}",
            path.display()
        ))
    })
}

/// One slot flag, in the order given: `--bind` (the `bindings` grammar,
/// free-form keys allowed), `--link` or `--vacant-link` (the `links`
/// grammar).
#[derive(Debug, Clone)]
struct FlagBind {
    key: String,
    /// The producer instance, or the vacancy's reason.
    value: String,
    kind: FlagKind,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FlagKind {
    Bind,
    Link,
    Vacant,
}

type Binds = Vec<FlagBind>;

/// `--link KEY@TARGET` / `--vacant-link KEY=WHY`: a key names a slot, by
/// the rule a launcher's `links` keys follow.
fn link_key(flag: &str, key: &str) -> Result<()> {
    peppy_schema::names::check_link_key(key)
        .map_err(|why| Error::Startup(format!("invalid {flag} key `{key}`: {why}")))
}

fn standalone_config(
    doc: &NodeModel,
    flags: Flags,
    standalone: &StandaloneConfig,
) -> Result<(StartupConfig, Option<Binds>)> {
    let mut binds = Vec::new();
    for b in &flags.bind {
        let Some((key, instance)) = b
            .split_once('@')
            .filter(|(k, i)| !k.is_empty() && !i.is_empty())
        else {
            return Err(Error::Startup(format!(
                "invalid --bind `{b}`: expected KEY@INSTANCE, e.g. --bind left_cam@rs_left"
            )));
        };
        // A key may repeat: a from_any slot takes several producers, and
        // the binding engine refuses a pinned slot bound twice.
        binds.push(FlagBind {
            key: key.to_string(),
            value: instance.to_string(),
            kind: FlagKind::Bind,
        });
    }
    for l in &flags.link {
        let Some((key, instance)) = l.split_once('@').filter(|(_, i)| !i.is_empty()) else {
            return Err(Error::Startup(format!(
                "invalid --link `{l}`: expected SLOT@INSTANCE, e.g. --link camera@cam_1"
            )));
        };
        link_key("--link", key)?;
        binds.push(FlagBind {
            key: key.to_string(),
            value: instance.to_string(),
            kind: FlagKind::Link,
        });
    }
    for v in &flags.vacant_link {
        // The reason may hold `=`: split on the first one only.
        let Some((key, why)) = v.split_once('=').filter(|(_, w)| !w.trim().is_empty()) else {
            return Err(Error::Startup(format!(
                "invalid --vacant-link `{v}`: expected SLOT=WHY with a reason, e.g. --vacant-link 'logger=not on the bench'"
            )));
        };
        link_key("--vacant-link", key)?;
        binds.push(FlagBind {
            key: key.to_string(),
            value: why.trim().to_string(),
            kind: FlagKind::Vacant,
        });
    }
    // The code's links stand in for a command line that links nothing.
    let code_links = binds.is_empty();
    if binds.is_empty() {
        for (key, instance) in &standalone.links {
            binds.push(FlagBind {
                key: key.clone(),
                value: instance.clone(),
                kind: FlagKind::Link,
            });
        }
        for key in &standalone.vacant {
            binds.push(FlagBind {
                key: key.clone(),
                value: "left vacant by the node's StandaloneConfig".to_string(),
                kind: FlagKind::Vacant,
            });
        }
    }
    let mut parameters = standalone.parameters.clone().unwrap_or(Json::Null);
    if let Some(file) = &flags.params {
        let text = std::fs::read_to_string(file).map_err(|e| {
            Error::Startup(format!("cannot read --params `{}`: {e}", file.display()))
        })?;
        let given: Json = serde_json::from_str(&text).map_err(|e| {
            Error::Startup(format!(
                "--params `{}` is not valid JSON: {e}",
                file.display()
            ))
        })?;
        merge(&mut parameters, given);
    }
    for o in &flags.overrides {
        let Some((path, raw)) = o.split_once('=').filter(|(p, _)| !p.is_empty()) else {
            return Err(Error::Startup(format!(
                "unexpected argument `{o}`: parameter overrides are `key=value` (dot-paths for groups)"
            )));
        };
        let value = typed_value(&doc.parameters, path, raw);
        let mut patch = value;
        for key in path.rsplit('.') {
            let mut m = serde_json::Map::new();
            m.insert(key.to_string(), patch);
            patch = Json::Object(m);
        }
        merge(&mut parameters, patch);
    }
    let endpoints = if flags.connect.is_empty() && flags.listen.is_empty() {
        standalone.endpoints.clone().unwrap_or(Endpoints {
            multicast_scouting: true,
            ..Endpoints::default()
        })
    } else {
        Endpoints {
            mode: None,
            listen: flags.listen,
            connect: flags.connect,
            multicast_scouting: false,
            login: None,
        }
    };
    let config = StartupConfig {
        instance_id: flags
            .instance_id
            .or_else(|| standalone.instance_id.clone())
            .unwrap_or_else(|| readable_id(&doc.identity.name)),
        core_node: standalone
            .core_node
            .clone()
            .unwrap_or_else(|| STANDALONE_CORE.to_string()),
        namespace: flags
            .namespace
            .or_else(|| standalone.namespace.clone())
            .unwrap_or_else(|| DEFAULT_NAMESPACE.to_string()),
        slots: Vec::new(),
        pairs: Vec::new(),
        parameters,
        zenoh: endpoints,
        use_sim_time: flags.use_sim_time || standalone.use_sim_time,
        shutdown_grace_secs: None,
        direct_links: flags.direct_links,
        producer_cores: if code_links {
            standalone.cores.iter().cloned().collect()
        } else {
            Default::default()
        },
    };
    Ok((config, Some(binds)))
}

/// `name-1a2b`: readable, and different on every start.
fn readable_id(node: &str) -> String {
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u32(std::process::id());
    h.write_u128(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos()),
    );
    format!("{node}-{:04x}", h.finish() & 0xffff)
}

/// Deep merge: objects merge key by key, anything else replaces.
fn merge(base: &mut Json, patch: Json) {
    match (base, patch) {
        (Json::Object(b), Json::Object(p)) => {
            for (k, v) in p {
                merge(b.entry(k).or_insert(Json::Null), v);
            }
        }
        (b, p) => *b = p,
    }
}

/// Parses a `key=value` override by the parameter's declared type.
fn typed_value(schema: &ParameterSchema, path: &str, raw: &str) -> Json {
    let mut fields = &schema.fields;
    let mut kind = None;
    for key in path.split('.') {
        let Some(f) = fields.iter().find(|f| f.name == key) else {
            return Json::String(raw.into());
        };
        kind = Some(&f.kind);
        if let ParamKind::Group(children) = &f.kind {
            fields = children;
        }
    }
    match kind {
        Some(ParamKind::Leaf { ty, .. }) => match ty {
            Primitive::Bool => raw
                .parse::<bool>()
                .map(Json::from)
                .unwrap_or_else(|_| Json::String(raw.into())),
            Primitive::String | Primitive::Bytes => Json::String(raw.into()),
            Primitive::F32 | Primitive::F64 | Primitive::Time => raw
                .parse::<f64>()
                .ok()
                .and_then(|f| serde_json::Number::from_f64(f).map(Json::Number))
                .unwrap_or_else(|| Json::String(raw.into())),
            _ => raw
                .parse::<i64>()
                .map(Json::from)
                .or_else(|_| raw.parse::<u64>().map(Json::from))
                .unwrap_or_else(|_| Json::String(raw.into())),
        },
        Some(ParamKind::Array { .. }) | Some(ParamKind::Group(_)) => {
            serde_json::from_str(raw).unwrap_or_else(|_| Json::String(raw.into()))
        }
        None => Json::String(raw.into()),
    }
}

/// `--link` / `--vacant-link` flags naming a pairing slot, as that slot's
/// plan (`SLOT@PEER` or `SLOT@PEER/PEER_SLOT`, repeated for an observer's
/// sources); the other flags are left for the binding engine.
fn pairs_from_flags(doc: &NodeModel, binds: Binds) -> Result<(Vec<PairPlan>, Binds)> {
    let mut plans: Vec<PairPlan> = Vec::new();
    let mut rest = Vec::new();
    for b in binds {
        let Some(slot) = doc.pairing(&b.key) else {
            rest.push(b);
            continue;
        };
        if b.kind == FlagKind::Bind {
            return Err(Error::Startup(format!(
                "--bind `{}@{}` names pairing slot `{}`: pair it with --link {}@{}",
                b.key, b.value, slot.link_id, b.key, b.value
            )));
        }
        let i = match plans.iter().position(|p| p.link_id == b.key) {
            Some(i) => i,
            None => {
                plans.push(PairPlan {
                    link_id: b.key.clone(),
                    peers: Vec::new(),
                    vacant: None,
                });
                plans.len() - 1
            }
        };
        match b.kind {
            FlagKind::Vacant => plans[i].vacant = Some(b.value),
            _ => {
                let end = PairEnd::parse(&b.value).ok_or_else(|| {
                    Error::Startup(format!(
                        "invalid --link `{}@{}`: a pairing slot takes PEER or PEER/PEER_SLOT",
                        b.key, b.value
                    ))
                })?;
                plans[i].peers.push(end);
            }
        }
    }
    // Whether the plans fit their slots (a slot linked and left vacant at
    // once among them) is `fit_pair_plans`'s to say, as for a launcher's.
    Ok((plans, rest))
}

/// Slots from `--bind` flags, through the binding engine. The producers'
/// nodes are not known on a command line, so a free-form key joins the
/// first `from_any` slot only when every `from_any` slot wants the same
/// producers; otherwise the flag must name the slot.
fn slots_from_flags(doc: &NodeModel, instance: &str, binds: &[FlagBind]) -> Result<Vec<SlotPlan>> {
    let requests: Vec<BindRequest<'_>> = binds
        .iter()
        .map(|b| match b.kind {
            FlagKind::Bind => BindRequest::key(&b.key, &b.value, None),
            FlagKind::Link => BindRequest {
                form: BindForm::Flag,
                ..BindRequest::key(&b.key, &b.value, None)
            },
            FlagKind::Vacant => BindRequest {
                form: BindForm::Vacant(&b.value),
                ..BindRequest::key(&b.key, "", None)
            },
        })
        .collect();
    engine(doc, instance, &requests)
}

fn engine(doc: &NodeModel, instance: &str, requests: &[BindRequest<'_>]) -> Result<Vec<SlotPlan>> {
    let outcome = assign(
        instance,
        &doc.identity,
        doc.spelling,
        &doc.dependencies,
        requests,
    );
    if outcome.errors.is_empty() {
        Ok(outcome.slots)
    } else {
        Err(Error::Bindings(
            outcome.errors.into_iter().map(|(_, e)| e).collect(),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use peppy_schema::{NodeDoc, RouteFilter, SlotBinding};

    /// A node's model as its binary sees it: through the JSON the build embeds.
    fn model(text: &str) -> NodeModel {
        let (doc, _) = NodeDoc::parse("peppy.json5", text).unwrap();
        NodeModel::from_json(&NodeModel::of(&doc).to_json()).unwrap()
    }

    #[test]
    fn no_session_copies_payloads_into_zenohs_own_pool() {
        for mode in ["peer", "client", "router"] {
            let endpoints = Endpoints {
                mode: Some(mode.into()),
                ..Endpoints::default()
            };
            let config = endpoints.zenoh_config().unwrap();
            assert_eq!(
                config
                    .get_json("transport/shared_memory/transport_optimization/enabled")
                    .unwrap(),
                "false",
                "{mode}"
            );
        }
    }

    fn doc() -> NodeModel {
        model(
            r#"{ peppy_schema: "node_v1",
                manifest: { name: "recon", tag: "v1", depends_on: { interfaces: [
                    { name: "depth_camera", tag: "v1", link_id: "left_cam" },
                    { name: "depth_camera", tag: "v1", link_id: "backup", from_any: true },
                ] } },
                execution: { language: "rust", run_cmd: ["x"], parameters: {
                    fps: { $type: "u16", $default: 30 }, name: "string", video: { scale: { $type: "f64", $default: 1 } } } } }"#,
        )
    }

    fn args(a: &[&str]) -> Vec<String> {
        std::iter::once("node")
            .chain(a.iter().copied())
            .map(String::from)
            .collect()
    }

    #[test]
    fn standalone_flags_bind_slots_and_type_parameters() {
        let s = load(
            &doc(),
            args(&[
                "--instance-id",
                "r1",
                "--bind",
                "left_cam@cam_a",
                "--bind",
                "spare@cam_b",
                "name=123",
                "video.scale=2.5",
            ]),
            None,
            &StandaloneConfig::new(),
        )
        .unwrap();
        assert_eq!(s.instance_id, "r1");
        assert_eq!(s.namespace, DEFAULT_NAMESPACE);
        assert_eq!(s.slots[0].filter, RouteFilter::Pin("cam_a".into()));
        assert_eq!(
            s.slots[1].binding,
            SlotBinding::FromAnyBound {
                producers: vec!["cam_b".into()]
            }
        );
        assert_eq!(
            s.parameters,
            serde_json::json!({ "fps": 30, "name": "123", "video": { "scale": 2.5 } })
        );
    }

    /// A `node/v1` consumer with one slot of each cardinality.
    fn slashed_node() -> NodeModel {
        model(
            r#"{ peppy_schema: "node/v1",
                manifest: { name: "mapper", tag: "v1", depends_on: {
                    contracts: [
                        { name: "range_scan", tag: "v1", link_id: "scan" },
                        { name: "range_scan", tag: "v1", link_id: "extra", cardinality: "zero_or_one" },
                        { name: "range_scan", tag: "v1", link_id: "scans", cardinality: "one_or_more" },
                    ],
                    nodes: [{ name: "logger", tag: "v1", link_id: "log", cardinality: "zero_or_more" }] } },
                execution: { language: "rust", run_cmd: ["x"] } }"#,
        )
    }

    fn start(doc: &NodeModel, a: &[&str]) -> Result<StartupConfig> {
        load(doc, args(a), None, &StandaloneConfig::new())
    }

    #[test]
    fn standalone_links_stand_in_for_a_command_line_that_links_nothing() {
        let code = StandaloneConfig::new()
            .with_bound_producer("scan", "lab", "lidar_a")
            .with_vacant_producer_slot("extra")
            .with_bound_producer("scans", "lab", "lidar_b")
            .with_messaging("192.0.2.7", 7447);
        let s = load(&slashed_node(), args(&[]), None, &code).unwrap();
        let slot = |id: &str| {
            s.slots
                .iter()
                .find(|p| p.link_id == id)
                .unwrap()
                .binding
                .clone()
        };
        assert_eq!(
            slot("scan"),
            SlotBinding::Pinned {
                producer: "lidar_a".into()
            }
        );
        assert!(
            matches!(slot("extra"), SlotBinding::Set { producers, vacant: Some(_) } if producers.is_empty())
        );
        assert_eq!(
            slot("scans"),
            SlotBinding::Set {
                producers: vec!["lidar_b".into()],
                vacant: None
            }
        );
        assert_eq!(s.zenoh.connect, vec!["tcp/192.0.2.7:7447".to_string()]);
        assert!(!s.zenoh.multicast_scouting);
        // A command line that links anything replaces the code's links whole.
        let s = load(
            &slashed_node(),
            args(&[
                "--link",
                "scan@lidar_c",
                "--vacant-link",
                "extra=x",
                "--link",
                "scans@lidar_c",
            ]),
            None,
            &code,
        )
        .unwrap();
        let slot = |id: &str| {
            s.slots
                .iter()
                .find(|p| p.link_id == id)
                .unwrap()
                .binding
                .clone()
        };
        assert_eq!(
            slot("scan"),
            SlotBinding::Pinned {
                producer: "lidar_c".into()
            }
        );
        // And the code's links go through the same rules as flags.
        let wrong = StandaloneConfig::new().with_vacant_producer_slot("scan");
        let e = load(&slashed_node(), args(&[]), None, &wrong)
            .unwrap_err()
            .to_string();
        assert!(e.contains("LinkVacantInvalid"), "{e}");
    }

    #[test]
    fn link_flags_fill_cardinality_slots_in_order() {
        let s = start(
            &slashed_node(),
            &[
                "--link",
                "scan@lidar_a",
                "--vacant-link",
                "extra=bench run: no second lidar",
                "--link",
                "scans@lidar_b",
                "--link",
                "scans@lidar_a",
            ],
        )
        .unwrap();
        let slot = |id: &str| s.slots.iter().find(|p| p.link_id == id).unwrap();
        assert_eq!(
            slot("scan").binding,
            SlotBinding::Pinned {
                producer: "lidar_a".into()
            }
        );
        assert_eq!(
            slot("extra").binding,
            SlotBinding::Set {
                producers: vec![],
                vacant: Some("bench run: no second lidar".into())
            }
        );
        assert_eq!(
            slot("scans").binding,
            SlotBinding::Set {
                producers: vec!["lidar_b".into(), "lidar_a".into()],
                vacant: None
            }
        );
        assert_eq!(
            slot("scans").filter,
            RouteFilter::OnlyFrom(["lidar_a".to_string(), "lidar_b".to_string()].into())
        );
        // zero_or_more left out: an empty set, nothing flows in.
        assert_eq!(
            slot("log").binding,
            SlotBinding::Set {
                producers: vec![],
                vacant: None
            }
        );
        assert!(!slot("log").filter.accepts("anyone"));
    }

    #[test]
    fn link_flags_refuse_what_the_links_rules_refuse() {
        let text = |a: &[&str]| start(&slashed_node(), a).unwrap_err().to_string();
        // zero_or_one left out, one_or_more unlinked: both named.
        let e = text(&["--link", "scan@a"]);
        assert!(
            e.contains("slot `extra`") && e.contains("is not linked"),
            "{e}"
        );
        assert!(e.contains("--vacant-link 'extra=<why>'"), "{e}");
        assert!(e.contains("slot `scans`"), "{e}");
        // A key naming no slot: no free-form keys in `node/v1`.
        let e = text(&[
            "--link",
            "scna@a",
            "--link",
            "scans@a",
            "--vacant-link",
            "extra=x",
        ]);
        assert!(
            e.contains("link `scna`") && e.contains("names no slot"),
            "{e}"
        );
        assert!(e.contains("did you mean `scan`?"), "{e}");
        // Keys are judged first, and alone: a misspelt key does not also
        // leave its slot reported unlinked.
        let e = text(&["--link", "scna@a"]);
        assert!(
            e.contains("names no slot") && !e.contains("is not linked"),
            "{e}"
        );
        // Vacancy only on zero_or_one.
        let e = text(&[
            "--vacant-link",
            "scan=nope",
            "--link",
            "scans@a",
            "--vacant-link",
            "extra=x",
        ]);
        assert!(
            e.contains("slot `scan` (cardinality one) cannot be vacant"),
            "{e}"
        );
        // One producer, twice.
        let e = text(&[
            "--link",
            "scan@a",
            "--link",
            "scan@b",
            "--link",
            "scans@a",
            "--vacant-link",
            "extra=x",
        ]);
        assert!(e.contains("takes one producer"), "{e}");
        // The same producer twice in a list.
        let e = text(&[
            "--link",
            "scan@a",
            "--link",
            "scans@a",
            "--link",
            "scans@a",
            "--vacant-link",
            "extra=x",
        ]);
        assert!(e.contains("lists `a` twice"), "{e}");
        // Malformed flags.
        for bad in [
            ["--link", "_@a"],
            ["--link", "scan"],
            ["--vacant-link", "extra="],
            ["--link", "a/b@c"],
        ] {
            let e = text(&bad);
            assert!(e.starts_with("invalid --"), "{bad:?}: {e}");
        }
    }

    #[test]
    fn a_free_form_key_is_refused_when_the_slot_would_be_a_guess() {
        let doc = model(
            r#"{ peppy_schema: "node_v1",
                manifest: { name: "mixer", tag: "v1", depends_on: {
                    interfaces: [ { name: "depth_camera", tag: "v1", link_id: "cams", from_any: true } ],
                    nodes: [ { name: "realsense_d405", tag: "v1", link_id: "realsenses", from_any: true } ] } },
                execution: { language: "rust", run_cmd: ["x"] } }"#,
        );
        // The producer's node is not known on a command line, and the two
        // from_any slots want different producers: no silent pick.
        let err = load(
            &doc,
            args(&["--bind", "front@rs_a"]),
            None,
            &StandaloneConfig::new(),
        )
        .unwrap_err();
        let Error::Bindings(errors) = &err else {
            panic!("{err}")
        };
        assert_eq!(errors[0].code(), peppy_schema::Code::DeadBindingKey);
        let text = err.to_string();
        assert!(
            text.contains("--bind cams@rs_a or --bind realsenses@rs_a"),
            "{text}"
        );
        // Naming the slot works.
        let s = load(
            &doc,
            args(&["--bind", "realsenses@rs_a"]),
            None,
            &StandaloneConfig::new(),
        )
        .unwrap();
        let slot = s.slots.iter().find(|x| x.link_id == "realsenses").unwrap();
        assert_eq!(
            slot.filter,
            RouteFilter::OnlyFrom(["rs_a".to_string()].into())
        );
    }

    #[test]
    fn a_free_form_key_without_a_from_any_slot_is_dead() {
        let doc = model(
            r#"{ peppy_schema: "node_v1",
                manifest: { name: "single", tag: "v1", depends_on: {
                    interfaces: [ { name: "depth_camera", tag: "v1", link_id: "left_cam" } ] } },
                execution: { language: "rust", run_cmd: ["x"] } }"#,
        );
        let err = load(
            &doc,
            args(&["--bind", "left_cam@a", "--bind", "front@rs_a"]),
            None,
            &StandaloneConfig::new(),
        )
        .unwrap_err();
        let Error::Bindings(errors) = &err else {
            panic!("{err}")
        };
        assert_eq!(errors.len(), 1, "{err}");
        assert_eq!(errors[0].code(), peppy_schema::Code::DeadBindingKey);
        assert!(err.to_string().contains("binding `front`"), "{err}");
    }

    #[test]
    fn a_pinned_slot_without_binding_names_the_flag() {
        let err = load(&doc(), args(&["name=x"]), None, &StandaloneConfig::new())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("slot `left_cam`") && err.contains("--bind left_cam@"),
            "{err}"
        );
    }

    #[test]
    fn missing_required_parameter_names_its_path() {
        let err = load(
            &doc(),
            args(&["--bind", "left_cam@a"]),
            None,
            &StandaloneConfig::new(),
        )
        .unwrap_err();
        let Error::Parameters(list) = &err else {
            panic!("{err}")
        };
        assert_eq!(list[0].path, "name");
        assert!(
            err.to_string()
                .contains("missing required parameter `name`")
        );
    }

    fn slot(link_id: &str, binding: SlotBinding, filter: RouteFilter) -> SlotPlan {
        SlotPlan {
            link_id: link_id.into(),
            kind: peppy_schema::SlotKind::Interface,
            target: peppy_schema::Identity::new("depth_camera", "v1"),
            binding,
            filter,
        }
    }

    fn plan_file(dir: &tempfile::TempDir, cfg: &StartupConfig) -> PathBuf {
        let path = dir.path().join("rt.json");
        std::fs::write(&path, serde_json::to_string(cfg).unwrap()).unwrap();
        path
    }

    fn launcher_config(slots: Vec<SlotPlan>) -> StartupConfig {
        StartupConfig {
            instance_id: "recon_1".into(),
            core_node: "lab-1".into(),
            namespace: "lab".into(),
            slots,
            pairs: Vec::new(),
            parameters: serde_json::json!({ "fps": 30, "name": "n", "video": { "scale": 1.0 } }),
            zenoh: Endpoints {
                connect: vec!["tcp/127.0.0.1:7447".into()],
                ..Endpoints::default()
            },
            use_sim_time: false,
            shutdown_grace_secs: None,
            direct_links: None,
            producer_cores: Default::default(),
        }
    }

    #[test]
    fn the_launchers_plan_is_applied_as_it_is() {
        let dir = tempfile::tempdir().unwrap();
        // Out of `depends_on` order, and a filter the engine would not
        // compute from these bindings alone: the node takes the plan, it
        // does not bind again.
        let backup = slot(
            "backup",
            SlotBinding::FromAnyUnbound,
            RouteFilter::AnyExcept(["rs_left".to_string(), "rs_spare".to_string()].into()),
        );
        let left = slot(
            "left_cam",
            SlotBinding::Pinned {
                producer: "rs_left".into(),
            },
            RouteFilter::Pin("rs_left".into()),
        );
        let cfg = launcher_config(vec![backup.clone(), left.clone()]);
        let s = load(
            &doc(),
            args(&["ignored=1"]),
            Some(plan_file(&dir, &cfg)),
            &StandaloneConfig::new(),
        )
        .unwrap();
        assert_eq!(s.slots, [left, backup]);
        assert_eq!(s.instance_id, "recon_1");
        assert_eq!(s.zenoh, cfg.zenoh);
        assert_eq!(s.parameters, cfg.parameters);
    }

    #[test]
    fn clock_and_grace_settings_come_from_the_plan_or_the_command_line() {
        let dir = tempfile::tempdir().unwrap();
        let left = slot(
            "left_cam",
            SlotBinding::Pinned {
                producer: "rs_left".into(),
            },
            RouteFilter::Pin("rs_left".into()),
        );
        let backup = slot("backup", SlotBinding::FromAnyUnbound, RouteFilter::Any);
        let base = launcher_config(vec![left, backup]);
        // A plan written before the two fields existed still reads, and
        // leaves them at their defaults (nothing new is written for them).
        let old = serde_json::to_value(&base).unwrap();
        assert!(old.get("use_sim_time").is_none() && old.get("shutdown_grace_secs").is_none());
        let s = load(
            &doc(),
            args(&[]),
            Some(plan_file(&dir, &base)),
            &StandaloneConfig::new(),
        )
        .unwrap();
        assert!(!s.use_sim_time);
        assert_eq!(shutdown_grace(&s, None).unwrap(), DEFAULT_SHUTDOWN_GRACE);
        assert_eq!(
            shutdown_grace(&s, Some(Duration::from_secs(9))).unwrap(),
            Duration::from_secs(9)
        );
        let set = StartupConfig {
            use_sim_time: true,
            shutdown_grace_secs: Some(1.5),
            ..base.clone()
        };
        let s = load(
            &doc(),
            args(&[]),
            Some(plan_file(&dir, &set)),
            &StandaloneConfig::new(),
        )
        .unwrap();
        assert!(s.use_sim_time);
        // The plan's window wins over the code's.
        assert_eq!(
            shutdown_grace(&s, Some(Duration::from_secs(9))).unwrap(),
            Duration::from_millis(1500)
        );
        for bad in [0.0, -1.0] {
            let cfg = StartupConfig {
                shutdown_grace_secs: Some(bad),
                ..base.clone()
            };
            let e = load(
                &doc(),
                args(&[]),
                Some(plan_file(&dir, &cfg)),
                &StandaloneConfig::new(),
            )
            .unwrap_err()
            .to_string();
            assert!(e.contains("`shutdown_grace_secs`"), "{e}");
        }
        // Standalone: the flag or the code's fallback.
        let cmd = ["--bind", "left_cam@a", "name=x"];
        let flagged: Vec<&str> = cmd.iter().copied().chain(["--use-sim-time"]).collect();
        assert!(
            load(&doc(), args(&flagged), None, &StandaloneConfig::new())
                .unwrap()
                .use_sim_time
        );
        let fallback = StandaloneConfig::new().with_use_sim_time(true);
        assert!(
            load(&doc(), args(&cmd), None, &fallback)
                .unwrap()
                .use_sim_time
        );
        assert!(
            !load(&doc(), args(&cmd), None, &StandaloneConfig::new())
                .unwrap()
                .use_sim_time
        );
    }

    #[test]
    fn a_plan_for_other_slots_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let pinned = |id: &str| {
            slot(
                id,
                SlotBinding::Pinned {
                    producer: "rs_left".into(),
                },
                RouteFilter::Pin("rs_left".into()),
            )
        };
        let unbound = |id: &str| slot(id, SlotBinding::FromAnyUnbound, RouteFilter::Any);
        for (slots, why) in [
            (vec![pinned("left_cam")], "leaves slot `backup` out"),
            (
                vec![pinned("left_cam"), unbound("backup"), unbound("spare")],
                "fills slot `spare`",
            ),
            (
                vec![pinned("left_cam"), unbound("backup"), unbound("backup")],
                "fills slot `backup` twice",
            ),
            (
                vec![unbound("left_cam"), unbound("backup")],
                "binds slot `left_cam` as from_any",
            ),
        ] {
            let path = plan_file(&dir, &launcher_config(slots));
            let err = load(&doc(), args(&[]), Some(path), &StandaloneConfig::new())
                .unwrap_err()
                .to_string();
            assert!(
                err.contains(why) && err.contains("another peppy.json5"),
                "{err}"
            );
        }
    }

    #[test]
    fn bad_flags_are_errors() {
        assert!(
            load(
                &doc(),
                args(&["--bind", "nokey"]),
                None,
                &StandaloneConfig::new()
            )
            .is_err()
        );
        assert!(
            load(
                &doc(),
                args(&["--instance-id", "a/b", "--bind", "left_cam@x", "name=y"]),
                None,
                &StandaloneConfig::new()
            )
            .is_err()
        );
        assert!(
            load(
                &doc(),
                args(&["positional"]),
                None,
                &StandaloneConfig::new()
            )
            .is_err()
        );
    }
}

#[cfg(test)]
mod pairing_tests {
    use super::*;
    use peppy_schema::{NodeDoc, PairEnd};

    /// A `node/v1` participant and observer of one pairing.
    fn paired() -> NodeModel {
        let (doc, _) = NodeDoc::parse(
            "peppy.json5",
            r#"{ peppy_schema: "node/v1",
                manifest: { name: "relay", tag: "v1", depends_on: {
                    pairings: [{ name: "joint_link", tag: "v1", role: "follower", link_id: "backbone" }],
                    pairing_observers: [{ name: "joint_link", tag: "v1", role: "leader", link_id: "watch",
                                          cardinality: "one_or_more" }] } },
                interfaces: { topics: { consumes: [{ link_id: "watch", name: "joint_setpoints" }] } },
                execution: { language: "rust", run_cmd: ["x"] } }"#,
        )
        .unwrap();
        NodeModel::from_json(&NodeModel::of(&doc).to_json()).unwrap()
    }

    #[test]
    fn the_code_pins_peers_and_sources_as_link_flags_do() {
        let code = StandaloneConfig::new()
            .with_peer_pin("backbone", "lab", "backbone_1", "left_arm_link")
            .with_observed_source("watch", "lab", "panel", "left_arm")
            .with_observed_source("watch", "lab", "teleop", "left_arm")
            .with_messaging_port(17447)
            .with_messaging_host("192.0.2.9");
        let s = load(&paired(), vec!["node".into()], None, &code).unwrap();
        let plan = |id: &str| {
            s.pairs
                .iter()
                .find(|p| p.link_id == id)
                .unwrap()
                .peers
                .clone()
        };
        let end = |i: &str, l: &str| PairEnd {
            instance: i.into(),
            link_id: Some(l.into()),
        };
        assert_eq!(plan("backbone"), vec![end("backbone_1", "left_arm_link")]);
        assert_eq!(
            plan("watch"),
            vec![end("panel", "left_arm"), end("teleop", "left_arm")]
        );
        assert_eq!(s.zenoh.connect, vec!["tcp/192.0.2.9:17447".to_string()]);
        // The flags' spelling gives the same plan.
        let flags = load(
            &paired(),
            [
                "node",
                "--link",
                "backbone@backbone_1/left_arm_link",
                "--link",
                "watch@panel/left_arm",
                "--link",
                "watch@teleop/left_arm",
            ]
            .map(String::from)
            .to_vec(),
            None,
            &StandaloneConfig::new(),
        )
        .unwrap();
        assert_eq!(flags.pairs, s.pairs);
        // As PeppyOS's `node run` takes them: `-i`, and links separated
        // by commas.
        let commas = load(
            &paired(),
            [
                "node",
                "-i",
                "relay_1",
                "--link",
                "backbone@backbone_1/left_arm_link,watch@panel/left_arm",
                "--link",
                "watch@teleop/left_arm",
            ]
            .map(String::from)
            .to_vec(),
            None,
            &StandaloneConfig::new(),
        )
        .unwrap();
        assert_eq!(commas.instance_id, "relay_1");
        assert_eq!(commas.pairs, s.pairs);
    }
}
