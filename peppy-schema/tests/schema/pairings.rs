//! `pairing/v1` documents: two roles and the topics between them,
//! each topic read with a contract's topic grammar plus `emitted_by`.

use peppy_schema::{
    Code, Diagnostics, Document, DocumentKind, Identity, InterfaceDoc, PairingDoc, QosProfile,
    RepoIndex, SourceFile, parse_document, sha256_hex,
};

use crate::support::*;

/// A two-way control link, shaped like the hubs' `joint_link`: each role
/// emits one stream, formats with arrays (fixed and generic) and labels.
const JOINT_LINK: &str = r#"// The leader streams setpoints, the follower its measured state.
{
  peppy_schema: "pairing/v1",
  manifest: { name: "joint_link", tag: "v1", labels: ["control"] },
  roles: ["leader", "follower"],
  topics: [
    {
      emitted_by: "leader",
      name: "joint_setpoints",
      qos_profile: "sensor_data",
      message_format: {
        timestamp: "time",
        positions: { $type: "array", $items: "f64" },
        pose: { $type: "array", $items: "f64", $length: 7 },
      },
    },
    {
      emitted_by: "follower",
      name: "joint_states",
      qos_profile: "reliable",
      message_format: { timestamp: "time", positions: { $type: "array", $items: "f64" } },
    },
  ],
}
"#;

/// A one-directional pair, shaped like the hubs' `sim_rgb_camera_link`: the
/// viewer emits nothing; a nested object header; one topic with the default
/// QoS and one without a payload.
const CAMERA_LINK: &str = r#"{
  peppy_schema: "pairing/v1",
  manifest: { name: "camera_link", tag: "v1" },
  roles: ["camera", "viewer"],
  topics: [
    {
      emitted_by: "camera",
      name: "video_stream",
      qos_profile: "sensor_data",
      message_format: {
        header: { $type: "object", timestamp: "time", frame_id: "u32" },
        encoding: "string",
        frame: { $type: "array", $items: "u8" },
      },
    },
    { emitted_by: "camera", name: "stream_info", message_format: { width: "u32", height: "u32" } },
    { emitted_by: "camera", name: "tick" },
  ],
}
"#;

fn parse(text: &str) -> peppy_schema::Parsed<PairingDoc> {
    PairingDoc::parse("link.json5", text)
}

/// All findings of a pairing that must be invalid.
fn errors(text: &str) -> Diagnostics {
    match parse(text) {
        Ok(_) => panic!("expected errors, the pairing was accepted:\n{text}"),
        Err(e) => e,
    }
}

/// A pairing with `roles` and `topics` spliced in.
fn pairing(roles: &str, topics: &str) -> String {
    format!(
        r#"{{
  peppy_schema: "pairing/v1",
  manifest: {{ name: "link", tag: "v1" }},
  roles: {roles},
  topics: {topics},
}}"#
    )
}

/// One topic emitted by `leader`.
const ONE_TOPIC: &str = r#"[{ emitted_by: "leader", name: "t" }]"#;

#[test]
fn a_pairing_is_read_with_its_roles_and_topics() {
    let (doc, warnings) = parse(JOINT_LINK).unwrap_or_else(|e| panic!("{e}"));
    assert!(warnings.is_empty(), "{warnings}");
    assert_eq!(doc.identity, Identity::new("joint_link", "v1"));
    assert_eq!(doc.labels, ["control"]);
    assert_eq!(doc.role_names(), ["leader", "follower"]);
    assert_eq!(doc.counterpart("leader"), Some("follower"));
    assert_eq!(doc.counterpart("follower"), Some("leader"));
    assert_eq!(doc.counterpart("ghost"), None);
    assert_eq!(lc_of(&doc.name_loc), pos(JOINT_LINK, r#""joint_link""#));
    assert_eq!(lc_of(&doc.roles[1].loc), pos(JOINT_LINK, r#""follower""#));

    let names: Vec<(&str, &str, QosProfile)> = doc
        .topics
        .iter()
        .map(|t| (t.emitted_by.as_str(), t.decl.name.as_str(), t.decl.qos))
        .collect();
    assert_eq!(
        names,
        [
            ("leader", "joint_setpoints", QosProfile::SensorData),
            ("follower", "joint_states", QosProfile::Reliable),
        ]
    );
    let setpoints = doc.topic("joint_setpoints").unwrap();
    // The contract grammar: aliases resolved, order kept, fixed lengths.
    assert_eq!(
        setpoints.decl.format.as_ref().unwrap().canonical(),
        "{timestamp:time,positions:[f64],pose:[f64;7]}"
    );
    assert_eq!(
        lc_of(&setpoints.decl.loc),
        pos(JOINT_LINK, r#""joint_setpoints""#)
    );
    assert_eq!(
        lc_of(&doc.topics[1].emitted_by_loc),
        pos_nth(JOINT_LINK, r#""follower""#, 1)
    );
    let emitted: Vec<&str> = doc
        .emitted_by("follower")
        .map(|t| t.decl.name.as_str())
        .collect();
    assert_eq!(emitted, ["joint_states"]);
    // The revision is the sha256 of the file's bytes, as for a contract.
    assert_eq!(doc.sha256, sha256_hex(JOINT_LINK.as_bytes()));

    // The kind comes from `peppy_schema`, not the file name.
    let (any, _) = parse_document(&SourceFile::new("x.json5", JOINT_LINK), &doc.sha256).unwrap();
    assert!(matches!(any, Document::Pairing(_)));
    assert_eq!(any.kind(), DocumentKind::Pairing);
    assert_eq!(any.kind().as_str(), "pairing");
}

#[test]
fn a_role_may_emit_nothing_and_qos_defaults_to_standard() {
    let (doc, _) = parse(CAMERA_LINK).unwrap_or_else(|e| panic!("{e}"));
    assert!(doc.labels.is_empty());
    assert_eq!(doc.emitted_by("viewer").count(), 0);
    assert_eq!(doc.emitted_by("camera").count(), 3);
    let info = doc.topic("stream_info").unwrap();
    assert_eq!(info.decl.qos, QosProfile::Standard);
    assert_eq!(
        doc.topic("video_stream")
            .unwrap()
            .decl
            .format
            .as_ref()
            .unwrap()
            .canonical(),
        "{header:{timestamp:time,frame_id:u32},encoding:string,frame:[u8]}"
    );
    // No `message_format`: a message with no payload.
    assert!(doc.topic("tick").unwrap().decl.format.is_none());
}

#[test]
fn the_manifest_follows_the_contract_rules() {
    let text = r#"{
  peppy_schema: "pairing/v1",
  manifest: { name: "arm.link", tag: "1.0", depends_on: {}, implements: [] },
  roles: ["a", "b"],
  topics: [{ emitted_by: "a", name: "t" }],
}"#;
    let e = errors(text);
    assert_eq!(
        error_codes(&e),
        [
            Code::InvalidName,
            Code::InvalidTag,
            Code::UnknownKey,
            Code::UnknownKey
        ],
        "{e}"
    );
    let name = one(&e, Code::InvalidName);
    assert_at(
        name,
        Code::InvalidName,
        "manifest.name",
        text,
        r#""arm.link""#,
    );
    assert_eq!(
        name.message,
        "invalid `manifest.name` `arm.link`: contains '.'; allowed: ASCII letters, digits, `_` and `-`"
    );
    let tag = one(&e, Code::InvalidTag);
    assert_at(tag, Code::InvalidTag, "manifest.tag", text, r#""1.0""#);
    assert!(
        tag.message
            .starts_with("invalid `manifest.tag` `1.0`: must start with an ASCII letter"),
        "{tag}"
    );
    let unknown = all(&e, Code::UnknownKey);
    assert_at(
        unknown[0],
        Code::UnknownKey,
        "manifest.depends_on",
        text,
        "depends_on",
    );
    assert_eq!(unknown[0].message, "unknown key `depends_on` in `manifest`");
    assert_at(
        unknown[1],
        Code::UnknownKey,
        "manifest.implements",
        text,
        "implements",
    );

    let text = r#"{ peppy_schema: "pairing/v1", roles: ["a", "b"], topics: [{ emitted_by: "a", name: "t" }] }"#;
    let missing = errors(text);
    let d = one(&missing, Code::MissingKey);
    assert_eq!(
        d.message,
        "missing required key `manifest` at the top level"
    );
    assert_eq!(lc(d), (1, 1));
}

#[test]
fn roles_are_required() {
    let text = r#"{
  peppy_schema: "pairing/v1",
  manifest: { name: "link", tag: "v1" },
  topics: [{ emitted_by: "a", name: "t" }],
}"#;
    let e = errors(text);
    assert_eq!(error_codes(&e), [Code::MissingKey], "{e}");
    let d = one(&e, Code::MissingKey);
    assert_eq!(d.message, "missing required key `roles` at the top level");
    assert_eq!(lc(d), (1, 1));
}

#[test]
fn exactly_two_roles() {
    for (roles, found) in [
        (r#"["leader"]"#, 1),
        (r#"["leader", "follower", "observer"]"#, 3),
        ("[]", 0),
    ] {
        let text = pairing(roles, ONE_TOPIC);
        let e = errors(&text);
        assert_eq!(error_codes(&e), [Code::PairingRoleCount], "{e}");
        let d = one(&e, Code::PairingRoleCount);
        assert_at(d, Code::PairingRoleCount, "roles", &text, roles);
        assert_eq!(
            d.message,
            format!("a pairing declares exactly two roles, found {found}")
        );
        assert!(help(d).contains(r#"roles: ["leader", "follower"]"#), "{d}");
    }
}

#[test]
fn roles_are_distinct() {
    let text = pairing(r#"["leader", "leader"]"#, ONE_TOPIC);
    let e = errors(&text);
    assert_eq!(error_codes(&e), [Code::DuplicateRole], "{e}");
    let d = one(&e, Code::DuplicateRole);
    let (line, column) = pos(&text, r#""leader""#);
    assert_eq!(key(d), "roles[1]");
    assert_eq!(lc(d), pos_nth(&text, r#""leader""#, 1));
    assert_eq!(d.message, "duplicate role `leader`");
    assert_eq!(
        help(d),
        format!(
            "`leader` is already the role at line {line}, column {column}; a pairing's two roles are distinct"
        )
    );
}

#[test]
fn the_role_underscore_is_reserved() {
    let text = pairing(r#"["leader", "_"]"#, ONE_TOPIC);
    let e = errors(&text);
    assert_eq!(error_codes(&e), [Code::ReservedRole], "{e}");
    let d = one(&e, Code::ReservedRole);
    assert_at(d, Code::ReservedRole, "roles[1]", &text, r#""_""#);
    assert_eq!(d.message, "the role `_` is reserved");
    assert!(help(d).contains("reserved default link key"), "{d}");
}

#[test]
fn roles_follow_the_name_rule() {
    let text = pairing(r#"["lead er", 7]"#, ONE_TOPIC);
    let e = errors(&text);
    assert_eq!(error_codes(&e), [Code::InvalidName, Code::WrongType], "{e}");
    let d = one(&e, Code::InvalidName);
    assert_at(d, Code::InvalidName, "roles[0]", &text, r#""lead er""#);
    assert_eq!(
        d.message,
        "invalid role `lead er`: contains ' '; allowed: ASCII letters, digits, `_` and `-`"
    );
    let d = one(&e, Code::WrongType);
    assert_at(d, Code::WrongType, "roles[1]", &text, "7]");
    assert_eq!(
        d.message,
        "expected a string for `roles[1]`, found a number"
    );
}

#[test]
fn topics_are_required_and_not_empty() {
    let text = r#"{
  peppy_schema: "pairing/v1",
  manifest: { name: "link", tag: "v1" },
  roles: ["leader", "follower"],
}"#;
    let e = errors(text);
    assert_eq!(error_codes(&e), [Code::MissingKey], "{e}");
    assert_eq!(
        one(&e, Code::MissingKey).message,
        "missing required key `topics` at the top level"
    );

    let text = pairing(r#"["leader", "follower"]"#, "[]");
    let e = errors(&text);
    assert_eq!(error_codes(&e), [Code::EmptyPairing], "{e}");
    let d = one(&e, Code::EmptyPairing);
    assert_at(d, Code::EmptyPairing, "topics", &text, "[]");
    assert_eq!(d.message, "a pairing declares no topics");
    assert!(help(d).contains("a role may emit none"), "{d}");
}

#[test]
fn emitted_by_names_one_of_the_roles() {
    let topics = r#"[
    { emitted_by: "leadr", name: "setpoints" },
    { emitted_by: "observer", name: "states" },
    { name: "orphan" },
  ]"#;
    let text = pairing(r#"["leader", "follower"]"#, topics);
    let e = errors(&text);
    assert_eq!(
        error_codes(&e),
        [Code::UnknownRole, Code::UnknownRole, Code::MissingKey],
        "{e}"
    );
    let unknown = all(&e, Code::UnknownRole);
    assert_at(
        unknown[0],
        Code::UnknownRole,
        "topics[0].emitted_by",
        &text,
        r#""leadr""#,
    );
    assert_eq!(
        unknown[0].message,
        "`emitted_by` names `leadr`, which is not one of the pairing's roles"
    );
    assert_eq!(
        help(unknown[0]),
        "did you mean `leader`? roles: `leader`, `follower`"
    );
    assert_at(
        unknown[1],
        Code::UnknownRole,
        "topics[1].emitted_by",
        &text,
        r#""observer""#,
    );
    assert_eq!(help(unknown[1]), "roles: `leader`, `follower`");
    let missing = one(&e, Code::MissingKey);
    assert_eq!(key(missing), "topics[2]");
    assert_eq!(lc(missing), pos(&text, "{ name: \"orphan\""));
    assert_eq!(
        missing.message,
        "missing required key `emitted_by` in `topics[2]`"
    );
}

#[test]
fn topic_names_are_unique_across_both_roles() {
    let topics = r#"[
    { emitted_by: "leader", name: "state" },
    { emitted_by: "follower", name: "state" },
  ]"#;
    let text = pairing(r#"["leader", "follower"]"#, topics);
    let e = errors(&text);
    assert_eq!(error_codes(&e), [Code::DuplicateEntryName], "{e}");
    let d = one(&e, Code::DuplicateEntryName);
    assert_eq!(key(d), "topics[1].name");
    assert_eq!(lc(d), pos_nth(&text, r#""state""#, 1));
    assert_eq!(d.message, "duplicate topic name `state`");
    let (line, column) = pos(&text, r#""state""#);
    assert_eq!(
        help(d),
        format!("`state` is already declared at line {line}, column {column}")
    );
}

#[test]
fn services_and_actions_are_refused_by_name() {
    let text = r#"{
  peppy_schema: "pairing/v1",
  manifest: { name: "link", tag: "v1" },
  roles: ["leader", "follower"],
  topics: [{ emitted_by: "leader", name: "t" }],
  services: [{ name: "reset" }],
  actions: [],
  extras: 1,
}"#;
    let e = errors(text);
    assert_eq!(
        error_codes(&e),
        [
            Code::PairingTopicsOnly,
            Code::PairingTopicsOnly,
            Code::UnknownKey
        ],
        "{e}"
    );
    let refused = all(&e, Code::PairingTopicsOnly);
    assert_at(
        refused[0],
        Code::PairingTopicsOnly,
        "services",
        text,
        "services",
    );
    assert_eq!(
        refused[0].message,
        "`services` in a pairing: pairings are topics-only"
    );
    assert!(help(refused[0]).contains("through a contract (`contract/v1`)"));
    assert_at(
        refused[1],
        Code::PairingTopicsOnly,
        "actions",
        text,
        "actions",
    );
    assert_eq!(
        refused[1].message,
        "`actions` in a pairing: pairings are topics-only"
    );
    // Any other unknown key is one, and `services` is not offered as accepted.
    let unknown = one(&e, Code::UnknownKey);
    assert_at(unknown, Code::UnknownKey, "extras", text, "extras");
    assert_eq!(
        help(unknown),
        "accepted keys here: `peppy_schema`, `manifest`, `roles`, `topics`"
    );
}

/// A pairing's topic is a contract's topic plus `emitted_by`: the same
/// names, QoS spellings and message-format rules (an empty format refused).
#[test]
fn topics_follow_the_contract_topic_grammar() {
    let topics = r#"[
    { emitted_by: "leader", name: "a b" },
    { emitted_by: "leader", name: "fast", qos_profile: "sensor" },
    { emitted_by: "follower", name: "empty", message_format: {} },
    { emitted_by: "follower", name: "typo", mesage_format: { x: "u8" } },
    { emitted_by: "follower", name: "bad_type", message_format: { x: "u9" } },
  ]"#;
    let text = pairing(r#"["leader", "follower"]"#, topics);
    let e = errors(&text);
    assert_eq!(
        error_codes(&e),
        [
            Code::InvalidEntryName,
            Code::InvalidValue,
            Code::EmptyMessageFormat,
            Code::UnknownKey,
            Code::UnknownType
        ],
        "{e}"
    );
    let d = one(&e, Code::InvalidEntryName);
    assert_at(
        d,
        Code::InvalidEntryName,
        "topics[0].name",
        &text,
        r#""a b""#,
    );
    assert!(d.message.starts_with("invalid topic name `a b`"), "{d}");
    let d = one(&e, Code::InvalidValue);
    assert_at(
        d,
        Code::InvalidValue,
        "topics[1].qos_profile",
        &text,
        r#""sensor""#,
    );
    assert_eq!(d.message, "unknown qos_profile `sensor`");
    assert!(help(d).starts_with("did you mean `sensor_data`?"), "{d}");
    let d = one(&e, Code::EmptyMessageFormat);
    assert_at(
        d,
        Code::EmptyMessageFormat,
        "topics[2].message_format",
        &text,
        "{} }",
    );
    assert_eq!(d.message, "message format has no fields");
    let d = one(&e, Code::UnknownKey);
    assert_at(
        d,
        Code::UnknownKey,
        "topics[3].mesage_format",
        &text,
        "mesage_format",
    );
    assert!(help(d).starts_with("did you mean `message_format`?"), "{d}");
    let d = one(&e, Code::UnknownType);
    assert_eq!(key(d), "topics[4].message_format.x");
    assert_eq!(lc(d), pos(&text, r#""u9""#));
}

#[test]
fn a_pairing_is_not_a_contract() {
    let e = InterfaceDoc::parse("link.json5", JOINT_LINK).expect_err("a pairing");
    let d = one(&e, Code::WrongDocumentKind);
    assert_at(
        d,
        Code::WrongDocumentKind,
        "peppy_schema",
        JOINT_LINK,
        r#""pairing/v1""#,
    );
    assert_eq!(
        d.message,
        "expected an interface document, found a pairing document"
    );
    let contract =
        r#"{ peppy_schema: "contract/v1", manifest: { name: "c", tag: "v1" }, interfaces: {} }"#;
    let e = errors(contract);
    assert_eq!(
        one(&e, Code::WrongDocumentKind).message,
        "expected a pairing document, found an interface document"
    );
    // A near miss of the kind is offered as `pairing/v1`.
    let text = r#"{ peppy_schema: "pairing/v2", manifest: { name: "c", tag: "v1" } }"#;
    let e = parse_document(&SourceFile::new("x.json5", text), "").expect_err("unknown");
    let d = one(&e, Code::UnknownSchema);
    assert!(help(d).starts_with("did you mean `pairing/v1`?"), "{d}");
}

/// A repository scan records pairings by identity (so a node's pairing slot
/// can resolve against one), and an invalid one as broken.
#[test]
fn a_repository_scan_indexes_pairings() {
    let tree = Tree::new();
    let good = tree.write("repo/pairings/joint.json5", JOINT_LINK);
    let broken = tree.write(
        "repo/pairings/broken.json5",
        &pairing(r#"["solo"]"#, r#"[{ emitted_by: "solo", name: "t" }]"#),
    );
    let index = RepoIndex::scan(&[tree.path("repo")]);
    let entry = index
        .pairing(&Identity::new("joint_link", "v1"))
        .expect("indexed");
    assert_eq!(entry.path, good);
    assert_eq!(entry.repository, tree.path("repo"));
    assert_eq!(entry.doc.sha256, sha256_hex(JOINT_LINK.as_bytes()));
    assert!(
        index
            .interface(&Identity::new("joint_link", "v1"))
            .is_none()
    );
    let id = Identity::new("link", "v1");
    assert!(index.pairing(&id).is_none());
    let b = index.broken(DocumentKind::Pairing, &id).expect("broken");
    assert_eq!(b.path, broken);
    assert!(b.diagnostics.contains(Code::PairingRoleCount));
}

fn lc_of(loc: &peppy_schema::Loc) -> (usize, usize) {
    let at = loc.file.line_col(loc.span.start);
    (at.line, at.column)
}
