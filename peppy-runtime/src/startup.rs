//! Start-up inputs: identity, bindings, parameters, namespace and Zenoh
//! endpoints, from the launcher's runtime-config file or, in a standalone
//! `cargo run`, from command-line flags and [`StandaloneConfig`].

use std::collections::BTreeMap;
use std::hash::{BuildHasher, Hasher};
use std::path::{Path, PathBuf};

use clap::Parser;
use peppy_schema::{
    BindRequest, NodeModel, ParamKind, ParameterSchema, Primitive, SlotBinding, SlotPlan, assign,
    requests_for,
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

/// What a node is told at start-up. The launcher writes it as JSON and names
/// the file in `PEPPY_RUNTIME_CONFIG`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StartupConfig {
    /// This instance's id.
    pub instance_id: String,
    /// The launch (core node) that started it.
    pub core_node: String,
    /// The namespace every key lives under.
    pub namespace: String,
    /// What fills each slot, by link_id.
    #[serde(default)]
    pub bindings: BTreeMap<String, SlotBinding>,
    /// Parameter values (defaults are filled again by the node).
    #[serde(default)]
    pub parameters: Json,
    /// How to reach the other nodes.
    #[serde(default)]
    pub zenoh: Endpoints,
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
}

/// Flags of a standalone run.
#[derive(Debug, Parser)]
#[command(about = "A peppy node. Started by `peppy-launch`, or standalone with these flags.")]
struct Flags {
    /// This instance's id (default: a readable random id).
    #[arg(long, value_name = "ID")]
    instance_id: Option<String>,
    /// Bind a slot: `--bind left_cam@rs_left` (repeatable).
    #[arg(long = "bind", value_name = "KEY@INSTANCE")]
    bind: Vec<String>,
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
    /// Parameter overrides, `key=value`, dot-paths for groups (`video.fps=30`).
    #[arg(value_name = "KEY=VALUE")]
    overrides: Vec<String>,
}

/// Everything the node needs, resolved and checked.
#[derive(Debug, Clone)]
pub(crate) struct Startup {
    pub(crate) config: StartupConfig,
    pub(crate) slots: Vec<SlotPlan>,
    pub(crate) parameters: Json,
}

/// Reads the start-up inputs: the runtime-config file when the launcher set
/// `PEPPY_RUNTIME_CONFIG`, else `args` (the command line) and `standalone`.
pub(crate) fn load(
    doc: &NodeModel,
    args: Vec<String>,
    env_file: Option<PathBuf>,
    standalone: &StandaloneConfig,
) -> Result<Startup> {
    let (config, binds_given) = match env_file {
        Some(path) => (read_config_file(&path)?, None),
        None => {
            let flags = Flags::try_parse_from(args).map_err(|e| Error::Startup(e.to_string()))?;
            standalone_config(doc, flags, standalone)?
        }
    };
    for (what, value) in [
        ("instance id", &config.instance_id),
        ("core node", &config.core_node),
        ("namespace", &config.namespace),
    ] {
        if let Err(why) = peppy_schema::names::check_name(value) {
            return Err(Error::Startup(format!("invalid {what} `{value}`: {why}")));
        }
    }
    let slots = match binds_given {
        Some(binds) => slots_from_flags(doc, &config.instance_id, &binds)?,
        None => slots_from_config(doc, &config.instance_id, &config.bindings)?,
    };
    let parameters = doc
        .parameters
        .resolve(&config.parameters)
        .map_err(Error::Parameters)?;
    Ok(Startup {
        config,
        slots,
        parameters,
    })
}

/// What a standalone command line (`--instance-id`, `--bind`, `--params`,
/// `key=value`, ...) means for the node `doc`: the start-up config it
/// describes, with bindings checked and parameters filled. `peppy-launch run`
/// hands this to the node it starts.
pub fn startup_from_flags(doc: &NodeModel, args: Vec<String>) -> Result<StartupConfig> {
    let s = load(doc, args, None, &StandaloneConfig::default())?;
    let mut config = s.config;
    config.bindings = s
        .slots
        .into_iter()
        .map(|slot| (slot.link_id, slot.binding))
        .collect();
    config.parameters = s.parameters;
    Ok(config)
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

type Binds = Vec<(String, String)>;

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
        binds.push((key.to_string(), instance.to_string()));
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
        }
    };
    let config = StartupConfig {
        instance_id: flags
            .instance_id
            .or_else(|| standalone.instance_id.clone())
            .unwrap_or_else(|| readable_id(&doc.identity.name)),
        core_node: STANDALONE_CORE.to_string(),
        namespace: flags
            .namespace
            .or_else(|| standalone.namespace.clone())
            .unwrap_or_else(|| DEFAULT_NAMESPACE.to_string()),
        bindings: BTreeMap::new(),
        parameters,
        zenoh: endpoints,
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

/// Slots from `--bind` flags, through the binding engine. The producers'
/// nodes are not known on a command line, so a free-form key joins the
/// first `from_any` slot only when every `from_any` slot wants the same
/// producers; otherwise the flag must name the slot.
fn slots_from_flags(
    doc: &NodeModel,
    instance: &str,
    binds: &[(String, String)],
) -> Result<Vec<SlotPlan>> {
    let requests: Vec<BindRequest<'_>> = binds
        .iter()
        .map(|(key, producer)| BindRequest {
            key,
            instance: producer,
            producer: None,
        })
        .collect();
    engine(doc, instance, &requests)
}

/// Slots from the launcher's bindings, re-checked by the same engine (the
/// launcher decided them; a disagreement means the binary and the launcher
/// read different documents).
fn slots_from_config(
    doc: &NodeModel,
    instance: &str,
    bindings: &BTreeMap<String, SlotBinding>,
) -> Result<Vec<SlotPlan>> {
    if let Some(unknown) = bindings.keys().find(|k| doc.dependency(k).is_none()) {
        return Err(Error::Startup(format!(
            "the runtime config binds `{unknown}`, which is not a slot of `{}`; was this binary built from another peppy.json5 than the launcher read?",
            doc.identity
        )));
    }
    let requests = requests_for(bindings.iter().map(|(k, b)| (k.as_str(), b)));
    engine(doc, instance, &requests)
}

fn engine(doc: &NodeModel, instance: &str, requests: &[BindRequest<'_>]) -> Result<Vec<SlotPlan>> {
    let outcome = assign(instance, &doc.identity, &doc.dependencies, requests);
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
    use peppy_schema::{NodeDoc, RouteFilter};

    /// A node's model as its binary sees it: through the JSON the build embeds.
    fn model(text: &str) -> NodeModel {
        let (doc, _) = NodeDoc::parse("peppy.json5", text).unwrap();
        NodeModel::from_json(&NodeModel::of(&doc).to_json()).unwrap()
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
        assert_eq!(s.config.instance_id, "r1");
        assert_eq!(s.config.namespace, DEFAULT_NAMESPACE);
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

    #[test]
    fn runtime_config_file_is_used_when_set() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rt.json");
        let cfg = StartupConfig {
            instance_id: "recon_1".into(),
            core_node: "lab-1".into(),
            namespace: "lab".into(),
            bindings: [(
                "left_cam".to_string(),
                SlotBinding::Pinned {
                    producer: "rs_left".into(),
                },
            )]
            .into(),
            parameters: serde_json::json!({ "name": "n" }),
            zenoh: Endpoints {
                connect: vec!["tcp/127.0.0.1:7447".into()],
                ..Endpoints::default()
            },
        };
        std::fs::write(&path, serde_json::to_string(&cfg).unwrap()).unwrap();
        let s = load(
            &doc(),
            args(&["ignored=1"]),
            Some(path),
            &StandaloneConfig::new(),
        )
        .unwrap();
        assert_eq!(s.config, cfg);
        assert_eq!(
            s.slots[1].filter,
            RouteFilter::AnyExcept(["rs_left".to_string()].into())
        );
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
