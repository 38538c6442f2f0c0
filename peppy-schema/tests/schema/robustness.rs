//! Bad input of every shape, in both spellings: each value of a valid
//! document replaced by values of every other kind, each member removed,
//! random byte edits, and `launcher/v1` links rewritten into every
//! shape and planned against real nodes. Whatever the input, the outcome
//! is a document or located errors inside the file: never a panic, never a
//! failure without a reason.

use std::sync::Arc;

use peppy_schema::json::{Node, Value, parse};
use peppy_schema::{Diagnostics, Document, NodeDoc, SourceFile, parse_document, plan_bindings};
use proptest::prelude::*;

/// One document of each kind and spelling, shaped like the files people
/// write (the slashed ones like the public hubs').
const FIXTURES: &[(&str, &str)] = &[
    (
        "node_slashed.json5",
        r#"{
  peppy_schema: "node/v1",
  manifest: {
    name: "mapper", tag: "v1", labels: ["nav"],
    implements: [{ name: "range_scan", tag: "v1", link_id: "scan_out" }],
    depends_on: {
      nodes: [{ name: "logger", tag: "v1", link_id: "log", cardinality: "zero_or_one" }],
      contracts: [{ name: "range_scan", tag: "v1", link_id: "scans", cardinality: "one_or_more" }],
      pairings: [{ name: "link", tag: "v1", role: "leader", link_id: "peer", optional: true }],
      pairing_observers: [{ name: "link", tag: "v1", role: "follower", link_id: "watch", cardinality: "zero_or_more" }],
    },
  },
  interfaces: {
    topics: {
      emits: [
        { link_id: "scan_out", name: "scan", refine: { message_format: { ranges: { $length: 360 } } } },
        { name: "map", qos_profile: "reliable", message_format: { cells: { $type: "array", $items: "u8" } } },
        { link_id: "peer", name: "setpoints" },
      ],
      consumes: [
        { link_id: "scans", name: "scan" },
        { link_id: "watch", name: "states" },
      ],
    },
    services: { exposes: [{ name: "reset" }], consumes: [{ link_id: "log", name: "flush" }] },
    actions: { exposes: [{ link_id: "scan_out", name: "sweep" }] },
  },
  execution: {
    language: "rust",
    container: { def_file: "apptainer.def", mount_paths: ["${parameters:device}:/dev/x"] },
    parameters: { device: "string", rate: { $type: "f64", $default: 10 } },
  },
}"#,
    ),
    (
        "node_underscored.json5",
        r#"{
  peppy_schema: "node_v1",
  manifest: {
    name: "recon", tag: "v1",
    depends_on: {
      interfaces: [
        { name: "depth_camera", tag: "v1", link_id: "left_cam" },
        { name: "depth_camera", tag: "v1", link_id: "backup", from_any: true },
      ],
    },
  },
  interfaces: {
    conforms_to: [{ name: "mapper_if", tag: "v1" }],
    topics: {
      emits: [{ name: "cloud", message_format: { points: { $type: "array", $items: "f32" } } }],
      consumes: [
        { link_id: "left_cam", name: "video_stream" },
        { name: "clock", message_format: { t: "time" } },
      ],
    },
  },
  execution: { language: "rust", run_cmd: ["./recon"], parameters: { fps: "u16" } },
}"#,
    ),
    (
        "contract.json5",
        r#"{
  peppy_schema: "contract/v1",
  manifest: { name: "range_scan", tag: "v1" },
  interfaces: {
    topics: [{ name: "scan", qos_profile: "sensor_data", message_format: { ranges: { $type: "array", $items: "f32" } } }],
    services: [{ name: "info", response_message_format: { max_range: "f32" } }],
    actions: [{
      name: "sweep",
      goal_service: { request_message_format: { from: "f32", to: "f32" } },
      feedback_topic: { message_format: { at: "f32" } },
      result_service: { response_message_format: { ok: "bool" } },
    }],
  },
}"#,
    ),
    (
        "pairing.json5",
        r#"{
  peppy_schema: "pairing/v1",
  manifest: { name: "link", tag: "v1" },
  roles: ["leader", "follower"],
  topics: [
    { emitted_by: "leader", name: "setpoints", message_format: { q: { $type: "array", $items: "f64" } } },
    { emitted_by: "follower", name: "states", qos_profile: "sensor_data" },
  ],
}"#,
    ),
    ("launcher_slashed.json5", LAUNCHER_SLASHED),
    (
        "launcher_underscored.json5",
        r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { local: "../nodes/recon" },
      instances: [{ instance_id: "recon_1", bindings: { left_cam: "cam_a", spare: "cam_b" } }] },
    { source: { name: "cam:v1" }, instances: [{ instance_id: "cam_a" }, { instance_id: "cam_b", restart: "always" }] },
  ],
}"#,
    ),
];

const LAUNCHER_SLASHED: &str = r#"{
  peppy_schema: "launcher/v1",
  core_nodes: ["robot", "workstation"],
  deployments: [
    { source: { name: "consumer", tag: "v1" },
      instances: [{
        instance_id: "consumer_1",
        core_node: "workstation",
        arguments: { rate: 5 },
        env_vars: { RUST_LOG: "info" },
        framework: { use_sim_time: false },
        links: { one: "prod_a", maybe: { vacant: "bench run" }, many: ["prod_a", "prod_b"], any: [] },
      }] },
    { source: { name: "producer:v1" },
      instances: [{ instance_id: "prod_a", core_node: "robot" }, { instance_id: "prod_b" }] },
  ],
}"#;

/// The nodes [`LAUNCHER_SLASHED`] deploys: one slot of each cardinality.
const CONSUMER: &str = r#"{ peppy_schema: "node/v1",
  manifest: { name: "consumer", tag: "v1", depends_on: {
    nodes: [
      { name: "producer", tag: "v1", link_id: "one" },
      { name: "producer", tag: "v1", link_id: "maybe", cardinality: "zero_or_one" },
      { name: "producer", tag: "v1", link_id: "many", cardinality: "one_or_more" },
      { name: "producer", tag: "v1", link_id: "any", cardinality: "zero_or_more" },
    ] } },
  execution: { language: "rust", run_cmd: ["x"], parameters: { rate: { $type: "u32", $default: 1 } } } }"#;
const PRODUCER: &str = r#"{ peppy_schema: "node/v1", manifest: { name: "producer", tag: "v1" },
  interfaces: { topics: { emits: [{ name: "data" }] } },
  execution: { language: "rust", run_cmd: ["x"] } }"#;

/// Values of every kind (and of the shapes slashed documents give
/// meaning to) that any value may be replaced by.
const REPLACEMENTS: &[&str] = &[
    "null",
    "0",
    "-1",
    "1.5e400",
    "true",
    "\"\"",
    "\"x\"",
    "\"_\"",
    "\"a/b/c\"",
    "\"n:t:u\"",
    "[]",
    "[\"x\", \"x\"]",
    "{}",
    "{ vacant: \"\" }",
    "{ $length: 7 }",
    "{ link_id: \"x\", name: \"y\" }",
];

/// Every finding of `text`, checked to be honest: a refusal says why, and
/// every location is inside the file.
fn check(name: &str, text: &str) -> Option<Document> {
    let file = Arc::new(SourceFile::new(name, text));
    let outcome = parse_document(&file, "0".repeat(64).as_str());
    let diags = match &outcome {
        Ok((_, warnings)) => warnings,
        Err(errors) => {
            assert!(errors.has_errors(), "refused without an error:\n{text}");
            errors
        }
    };
    located_inside(diags, text);
    outcome.ok().map(|(d, _)| d)
}

fn located_inside(diags: &Diagnostics, text: &str) {
    for d in diags.iter() {
        if let Some(span) = d.span() {
            assert!(
                span.start <= span.end && span.end <= text.len(),
                "`{d}` points outside the file ({span:?}, {} bytes):\n{text}",
                text.len()
            );
        }
    }
}

/// Every value node and member of `node`, depth first.
fn spans(node: &Node, values: &mut Vec<(usize, usize)>, members: &mut Vec<(usize, usize)>) {
    values.push((node.span.start, node.span.end));
    match &node.value {
        Value::Object(ms) => {
            for m in ms {
                members.push((m.key_span.start, m.value.span.end));
                spans(&m.value, values, members);
            }
        }
        Value::Array(items) => items.iter().for_each(|i| spans(i, values, members)),
        _ => {}
    }
}

fn tree(name: &str, text: &str) -> Node {
    let file = Arc::new(SourceFile::new(name, text));
    parse(&file).unwrap_or_else(|e| panic!("{name}: {e}")).0
}

#[test]
fn the_fixtures_are_valid() {
    for (name, text) in FIXTURES {
        assert!(check(name, text).is_some(), "{name} should be valid");
    }
}

#[test]
fn any_value_replaced_by_any_kind_is_a_document_or_located_errors() {
    let mut parses = 0;
    for (name, text) in FIXTURES {
        let (mut values, mut members) = (Vec::new(), Vec::new());
        spans(&tree(name, text), &mut values, &mut members);
        for (start, end) in values {
            for r in REPLACEMENTS {
                let mutated = format!("{}{r}{}", &text[..start], &text[end..]);
                check(name, &mutated);
                parses += 1;
            }
        }
        // Each member removed (its trailing comma stays: JSON5 allows it
        // unless it doubles, which is a located syntax error).
        for (start, end) in members {
            let mutated = format!("{}{}", &text[..start], &text[end..]);
            check(name, &mutated);
            parses += 1;
        }
    }
    assert!(parses > 2_000, "only {parses} mutations");
}

/// `launcher` planned against [`CONSUMER`] and [`PRODUCER`].
fn plan(text: &str) {
    let Some(Document::Launcher(launcher)) = check("launcher.json5", text) else {
        return;
    };
    let consumer = node(CONSUMER);
    let producer = node(PRODUCER);
    let nodes: Vec<Option<&NodeDoc>> = launcher
        .deployments
        .iter()
        .map(|d| match format!("{:?}", d.source) {
            s if s.contains("consumer") => Some(&consumer),
            s if s.contains("producer") => Some(&producer),
            _ => None,
        })
        .collect();
    let diags = match plan_bindings(&launcher, &nodes) {
        Ok((_, warnings)) => warnings,
        Err(errors) => {
            assert!(
                errors.has_errors(),
                "plan refused without an error:\n{text}"
            );
            errors
        }
    };
    located_inside(&diags, text);
}

fn node(text: &str) -> NodeDoc {
    NodeDoc::parse("peppy.json5", text)
        .unwrap_or_else(|e| panic!("{e}"))
        .0
}

#[test]
fn every_link_shape_on_every_cardinality_plans_or_is_located() {
    let links_at = LAUNCHER_SLASHED.find("links:").unwrap();
    let values = [
        "\"prod_a\"",
        "\"prod_b\"",
        "\"nobody\"",
        "\"prod_a/peer\"",
        "[]",
        "[\"prod_a\"]",
        "[\"prod_b\", \"prod_a\"]",
        "[\"prod_a\", \"prod_a\"]",
        "[\"consumer_1\"]",
        "{ vacant: \"why\" }",
        "{ vacant: \" \" }",
        "{ vacant: \"why\", extra: 1 }",
        "7",
    ];
    let slots = ["one", "maybe", "many", "any", "nope", "_"];
    let mut planned = 0;
    for slot in slots {
        for v in values {
            for keep_others in [true, false] {
                let links = if keep_others {
                    let mut all: Vec<String> = [
                        "one: \"prod_a\"",
                        "maybe: \"prod_b\"",
                        "many: [\"prod_a\"]",
                        "any: []",
                    ]
                    .iter()
                    .filter(|l| !l.starts_with(&format!("{slot}:")))
                    .map(|l| l.to_string())
                    .collect();
                    all.push(format!("{slot}: {v}"));
                    all.join(", ")
                } else {
                    format!("{slot}: {v}")
                };
                let end = LAUNCHER_SLASHED[links_at..].find('}').unwrap() + links_at;
                // The vacancy fixture's braces: cut at the links map's end.
                let end = LAUNCHER_SLASHED[end + 1..].find('}').unwrap() + end + 1;
                let text = format!(
                    "{}links: {{ {links} }}{}",
                    &LAUNCHER_SLASHED[..links_at],
                    &LAUNCHER_SLASHED[end + 1..]
                );
                plan(&text);
                planned += 1;
            }
        }
    }
    assert_eq!(planned, slots.len() * values.len() * 2);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

    /// Random byte edits anywhere in any fixture.
    #[test]
    fn random_edits_never_panic(
        which in 0..FIXTURES.len(),
        edits in proptest::collection::vec((any::<prop::sample::Index>(), 0u8..4, any::<char>()), 1..6),
    ) {
        let (name, text) = FIXTURES[which];
        let mut s: Vec<char> = text.chars().collect();
        for (at, op, c) in edits {
            if s.is_empty() {
                break;
            }
            let i = at.index(s.len());
            match op {
                0 => { s.remove(i); }
                1 => s.insert(i, c),
                2 => s[i] = c,
                _ => s.truncate(i),
            }
        }
        let text: String = s.into_iter().collect();
        check(name, &text);
        if name == "launcher_slashed.json5" {
            plan(&text);
        }
    }
}
