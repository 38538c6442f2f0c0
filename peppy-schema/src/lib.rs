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

mod binding;
mod diag;
mod document;
mod entries;
mod format;
mod interface;
pub mod json;
mod launcher;
pub mod names;
mod node;
mod params;
mod plan;
mod read;
mod repos;
mod resolve;
mod source;
mod stack;

pub use binding::{
    Assignment, BindError, BindRequest, Producer, RouteFilter, SlotBinding, SlotPlan, assign,
    compute_filters, conformances, requests_for,
};
pub use diag::{Code, Diagnostic, Diagnostics, Severity, did_you_mean};
pub use document::{
    Document, DocumentKind, Parsed, REPOSITORIES_FILE, RepositoriesDoc, SCHEMAS, detect_kind,
    load_as, load_document, parse_as, parse_document,
};
pub use entries::{
    ActionDecl, EntryKind, FeedbackDecl, QOS_NAMES, QosProfile, RESERVED_SERVICE_NAMES,
    ServiceDecl, TopicDecl,
};
pub use format::{Field, FieldType, MAX_FIXED_LENGTH, MessageFormat, Primitive, TYPE_NAMES};
pub use interface::InterfaceDoc;
pub use launcher::{
    Binding, Deployment, FORBIDDEN_ENV_VARS, Instance, LauncherDoc, RestartPolicy, Source,
    stack_rules,
};
pub use node::{
    ConsumedRef, ConsumedTopic, Container, Dependency, Execution, Identity, InterfaceRef, Launch,
    NodeDoc, SlotKind, TopicSource,
};
pub use params::{
    ParamError, ParamErrorKind, ParamField, ParamItem, ParamKind, ParameterSchema, check_leaf,
    describe,
};
pub use plan::{BindingPlan, InstancePlan, plan_bindings};
pub use read::Loc;
pub use repos::{
    Broken, Entry, REPOSITORIES_ENV, RepoIndex, RepositoryList, SKIPPED_DIRS, json5_files,
};
pub use resolve::{
    Origin, Provided, ResolvedCall, ResolvedNode, ResolvedTopic, SlotRef, UsedInterface,
    resolve_node,
};
pub use source::{LineCol, MAX_DOCUMENT_BYTES, SourceFile, Span, sha256_hex};
pub use stack::{
    DeployedNode, NodeCheck, RepoOptions, StackCheck, check_launcher, check_node, node_file,
};
