//! SPEC 6.1 rules 1-10 and the SPEC 5 routing filters, through
//! `check_launcher` on stacks written to a temporary directory.

use std::collections::BTreeSet;
use std::path::PathBuf;

use peppy_schema::{
    Code, Identity, InstancePlan, RestartPolicy, RouteFilter, SlotBinding, SlotKind, SlotPlan,
    StackCheck, sha256_hex,
};
use serde_json::json;

use crate::support::*;

const CAM_IFACE: &str = r#"{
  peppy_schema: "interface_v1",
  manifest: { name: "cam", tag: "v1" },
  interfaces: {
    topics: [{ name: "frame", qos_profile: "sensor_data", message_format: { width: "u32", data: "bytes" } }],
    services: [{ name: "info", response_message_format: { fps: "u8" } }],
  },
}
"#;

/// A repository of producers and consumers, found through the
/// `peppy_repositories.json5` next to the launchers.
fn stack() -> Tree {
    let tree = Tree::new();
    tree.write(
        peppy_schema::REPOSITORIES_FILE,
        r#"[{ type: "fs", path: "repo" }]"#,
    );
    tree.write("repo/interfaces/cam.json5", CAM_IFACE);
    let conforms = r#"conforms_to: [{ name: "cam", tag: "v1" }]"#;
    tree.write(
        "repo/cam_a/peppy.json5",
        &node_text(
            "cam_a",
            "",
            conforms,
            r#"parameters: {
      fps: { $type: "u16", $default: 30 },
      video: { width: { $type: "u32", $default: 640 }, height: { $type: "u32", $default: 480 } },
    }"#,
        ),
    );
    tree.write(
        "repo/cam_b/peppy.json5",
        &node_text("cam_b", "", conforms, ""),
    );
    tree.write(
        "repo/plain/peppy.json5",
        &node_text("plain", "", r#"topics: { emits: [{ name: "frame", message_format: { width: "u32", data: "bytes" } }] }"#, ""),
    );
    tree.write(
        "repo/fusion/peppy.json5",
        &node_text(
            "fusion",
            r#"interfaces: [
        { name: "cam", tag: "v1", link_id: "left" },
        { name: "cam", tag: "v1", link_id: "right" },
        { name: "cam", tag: "v1", link_id: "extras", from_any: true },
      ]"#,
            r#"topics: { consumes: [
      { link_id: "left", name: "frame" },
      { link_id: "right", name: "frame" },
      { link_id: "extras", name: "frame" },
    ] }"#,
            "",
        ),
    );
    tree.write(
        "repo/mosaic/peppy.json5",
        &node_text(
            "mosaic",
            r#"interfaces: [{ name: "cam", tag: "v1", link_id: "cams", from_any: true }]"#,
            "",
            "",
        ),
    );
    tree.write(
        "repo/follower/peppy.json5",
        &node_text(
            "follower",
            r#"nodes: [{ name: "plain", tag: "v1", link_id: "leader" }]"#,
            r#"topics: { consumes: [{ link_id: "leader", name: "frame" }] }"#,
            "",
        ),
    );
    tree.write(
        "repo/sorter/peppy.json5",
        &node_text(
            "sorter",
            r#"nodes: [{ name: "cam_a", tag: "v1", link_id: "m_node", from_any: true }],
      interfaces: [{ name: "cam", tag: "v1", link_id: "a_iface", from_any: true }]"#,
            "",
            "",
        ),
    );
    tree.write(
        "repo/needy/peppy.json5",
        &node_text(
            "needy",
            "",
            "",
            r#"parameters: {
      rate: { $type: "u16", $default: 10 },
      device: { serial: "string", port: { $type: "u16", $default: 7 } },
    }"#,
        ),
    );
    tree
}

/// `{ source: { name: "<node>:v1" }, instances: [<instances>] }`.
fn dep(node: &str, instances: &str) -> String {
    format!("    {{ source: {{ name: \"{node}:v1\" }}, instances: [\n{instances}\n    ] }},\n")
}

/// Writes `launch.json5` with these deployments; returns its path and text.
fn launcher(tree: &Tree, deployments: &[String]) -> (PathBuf, String) {
    let text = format!(
        "{{\n  peppy_schema: \"launcher_v1\",\n  deployments: [\n{}  ],\n}}\n",
        deployments.concat()
    );
    (tree.write("launch.json5", &text), text)
}

fn slot<'a>(plan: &'a InstancePlan, link_id: &str) -> &'a SlotPlan {
    plan.slots
        .iter()
        .find(|s| s.link_id == link_id)
        .unwrap_or_else(|| panic!("no slot `{link_id}`"))
}

fn set(items: &[&str]) -> BTreeSet<String> {
    items.iter().map(|s| s.to_string()).collect()
}

fn pinned(p: &str) -> SlotBinding {
    SlotBinding::Pinned { producer: p.into() }
}

fn bound(ps: &[&str]) -> SlotBinding {
    SlotBinding::FromAnyBound {
        producers: ps.iter().map(|s| s.to_string()).collect(),
    }
}

fn cams() -> String {
    dep(
        "cam_a",
        r#"      { instance_id: "a1" }, { instance_id: "a2" },"#,
    ) + &dep("cam_b", r#"      { instance_id: "b1" },"#)
}

fn ok(tree: &Tree, deployments: &[String]) -> StackCheck {
    let (path, _) = launcher(tree, deployments);
    stack_ok(&path)
}

#[test]
fn pinned_slots_and_a_free_form_key() {
    let tree = stack();
    let s = ok(
        &tree,
        &[
            cams(),
            dep(
                "fusion",
                r#"      { instance_id: "f1", bindings: { left: "a1", right: "a2", extra_1: "b1" } },"#,
            ),
        ],
    );
    assert!(s.warnings.is_empty(), "{}", s.warnings);
    let ids: Vec<&str> = s
        .plan
        .instances
        .iter()
        .map(|i| i.instance_id.as_str())
        .collect();
    assert_eq!(ids, ["a1", "a2", "b1", "f1"]);
    let f1 = s.plan.instance("f1").unwrap();
    assert_eq!(f1.node, Identity::new("fusion", "v1"));
    assert_eq!(f1.deployment, 2);
    let got: Vec<(&str, SlotKind, &SlotBinding, &RouteFilter)> = f1
        .slots
        .iter()
        .map(|s| (s.link_id.as_str(), s.kind, &s.binding, &s.filter))
        .collect();
    assert_eq!(
        got,
        [
            (
                "left",
                SlotKind::Interface,
                &pinned("a1"),
                &RouteFilter::Pin("a1".into())
            ),
            (
                "right",
                SlotKind::Interface,
                &pinned("a2"),
                &RouteFilter::Pin("a2".into())
            ),
            (
                "extras",
                SlotKind::Interface,
                &bound(&["b1"]),
                &RouteFilter::OnlyFrom(set(&["b1"]))
            ),
        ]
    );
    assert!(
        f1.slots
            .iter()
            .all(|s| s.target == Identity::new("cam", "v1"))
    );
    // Producers have no slots; their parameters get the defaults.
    let a1 = s.plan.instance("a1").unwrap();
    assert!(a1.slots.is_empty());
    assert_eq!(
        a1.parameters,
        json!({ "fps": 30, "video": { "width": 640, "height": 480 } })
    );
    assert_eq!(a1.restart, RestartPolicy::No);
    assert_eq!(s.plan.instance("b1").unwrap().parameters, json!({}));
    // Every deployment was resolved, in launcher order.
    let nodes: Vec<String> = s
        .deployments
        .iter()
        .map(|d| d.resolved.node.identity().to_string())
        .collect();
    assert_eq!(nodes, ["cam_a:v1", "cam_b:v1", "fusion:v1"]);
    assert_eq!(s.deployments[2].dir, tree.path("repo/fusion"));
    assert_eq!(s.repositories, [tree.path("repo")]);
}

#[test]
fn unbound_from_any_takes_any_producer_not_claimed_by_a_sibling() {
    let tree = stack();
    let s = ok(
        &tree,
        &[
            cams(),
            dep(
                "fusion",
                r#"      { instance_id: "f1", bindings: { left: "a1", right: "a2" } },"#,
            ),
            dep("mosaic", r#"      { instance_id: "m1" },"#),
        ],
    );
    let extras = slot(s.plan.instance("f1").unwrap(), "extras");
    assert_eq!(extras.binding, SlotBinding::FromAnyUnbound);
    assert_eq!(extras.filter, RouteFilter::AnyExcept(set(&["a1", "a2"])));
    assert!(extras.filter.accepts("b1") && !extras.filter.accepts("a1"));
    let cams = slot(s.plan.instance("m1").unwrap(), "cams");
    assert_eq!(cams.binding, SlotBinding::FromAnyUnbound);
    assert_eq!(cams.filter, RouteFilter::Any);
    assert_eq!((extras.named_server(), cams.named_server()), (None, None));
}

#[test]
fn bound_from_any_excludes_producers_pinned_by_a_sibling() {
    let tree = stack();
    let s = ok(
        &tree,
        &[
            cams(),
            dep(
                "fusion",
                r#"      { instance_id: "f1", bindings: { left: "a1", right: "a2", x: "a1", y: "b1" } },"#,
            ),
        ],
    );
    let f1 = s.plan.instance("f1").unwrap();
    let extras = slot(f1, "extras");
    assert_eq!(extras.binding, bound(&["a1", "b1"]));
    assert_eq!(extras.filter, RouteFilter::OnlyFrom(set(&["b1"])));
    // Requests go to the one server the filter lets through, or to the
    // pinned one, without probing.
    assert_eq!(extras.named_server(), Some("b1"));
    assert_eq!(slot(f1, "left").named_server(), Some("a1"));
}

#[test]
fn one_producer_may_fill_two_pinned_slots() {
    let tree = stack();
    let s = ok(
        &tree,
        &[
            cams(),
            dep(
                "fusion",
                r#"      { instance_id: "f1", bindings: { left: "a1", right: "a1" } },"#,
            ),
        ],
    );
    let f1 = s.plan.instance("f1").unwrap();
    assert_eq!(slot(f1, "left").filter, RouteFilter::Pin("a1".into()));
    assert_eq!(slot(f1, "right").filter, RouteFilter::Pin("a1".into()));
    assert_eq!(
        slot(f1, "extras").filter,
        RouteFilter::AnyExcept(set(&["a1"]))
    );
}

#[test]
fn free_form_keys_go_to_the_first_accepting_from_any_slot_alphabetically() {
    let tree = stack();
    // `m_node` is declared first (nodes before interfaces) but `a_iface`
    // sorts first, and both accept cam_a instances.
    let s = ok(
        &tree,
        &[
            cams(),
            dep(
                "sorter",
                r#"      { instance_id: "s1", bindings: { k1: "a1", k2: "b1", k3: "a2" } },"#,
            ),
        ],
    );
    let s1 = s.plan.instance("s1").unwrap();
    let order: Vec<&str> = s1.slots.iter().map(|s| s.link_id.as_str()).collect();
    assert_eq!(order, ["m_node", "a_iface"], "slots keep depends_on order");
    assert_eq!(slot(s1, "a_iface").binding, bound(&["a1", "b1", "a2"]));
    assert_eq!(slot(s1, "m_node").binding, SlotBinding::FromAnyUnbound);
    assert_eq!(slot(s1, "m_node").kind, SlotKind::Node);
    assert_eq!(
        slot(s1, "m_node").filter,
        RouteFilter::Any,
        "slots of another kind are not siblings"
    );

    // A key equal to a from_any link_id binds that slot.
    let s = ok(
        &tree,
        &[
            cams(),
            dep(
                "sorter",
                r#"      { instance_id: "s1", bindings: { m_node: "a1", k: "b1" } },"#,
            ),
        ],
    );
    let s1 = s.plan.instance("s1").unwrap();
    assert_eq!(slot(s1, "m_node").binding, bound(&["a1"]));
    assert_eq!(slot(s1, "a_iface").binding, bound(&["b1"]));
}

#[test]
fn a_pinned_slot_without_binding() {
    let tree = stack();
    let (path, text) = launcher(
        &tree,
        &[
            cams(),
            dep(
                "fusion",
                r#"      { instance_id: "f1", bindings: { right: "a2" } },"#,
            ),
        ],
    );
    let errors = stack_err(&path);
    assert_eq!(errors.error_count(), 1, "{errors}");
    let d = one(&errors, Code::PinnedSlotUnbound);
    assert_at(
        d,
        Code::PinnedSlotUnbound,
        "deployments[2].instances[0].instance_id",
        &text,
        r#""f1""#,
    );
    assert_eq!(
        d.message,
        "instance `f1`: pinned slot `left` (interface `cam:v1`) is unbound"
    );
    assert_eq!(
        help(d),
        "add `bindings: { left: \"a1\" }`; instances that fit: `a1`, `a2`, `b1`"
    );

    // With nothing that fits, the help says so.
    let (path, _) = launcher(
        &tree,
        &[
            dep("plain", r#"      { instance_id: "p1" },"#),
            dep("fusion", r#"      { instance_id: "f1" },"#),
        ],
    );
    let errors = stack_err(&path);
    let found = all(&errors, Code::PinnedSlotUnbound);
    assert_eq!(found.len(), 2, "{errors}");
    assert!(
        help(found[0]).contains("no instance in this launcher fills interface `cam:v1` yet"),
        "{}",
        found[0]
    );
}

#[test]
fn dead_binding_keys() {
    let tree = stack();
    let (path, text) = launcher(
        &tree,
        &[
            cams(),
            dep("plain", r#"      { instance_id: "p1" },"#),
            dep(
                "follower",
                r#"      { instance_id: "fo", bindings: { leader: "p1", extra: "a1" } },"#,
            ),
            dep(
                "fusion",
                r#"      { instance_id: "f1", bindings: { left: "a1", right: "a2", spare: "p1" } },"#,
            ),
        ],
    );
    let errors = stack_err(&path);
    let found = all(&errors, Code::DeadBindingKey);
    assert_eq!(errors.error_count(), 2, "{errors}");
    assert_at(
        found[0],
        Code::DeadBindingKey,
        "deployments[3].instances[0].bindings.extra",
        &text,
        "extra:",
    );
    assert_eq!(
        found[0].message,
        "binding `extra` on instance `fo` matches no slot of `follower:v1`, and no from_any slot accepts `a1`"
    );
    assert_eq!(
        help(found[0]),
        "declared link_ids: `leader`; a free-form key needs a from_any slot, and `follower:v1` has none"
    );
    assert_at(
        found[1],
        Code::DeadBindingKey,
        "deployments[4].instances[0].bindings.spare",
        &text,
        "spare:",
    );
    assert_eq!(
        help(found[1]),
        "declared link_ids: `left`, `right`, `extras`; from_any slots: `extras` (interface `cam:v1`); `p1` deploys `plain:v1`"
    );

    // A node without slots.
    let (path, _) = launcher(
        &tree,
        &[
            cams(),
            dep("mosaic", r#"      { instance_id: "m1" },"#),
            dep(
                "plain",
                r#"      { instance_id: "p1", bindings: { x: "a1" } },"#,
            ),
        ],
    );
    let errors = stack_err(&path);
    assert!(help(one(&errors, Code::DeadBindingKey)).contains("declares no slots"));
}

#[test]
fn a_node_slot_bound_to_another_node() {
    let tree = stack();
    let (path, text) = launcher(
        &tree,
        &[
            cams(),
            dep(
                "follower",
                r#"      { instance_id: "fo", bindings: { leader: "a1" } },"#,
            ),
        ],
    );
    let errors = stack_err(&path);
    // The slot is keyed, so it is not also reported unbound.
    assert_eq!(error_codes(&errors), [Code::BindingTargetMismatch]);
    let d = one(&errors, Code::BindingTargetMismatch);
    assert_at(
        d,
        Code::BindingTargetMismatch,
        "deployments[2].instances[0].bindings.leader",
        &text,
        r#""a1" } },"#,
    );
    assert_eq!(
        d.message,
        "binding `leader` on instance `fo`: `a1` deploys node `cam_a:v1`, but slot `leader` expects node `plain:v1`"
    );
    assert_eq!(help(d), "bind an instance of `plain:v1`");
}

#[test]
fn an_interface_slot_bound_to_a_node_that_does_not_conform() {
    let tree = stack();
    let (path, text) = launcher(
        &tree,
        &[
            cams(),
            dep("plain", r#"      { instance_id: "p1" },"#),
            dep(
                "fusion",
                r#"      { instance_id: "f1", bindings: { left: "p1", right: "a2" } },"#,
            ),
        ],
    );
    let errors = stack_err(&path);
    assert_eq!(error_codes(&errors), [Code::BindingInterfaceNotConformed]);
    let d = one(&errors, Code::BindingInterfaceNotConformed);
    assert_at(
        d,
        Code::BindingInterfaceNotConformed,
        "deployments[3].instances[0].bindings.left",
        &text,
        r#""p1", right"#,
    );
    assert!(d.message.contains("`p1` deploys `plain:v1`, which does not conform to interface `cam:v1` required by slot `left`"), "{d}");
    assert!(
        help(d).contains(r#"add `conforms_to: [{ name: "cam", tag: "v1" }]` to `plain:v1`"#),
        "{d}"
    );
}

#[test]
fn parameters_are_checked_and_filled() {
    let tree = stack();
    let (path, text) = launcher(
        &tree,
        &[
            dep(
                "cam_a",
                r#"      { instance_id: "a1", arguments: { video: { width: 1280 } } },
      { instance_id: "a2", arguments: { fps: "fast" } },
      { instance_id: "a3", arguments: { fpss: 10 } },"#,
            ),
            dep(
                "needy",
                r#"      { instance_id: "n1" },
      { instance_id: "n2", arguments: { device: { port: 8 } } },
      { instance_id: "n3", arguments: { device: { serial: "SN1" }, rate: 70000 } },"#,
            ),
        ],
    );
    let errors = stack_err(&path);
    let got: Vec<(Code, &str, (usize, usize))> = errors
        .sorted()
        .iter()
        .map(|d| (d.code, key(d), lc(d)))
        .collect();
    assert_eq!(
        got,
        [
            (
                Code::ParameterTypeMismatch,
                "deployments[0].instances[1].arguments.fps",
                pos(&text, r#""fast""#)
            ),
            (
                Code::UnknownParameter,
                "deployments[0].instances[2].arguments.fpss",
                pos(&text, "10 }")
            ),
            (
                Code::MissingParameter,
                "deployments[1].instances[0].instance_id",
                pos(&text, r#""n1""#)
            ),
            (
                Code::MissingParameter,
                "deployments[1].instances[1].arguments.device.serial",
                pos(&text, "{ device: { port")
            ),
            (
                Code::ParameterTypeMismatch,
                "deployments[1].instances[2].arguments.rate",
                pos(&text, "70000")
            ),
        ]
    );
    let d = errors.sorted()[0];
    assert_eq!(
        d.message,
        "instance `a2`: parameter `fps` expects a `u16` (an integer from 0 to 65535), found the string \"fast\""
    );
    let unknown = one(&errors, Code::UnknownParameter);
    assert_eq!(unknown.message, "instance `a3`: unknown parameter `fpss`");
    assert_eq!(
        help(unknown),
        "did you mean `fps`? parameters here: `fps`, `video`"
    );
    let missing = all(&errors, Code::MissingParameter);
    assert_eq!(
        missing[0].message,
        "instance `n1`: missing required parameter `device.serial` (a `string`)"
    );
    assert!(
        help(missing[0]).contains("add it under `arguments`"),
        "{}",
        missing[0]
    );

    // The good ones, alone, plan with defaults filled in around what is given.
    let s = ok(
        &tree,
        &[
            dep(
                "cam_a",
                r#"      { instance_id: "a1", arguments: { video: { width: 1280 } } },"#,
            ),
            dep(
                "needy",
                r#"      { instance_id: "n3", arguments: { device: { serial: "SN1" } }, restart: "on-failure", env_vars: { RUST_LOG: "info" } },"#,
            ),
        ],
    );
    assert_eq!(
        s.plan.instance("a1").unwrap().parameters,
        json!({ "fps": 30, "video": { "width": 1280, "height": 480 } })
    );
    let n3 = s.plan.instance("n3").unwrap();
    assert_eq!(
        n3.parameters,
        json!({ "rate": 10, "device": { "serial": "SN1", "port": 7 } })
    );
    assert_eq!(n3.restart, RestartPolicy::OnFailure);
    assert_eq!(n3.env_vars, [("RUST_LOG".to_string(), "info".to_string())]);
}

#[test]
fn all_errors_of_a_stack_are_reported_together() {
    let tree = stack();
    let (path, text) = launcher(
        &tree,
        &[
            dep(
                "cam_a",
                r#"      { instance_id: "a1", arguments: { fps: -3 } },"#,
            ),
            dep(
                "follower",
                r#"      { instance_id: "fo", bindings: { leader: "a1" } },"#,
            ),
            dep(
                "fusion",
                r#"      { instance_id: "f1", bindings: { right: "a1", nope: "fo" } },"#,
            ),
        ],
    );
    let errors = stack_err(&path);
    let got: Vec<(Code, usize)> = errors.sorted().iter().map(|d| (d.code, lc(d).0)).collect();
    assert_eq!(
        got,
        [
            (Code::ParameterTypeMismatch, pos(&text, "-3").0),
            (Code::BindingTargetMismatch, pos(&text, "leader:").0),
            (Code::PinnedSlotUnbound, pos(&text, "\"f1\"").0),
            (Code::DeadBindingKey, pos(&text, "nope:").0),
        ]
    );
}

#[test]
fn a_node_deployed_twice() {
    let tree = stack();
    let (path, text) = launcher(
        &tree,
        &[
            dep("cam_b", r#"      { instance_id: "b1" },"#),
            r#"    { source: { local: "repo/cam_b" }, instances: [{ instance_id: "b2" }] },
"#
            .to_string(),
        ],
    );
    let errors = stack_err(&path);
    let d = one(&errors, Code::DuplicateDeployment);
    assert_eq!(errors.error_count(), 1, "{errors}");
    assert_at(
        d,
        Code::DuplicateDeployment,
        "deployments[1].source",
        &text,
        r#"{ local: "repo/cam_b" }"#,
    );
    assert_eq!(d.message, "`cam_b:v1` is deployed twice");
    let (line, col) = pos(&text, r#"{ name: "cam_b:v1" }"#);
    assert_eq!(
        help(d),
        format!("put all its instances in the deployment at line {line}, column {col}")
    );
}

#[test]
fn sources_that_cannot_be_found() {
    let tree = stack();
    let (path, text) = launcher(
        &tree,
        &[
            dep("ghost", r#"      { instance_id: "g1" },"#),
            r#"    { source: { local: "repo/nothing_here" }, instances: [{ instance_id: "l1" }] },
"#
            .to_string(),
        ],
    );
    let errors = stack_err(&path);
    assert_eq!(
        error_codes(&errors),
        [Code::DependencyNotFound, Code::InvalidSource]
    );
    let d = one(&errors, Code::DependencyNotFound);
    assert_at(
        d,
        Code::DependencyNotFound,
        "deployments[0].source",
        &text,
        r#"{ name: "ghost:v1" }"#,
    );
    assert_eq!(d.message, "no repository provides node `ghost:v1`");
    assert_eq!(
        help(d),
        format!("searched `{}`", tree.path("repo").display())
    );
    assert!(
        one(&errors, Code::InvalidSource)
            .message
            .contains("has no node")
    );
}

#[test]
fn interface_pins_are_enforced_at_launch() {
    let tree = stack();
    let good = sha256_hex(CAM_IFACE.as_bytes());
    let stale = "f".repeat(64);
    for (pin, expect_ok) in [(good.as_str(), true), (stale.as_str(), false)] {
        tree.write(
            "repo/pinned/peppy.json5",
            &node_text("pinned", &format!(r#"interfaces: [{{ name: "cam", tag: "v1", link_id: "cams", from_any: true, sha256: "{pin}" }}]"#), "", ""),
        );
        let (path, _) = launcher(
            &tree,
            &[cams(), dep("pinned", r#"      { instance_id: "p" },"#)],
        );
        match peppy_schema::check_launcher(&path, &options(Vec::new())) {
            Ok(s) => {
                assert!(expect_ok, "a stale pin must be refused");
                assert_eq!(
                    slot(s.plan.instance("p").unwrap(), "cams").filter,
                    RouteFilter::Any
                );
            }
            Err(errors) => {
                assert!(!expect_ok, "{errors}");
                let d = one(&errors, Code::InterfacePinMismatch);
                assert!(d.message.contains(&good), "{d}");
                assert_eq!(
                    d.file_path(),
                    Some(tree.path("repo/pinned/peppy.json5").as_path())
                );
            }
        }
    }
}

#[test]
fn unknown_binding_targets_suggest_the_closest_instance() {
    let tree = stack();
    let (path, text) = launcher(
        &tree,
        &[
            dep(
                "cam_a",
                r#"      { instance_id: "rs_left" }, { instance_id: "rs_right" },"#,
            ),
            dep(
                "fusion",
                r#"      { instance_id: "f1", bindings: { left: "rs_lfet", right: "rs_right" } },"#,
            ),
        ],
    );
    let errors = stack_err(&path);
    assert_eq!(error_codes(&errors), [Code::UnknownBindingTarget]);
    let d = one(&errors, Code::UnknownBindingTarget);
    assert_at(
        d,
        Code::UnknownBindingTarget,
        "deployments[1].instances[0].bindings.left",
        &text,
        r#""rs_lfet""#,
    );
    assert_eq!(
        help(d),
        "did you mean `rs_left`? instances in this launcher: `rs_left`, `rs_right`, `f1`"
    );
}
