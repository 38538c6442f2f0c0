//! `node/v1` nodes get PeppyOS's module paths: a contract's members
//! under the `implements` link_id, consumed entries under their slot's
//! link_id with the slot's bound-producer accessor; sibling modules that
//! read the same once sanitised are a located `ModuleNameCollision`.

use crate::support::{config, fixtures};

/// Every module path (`a::b::c`) and function path of the generated file.
fn paths_of(fixture: &str) -> Vec<String> {
    let generated = config(&fixtures().join(fixture))
        .generate()
        .unwrap_or_else(|e| panic!("{e}"));
    let file: syn::File = syn::parse2(generated.tokens).expect("a Rust file");
    let mut out = Vec::new();
    walk(&file.items, "", &mut out);
    out
}

fn walk(items: &[syn::Item], prefix: &str, out: &mut Vec<String>) {
    for item in items {
        match item {
            syn::Item::Mod(m) => {
                let path = format!("{prefix}{}", m.ident);
                out.push(path.clone());
                if let Some((_, inner)) = &m.content {
                    walk(inner, &format!("{path}::"), out);
                }
            }
            syn::Item::Fn(f) => out.push(format!("{prefix}{}()", f.sig.ident)),
            syn::Item::Use(u) => {
                let mut tree = &u.tree;
                while let syn::UseTree::Path(p) = tree {
                    tree = &p.tree;
                }
                if let syn::UseTree::Name(n) = tree {
                    out.push(format!("{prefix}{}", n.ident));
                }
            }
            _ => {}
        }
    }
}

fn has(paths: &[String], path: &str) -> bool {
    paths.iter().any(|p| p == path)
}

#[test]
fn an_implementer_nests_contract_members_under_its_link_id() {
    let paths = paths_of("gripper_driver");
    for p in [
        "emitted_topics::status::emit()",
        "emitted_topics::hand::joint_state::emit()",
        "exposed_services::hand::set_force::handle_next_request()",
        "exposed_actions::hand::grasp",
    ] {
        assert!(has(&paths, p), "{p} missing from {paths:#?}");
    }
    // No `node_v1`-style `<interface>::<tag>` nesting and no flat aliases.
    assert!(
        !paths.iter().any(|p| p.contains("gripper::v1")),
        "{paths:#?}"
    );
    assert!(!has(&paths, "emitted_topics::joint_state"), "{paths:#?}");
}

#[test]
fn a_consumer_nests_by_slot_with_typed_bound_producers() {
    let paths = paths_of("grasp_planner");
    for p in [
        "consumed_topics::main_hand::joint_state::on_next_message_received()",
        "consumed_topics::main_hand::bound_producer()",
        "consumed_topics::spare_hands::joint_state::on_next_message_received()",
        "consumed_topics::spare_hands::bound_producers()",
        "consumed_services::main_hand::set_force::poll()",
        "consumed_services::main_hand::bound_producer()",
        "consumed_actions::main_hand::grasp",
        "consumed_actions::spare_hands::grasp",
        "consumed_actions::spare_hands::bound_producers()",
    ] {
        assert!(has(&paths, p), "{p} missing from {paths:#?}");
    }
    assert!(
        !has(&paths, "consumed_topics::main_hand_joint_state"),
        "{paths:#?}"
    );
    assert!(
        !has(&paths, "consumed_topics::spare_hands::bound_producer()"),
        "{paths:#?}"
    );
    // The accessors' types follow the slot's cardinality.
    let generated = config(&fixtures().join("grasp_planner"))
        .generate()
        .unwrap();
    let text = peppy_build::pretty(&generated.tokens).unwrap();
    assert!(
        text.contains(") -> &::peppy::codegen::ProducerRef {"),
        "{text}"
    );
    // spare_hands is `zero_or_more`: a possibly empty slice.
    assert!(
        text.contains(") -> &[::peppy::codegen::ProducerRef] {"),
        "{text}"
    );
    // Every entry module of a slot repeats its accessor, where `peppylib`
    // API code reaches for it, and its calls name their target.
    for p in [
        "consumed_topics::main_hand::joint_state::bound_producer",
        "consumed_topics::main_hand::joint_state::subscribe()",
        "consumed_actions::main_hand::grasp::bound_producer",
        "consumed_services::main_hand::set_force::bound_producer",
    ] {
        assert!(has(&paths, p), "{p} missing from {paths:#?}");
    }
    assert!(
        text.contains("target: &::peppy::codegen::ProducerRef,"),
        "{text}"
    );
    // A node/v1 server decides with `GoalDecision`; the `emit` API's `GoalResponse` is not offered.
    let server = config(&fixtures().join("gripper_driver"))
        .generate()
        .unwrap();
    let server = peppy_build::pretty(&server.tokens).unwrap();
    assert!(
        server.contains("pub use ::peppy::codegen::GoalDecision;"),
        "{server}"
    );
    assert!(!server.contains("GoalResponse"), "{server}");
}

/// Writes a `node/v1` document next to the fixture repository and returns
/// the rendered errors of generating it.
fn errors_of(doc: &str) -> Vec<(String, String)> {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("peppy.json5"), doc).unwrap();
    let base = std::fs::canonicalize(dir.path()).unwrap();
    let mut c = peppy_build::Config::new();
    c.manifest_dir(&base)
        .repositories_env(None)
        .repository(fixtures().join("repo"));
    match c.generate() {
        Ok(_) => panic!("expected errors for:\n{doc}"),
        Err(peppy_build::Error::Schema { diagnostics, .. }) => diagnostics
            .sorted()
            .into_iter()
            .map(|d| {
                (
                    d.code.as_str().to_string(),
                    peppy_build::macro_support::message(d, &base),
                )
            })
            .collect(),
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn sibling_modules_that_sanitise_alike_are_a_module_name_collision() {
    // An own topic `Hand` and the implements slot `hand` both become module
    // `hand`. (Two consumer slots whose link_ids sanitise alike are already
    // refused by the schema, as `DuplicateEntryName`, before generation.)
    let doc = r#"{
  peppy_schema: "node/v1",
  manifest: {
    name: "clashes",
    tag: "v1",
    implements: [{ name: "gripper", tag: "v1", link_id: "hand" }],
  },
  interfaces: {
    topics: {
      emits: [
        { name: "Hand", message_format: { a: "u8" } },
        { link_id: "hand", name: "joint_state" },
      ],
    },
    services: { exposes: [{ link_id: "hand", name: "set_force" }] },
    actions: { exposes: [{ link_id: "hand", name: "grasp" }] },
  },
  execution: { language: "rust", run_cmd: ["x"] },
}
"#;
    let errors = errors_of(doc);
    let codes: Vec<&str> = errors.iter().map(|(c, _)| c.as_str()).collect();
    assert_eq!(codes, ["ModuleNameCollision"], "{errors:#?}");
    let line = doc.lines().position(|l| l.contains("implements:")).unwrap() + 1;
    let message = &errors[0].1;
    assert!(
        message.starts_with(&format!("peppy.json5:{line}:18: ")),
        "{message}"
    );
    assert!(
        message.contains(
            "module name clash: implements slot `hand` (contract `gripper:v1`) would be generated as module `hand`, which topic `Hand` already uses (declared at peppy.json5:11:17)"
        ),
        "{message}"
    );
}

/// The `.peppy/libs` crates of a node: the generated items, the clock, and
/// the runtime under PeppyOS's names; nothing of this machine in them but the
/// peppy path given; each node's `peppygen` named apart (nodes built into
/// one target directory must not take each other's).
#[test]
fn the_libs_crates_of_two_nodes_differ_only_where_they_must() {
    let libs = |fixture: &str| {
        let generated = config(&fixtures().join(fixture)).generate().unwrap();
        peppy_build::rust_libs(&generated.check.resolved, "../../../peppy", "peppy.json5").unwrap()
    };
    let (driver, planner) = (libs("gripper_driver"), libs("grasp_planner"));
    let file = |files: &[peppy_build::LibFile], path: &str| {
        files
            .iter()
            .find(|f| f.path == std::path::Path::new(path))
            .unwrap_or_else(|| panic!("no {path}"))
            .text
            .clone()
    };
    let manifest = file(&driver, "peppygen/Cargo.toml");
    assert!(
        manifest.contains("version = \"0.1.0+gripper-driver-v1\""),
        "{manifest}"
    );
    assert!(
        manifest.contains("peppy = { path = \"../../../peppy\", default-features = false }"),
        "{manifest}"
    );
    assert!(
        manifest.contains("testing = [\"peppy/testing\"]"),
        "{manifest}"
    );
    assert!(file(&planner, "peppygen/Cargo.toml").contains("0.1.0+grasp-planner-v1"));
    assert_eq!(
        file(&driver, "peppylib/src/lib.rs"),
        file(&planner, "peppylib/src/lib.rs")
    );
    let lib = file(&driver, "peppygen/src/lib.rs");
    assert!(lib.starts_with("// @generated"), "{lib}");
    assert!(
        lib.contains("include!(\"api.rs\");")
            && lib.contains("pub use ::peppy::clock::{init, now_ns};"),
        "{lib}"
    );
    let api = file(&driver, "peppygen/src/api.rs");
    assert!(api.contains("document_path: \"peppy.json5\""), "{api}");
    assert!(
        !api.contains(&fixtures().display().to_string()),
        "a path of this machine in:\n{api}"
    );
}
