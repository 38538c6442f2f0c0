//! SPEC 3: resolving one node against repositories.

use std::path::PathBuf;

use peppy_schema::{
    Code, Identity, NodeCheck, Origin, QosProfile, SlotKind, SlotRef, check_node, sha256_hex,
};

use crate::support::*;

const CAM_IFACE: &str = r#"{
  peppy_schema: "interface_v1",
  manifest: { name: "cam", tag: "v1" },
  interfaces: {
    topics: [{ name: "frame", qos_profile: "sensor_data", message_format: { width: "u32", data: "bytes" } }],
    services: [{ name: "info", response_message_format: { fps: "u8" } }],
    actions: [{ name: "calibrate", goal_service: { request_message_format: { passes: "u8" } } }],
  },
}
"#;

/// A repository with the `cam:v1` interface and a producer that conforms to
/// it and also emits a native `frame` of another shape.
fn repo() -> Tree {
    let tree = Tree::new();
    tree.write("repo/interfaces/cam.json5", CAM_IFACE);
    tree.write(
        "repo/nodes/producer/peppy.json5",
        &node_text(
            "producer",
            "",
            r#"conforms_to: [{ name: "cam", tag: "v1" }],
    topics: { emits: [
      { name: "frame", qos_profile: "reliable", message_format: { native: "u8" } },
      { name: "status", message_format: { ok: "bool" } },
    ] },
    services: { exposes: [{ name: "reset" }] }"#,
            "",
        ),
    );
    tree
}

fn check(tree: &Tree, rel: &str) -> NodeCheck {
    match check_node(&tree.path(rel), &options(vec![tree.path("repo")])) {
        Ok(c) => c,
        Err(e) => panic!("expected `{rel}` to resolve, got:\n{e}"),
    }
}

fn check_err(tree: &Tree, rel: &str) -> peppy_schema::Diagnostics {
    match check_node(&tree.path(rel), &options(vec![tree.path("repo")])) {
        Ok(_) => panic!("expected `{rel}` to fail"),
        Err(e) => e,
    }
}

fn cam() -> Identity {
    Identity::new("cam", "v1")
}

#[test]
fn conformed_entries_are_provided_with_the_interface_origin() {
    let tree = repo();
    let c = check(&tree, "repo/nodes/producer");
    assert!(c.warnings.is_empty(), "{}", c.warnings);
    let r = &c.resolved;
    let own = Origin::Node(Identity::new("producer", "v1"));
    let topics: Vec<(&str, &Origin, QosProfile)> = r
        .emitted_topics
        .iter()
        .map(|p| (p.decl.name.as_str(), &p.origin, p.decl.qos))
        .collect();
    // Own entries first, then the interface's; equal names are two streams.
    assert_eq!(
        topics,
        [
            ("frame", &own, QosProfile::Reliable),
            ("status", &own, QosProfile::Standard),
            ("frame", &Origin::Interface(cam()), QosProfile::SensorData),
        ]
    );
    let services: Vec<(&str, &Origin)> = r
        .exposed_services
        .iter()
        .map(|p| (p.decl.name.as_str(), &p.origin))
        .collect();
    assert_eq!(
        services,
        [("reset", &own), ("info", &Origin::Interface(cam()))]
    );
    assert_eq!(r.exposed_actions.len(), 1);
    assert_eq!(r.exposed_actions[0].origin, Origin::Interface(cam()));
    assert_eq!(r.conformed.len(), 1);
    assert_eq!(r.conformed[0].doc.identity, cam());
    assert_eq!(r.conformed[0].path, tree.path("repo/interfaces/cam.json5"));
    assert_eq!(
        r.files,
        [
            tree.path("repo/interfaces/cam.json5"),
            tree.path("repo/nodes/producer/peppy.json5")
        ]
    );
    assert_eq!(c.repositories.paths, [tree.path("repo")]);
}

#[test]
fn a_node_slot_sees_native_and_inherited_entries_native_winning() {
    let tree = repo();
    tree.write(
        "consumer/peppy.json5",
        &node_text(
            "consumer",
            r#"nodes: [{ name: "producer", tag: "v1", link_id: "prod" }]"#,
            r#"topics: { consumes: [{ link_id: "prod", name: "frame" }, { link_id: "prod", name: "status" }] },
    services: { consumes: [{ link_id: "prod", name: "info" }, { link_id: "prod", name: "reset" }] },
    actions: { consumes: [{ link_id: "prod", name: "calibrate" }] }"#,
            "",
        ),
    );
    let c = check(&tree, "consumer/peppy.json5");
    let r = &c.resolved;
    let slot = SlotRef {
        link_id: "prod".into(),
        kind: SlotKind::Node,
        target: Identity::new("producer", "v1"),
        from_any: false,
    };
    let native = Origin::Node(Identity::new("producer", "v1"));

    let frame = &r.consumed_topics[0];
    assert_eq!(frame.slot.as_ref(), Some(&slot));
    assert_eq!(
        frame.origin.as_ref(),
        Some(&native),
        "the native `frame` wins over the conformed one"
    );
    assert_eq!(frame.format.as_ref().unwrap().canonical(), "{native:u8}");
    assert_eq!(frame.qos, QosProfile::Reliable);
    assert_eq!(r.consumed_topics[1].origin.as_ref(), Some(&native));

    let calls: Vec<(&str, &Origin)> = r
        .consumed_services
        .iter()
        .map(|s| (s.decl.name.as_str(), &s.origin))
        .collect();
    assert_eq!(
        calls,
        [("info", &Origin::Interface(cam())), ("reset", &native)]
    );
    assert_eq!(
        r.consumed_services[0]
            .decl
            .response
            .as_ref()
            .unwrap()
            .canonical(),
        "{fps:u8}"
    );
    assert_eq!(r.consumed_actions[0].origin, Origin::Interface(cam()));
    assert_eq!(
        r.consumed_actions[0]
            .decl
            .goal
            .as_ref()
            .unwrap()
            .canonical(),
        "{passes:u8}"
    );
    // Every file read: the consumer, its producer, the producer's interface.
    assert_eq!(
        r.files,
        [
            tree.path("consumer/peppy.json5"),
            tree.path("repo/interfaces/cam.json5"),
            tree.path("repo/nodes/producer/peppy.json5"),
        ]
    );
}

#[test]
fn an_interface_slot_and_an_external_topic() {
    let tree = repo();
    tree.write(
        "consumer/peppy.json5",
        &node_text(
            "consumer",
            r#"interfaces: [{ name: "cam", tag: "v1", link_id: "cams", from_any: true }]"#,
            r#"topics: { consumes: [
      { link_id: "cams", name: "frame" },
      { name: "weather", message_format: { temp: "f32" } },
    ] },
    services: { consumes: [{ link_id: "cams", name: "info" }] }"#,
            "",
        ),
    );
    let r = check(&tree, "consumer").resolved;
    let frame = &r.consumed_topics[0];
    assert_eq!(
        frame.slot.as_ref(),
        Some(&SlotRef {
            link_id: "cams".into(),
            kind: SlotKind::Interface,
            target: cam(),
            from_any: true
        })
    );
    assert_eq!(frame.origin.as_ref(), Some(&Origin::Interface(cam())));
    assert_eq!(
        frame.format.as_ref().unwrap().canonical(),
        "{width:u32,data:bytes}"
    );
    assert_eq!(frame.qos, QosProfile::SensorData);

    let weather = &r.consumed_topics[1];
    assert!(weather.slot.is_none() && weather.origin.is_none());
    assert_eq!(weather.format.as_ref().unwrap().canonical(), "{temp:f32}");
    assert_eq!(weather.qos, QosProfile::Standard);
    assert_eq!(weather.loc.key_path, "interfaces.topics.consumes[1]");

    assert_eq!(r.consumed_services[0].origin, Origin::Interface(cam()));
    assert_eq!(
        r.files,
        [
            tree.path("consumer/peppy.json5"),
            tree.path("repo/interfaces/cam.json5")
        ]
    );
}

#[test]
fn dependency_not_found_lists_the_repositories_searched() {
    let tree = repo();
    let text = node_text(
        "consumer",
        r#"nodes: [{ name: "ghost", tag: "v1", link_id: "g" }],
      interfaces: [{ name: "cam", tag: "v2", link_id: "c" }]"#,
        r#"conforms_to: [{ name: "lidar", tag: "v1" }],
    topics: { consumes: [{ link_id: "g", name: "x" }, { link_id: "c", name: "frame" }] }"#,
        "",
    );
    tree.write("consumer/peppy.json5", &text);
    let errors = check_err(&tree, "consumer");
    let found = all(&errors, Code::DependencyNotFound);
    assert_eq!(errors.len(), 3, "{errors}");
    let searched = format!("searched `{}`", tree.path("repo").display());
    assert_at(
        found[0],
        Code::DependencyNotFound,
        "manifest.depends_on.nodes[0]",
        &text,
        r#"{ name: "ghost""#,
    );
    assert_eq!(found[0].message, "no repository provides node `ghost:v1`");
    assert_eq!(help(found[0]), searched);
    assert_at(
        found[1],
        Code::DependencyNotFound,
        "manifest.depends_on.interfaces[0]",
        &text,
        r#"{ name: "cam""#,
    );
    assert_eq!(
        found[1].message,
        "no repository provides interface `cam:v2`"
    );
    assert_eq!(help(found[1]), format!("did you mean `cam:v1`? {searched}"));
    assert_at(
        found[2],
        Code::DependencyNotFound,
        "interfaces.conforms_to[0]",
        &text,
        r#"{ name: "lidar""#,
    );
    assert!(help(found[2]).contains(&tree.path("repo").display().to_string()));
}

#[test]
fn no_repositories_at_all_says_how_to_configure_them() {
    let tree = Tree::new();
    let path = tree.write(
        "consumer/peppy.json5",
        &node_text(
            "consumer",
            r#"nodes: [{ name: "ghost", tag: "v1", link_id: "g" }]"#,
            "",
            "",
        ),
    );
    let errors = check_node(&path, &options(Vec::new())).unwrap_err();
    let d = one(&errors, Code::DependencyNotFound);
    assert!(help(d).contains("no repositories are configured"), "{d}");
    assert!(help(d).contains("PEPPY_REPOSITORIES"), "{d}");
}

#[test]
fn missing_on_producer_names_what_it_offers() {
    let tree = repo();
    let text = node_text(
        "consumer",
        r#"nodes: [{ name: "producer", tag: "v1", link_id: "prod" }],
      interfaces: [{ name: "cam", tag: "v1", link_id: "cams" }]"#,
        r#"topics: { consumes: [{ link_id: "prod", name: "frames" }, { link_id: "cams", name: "status" }] },
    services: { consumes: [{ link_id: "prod", name: "calibrate" }] },
    actions: { consumes: [{ link_id: "cams", name: "info" }] }"#,
        "",
    );
    tree.write("consumer/peppy.json5", &text);
    let errors = check_err(&tree, "consumer");
    let found = all(&errors, Code::MissingOnProducer);
    assert_eq!(errors.len(), 4, "{errors}");
    assert_at(
        found[0],
        Code::MissingOnProducer,
        "interfaces.topics.consumes[0]",
        &text,
        r#"{ link_id: "prod", name: "frames" }"#,
    );
    assert_eq!(
        found[0].message,
        "slot `prod` (node `producer:v1`) has no topic `frames`"
    );
    assert_eq!(
        help(found[0]),
        "did you mean `frame`? node `producer:v1` offers topics: `frame`, `status`"
    );
    assert_eq!(
        found[1].message,
        "slot `cams` (interface `cam:v1`) has no topic `status`"
    );
    assert_eq!(help(found[1]), "interface `cam:v1` offers topics: `frame`");
    assert_eq!(
        found[2].message,
        "slot `prod` (node `producer:v1`) has no service `calibrate`"
    );
    assert_eq!(
        help(found[2]),
        "node `producer:v1` offers services: `reset`, `info`"
    );
    assert_eq!(
        found[3].message,
        "slot `cams` (interface `cam:v1`) has no action `info`"
    );
    assert_eq!(
        help(found[3]),
        "interface `cam:v1` offers actions: `calibrate`"
    );
}

fn pinned_consumer(pin: &str) -> String {
    node_text(
        "consumer",
        &format!(r#"interfaces: [{{ name: "cam", tag: "v1", link_id: "cams", sha256: "{pin}" }}]"#),
        r#"topics: { consumes: [{ link_id: "cams", name: "frame" }] }"#,
        "",
    )
}

#[test]
fn sha256_pins_are_checked_on_each_side() {
    let tree = repo();
    let pin = sha256_hex(CAM_IFACE.as_bytes());
    tree.write(
        "repo/nodes/pinned_producer/peppy.json5",
        &node_text(
            "pinned_producer",
            "",
            &format!(r#"conforms_to: [{{ name: "cam", tag: "v1", sha256: "{pin}" }}]"#),
            "",
        ),
    );
    let consumer_text = pinned_consumer(&pin);
    tree.write("consumer/peppy.json5", &consumer_text);
    check(&tree, "repo/nodes/pinned_producer");
    let c = check(&tree, "consumer");
    assert_eq!(
        c.resolved.consumed_topics[0]
            .format
            .as_ref()
            .unwrap()
            .canonical(),
        "{width:u32,data:bytes}"
    );

    // Any change to the document's bytes (even a comment) breaks both pins.
    let changed = format!("// reviewed\n{CAM_IFACE}");
    tree.write("repo/interfaces/cam.json5", &changed);
    let actual = sha256_hex(changed.as_bytes());
    let iface_path = tree.path("repo/interfaces/cam.json5");

    let errors = check_err(&tree, "consumer");
    let d = one(&errors, Code::InterfacePinMismatch);
    assert_eq!(errors.len(), 1, "{errors}");
    assert_at(
        d,
        Code::InterfacePinMismatch,
        "manifest.depends_on.interfaces[0]",
        &consumer_text,
        r#"{ name: "cam""#,
    );
    assert_eq!(
        d.message,
        format!(
            "this node depends on `cam:v1` pinned to sha256 `{pin}`, but the interface document has sha256 `{actual}` in `{}`",
            iface_path.display()
        )
    );
    assert!(help(d).contains(&format!("sha256: \"{actual}\"")), "{d}");

    let errors = check_err(&tree, "repo/nodes/pinned_producer");
    let d = one(&errors, Code::InterfacePinMismatch);
    assert_eq!(key(d), "interfaces.conforms_to[0]");
    assert!(
        d.message.starts_with(&format!(
            "this node conforms to `cam:v1` pinned to sha256 `{pin}`"
        )),
        "{d}"
    );

    // The sides are not cross-checked: an unpinned consumer of the stale
    // producer still resolves.
    tree.write(
        "consumer2/peppy.json5",
        &node_text(
            "consumer2",
            r#"nodes: [{ name: "pinned_producer", tag: "v1", link_id: "p" }]"#,
            r#"topics: { consumes: [{ link_id: "p", name: "frame" }] }"#,
            "",
        ),
    );
    let r = check(&tree, "consumer2").resolved;
    assert_eq!(r.consumed_topics[0].origin, Some(Origin::Interface(cam())));
}

#[test]
fn a_pin_selects_among_copies_in_several_repositories() {
    let tree = repo();
    let other = CAM_IFACE.replace("data: \"bytes\"", "data: \"bytes\", depth: \"u16\"");
    tree.write("repo2/cam.json5", &other);
    tree.write(
        "consumer/peppy.json5",
        &pinned_consumer(&sha256_hex(other.as_bytes())),
    );
    let c = check_node(
        &tree.path("consumer"),
        &options(vec![tree.path("repo"), tree.path("repo2")]),
    )
    .unwrap();
    let topic = &c.resolved.consumed_topics[0];
    assert_eq!(
        topic.format.as_ref().unwrap().canonical(),
        "{width:u32,data:bytes,depth:u16}"
    );
    let files: Vec<PathBuf> = c.resolved.files.clone();
    assert!(
        files.contains(&tree.path("repo2/cam.json5"))
            && !files.contains(&tree.path("repo/interfaces/cam.json5"))
    );
}

#[test]
fn conformance_is_explicit() {
    let tree = repo();
    // Named like the interface, same topic, no conforms_to: it provides only its own entries.
    tree.write(
        "repo/nodes/lookalike/peppy.json5",
        &node_text("cam", "", r#"topics: { emits: [{ name: "frame", message_format: { width: "u32", data: "bytes" } }] }"#, ""),
    );
    let r = check(&tree, "repo/nodes/lookalike").resolved;
    assert!(r.conformed.is_empty());
    assert_eq!(r.emitted_topics.len(), 1);
    assert_eq!(r.emitted_topics[0].origin, Origin::Node(cam()));
}

/// A node that hears peers of its own kind (`node init`'s greeter, a
/// swarm) is its own producer: it resolves where no repository lists it.
#[test]
fn a_node_that_hears_its_own_kind_needs_no_repository() {
    let tree = Tree::new();
    tree.write(
        "swarm/peppy.json5",
        r#"{
  peppy_schema: "node/v1",
  manifest: {
    name: "swarm", tag: "v1",
    depends_on: { nodes: [{ name: "swarm", tag: "v1", link_id: "peers", cardinality: "zero_or_more" }] },
  },
  interfaces: {
    topics: {
      emits: [{ name: "hello", message_format: { n: "u32" } }],
      consumes: [{ link_id: "peers", name: "hello" }],
    },
  },
  execution: { language: "rust", build_cmd: ["cargo", "build"] },
}"#,
    );
    let check = check_node(&tree.path("swarm"), &options(Vec::new())).unwrap();
    let consumed = &check.resolved.consumed_topics;
    assert_eq!(consumed.len(), 1);
    assert_eq!(consumed[0].name, "hello");
    // The peer's format is its own emitted one.
    assert_eq!(
        consumed[0].format,
        check.resolved.emitted_topics[0].decl.format
    );
}
