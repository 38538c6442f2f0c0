//! Pairing slots resolved against their `pairing/v1` documents, and a
//! launcher's links on them planned into each instance's `PairPlan`s
//! (docs/PAIRINGS.md §1–2), every error located.

use peppy_schema::{
    Code, Diagnostics, LauncherDoc, NodeDoc, PairEnd, PairPlan, check_node, plan_bindings,
};

use crate::support::*;

const ARM_LINK: &str = r#"{
  peppy_schema: "pairing/v1",
  manifest: { name: "arm_link", tag: "v1" },
  roles: ["commander", "arm"],
  topics: [
    { emitted_by: "commander", name: "setpoint", message_format: { position: "f64" } },
    { emitted_by: "arm", name: "state", message_format: { position: "f64", samples: { $type: "array", $items: "f32" } } },
    { emitted_by: "arm", name: "fault", message_format: { code: "u16" } },
  ],
}
"#;

fn node(name: &str, depends_on: &str, topics: &str) -> String {
    format!(
        r#"{{
  peppy_schema: "node/v1",
  manifest: {{ name: "{name}", tag: "v1", depends_on: {{ {depends_on} }} }},
  execution: {{ language: "python", run_cmd: ["python3", "main.py"] }},
  interfaces: {{ topics: {{ {topics} }} }},
}}
"#
    )
}

const COMMANDER: (&str, &str) = (
    r#"pairings: [{ name: "arm_link", tag: "v1", role: "commander", link_id: "arm" }]"#,
    r#"emits: [{ link_id: "arm", name: "setpoint" }], consumes: [{ link_id: "arm", name: "state" }]"#,
);
const ARM: (&str, &str) = (
    r#"pairings: [{ name: "arm_link", tag: "v1", role: "arm", link_id: "commander" }]"#,
    r#"emits: [{ link_id: "commander", name: "state" }, { link_id: "commander", name: "fault" }], consumes: [{ link_id: "commander", name: "setpoint" }]"#,
);
const MONITOR: (&str, &str) = (
    r#"pairing_observers: [{ name: "arm_link", tag: "v1", role: "arm", link_id: "arms", cardinality: "one_or_more" }]"#,
    r#"consumes: [{ link_id: "arms", name: "state" }]"#,
);

fn repo(extra: &[(&str, String)]) -> Tree {
    let tree = Tree::new();
    tree.write("repo/pairings/arm_link.json5", ARM_LINK);
    for (name, text) in extra {
        tree.write(&format!("repo/nodes/{name}/peppy.json5"), text);
    }
    tree
}

fn resolve_err(text: String) -> (Diagnostics, String) {
    let tree = repo(&[("n", text.clone())]);
    match check_node(
        &tree.path("repo/nodes/n/peppy.json5"),
        &options(vec![tree.path("repo")]),
    ) {
        Ok(_) => panic!("expected an error"),
        Err(e) => (e, text),
    }
}

#[test]
fn pairing_slots_resolve_with_their_topics_and_counterpart() {
    let tree = repo(&[
        ("commander", node("commander", COMMANDER.0, COMMANDER.1)),
        ("arm", node("arm", ARM.0, ARM.1)),
        ("monitor", node("monitor", MONITOR.0, MONITOR.1)),
    ]);
    let opts = options(vec![tree.path("repo")]);
    let arm = check_node(&tree.path("repo/nodes/arm/peppy.json5"), &opts)
        .unwrap_or_else(|e| panic!("{e}"));
    let p = &arm.resolved.pairings[0];
    assert_eq!(p.slot.counterpart, "commander");
    let names = |l: &[peppy_schema::PairingTopicUse]| -> Vec<String> {
        l.iter().map(|t| t.topic.decl.name.clone()).collect()
    };
    assert_eq!(names(&p.emitted), ["state", "fault"]);
    assert_eq!(names(&p.consumed), ["setpoint"]);
    // The model a binary embeds carries the counterpart.
    let model = peppy_schema::NodeModel::of(&arm.resolved.node);
    assert_eq!(model.pairing("commander").unwrap().counterpart, "commander");
    // Pairing topics are not the node's own topics.
    assert!(arm.resolved.emitted_topics.is_empty());
    assert!(arm.resolved.consumed_topics.is_empty());

    let monitor = check_node(&tree.path("repo/nodes/monitor/peppy.json5"), &opts)
        .unwrap_or_else(|e| panic!("{e}"));
    let o = &monitor.resolved.pairings[0];
    assert!(o.slot.observer && o.emitted.is_empty());
    assert_eq!(names(&o.consumed), ["state"]);
    assert_eq!(o.slot.counterpart, "commander");
}

#[test]
fn a_participant_lists_exactly_what_its_role_emits() {
    let (errors, text) = resolve_err(node(
        "n",
        ARM.0,
        r#"emits: [{ link_id: "commander", name: "state" }, { link_id: "commander", name: "setpoint" }, { link_id: "commander", name: "stat" }]"#,
    ));
    let d = one(&errors, Code::PairingCoverageMismatch);
    assert_at(
        d,
        Code::PairingCoverageMismatch,
        "manifest.depends_on.pairings[0]",
        &text,
        r#"{ name: "arm_link""#,
    );
    assert_eq!(
        d.message,
        "pairing slot `commander` does not list the topics role `arm` of `arm_link:v1` emits: missing: `fault`; `setpoint` is emitted by role `commander`, not `arm`; unknown topic `stat`"
    );
    assert!(help(d).contains("`state`, `fault`"), "{}", help(d));
}

#[test]
fn what_a_slot_consumes_comes_from_the_other_role_or_the_watched_one() {
    let (errors, text) = resolve_err(node(
        "n",
        COMMANDER.0,
        r#"emits: [{ link_id: "arm", name: "setpoint" }], consumes: [{ link_id: "arm", name: "setpoint" }, { link_id: "arm", name: "stat" }]"#,
    ));
    let found = all(&errors, Code::PairingCoverageMismatch);
    assert_eq!(found.len(), 2, "{errors}");
    assert_at(
        found[0],
        Code::PairingCoverageMismatch,
        "interfaces.topics.consumes[0]",
        &text,
        r#"{ link_id: "arm", name: "setpoint" }, { link_id: "arm", name: "stat" }"#,
    );
    assert_eq!(
        found[0].message,
        "slot `arm` plays role `commander`, which emits `setpoint` itself"
    );
    assert_eq!(
        found[1].message,
        "pairing `arm_link:v1` has no topic `stat`"
    );
    assert!(
        help(found[1]).starts_with("did you mean `state`?"),
        "{}",
        help(found[1])
    );

    let (errors, _) = resolve_err(node(
        "n",
        MONITOR.0,
        r#"consumes: [{ link_id: "arms", name: "setpoint" }]"#,
    ));
    assert_eq!(
        one(&errors, Code::PairingCoverageMismatch).message,
        "observer slot `arms` watches role `arm`, and `setpoint` is emitted by `commander`"
    );
}

#[test]
fn unknown_roles_missing_documents_and_stale_pins() {
    let (errors, _) = resolve_err(node(
        "n",
        r#"pairings: [{ name: "arm_link", tag: "v1", role: "leader", link_id: "arm" }]"#,
        "",
    ));
    let d = one(&errors, Code::PairingRoleUnknown);
    assert_eq!(
        d.message,
        "slot `arm` plays role `leader`, which pairing `arm_link:v1` does not have"
    );
    assert_eq!(help(d), "its roles are `commander`, `arm`");

    let (errors, _) = resolve_err(node(
        "n",
        r#"pairings: [{ name: "arm_lnk", tag: "v1", role: "arm", link_id: "arm" }]"#,
        "",
    ));
    let d = one(&errors, Code::DependencyNotFound);
    assert_eq!(d.message, "no repository provides pairing `arm_lnk:v1`");
    assert!(
        help(d).starts_with("did you mean `arm_link:v1`?"),
        "{}",
        help(d)
    );

    let (errors, _) = resolve_err(node(
        "n",
        &format!(
            r#"pairings: [{{ name: "arm_link", tag: "v1", role: "commander", link_id: "arm", sha256: "{}" }}]"#,
            "0".repeat(64)
        ),
        COMMANDER.1,
    ));
    let d = one(&errors, Code::PairingShaMismatch);
    assert!(
        d.message
            .starts_with("slot `arm` pins pairing `arm_link:v1` to sha256 `000"),
        "{}",
        d.message
    );
}

// ---- the launcher's plan ----

fn docs() -> Vec<NodeDoc> {
    [
        ("commander", COMMANDER),
        ("arm", ARM),
        ("monitor", MONITOR),
        (
            "dual",
            (
                r#"pairings: [
                    { name: "arm_link", tag: "v1", role: "commander", link_id: "left" },
                    { name: "arm_link", tag: "v1", role: "commander", link_id: "right", optional: true },
                  ]"#,
                r#"emits: [{ link_id: "left", name: "setpoint" }, { link_id: "right", name: "setpoint" }]"#,
            ),
        ),
    ]
    .iter()
    .map(|(name, (deps, topics))| {
        NodeDoc::parse(format!("{name}.json5"), node(name, deps, topics))
            .unwrap_or_else(|e| panic!("{e}"))
            .0
    })
    .collect()
}

/// A launcher with one deployment per node of [`docs`] that has
/// instances (`commander`, `arm`, `monitor`, `dual`, in that order), and
/// its plan.
fn plan(instances: [&str; 4]) -> (Result<peppy_schema::BindingPlan, Diagnostics>, String) {
    let docs = docs();
    let names = ["commander", "arm", "monitor", "dual"];
    let used: Vec<usize> = (0..4).filter(|i| !instances[*i].is_empty()).collect();
    let deployments: Vec<String> = used
        .iter()
        .map(|&i| {
            format!(
                "    {{ source: {{ name: \"{}:v1\" }}, instances: [{}] }},",
                names[i], instances[i]
            )
        })
        .collect();
    let text = format!(
        "{{\n  peppy_schema: \"launcher/v1\",\n  deployments: [\n{}\n  ],\n}}\n",
        deployments.join("\n")
    );
    let (launcher, _) = LauncherDoc::parse("launch.json5", &text).unwrap_or_else(|e| panic!("{e}"));
    let nodes: Vec<Option<&NodeDoc>> = used.iter().map(|&i| Some(&docs[i])).collect();
    (plan_bindings(&launcher, &nodes).map(|(p, _)| p), text)
}

fn end(instance: &str, link: &str) -> PairEnd {
    PairEnd {
        instance: instance.into(),
        link_id: Some(link.into()),
    }
}

fn pair(link: &str, peers: Vec<PairEnd>) -> PairPlan {
    PairPlan {
        link_id: link.into(),
        peers,
        vacant: None,
    }
}

#[test]
fn two_commanders_and_two_arms_pair_one_to_one_from_either_side() {
    // c1 links its arm; a2 links its commander: one side covers both.
    let (plan, _) = plan([
        r#"{ instance_id: "c1", links: { arm: "a1" } }, { instance_id: "c2" }"#,
        r#"{ instance_id: "a1" }, { instance_id: "a2", links: { commander: "c2/arm" } }"#,
        r#"{ instance_id: "m", links: { arms: ["a1", "a2/commander"] } }"#,
        "",
    ]);
    let plan = plan.unwrap_or_else(|e| panic!("{e}"));
    let pairs = |id: &str| plan.instance(id).unwrap().pairs.clone();
    assert_eq!(pairs("c1"), [pair("arm", vec![end("a1", "commander")])]);
    assert_eq!(pairs("a1"), [pair("commander", vec![end("c1", "arm")])]);
    assert_eq!(pairs("c2"), [pair("arm", vec![end("a2", "commander")])]);
    assert_eq!(pairs("a2"), [pair("commander", vec![end("c2", "arm")])]);
    assert_eq!(
        pairs("m"),
        [pair(
            "arms",
            vec![end("a1", "commander"), end("a2", "commander")]
        )]
    );
}

#[test]
fn a_commander_with_two_arm_slots_pairs_each_and_may_leave_an_optional_one_vacant() {
    let (plan, _) = plan([
        "",
        r#"{ instance_id: "a1", links: { commander: "d/left" } }"#,
        "",
        r#"{ instance_id: "d", links: { right: { vacant: "one-armed bench" } } }"#,
    ]);
    let plan = plan.unwrap_or_else(|e| panic!("{e}"));
    let d = plan.instance("d").unwrap();
    assert_eq!(d.pairs[0], pair("left", vec![end("a1", "commander")]));
    assert_eq!(
        d.pairs[1],
        PairPlan {
            link_id: "right".into(),
            peers: vec![],
            vacant: Some("one-armed bench".into()),
        }
    );
}

#[test]
fn every_pairing_rule_is_located_in_the_launcher() {
    let cases: [([&str; 4], Code, &str, &str); 8] = [
        (
            [
                r#"{ instance_id: "c1", links: { arm: "a1" } }, { instance_id: "c2", links: { arm: "a1" } }"#,
                r#"{ instance_id: "a1" }"#,
                "",
                "",
            ],
            Code::PairingSlotAlreadyPaired,
            r#""a1" } }]"#,
            "`a1/commander` holds one peer, and is already paired with `c1/arm` (linked by `c1`)",
        ),
        (
            [
                r#"{ instance_id: "c1", links: { arm: "a1" } }, { instance_id: "c2" }"#,
                r#"{ instance_id: "a1", links: { commander: "c2" } }"#,
                "",
                "",
            ],
            Code::PairingConflict,
            r#""c2" } }]"#,
            "`a1/commander` is paired with `c1/arm` by the link of `c1`, and with `c2/arm` here",
        ),
        (
            [
                r#"{ instance_id: "c1", links: { arm: "m" } }"#,
                "",
                r#"{ instance_id: "m", links: { arms: [] } }"#,
                "",
            ],
            Code::PairingTargetNotComplementary,
            r#""m" }"#,
            "slot `arm` of instance `c1` plays `commander` of `arm_link:v1`, and `m` has no slot of the other role of that pairing",
        ),
        (
            [
                r#"{ instance_id: "c1", links: { arm: "a1/nope" } }"#,
                r#"{ instance_id: "a1" }"#,
                "",
                "",
            ],
            Code::PairingTargetNotComplementary,
            r#""a1/nope""#,
            "slot `arm` of instance `c1` plays `commander` of `arm_link:v1`, and `a1/nope` has no slot of the other role of that pairing",
        ),
        (
            [r#"{ instance_id: "c1" }"#, "", "", ""],
            Code::PairingSlotUncovered,
            r#""c1""#,
            "instance `c1` leaves pairing slot `arm` (commander of `arm_link:v1`) without a peer",
        ),
        (
            [
                r#"{ instance_id: "c1", links: { arm: { vacant: "later" } } }"#,
                "",
                "",
                "",
            ],
            Code::LinkVacantInvalid,
            r#"{ vacant: "later" }"#,
            "pairing slot `arm` of instance `c1` may not be left vacant",
        ),
        (
            [
                "",
                "",
                r#"{ instance_id: "m", links: { arms: ["d"] } }"#,
                r#"{ instance_id: "d", links: { right: { vacant: "x" }, left: { vacant: "y" } } }"#,
            ],
            Code::ObservationTargetNotObservable,
            r#""d"]"#,
            "observer slot `arms` of instance `m` watches role `arm` of `arm_link:v1`, and `d` does not play it",
        ),
        (
            [
                r#"{ instance_id: "c1", links: { arm: "a1" } }"#,
                r#"{ instance_id: "a1" }"#,
                r#"{ instance_id: "m", links: { arms: ["a1", "a1/commander"] } }"#,
                "",
            ],
            Code::DuplicateObservationTarget,
            r#""a1/commander"]"#,
            "observer slot `arms` of instance `m` lists `a1/commander` twice",
        ),
    ];
    for (instances, code, needle, message) in cases {
        let (result, text) = plan(instances);
        let errors = result.expect_err(message);
        let found = all(&errors, code);
        let d = found
            .iter()
            .find(|d| d.message == message)
            .unwrap_or_else(|| panic!("no `{message}` in:\n{errors}"));
        let at = pos(&text, needle);
        assert_eq!(lc(d), at, "{code:?}: {d}\n{text}");
    }
}

/// A slot an instance leaves vacant while a peer links to it: one rule
/// (`check_pair_plan`) for the launcher and the command line, refused here
/// before anything starts.
#[test]
fn a_slot_left_vacant_and_linked_by_a_peer_is_refused() {
    let (result, text) = plan([
        "",
        r#"{ instance_id: "a1", links: { commander: "d/right" } }, { instance_id: "a2", links: { commander: "d/left" } }"#,
        "",
        r#"{ instance_id: "d", links: { right: { vacant: "one-armed bench" } } }"#,
    ]);
    let errors = result.expect_err("linked and vacant");
    let d = one(&errors, Code::LinkVacantInvalid);
    assert_eq!(
        d.message,
        "instance `d`: pairing slot `right` is both linked and left vacant"
    );
    assert_eq!(lc(d), pos(&text, r#""d", links"#));
}

#[test]
fn a_peer_with_several_fitting_slots_is_named_with_its_slot() {
    let (result, _) = plan([
        "",
        r#"{ instance_id: "a1", links: { commander: "d" } }"#,
        "",
        r#"{ instance_id: "d", links: { right: { vacant: "x" } } }"#,
    ]);
    let errors = result.expect_err("ambiguous");
    let d = one(&errors, Code::PairingTargetAmbiguous);
    assert_eq!(
        d.message,
        "instance `d` takes part in `arm_link:v1` through several slots: `left`, `right`"
    );
    assert_eq!(help(d), r#"name the slot: `"d/left"`"#);
}

/// Both ends of a pair read one pairing document: two different pins are
/// refused at the link (PeppyOS's `PairingSha256Mismatch`), for an
/// observer and its source too; equal pins agree.
#[test]
fn the_two_ends_of_a_pair_pin_the_same_revision() {
    let a = "a".repeat(64);
    let b = "b".repeat(64);
    let pinned = |slot: &str, sha: &str| {
        slot.replace(r#"tag: "v1","#, &format!(r#"tag: "v1", sha256: "{sha}","#))
    };
    let commander = NodeDoc::parse(
        "c.json5",
        node("commander", &pinned(COMMANDER.0, &a), COMMANDER.1),
    )
    .unwrap()
    .0;
    let arm = NodeDoc::parse("a.json5", node("arm", &pinned(ARM.0, &b), ARM.1))
        .unwrap()
        .0;
    let arm_same = NodeDoc::parse("a.json5", node("arm", &pinned(ARM.0, &a), ARM.1))
        .unwrap()
        .0;
    let monitor = NodeDoc::parse(
        "m.json5",
        node("monitor", &pinned(MONITOR.0, &a), MONITOR.1),
    )
    .unwrap()
    .0;
    let text = r#"{ peppy_schema: "launcher/v1", deployments: [
      { source: { name: "commander:v1" }, instances: [{ instance_id: "c1", links: { arm: "a1" } }] },
      { source: { name: "arm:v1" }, instances: [{ instance_id: "a1" }] },
      { source: { name: "monitor:v1" }, instances: [{ instance_id: "m", links: { arms: ["a1"] } }] },
    ] }"#;
    let (launcher, _) = LauncherDoc::parse("launch.json5", text).unwrap();
    let errors = plan_bindings(&launcher, &[Some(&commander), Some(&arm), Some(&monitor)])
        .expect_err("different pins");
    let found = all(&errors, Code::PairingSha256Mismatch);
    assert_eq!(found.len(), 2, "{errors}");
    assert_eq!(
        found[0].message,
        format!(
            "slot `arm` of `c1` pins pairing `arm_link:v1` at sha256 {a}, and slot `commander` of `a1` at {b}"
        )
    );
    assert_eq!(lc(found[0]), pos(text, r#""a1" } }]"#));
    assert_eq!(lc(found[1]), pos(text, r#""a1"] } }]"#));
    // The same pin on both ends agrees.
    plan_bindings(
        &launcher,
        &[Some(&commander), Some(&arm_same), Some(&monitor)],
    )
    .unwrap_or_else(|e| panic!("{e}"));
}
