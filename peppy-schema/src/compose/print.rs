//! The flat launcher as text: pretty `launcher/v1` JSON5 (unquoted keys,
//! two-space indent, one key per line; every instance with `arguments`,
//! `env_vars` and `framework`; argument and link keys sorted), which parses
//! back to the same launcher and prints again the same.

use std::fmt::Write as _;

use crate::json::{Member, Node, Number, Value};

/// A flat launcher being composed.
#[derive(Debug, Clone)]
pub(crate) struct FlatLauncher {
    pub(crate) core_nodes: Option<Node>,
    pub(crate) security: Option<Node>,
    pub(crate) deployments: Vec<FlatDeployment>,
}

/// One deployment of a flat launcher.
#[derive(Debug, Clone)]
pub(crate) struct FlatDeployment {
    pub(crate) source: Node,
    pub(crate) instances: Vec<FlatInstance>,
}

/// One instance: its id and its other keys.
#[derive(Debug, Clone)]
pub(crate) struct FlatInstance {
    pub(crate) id: String,
    pub(crate) members: Vec<Member>,
}

/// Keys printed in this order; any other after them, as written.
const INSTANCE_ORDER: &[&str] = &[
    "arguments",
    "env_vars",
    "framework",
    "links",
    "core_node",
    "restart",
];

/// Always printed, even empty.
const ALWAYS: &[&str] = &["arguments", "env_vars", "framework"];

impl FlatLauncher {
    pub(crate) fn render(&self) -> String {
        let mut top: Vec<(String, String)> =
            vec![("peppy_schema".into(), "\"launcher/v1\"".into())];
        if let Some(c) = &self.core_nodes {
            top.push(("core_nodes".into(), pretty(c, 1)));
        }
        if let Some(s) = &self.security {
            top.push(("security".into(), pretty(s, 1)));
        }
        let mut deps = String::from("[\n");
        for (i, d) in self.deployments.iter().enumerate() {
            deps.push_str("    {\n");
            let _ = writeln!(deps, "      source: {},", pretty(&d.source, 3));
            deps.push_str("      instances: [\n");
            for (j, inst) in d.instances.iter().enumerate() {
                deps.push_str("        {\n");
                let _ = write!(deps, "          instance_id: {}", quote(&inst.id));
                for key in INSTANCE_ORDER {
                    match inst.members.iter().find(|m| m.key == *key) {
                        Some(m) => {
                            let sorted = matches!(*key, "arguments" | "links");
                            let v = if sorted {
                                sorted_object(&m.value)
                            } else {
                                m.value.clone()
                            };
                            let _ = write!(deps, ",\n          {key}: {}", pretty(&v, 5));
                        }
                        None if ALWAYS.contains(key) => {
                            let _ = write!(deps, ",\n          {key}: {{}}");
                        }
                        None => {}
                    }
                }
                for m in inst
                    .members
                    .iter()
                    .filter(|m| !INSTANCE_ORDER.contains(&m.key.as_str()))
                {
                    let _ = write!(
                        deps,
                        ",\n          {}: {}",
                        key(&m.key),
                        pretty(&m.value, 5)
                    );
                }
                deps.push_str("\n        }");
                deps.push_str(if j + 1 < d.instances.len() {
                    ",\n"
                } else {
                    "\n"
                });
            }
            deps.push_str("      ]\n    }");
            deps.push_str(if i + 1 < self.deployments.len() {
                ",\n"
            } else {
                "\n"
            });
        }
        deps.push_str("  ]");
        top.push(("deployments".into(), deps));
        let mut out = String::from("{\n");
        for (i, (k, v)) in top.iter().enumerate() {
            let _ = write!(out, "  {k}: {v}");
            out.push_str(if i + 1 < top.len() { ",\n" } else { "\n" });
        }
        out.push_str("}\n");
        out
    }
}

/// An object with its keys sorted (anything else as it is).
fn sorted_object(n: &Node) -> Node {
    match &n.value {
        Value::Object(members) => {
            let mut members = members.clone();
            members.sort_by(|a, b| a.key.cmp(&b.key));
            Node {
                span: n.span,
                value: Value::Object(members),
            }
        }
        _ => n.clone(),
    }
}

fn quote(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| format!("{s:?}"))
}

/// A key unquoted when it is an identifier.
fn key(k: &str) -> String {
    let mut chars = k.chars();
    let ident = chars
        .next()
        .is_some_and(|c| c == '_' || c == '$' || c.is_ascii_alphabetic())
        && chars.all(|c| c == '_' || c == '$' || c.is_ascii_alphanumeric());
    if ident { k.to_string() } else { quote(k) }
}

fn number(n: Number) -> String {
    match n {
        Number::Int(i) => i.to_string(),
        Number::Float(f) if f.is_nan() => "NaN".to_string(),
        Number::Float(f) if f.is_infinite() => {
            if f > 0.0 { "Infinity" } else { "-Infinity" }.to_string()
        }
        // `{:?}` keeps a float a float (`30.0`, not `30`).
        Number::Float(f) => format!("{f:?}"),
    }
}

/// JSON5 of `n`, nested at `depth` (two spaces each).
pub(crate) fn pretty(n: &Node, depth: usize) -> String {
    let pad = "  ".repeat(depth + 1);
    let close = "  ".repeat(depth);
    match &n.value {
        Value::Null => "null".into(),
        Value::Bool(b) => b.to_string(),
        Value::Number(x) => number(*x),
        Value::String(s) => quote(s),
        Value::Array(items) if items.is_empty() => "[]".into(),
        Value::Object(members) if members.is_empty() => "{}".into(),
        Value::Array(items) => {
            let inner: Vec<String> = items
                .iter()
                .map(|i| format!("{pad}{}", pretty(i, depth + 1)))
                .collect();
            format!("[\n{}\n{close}]", inner.join(",\n"))
        }
        Value::Object(members) => {
            let inner: Vec<String> = members
                .iter()
                .map(|m| format!("{pad}{}: {}", key(&m.key), pretty(&m.value, depth + 1)))
                .collect();
            format!("{{\n{}\n{close}}}", inner.join(",\n"))
        }
    }
}

/// Compact JSON of `n`, for reports.
pub(crate) fn compact(n: &Node) -> String {
    match &n.value {
        Value::Number(x) => number(*x),
        _ => n.to_json().to_string(),
    }
}
