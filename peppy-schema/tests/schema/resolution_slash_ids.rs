//! Resolving `node/v1` documents against a repository of
//! `contract/v1` and node documents (current_peppyos.md §1.1
//! "Document-resolution errors", §2): contract coverage, refinements,
//! natives-only node slots and both spellings meeting on one contract
//! (pairing slots: `pair_plans`).

use peppy_schema::{Code, Diagnostics, Identity, NodeCheck, Origin, SlotKind, check_node};

use crate::support::*;

/// A contract with an open array, a fixed one, a scalar, a string, an
/// array of objects, a service without request and an action.
const ARM_CONTRACT: &str = r#"{
  peppy_schema: "contract/v1",
  manifest: { name: "arm_control", tag: "v1" },
  interfaces: {
    topics: [
      {
        name: "joint_states",
        message_format: {
          positions: { $type: "array", $items: "f64" },
          home: { $type: "array", $items: "f64", $length: 6 },
          stamp: "u64",
          frame: "string",
          links: { $type: "array", $items: { length: "f32" } },
        },
      },
    ],
    services: [{ name: "get_limits", response_message_format: { max_velocity: "f64" } }],
    actions: [{ name: "move_to", goal_service: { request_message_format: { target: { $type: "array", $items: "f64" } } } }],
  },
}
"#;

const GRIPPER_CONTRACT: &str = r#"{
  peppy_schema: "contract/v1",
  manifest: { name: "gripper", tag: "v1" },
  interfaces: {
    topics: [{ name: "grip_state", message_format: { closed: "bool" } }],
  },
}
"#;

/// A `node/v1` document.
fn slashed_node(name: &str, manifest: &str, interfaces: &str) -> String {
    format!(
        r#"{{
  peppy_schema: "node/v1",
  manifest: {{
    name: "{name}",
    tag: "v1",
    {manifest}
  }},
  execution: {{ language: "python", run_cmd: ["python3", "main.py"] }},
  interfaces: {{
    {interfaces}
  }},
}}
"#
    )
}

/// The members of `arm_control` listed through slot `arm`.
const ARM_MEMBERS: &str = r#"topics: { emits: [{ link_id: "arm", name: "joint_states" }, { name: "temperature", message_format: { celsius: "f32" } }] },
    services: { exposes: [{ link_id: "arm", name: "get_limits" }] },
    actions: { exposes: [{ link_id: "arm", name: "move_to" }] },"#;

const IMPLEMENTS_ARM: &str = r#"implements: [{ name: "arm_control", tag: "v1", link_id: "arm" }],"#;

/// A repository with both contracts and a `node/v1` implementer of
/// `arm_control`.
fn repo() -> Tree {
    let tree = Tree::new();
    tree.write("repo/contracts/arm.json5", ARM_CONTRACT);
    tree.write("repo/contracts/gripper.json5", GRIPPER_CONTRACT);
    tree.write(
        "repo/nodes/arm_driver/peppy.json5",
        &slashed_node("arm_driver", IMPLEMENTS_ARM, ARM_MEMBERS),
    );
    tree
}

fn check(tree: &Tree, rel: &str) -> NodeCheck {
    match check_node(&tree.path(rel), &options(vec![tree.path("repo")])) {
        Ok(c) => c,
        Err(e) => panic!("expected `{rel}` to resolve, got:\n{e}"),
    }
}

fn check_err(tree: &Tree, rel: &str) -> Diagnostics {
    match check_node(&tree.path(rel), &options(vec![tree.path("repo")])) {
        Ok(_) => panic!("expected `{rel}` to fail"),
        Err(e) => e,
    }
}

fn arm() -> Identity {
    Identity::new("arm_control", "v1")
}

/// Writes `repo/nodes/<name>/peppy.json5`; returns its relative path and text.
fn write(tree: &Tree, name: &str, text: String) -> (String, String) {
    let rel = format!("repo/nodes/{name}/peppy.json5");
    tree.write(&rel, &text);
    (rel, text)
}

#[test]
fn an_implementer_provides_the_contract_members() {
    let tree = repo();
    let c = check(&tree, "repo/nodes/arm_driver");
    let emitted: Vec<(&str, &Origin)> = c
        .resolved
        .emitted_topics
        .iter()
        .map(|t| (t.decl.name.as_str(), &t.origin))
        .collect();
    assert_eq!(
        emitted,
        [
            (
                "temperature",
                &Origin::Node(Identity::new("arm_driver", "v1"))
            ),
            ("joint_states", &Origin::Interface(arm())),
        ]
    );
    assert_eq!(
        c.resolved.exposed_services[0].origin,
        Origin::Interface(arm())
    );
    assert_eq!(
        c.resolved.exposed_actions[0].origin,
        Origin::Interface(arm())
    );
    assert_eq!(c.resolved.conformed.len(), 1);
}

#[test]
fn coverage_lists_every_problem_of_a_slot_in_one_error() {
    let tree = repo();
    let (rel, text) = write(
        &tree,
        "partial",
        slashed_node(
            "partial",
            r#"implements: [
      { name: "arm_control", tag: "v1", link_id: "arm" },
      { name: "gripper", tag: "v1", link_id: "grip" },
    ],"#,
            // `get_limits` left out, `bogus` unknown, `move_to` listed as a
            // topic; the gripper slot lists nothing.
            r#"topics: { emits: [
      { link_id: "arm", name: "joint_states" },
      { link_id: "arm", name: "bogus" },
      { link_id: "arm", name: "move_to" },
    ] },"#,
        ),
    );
    let errors = check_err(&tree, &rel);
    assert_eq!(
        error_codes(&errors),
        [
            Code::ContractCoverageMismatch,
            Code::ContractCoverageMismatch
        ],
        "{errors}"
    );
    let found = all(&errors, Code::ContractCoverageMismatch);
    assert_at(
        found[0],
        Code::ContractCoverageMismatch,
        "manifest.implements[0]",
        &text,
        r#"{ name: "arm_control""#,
    );
    assert_eq!(
        found[0].message,
        "implements slot `arm` does not list the members of contract `arm_control:v1`: \
         missing services: `get_limits`; missing actions: `move_to`; unknown topic: `bogus`; \
         wrong kind: `move_to` is an action of the contract, listed as a topic"
    );
    assert!(
        help(found[0]).contains(r#"{ link_id: "arm", name: "<member>" }"#),
        "{}",
        help(found[0])
    );
    assert_at(
        found[1],
        Code::ContractCoverageMismatch,
        "manifest.implements[1]",
        &text,
        r#"{ name: "gripper""#,
    );
    assert_eq!(
        found[1].message,
        "implements slot `grip` does not list the members of contract `gripper:v1`: missing topics: `grip_state`"
    );
}

#[test]
fn refinements_are_checked_against_the_contract() {
    let tree = repo();
    let (rel, text) = write(
        &tree,
        "refiner",
        slashed_node(
            "refiner",
            IMPLEMENTS_ARM,
            r#"topics: { emits: [{ link_id: "arm", name: "joint_states", refine: { message_format: {
      nope: { $length: 1 },
      stamp: { $length: 2 },
      home: { $length: 3 },
      positions: { $items: { x: { $length: 4 } } },
    } } }] },
    services: { exposes: [{ link_id: "arm", name: "get_limits", refine: { request_message_format: { max_velocity: { $length: 5 } } } }] },
    actions: { exposes: [{ link_id: "arm", name: "move_to" }] },"#,
        ),
    );
    let errors = check_err(&tree, &rel);
    let found = all(&errors, Code::RefinementMismatch);
    assert_eq!(error_codes(&errors).len(), found.len(), "{errors}");
    let got: Vec<(&str, (usize, usize), &str)> = found
        .iter()
        .map(|d| (key(d), lc(d), d.message.as_str()))
        .collect();
    let base = "interfaces.topics.emits[0].refine.message_format";
    assert_eq!(
        got,
        [
            (
                &*format!("{base}.nope"),
                pos(&text, "nope"),
                "`refine` of `joint_states`: UnknownField: `message_format` has no field `nope` \
                 (fields: `positions`, `home`, `stamp`, `frame`, `links`)"
            ),
            (
                &*format!("{base}.stamp"),
                pos(&text, "stamp:"),
                "`refine` of `joint_states`: NotAnArray: `message_format.stamp` is not an array"
            ),
            (
                &*format!("{base}.home"),
                pos(&text, "home:"),
                "`refine` of `joint_states`: AlreadyFixed: `message_format.home` already has `$length: 6`"
            ),
            (
                &*format!("{base}.positions"),
                pos(&text, "positions:"),
                "`refine` of `joint_states`: ItemsNotObjects: `message_format.positions` is not an array of objects; `$items` steps into objects"
            ),
            (
                "interfaces.services.exposes[0].refine",
                pos(&text, "{ request_message_format"),
                "`refine` of `get_limits`: FormatAbsent: the member has no `request_message_format` to refine"
            ),
        ]
    );
    assert!(help(found[0]).contains("open"), "{}", help(found[0]));
}

#[test]
fn refinements_that_land_resolve() {
    let tree = repo();
    write(
        &tree,
        "pinned",
        slashed_node(
            "pinned",
            IMPLEMENTS_ARM,
            r#"topics: { emits: [{ link_id: "arm", name: "joint_states", refine: { message_format: {
      positions: { $length: 6 },
      links: { $items: { length: { $length: 1 } } },
    } } }] },
    services: { exposes: [{ link_id: "arm", name: "get_limits" }] },
    actions: { exposes: [{ link_id: "arm", name: "move_to", refine: { goal_service: { request_message_format: { target: { $length: 7 } } } } }] },"#,
        ),
    );
    // `links[].length` is a scalar, not an array: that one does not land;
    // the others do.
    let errors = check_err(&tree, "repo/nodes/pinned");
    let d = only_refinement(&errors);
    assert!(
        d.message
            .contains("NotAnArray: `message_format.links[].length`"),
        "{}",
        d.message
    );

    write(
        &tree,
        "clean",
        slashed_node(
            "clean",
            IMPLEMENTS_ARM,
            r#"topics: { emits: [{ link_id: "arm", name: "joint_states", refine: { message_format: { positions: { $length: 6 } } } }] },
    services: { exposes: [{ link_id: "arm", name: "get_limits" }] },
    actions: { exposes: [{ link_id: "arm", name: "move_to", refine: { goal_service: { request_message_format: { target: { $length: 7 } } } } }] },"#,
        ),
    );
    let c = check(&tree, "repo/nodes/clean");
    assert!(c.warnings.is_empty(), "{}", c.warnings);
    let refine = c.resolved.node.members[0].refine.as_ref().expect("refine");
    assert_eq!(refine.formats.len(), 1);
    assert!(matches!(
        refine.formats[0].1.fields[0].pin,
        peppy_schema::Pin::Length(6)
    ));

    // The consumer's side: a refine through a contract slot is checked
    // against the contract too.
    let (rel, text) = write(
        &tree,
        "viewer",
        slashed_node(
            "viewer",
            r#"depends_on: { contracts: [{ name: "arm_control", tag: "v1", link_id: "arm" }] },"#,
            r#"topics: { consumes: [{ link_id: "arm", name: "joint_states", refine: { message_format: { frame: { $length: 2 } } } }] },
    actions: { consumes: [{ link_id: "arm", name: "move_to", refine: { goal_service: { request_message_format: { target: { $length: 7 } } } } }] },"#,
        ),
    );
    let errors = check_err(&tree, &rel);
    let d = only_refinement(&errors);
    assert_at(
        d,
        Code::RefinementMismatch,
        "interfaces.topics.consumes[0].refine.message_format.frame",
        &text,
        "frame",
    );
}

#[track_caller]
fn only_refinement(errors: &Diagnostics) -> &peppy_schema::Diagnostic {
    assert_eq!(error_codes(errors), [Code::RefinementMismatch], "{errors}");
    one(errors, Code::RefinementMismatch)
}

#[test]
fn a_node_slot_sees_only_the_producers_own_entries() {
    let tree = repo();
    let (rel, text) = write(
        &tree,
        "watcher",
        slashed_node(
            "watcher",
            r#"depends_on: { nodes: [{ name: "arm_driver", tag: "v1", link_id: "driver" }] },"#,
            r#"topics: { consumes: [
      { link_id: "driver", name: "temperature" },
      { link_id: "driver", name: "joint_states" },
    ] },
    services: { consumes: [{ link_id: "driver", name: "get_limits" }] },"#,
        ),
    );
    let errors = check_err(&tree, &rel);
    assert_eq!(
        error_codes(&errors),
        [
            Code::ConsumedInterfaceOnlyContractBacked,
            Code::ConsumedInterfaceOnlyContractBacked
        ],
        "{errors}"
    );
    let found = all(&errors, Code::ConsumedInterfaceOnlyContractBacked);
    assert_at(
        found[0],
        Code::ConsumedInterfaceOnlyContractBacked,
        "interfaces.topics.consumes[1]",
        &text,
        r#"{ link_id: "driver", name: "joint_states" }"#,
    );
    assert_eq!(
        found[0].message,
        "node `arm_driver:v1` provides topic `joint_states` only through its contract slot `arm`, and a node slot sees only a producer's own entries"
    );
    assert!(
        help(found[0]).contains("depends_on.contracts"),
        "{}",
        help(found[0])
    );
    assert_at(
        found[1],
        Code::ConsumedInterfaceOnlyContractBacked,
        "interfaces.services.consumes[0]",
        &text,
        r#"{ link_id: "driver", name: "get_limits" }"#,
    );

    // Through the node slot, its own entry alone resolves.
    write(
        &tree,
        "thermo",
        slashed_node(
            "thermo",
            r#"depends_on: { nodes: [{ name: "arm_driver", tag: "v1", link_id: "driver" }] },"#,
            r#"topics: { consumes: [{ link_id: "driver", name: "temperature" }] },"#,
        ),
    );
    let c = check(&tree, "repo/nodes/thermo");
    let t = &c.resolved.consumed_topics[0];
    assert_eq!(
        t.origin,
        Some(Origin::Node(Identity::new("arm_driver", "v1")))
    );
}

#[test]
fn an_underscored_consumer_meets_a_slashed_implementer_on_the_contract() {
    let tree = repo();
    tree.write(
        "repo/nodes/panel/peppy.json5",
        &node_text(
            "panel",
            r#"interfaces: [{ name: "arm_control", tag: "v1", link_id: "arm" }]"#,
            r#"topics: { consumes: [{ link_id: "arm", name: "joint_states" }] },
    services: { consumes: [{ link_id: "arm", name: "get_limits" }] },
    actions: { consumes: [{ link_id: "arm", name: "move_to" }] }"#,
            "",
        ),
    );
    let producer = check(&tree, "repo/nodes/arm_driver");
    let consumer = check(&tree, "repo/nodes/panel");
    let slot = &consumer.resolved.node.dependencies[0];
    assert_eq!((slot.kind, &slot.target), (SlotKind::Interface, &arm()));
    let consumed = &consumer.resolved.consumed_topics[0];
    let emitted = producer
        .resolved
        .emitted_topics
        .iter()
        .find(|t| t.decl.name == "joint_states")
        .expect("emitted");
    assert_eq!(consumed.origin.as_ref(), Some(&emitted.origin));
    assert_eq!(emitted.origin, Origin::Interface(arm()));
    assert_eq!(consumed.format, emitted.decl.format);
    assert_eq!(
        consumer.resolved.consumed_services[0].origin,
        producer.resolved.exposed_services[0].origin
    );
    assert_eq!(
        consumer.resolved.consumed_actions[0].origin,
        producer.resolved.exposed_actions[0].origin
    );
}

#[test]
fn a_slashed_consumer_meets_an_underscored_conformer_on_the_contract() {
    let tree = repo();
    tree.write(
        "repo/nodes/underscored_arm/peppy.json5",
        &node_text(
            "underscored_arm",
            "",
            r#"conforms_to: [{ name: "arm_control", tag: "v1" }]"#,
            "",
        ),
    );
    write(
        &tree,
        "console",
        slashed_node(
            "console",
            r#"depends_on: { contracts: [{ name: "arm_control", tag: "v1", link_id: "arm", cardinality: "zero_or_more" }] },"#,
            r#"topics: { consumes: [{ link_id: "arm", name: "joint_states" }] },
    services: { consumes: [{ link_id: "arm", name: "get_limits" }] },"#,
        ),
    );
    let producer = check(&tree, "repo/nodes/underscored_arm");
    let consumer = check(&tree, "repo/nodes/console");
    let emitted = producer
        .resolved
        .emitted_topics
        .iter()
        .find(|t| t.decl.name == "joint_states")
        .expect("emitted");
    let consumed = &consumer.resolved.consumed_topics[0];
    assert_eq!(consumed.origin.as_ref(), Some(&emitted.origin));
    assert_eq!(emitted.origin, Origin::Interface(arm()));
    assert_eq!(
        consumer.resolved.consumed_services[0].origin,
        producer.resolved.exposed_services[0].origin
    );
    let slot = consumed.slot.as_ref().expect("slot");
    assert_eq!(
        (slot.link_id.as_str(), slot.kind, &slot.target),
        ("arm", SlotKind::Interface, &arm())
    );
}
