//! `launcher/v1` `links` planned through the binding engine against
//! `node/v1` cardinalities (current_peppyos.md §3, "Errors a launch
//! gets", producer slots), each error located in the launcher file.

use std::collections::BTreeSet;
use std::path::PathBuf;

use peppy_schema::{
    Code, Diagnostics, Identity, InstancePlan, RouteFilter, SlotBinding, SlotKind, SlotPlan,
    StackCheck,
};

use crate::support::*;

const CAM_CONTRACT: &str = r#"{
  peppy_schema: "contract/v1",
  manifest: { name: "cam", tag: "v1" },
  interfaces: { topics: [{ name: "frame", message_format: { width: "u32" } }] },
}
"#;

/// A `node/v1` document.
fn slashed_node(name: &str, manifest: &str, interfaces: &str) -> String {
    format!(
        r#"{{
  peppy_schema: "node/v1",
  manifest: {{ name: "{name}", tag: "v1", {manifest} }},
  execution: {{ language: "python", run_cmd: ["python3", "main.py"] }},
  interfaces: {{ {interfaces} }},
}}
"#
    )
}

const IMPLEMENTS_CAM: &str = r#"implements: [{ name: "cam", tag: "v1", link_id: "cam" }],"#;
const CAM_MEMBERS: &str = r#"topics: { emits: [{ link_id: "cam", name: "frame" }] }"#;

/// The consumer: a node slot and a contract slot of each cardinality.
const HUB_SLOTS: &str = r#"depends_on: {
    nodes: [{ name: "cam_a", tag: "v1", link_id: "leader" }],
    contracts: [
      { name: "cam", tag: "v1", link_id: "main" },
      { name: "cam", tag: "v1", link_id: "backup", cardinality: "zero_or_one" },
      { name: "cam", tag: "v1", link_id: "many", cardinality: "one_or_more" },
      { name: "cam", tag: "v1", link_id: "extras", cardinality: "zero_or_more" },
    ],
  },"#;

/// Two implementers of `cam:v1`, a node that implements nothing, and the
/// consumer `hub`.
fn stack() -> Tree {
    let tree = Tree::new();
    tree.write(
        peppy_schema::REPOSITORIES_FILE,
        r#"[{ type: "fs", path: "repo" }]"#,
    );
    tree.write("repo/contracts/cam.json5", CAM_CONTRACT);
    for name in ["cam_a", "cam_b"] {
        tree.write(
            &format!("repo/{name}/peppy.json5"),
            &slashed_node(name, IMPLEMENTS_CAM, CAM_MEMBERS),
        );
    }
    tree.write(
        "repo/lidar/peppy.json5",
        &slashed_node(
            "lidar",
            "",
            r#"topics: { emits: [{ name: "frame", message_format: { width: "u32" } }] }"#,
        ),
    );
    tree.write("repo/hub/peppy.json5", &slashed_node("hub", HUB_SLOTS, ""));
    tree
}

/// `launch.json5` deploying `a1`, `a2` (cam_a), `b1` (cam_b), `l1` (lidar)
/// and `h` (hub) with `links: { <links> }`.
fn launcher(tree: &Tree, links: &str) -> (PathBuf, String) {
    let text = format!(
        r#"{{
  peppy_schema: "launcher/v1",
  deployments: [
    {{ source: {{ name: "cam_a:v1" }}, instances: [{{ instance_id: "a1" }}, {{ instance_id: "a2" }}] }},
    {{ source: {{ name: "cam_b:v1" }}, instances: [{{ instance_id: "b1" }}] }},
    {{ source: {{ name: "lidar:v1" }}, instances: [{{ instance_id: "l1" }}] }},
    {{ source: {{ name: "hub:v1" }}, instances: [
      {{ instance_id: "h", links: {{ {links} }} }},
    ] }},
  ],
}}
"#
    );
    (tree.write("launch.json5", &text), text)
}

/// Links filling every slot that must be linked, with `main` left to the
/// caller.
const REST: &str = r#"backup: "b1", many: ["a1"], leader: "a2""#;

fn plan_ok(links: &str) -> StackCheck {
    let tree = stack();
    let (path, _) = launcher(&tree, links);
    stack_ok(&path)
}

/// The errors of a launcher with these links, and its text.
fn plan_err(links: &str) -> (Diagnostics, String) {
    let tree = stack();
    let (path, text) = launcher(&tree, links);
    (stack_err(&path), text)
}

/// The launcher's only error, which must have `code`.
#[track_caller]
fn only(d: &Diagnostics, code: Code) -> &peppy_schema::Diagnostic {
    assert_eq!(error_codes(d), [code], "{d}");
    one(d, code)
}

fn slot<'a>(plan: &'a InstancePlan, link_id: &str) -> &'a SlotPlan {
    plan.slots
        .iter()
        .find(|s| s.link_id == link_id)
        .unwrap_or_else(|| panic!("no slot `{link_id}`"))
}

fn only_from(items: &[&str]) -> RouteFilter {
    RouteFilter::OnlyFrom(items.iter().map(|s| s.to_string()).collect::<BTreeSet<_>>())
}

fn set(items: &[&str], vacant: Option<&str>) -> SlotBinding {
    SlotBinding::Set {
        producers: items.iter().map(|s| s.to_string()).collect(),
        vacant: vacant.map(str::to_string),
    }
}

const LINKS: &str = "deployments[3].instances[0].links";

#[test]
fn every_cardinality_plans_its_set_in_link_order() {
    let s = plan_ok(r#"main: "a1", backup: "b1", many: ["b1", "a2", "a1"], leader: "a2""#);
    assert!(s.warnings.is_empty(), "{}", s.warnings);
    let h = s.plan.instance("h").expect("h");
    let got: Vec<(&str, SlotKind, &SlotBinding, &RouteFilter)> = h
        .slots
        .iter()
        .map(|s| (s.link_id.as_str(), s.kind, &s.binding, &s.filter))
        .collect();
    assert_eq!(
        got,
        [
            (
                "leader",
                SlotKind::Node,
                &SlotBinding::Pinned {
                    producer: "a2".into()
                },
                &RouteFilter::Pin("a2".into())
            ),
            (
                "main",
                SlotKind::Interface,
                &SlotBinding::Pinned {
                    producer: "a1".into()
                },
                &RouteFilter::Pin("a1".into())
            ),
            (
                "backup",
                SlotKind::Interface,
                &set(&["b1"], None),
                &only_from(&["b1"])
            ),
            (
                "many",
                SlotKind::Interface,
                &set(&["b1", "a2", "a1"], None),
                &only_from(&["a1", "a2", "b1"])
            ),
            // Left out: the empty set, nothing flows in.
            (
                "extras",
                SlotKind::Interface,
                &set(&[], None),
                &only_from(&[])
            ),
        ]
    );
    assert_eq!(slot(h, "main").target, Identity::new("cam", "v1"));
    assert_eq!(slot(h, "leader").target, Identity::new("cam_a", "v1"));
}

#[test]
fn an_empty_list_on_zero_or_more_and_a_vacancy_on_zero_or_one() {
    let s = plan_ok(
        r#"main: "a1", backup: { vacant: "no second camera on this robot" }, many: ["a1"], extras: [], leader: "a2""#,
    );
    let h = s.plan.instance("h").expect("h");
    assert_eq!(
        slot(h, "backup").binding,
        set(&[], Some("no second camera on this robot"))
    );
    assert_eq!(slot(h, "backup").filter, only_from(&[]));
    assert_eq!(slot(h, "extras").binding, set(&[], None));
}

#[test]
fn a_link_key_names_a_slot() {
    let (errors, text) = plan_err(&format!(r#"main: "a1", extra: ["b1"], {REST}"#));
    let d = only(&errors, Code::LinkUnknownSlot);
    assert_at(
        d,
        Code::LinkUnknownSlot,
        &format!("{LINKS}.extra"),
        &text,
        "extra:",
    );
    assert_eq!(
        d.message,
        "link `extra` on instance `h` names no slot of `hub:v1`"
    );
    assert_eq!(
        help(d),
        "did you mean `extras`? declared slots: `backup`, `extras`, `leader`, `main`, `many`"
    );
}

#[test]
fn slots_left_out_that_must_be_linked() {
    // `one`.
    let (errors, text) = plan_err(REST);
    let d = only(&errors, Code::BindingSlotUnfulfilled);
    assert_at(
        d,
        Code::BindingSlotUnfulfilled,
        "deployments[3].instances[0].instance_id",
        &text,
        r#""h""#,
    );
    assert_eq!(
        d.message,
        "instance `h`: slot `main` (interface `cam:v1`, cardinality one) is not linked"
    );
    assert_eq!(
        help(d),
        r#"add `links: { main: "a1" }`; instances that fit: `a1`, `a2`, `b1`"#
    );

    // `zero_or_one`: leaving it out is not vacating it.
    let (errors, text) = plan_err(r#"main: "a1", many: ["a1"], leader: "a2""#);
    let d = only(&errors, Code::BindingSlotUnfulfilled);
    assert_at(
        d,
        Code::BindingSlotUnfulfilled,
        "deployments[3].instances[0].instance_id",
        &text,
        r#""h""#,
    );
    assert!(d.message.contains("slot `backup`"), "{}", d.message);
    assert!(
        help(d).contains(r#"{ backup: { vacant: "<why>" } }"#),
        "{}",
        help(d)
    );

    // `one_or_more`.
    let (errors, _) = plan_err(r#"main: "a1", backup: "b1", leader: "a2""#);
    let d = only(&errors, Code::BindingSlotUnfulfilled);
    assert!(d.message.contains("slot `many`"), "{}", d.message);
    assert!(
        help(d).starts_with(r#"link at least one producer: `links: { many: ["a1"] }`"#),
        "{}",
        help(d)
    );
}

#[test]
fn a_list_on_a_scalar_slot_and_a_scalar_on_a_list_slot() {
    let (errors, text) = plan_err(r#"main: ["a1"], backup: "b1", many: "a2", leader: "a2""#);
    assert_eq!(
        error_codes(&errors),
        [
            Code::BindingArrayOnScalarSlot,
            Code::BindingScalarOnMultiSlot
        ],
        "{errors}"
    );
    let d = one(&errors, Code::BindingArrayOnScalarSlot);
    assert_at(
        d,
        Code::BindingArrayOnScalarSlot,
        &format!("{LINKS}.main[0]"),
        &text,
        r#""a1"]"#,
    );
    assert_eq!(
        d.message,
        "instance `h`: slot `main` (cardinality one) takes one producer, and is linked to a list"
    );
    assert_eq!(
        help(d),
        r#"a `one` slot takes one producer: write `main: "<instance_id>"`"#
    );
    let d = one(&errors, Code::BindingScalarOnMultiSlot);
    assert_at(
        d,
        Code::BindingScalarOnMultiSlot,
        &format!("{LINKS}.many"),
        &text,
        r#""a2", leader"#,
    );
    assert_eq!(
        d.message,
        "instance `h`: slot `many` (cardinality one_or_more) takes a list, and is linked to a single instance"
    );
}

#[test]
fn an_empty_list_on_one_or_more_is_unmet() {
    let (errors, text) = plan_err(r#"main: "a1", backup: "b1", many: [], leader: "a2""#);
    let d = only(&errors, Code::BindingCardinalityUnmet);
    assert_at(
        d,
        Code::BindingCardinalityUnmet,
        &format!("{LINKS}.many"),
        &text,
        "[]",
    );
    assert_eq!(
        d.message,
        "instance `h`: slot `many` (interface `cam:v1`, cardinality one_or_more) is linked to an empty list"
    );
}

#[test]
fn a_vacancy_only_on_zero_or_one() {
    let vacant = r#"{ vacant: "broken" }"#;
    for (links, slot, cardinality) in [
        (format!(r#"main: {vacant}, {REST}"#), "main", "one"),
        (
            format!(r#"main: "a1", backup: "b1", many: {vacant}, leader: "a2""#),
            "many",
            "one_or_more",
        ),
        (
            format!(r#"main: "a1", extras: {vacant}, {REST}"#),
            "extras",
            "zero_or_more",
        ),
    ] {
        let (errors, text) = plan_err(&links);
        let d = only(&errors, Code::LinkVacantInvalid);
        assert_at(
            d,
            Code::LinkVacantInvalid,
            &format!("{LINKS}.{slot}"),
            &text,
            vacant,
        );
        assert_eq!(
            d.message,
            format!("instance `h`: slot `{slot}` (cardinality {cardinality}) cannot be vacant")
        );
        if cardinality == "zero_or_more" {
            assert_eq!(
                help(d),
                "a `zero_or_more` slot can simply stay empty: `[]` or leave the slot out"
            );
        } else {
            assert!(
                help(d).starts_with(&format!(
                    "a `{cardinality}` slot is required; only a `zero_or_one` slot may be vacant"
                )),
                "{}",
                help(d)
            );
        }
    }
}

#[test]
fn a_contract_slot_takes_an_implementer() {
    let (errors, text) = plan_err(&format!(r#"main: "l1", {REST}"#));
    let d = only(&errors, Code::BindingContractNotImplemented);
    // The value, not the key (`"l1"` first occurs in its deployment).
    assert_eq!(key(d), format!("{LINKS}.main"));
    assert_eq!(lc(d), pos_nth(&text, r#""l1""#, 1), "{d}");
    assert_eq!(
        d.message,
        "link `main` on instance `h`: `l1` deploys `lidar:v1`, which does not implement contract `cam:v1` required by slot `main`"
    );
    assert!(help(d).contains("implements: ["), "{}", help(d));
}

#[test]
fn a_node_slot_takes_that_node() {
    let (errors, text) = plan_err(r#"main: "a1", backup: "b1", many: ["a1"], leader: "b1""#);
    let d = only(&errors, Code::BindingTargetMismatch);
    assert_eq!(key(d), format!("{LINKS}.leader"));
    assert_eq!(lc(d), pos_nth(&text, r#""b1""#, 2), "{d}");
    assert_eq!(
        d.message,
        "link `leader` on instance `h`: `b1` deploys node `cam_b:v1`, but slot `leader` expects node `cam_a:v1`"
    );
    assert_eq!(help(d), "link an instance of `cam_a:v1`");
}

#[test]
fn a_producer_slot_takes_a_bare_instance_id() {
    let (errors, text) = plan_err(&format!(r#"main: "a1/cam", {REST}"#));
    let d = only(&errors, Code::UnknownInstanceId);
    assert_at(
        d,
        Code::UnknownInstanceId,
        &format!("{LINKS}.main"),
        &text,
        r#""a1/cam""#,
    );
    assert!(
        d.message
            .contains("a producer slot takes a bare instance id"),
        "{}",
        d.message
    );
    assert_eq!(help(d), r#"write `"a1"`"#);
}

#[test]
fn both_spellings_plan_the_same_pinned_slots() {
    let tree = Tree::new();
    tree.write(
        peppy_schema::REPOSITORIES_FILE,
        r#"[{ type: "fs", path: "repo" }]"#,
    );
    tree.write("repo/contracts/cam.json5", CAM_CONTRACT);
    for name in ["cam_a", "cam_b"] {
        tree.write(
            &format!("repo/{name}/peppy.json5"),
            &slashed_node(name, IMPLEMENTS_CAM, CAM_MEMBERS),
        );
    }
    tree.write(
        "repo/fusion_underscored/peppy.json5",
        &node_text(
            "fusion",
            r#"nodes: [{ name: "cam_a", tag: "v1", link_id: "leader" }],
      interfaces: [
        { name: "cam", tag: "v1", link_id: "left" },
        { name: "cam", tag: "v1", link_id: "right" },
      ]"#,
            r#"topics: { consumes: [{ link_id: "left", name: "frame" }, { link_id: "right", name: "frame" }] }"#,
            "",
        ),
    );
    tree.write(
        "repo/fusion_slashed/peppy.json5",
        &slashed_node(
            "fusion_slashed",
            r#"depends_on: {
    nodes: [{ name: "cam_a", tag: "v1", link_id: "leader" }],
    contracts: [{ name: "cam", tag: "v1", link_id: "left" }, { name: "cam", tag: "v1", link_id: "right", cardinality: "one" }],
  },"#,
            r#"topics: { consumes: [{ link_id: "left", name: "frame" }, { link_id: "right", name: "frame" }] }"#,
        ),
    );
    let write = |file: &str, schema: &str, node: &str, key: &str| {
        tree.write(
            file,
            &format!(
                r#"{{
  peppy_schema: "{schema}",
  deployments: [
    {{ source: {{ name: "cam_a:v1" }}, instances: [{{ instance_id: "a1" }}, {{ instance_id: "a2" }}] }},
    {{ source: {{ name: "cam_b:v1" }}, instances: [{{ instance_id: "b1" }}] }},
    {{ source: {{ name: "{node}:v1" }}, instances: [
      {{ instance_id: "f", {key}: {{ leader: "a2", left: "a1", right: "b1" }} }},
    ] }},
  ],
}}
"#
            ),
        )
    };
    let underscored = stack_ok(&write(
        "underscored.json5",
        "launcher_v1",
        "fusion",
        "bindings",
    ));
    let slashed = stack_ok(&write(
        "slashed.json5",
        "launcher/v1",
        "fusion_slashed",
        "links",
    ));
    let slots =
        |s: &StackCheck| -> Vec<SlotPlan> { s.plan.instance("f").expect("f").slots.clone() };
    let (underscored, slashed) = (slots(&underscored), slots(&slashed));
    assert_eq!(underscored, slashed);
    let got: Vec<(&str, &SlotBinding, &RouteFilter)> = slashed
        .iter()
        .map(|s| (s.link_id.as_str(), &s.binding, &s.filter))
        .collect();
    let pin = |p: &str| SlotBinding::Pinned { producer: p.into() };
    assert_eq!(
        got,
        [
            ("leader", &pin("a2"), &RouteFilter::Pin("a2".into())),
            ("left", &pin("a1"), &RouteFilter::Pin("a1".into())),
            ("right", &pin("b1"), &RouteFilter::Pin("b1".into())),
        ]
    );
}

/// `launcher/v1` links on a `node_v1` node's `from_any` slot: the slot
/// takes a list (exactly those), `[]` (exactly none, never "any"), and no
/// vacancy; left out, it keeps its `node_v1` meaning (any producer).
#[test]
fn slashed_links_on_an_underscored_from_any_slot() {
    let tree = stack();
    tree.write(
        "repo/mosaic/peppy.json5",
        r#"{ peppy_schema: "node_v1",
  manifest: { name: "mosaic", tag: "v1", depends_on: { interfaces: [
    { name: "cam", tag: "v1", link_id: "extras", from_any: true } ] } },
  interfaces: { topics: { consumes: [{ link_id: "extras", name: "frame" }] } },
  execution: { language: "python", run_cmd: ["python3", "main.py"] } }"#,
    );
    let plan = |links: &str| {
        let text = format!(
            r#"{{ peppy_schema: "launcher/v1", deployments: [
  {{ source: {{ name: "cam_a:v1" }}, instances: [{{ instance_id: "a1" }}, {{ instance_id: "a2" }}] }},
  {{ source: {{ name: "mosaic:v1" }}, instances: [{{ instance_id: "m", {links} }}] }},
] }}"#
        );
        (tree.write("mosaic.json5", &text), text)
    };
    let extras = |links: &str| {
        let (path, _) = plan(links);
        let s = stack_ok(&path);
        let m = s.plan.instance("m").expect("m");
        let p = slot(m, "extras");
        (p.binding.clone(), p.filter.clone())
    };
    assert_eq!(
        extras(r#"links: { extras: ["a2", "a1"] }"#),
        (
            SlotBinding::FromAnyBound {
                producers: vec!["a2".into(), "a1".into()]
            },
            only_from(&["a1", "a2"])
        )
    );
    let (binding, filter) = extras(r#"links: { extras: [] }"#);
    assert_eq!(binding, SlotBinding::FromAnyBound { producers: vec![] });
    assert!(!filter.accepts("a1"), "`[]` is no producer, not any");
    assert_eq!(extras("links: {}").0, SlotBinding::FromAnyUnbound);

    let (path, text) = plan(r#"links: { extras: { vacant: "off" } }"#);
    let errors = stack_err(&path);
    let d = only(&errors, Code::LinkVacantInvalid);
    assert_eq!(lc(d), pos(&text, r#"{ vacant"#), "{d}");
    assert_eq!(
        d.message,
        "instance `m`: slot `extras` (cardinality zero_or_more) cannot be vacant"
    );
    assert!(help(d).contains("can simply stay empty"), "{}", help(d));
}

const PING_CONTRACT: &str = r#"{
  peppy_schema: "contract/v1",
  manifest: { name: "ping", tag: "v1" },
  interfaces: { services: [{ name: "ping", response_message_format: { ok: "bool" } }] },
}
"#;

/// Nodes calling each other's services round a loop, through a contract
/// and a node slot, are refused before anything runs, at the slot that
/// closes the loop (PeppyOS's `ServiceActionContractCycle`); topics both
/// ways are no loop.
#[test]
fn calls_round_a_loop_are_refused_and_topics_both_ways_are_not() {
    let tree = Tree::new();
    tree.write(
        peppy_schema::REPOSITORIES_FILE,
        r#"[{ type: "fs", path: "repo" }]"#,
    );
    tree.write("repo/contracts/ping.json5", PING_CONTRACT);
    tree.write("repo/contracts/cam.json5", CAM_CONTRACT);
    let pinger = |name: &str, calls: &str| {
        slashed_node(
            name,
            &format!(
                r#"implements: [{{ name: "ping", tag: "v1", link_id: "me" }}],
                   depends_on: {calls},"#
            ),
            r#"services: { exposes: [{ link_id: "me", name: "ping" }], consumes: [{ link_id: "other", name: "ping" }] }"#,
        )
    };
    // `left` calls any `ping:v1` (so `right`); `right` calls `left` itself.
    tree.write(
        "repo/left/peppy.json5",
        &pinger(
            "left",
            r#"{ contracts: [{ name: "ping", tag: "v1", link_id: "other" }] }"#,
        ),
    );
    let right_text = pinger(
        "right",
        r#"{ nodes: [{ name: "left", tag: "v1", link_id: "other" }] }"#,
    );
    tree.write("repo/right/peppy.json5", &right_text);
    let path = tree.write(
        "launch.json5",
        r#"{ peppy_schema: "launcher/v1", deployments: [
          { source: { name: "left:v1" }, instances: [{ instance_id: "l", links: { other: "r" } }] },
          { source: { name: "right:v1" }, instances: [{ instance_id: "r", links: { other: "l" } }] },
        ] }"#,
    );
    let errors = stack_err(&path);
    let d = one(&errors, Code::ServiceActionContractCycle);
    assert!(
        d.message
            .contains("`left:v1`, `right:v1` call each other round a loop"),
        "{}",
        d.message
    );
    assert!(help(d).contains("deadlock"), "{}", help(d));

    // Topics both ways: no loop.
    let cam = |name: &str, other: &str| {
        slashed_node(
            name,
            &format!(
                r#"{IMPLEMENTS_CAM} depends_on: {{ nodes: [{{ name: "{other}", tag: "v1", link_id: "peer" }}] }},"#
            ),
            r#"topics: { emits: [{ link_id: "cam", name: "frame" }], consumes: [{ link_id: "peer", name: "frame" }] }"#,
        )
    };
    tree.write("repo/cam_x/peppy.json5", &cam("cam_x", "cam_y"));
    tree.write("repo/cam_y/peppy.json5", &cam("cam_y", "cam_x"));
    let path = tree.write(
        "topics.json5",
        r#"{ peppy_schema: "launcher/v1", deployments: [
          { source: { name: "cam_x:v1" }, instances: [{ instance_id: "x", links: { peer: "y" } }] },
          { source: { name: "cam_y:v1" }, instances: [{ instance_id: "y", links: { peer: "x" } }] },
        ] }"#,
    );
    let errors = peppy_schema::check_launcher(&path, &options(Vec::new()));
    if let Err(e) = errors {
        assert!(all(&e, Code::ServiceActionContractCycle).is_empty(), "{e}");
    }
}
