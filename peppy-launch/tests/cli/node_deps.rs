//! A node links what a node needs. Its binary carries the runtime and the
//! model its build embedded: no document parser, no code generator, and no
//! TLS (a node reaches its launch's router over TCP; TLS links core nodes'
//! routers, in the launcher). Nothing it links is there to match the
//! launcher's features; only its proc-macros' are (docs/PERFORMANCE.md,
//! "Build time").

use std::collections::BTreeSet;

use crate::support::cargo;

/// The lines of `cargo tree` over `args`, one package per line in `format`,
/// without the mark of a package already shown.
fn tree(format: &str, args: &[&str]) -> Vec<String> {
    let mut tree = vec!["tree", "--offline", "--prefix", "none", "--format", format];
    tree.extend_from_slice(args);
    let out = cargo(&tree);
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| l.trim_end_matches(" (*)").to_string())
        .collect()
}

/// The packages `package` links (its normal dependencies, every level).
fn linked(package: &str) -> BTreeSet<String> {
    tree("{p}", &["-e", "normal", "-p", package])
        .iter()
        .filter_map(|l| l.split_whitespace().next())
        .map(String::from)
        .collect()
}

#[test]
fn a_node_links_no_document_parser_generator_or_tls() {
    let node = linked("realsense_d405");
    assert!(
        node.contains("zenoh") && node.contains("peppy-runtime"),
        "{node:?}"
    );
    let not_a_nodes: Vec<&str> = [
        "jsonc-parser",
        "miette",
        "peppy-build",
        "prettyplease",
        "rustls",
        "ring",
        "zenoh-link-tls",
        "x509-parser",
    ]
    .into_iter()
    .filter(|p| node.contains(*p))
    .collect();
    assert!(
        not_a_nodes.is_empty(),
        "a node links {not_a_nodes:?}; what added them?"
    );
    // The launcher links them: the list above is not vacuous.
    let launcher = linked("peppy-launch");
    for p in [
        "jsonc-parser",
        "miette",
        "peppy-build",
        "rustls",
        "zenoh-link-tls",
    ] {
        assert!(launcher.contains(p), "the launcher links no {p}");
    }
}

/// The feature sets cargo resolves for `syn` and `proc-macro2` in `args`'s
/// tree: every proc-macro's build rests on them.
fn proc_macro_roots(args: &[&str]) -> BTreeSet<String> {
    tree("{p}|{f}", args)
        .into_iter()
        .filter(|l| l.starts_with("syn ") || l.starts_with("proc-macro2 "))
        .collect()
}

/// A node built in the workspace after `cargo test` builds no proc-macro
/// again, nor what one builds (serde, stabby, most of Zenoh): its `syn` and
/// `proc-macro2` have the features the workspace's test build gives them
/// (peppy-runtime's build-dependencies ask for what the launcher's host
/// side turns on). Without that, an example node's build after the test build took
/// 127 s against 78 s on two cores (docs/PERFORMANCE.md, "Build time").
#[test]
fn a_node_builds_on_the_test_builds_proc_macros() {
    let workspace = proc_macro_roots(&["--workspace", "-e", "normal,build,dev"]);
    for node in ["realsense_d405", "peppylib_camera"] {
        let own = proc_macro_roots(&["-p", node, "-e", "normal,build"]);
        assert!(own.iter().any(|l| l.starts_with("syn ")), "{own:?}");
        let apart: Vec<&String> = own.difference(&workspace).collect();
        assert!(
            apart.is_empty(),
            "{node} resolves {apart:?}, which the workspace's test build does not \
             (it has {workspace:?}): match them in peppy-runtime's build-dependencies"
        );
    }
}

/// The files cargo names for the `zenoh` library that `package`'s build
/// links (building it first when it is not built yet).
fn zenoh_built_for(package: &str) -> Vec<String> {
    let out = cargo(&["build", "-p", package, "--message-format=json"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let zenoh = stdout
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|m| {
            m["reason"] == "compiler-artifact"
                && m["target"]["name"] == "zenoh"
                && m["target"]["kind"] == serde_json::json!(["lib"])
        })
        .unwrap_or_else(|| panic!("no zenoh artifact in the build of {package}:\n{stdout}"));
    let files: Vec<String> = zenoh["filenames"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|f| f.as_str().map(String::from))
        .collect();
    assert!(!files.is_empty(), "{zenoh}");
    files
}

/// A node whose build script runs the generator and a node laid out as
/// PeppyOS lays them out (`.peppy/libs`, no build script) build the same
/// Zenoh: a stack mixing them builds it once. The generator turns on serde
/// features on the host that Zenoh's proc-macro sees; peppy-runtime's
/// build-dependencies turn them on for the other layout too.
#[test]
fn both_node_layouts_build_one_zenoh() {
    assert_eq!(
        zenoh_built_for("camera_viewer"),
        zenoh_built_for("peppylib_camera"),
        "the two layouts build Zenoh with different features (see peppy-runtime's build-dependencies)"
    );
}
