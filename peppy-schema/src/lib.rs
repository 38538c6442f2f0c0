//! # peppy-schema
//!
//! The one model of every peppy document, shared by the build script, the
//! `#[peppy::node]` macro and the launcher. It parses JSON5 with spans,
//! enforces every rule of the node, interface and launcher formats, resolves
//! a node against repositories (conformed interfaces, dependency slots,
//! sha256 pins) and builds a launcher's binding plan. It does no network or
//! process work: file contents in, model or located diagnostics out.
//!
//! ```
//! use peppy_schema::NodeDoc;
//!
//! let (node, warnings) = NodeDoc::parse("peppy.json5", r#"{
//!     peppy_schema: "node_v1",
//!     manifest: { name: "camera", tag: "v1" },
//!     interfaces: { topics: { emits: [
//!         { name: "frame", qos_profile: "sensor_data", message_format: { width: "u32", data: "bytes" } },
//!     ] } },
//!     execution: { language: "rust", run_cmd: ["./target/release/camera"] },
//! }"#).expect("valid");
//! assert!(warnings.is_empty());
//! assert_eq!(node.identity().to_string(), "camera:v1");
//! assert_eq!(node.emits[0].format.as_ref().unwrap().canonical(), "{width:u32,data:bytes}");
//!
//! // Every error of a document, located and named.
//! let errors = NodeDoc::parse("peppy.json5", r#"{
//!     peppy_schema: "node_v1",
//!     manifest: { name: "camera", tag: "0.1.0" },
//!     execution: { language: "rust", run_cmd: ["x"], bogus: 1 },
//! }"#).unwrap_err();
//! let lines: Vec<String> = errors.sorted().iter().map(|d| d.jump_line(None)).collect();
//! assert!(lines[0].starts_with("peppy.json5:3:38: error: invalid `manifest.tag` `0.1.0`"), "{}", lines[0]);
//! assert!(lines[1].starts_with("peppy.json5:4:52: error: unknown key `bogus` in `execution`"), "{}", lines[1]);
//! ```

// The run-time model: what a node binary needs, with no document parser.
mod binding;
mod diag;
mod loc;
mod model;
pub mod names;
mod pairs;
mod params;
mod primitive;
mod qos;
mod shutdown;
mod source;

// The documents: parsing, resolution, launchers and repositories (the
// `documents` feature, on by default; node binaries go without it).
#[cfg(feature = "documents")]
mod call_cycles;
#[cfg(feature = "documents")]
mod compose;
#[cfg(feature = "documents")]
mod core_nodes;
#[cfg(feature = "documents")]
mod document;
#[cfg(feature = "documents")]
mod entries;
#[cfg(feature = "documents")]
mod format;
#[cfg(feature = "documents")]
mod interface;
#[cfg(feature = "documents")]
pub mod json;
#[cfg(feature = "documents")]
mod launcher;
#[cfg(feature = "documents")]
pub mod layout;
#[cfg(feature = "documents")]
pub mod migrate;
#[cfg(feature = "documents")]
mod node;
#[cfg(feature = "documents")]
mod pair_links;
#[cfg(feature = "documents")]
mod pairing;
#[cfg(feature = "documents")]
mod pairing_slots;
#[cfg(feature = "documents")]
mod plan;
#[cfg(feature = "documents")]
mod read;
#[cfg(feature = "documents")]
mod repos;
#[cfg(feature = "documents")]
mod repository_index;
#[cfg(feature = "documents")]
mod resolve;
#[cfg(feature = "documents")]
mod stack;

pub use binding::{
    Assignment, BindError, BindForm, BindRequest, PlanMismatch, Producer, RouteFilter,
    ShapeProblem, SlotBinding, SlotPlan, assign, compute_filters, fit_plan,
};
pub use diag::{Code, Diagnostic, Diagnostics, Severity, did_you_mean};
pub use loc::Loc;
pub use model::{
    Cardinality, Dependency, Identity, NodeApi, NodeModel, PairingSlot, SlotKind, Spelling,
};
pub use pairs::{PairEnd, PairPlan, PairPlanError, check_pair_plan, fit_pair_plans};
pub use params::{
    ParamError, ParamErrorKind, ParamField, ParamItem, ParamKind, ParameterSchema, check_leaf,
    describe,
};
pub use primitive::{MAX_FIXED_LENGTH, Primitive, TYPE_NAMES};
pub use qos::{QOS_NAMES, QosProfile};
pub use shutdown::{
    DEFAULT_SHUTDOWN_GRACE, GraceError, MAX_SHUTDOWN_GRACE_SECS, SHUTDOWN_GRACE_ENV, grace_window,
    grace_window_env, grace_window_text,
};
pub use source::{LineCol, MAX_DOCUMENT_BYTES, SourceFile, Span};

#[cfg(feature = "documents")]
pub use binding::conformances;
#[cfg(feature = "documents")]
pub use compose::{
    Adjustment, AppliedChange, Axis, AxisOption, Choice, ChoiceSource, Composition,
    CompositionCheck, Constraint, MAX_LISTED_SELECTIONS, MAX_SELECTIONS, Pair, ResolveReport,
    Resolved, Selection, SelectionVerdict, SkippedAdjustment, resolve_launcher,
};
#[cfg(feature = "documents")]
pub use core_nodes::{CoreNode, Placement};
#[cfg(feature = "documents")]
pub use document::{
    Document, DocumentKind, GitRepository, Parsed, REPOSITORIES_FILE, RepositoriesDoc,
    RepositoryEntry, SCHEMAS, detect_kind, load_as, load_document, parse_as, parse_document,
};
#[cfg(feature = "documents")]
pub use entries::{
    ActionDecl, Declared, EntryKind, FeedbackDecl, RESERVED_SERVICE_NAMES, ServiceDecl, TopicDecl,
};
#[cfg(feature = "documents")]
pub use format::{CanonicalError, Field, FieldType, MessageFormat};
#[cfg(feature = "documents")]
pub use interface::InterfaceDoc;
#[cfg(feature = "documents")]
pub use launcher::{
    Deployment, FORBIDDEN_ENV_VARS, Framework, Instance, LauncherDoc, Link, LinkTarget, LinkValue,
    RestartPolicy, Source, stack_rules,
};
#[cfg(feature = "documents")]
pub use node::{
    ConsumedRef, ConsumedTopic, Container, Execution, FieldRefine, FormatRefine, InterfaceRef,
    Launch, MemberRef, NodeDoc, Pin, Refine, RefinedMessage, TopicSource,
};
#[cfg(feature = "documents")]
pub use pairing::{PairingDoc, PairingRole, PairingTopic};
#[cfg(feature = "documents")]
pub use pairing_slots::{PairingTopicUse, ResolvedPairing};
#[cfg(feature = "documents")]
pub use plan::{BindingPlan, InstancePlan, plan_bindings};
#[cfg(feature = "documents")]
pub use repos::{
    Broken, Entry, LauncherLookup, ListedBy, ListedRepository, REPOSITORIES_ENV, RepoIndex,
    RepositoryList, SKIPPED_DIRS, json5_files,
};
#[cfg(feature = "documents")]
pub use repository_index::{
    DeclaredIndex, Drift, IndexCheck, IndexKey, IndexSection, Listed, REPOSITORY_INDEX_FILE,
    REPOSITORY_INDEX_SCHEMA, RepositoryIndexDoc, check_index, check_index_path, declared_in,
};
#[cfg(feature = "documents")]
pub use resolve::{
    Origin, Provided, ResolvedCall, ResolvedNode, ResolvedTopic, SlotRef, UsedInterface,
    resolve_node,
};
#[cfg(feature = "documents")]
pub use source::sha256_hex;
#[cfg(feature = "documents")]
pub use stack::{
    DeployedNode, FetchError, FetchSource, NoFetch, NodeCheck, RepoOptions, StackCheck,
    check_launcher, check_launcher_selection, check_launcher_with, check_node, check_node_with,
    check_resolved, fills, node_file,
};
