//! SPEC 1.1: the rules of a node document.

use peppy_schema::{Code, RESERVED_SERVICE_NAMES, Severity, SlotKind, TopicSource};

use crate::support::*;

#[test]
fn duplicate_link_id_within_nodes() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: {
    name: "fusion",
    tag: "v1",
    depends_on: {
      nodes: [
        { name: "cam", tag: "v1", link_id: "front" },
        { name: "lidar", tag: "v1", link_id: "front" },
      ],
    },
  },
  execution: { language: "rust", run_cmd: ["./fusion"] },
}"#;
    let errors = node_err(text);
    assert_eq!(codes(&errors), [Code::DuplicateLinkId]);
    let d = one(&errors, Code::DuplicateLinkId);
    assert_at(
        d,
        Code::DuplicateLinkId,
        "manifest.depends_on.nodes[1]",
        text,
        r#"{ name: "lidar""#,
    );
    assert!(d.message.contains("duplicate link_id `front`"), "{d}");
    let (line, col) = pos(text, r#"{ name: "cam""#);
    assert!(
        help(d).contains(&format!("line {line}, column {col}")),
        "{d}"
    );
}

#[test]
fn duplicate_link_id_across_nodes_and_interfaces() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: {
    name: "fusion",
    tag: "v1",
    depends_on: {
      nodes: [{ name: "cam", tag: "v1", link_id: "front" }],
      interfaces: [{ name: "depth_camera", tag: "v1", link_id: "front" }],
    },
  },
  execution: { language: "rust", run_cmd: ["./fusion"] },
}"#;
    let errors = node_err(text);
    assert_eq!(codes(&errors), [Code::DuplicateLinkId]);
    let d = one(&errors, Code::DuplicateLinkId);
    assert_at(
        d,
        Code::DuplicateLinkId,
        "manifest.depends_on.interfaces[0]",
        text,
        r#"{ name: "depth_camera""#,
    );
    assert!(
        help(d).contains("unique across `nodes` and `interfaces`"),
        "{d}"
    );
}

#[test]
fn conflicting_from_any() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: {
    name: "fusion",
    tag: "v1",
    depends_on: {
      interfaces: [
        { name: "depth_camera", tag: "v1", link_id: "any_a", from_any: true },
        { name: "depth_camera", tag: "v2", link_id: "any_v2", from_any: true },
        { name: "depth_camera", tag: "v1", link_id: "any_b", from_any: true },
      ],
    },
  },
  execution: { language: "rust", run_cmd: ["./fusion"] },
}"#;
    let errors = node_err(text);
    assert_eq!(codes(&errors), [Code::ConflictingFromAny]);
    let d = one(&errors, Code::ConflictingFromAny);
    assert_at(
        d,
        Code::ConflictingFromAny,
        "manifest.depends_on.interfaces[2]",
        text,
        r#"{ name: "depth_camera", tag: "v1", link_id: "any_b""#,
    );
    assert!(
        d.message.contains("`depth_camera:v1`") && d.message.contains("`any_a`"),
        "{d}"
    );
}

#[test]
fn several_pinned_slots_may_share_a_name_and_tag() {
    let text = node_text(
        "recon",
        r#"interfaces: [
        { name: "depth_camera", tag: "v1", link_id: "left_cam" },
        { name: "depth_camera", tag: "v1", link_id: "right_cam" },
        { name: "depth_camera", tag: "v1", link_id: "backup_cams", from_any: true },
      ],
      nodes: [
        { name: "zed_2i", tag: "v1", link_id: "zed_a" },
        { name: "zed_2i", tag: "v1", link_id: "zed_b" },
      ]"#,
        "",
        "",
    );
    let (node, warnings) = node_ok(&text);
    assert!(warnings.is_empty(), "{warnings}");
    let slots: Vec<(&str, SlotKind, String, bool)> = node
        .dependencies
        .iter()
        .map(|d| (d.link_id.as_str(), d.kind, d.target.to_string(), d.from_any))
        .collect();
    // Node slots first, then interface slots, each in document order.
    assert_eq!(
        slots,
        [
            ("zed_a", SlotKind::Node, "zed_2i:v1".to_string(), false),
            ("zed_b", SlotKind::Node, "zed_2i:v1".to_string(), false),
            (
                "left_cam",
                SlotKind::Interface,
                "depth_camera:v1".to_string(),
                false
            ),
            (
                "right_cam",
                SlotKind::Interface,
                "depth_camera:v1".to_string(),
                false
            ),
            (
                "backup_cams",
                SlotKind::Interface,
                "depth_camera:v1".to_string(),
                true
            ),
        ]
    );
    assert_eq!(
        node.dependency("right_cam").unwrap().target.name,
        "depth_camera"
    );
}

#[test]
fn consumed_entries_must_use_declared_link_ids() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: {
    name: "consumer",
    tag: "v1",
    depends_on: { nodes: [{ name: "cam", tag: "v1", link_id: "cam" }] },
  },
  interfaces: {
    topics: { consumes: [{ link_id: "ghost", name: "frame" }] },
    services: { consumes: [{ link_id: "cam", name: "info" }, { link_id: "phantom", name: "info" }] },
    actions: { consumes: [{ link_id: "spectre", name: "calibrate" }] },
  },
  execution: { language: "rust", run_cmd: ["./consumer"] },
}"#;
    let errors = node_err(text);
    let found = all(&errors, Code::UndeclaredLinkId);
    assert_eq!(errors.len(), 3, "{errors}");
    assert_eq!(found.len(), 3);
    assert_at(
        found[0],
        Code::UndeclaredLinkId,
        "interfaces.topics.consumes[0]",
        text,
        r#"{ link_id: "ghost""#,
    );
    assert_at(
        found[1],
        Code::UndeclaredLinkId,
        "interfaces.services.consumes[1]",
        text,
        r#"{ link_id: "phantom""#,
    );
    assert_at(
        found[2],
        Code::UndeclaredLinkId,
        "interfaces.actions.consumes[0]",
        text,
        r#"{ link_id: "spectre""#,
    );
    assert!(
        found[0]
            .message
            .contains("consumed topic uses link_id `ghost`"),
        "{}",
        found[0]
    );
    assert!(
        found[1].message.contains("consumed service"),
        "{}",
        found[1]
    );
    assert!(found[2].message.contains("consumed action"), "{}", found[2]);
    assert!(
        help(found[0]).contains("declared link_ids: `cam`"),
        "{}",
        found[0]
    );
}

#[test]
fn consumed_services_and_actions_need_a_link_id() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "consumer", tag: "v1" },
  interfaces: {
    services: { consumes: [{ name: "video_stream_info" }] },
    actions: { consumes: [{ name: "calibrate" }] },
  },
  execution: { language: "rust", run_cmd: ["./consumer"] },
}"#;
    let errors = node_err(text);
    let found = all(&errors, Code::MissingLinkId);
    assert_eq!(errors.len(), 2, "{errors}");
    assert_at(
        found[0],
        Code::MissingLinkId,
        "interfaces.services.consumes[0]",
        text,
        r#"{ name: "video_stream_info" }"#,
    );
    assert_at(
        found[1],
        Code::MissingLinkId,
        "interfaces.actions.consumes[0]",
        text,
        r#"{ name: "calibrate" }"#,
    );
    assert_eq!(found[0].message, "a consumed service needs a `link_id`");
    assert_eq!(found[1].message, "a consumed action needs a `link_id`");
    assert!(
        help(found[0]).contains("only topics can be consumed externally"),
        "{}",
        found[0]
    );
}

#[test]
fn linked_consumed_topic_with_a_format_is_refused() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "consumer", tag: "v1", depends_on: { nodes: [{ name: "cam", tag: "v1", link_id: "cam" }] } },
  interfaces: {
    topics: { consumes: [{ link_id: "cam", name: "frame", message_format: { width: "u32" } }] },
  },
  execution: { language: "rust", run_cmd: ["./consumer"] },
}"#;
    let errors = node_err(text);
    assert_eq!(codes(&errors), [Code::LinkedFormatGiven]);
    let d = one(&errors, Code::LinkedFormatGiven);
    assert_at(
        d,
        Code::LinkedFormatGiven,
        "interfaces.topics.consumes[0].message_format",
        text,
        "message_format",
    );
    assert!(
        help(d).contains("remove `message_format`, or remove `link_id`"),
        "{d}"
    );
}

#[test]
fn consumed_topic_needs_a_link_id_or_a_format() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "consumer", tag: "v1" },
  interfaces: {
    topics: { consumes: [
      { name: "joint_commands", message_format: { max_velocity: "f64" } },
      { name: "joint_states" },
    ] },
  },
  execution: { language: "rust", run_cmd: ["./consumer"] },
}"#;
    let errors = node_err(text);
    assert_eq!(codes(&errors), [Code::ExternalFormatMissing]);
    let d = one(&errors, Code::ExternalFormatMissing);
    assert_at(
        d,
        Code::ExternalFormatMissing,
        "interfaces.topics.consumes[1]",
        text,
        r#"{ name: "joint_states" }"#,
    );

    // The external one alone is fine.
    let fixed = text.replace(r#"      { name: "joint_states" },"#, "");
    let (node, _) = node_ok(&fixed);
    match &node.consumed_topics[0].source {
        TopicSource::External(f) => assert_eq!(f.canonical(), "{max_velocity:f64}"),
        other => panic!("expected an external topic, got {other:?}"),
    }
}

#[test]
fn execution_needs_exactly_one_of_run_cmd_and_container() {
    let both = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  execution: {
    language: "rust",
    run_cmd: ["./cam"],
    container: { def_file: "cam.def" },
  },
}"#;
    let errors = node_err(both);
    assert_eq!(codes(&errors), [Code::ExecutionConflict]);
    let d = one(&errors, Code::ExecutionConflict);
    assert_at(
        d,
        Code::ExecutionConflict,
        "execution.container",
        both,
        "container",
    );
    assert!(d.message.contains("both"), "{d}");

    let neither = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  execution: { language: "python", build_cmd: ["pip", "install", "."] },
}"#;
    let errors = node_err(neither);
    assert_eq!(codes(&errors), [Code::ExecutionConflict]);
    let d = one(&errors, Code::ExecutionConflict);
    assert_at(
        d,
        Code::ExecutionConflict,
        "execution",
        neither,
        r#"{ language: "python", build"#,
    );
    assert!(d.message.contains("neither"), "{d}");
    assert!(help(d).contains("only `language: \"rust\"` nodes"), "{d}");

    // A Rust node built with cargo may leave its executable to cargo.
    for build in [
        "",
        r#"build_cmd: ["cargo", "build", "--release", "-p", "cam"],"#,
    ] {
        let cargo = format!(
            r#"{{ peppy_schema: "node_v1", manifest: {{ name: "cam", tag: "v1" }},
                 execution: {{ language: "rust", {build} }} }}"#
        );
        let (node, _) = node_ok(&cargo);
        assert_eq!(node.execution.launch(), peppy_schema::Launch::CargoBinary);
        assert_eq!(
            node.execution.build_command().unwrap()[..2],
            ["cargo", "build"]
        );
    }
    // ... but only when the build is a cargo build.
    let not_cargo = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  execution: { language: "rust", build_cmd: ["make"] },
}"#;
    let errors = node_err(not_cargo);
    let d = one(&errors, Code::ExecutionConflict);
    assert_at(
        d,
        Code::ExecutionConflict,
        "execution.build_cmd",
        not_cargo,
        r#"["make"]"#,
    );
    assert!(d.message.contains("not a `cargo build`"), "{d}");

    let container = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  execution: {
    language: "python",
    container: { def_file: "cam.def", mount_paths: ["/dev/video0"], apptainer_run_extra_args: ["--nv"] },
  },
}"#;
    let (node, _) = node_ok(container);
    assert_eq!(node.execution.language, "python");
    assert!(node.execution.run_cmd.is_none());
    let c = node
        .execution
        .container
        .as_ref()
        .expect("container carried");
    assert_eq!(c.def_file, "cam.def");
    assert_eq!(c.mount_paths, ["/dev/video0"]);
    assert_eq!(c.apptainer_run_extra_args, ["--nv"]);
    assert!(c.lima_shell_extra_args.is_empty());
}

#[test]
fn empty_commands_are_refused() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  execution: { language: "rust", build_cmd: [], run_cmd: ["  "] },
}"#;
    let errors = node_err(text);
    let found = all(&errors, Code::EmptyCommand);
    assert_eq!(found.len(), 2, "{errors}");
    assert_eq!(key(found[0]), "execution.build_cmd");
    assert_eq!(key(found[1]), "execution.run_cmd");
}

#[test]
fn unknown_keys_anywhere_with_did_you_mean() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: {
    name: "cam",
    tag: "v1",
    lables: ["x"],
    depends_on: { nodes: [{ name: "imu", tag: "v1", link_id: "imu", from_anyy: true }] },
  },
  interfaces: {
    conforms_to: [{ name: "depth_camera", tag: "v1", sha: "x" }],
    topics: {
      emits: [{ name: "frame", qos_profil: "sensor_data", message_format: { w: "u32" } }],
      consumes: [{ link_id: "imu", name: "accel", qos_profile: "standard" }],
    },
    services: { exposes: [{ name: "info", response_format: { w: "u32" } }] },
    actions: { exposes: [{ name: "calibrate", goal_service: { request_message_formt: { a: "u8" } } }] },
    parameters: {},
  },
  execution: {
    language: "rust",
    container: { def_file: "x.def", mount_path: ["/x"] },
    enviroment: {},
  },
  bogus: 1,
}"#;
    let errors = node_err(text);
    let found = all(&errors, Code::UnknownKey);
    assert_eq!(
        errors.error_count(),
        found.len(),
        "only unknown keys expected:\n{errors}"
    );
    let got: Vec<(&str, (usize, usize))> = found.iter().map(|d| (key(d), lc(d))).collect();
    let expected = [
        ("manifest.lables", pos(text, "lables")),
        (
            "manifest.depends_on.nodes[0].from_anyy",
            pos(text, "from_anyy"),
        ),
        ("interfaces.conforms_to[0].sha", pos(text, "sha:")),
        (
            "interfaces.topics.emits[0].qos_profil",
            pos(text, "qos_profil"),
        ),
        (
            "interfaces.topics.consumes[0].qos_profile",
            pos(text, r#"qos_profile: "standard""#),
        ),
        (
            "interfaces.services.exposes[0].response_format",
            pos(text, "response_format"),
        ),
        (
            "interfaces.actions.exposes[0].goal_service.request_message_formt",
            pos(text, "request_message_formt"),
        ),
        ("interfaces.parameters", pos(text, "parameters")),
        ("execution.container.mount_path", pos(text, "mount_path")),
        ("execution.enviroment", pos(text, "enviroment")),
        ("bogus", pos(text, "bogus")),
    ];
    assert_eq!(got, expected);

    let by_key = |k: &str| found.iter().find(|d| key(d) == k).copied().unwrap();
    let qos = by_key("interfaces.topics.emits[0].qos_profil");
    assert_eq!(
        qos.message,
        "unknown key `qos_profil` in `interfaces.topics.emits[0]`"
    );
    assert!(
        help(qos).starts_with("did you mean `qos_profile`?"),
        "{qos}"
    );
    assert!(
        help(qos).contains("accepted keys here: `name`, `qos_profile`, `message_format`"),
        "{qos}"
    );
    for (k, suggestion) in [
        ("manifest.lables", "labels"),
        ("manifest.depends_on.nodes[0].from_anyy", "from_any"),
        (
            "interfaces.actions.exposes[0].goal_service.request_message_formt",
            "request_message_format",
        ),
        ("execution.container.mount_path", "mount_paths"),
    ] {
        let d = by_key(k);
        assert!(
            help(d).starts_with(&format!("did you mean `{suggestion}`?")),
            "{d}"
        );
    }
    let top = by_key("bogus");
    assert_eq!(top.message, "unknown key `bogus` at the top level");
    assert!(!help(top).contains("did you mean"), "{top}");
    // A consumed topic takes its qos from the producer: no qos_profile there.
    assert!(
        help(by_key("interfaces.topics.consumes[0].qos_profile"))
            .contains("`name`, `link_id`, `message_format`")
    );
}

#[test]
fn tags_are_labels_not_versions() {
    for bad in ["0.1.0", "v1.2", "1", "-v1", ""] {
        let text = format!(
            r#"{{
  peppy_schema: "node_v1",
  manifest: {{ name: "cam", tag: "{bad}" }},
  execution: {{ language: "rust", run_cmd: ["./cam"] }},
}}"#
        );
        let errors = node_err(&text);
        assert_eq!(codes(&errors), [Code::InvalidTag], "{bad}: {errors}");
        let d = one(&errors, Code::InvalidTag);
        assert_at(
            d,
            Code::InvalidTag,
            "manifest.tag",
            &text,
            &format!("\"{bad}\""),
        );
        assert!(
            d.message
                .starts_with(&format!("invalid `manifest.tag` `{bad}`")),
            "{d}"
        );
    }
    for good in ["v1", "donut", "v1-beta", "V_2"] {
        let text = format!(
            r#"{{ peppy_schema: "node_v1", manifest: {{ name: "cam", tag: "{good}" }}, execution: {{ language: "rust", run_cmd: ["x"] }} }}"#
        );
        let (node, _) = node_ok(&text);
        assert_eq!(node.identity().to_string(), format!("cam:{good}"));
    }
    // Tags are checked wherever they appear.
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: {
    name: "cam",
    tag: "v1",
    depends_on: {
      nodes: [{ name: "imu", tag: "1.0", link_id: "imu" }],
      interfaces: [{ name: "depth_camera", tag: "v1.2", link_id: "cams" }],
    },
  },
  interfaces: { conforms_to: [{ name: "uvc", tag: "2.0.0" }] },
  execution: { language: "rust", run_cmd: ["./cam"] },
}"#;
    let errors = node_err(text);
    let found = all(&errors, Code::InvalidTag);
    assert_eq!(errors.error_count(), 3, "{errors}");
    assert_at(
        found[0],
        Code::InvalidTag,
        "manifest.depends_on.nodes[0].tag",
        text,
        r#""1.0""#,
    );
    assert_at(
        found[1],
        Code::InvalidTag,
        "manifest.depends_on.interfaces[0].tag",
        text,
        r#""v1.2""#,
    );
    assert_at(
        found[2],
        Code::InvalidTag,
        "interfaces.conforms_to[0].tag",
        text,
        r#""2.0.0""#,
    );
}

#[test]
fn invalid_names() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "my.cam", tag: "v1" },
  interfaces: { topics: { emits: [{ name: "a/b" }, { name: "" }, { name: "x@y" }] } },
  execution: { language: "rust", run_cmd: ["./cam"] },
}"#;
    let errors = node_err(text);
    assert_eq!(
        codes(&errors),
        [
            Code::InvalidName,
            Code::InvalidEntryName,
            Code::InvalidEntryName,
            Code::InvalidEntryName
        ]
    );
    let names = all(&errors, Code::InvalidEntryName);
    assert_at(
        names[0],
        Code::InvalidEntryName,
        "interfaces.topics.emits[0].name",
        text,
        r#""a/b""#,
    );
    assert_at(
        names[2],
        Code::InvalidEntryName,
        "interfaces.topics.emits[2].name",
        text,
        r#""x@y""#,
    );
    assert_at(
        one(&errors, Code::InvalidName),
        Code::InvalidName,
        "manifest.name",
        text,
        r#""my.cam""#,
    );
}

#[test]
fn duplicate_entry_names_within_one_list() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  interfaces: {
    topics: { emits: [
      { name: "frame", message_format: { w: "u32" } },
      { name: "status" },
      { name: "frame" },
    ] },
    services: { exposes: [{ name: "info" }, { name: "info" }] },
    actions: { exposes: [{ name: "calibrate" }, { name: "calibrate" }] },
  },
  execution: { language: "rust", run_cmd: ["./cam"] },
}"#;
    let errors = node_err(text);
    let found = all(&errors, Code::DuplicateEntryName);
    assert_eq!(errors.len(), 3, "{errors}");
    assert_at(
        found[0],
        Code::DuplicateEntryName,
        "interfaces.topics.emits[2].name",
        text,
        r#""frame" }"#,
    );
    assert_eq!(found[0].message, "duplicate topic name `frame`");
    let (line, col) = pos(text, r#""frame", message_format"#);
    assert_eq!(
        help(found[0]),
        format!("`frame` is already declared at line {line}, column {col}")
    );
    assert_eq!(key(found[1]), "interfaces.services.exposes[1].name");
    assert_eq!(found[1].message, "duplicate service name `info`");
    assert_eq!(key(found[2]), "interfaces.actions.exposes[1].name");
    assert_eq!(found[2].message, "duplicate action name `calibrate`");

    // The same name in different kinds is fine.
    let ok = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  interfaces: {
    topics: { emits: [{ name: "status" }] },
    services: { exposes: [{ name: "status" }] },
    actions: { exposes: [{ name: "status" }] },
  },
  execution: { language: "rust", run_cmd: ["./cam"] },
}"#;
    let (node, _) = node_ok(ok);
    assert_eq!(node.emits[0].name, "status");
    assert!(
        node.emits[0].format.is_none(),
        "no message_format means no payload"
    );
}

#[test]
fn consumed_entries_that_would_generate_the_same_module() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "c", tag: "v1", depends_on: { nodes: [{ name: "cam", tag: "v1", link_id: "cam" }] } },
  interfaces: { topics: { consumes: [
    { link_id: "cam", name: "frame" },
    { link_id: "cam", name: "frame" },
  ] } },
  execution: { language: "rust", run_cmd: ["./c"] },
}"#;
    let errors = node_err(text);
    let d = one(&errors, Code::DuplicateEntryName);
    assert_eq!(
        lc(d),
        pos_nth(text, r#"{ link_id: "cam", name: "frame" }"#, 1)
    );
    assert!(d.message.contains("consumed_topics::cam_frame"), "{d}");
}

#[test]
fn reserved_service_names() {
    for reserved in RESERVED_SERVICE_NAMES {
        let text = format!(
            r#"{{
  peppy_schema: "node_v1",
  manifest: {{ name: "cam", tag: "v1" }},
  interfaces: {{ services: {{ exposes: [{{ name: "ok" }}, {{ name: "{reserved}" }}] }} }},
  execution: {{ language: "rust", run_cmd: ["./cam"] }},
}}"#
        );
        let errors = node_err(&text);
        assert_eq!(codes(&errors), [Code::ReservedServiceName]);
        let d = one(&errors, Code::ReservedServiceName);
        assert_at(
            d,
            Code::ReservedServiceName,
            "interfaces.services.exposes[1].name",
            &text,
            &format!("\"{reserved}\""),
        );
        assert_eq!(
            d.message,
            format!("service name `{reserved}` is reserved by the runtime")
        );
        assert!(
            help(d).contains("`node_ready`, `node_health`, `shutdown`"),
            "{d}"
        );
    }
    // Only services are reserved: a topic may be called `shutdown`.
    let text = node_text(
        "cam",
        "",
        r#"topics: { emits: [{ name: "shutdown" }] }"#,
        "",
    );
    node_ok(&text);
}

#[test]
fn bad_qos_profile_suggests_the_closest() {
    let text = node_text(
        "cam",
        "",
        r#"topics: { emits: [{ name: "frame", qos_profile: "sensor-data" }] }"#,
        "",
    );
    let errors = node_err(&text);
    let d = one(&errors, Code::InvalidValue);
    assert_at(
        d,
        Code::InvalidValue,
        "interfaces.topics.emits[0].qos_profile",
        &text,
        r#""sensor-data""#,
    );
    assert!(help(d).starts_with("did you mean `sensor_data`?"), "{d}");
}

#[test]
fn every_error_of_a_document_is_reported_in_position_order() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "0.1.0",
    depends_on: {
      nodes: [{ name: "imu", tag: "v1", link_id: "imu", form_any: true }],
    },
  },
  interfaces: {
    topics: {
      emits: [{ name: "frame", qos_profil: "sensor_data" }],
      consumes: [{ name: "orphan" }],
    },
    services: {
      exposes: [{ name: "shutdown" }],
      consumes: [{ name: "calibrate" }],
    },
  },
  execution: { language: "python" },
}"#;
    let errors = node_err(text);
    let sorted = errors.sorted();
    let got: Vec<(Code, usize)> = sorted.iter().map(|d| (d.code, lc(d).0)).collect();
    assert_eq!(
        got,
        [
            (Code::InvalidTag, 3),
            (Code::UnknownKey, 5),
            (Code::UnknownKey, 10),
            (Code::ExternalFormatMissing, 11),
            (Code::ReservedServiceName, 14),
            (Code::MissingLinkId, 15),
            (Code::ExecutionConflict, 18),
        ]
    );
    assert!(sorted.iter().all(|d| d.severity == Severity::Error));
    assert!(
        sorted.windows(2).all(|w| lc(w[0]) < lc(w[1])),
        "positions increase"
    );
    assert_eq!(errors.error_count(), 7);
    // Display lists them in the same order, each with its help.
    let shown = errors.to_string();
    let first = shown.find("invalid `manifest.tag`").unwrap();
    let last = shown.find("neither `run_cmd` nor `container`").unwrap();
    assert!(first < last);
    assert!(
        shown.contains("\n  help: did you mean `from_any`?"),
        "{shown}"
    );
}

#[test]
fn wrong_types_and_missing_keys() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: 3, labels: "x" },
  interfaces: { topics: { emits: {} } },
  execution: { language: "rust", run_cmd: "./cam" },
}"#;
    let errors = node_err(text);
    let got: Vec<(Code, &str)> = errors.sorted().iter().map(|d| (d.code, key(d))).collect();
    assert_eq!(
        got,
        [
            (Code::MissingKey, "manifest"),
            (Code::WrongType, "manifest.name"),
            (Code::WrongType, "manifest.labels"),
            (Code::WrongType, "interfaces.topics.emits"),
            (Code::WrongType, "execution.run_cmd"),
        ]
    );
    let missing = one(&errors, Code::MissingKey);
    assert_eq!(missing.message, "missing required key `tag` in `manifest`");
}

#[test]
fn the_kind_comes_from_peppy_schema() {
    let errors = node_err(r#"{ peppy_schema: "node_v2", manifest: { name: "a", tag: "v1" } }"#);
    let d = one(&errors, Code::UnknownSchema);
    assert!(help(d).starts_with("did you mean `node_v1`?"), "{d}");
    let errors = node_err(
        r#"{ peppy_schema: "interface_v1", manifest: { name: "a", tag: "v1" }, interfaces: {} }"#,
    );
    let d = one(&errors, Code::WrongDocumentKind);
    assert_eq!(
        d.message,
        "expected a node document, found an interface document"
    );
    let errors = node_err(r#"{ manifest: { name: "a", tag: "v1" } }"#);
    assert!(
        one(&errors, Code::UnknownSchema)
            .message
            .starts_with("missing `peppy_schema`")
    );
}

#[test]
fn a_broken_depends_on_does_not_make_its_link_ids_undeclared() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: {
    name: "c",
    tag: "v1",
    depends_on: {
      nodes: [
        { name: "imu", tag: "v1", link_id: "imu" },
        { name: "gps", tag: "v1", link_id: "imu" },
      ],
      interfaces: [{ name: "clock", tag: "v1", link_id: "clk", from_any: "yes" }],
    },
  },
  interfaces: {
    topics: { consumes: [{ link_id: "imu", name: "accel" }, { link_id: "gyro", name: "rate" }] },
    services: { consumes: [{ link_id: "clk", name: "now" }] },
  },
  execution: { language: "rust", run_cmd: ["./c"] },
}"#;
    let errors = node_err(text);
    assert_eq!(
        codes(&errors),
        [
            Code::DuplicateLinkId,
            Code::WrongType,
            Code::UndeclaredLinkId
        ]
    );
    let d = one(&errors, Code::UndeclaredLinkId);
    assert_at(
        d,
        Code::UndeclaredLinkId,
        "interfaces.topics.consumes[1]",
        text,
        r#"{ link_id: "gyro""#,
    );
    assert_eq!(
        help(d),
        "declare it under `manifest.depends_on`; declared link_ids: `imu`, `clk`"
    );
}
