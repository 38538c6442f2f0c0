//! `repository/v1` (`peppy_repository.json5`): its rules, reading a
//! repository through it, and what `repo index` writes and checks
//! (reference §6).

use peppy_schema::{
    Code, DeclaredIndex, Diagnostics, Document, DocumentKind, Drift, Identity, IndexKey,
    IndexSection, REPOSITORY_INDEX_FILE, RepoIndex, RepositoryIndexDoc, Severity, SourceFile,
    check_index, check_index_path, declared_in, parse_document,
};

use crate::support::*;

fn parse(text: &str) -> Result<(RepositoryIndexDoc, Diagnostics), Diagnostics> {
    RepositoryIndexDoc::parse(REPOSITORY_INDEX_FILE, text)
}

fn index_ok(text: &str) -> RepositoryIndexDoc {
    match parse(text) {
        Ok((doc, warnings)) => {
            assert!(warnings.is_empty(), "{warnings}");
            doc
        }
        Err(e) => panic!("expected a valid index, got:\n{e}"),
    }
}

fn index_err(text: &str) -> Diagnostics {
    match parse(text) {
        Ok(_) => panic!("expected errors, the index was accepted:\n{text}"),
        Err(e) => e,
    }
}

fn node_key(name: &str, tag: &str) -> IndexKey {
    IndexKey::tagged(IndexSection::Nodes, &Identity::new(name, tag))
}

fn key_of(section: IndexSection, name: &str, tag: &str) -> IndexKey {
    IndexKey::tagged(section, &Identity::new(name, tag))
}

const FULL: &str = r#"// every section
{
  peppy_schema: "repository/v1",
  nodes: {
    cam: { v1: { path: "cam/peppy.json5" }, v2: { path: "cam2/peppy.json5" } },
    "zed-2i": { v1: { path: "zed/peppy.json5" } },
  },
  launchers: { demo: { path: "stacks/demo.json5" } },
  contracts: { rgb: { v1: { path: "contracts/rgb.json5" } } },
  pairings: { joint_link: { v1: { path: "robot/joint_link.json5" } } },
  mcp_exposures: { arm_mcp: { v1: { path: "mcp/arm.json5" } } },
}
"#;

#[test]
fn every_section_is_read_by_name_and_tag() {
    let doc = index_ok(FULL);
    let got: Vec<(String, &str)> = doc
        .entries
        .iter()
        .map(|(k, l)| (k.to_string(), l.path.as_str()))
        .collect();
    assert_eq!(
        got,
        [
            ("node `cam:v1`".to_string(), "cam/peppy.json5"),
            ("node `cam:v2`".to_string(), "cam2/peppy.json5"),
            ("node `zed-2i:v1`".to_string(), "zed/peppy.json5"),
            ("launcher `demo`".to_string(), "stacks/demo.json5"),
            ("contract `rgb:v1`".to_string(), "contracts/rgb.json5"),
            (
                "pairing `joint_link:v1`".to_string(),
                "robot/joint_link.json5"
            ),
            ("MCP exposure `arm_mcp:v1`".to_string(), "mcp/arm.json5"),
        ]
    );
    // Each entry keeps where its path is, for findings about it later.
    let listed = &doc.entries[&IndexKey::launcher("demo")];
    assert_eq!(listed.loc.key_path, "launchers.demo.path");
    let at = listed.loc.file.line_col(listed.loc.span.start);
    assert_eq!((at.line, at.column), pos(FULL, r#""stacks/demo.json5""#));

    // It is a document kind of its own, found by `peppy_schema`.
    let (doc, _) = parse_document(&SourceFile::new("any_name.json5", FULL), "").unwrap();
    assert_eq!(doc.kind(), DocumentKind::RepositoryIndex);
    assert_eq!(doc.kind().as_str(), "repository_index");
    assert!(matches!(doc, Document::RepositoryIndex(_)));
}

#[test]
fn every_section_is_optional() {
    let doc = index_ok(r#"{ peppy_schema: "repository/v1" }"#);
    assert!(doc.entries.is_empty());
    let doc = index_ok(r#"{ peppy_schema: "repository/v1", nodes: {}, launchers: {} }"#);
    assert!(doc.entries.is_empty());
}

#[test]
fn unknown_keys_are_refused_at_every_level() {
    let text = r#"{
  peppy_schema: "repository/v1",
  interfaces: {},
  nodes: { cam: { v1: { path: "cam/peppy.json5", sha256: "00" } } },
  launchers: { demo: { path: "demo.json5", tag: "v1" } },
}"#;
    let errors = index_err(text);
    let found = all(&errors, Code::UnknownKey);
    assert_eq!(found.len(), 3, "{errors}");
    assert_at(found[0], Code::UnknownKey, "interfaces", text, "interfaces");
    assert_eq!(
        found[0].message,
        "unknown key `interfaces` at the top level"
    );
    assert!(
        help(found[0]).contains("`nodes`, `launchers`, `contracts`, `pairings`, `mcp_exposures`"),
        "{}",
        found[0]
    );
    assert_at(
        found[1],
        Code::UnknownKey,
        "nodes.cam.v1.sha256",
        text,
        "sha256",
    );
    assert_at(
        found[2],
        Code::UnknownKey,
        "launchers.demo.tag",
        text,
        "tag",
    );
    assert_eq!(errors.len(), 3, "{errors}");
}

#[test]
fn shapes_are_checked() {
    let text = r#"{
  peppy_schema: "repository/v1",
  nodes: [],
  contracts: { rgb: "v1" },
  pairings: { link: { v1: { } } },
  mcp_exposures: { arm: { v1: { path: 7 } } },
  launchers: { demo: "demo.json5" },
}"#;
    let errors = index_err(text);
    let got: Vec<(Code, &str, String)> = errors
        .sorted()
        .iter()
        .map(|d| (d.code, key(d), d.message.clone()))
        .collect();
    assert_eq!(
        got,
        [
            (
                Code::WrongType,
                "nodes",
                "expected an object for `nodes`, found an array".to_string()
            ),
            (
                Code::WrongType,
                "contracts.rgb",
                "expected an object for `contracts.rgb`, found a string".to_string()
            ),
            (
                Code::MissingKey,
                "pairings.link.v1",
                "missing required key `path` in `pairings.link.v1`".to_string()
            ),
            (
                Code::WrongType,
                "mcp_exposures.arm.v1.path",
                "expected a string for `mcp_exposures.arm.v1.path`, found a number".to_string()
            ),
            (
                Code::WrongType,
                "launchers.demo",
                "expected an object for `launchers.demo`, found a string".to_string()
            ),
        ]
    );
    assert_eq!(lc(one(&errors, Code::MissingKey)), pos(text, "{ }"));
    assert_eq!(
        lc(errors.sorted()[3]),
        pos(text, "7"),
        "{}",
        errors.sorted()[3]
    );
}

#[test]
fn names_obey_the_name_rule_and_tags_the_tag_rule() {
    let text = r#"{
  peppy_schema: "repository/v1",
  nodes: {
    "my.cam": { v1: { path: "a/peppy.json5" } },
    cam: { "0.1.0": { path: "b/peppy.json5" }, "": { path: "c/peppy.json5" } },
  },
  contracts: { "": { v1: { path: "d.json5" } } },
  launchers: { "demo.launch": { path: "demo.launch.json5" } },
}"#;
    let errors = index_err(text);
    let names = all(&errors, Code::InvalidName);
    assert_eq!(names.len(), 3, "{errors}");
    assert_at(
        names[0],
        Code::InvalidName,
        "nodes.my.cam",
        text,
        r#""my.cam""#,
    );
    assert_eq!(
        names[0].message,
        "invalid node name `my.cam`: contains '.'; allowed: ASCII letters, digits, `_` and `-`"
    );
    assert_eq!(help(names[0]), "a node is listed by its `manifest.name`");
    assert_at(
        names[1],
        Code::InvalidName,
        "contracts.",
        text,
        r#""": { v1"#,
    );
    assert_eq!(
        names[1].message,
        "invalid contract name ``: must not be empty"
    );
    assert_at(
        names[2],
        Code::InvalidName,
        "launchers.demo.launch",
        text,
        r#""demo.launch""#,
    );
    assert_eq!(
        help(names[2]),
        "a launcher is listed by its file name without `.json5`"
    );
    let tags = all(&errors, Code::InvalidTag);
    assert_eq!(tags.len(), 2, "{errors}");
    assert_at(
        tags[0],
        Code::InvalidTag,
        "nodes.cam.0.1.0",
        text,
        r#""0.1.0""#,
    );
    assert!(
        tags[0]
            .message
            .starts_with("invalid tag `0.1.0` of node `cam`: must start with an ASCII letter"),
        "{}",
        tags[0]
    );
    assert_at(
        tags[1],
        Code::InvalidTag,
        "nodes.cam.",
        text,
        r#""": { path: "c"#,
    );
    assert_eq!(errors.len(), 5, "{errors}");
    // Names may hold `-` (not a tag's first character).
    index_ok(
        r#"{ peppy_schema: "repository/v1", nodes: { "zed-2i": { "v1-beta": { path: "z/peppy.json5" } } } }"#,
    );
}

#[test]
fn paths_are_canonical() {
    let cases = [
        ("", "it is empty"),
        (
            "cams\\\\rgb.json5",
            "it contains a backslash; separate segments with `/`",
        ),
        (
            "/cams/rgb.json5",
            "it starts with `/`; paths are relative to the repository root",
        ),
        ("cams/", "it ends with `/`; it names a file"),
        ("cams//rgb.json5", "it has an empty segment (`//`)"),
        ("./rgb.json5", "it has a `.` segment"),
        ("cams/./rgb.json5", "it has a `.` segment"),
        ("../rgb.json5", "it has a `..` segment"),
        ("cams/../rgb.json5", "it has a `..` segment"),
    ];
    for (path, why) in cases {
        let text = format!(
            "{{\n  peppy_schema: \"repository/v1\",\n  contracts: {{ rgb: {{ v1: {{ path: \"{path}\" }} }} }},\n}}"
        );
        let errors = index_err(&text);
        let d = one(&errors, Code::NonCanonicalPath);
        assert_eq!(errors.len(), 1, "{errors}");
        assert_at(
            d,
            Code::NonCanonicalPath,
            "contracts.rgb.v1.path",
            &text,
            &format!("\"{path}\""),
        );
        let written = path.replace("\\\\", "\\");
        assert_eq!(
            d.message,
            format!("`path` `{written}` is not canonical: {why}")
        );
        assert!(help(d).contains("from the repository root"), "{d}");
        assert_eq!(check_index_path(&written), Err(why.to_string()));
    }
    for ok in ["rgb.json5", "cams/rgb.json5", "a/b-c/.d/e..f/g.json5"] {
        assert_eq!(check_index_path(ok), Ok(()), "{ok}");
    }
}

#[test]
fn repeated_keys_are_errors_naming_both() {
    let text = r#"{
  peppy_schema: "repository/v1",
  nodes: {
    cam: { v1: { path: "a/peppy.json5" }, v1: { path: "b/peppy.json5" } },
    cam: { v2: { path: "c/peppy.json5" } },
  },
  nodes: {},
}"#;
    let errors = index_err(text);
    let found = all(&errors, Code::DuplicateKey);
    assert_eq!(found.len(), 3, "{errors}");
    // The second of each pair is the error; the help names the first.
    // (The 0th `v1` is in `repository/v1`.)
    assert_eq!(lc(found[0]), pos_nth(text, "v1", 2));
    assert_eq!(found[0].message, "duplicate key `v1`");
    let first = pos_nth(text, "v1", 1);
    assert_eq!(
        help(found[0]),
        format!(
            "`v1` is already set at line {}, column {}; keep one",
            first.0, first.1
        )
    );
    assert_eq!(lc(found[1]), pos_nth(text, "cam", 1));
    assert_eq!(lc(found[2]), pos_nth(text, "nodes", 1));
    let first = pos_nth(text, "nodes", 0);
    assert_eq!(
        help(found[2]),
        format!(
            "`nodes` is already set at line {}, column {}; keep one",
            first.0, first.1
        )
    );
}

#[test]
fn unknown_schema_versions_are_refused() {
    let text = r#"{ peppy_schema: "repository/v2" }"#;
    let errors = parse_document(&SourceFile::new("i.json5", text), "").unwrap_err();
    let d = one(&errors, Code::UnknownSchema);
    assert_at(
        d,
        Code::UnknownSchema,
        "peppy_schema",
        text,
        r#""repository/v2""#,
    );
    assert!(
        help(d).starts_with("did you mean `repository/v1`?"),
        "{}",
        help(d)
    );
    // The index is no longer among the kinds not read yet.
    let text = r#"{ peppy_schema: "mcp_exposure/v1" }"#;
    let errors = parse_document(&SourceFile::new("p.json5", text), "").unwrap_err();
    let d = one(&errors, Code::UnknownSchema);
    assert!(help(d).contains("`repository/v1`"), "{}", help(d));
}

// ---- Reading a repository through its index ----

const NODE_V1_BROKEN: &str = r#"{ peppy_schema: "node/v1", manifest: { name: "slashed_cam", tag: "v1", bogus: 1 }, execution: { language: "rust", run_cmd: ["x"] } }"#;

/// A repository whose index lists a `node_v1` node, a contract, a launcher, a
/// pairing and a broken `node/v1` node, next to an unlisted node.
fn indexed_repo(tree: &Tree) {
    tree.write("repo/cam/peppy.json5", &node_text("cam", "", "", ""));
    tree.write(
        "repo/unlisted/peppy.json5",
        &node_text("unlisted", "", "", ""),
    );
    tree.write(
        "repo/contracts/rgb.json5",
        r#"{ peppy_schema: "contract/v1", manifest: { name: "rgb", tag: "v1" }, interfaces: { topics: [{ name: "frame", message_format: { w: "u32" } }] } }"#,
    );
    tree.write(
        "repo/unlisted_iface.json5",
        &interface_text("unlisted_if", "v1", ""),
    );
    tree.write(
        "repo/stacks/demo.json5",
        r#"{ peppy_schema: "launcher_v1", deployments: [] }"#,
    );
    tree.write(
        "repo/stacks/other.json5",
        r#"{ peppy_schema: "launcher_v1", deployments: [] }"#,
    );
    tree.write(
        "repo/robot/joint_link.json5",
        r#"{ peppy_schema: "pairing/v1", manifest: { name: "joint_link", tag: "v1" }, roles: ["a", "b"], topics: [{ emitted_by: "a", name: "t", message_format: { x: "u8" } }] }"#,
    );
    tree.write("repo/slashed/peppy.json5", NODE_V1_BROKEN);
    tree.write(
        &format!("repo/{REPOSITORY_INDEX_FILE}"),
        r#"{
  peppy_schema: "repository/v1",
  nodes: {
    cam: { v1: { path: "cam/peppy.json5" } },
    slashed_cam: { v1: { path: "slashed/peppy.json5" } },
  },
  launchers: { demo: { path: "stacks/demo.json5" } },
  contracts: { rgb: { v1: { path: "contracts/rgb.json5" } } },
  pairings: { joint_link: { v1: { path: "robot/joint_link.json5" } } },
}"#,
    );
}

#[test]
fn a_repository_with_an_index_is_read_through_it() {
    let tree = Tree::new();
    indexed_repo(&tree);
    let index = RepoIndex::scan(&[tree.path("repo")]);
    let nodes: Vec<String> = index.node_ids().map(ToString::to_string).collect();
    assert_eq!(nodes, ["cam:v1"], "only listed files are read");
    let interfaces: Vec<String> = index.interface_ids().map(ToString::to_string).collect();
    assert_eq!(interfaces, ["rgb:v1"]);
    let pairing = index.pairings(&Identity::new("joint_link", "v1"));
    assert_eq!(pairing.len(), 1, "a listed pairing is read");
    assert_eq!(pairing[0].path, tree.path("repo/robot/joint_link.json5"));
    assert_eq!(
        index.launcher("demo"),
        Some(tree.path("repo/stacks/demo.json5").as_path())
    );
    assert!(index.launcher("other").is_none());
    assert_eq!(
        index.node(&Identity::new("cam", "v1")).unwrap().repository,
        tree.path("repo")
    );

    // A listed document that does not parse is kept as broken, saying why,
    // without failing the rest of the index or warning on every scan.
    let broken = index
        .broken(DocumentKind::Node, &Identity::new("slashed_cam", "v1"))
        .expect("kept under its listed identity");
    assert_eq!(broken.path, tree.path("repo/slashed/peppy.json5"));
    let d = one(&broken.diagnostics, Code::UnknownKey);
    assert_eq!(d.message, "unknown key `bogus` in `manifest`");
    assert!(index.findings().is_empty(), "{}", index.findings());
}

#[test]
fn a_launcher_deploying_a_broken_listed_node_says_why() {
    let tree = Tree::new();
    indexed_repo(&tree);
    let text = r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "slashed_cam:v1" }, instances: [{ instance_id: "c" }] }] }"#;
    let path = tree.write("stack.json5", text);
    let errors =
        peppy_schema::check_launcher(&path, &options(vec![tree.path("repo")])).unwrap_err();
    let d = one(&errors, Code::DependencyInvalid);
    assert_eq!(errors.len(), 1, "{errors}");
    assert!(
        help(d).contains("unknown key `bogus` in `manifest`"),
        "{d}: {}",
        help(d)
    );
}

#[test]
fn listed_files_must_declare_what_they_are_listed_as() {
    let tree = Tree::new();
    tree.write("repo/cam/peppy.json5", &node_text("cam", "", "", ""));
    tree.write("repo/rgb.json5", &interface_text("rgb", "v1", ""));
    tree.write(
        "repo/stacks/demo.json5",
        r#"{ peppy_schema: "launcher_v1" }"#,
    );
    tree.write(
        "repo/frag.json5",
        r#"{ peppy_schema: "launcher_fragment/v1" }"#,
    );
    tree.mkdir("repo/adir");
    let text = r#"{
  peppy_schema: "repository/v1",
  nodes: {
    cam: { v2: { path: "cam/peppy.json5" } },
    gone: { v1: { path: "gone/peppy.json5" } },
    rgb: { v1: { path: "rgb.json5" } },
    adir: { v1: { path: "adir" } },
  },
  launchers: {
    renamed: { path: "stacks/demo.json5" },
    frag: { path: "frag.json5" },
  },
}"#;
    tree.write(&format!("repo/{REPOSITORY_INDEX_FILE}"), text);
    let index = RepoIndex::scan(&[tree.path("repo")]);
    assert_eq!(index.node_ids().count(), 0);
    assert_eq!(index.interface_ids().count(), 0, "rgb is listed as a node");
    assert!(index.launcher("renamed").is_none());
    assert!(index.launcher("demo").is_none());
    let found = all(index.findings(), Code::UnmatchedIndexEntry);
    assert_eq!(found.len(), 6, "{}", index.findings());
    let got: Vec<(&str, &str)> = found.iter().map(|d| (key(d), d.message.as_str())).collect();
    assert_eq!(
        got,
        [
            (
                "nodes.cam.v2.path",
                "node `cam:v2` is listed at `cam/peppy.json5`, which declares `cam:v1`"
            ),
            (
                "nodes.gone.v1.path",
                "node `gone:v1` is listed at `gone/peppy.json5`, which does not exist"
            ),
            (
                "nodes.rgb.v1.path",
                "node `rgb:v1` is listed at `rgb.json5`, which is not a node (its `peppy_schema` is `interface_v1`)"
            ),
            (
                "nodes.adir.v1.path",
                "node `adir:v1` is listed at `adir`, which is not a file"
            ),
            (
                "launchers.renamed.path",
                "launcher `renamed` is listed at `stacks/demo.json5`, which is launcher `demo` (a launcher is listed by its file stem)"
            ),
            (
                "launchers.frag.path",
                "launcher `frag` is listed at `frag.json5`, which is a `launcher_fragment/v1` document (fragments are never listed)"
            ),
        ]
    );
    for d in &found {
        assert_eq!(d.severity, Severity::Warning, "{d}");
        assert!(help(d).contains("peppy-launch repo index"), "{d}");
    }
    assert_eq!(lc(found[0]), pos(text, r#""cam/peppy.json5""#));
    assert_eq!(index.findings().len(), 6, "{}", index.findings());
}

#[test]
fn an_invalid_index_skips_its_repository_with_warnings() {
    let tree = Tree::new();
    tree.write("repo/cam/peppy.json5", &node_text("cam", "", "", ""));
    let text = r#"{ peppy_schema: "repository/v1", nodes: { cam: { v1: { path: "../cam/peppy.json5" } } } }"#;
    let index_path = tree.write(&format!("repo/{REPOSITORY_INDEX_FILE}"), text);
    tree.write("other/cam2/peppy.json5", &node_text("cam2", "", "", ""));
    let index = RepoIndex::scan(&[tree.path("repo"), tree.path("other")]);
    let nodes: Vec<String> = index.node_ids().map(ToString::to_string).collect();
    assert_eq!(nodes, ["cam2:v1"], "the other repository is still read");
    let bad = one(index.findings(), Code::NonCanonicalPath);
    assert_eq!(bad.severity, Severity::Warning);
    assert_eq!(lc(bad), pos(text, r#""../cam"#));
    let skipped = one(index.findings(), Code::DependencyNotFound);
    assert_eq!(
        skipped.message,
        format!(
            "repository `{}` is skipped: its `peppy_repository.json5` is invalid",
            tree.path("repo").display()
        )
    );
    assert_eq!(skipped.file_path(), Some(index_path.as_path()));
    assert!(!index.findings().has_errors());
}

#[test]
fn without_an_index_hidden_directories_like_github_are_not_walked() {
    let tree = Tree::new();
    tree.write("repo/cam/peppy.json5", &node_text("cam", "", "", ""));
    tree.write(
        "repo/.github/ci/peppy.json5",
        &node_text("ci_only", "", "", ""),
    );
    tree.write(
        "repo/.github/contract.json5",
        &interface_text("ci_if", "v1", ""),
    );
    let index = RepoIndex::scan(&[tree.path("repo")]);
    let nodes: Vec<String> = index.node_ids().map(ToString::to_string).collect();
    assert_eq!(nodes, ["cam:v1"]);
    assert_eq!(index.interface_ids().count(), 0);
    // `repo index` skips them too.
    let (declared, warnings) = declared_in(&tree.path("repo")).unwrap();
    assert!(warnings.is_empty(), "{warnings}");
    let keys: Vec<String> = declared.entries.keys().map(ToString::to_string).collect();
    assert_eq!(keys, ["node `cam:v1`"]);
}

// ---- What `repo index` writes ----

#[test]
fn the_written_index_lists_every_kind_from_raw_trees() {
    let tree = Tree::new();
    indexed_repo(&tree);
    tree.write(
        "repo/frag/arm.json5",
        r#"{ peppy_schema: "launcher_fragment/v1" }"#,
    );
    tree.write(
        "repo/mcp/arm.json5",
        r#"{ peppy_schema: "mcp_exposure/v1", manifest: { name: "arm_mcp", tag: "v1" } }"#,
    );
    tree.write("repo/zed/peppy.json5", &node_text("zed-2i", "", "", ""));
    tree.write(
        "repo/contracts/rgb_v2.json5",
        &interface_text("rgb", "v2", ""),
    );
    tree.write("repo/.hidden.json5", &node_text("hidden_file", "", "", ""));
    tree.write("repo/target/x/peppy.json5", &node_text("built", "", "", ""));
    tree.write("repo/settings.json5", "{ hello: 1 }");
    tree.write("repo/list.json5", "[1, 2]");
    let broken = tree.write("repo/notes/broken.json5", "{ oops ");
    let (declared, warnings) = declared_in(&tree.path("repo")).unwrap();
    let text = declared.render();
    assert_eq!(
        text,
        r#"{
  peppy_schema: "repository/v1",
  nodes: {
    cam: {
      v1: {
        path: "cam/peppy.json5"
      }
    },
    slashed_cam: {
      v1: {
        path: "slashed/peppy.json5"
      }
    },
    unlisted: {
      v1: {
        path: "unlisted/peppy.json5"
      }
    },
    "zed-2i": {
      v1: {
        path: "zed/peppy.json5"
      }
    }
  },
  launchers: {
    demo: {
      path: "stacks/demo.json5"
    },
    other: {
      path: "stacks/other.json5"
    }
  },
  contracts: {
    rgb: {
      v1: {
        path: "contracts/rgb.json5"
      },
      v2: {
        path: "contracts/rgb_v2.json5"
      }
    },
    unlisted_if: {
      v1: {
        path: "unlisted_iface.json5"
      }
    }
  },
  pairings: {
    joint_link: {
      v1: {
        path: "robot/joint_link.json5"
      }
    }
  },
  mcp_exposures: {
    arm_mcp: {
      v1: {
        path: "mcp/arm.json5"
      }
    }
  }
}
"#
    );
    // A file that is not JSON5 is skipped, with a warning.
    let w = one(&warnings, Code::Syntax);
    assert_eq!(w.severity, Severity::Warning);
    assert_eq!(w.file_path(), Some(broken.as_path()));
    assert!(help(w).ends_with("`repo index` skipped this file"), "{w}");
    assert_eq!(warnings.len(), 1, "{warnings}");

    // What is written reads back as the same entries.
    let (doc, _) = RepositoryIndexDoc::parse("i.json5", text).unwrap();
    let back: Vec<(&IndexKey, &str)> = doc
        .entries
        .iter()
        .map(|(k, l)| (k, l.path.as_str()))
        .collect();
    let written: Vec<(&IndexKey, &str)> = declared
        .entries
        .iter()
        .map(|(k, p)| (k, p.as_str()))
        .collect();
    assert_eq!(back, written);

    // Nothing declared: only the schema.
    assert_eq!(
        DeclaredIndex::default().render(),
        "{\n  peppy_schema: \"repository/v1\"\n}\n"
    );
}

#[test]
fn one_identity_claimed_twice_is_refused() {
    let tree = Tree::new();
    tree.write("repo/a/peppy.json5", &node_text("cam", "", "", ""));
    tree.write("repo/b/peppy.json5", &node_text("cam", "", "", ""));
    tree.write("repo/one/demo.json5", r#"{ peppy_schema: "launcher_v1" }"#);
    tree.write("repo/two/demo.json5", r#"{ peppy_schema: "launcher/v1" }"#);
    tree.write("repo/c1.json5", &interface_text("rgb", "v1", ""));
    tree.write(
        "repo/c2.json5",
        r#"{ peppy_schema: "contract/v1", manifest: { name: "rgb", tag: "v1" } }"#,
    );
    tree.write("repo/c3.json5", &interface_text("rgb", "v1", ""));
    let errors = declared_in(&tree.path("repo")).unwrap_err();
    let found = all(&errors, Code::DuplicateIdentity);
    let messages: Vec<&str> = found.iter().map(|d| d.message.as_str()).collect();
    assert_eq!(
        messages,
        [
            "2 node manifests claim `cam:v1`: a/peppy.json5, b/peppy.json5",
            "3 contract manifests claim `rgb:v1`: c1.json5, c2.json5, c3.json5",
            "2 launcher files claim `demo`: one/demo.json5, two/demo.json5",
        ]
    );
    assert_eq!(errors.len(), 3, "{errors}");
}

#[test]
fn identities_the_index_cannot_hold_are_refused_where_written() {
    let tree = Tree::new();
    let legacy_tag = r#"{ peppy_schema: "node/v1", manifest: { name: "cam", tag: "0.1.0" } }"#;
    let bad_tag = tree.write("repo/a/peppy.json5", legacy_tag);
    let no_manifest = tree.write("repo/b.json5", r#"{ peppy_schema: "pairing/v1" }"#);
    let number_name = r#"{ peppy_schema: "contract/v1", manifest: { name: 7, tag: "v1" } }"#;
    tree.write("repo/c.json5", number_name);
    let launcher = tree.write("repo/my.stack.json5", r#"{ peppy_schema: "launcher/v1" }"#);
    let errors = declared_in(&tree.path("repo")).unwrap_err();
    let tag = one(&errors, Code::InvalidTag);
    assert_eq!(tag.file_path(), Some(bad_tag.as_path()));
    assert_at(
        tag,
        Code::InvalidTag,
        "manifest.tag",
        legacy_tag,
        r#""0.1.0""#,
    );
    assert!(
        tag.message.starts_with(
            "`manifest.tag` `0.1.0` cannot be listed: must start with an ASCII letter"
        ),
        "{tag}"
    );
    let missing = one(&errors, Code::MissingKey);
    assert_eq!(missing.file_path(), Some(no_manifest.as_path()));
    assert_eq!(
        missing.message,
        "a `pairing/v1` document without a `manifest` cannot be listed"
    );
    let wrong = one(&errors, Code::WrongType);
    assert_at(wrong, Code::WrongType, "manifest.name", number_name, "7");
    let name = one(&errors, Code::InvalidName);
    assert_eq!(name.file_path(), Some(launcher.as_path()));
    assert!(
        name.message
            .starts_with("launcher file stem `my.stack` cannot be listed"),
        "{name}"
    );
    assert_eq!(errors.len(), 4, "{errors}");

    let missing_dir = declared_in(&tree.path("nowhere")).unwrap_err();
    assert!(missing_dir.contains(Code::CannotRead));
}

// ---- `repo index --check` ----

#[test]
fn check_reports_every_drift_at_once() {
    let tree = Tree::new();
    tree.write("repo/cam/peppy.json5", &node_text("cam", "", "", ""));
    tree.write(
        "repo/moved/here/peppy.json5",
        &node_text("mover", "", "", ""),
    );
    tree.write("repo/new/peppy.json5", &node_text("fresh", "", "", ""));
    tree.write("repo/rgb.json5", &interface_text("rgb", "v2", ""));
    tree.write(
        "repo/stacks/demo.json5",
        r#"{ peppy_schema: "launcher_v1" }"#,
    );
    let text = r#"{
  peppy_schema: "repository/v1",
  nodes: {
    cam: { v1: { path: "cam/peppy.json5" } },
    gone: { v1: { path: "gone/peppy.json5" } },
    mover: { v1: { path: "moved/peppy.json5" } },
  },
  launchers: { demo: { path: "stacks/demo.json5" } },
  contracts: { rgb: { v1: { path: "rgb.json5" } } },
}"#;
    tree.write(&format!("repo/{REPOSITORY_INDEX_FILE}"), text);
    let (check, warnings) = check_index(&tree.path("repo")).unwrap();
    assert!(warnings.is_empty(), "{warnings}");
    assert!(!check.is_current());
    let lines: Vec<String> = check.drifts.iter().map(ToString::to_string).collect();
    assert_eq!(
        lines,
        [
            "Unlisted: node `fresh:v1` is declared in `new/peppy.json5`, not listed",
            "Unmatched: node `gone:v1` is listed at `gone/peppy.json5` (line 5), which does not exist",
            "Moved: node `mover:v1` is listed at `moved/peppy.json5` (line 6), declared in `moved/here/peppy.json5`",
            "Unmatched: contract `rgb:v1` is listed at `rgb.json5` (line 9), which declares `rgb:v2`",
            "Unlisted: contract `rgb:v2` is declared in `rgb.json5`, not listed",
        ]
    );
    let kinds: Vec<&str> = check.drifts.iter().map(Drift::kind).collect();
    assert_eq!(
        kinds,
        ["Unlisted", "Unmatched", "Moved", "Unmatched", "Unlisted"]
    );
    assert_eq!(check.drifts[2].key(), &node_key("mover", "v1"));
    assert_eq!(
        check.drifts[3].key(),
        &key_of(IndexSection::Contracts, "rgb", "v1")
    );

    // Comments and formatting do not count; content does.
    let written = check.declared.render();
    tree.write(
        &format!("repo/{REPOSITORY_INDEX_FILE}"),
        &format!("// regenerated\n{}", written.replace("  ", "\t")),
    );
    let (check, _) = check_index(&tree.path("repo")).unwrap();
    assert!(check.is_current(), "{:?}", check.drifts);
}

#[test]
fn check_without_an_index_lists_everything_as_unlisted() {
    let tree = Tree::new();
    tree.write("repo/cam/peppy.json5", &node_text("cam", "", "", ""));
    let (check, _) = check_index(&tree.path("repo")).unwrap();
    assert!(check.index.is_none());
    assert!(!check.is_current());
    let kinds: Vec<&str> = check.drifts.iter().map(Drift::kind).collect();
    assert_eq!(kinds, ["Unlisted"]);
}

#[test]
fn check_reports_an_invalid_index_and_an_unindexable_tree_together() {
    let tree = Tree::new();
    tree.write("repo/a/peppy.json5", &node_text("cam", "", "", ""));
    tree.write("repo/b/peppy.json5", &node_text("cam", "", "", ""));
    tree.write(
        &format!("repo/{REPOSITORY_INDEX_FILE}"),
        r#"{ peppy_schema: "repository/v1", nodes: { cam: { v1: { path: "/a/peppy.json5" } } } }"#,
    );
    let errors = check_index(&tree.path("repo")).unwrap_err();
    assert_eq!(
        error_codes(&errors),
        [Code::DuplicateIdentity, Code::NonCanonicalPath],
        "{errors}"
    );
}
