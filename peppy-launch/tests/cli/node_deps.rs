//! A node links what a node needs. Its binary carries the runtime and the
//! model its build embedded: no document parser, no code generator, and no
//! TLS (a node reaches its launch's router over TCP; TLS links core nodes'
//! routers, in the launcher). Nothing in its dependencies is there to match
//! the launcher's features (docs/PERFORMANCE.md, "Build time").

use std::collections::BTreeSet;

use crate::support::cargo;

/// The packages `package` links (its normal dependencies, every level).
fn linked(package: &str) -> BTreeSet<String> {
    let out = cargo(&[
        "tree",
        "--offline",
        "-e",
        "normal",
        "--prefix",
        "none",
        "--format",
        "{p}",
        "-p",
        package,
    ]);
    String::from_utf8_lossy(&out.stdout)
        .lines()
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
