//! A node built alone reuses what the launcher's build compiled.
//!
//! `up` builds each node with its own `cargo build -p NODE`, after the
//! launcher was built on its own (`cargo run -p peppy-launch`). Cargo
//! reuses a crate only when both builds ask for it with the same features
//! (and the same for everything below it); otherwise the node's build
//! compiles it again, and for zenoh that is minutes on two cores. The
//! runtime and the generator ask for a few features only the launcher uses
//! for that reason (their Cargo.toml say which and why). This test fails
//! when those lists drift: every registry crate the node's build compiles
//! must be a file the launcher's build made, by the hash cargo names it
//! with. The workspace's own crates are not held to it: a node links the
//! runtime's model without the document parser the launcher links, and
//! rebuilding them takes seconds.

use std::collections::{BTreeMap, BTreeSet};
use std::process::{Command, Stdio};

use crate::support::{COMMAND_BOUND, root, wait_bounded};

/// What `cargo build -p PACKAGE` compiles: each crate's target (package
/// and target name, with its kind) and the files it produced (their names
/// carry the unit's hash).
fn artifacts(package: &str) -> BTreeMap<String, BTreeSet<String>> {
    let child = Command::new(env!("CARGO"))
        .args(["build", "--frozen", "--message-format=json", "-p", package])
        .current_dir(root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run cargo");
    let out = wait_bounded(child, COMMAND_BOUND, &format!("cargo build -p {package}"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut found = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let Ok(message) = serde_json::from_str::<serde_json::Value>(line) else {
            continue;
        };
        let id = message["package_id"].as_str().unwrap_or_default();
        if message["reason"] != "compiler-artifact" || !id.starts_with("registry+") {
            continue;
        }
        let unit = format!(
            "{} {} {}",
            id,
            message["target"]["name"].as_str().unwrap_or_default(),
            message["target"]["kind"]
        );
        let mut files: Vec<String> = message["filenames"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|f| f.as_str())
            .filter_map(|f| f.rsplit('/').next())
            .map(String::from)
            .collect();
        files.sort();
        found
            .entry(unit)
            .or_insert_with(BTreeSet::new)
            .insert(files.join(" "));
    }
    found
}

#[test]
fn a_node_built_alone_reuses_the_launchers_crates() {
    let launcher = artifacts("peppy-launch");
    let node = artifacts("realsense_d405");
    let shared: Vec<&String> = node.keys().filter(|u| launcher.contains_key(*u)).collect();
    assert!(
        shared.iter().any(|u| u.contains("#zenoh@")),
        "zenoh is built by both: {shared:?}"
    );
    // A crate may be built twice in one build (for the host and the
    // target): the node's must be among the launcher's.
    let differing: Vec<String> = shared
        .iter()
        .filter(|u| !node[**u].is_subset(&launcher[**u]))
        .map(|u| {
            format!(
                "{u}:\n  launcher: {:?}\n  node:     {:?}",
                launcher[*u], node[*u]
            )
        })
        .collect();
    assert!(
        differing.is_empty(),
        "a node built alone compiles these crates again (their features differ from the launcher's build; see peppy-runtime's and peppy-build's Cargo.toml):\n{}",
        differing.join("\n")
    );
}
