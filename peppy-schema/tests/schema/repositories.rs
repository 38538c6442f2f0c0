//! SPEC 1.5: where repositories come from and what a scan indexes.

use std::ffi::OsString;
use std::sync::Arc;

use peppy_schema::{
    Code, DocumentKind, Identity, NodeDoc, REPOSITORIES_FILE, RepoIndex, RepositoryEntry,
    RepositoryList, SKIPPED_DIRS, Severity, check_node, resolve_node,
};

use crate::support::*;

fn fs_list(paths: &[&str]) -> String {
    let items: Vec<String> = paths
        .iter()
        .map(|p| format!("  {{ type: \"fs\", path: \"{p}\" }},"))
        .collect();
    format!("// repositories\n[\n{}\n]\n", items.join("\n"))
}

#[test]
fn discover_order_explicit_then_env_then_nearest_file() {
    let tree = Tree::new();
    for d in ["a", "b", "c", "d", "e", "proj/sub/deeper"] {
        tree.mkdir(d);
    }
    let e_abs = tree.path("e");
    // The nearest file wins; the one further up is not read.
    let nearest = tree.write(
        &format!("proj/{REPOSITORIES_FILE}"),
        &fs_list(&["../d", e_abs.to_str().unwrap(), "../a"]),
    );
    tree.write(REPOSITORIES_FILE, &fs_list(&["c"]));
    let env = std::env::join_paths([tree.path("b"), tree.path("a"), "".into()]).unwrap();
    let list = RepositoryList::discover(
        &[tree.path("a")],
        Some(env.as_os_str()),
        &tree.path("proj/sub/deeper"),
    )
    .unwrap();
    assert_eq!(
        list.paths,
        [
            tree.path("a"),
            tree.path("b"),
            tree.path("d"),
            tree.path("e")
        ]
    );
    assert_eq!(list.files_read, [nearest]);

    // Without explicit paths or env, only the file counts; from the top, the top file.
    let list = RepositoryList::discover(&[], None, &tree.path("proj/sub")).unwrap();
    assert_eq!(list.paths, [tree.path("d"), tree.path("e"), tree.path("a")]);
    let list = RepositoryList::discover(&[], Some(&OsString::new()), &tree.root()).unwrap();
    assert_eq!(list.paths, [tree.path("c")]);
    assert_eq!(list.files_read, [tree.path(REPOSITORIES_FILE)]);
}

#[test]
fn repositories_file_is_validated() {
    let tree = Tree::new();
    let text = r#"[
  { type: "fs", path: "." },
  { type: "git", path: "https://example.invalid/r.git" },
  { type: "svn", path: "x" },
  { type: "fs" },
  { type: "fs", path: "y", branch: "main" },
  { type: "fs", path: "z", ref: "main" },
  { type: "git", url: "" },
  { type: "git", url: "https://example.invalid/r.git", ref: "--upload-pack=x" },
  { id: -1, type: "fs", path: "w" },
  { type: "git", url: "--upload-pack=touch /tmp/x" },
]"#;
    tree.write(REPOSITORIES_FILE, text);
    let errors = RepositoryList::discover(&[], None, &tree.root()).unwrap_err();
    let got: Vec<(Code, &str)> = errors.sorted().iter().map(|d| (d.code, key(d))).collect();
    assert_eq!(
        got,
        [
            (Code::MissingKey, "[1]"),
            (Code::InvalidValue, "[1].path"),
            (Code::InvalidValue, "[2].type"),
            (Code::MissingKey, "[3]"),
            (Code::UnknownKey, "[4].branch"),
            (Code::InvalidValue, "[5].ref"),
            (Code::InvalidValue, "[6].url"),
            (Code::InvalidValue, "[7].ref"),
            (Code::InvalidValue, "[8].id"),
            (Code::InvalidValue, "[9].url"),
        ]
    );
    let unknown_type = errors
        .sorted()
        .into_iter()
        .find(|d| key(d) == "[2].type")
        .unwrap();
    assert_eq!(lc(unknown_type), pos(text, r#""svn""#));
    assert!(
        help(unknown_type).contains("`git`"),
        "{}",
        help(unknown_type)
    );
}

/// Git repositories beside folders: in `id` order where ids are given
/// (lower first), as written otherwise; a relative URL is a repository
/// next to the list; none is fetched by discovery.
#[test]
fn git_repositories_are_listed_in_id_order_and_not_fetched() {
    let tree = Tree::new();
    tree.write(
        REPOSITORIES_FILE,
        r#"[
  { type: "fs", path: "local" },
  { id: 2, type: "git", url: "https://example.invalid/second.git" },
  { id: 1, type: "git", url: "../hubs/first.git", ref: "v2" },
]"#,
    );
    std::fs::create_dir_all(tree.path("local")).unwrap();
    let list = RepositoryList::discover(&[], Some(&OsString::new()), &tree.root()).unwrap();
    let described: Vec<String> = list
        .listed
        .iter()
        .map(|l| match &l.entry {
            RepositoryEntry::Git(g) => format!("{} {}", g.short_name(), g.describe()),
            RepositoryEntry::Folder(p) => p.display().to_string(),
        })
        .collect();
    let first = tree.root().join("../hubs/first.git");
    assert_eq!(
        described,
        [
            format!("first {}@v2", first.display()),
            "second https://example.invalid/second.git".to_string(),
            tree.path("local").display().to_string(),
        ]
    );
    // Only the folder is local until a fetcher brings the git ones.
    assert_eq!(list.paths, [tree.path("local")]);
    assert_eq!(list.unfetched().count(), 2);
}

#[test]
fn skipped_and_hidden_directories_are_not_scanned() {
    let tree = Tree::new();
    tree.write("repo/real/peppy.json5", &node_text("real", "", "", ""));
    let mut dirs: Vec<&str> = SKIPPED_DIRS.to_vec();
    dirs.push(".hidden");
    for (i, dir) in dirs.iter().enumerate() {
        let name = format!("skipped_{i}");
        tree.write(
            &format!("repo/{dir}/{name}/peppy.json5"),
            &node_text(&name, "", "", ""),
        );
        tree.write(
            &format!("repo/nested/{dir}/iface.json5"),
            &interface_text(&name, "v1", ""),
        );
    }
    assert!(
        SKIPPED_DIRS.contains(&"target")
            && SKIPPED_DIRS.contains(&".git")
            && SKIPPED_DIRS.contains(&"node_modules")
    );
    let index = RepoIndex::scan(&[tree.path("repo")]);
    let nodes: Vec<String> = index.node_ids().map(ToString::to_string).collect();
    assert_eq!(nodes, ["real:v1"]);
    assert_eq!(index.interface_ids().count(), 0);
    assert!(index.findings().is_empty(), "{}", index.findings());
}

#[test]
fn the_first_repository_wins_and_the_duplicate_is_reported() {
    let tree = Tree::new();
    let first = tree.write(
        "one/cam/peppy.json5",
        &node_text(
            "cam",
            "",
            r#"topics: { emits: [{ name: "from_one" }] }"#,
            "",
        ),
    );
    let second = tree.write(
        "two/cam/peppy.json5",
        &node_text(
            "cam",
            "",
            r#"topics: { emits: [{ name: "from_two" }] }"#,
            "",
        ),
    );
    tree.write(
        "one/ifaces/cam.json5",
        &interface_text("cam_if", "v1", r#"topics: [{ name: "one" }]"#),
    );
    let second_iface = tree.write(
        "two/cam_if.json5",
        &interface_text("cam_if", "v1", r#"topics: [{ name: "two" }]"#),
    );
    let index = RepoIndex::scan(&[tree.path("one"), tree.path("two")]);

    let cam = index.node(&Identity::new("cam", "v1")).unwrap();
    assert_eq!(cam.path, first);
    assert_eq!(cam.repository, tree.path("one"));
    assert_eq!(cam.doc.emits[0].name, "from_one");
    let iface = Identity::new("cam_if", "v1");
    assert_eq!(index.interface(&iface).unwrap().doc.topics[0].name, "one");
    assert_eq!(
        index.interfaces(&iface).len(),
        2,
        "every copy is kept for sha256 pins"
    );

    let dups: Vec<_> = index.findings().iter().collect();
    assert_eq!(dups.len(), 2, "{}", index.findings());
    for d in &dups {
        assert_eq!(d.code, Code::DuplicateInRepositories);
        assert_eq!(d.severity, Severity::Warning);
        assert!(help(d).contains("earlier in the list win"), "{d}");
    }
    let node_dup = dups
        .iter()
        .find(|d| d.file_path() == Some(second.as_path()))
        .unwrap();
    assert_eq!(
        node_dup.message,
        format!(
            "`cam:v1` is defined twice: `{}` wins over `{}`",
            first.display(),
            second.display()
        )
    );
    assert!(
        dups.iter()
            .any(|d| d.file_path() == Some(second_iface.as_path()))
    );

    // Reversing the order reverses the winner.
    let index = RepoIndex::scan(&[tree.path("two"), tree.path("one")]);
    assert_eq!(
        index.node(&Identity::new("cam", "v1")).unwrap().path,
        second
    );
}

#[test]
fn kinds_come_from_peppy_schema_not_file_names() {
    let tree = Tree::new();
    tree.write("repo/nodes/cam/peppy.json5", &node_text("cam", "", "", ""));
    // A node document under another name is not a node of the repository.
    tree.write(
        "repo/nodes/other/node.json5",
        &node_text("other", "", "", ""),
    );
    // Interfaces and launchers may have any *.json5 name.
    tree.write(
        "repo/contracts/whatever_name.json5",
        &interface_text("depth_camera", "v1", ""),
    );
    tree.write(
        "repo/nodes/odd/peppy.json5",
        &interface_text("odd_iface", "v2", ""),
    );
    tree.write(
        "repo/stacks/demo.json5",
        r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "cam:v1" }, instances: [{ instance_id: "c" }] }] }"#,
    );
    tree.write("repo/misc/settings.json5", "{ hello: 1 }");
    tree.write("repo/misc/list.json5", "[1, 2]");
    tree.write("repo/misc/broken_syntax.json5", "{ oops ");
    tree.write("repo/misc/peppy.json", &node_text("json_ext", "", "", ""));
    let index = RepoIndex::scan(&[tree.path("repo")]);
    let nodes: Vec<String> = index.node_ids().map(ToString::to_string).collect();
    assert_eq!(nodes, ["cam:v1"]);
    let interfaces: Vec<String> = index.interface_ids().map(ToString::to_string).collect();
    assert_eq!(interfaces, ["depth_camera:v1", "odd_iface:v2"]);
    assert_eq!(
        index.launcher("demo"),
        Some(tree.path("repo/stacks/demo.json5").as_path())
    );
    assert!(index.launcher("settings").is_none());
    assert!(index.findings().is_empty(), "{}", index.findings());
}

#[test]
fn broken_documents_surface_when_depended_on() {
    let tree = Tree::new();
    let broken_node = tree.write(
        "repo/broken/peppy.json5",
        r#"{
  peppy_schema: "node_v1",
  manifest: { name: "broken", tag: "v1" },
  execution: { language: "rust", run_cmd: ["./broken"], colour: "red" },
}"#,
    );
    let broken_iface = tree.write(
        "repo/ifaces/bad.json5",
        &interface_text(
            "bad_iface",
            "v1",
            r#"topics: [{ name: "t", message_format: { x: "nope" } }]"#,
        ),
    );
    let consumer_text = node_text(
        "consumer",
        r#"nodes: [{ name: "broken", tag: "v1", link_id: "b" }]"#,
        r#"conforms_to: [{ name: "bad_iface", tag: "v1" }]"#,
        "",
    );
    let consumer = tree.write("consumer/peppy.json5", &consumer_text);
    let index = RepoIndex::scan(&[tree.path("repo")]);
    assert!(index.node(&Identity::new("broken", "v1")).is_none());
    let b = index
        .broken(DocumentKind::Node, &Identity::new("broken", "v1"))
        .unwrap();
    assert_eq!(b.path, broken_node);
    assert!(b.diagnostics.contains(Code::UnknownKey));

    let errors = check_node(&consumer, &options(vec![tree.path("repo")])).unwrap_err();
    let found = all(&errors, Code::DependencyInvalid);
    assert_eq!(errors.len(), 2, "{errors}");
    assert_at(
        found[0],
        Code::DependencyInvalid,
        "manifest.depends_on.nodes[0]",
        &consumer_text,
        "{ name: \"broken\"",
    );
    assert_eq!(
        found[0].message,
        format!(
            "node `broken:v1` is defined in `{}`, but that document is invalid",
            broken_node.display()
        )
    );
    assert!(
        help(found[0]).contains("unknown key `colour` in `execution`"),
        "{}",
        found[0]
    );
    assert_at(
        found[1],
        Code::DependencyInvalid,
        "interfaces.conforms_to[0]",
        &consumer_text,
        "{ name: \"bad_iface\"",
    );
    assert!(found[1].message.starts_with(&format!(
        "interface `bad_iface:v1` is defined in `{}`",
        broken_iface.display()
    )));
    assert!(
        help(found[1]).contains("unknown type `nope`"),
        "{}",
        found[1]
    );
}

#[test]
fn missing_repository_directories_are_reported_not_fatal() {
    let tree = Tree::new();
    tree.write("repo/cam/peppy.json5", &node_text("cam", "", "", ""));
    let index = RepoIndex::scan(&[tree.path("nowhere"), tree.path("repo")]);
    assert_eq!(index.node_ids().count(), 1);
    let d = one(index.findings(), Code::DependencyNotFound);
    assert_eq!(d.severity, Severity::Warning);
    assert!(d.message.contains("is not a directory"), "{d}");
}

#[test]
fn dependencies_resolve_against_the_winning_copy() {
    let tree = Tree::new();
    let winner = tree.write(
        "one/cam/peppy.json5",
        &node_text(
            "cam",
            "",
            r#"topics: { emits: [{ name: "frame", message_format: { a: "u8" } }] }"#,
            "",
        ),
    );
    tree.write(
        "two/cam/peppy.json5",
        &node_text(
            "cam",
            "",
            r#"topics: { emits: [{ name: "frame", message_format: { b: "u16" } }] }"#,
            "",
        ),
    );
    let consumer = tree.write(
        "two/consumer/peppy.json5",
        &node_text(
            "consumer",
            r#"nodes: [{ name: "cam", tag: "v1", link_id: "cam" }]"#,
            r#"topics: { consumes: [{ link_id: "cam", name: "frame" }] }"#,
            "",
        ),
    );
    let index = RepoIndex::scan(&[tree.path("one"), tree.path("two")]);
    let (doc, _) = NodeDoc::load(&consumer).unwrap();
    let (resolved, warnings) = resolve_node(Arc::new(doc), consumer.clone(), &index).unwrap();
    assert!(warnings.is_empty());
    assert_eq!(
        resolved.consumed_topics[0]
            .format
            .as_ref()
            .unwrap()
            .canonical(),
        "{a:u8}"
    );
    assert!(resolved.files.contains(&winner));
}

#[test]
fn a_launcher_deploying_a_broken_node_says_it_is_invalid() {
    let tree = Tree::new();
    let broken = tree.write(
        "repo/broken/peppy.json5",
        r#"{ peppy_schema: "node_v1", manifest: { name: "broken", tag: "v1" }, execution: { language: "python" } }"#,
    );
    let text = r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "broken:v1" }, instances: [{ instance_id: "b" }] }] }"#;
    let path = tree.write("stack.json5", text);
    let errors =
        peppy_schema::check_launcher(&path, &options(vec![tree.path("repo")])).unwrap_err();
    let d = one(&errors, Code::DependencyInvalid);
    assert_eq!(errors.len(), 1, "{errors}");
    assert_at(
        d,
        Code::DependencyInvalid,
        "deployments[0].source",
        text,
        "{ name: \"broken:v1\" }",
    );
    assert_eq!(
        d.message,
        format!(
            "node `broken:v1` is defined in `{}`, but that document is invalid",
            broken.display()
        )
    );
    assert!(help(d).contains("neither `run_cmd` nor `container`"), "{d}");
}
