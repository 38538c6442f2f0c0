//! SPEC 1.4 / 6.1 / 6.2: launcher documents on their own (and the source
//! kinds `check_launcher` refuses).

use std::path::PathBuf;

use peppy_schema::{Code, Identity, RestartPolicy, Source};

use crate::support::*;

#[test]
fn instance_ids_are_unique_across_deployments() {
    let text = r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { name: "cam:v1" }, instances: [{ instance_id: "cam_1" }, { instance_id: "cam_2" }] },
    { source: { name: "lidar:v1" }, instances: [{ instance_id: "cam_1" }] },
  ],
}"#;
    let errors = launcher_err(text);
    assert_eq!(codes(&errors), [Code::DuplicateInstanceId]);
    let d = one(&errors, Code::DuplicateInstanceId);
    assert_at(
        d,
        Code::DuplicateInstanceId,
        "deployments[1].instances[0].instance_id",
        text,
        r#""cam_1" }] },
  ],"#,
    );
    assert_eq!(d.message, "duplicate instance_id `cam_1`");
    let (line, col) = pos(text, r#""cam_1""#);
    assert!(
        help(d).contains(&format!("already used at line {line}, column {col}")),
        "{d}"
    );
}

#[test]
fn binding_targets_must_be_declared() {
    let text = r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { name: "cam:v1" }, instances: [{ instance_id: "rs_left" }] },
    { source: { name: "recon:v1" }, instances: [{ instance_id: "recon", bindings: { left_cam: "rs_lfet", right_cam: "zzz" } }] },
  ],
}"#;
    let errors = launcher_err(text);
    let found = all(&errors, Code::UnknownBindingTarget);
    assert_eq!(errors.len(), 2, "{errors}");
    assert_at(
        found[0],
        Code::UnknownBindingTarget,
        "deployments[1].instances[0].bindings.left_cam",
        text,
        r#""rs_lfet""#,
    );
    assert_eq!(
        found[0].message,
        "binding `left_cam` on instance `recon` names `rs_lfet`, which no deployment declares"
    );
    assert_eq!(
        help(found[0]),
        "did you mean `rs_left`? instances in this launcher: `rs_left`, `recon`"
    );
    assert_eq!(
        help(found[1]),
        "instances in this launcher: `rs_left`, `recon`"
    );
}

#[test]
fn reserved_and_duplicate_binding_keys() {
    let text = r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { name: "cam:v1" }, instances: [{ instance_id: "a" }, { instance_id: "b" }] },
    { source: { name: "recon:v1" }, instances: [
      { instance_id: "r1", bindings: { _: "a" } },
      { instance_id: "r2", bindings: { left: "a", left: "b" } },
    ] },
  ],
}"#;
    let errors = launcher_err(text);
    assert_eq!(
        codes(&errors),
        [Code::ReservedBindingKey, Code::DuplicateBindingKey]
    );
    let reserved = one(&errors, Code::ReservedBindingKey);
    assert_at(
        reserved,
        Code::ReservedBindingKey,
        "deployments[1].instances[0].bindings._",
        text,
        "_:",
    );
    assert_eq!(reserved.message, "binding key `_` is reserved");
    let dup = one(&errors, Code::DuplicateBindingKey);
    assert_eq!(lc(dup), pos_nth(text, "left:", 1));
    assert_eq!(dup.message, "instance `r2` has binding key `left` twice");
    assert!(
        help(dup).contains(&format!(
            "line {}, column {}",
            pos(text, "left:").0,
            pos(text, "left:").1
        )),
        "{dup}"
    );
}

#[test]
fn deployments_need_instances() {
    let text = r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { name: "cam:v1" }, instances: [] },
  ],
}"#;
    let errors = launcher_err(text);
    assert_eq!(codes(&errors), [Code::EmptyDeployment]);
    assert_at(
        one(&errors, Code::EmptyDeployment),
        Code::EmptyDeployment,
        "deployments[0].instances",
        text,
        "[] }",
    );

    let errors = launcher_err(r#"{ peppy_schema: "launcher_v1", deployments: [] }"#);
    assert_eq!(codes(&errors), [Code::InvalidValue]);
    let errors = launcher_err(r#"{ peppy_schema: "launcher_v1" }"#);
    assert_eq!(codes(&errors), [Code::MissingKey]);
}

#[test]
fn source_forms() {
    let text = r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { name: "cam:v1" }, instances: [{ instance_id: "a" }] },
    { source: { name: "lidar", tag: "v2" }, instances: [{ instance_id: "b" }] },
    { source: { local: "../nodes/recon" }, instances: [{ instance_id: "c" }] },
    { source: { repo: "https://example.invalid/x.git", path: "nodes/imu", ref: "main" }, instances: [{ instance_id: "d" }] },
    { source: { url: "file:///tmp/x.tar.gz", sha256: "0000000000000000000000000000000000000000000000000000000000000000" }, instances: [{ instance_id: "e" }] },
  ],
}"#;
    let l = launcher_ok(text);
    let sources: Vec<&Source> = l.deployments.iter().map(|d| &d.source).collect();
    assert_eq!(
        sources,
        [
            &Source::Repository {
                identity: Identity::new("cam", "v1")
            },
            &Source::Repository {
                identity: Identity::new("lidar", "v2")
            },
            &Source::Local {
                path: PathBuf::from("../nodes/recon")
            },
            &Source::Git {
                repo: "https://example.invalid/x.git".into(),
                path: "nodes/imu".into(),
                reference: "main".into()
            },
            &Source::Archive {
                url: "file:///tmp/x.tar.gz".into(),
                sha256: "0".repeat(64)
            },
        ]
    );
    assert_eq!(
        l.deployments[2].source_loc.key_path,
        "deployments[2].source"
    );
    let ids: Vec<&str> = l.instances().map(|(_, i)| i.instance_id.as_str()).collect();
    assert_eq!(ids, ["a", "b", "c", "d", "e"]);
}

#[test]
fn malformed_sources() {
    let cases: &[(&str, Code, &str)] = &[
        (
            r#"{ name: "cam" }"#,
            Code::InvalidSource,
            "`source.name` `cam` has no tag",
        ),
        (
            r#"{ name: "cam:v1", tag: "v1" }"#,
            Code::InvalidSource,
            "`source.name` `cam:v1` already has a tag",
        ),
        (
            r#"{ local: "x", name: "cam:v1" }"#,
            Code::InvalidSource,
            "`source` mixes `local` keys with `name`",
        ),
        (r#"{}"#, Code::InvalidSource, "`source` names no node"),
        (
            r#"{ local: "  " }"#,
            Code::InvalidSource,
            "`source.local` is empty",
        ),
        (
            r#"{ name: "cam:v 1" }"#,
            Code::InvalidTag,
            "invalid tag `v 1`",
        ),
        (
            r#"{ name: "my cam:v1" }"#,
            Code::InvalidName,
            "invalid node name `my cam`",
        ),
        (
            r#"{ repo: "r", path: "../up", ref: "main" }"#,
            Code::InvalidSource,
            "must be relative to the repository",
        ),
        (
            r#"{ url: "file:///x", sha256: "abc" }"#,
            Code::InvalidValue,
            "must be 64 lowercase hex characters",
        ),
        (
            r#"{ url: "file:///x" }"#,
            Code::MissingKey,
            "missing required key `sha256`",
        ),
    ];
    for (source, code, message) in cases {
        let text = format!(
            r#"{{ peppy_schema: "launcher_v1", deployments: [{{ source: {source}, instances: [{{ instance_id: "a" }}] }}] }}"#
        );
        let errors = launcher_err(&text);
        assert_eq!(codes(&errors), [*code], "{source}: {errors}");
        let d = one(&errors, *code);
        assert!(d.message.contains(message), "{source}: {d}");
        assert!(key(d).starts_with("deployments[0].source"), "{d}");
    }
}

#[test]
fn loader_env_vars_are_forbidden() {
    let text = r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { name: "cam:v1" }, instances: [
      { instance_id: "a", env_vars: { RUST_LOG: "debug", LD_PRELOAD: "/tmp/evil.so" } },
      { instance_id: "b", env_vars: { ld_library_path: "/tmp" } },
    ] },
  ],
}"#;
    let errors = launcher_err(text);
    let found = all(&errors, Code::ForbiddenEnvVar);
    assert_eq!(errors.len(), 2, "{errors}");
    assert_at(
        found[0],
        Code::ForbiddenEnvVar,
        "deployments[0].instances[0].env_vars.LD_PRELOAD",
        text,
        "LD_PRELOAD",
    );
    assert_eq!(
        found[0].message,
        "`LD_PRELOAD` may not be set by a launcher"
    );
    assert_eq!(
        key(found[1]),
        "deployments[0].instances[1].env_vars.ld_library_path"
    );

    let ok = launcher_ok(
        r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "cam:v1" }, instances: [
            { instance_id: "a", env_vars: { RUST_LOG: "debug", CAMERA: "front" } } ] }] }"#,
    );
    let env = &ok.deployments[0].instances[0].env_vars;
    assert_eq!(
        env,
        &[
            ("RUST_LOG".to_string(), "debug".to_string()),
            ("CAMERA".to_string(), "front".to_string())
        ]
    );
}

#[test]
fn restart_policies() {
    let l = launcher_ok(
        r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "cam:v1" }, instances: [
            { instance_id: "a" },
            { instance_id: "b", restart: "no" },
            { instance_id: "c", restart: "on-failure" },
            { instance_id: "d", restart: "always" },
        ] }] }"#,
    );
    let policies: Vec<RestartPolicy> = l.instances().map(|(_, i)| i.restart).collect();
    assert_eq!(
        policies,
        [
            RestartPolicy::No,
            RestartPolicy::No,
            RestartPolicy::OnFailure,
            RestartPolicy::Always
        ]
    );

    let text = r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "cam:v1" }, instances: [
            { instance_id: "a", restart: "on_failure" },
            { instance_id: "b", restart: true },
        ] }] }"#;
    let errors = launcher_err(text);
    assert_eq!(codes(&errors), [Code::InvalidValue, Code::WrongType]);
    let d = one(&errors, Code::InvalidValue);
    assert_at(
        d,
        Code::InvalidValue,
        "deployments[0].instances[0].restart",
        text,
        r#""on_failure""#,
    );
    assert_eq!(d.message, "unknown restart policy `on_failure`");
    assert_eq!(help(d), "accepted: `no`, `on-failure`, `always`");
}

#[test]
fn instance_shape() {
    let text = r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "cam:v1" }, instances: [
            { instance_id: "a.b", binding: {}, arguments: [1] },
        ] }] }"#;
    let errors = launcher_err(text);
    let got: Vec<(Code, &str)> = errors.sorted().iter().map(|d| (d.code, key(d))).collect();
    assert_eq!(
        got,
        [
            (Code::InvalidName, "deployments[0].instances[0].instance_id"),
            (Code::UnknownKey, "deployments[0].instances[0].binding"),
            (Code::WrongType, "deployments[0].instances[0].arguments"),
        ]
    );
    assert!(help(one(&errors, Code::UnknownKey)).starts_with("did you mean `bindings`?"));
}

/// Without the launcher's fetcher (a plain `check_launcher`), git and
/// archive sources are refused where they stand, and the message sends the
/// reader to `peppy-launch check` and `up`, which fetch them.
#[test]
fn remote_sources_without_a_fetcher_point_to_the_launcher() {
    let tree = Tree::new();
    let text = r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { repo: "file:///srv/git/cams.git", path: "nodes/cam", ref: "v1" }, instances: [{ instance_id: "a" }] },
    { source: { url: "file:///srv/cam.tar.gz", sha256: "1111111111111111111111111111111111111111111111111111111111111111" }, instances: [{ instance_id: "b" }] },
  ],
}"#;
    let path = tree.write("stack.json5", text);
    let errors = stack_err(&path);
    let found = all(&errors, Code::UnsupportedSource);
    assert_eq!(errors.error_count(), 2, "{errors}");
    assert_at(
        found[0],
        Code::UnsupportedSource,
        "deployments[0].source",
        text,
        "{ repo:",
    );
    assert_eq!(
        found[0].message,
        "git (`repo`/`path`/`ref`) sources are not supported here (`peppy-launch check` and `up` fetch them)"
    );
    assert_at(
        found[1],
        Code::UnsupportedSource,
        "deployments[1].source",
        text,
        "{ url:",
    );
    assert_eq!(
        found[1].message,
        "archive (`url`/`sha256`) sources are not supported here (`peppy-launch check` and `up` fetch them)"
    );
    assert!(
        help(found[0]).contains("{ local: \"path\" }"),
        "{}",
        found[0]
    );
    assert_eq!(found[0].file_path(), Some(path.as_path()));
}

/// Rules 7 and 8 are reported together with binding and parameter errors
/// by `check_launcher`, and on their own by a document-level parse.
#[test]
fn stack_rules_join_the_binding_plan_errors() {
    let dir = tempfile::tempdir().unwrap();
    let examples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let launcher = r#"{ peppy_schema: "launcher_v1", deployments: [
        { source: { name: "realsense_d405:v1" }, instances: [{ instance_id: "cam" }, { instance_id: "cam" }] },
        { source: { name: "video_reconstruction:v1" }, instances: [
            { instance_id: "recon", bindings: { left_cam: "cma", right_cam: "cam", junk: "recon", } },
        ] },
    ] }"#;
    let path = dir.path().join("l.json5");
    std::fs::write(&path, launcher).unwrap();
    let options = peppy_schema::RepoOptions {
        explicit: vec![examples],
        env: Some(Default::default()),
        last: Vec::new(),
    };
    let err = peppy_schema::check_launcher(&path, &options).unwrap_err();
    let mut codes: Vec<peppy_schema::Code> = err.errors().map(|d| d.code).collect();
    codes.sort();
    let mut expected = vec![
        peppy_schema::Code::DuplicateInstanceId,
        peppy_schema::Code::UnknownBindingTarget,
        peppy_schema::Code::DeadBindingKey,
    ];
    expected.sort();
    assert_eq!(codes, expected, "{err}");
    let parse_only = peppy_schema::LauncherDoc::load(&path).unwrap_err();
    assert!(parse_only.contains(peppy_schema::Code::DuplicateInstanceId));
    assert!(parse_only.contains(peppy_schema::Code::UnknownBindingTarget));
}

/// Placement: `core_nodes` as a list or with endpoints, and `core_node` on
/// instances.
#[test]
fn core_nodes_name_the_machines_and_instances_are_placed_on_them() {
    let listed = launcher_ok(
        r#"{ peppy_schema: "launcher_v1", core_nodes: ["robot", "workstation"],
            deployments: [{ source: { name: "cam:v1" }, instances: [
                { instance_id: "cam", core_node: "robot" }, { instance_id: "spare" } ] }] }"#,
    );
    let names: Vec<&str> = listed.core_nodes.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["robot", "workstation"]);
    let placed: Vec<Option<&str>> = listed
        .instances()
        .map(|(_, i)| i.core_node.as_ref().map(|(n, _)| n.as_str()))
        .collect();
    assert_eq!(placed, [Some("robot"), None]);

    let with_endpoints = launcher_ok(
        r#"{ peppy_schema: "launcher_v1",
            core_nodes: { robot: { listen: ["tcp/0.0.0.0:7447"] },
                          workstation: { connect: ["tcp/192.0.2.10:7447"] } },
            deployments: [{ source: { name: "cam:v1" }, instances: [{ instance_id: "cam", core_node: "robot" }] }] }"#,
    );
    let robot = &with_endpoints.core_nodes[0];
    assert_eq!(
        (robot.name.as_str(), robot.listen.as_slice()),
        ("robot", &["tcp/0.0.0.0:7447".to_string()][..])
    );
    assert_eq!(
        with_endpoints.core_nodes[1].connect,
        ["tcp/192.0.2.10:7447"]
    );
}

#[test]
fn placement_on_an_undeclared_core_node_is_located() {
    let text = r#"{
  peppy_schema: "launcher_v1",
  core_nodes: ["robot", "workstation"],
  deployments: [
    { source: { name: "cam:v1" }, instances: [{ instance_id: "cam", core_node: "robto" }] },
  ],
}"#;
    let errors = launcher_err(text);
    assert_eq!(codes(&errors), [Code::UnknownCoreNode]);
    let d = one(&errors, Code::UnknownCoreNode);
    assert_at(
        d,
        Code::UnknownCoreNode,
        "deployments[0].instances[0].core_node",
        text,
        r#""robto""#,
    );
    assert_eq!(
        d.message,
        "instance `cam` is placed on core node `robto`, which `core_nodes` does not declare"
    );
    assert!(help(d).starts_with("did you mean `robot`?"), "{d}");

    // Placing anything needs the machines declared.
    let undeclared = launcher_err(
        r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "cam:v1" },
            instances: [{ instance_id: "cam", core_node: "robot" }] }] }"#,
    );
    assert!(help(one(&undeclared, Code::UnknownCoreNode)).contains("core_nodes: [\"robot\""));
}

#[test]
fn bad_core_node_declarations_are_reported() {
    let twice = launcher_err(
        r#"{ peppy_schema: "launcher_v1", core_nodes: ["robot", "robot"],
            deployments: [{ source: { name: "cam:v1" }, instances: [{ instance_id: "cam" }] }] }"#,
    );
    assert_eq!(codes(&twice), [Code::DuplicateCoreNode]);
    let bad = launcher_err(
        r#"{ peppy_schema: "launcher_v1",
            core_nodes: { "a b": {}, robot: { listen: ["7447"], bogus: [] } },
            deployments: [{ source: { name: "cam:v1" }, instances: [{ instance_id: "cam" }] }] }"#,
    );
    let mut found = codes(&bad);
    found.sort_by_key(|c| c.to_string());
    assert_eq!(
        found,
        [Code::InvalidName, Code::InvalidValue, Code::UnknownKey],
        "{bad}"
    );
    let empty = launcher_err(
        r#"{ peppy_schema: "launcher_v1", core_nodes: [],
            deployments: [{ source: { name: "cam:v1" }, instances: [{ instance_id: "cam" }] }] }"#,
    );
    assert_eq!(codes(&empty), [Code::InvalidValue]);
    let wrong = launcher_err(
        r#"{ peppy_schema: "launcher_v1", core_nodes: "robot",
            deployments: [{ source: { name: "cam:v1" }, instances: [{ instance_id: "cam" }] }] }"#,
    );
    assert_eq!(codes(&wrong), [Code::WrongType]);
}
