//! `node/v1` documents (current_peppyos.md §1.1, §2, §3): read into the
//! model `node_v1` documents are read into, and every parse-time rule a
//! located error with PeppyOS's name.

use peppy_schema::{
    Cardinality, Code, Diagnostics, EntryKind, Identity, Launch, SlotKind, Spelling,
};

use crate::support::*;

/// A `node/v1` document: `manifest` gets `manifest` spliced in after its
/// identity, `interfaces` is `interfaces`.
fn doc(manifest: &str, interfaces: &str) -> String {
    format!(
        r#"{{
  peppy_schema: "node/v1",
  manifest: {{
    name: "robot",
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

/// The one error with `code`, after checking it is the only error (no
/// cascade).
#[track_caller]
fn only(d: &Diagnostics, code: Code) -> &peppy_schema::Diagnostic {
    assert_eq!(error_codes(d), [code], "{d}");
    one(d, code)
}

/// Shaped like the hubs' camera and robot nodes: an `implements` slot with
/// its members listed, producer slots of every cardinality, parameters and
/// a container.
const HUB_NODE: &str = r#"{
  peppy_schema: "node/v1",
  manifest: {
    name: "arm_driver",
    tag: "v1",
    labels: ["manipulation"],
    implements: [
      { name: "arm_control", tag: "v1", link_id: "arm" },
    ],
    depends_on: {
      nodes: [
        { name: "safety_monitor", tag: "v1", link_id: "safety" },
      ],
      contracts: [
        { name: "rgb_camera", tag: "v1", link_id: "camera", cardinality: "zero_or_one" },
        { name: "rgb_camera", tag: "v1", link_id: "extra_cameras", cardinality: "zero_or_more" },
        { name: "joystick", tag: "v1", link_id: "pads", cardinality: "one_or_more" },
      ],
    },
  },
  execution: {
    language: "rust",
    container: { def_file: "apptainer.def", mount_paths: ["${parameters:device}:/dev/arm:rw"] },
    parameters: {
      device: "string",
      rate: { $type: "u16", $default: 50 },
    },
  },
  interfaces: {
    topics: {
      emits: [
        { link_id: "arm", name: "joint_states" },
        { name: "temperature", qos_profile: "sensor_data", message_format: { celsius: "f32" } },
      ],
      consumes: [
        { link_id: "camera", name: "video_stream" },
        { link_id: "safety", name: "stop" },
        { link_id: "pads", name: "axes" },
      ],
    },
    services: {
      exposes: [{ link_id: "arm", name: "get_limits" }],
      consumes: [{ link_id: "camera", name: "video_stream_info" }],
    },
    actions: {
      exposes: [{ link_id: "arm", name: "move_to", refine: { goal_service: { request_message_format: { target: { $length: 7 } } } } }],
    },
  },
}
"#;

#[test]
fn a_node_shaped_like_the_hubs_reads_into_the_model() {
    let (node, warnings) = node_ok(HUB_NODE);
    assert!(warnings.is_empty(), "{warnings}");
    assert_eq!(node.spelling, Spelling::SlashIds);
    assert_eq!(node.identity(), Identity::new("arm_driver", "v1"));
    assert_eq!(node.labels, ["manipulation"]);
    // `implements` is conformance, with its slot name.
    assert_eq!(node.conforms_to.len(), 1);
    assert_eq!(
        node.conforms_to[0].target,
        Identity::new("arm_control", "v1")
    );
    assert_eq!(node.conforms_to[0].link_id.as_deref(), Some("arm"));
    // Members listed through the slot, in document order by section.
    let members: Vec<(EntryKind, &str, &str, bool)> = node
        .members
        .iter()
        .map(|m| {
            (
                m.kind,
                m.link_id.as_str(),
                m.name.as_str(),
                m.refine.is_some(),
            )
        })
        .collect();
    assert_eq!(
        members,
        [
            (EntryKind::Topic, "arm", "joint_states", false),
            (EntryKind::Service, "arm", "get_limits", false),
            (EntryKind::Action, "arm", "move_to", true),
        ]
    );
    // Natives stay the node's own entries.
    let natives: Vec<&str> = node.emits.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(natives, ["temperature"]);
    // Slots: nodes first, then contracts, each with its cardinality.
    let slots: Vec<(&str, SlotKind, Cardinality, bool)> = node
        .dependencies
        .iter()
        .map(|d| (d.link_id.as_str(), d.kind, d.cardinality, d.from_any))
        .collect();
    assert_eq!(
        slots,
        [
            ("safety", SlotKind::Node, Cardinality::One, false),
            ("camera", SlotKind::Interface, Cardinality::ZeroOrOne, false),
            (
                "extra_cameras",
                SlotKind::Interface,
                Cardinality::ZeroOrMore,
                false
            ),
            ("pads", SlotKind::Interface, Cardinality::OneOrMore, false),
        ]
    );
    assert_eq!(
        node.dependencies[1].target,
        Identity::new("rgb_camera", "v1")
    );
    assert_eq!(node.consumed_topics.len(), 3);
    assert_eq!(node.consumed_services.len(), 1);
    assert!(node.pairings.is_empty());
    // Execution: a container, parameters with their default.
    assert!(
        matches!(node.execution.launch(), Launch::Container(c) if c.def_file == "apptainer.def")
    );
    assert_eq!(
        node.execution
            .parameters
            .resolve(&serde_json::json!({ "device": "/dev/ttyUSB0" }))
            .expect("parameters"),
        serde_json::json!({ "device": "/dev/ttyUSB0", "rate": 50 })
    );
}

#[test]
fn an_unknown_cardinality_suggests_the_closest() {
    let text = doc(
        r#"depends_on: { contracts: [{ name: "cam", tag: "v1", link_id: "cams", cardinality: "one_or_mor" }] },"#,
        "",
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::InvalidValue);
    assert_at(
        d,
        Code::InvalidValue,
        "manifest.depends_on.contracts[0].cardinality",
        &text,
        r#""one_or_mor""#,
    );
    assert_eq!(d.message, "unknown cardinality `one_or_mor`");
    assert!(
        help(d).starts_with("did you mean `one_or_more`?"),
        "{}",
        help(d)
    );
    assert!(help(d).contains("zero_or_more"), "{}", help(d));
}

#[test]
fn from_any_is_the_underscored_spelling_and_points_to_cardinality() {
    let text = doc(
        r#"depends_on: { nodes: [{ name: "cam", tag: "v1", link_id: "cams", from_any: true }] },"#,
        "",
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::UnknownKey);
    assert_at(
        d,
        Code::UnknownKey,
        "manifest.depends_on.nodes[0].from_any",
        &text,
        "from_any",
    );
    assert!(d.message.contains("`cardinality`"), "{}", d.message);
    assert!(
        help(d).contains("cardinality: \"zero_or_more\""),
        "{}",
        help(d)
    );
}

#[test]
fn conforms_to_is_not_a_key_of_slashed_interfaces() {
    let text = doc("", r#"conforms_to: [{ name: "cam", tag: "v1" }],"#);
    let errors = node_err(&text);
    let d = only(&errors, Code::UnknownKey);
    assert_at(
        d,
        Code::UnknownKey,
        "interfaces.conforms_to",
        &text,
        "conforms_to",
    );
    assert_eq!(d.message, "unknown key `conforms_to` in `interfaces`");
}

#[test]
fn external_consumed_topics_are_refused() {
    let text = doc(
        "",
        r#"topics: { consumes: [{ name: "clock", message_format: { t: "u64" } }] },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::UnknownKey);
    assert_at(
        d,
        Code::UnknownKey,
        "interfaces.topics.consumes[0].message_format",
        &text,
        "message_format",
    );
    assert!(
        d.message.contains("external consumed topics"),
        "{}",
        d.message
    );
    assert!(help(d).contains("{ link_id, name }"), "{}", help(d));
}

#[test]
fn link_ids_are_one_namespace_across_implements_contracts_and_pairings() {
    let text = doc(
        r#"implements: [{ name: "arm_control", tag: "v1", link_id: "arm" }],
    depends_on: {
      contracts: [{ name: "cam", tag: "v1", link_id: "arm" }],
      pairings: [{ name: "handshake", tag: "v1", role: "leader", link_id: "arm" }],
    },"#,
        "",
    );
    let errors = node_err(&text);
    assert_eq!(
        error_codes(&errors),
        [Code::DuplicateLinkId, Code::DuplicateLinkId],
        "{errors}"
    );
    let found = all(&errors, Code::DuplicateLinkId);
    assert_at(
        found[0],
        Code::DuplicateLinkId,
        "manifest.depends_on.contracts[0]",
        &text,
        r#"{ name: "cam""#,
    );
    assert_at(
        found[1],
        Code::DuplicateLinkId,
        "manifest.depends_on.pairings[0]",
        &text,
        r#"{ name: "handshake""#,
    );
    assert_eq!(found[0].message, "duplicate link_id `arm` in `manifest`");
    // The first use is the implements slot, on line 5.
    let (line, col) = pos(&text, r#"{ name: "arm_control""#);
    assert!(
        help(found[1]).ends_with(&format!("already used at line {line}, column {col}")),
        "{}",
        help(found[1])
    );
}

#[test]
fn a_contract_is_implemented_once() {
    let text = doc(
        r#"implements: [
      { name: "arm_control", tag: "v1", link_id: "left" },
      { name: "arm_control", tag: "v1", link_id: "right" },
    ],"#,
        "",
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::DuplicateImplementsContract);
    assert_at(
        d,
        Code::DuplicateImplementsContract,
        "manifest.implements[1]",
        &text,
        r#"{ name: "arm_control", tag: "v1", link_id: "right" }"#,
    );
    assert_eq!(d.message, "`arm_control:v1` is implemented twice");
}

#[test]
fn implemented_tags_must_not_collide_once_sanitized() {
    let text = doc(
        r#"implements: [
      { name: "arm_control", tag: "v1-a", link_id: "left" },
      { name: "arm_control", tag: "v1_a", link_id: "right" },
    ],"#,
        "",
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::ImplementsTagSanitizationCollision);
    assert_at(
        d,
        Code::ImplementsTagSanitizationCollision,
        "manifest.implements[1]",
        &text,
        r#"{ name: "arm_control", tag: "v1_a""#,
    );
    assert_eq!(
        d.message,
        "`arm_control:v1-a` and `arm_control:v1_a` collide once `-` is read as `_`"
    );
}

const ARM: &str = r#"implements: [{ name: "arm_control", tag: "v1", link_id: "arm" }],"#;

#[test]
fn a_linked_entry_takes_no_inline_shape() {
    let text = doc(
        ARM,
        r#"topics: { emits: [{ link_id: "arm", name: "joint_states", message_format: { p: "f64" } }] },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::LinkedEntryWithInlineShape);
    assert_at(
        d,
        Code::LinkedEntryWithInlineShape,
        "interfaces.topics.emits[0].message_format",
        &text,
        "message_format",
    );
    assert_eq!(
        d.message,
        "`message_format` on an entry with a `link_id` in `interfaces.topics.emits`"
    );
}

#[test]
fn refine_needs_a_link_id() {
    let text = doc(
        "",
        r#"topics: { emits: [{ name: "scan", message_format: { r: { $type: "array", $items: "f32" } }, refine: { message_format: { r: { $length: 360 } } } }] },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::RefineWithoutLinkId);
    assert_at(
        d,
        Code::RefineWithoutLinkId,
        "interfaces.topics.emits[0].refine",
        &text,
        "refine",
    );
    assert!(help(d).contains("`$length`"), "{}", help(d));
}

#[test]
fn a_member_is_listed_once_per_section() {
    let text = doc(
        ARM,
        r#"services: { exposes: [
      { link_id: "arm", name: "get_limits" },
      { link_id: "arm", name: "get_limits" },
    ] },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::DuplicateInterfaceEntry);
    let needle = r#"{ link_id: "arm", name: "get_limits" }"#;
    assert_eq!(
        d.key_path.as_deref(),
        Some("interfaces.services.exposes[1]")
    );
    assert_eq!(lc(d), pos_nth(&text, needle, 1));
    assert_eq!(
        d.message,
        "`get_limits` of `arm` is listed twice in `interfaces.services.exposes`"
    );
    let (line, col) = pos(&text, needle);
    assert!(
        help(d).ends_with(&format!("line {line}, column {col}")),
        "{}",
        help(d)
    );
}

#[test]
fn an_emitted_member_names_a_declared_slot() {
    let text = doc(
        ARM,
        r#"topics: { emits: [{ link_id: "armm", name: "joint_states" }] },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::UndeclaredEmitsLinkId);
    assert_at(
        d,
        Code::UndeclaredEmitsLinkId,
        "interfaces.topics.emits[0]",
        &text,
        r#"{ link_id: "armm""#,
    );
    assert_eq!(
        d.message,
        "`interfaces.topics.emits` entry `joint_states` names link_id `armm`, which `manifest` does not declare"
    );
    assert!(help(d).starts_with("did you mean `arm`?"), "{}", help(d));
}

#[test]
fn a_service_is_exposed_only_through_an_implements_slot() {
    let text = doc(
        r#"depends_on: { contracts: [{ name: "arm_control", tag: "v1", link_id: "arm" }] },"#,
        r#"services: { exposes: [{ link_id: "arm", name: "get_limits" }] },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::EmitsLinkIdNotImplements);
    assert_at(
        d,
        Code::EmitsLinkIdNotImplements,
        "interfaces.services.exposes[0]",
        &text,
        r#"{ link_id: "arm", name: "get_limits" }"#,
    );
    assert_eq!(
        d.message,
        "`interfaces.services.exposes` entry `get_limits` names `arm`, a `depends_on.contracts` slot"
    );
    assert!(help(d).contains("topics-only"), "{}", help(d));
}

const OBSERVER: &str = r#"depends_on: {
      pairing_observers: [{ name: "handshake", tag: "v1", role: "leader", link_id: "watch" }],
    },"#;

#[test]
fn an_observer_slot_is_not_emitted_on() {
    let text = doc(
        OBSERVER,
        r#"topics: {
      emits: [{ link_id: "watch", name: "ping" }],
      consumes: [{ link_id: "watch", name: "ping" }],
    },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::EmitsOnObserverSlot);
    assert_at(
        d,
        Code::EmitsOnObserverSlot,
        "interfaces.topics.emits[0]",
        &text,
        r#"{ link_id: "watch", name: "ping" }"#,
    );
    assert_eq!(
        d.message,
        "`interfaces.topics.emits` names observer slot `watch`"
    );
}

#[test]
fn an_observer_slot_must_be_consumed() {
    let text = doc(OBSERVER, "");
    let errors = node_err(&text);
    let d = only(&errors, Code::ObserverLinkNeverConsumed);
    assert_at(
        d,
        Code::ObserverLinkNeverConsumed,
        "manifest.depends_on.pairing_observers[0]",
        &text,
        r#"{ name: "handshake""#,
    );
    assert_eq!(d.message, "observer slot `watch` is never consumed");
    assert!(help(d).contains(r#"link_id: "watch""#), "{}", help(d));
}

#[test]
fn a_node_does_not_consume_what_it_implements() {
    let text = doc(
        ARM,
        r#"topics: { emits: [{ link_id: "arm", name: "joint_states" }] },
    services: { consumes: [{ link_id: "arm", name: "get_limits" }] },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::ConsumedItemReferencesImplementsLinkId);
    assert_at(
        d,
        Code::ConsumedItemReferencesImplementsLinkId,
        "interfaces.services.consumes[0]",
        &text,
        r#"{ link_id: "arm", name: "get_limits" }"#,
    );
    assert_eq!(
        d.message,
        "consumed service names `arm`, an `implements` slot"
    );
}

#[test]
fn services_and_actions_are_not_consumed_through_pairings() {
    let text = doc(
        r#"depends_on: { pairings: [{ name: "handshake", tag: "v1", role: "follower", link_id: "peer" }] },"#,
        r#"topics: { consumes: [{ link_id: "peer", name: "ping" }] },
    actions: { consumes: [{ link_id: "peer", name: "align" }] },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::ConsumedItemReferencesPairingLinkId);
    assert_at(
        d,
        Code::ConsumedItemReferencesPairingLinkId,
        "interfaces.actions.consumes[0]",
        &text,
        r#"{ link_id: "peer", name: "align" }"#,
    );
    assert_eq!(d.message, "consumed action names pairing slot `peer`");
}

#[test]
fn refine_is_not_for_node_slots() {
    let text = doc(
        r#"depends_on: { nodes: [{ name: "lidar", tag: "v1", link_id: "lidar" }] },"#,
        r#"topics: { consumes: [{ link_id: "lidar", name: "scan", refine: { message_format: { ranges: { $length: 360 } } } }] },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::RefineOnNodeSlot);
    assert_at(
        d,
        Code::RefineOnNodeSlot,
        "interfaces.topics.consumes[0].refine",
        &text,
        "{ message_format: { ranges",
    );
    assert_eq!(
        d.message,
        "`refine` on `scan`, consumed through node slot `lidar`"
    );
}

#[test]
fn pairing_slot_keys_by_family() {
    // A participant has no cardinality, an observer no `optional`.
    let text = doc(
        r#"depends_on: {
      pairings: [{ name: "handshake", tag: "v1", role: "leader", link_id: "peer", cardinality: "one" }],
      pairing_observers: [{ name: "handshake", tag: "v1", role: "leader", link_id: "watch", optional: true }],
    },"#,
        "",
    );
    let errors = node_err(&text);
    assert_eq!(
        error_codes(&errors),
        [Code::CardinalityOnPairingSlot, Code::OptionalOnObserverSlot],
        "{errors}"
    );
    let d = one(&errors, Code::CardinalityOnPairingSlot);
    assert_at(
        d,
        Code::CardinalityOnPairingSlot,
        "manifest.depends_on.pairings[0].cardinality",
        &text,
        "cardinality",
    );
    assert_eq!(d.message, "`cardinality` is not a key of a pairing slot");
    assert!(help(d).contains("optional: true"), "{}", help(d));
    let d = one(&errors, Code::OptionalOnObserverSlot);
    assert_at(
        d,
        Code::OptionalOnObserverSlot,
        "manifest.depends_on.pairing_observers[0].optional",
        &text,
        "optional",
    );
    assert_eq!(
        d.message,
        "`optional` is not a key of a pairing observer slot"
    );
    assert!(help(d).contains("zero_or_one"), "{}", help(d));
}

#[test]
fn a_pairing_slot_names_its_role() {
    let text = doc(
        r#"depends_on: { pairings: [{ name: "handshake", tag: "v1", link_id: "peer" }] },"#,
        "",
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::PairingSlotMissingRole);
    assert_at(
        d,
        Code::PairingSlotMissingRole,
        "manifest.depends_on.pairings[0]",
        &text,
        r#"{ name: "handshake""#,
    );
    assert_eq!(
        d.message,
        "`manifest.depends_on.pairings[0]` names no `role`"
    );
    assert!(help(d).contains("role it plays"), "{}", help(d));
}

#[test]
fn pairing_link_ids_are_not_link_target_sentinels() {
    for id in ["_", "*", "**", "a/b", "a@b"] {
        let text = doc(
            &format!(
                r#"depends_on: {{ pairing_observers: [{{ name: "handshake", tag: "v1", role: "leader", link_id: "{id}" }}] }},"#
            ),
            "",
        );
        let errors = node_err(&text);
        let d = only(&errors, Code::PairingSentinelLinkId);
        assert_at(
            d,
            Code::PairingSentinelLinkId,
            "manifest.depends_on.pairing_observers[0].link_id",
            &text,
            &format!("\"{id}\""),
        );
        assert_eq!(
            d.message,
            format!("link_id `{id}` is reserved in link targets (`/`, `@`, `*`, `**`, `_`)")
        );
    }
    // Producer slots keep the general link_id rule.
    let text = doc(
        r#"depends_on: { contracts: [{ name: "cam", tag: "v1", link_id: "a/b" }] },"#,
        "",
    );
    let errors = node_err(&text);
    assert_eq!(error_codes(&errors), [Code::InvalidName], "{errors}");
}

/// A contract-slot consumer with `refine`.
fn refined(refine: &str) -> String {
    doc(
        r#"depends_on: { contracts: [{ name: "lidar", tag: "v1", link_id: "lidar" }] },"#,
        &format!(
            r#"topics: {{ consumes: [{{ link_id: "lidar", name: "scan", refine: {refine} }}] }},"#
        ),
    )
}

#[test]
fn a_refine_block_has_one_of_the_refinement_forms() {
    // Empty.
    let text = refined("{}");
    let errors = node_err(&text);
    let d = only(&errors, Code::InvalidRefine);
    assert_at(
        d,
        Code::InvalidRefine,
        "interfaces.topics.consumes[0].refine",
        &text,
        "{} }",
    );
    assert_eq!(d.message, "`interfaces.topics.consumes[0].refine` is empty");

    // `$length` at the root of a format.
    let text = refined("{ message_format: { $length: 3 } }");
    let errors = node_err(&text);
    let d = only(&errors, Code::InvalidRefine);
    assert_at(
        d,
        Code::InvalidRefine,
        "interfaces.topics.consumes[0].refine.message_format.$length",
        &text,
        "$length",
    );
    assert_eq!(
        d.message,
        "`$length` cannot stand at the level of `interfaces.topics.consumes[0].refine.message_format`"
    );

    // Mixed forms in one field.
    let text = refined("{ message_format: { ranges: { $length: 3, min: { $length: 1 } } } }");
    let errors = node_err(&text);
    let d = only(&errors, Code::InvalidRefine);
    assert_at(
        d,
        Code::InvalidRefine,
        "interfaces.topics.consumes[0].refine.message_format.ranges",
        &text,
        "{ $length: 3,",
    );
    assert_eq!(
        d.message,
        "`interfaces.topics.consumes[0].refine.message_format.ranges` mixes refinement forms"
    );

    // An unknown `$` key.
    let text = refined("{ message_format: { ranges: { $size: 3 } } }");
    let errors = node_err(&text);
    let d = only(&errors, Code::InvalidRefine);
    assert_at(
        d,
        Code::InvalidRefine,
        "interfaces.topics.consumes[0].refine.message_format.ranges.$size",
        &text,
        "$size",
    );
    assert_eq!(d.message, "unknown refinement `$size`");
    assert_eq!(help(d), "a refinement is `$length` or `$items`");
}

#[test]
fn a_consumed_entry_names_a_declared_slot() {
    let text = doc(
        r#"depends_on: { contracts: [{ name: "cam", tag: "v1", link_id: "camera" }] },"#,
        r#"topics: { consumes: [{ link_id: "camra", name: "frame" }] },"#,
    );
    let errors = node_err(&text);
    let d = only(&errors, Code::UndeclaredLinkId);
    assert_at(
        d,
        Code::UndeclaredLinkId,
        "interfaces.topics.consumes[0]",
        &text,
        r#"{ link_id: "camra""#,
    );
    assert_eq!(
        d.message,
        "consumed topic uses link_id `camra`, which `manifest.depends_on` does not declare"
    );
    assert!(help(d).starts_with("did you mean `camera`?"), "{}", help(d));
}
