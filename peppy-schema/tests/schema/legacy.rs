//! SPEC 1.2: the legacy `schema_version: 1` form of seed 002.

use peppy_schema::{
    Code, Diagnostics, QosProfile, RepoIndex, Severity, SlotKind, TopicSource, resolve_node,
};

use crate::support::*;

/// Seed 002, `robot_arm` (Rust variant), laid out on lines.
pub(crate) const ROBOT_ARM: &str = r#"{
  schema_version: 1,
  manifest: {
    name: "robot_arm",
    tag: "0.1.0",
    language: "rust",
    // No depends_on — robot_arm does not depend on arm_controller
  },
  process: {
    add_cmd: ["cargo", "build", "--release"],
    start_cmd: ["./target/release/robot_arm"]
  },
  interfaces: {
    topics: {
      emits: [
        {
          name: "joint_states",
          qos_profile: "sensor_data",
          message_format: {
            positions: { $type: "array", $items: "f64", $length: 3 },
            velocities: { $type: "array", $items: "f64", $length: 3 },
            timestamp: "time"
          }
        }
      ],
      consumes: [
        {
          // No local_node_id — this is an external consumed topic
          name: "joint_commands",
          message_format: {
            target_positions: { $type: "array", $items: "f64", $length: 3 },
            max_velocity: "f64"
          }
        }
      ],
    },
  },
}
"#;

/// Seed 002, `arm_controller` (Rust variant), laid out on lines.
pub(crate) const ARM_CONTROLLER: &str = r#"{
  schema_version: 1,
  manifest: {
    name: "arm_controller",
    tag: "0.1.0",
    language: "rust",
    depends_on: {
      nodes: [
        { name: "robot_arm", tag: "0.1.0", local_id: "robot_arm" },
      ]
    },
  },
  process: {
    add_cmd: ["cargo", "build", "--release"],
    start_cmd: ["./target/release/arm_controller"]
  },
  interfaces: {
    topics: {
      emits: [
        {
          name: "joint_commands",
          qos_profile: "reliable",
          message_format: {
            target_positions: { $type: "array", $items: "f64", $length: 3 },
            max_velocity: "f64"
          }
        }
      ],
      consumes: [
        {
          local_node_id: "robot_arm", // Linked — references depends_on
          name: "joint_states",
        },
      ],
    },
  },
}
"#;

/// `(key path, line, help)` of every warning, in position order.
fn warnings_of(warnings: &Diagnostics) -> Vec<(String, usize, String)> {
    warnings
        .sorted()
        .iter()
        .map(|d| {
            assert_eq!(d.code, Code::LegacySpelling, "{d}");
            assert_eq!(d.severity, Severity::Warning, "{d}");
            (key(d).to_string(), lc(d).0, help(d).to_string())
        })
        .collect()
}

#[test]
fn seed_robot_arm_parses_with_warnings_naming_the_new_spelling() {
    let (node, warnings) = node_ok(ROBOT_ARM);
    assert!(!warnings.has_errors());
    let t = ROBOT_ARM;
    assert_eq!(
        warnings_of(&warnings),
        [
            (
                "schema_version".into(),
                pos(t, "schema_version").0,
                "write `peppy_schema: \"node_v1\"`".into()
            ),
            (
                "manifest.language".into(),
                pos(t, "language").0,
                "write `execution.language`".into()
            ),
            (
                "process".into(),
                pos(t, "process").0,
                "write `execution`".into()
            ),
            (
                "process.add_cmd".into(),
                pos(t, "add_cmd").0,
                "write `execution.build_cmd`".into()
            ),
            (
                "process.start_cmd".into(),
                pos(t, "start_cmd").0,
                "write `execution.run_cmd`".into()
            ),
        ]
    );
    let d = warnings.sorted()[0];
    assert_eq!(lc(d), pos(t, "schema_version"));
    assert!(
        d.message.contains("legacy `schema_version: 1` spelling"),
        "{d}"
    );
    assert!(
        d.jump_line(None).starts_with("peppy.json5:2:3: warning: "),
        "{}",
        d.jump_line(None)
    );

    assert!(node.legacy);
    assert_eq!(node.identity().to_string(), "robot_arm:0.1.0");
    assert_eq!(node.execution.language, "rust");
    assert_eq!(
        node.execution.build_cmd.as_deref().unwrap(),
        ["cargo", "build", "--release"]
    );
    assert_eq!(
        node.execution.run_cmd.as_deref().unwrap(),
        ["./target/release/robot_arm"]
    );
    assert!(node.dependencies.is_empty());
    assert_eq!(node.emits[0].qos, QosProfile::SensorData);
    assert_eq!(
        node.emits[0].format.as_ref().unwrap().canonical(),
        "{positions:[f64;3],velocities:[f64;3],timestamp:time}"
    );
    assert_eq!(node.consumed_topics[0].name, "joint_commands");
    match &node.consumed_topics[0].source {
        TopicSource::External(f) => {
            assert_eq!(f.canonical(), "{target_positions:[f64;3],max_velocity:f64}")
        }
        other => panic!("expected an external topic, got {other:?}"),
    }
}

#[test]
fn seed_arm_controller_maps_local_ids_onto_link_ids() {
    let (node, warnings) = node_ok(ARM_CONTROLLER);
    let t = ARM_CONTROLLER;
    assert_eq!(
        warnings_of(&warnings),
        [
            (
                "schema_version".into(),
                2,
                "write `peppy_schema: \"node_v1\"`".into()
            ),
            (
                "manifest.language".into(),
                6,
                "write `execution.language`".into()
            ),
            (
                "manifest.depends_on.nodes[0].local_id".into(),
                pos(t, "local_id").0,
                "write `link_id`".into()
            ),
            (
                "process".into(),
                pos(t, "process").0,
                "write `execution`".into()
            ),
            (
                "process.add_cmd".into(),
                pos(t, "add_cmd").0,
                "write `execution.build_cmd`".into()
            ),
            (
                "process.start_cmd".into(),
                pos(t, "start_cmd").0,
                "write `execution.run_cmd`".into()
            ),
            (
                "interfaces.topics.consumes[0].local_node_id".into(),
                pos(t, "local_node_id").0,
                "write `link_id`".into()
            ),
        ]
    );

    assert!(node.legacy);
    assert_eq!(node.identity().to_string(), "arm_controller:0.1.0");
    let dep = &node.dependencies[0];
    assert_eq!(
        (
            dep.kind,
            dep.target.to_string(),
            dep.link_id.as_str(),
            dep.from_any
        ),
        (
            SlotKind::Node,
            "robot_arm:0.1.0".to_string(),
            "robot_arm",
            false
        )
    );
    match &node.consumed_topics[0].source {
        TopicSource::Linked { link_id } => assert_eq!(link_id, "robot_arm"),
        other => panic!("expected a linked topic, got {other:?}"),
    }
    assert_eq!(node.emits[0].qos, QosProfile::Reliable);
}

#[test]
fn seed_python_variant_carries_its_language() {
    let text = ROBOT_ARM
        .replace(r#"language: "rust""#, r#"language: "python""#)
        .replace(
            r#"add_cmd: ["cargo", "build", "--release"]"#,
            r#"add_cmd: ["uv", "sync"]"#,
        )
        .replace(
            r#"start_cmd: ["./target/release/robot_arm"]"#,
            r#"start_cmd: ["uv", "run", "robot_arm"]"#,
        );
    let (node, warnings) = node_ok(&text);
    assert_eq!(warnings.len(), 5);
    assert_eq!(node.execution.language, "python");
    assert_eq!(node.execution.build_cmd.as_deref().unwrap(), ["uv", "sync"]);
    assert_eq!(
        node.execution.run_cmd.as_deref().unwrap(),
        ["uv", "run", "robot_arm"]
    );
}

#[test]
fn legacy_documents_are_still_validated() {
    // No `process.start_cmd`, no `manifest.language`, and a current-only key.
    let text = r#"{
  schema_version: 1,
  manifest: { name: "robot_arm", tag: "0.1.0" },
  process: { add_cmd: ["make"] },
  execution: { language: "rust" },
}"#;
    let errors = node_err(text);
    let got: Vec<(Code, &str)> = errors
        .sorted()
        .iter()
        .filter(|d| d.is_error())
        .map(|d| (d.code, key(d)))
        .collect();
    assert_eq!(
        got,
        [
            (Code::MissingKey, "manifest"),
            (Code::MissingKey, "process"),
            (Code::UnknownKey, "execution")
        ]
    );
    assert!(
        all(&errors, Code::MissingKey)[0]
            .message
            .contains("`language`")
    );
    assert!(
        all(&errors, Code::MissingKey)[1]
            .message
            .contains("`start_cmd`")
    );
}

#[test]
fn current_documents_get_pointed_at_link_id() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: {
    name: "arm_controller",
    tag: "v1",
    depends_on: { nodes: [{ name: "robot_arm", tag: "v1", local_id: "robot_arm" }] },
  },
  interfaces: { topics: { consumes: [{ local_node_id: "robot_arm", name: "joint_states" }] } },
  execution: { language: "rust", run_cmd: ["./arm_controller"] },
}"#;
    let errors = node_err(text);
    let unknown = all(&errors, Code::UnknownKey);
    assert_eq!(unknown.len(), 2, "{errors}");
    assert_at(
        unknown[0],
        Code::UnknownKey,
        "manifest.depends_on.nodes[0].local_id",
        text,
        "local_id",
    );
    assert!(
        help(unknown[0]).starts_with("did you mean `link_id`?"),
        "{}",
        unknown[0]
    );
    assert_at(
        unknown[1],
        Code::UnknownKey,
        "interfaces.topics.consumes[0].local_node_id",
        text,
        "local_node_id",
    );
    assert!(
        help(unknown[1]).starts_with("did you mean `link_id`?"),
        "{}",
        unknown[1]
    );
    // Without link_id the slot misses its key, and the topic has neither link nor format.
    assert!(errors.contains(Code::MissingKey));
    assert!(errors.contains(Code::ExternalFormatMissing));
    assert!(
        !errors.contains(Code::LegacySpelling),
        "no legacy warnings in a current document"
    );

    // Other legacy spellings in a current document.
    let text = r#"{
  peppy_schema: "node_v1",
  schema_version: 1,
  manifest: { name: "robot_arm", tag: "v1" },
  process: { start_cmd: ["x"] },
  execution: { language: "rust", start_cmd: ["x"] },
}"#;
    let errors = node_err(text);
    let helps: Vec<(&str, &str)> = all(&errors, Code::UnknownKey)
        .iter()
        .map(|d| (key(d), help(d)))
        .collect();
    assert_eq!(helps.len(), 3, "{errors}");
    assert_eq!(helps[0].0, "schema_version");
    assert!(helps[0].1.starts_with("did you mean `peppy_schema`?"));
    assert_eq!(helps[1].0, "process");
    assert!(helps[1].1.starts_with("did you mean `execution`?"));
    assert_eq!(helps[2].0, "execution.start_cmd");
    assert!(helps[2].1.starts_with("did you mean `run_cmd`?"));
}

#[test]
fn dotted_tags_only_in_legacy_documents() {
    let current = r#"{ peppy_schema: "node_v1", manifest: { name: "robot_arm", tag: "0.1.0" }, execution: { language: "rust", run_cmd: ["x"] } }"#;
    let errors = node_err(current);
    assert_eq!(codes(&errors), [Code::InvalidTag]);
    // A legacy document may also depend on a dotted tag.
    let (node, _) = node_ok(ARM_CONTROLLER);
    assert_eq!(node.dependencies[0].target.tag, "0.1.0");
}

#[test]
fn the_seed_pair_resolves_against_each_other() {
    let tree = Tree::new();
    tree.write("repo/robot_arm/peppy.json5", ROBOT_ARM);
    let controller = tree.write("repo/arm_controller/peppy.json5", ARM_CONTROLLER);
    let index = RepoIndex::scan(&[tree.path("repo")]);
    assert!(index.findings().is_empty(), "{}", index.findings());
    let (doc, _) = peppy_schema::NodeDoc::load(&controller).unwrap();
    let (resolved, warnings) =
        resolve_node(std::sync::Arc::new(doc), controller.clone(), &index).unwrap();
    assert!(warnings.is_empty(), "{warnings}");
    let t = &resolved.consumed_topics[0];
    assert_eq!(t.name, "joint_states");
    assert_eq!(
        t.origin,
        Some(peppy_schema::Origin::Node(peppy_schema::Identity::new(
            "robot_arm",
            "0.1.0"
        )))
    );
    assert_eq!(t.qos, QosProfile::SensorData);
    assert_eq!(
        t.format.as_ref().unwrap().canonical(),
        "{positions:[f64;3],velocities:[f64;3],timestamp:time}"
    );
    assert_eq!(
        resolved.files,
        [
            tree.path("repo/arm_controller/peppy.json5"),
            tree.path("repo/robot_arm/peppy.json5")
        ]
    );

    // A launcher can run the pair from local sources.
    let launcher = tree.write(
        "repo/loop.json5",
        r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { local: "robot_arm" }, instances: [{ instance_id: "arm" }] },
    { source: { local: "arm_controller" }, instances: [{ instance_id: "controller", bindings: { robot_arm: "arm" } }] },
  ],
}"#,
    );
    let stack = peppy_schema::check_launcher(&launcher, &options(vec![tree.path("repo")]))
        .unwrap_or_else(|e| panic!("{e}"));
    let controller = stack.plan.instance("controller").unwrap();
    assert_eq!(
        controller.slots[0].binding,
        peppy_schema::SlotBinding::Pinned {
            producer: "arm".into()
        }
    );
    // The legacy spellings are still reported when the stack is checked.
    assert!(
        stack
            .warnings
            .iter()
            .all(|d| d.code == Code::LegacySpelling)
    );
    assert_eq!(stack.warnings.len(), 12, "{}", stack.warnings);
}
