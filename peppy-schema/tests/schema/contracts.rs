//! `contract/v1` documents: the content of an `interface_v1`, read into
//! the same model, so a `node_v1` node conforms to or consumes a
//! `contract/v1` contract exactly as it does an `interface_v1` interface.

use peppy_schema::{
    Code, Document, DocumentKind, Identity, InterfaceDoc, Origin, SlotKind, Spelling, check_node,
    sha256_hex,
};

use crate::support::*;

/// A contract as PeppyOS's hubs write one: labels, all three kinds of
/// members, an action whose feedback topic names itself.
const ARM: &str = r#"{
  peppy_schema: "contract/v1",
  manifest: { name: "arm_control", tag: "v1", labels: ["manipulation"] },
  interfaces: {
    topics: [
      { name: "joint_states", qos_profile: "sensor_data", message_format: { positions: { $type: "array", $items: "f64" } } },
    ],
    services: [
      { name: "get_limits", response_message_format: { max_velocity: "f64" } },
    ],
    actions: [
      {
        name: "move_to",
        goal_service: { request_message_format: { target: { $type: "array", $items: "f64" } } },
        feedback_topic: { name: "move_to_progress", type: "progress", message_format: { remaining: "f64" } },
        result_service: { response_message_format: { reached: "bool" } },
      },
    ],
  },
}
"#;

fn parse(text: &str) -> peppy_schema::Parsed<InterfaceDoc> {
    InterfaceDoc::parse("contract.json5", text)
}

#[test]
fn a_contract_is_read_as_an_interface() {
    let (doc, warnings) = parse(ARM).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(doc.spelling, Spelling::SlashIds);
    assert_eq!(doc.identity, Identity::new("arm_control", "v1"));
    assert_eq!(doc.labels, ["manipulation"]);
    assert_eq!(
        (doc.topics.len(), doc.services.len(), doc.actions.len()),
        (1, 1, 1)
    );
    let action = &doc.actions[0];
    assert!(action.goal.is_some() && action.feedback.is_some() && action.result.is_some());
    // The feedback topic's `name` and `type` are read, and said to be unused.
    let ignored: Vec<&str> = all(&warnings, Code::IgnoredKey)
        .into_iter()
        .map(key)
        .collect();
    assert_eq!(
        ignored,
        [
            "interfaces.actions[0].feedback_topic.name",
            "interfaces.actions[0].feedback_topic.type"
        ]
    );
    // The revision is the sha256 of the file's bytes, as for an interface.
    assert_eq!(doc.sha256, sha256_hex(ARM.as_bytes()));
    // Kind detection reads `peppy_schema`, not the file name.
    let (any, _) =
        peppy_schema::parse_document(&peppy_schema::SourceFile::new("x.json5", ARM), &doc.sha256)
            .unwrap();
    assert!(matches!(any, Document::Interface(_)));
    assert_eq!(any.kind(), DocumentKind::Interface);
}

#[test]
fn an_empty_contract_is_valid_and_an_interface_v1_keeps_its_spelling() {
    let (doc, _) = parse(
        r#"{ peppy_schema: "contract/v1", manifest: { name: "empty", tag: "v1" }, interfaces: {} }"#,
    )
    .unwrap();
    assert!(doc.topics.is_empty() && doc.services.is_empty() && doc.actions.is_empty());
    let (interface, _) = parse(
        r#"{ peppy_schema: "interface_v1", manifest: { name: "empty", tag: "v1" }, interfaces: {} }"#,
    )
    .unwrap();
    assert_eq!(interface.spelling, Spelling::UnderscoreIds);
}

#[test]
fn contract_rules_are_located_errors() {
    let text = r#"{
  peppy_schema: "contract/v1",
  manifest: { name: "arm", tag: "1.0", implements: [] },
  interfaces: {
    topics: [{ name: "state" }, { name: "state" }],
    actions: [{ name: "go", result_service: { request_message_format: { id: "u32" } } }],
  },
}"#;
    let errors = parse(text).expect_err("invalid");
    let got: Vec<(Code, &str)> = errors
        .sorted()
        .iter()
        .filter(|d| d.severity == peppy_schema::Severity::Error)
        .map(|d| (d.code, key(d)))
        .collect();
    assert_eq!(
        got,
        [
            (Code::InvalidTag, "manifest.tag"),
            (Code::UnknownKey, "manifest.implements"),
            (Code::DuplicateEntryName, "interfaces.topics[1].name"),
            (
                Code::UnknownKey,
                "interfaces.actions[0].result_service.request_message_format"
            ),
        ],
        "{errors}"
    );
    assert_at(
        one(&errors, Code::InvalidTag),
        Code::InvalidTag,
        "manifest.tag",
        text,
        r#""1.0""#,
    );
}

/// A `node_v1` node conforms to a `contract/v1` contract and another
/// consumes it through an interface slot: the contract resolves from the
/// repository like an interface, pins included.
#[test]
fn underscored_nodes_conform_to_and_consume_a_contract() {
    let tree = Tree::new();
    tree.write("repo/contracts/arm.json5", ARM);
    tree.write(
        "repo/nodes/arm/peppy.json5",
        &node_text(
            "arm",
            "",
            r#"conforms_to: [{ name: "arm_control", tag: "v1" }]"#,
            "",
        ),
    );
    let pin = sha256_hex(ARM.as_bytes());
    tree.write(
        "repo/nodes/panel/peppy.json5",
        &node_text(
            "panel",
            &format!(
                r#"interfaces: [{{ name: "arm_control", tag: "v1", link_id: "arm", sha256: "{pin}" }}]"#
            ),
            r#"topics: { consumes: [{ link_id: "arm", name: "joint_states" }] },
    services: { consumes: [{ link_id: "arm", name: "get_limits" }] },
    actions: { consumes: [{ link_id: "arm", name: "move_to" }] }"#,
            "",
        ),
    );
    let options = options(vec![tree.path("repo")]);
    let arm = check_node(&tree.path("repo/nodes/arm"), &options).unwrap_or_else(|e| panic!("{e}"));
    let contract = Identity::new("arm_control", "v1");
    assert!(
        arm.resolved
            .emitted_topics
            .iter()
            .any(|t| t.decl.name == "joint_states"
                && t.origin == Origin::Interface(contract.clone())),
        "the conformed contract's topic is the node's"
    );
    let panel =
        check_node(&tree.path("repo/nodes/panel"), &options).unwrap_or_else(|e| panic!("{e}"));
    let slot = &panel.resolved.node.dependencies[0];
    assert_eq!((slot.kind, &slot.target), (SlotKind::Interface, &contract));
    assert_eq!(panel.resolved.consumed_topics.len(), 1);
    assert_eq!(panel.resolved.consumed_services.len(), 1);
    assert_eq!(panel.resolved.consumed_actions.len(), 1);
}

/// PeppyOS's slashed kinds peppy does not read yet are named as such, not
/// guessed at as a typo of the underscored spelling.
#[test]
fn slashed_kinds_not_read_yet_say_so() {
    let text = r#"{ peppy_schema: "mcp_exposure/v1", manifest: { name: "a", tag: "v1" } }"#;
    let errors = peppy_schema::parse_document(&peppy_schema::SourceFile::new("n.json5", text), "")
        .expect_err("not read yet");
    let d = one(&errors, Code::UnknownSchema);
    assert_at(
        d,
        Code::UnknownSchema,
        "peppy_schema",
        text,
        r#""mcp_exposure/v1""#,
    );
    assert_eq!(
        d.message,
        "`mcp_exposure/v1` is a PeppyOS document kind peppy does not read yet"
    );
    assert!(!help(d).contains("did you mean"), "{}", help(d));
}
