//! `launcher/v1` launchers (current_peppyos.md §5.1-§5.3, §3
//! "Vacancy"): read into the launcher model with `links` instead of
//! `bindings`, parse-time rules only; a composed launcher reads as its
//! default selection (composition itself: composition.rs).

use std::path::PathBuf;

use peppy_schema::{
    Code, Document, DocumentKind, Identity, LinkValue, RestartPolicy, Source, SourceFile, Spelling,
    parse_document,
};

use crate::support::*;

/// A `launcher/v1` with one deployment of `cam:v1` and the given
/// instances, plus a second deployment holding `a` and `b` to link to.
fn with_instances(instances: &str) -> String {
    format!(
        r#"{{
  peppy_schema: "launcher/v1",
  deployments: [
    {{ source: {{ name: "prod", tag: "v1" }}, instances: [{{ instance_id: "a" }}, {{ instance_id: "b" }}] }},
    {{ source: {{ name: "cons:v1" }}, instances: [
      {instances}
    ] }},
  ],
}}"#
    )
}

/// Shaped like the launchers hub's `examples/rust_robot.json5`: both
/// source forms, scalar links, arguments.
const RUST_ROBOT: &str = r#"{
  peppy_schema: "launcher/v1",
  deployments: [
    {
      // By `name:tag` from the repositories.
      source: { name: "robot_brain:v1" },
      instances: [
        { instance_id: "the_brain", links: { camera: "the_camera", robot_controller: "the_controller" } },
      ],
    },
    {
      source: { name: "robot_backbone", tag: "v1" },
      instances: [
        { instance_id: "the_controller", links: { left_robot_arm: "the_left_arm", right_robot_arm: "the_right_arm" } },
      ],
    },
    {
      source: { name: "robot_arm:v1" },
      instances: [{ instance_id: "the_right_arm" }, { instance_id: "the_left_arm" }],
    },
    {
      source: { name: "uvc_camera_mock:v1" },
      instances: [
        {
          instance_id: "the_camera",
          arguments: { device_path: "/dev/video0", video: { frame_rate: 30, resolution: { width: 1920, height: 1080 } } },
        },
      ],
    },
  ],
}
"#;

#[test]
fn a_flat_launcher_like_the_hubs_rust_robot_reads() {
    let l = launcher_ok(RUST_ROBOT);
    assert_eq!(l.spelling, Spelling::SlashIds);
    assert!(l.core_nodes.is_empty());
    let sources: Vec<&Source> = l.deployments.iter().map(|d| &d.source).collect();
    assert_eq!(
        sources,
        [
            &Source::Repository {
                identity: Identity::new("robot_brain", "v1")
            },
            &Source::Repository {
                identity: Identity::new("robot_backbone", "v1")
            },
            &Source::Repository {
                identity: Identity::new("robot_arm", "v1")
            },
            &Source::Repository {
                identity: Identity::new("uvc_camera_mock", "v1")
            },
        ]
    );
    let brain = &l.deployments[0].instances[0];
    assert!(
        brain
            .links
            .iter()
            .all(|l| !matches!(l.value, peppy_schema::LinkValue::Bound(_)))
    );
    assert_eq!(brain.framework.use_sim_time, None);
    let links: Vec<(&str, String)> = brain
        .links
        .iter()
        .map(|k| {
            let LinkValue::One(t) = &k.value else {
                panic!("scalar link expected: {k:?}")
            };
            (k.key.as_str(), t.to_string())
        })
        .collect();
    assert_eq!(
        links,
        [
            ("camera", "the_camera".to_string()),
            ("robot_controller", "the_controller".to_string())
        ]
    );
    let camera = &brain.links[0];
    assert_eq!(
        camera.key_loc.key_path,
        "deployments[0].instances[0].links.camera"
    );
    assert_eq!(
        lc_of(&camera.key_loc),
        pos(RUST_ROBOT, "camera: \"the_camera\"")
    );
    assert_eq!(lc_of(camera.value.loc()), pos(RUST_ROBOT, "\"the_camera\""));
    let cam = &l.deployments[3].instances[0];
    assert!(cam.links.is_empty());
    assert!(cam.arguments.is_some());

    // The kind is read from `peppy_schema`, as for every document.
    let (doc, _) = parse_document(&SourceFile::new("stack.json5", RUST_ROBOT), "")
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(doc.kind(), DocumentKind::Launcher);
    assert!(matches!(doc, Document::Launcher(_)));
}

fn lc_of(loc: &peppy_schema::Loc) -> (usize, usize) {
    let at = loc.file.line_col(loc.span.start);
    (at.line, at.column)
}

/// Shaped like the hub's `examples/split_compute_manipulation.json5`:
/// core node placeholders, placement, a pairing target naming the peer's
/// slot, lists, a vacancy, framework knobs and environment.
const SPLIT: &str = r#"{
  peppy_schema: "launcher/v1",
  core_nodes: ["robot_onboard", "cloud_inference"],
  deployments: [
    { source: { name: "uvc_camera", tag: "v1" }, instances: [
      { instance_id: "wrist_cam", core_node: "robot_onboard", env_vars: { RUST_LOG: "info,cam=debug", DEVICE: "/dev/video0" } },
      { instance_id: "chest_cam", core_node: "robot_onboard" },
    ] },
    { source: { name: "reactive_policy", tag: "v1" }, instances: [
      { instance_id: "reflex", core_node: "robot_onboard", framework: { use_sim_time: true }, restart: "on-failure",
        links: { camera: "wrist_cam", deliberation: "planner/deliberation", cameras: ["wrist_cam", "chest_cam"], extras: [],
                 logger: { vacant: "  no logger on this rig  " } } },
    ] },
    { source: { name: "planner", tag: "v1" }, instances: [
      { instance_id: "planner", core_node: "cloud_inference", framework: {}, links: { scene: "wrist_cam" } },
    ] },
  ],
  security: false,
}"#;

#[test]
fn placement_pairing_targets_lists_vacancies_and_framework_read() {
    let l = launcher_ok(SPLIT);
    let names: Vec<&str> = l.core_nodes.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["robot_onboard", "cloud_inference"]);
    let placed: Vec<(&str, Option<&str>)> = l
        .instances()
        .map(|(_, i)| {
            (
                i.instance_id.as_str(),
                i.core_node.as_ref().map(|(n, _)| n.as_str()),
            )
        })
        .collect();
    assert_eq!(
        placed,
        [
            ("wrist_cam", Some("robot_onboard")),
            ("chest_cam", Some("robot_onboard")),
            ("reflex", Some("robot_onboard")),
            ("planner", Some("cloud_inference")),
        ]
    );
    assert_eq!(l.security.as_ref().map(|(on, _)| *on), Some(false));
    let cam = &l.deployments[0].instances[0];
    assert_eq!(
        cam.env_vars,
        [
            ("RUST_LOG".to_string(), "info,cam=debug".to_string()),
            ("DEVICE".to_string(), "/dev/video0".to_string())
        ]
    );
    let reflex = &l.deployments[1].instances[0];
    assert_eq!(reflex.framework.use_sim_time, Some(true));
    assert_eq!(reflex.restart, RestartPolicy::OnFailure);
    let keys: Vec<&str> = reflex.links.iter().map(|k| k.key.as_str()).collect();
    assert_eq!(
        keys,
        ["camera", "deliberation", "cameras", "extras", "logger"]
    );
    let LinkValue::One(pair) = &reflex.links[1].value else {
        panic!("{:?}", reflex.links[1])
    };
    assert_eq!(
        (pair.instance.as_str(), pair.peer_slot.as_deref()),
        ("planner", Some("deliberation"))
    );
    assert_eq!(lc_of(&pair.loc), pos(SPLIT, "\"planner/deliberation\""));
    let LinkValue::Many(cams, list_loc) = &reflex.links[2].value else {
        panic!("{:?}", reflex.links[2])
    };
    let cams: Vec<String> = cams.iter().map(ToString::to_string).collect();
    assert_eq!(cams, ["wrist_cam", "chest_cam"]);
    assert_eq!(lc_of(list_loc), pos(SPLIT, "[\"wrist_cam\""));
    assert_eq!(
        reflex.links[2].value.targets()[1].loc.key_path,
        "deployments[1].instances[0].links.cameras[1]"
    );
    assert!(matches!(&reflex.links[3].value, LinkValue::Many(v, _) if v.is_empty()));
    let LinkValue::Vacant { reason, loc } = &reflex.links[4].value else {
        panic!("{:?}", reflex.links[4])
    };
    assert_eq!(reason, "no logger on this rig");
    assert_eq!(loc.key_path, "deployments[1].instances[0].links.logger");
    assert!(reflex.links[4].value.targets().is_empty());
    let planner = &l.deployments[2].instances[0];
    assert_eq!(planner.framework.use_sim_time, None);
}

/// Shaped like the hub's `openarm/openarm_v2.json5`: a family whose base
/// links to instances only its fragments define. Parsed from text with no
/// fragment files beside it, the one error is the missing fragment, where
/// the option names it; nothing it causes.
#[test]
fn a_composed_launcher_without_its_fragments_names_the_missing_one() {
    let text = r#"{
  peppy_schema: "launcher/v1",
  components: [
    { name: "robot", provides: ["left_arm_inst"], default: "real",
      options: { real: { deployments: [{ source: { name: "openarm_arm", tag: "v1" }, instances: [{ instance_id: "left_arm_inst" }] }] },
                 mujoco: ["fragments/sim_relays.json5"] } },
  ],
  constraints: [{ forbids: [{ robot: "mujoco" }], reason: "x" }],
  adjustments: [{ target: "backbone_inst", set_arguments: { hardware_version: "v2" } }],
  deployments: [
    { source: { name: "openarm_backbone", tag: "v1" }, instances: [
      { instance_id: "backbone_inst", links: { left_arm_link: "left_arm_inst", pose: { vacant: "joints" } } },
    ] },
  ],
}"#;
    let errors = launcher_err(text);
    assert_eq!(codes(&errors), [Code::FragmentUnreadable], "{errors}");
    assert_at(
        one(&errors, Code::FragmentUnreadable),
        Code::FragmentUnreadable,
        "components[0].options.mujoco[0]",
        text,
        "\"fragments/sim_relays.json5\"",
    );

    // A family needs an axis.
    let bare = r#"{ peppy_schema: "launcher/v1", components: [] }"#;
    let errors = launcher_err(bare);
    assert_eq!(codes(&errors), [Code::InvalidValue], "{errors}");
    assert_at(
        one(&errors, Code::InvalidValue),
        Code::InvalidValue,
        "components",
        bare,
        "[]",
    );
}

#[test]
fn a_fragment_is_not_a_document_on_its_own() {
    let text = r#"{
  peppy_schema: "launcher_fragment/v1",
  deployments: [{ source: { name: "zed_camera", tag: "v1" }, instances: [{ instance_id: "chest" }] }],
  adjustments: [{ target: "recorder_inst", add_links: { rgbd_cameras: ["chest"] } }],
}"#;
    let errors = parse_document(&SourceFile::new("cameras.json5", text), "")
        .expect_err("a fragment is read through a launcher");
    assert_eq!(codes(&errors), [Code::WrongDocumentKind], "{errors}");
    let d = one(&errors, Code::WrongDocumentKind);
    assert_at(
        d,
        Code::WrongDocumentKind,
        "peppy_schema",
        text,
        "\"launcher_fragment/v1\"",
    );
    assert!(help(d).contains("`components`"), "{d}");
    // Asked for as a launcher, the same error.
    let errors = launcher_err(text);
    assert_eq!(codes(&errors), [Code::WrongDocumentKind], "{errors}");
}

/// Each spelling refuses the other's way of filling slots, and says which
/// spelling it belongs to.
#[test]
fn each_spelling_refuses_the_others_slot_key() {
    let underscored = r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "cam:v1" }, instances: [
        { instance_id: "a", links: { cam: "a" }, framework: {} } ] }] }"#;
    let errors = launcher_err(underscored);
    assert_eq!(
        codes(&errors),
        [Code::UnknownKey, Code::UnknownKey],
        "{errors}"
    );
    let found = all(&errors, Code::UnknownKey);
    assert_at(
        found[0],
        Code::UnknownKey,
        "deployments[0].instances[0].links",
        underscored,
        "links:",
    );
    assert_eq!(
        found[0].message,
        "unknown key `links` in `deployments[0].instances[0]`"
    );
    assert_eq!(
        help(found[0]),
        "`links` is the slashed spelling (`launcher/v1`); a `launcher_v1` file writes `bindings`"
    );
    // `framework` is the slashed spelling's only: the underscored one's usual
    // unknown-key error.
    assert_at(
        found[1],
        Code::UnknownKey,
        "deployments[0].instances[0].framework",
        underscored,
        "framework:",
    );
    assert!(
        help(found[1]).starts_with("accepted keys here:"),
        "{}",
        found[1]
    );

    let slashed = with_instances(r#"{ instance_id: "c", bindings: { cam: "a" } }"#);
    let errors = launcher_err(&slashed);
    assert_eq!(codes(&errors), [Code::UnknownKey], "{errors}");
    let d = one(&errors, Code::UnknownKey);
    assert_at(
        d,
        Code::UnknownKey,
        "deployments[1].instances[0].bindings",
        &slashed,
        "bindings:",
    );
    assert_eq!(
        d.message,
        "unknown key `bindings` in `deployments[1].instances[0]`"
    );
    assert_eq!(
        help(d),
        "`bindings` is the underscored spelling (`launcher_v1`); write `links`"
    );

    // Typos still get a did-you-mean against the spelling's own keys.
    let typo = with_instances(r#"{ instance_id: "c", link: {} }"#);
    let errors = launcher_err(&typo);
    assert!(
        help(one(&errors, Code::UnknownKey)).starts_with("did you mean `links`?"),
        "{errors}"
    );

    // `launcher_v1`'s bindings are links of the binding form.
    let l = launcher_ok(
        r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "cam:v1" }, instances: [
            { instance_id: "a" }, { instance_id: "b", bindings: { left: "a" } } ] }] }"#,
    );
    assert_eq!(l.spelling, Spelling::UnderscoreIds);
    let b = &l.deployments[0].instances[1];
    assert_eq!(b.links.len(), 1);
    assert_eq!(b.links[0].key, "left");
    assert!(
        matches!(&b.links[0].value, peppy_schema::LinkValue::Bound(t) if t.instance == "a"),
        "{:?}",
        b.links[0].value
    );
}

#[test]
fn link_keys_are_link_ids_and_not_the_sentinel() {
    let text = with_instances(
        r#"{ instance_id: "c", links: { _: "a", "a.b": "a", "": "a", "__": "b", ok: "b" } }"#,
    );
    let errors = launcher_err(&text);
    assert_eq!(
        codes(&errors),
        [
            Code::LinkSentinelKey,
            Code::InvalidName,
            Code::InvalidName,
            Code::InvalidName
        ],
        "{errors}"
    );
    let d = one(&errors, Code::LinkSentinelKey);
    assert_at(
        d,
        Code::LinkSentinelKey,
        "deployments[1].instances[0].links._",
        &text,
        "_:",
    );
    assert_eq!(d.message, "link key `_` is reserved");
    assert_eq!(
        help(d),
        "a link key is the link_id of one of the node's slots"
    );
    let bad = all(&errors, Code::InvalidName);
    assert_at(
        bad[0],
        Code::InvalidName,
        "deployments[1].instances[0].links.a.b",
        &text,
        "\"a.b\"",
    );
    assert_eq!(
        bad[0].message,
        "invalid link key `a.b`: contains '.'; allowed: ASCII letters, digits, `_` and `-`"
    );
    assert_eq!(bad[1].message, "invalid link key ``: must not be empty");
    assert_eq!(
        bad[2].message,
        "invalid link key `__`: must contain at least one ASCII letter or digit"
    );

    // A key written twice is the JSON reader's duplicate key.
    let text = with_instances(r#"{ instance_id: "c", links: { cam: "a", cam: "b" } }"#);
    let errors = launcher_err(&text);
    assert_eq!(codes(&errors), [Code::DuplicateKey], "{errors}");
    assert_eq!(
        lc(one(&errors, Code::DuplicateKey)),
        pos_nth(&text, "cam:", 1)
    );
}

#[test]
fn link_targets_are_an_instance_and_at_most_one_peer_slot() {
    let text = with_instances(
        r#"{ instance_id: "c", links: { e: "", s: "   ", two: "a/x/y", left: "/x", right: "a/", many: ["a", "b/", 3] } }"#,
    );
    let errors = launcher_err(&text);
    assert_eq!(
        codes(&errors),
        [
            Code::InvalidLinkTarget,
            Code::InvalidLinkTarget,
            Code::InvalidLinkTarget,
            Code::InvalidLinkTarget,
            Code::InvalidLinkTarget,
            Code::InvalidLinkTarget,
            Code::WrongType
        ],
        "{errors}"
    );
    let found = all(&errors, Code::InvalidLinkTarget);
    let expected: [(&str, &str, &str); 6] = [
        ("e", r#""""#, "link `e` has an empty target"),
        ("s", r#""   ""#, "link `s` has an empty target"),
        (
            "two",
            r#""a/x/y""#,
            "link target `a/x/y` has more than one `/`",
        ),
        (
            "left",
            r#""/x""#,
            "link target `/x` has an empty side of `/`",
        ),
        (
            "right",
            r#""a/""#,
            "link target `a/` has an empty side of `/`",
        ),
        (
            "many[1]",
            r#""b/""#,
            "link target `b/` has an empty side of `/`",
        ),
    ];
    for (d, (key_name, needle, message)) in found.iter().zip(expected) {
        assert_at(
            d,
            Code::InvalidLinkTarget,
            &format!("deployments[1].instances[0].links.{key_name}"),
            &text,
            needle,
        );
        assert_eq!(d.message, message);
        assert!(help(d).starts_with("a target is an instance id"), "{d}");
    }
    assert_at(
        one(&errors, Code::WrongType),
        Code::WrongType,
        "deployments[1].instances[0].links.many[2]",
        &text,
        "3]",
    );
}

#[test]
fn a_list_names_each_target_once() {
    let text = with_instances(
        r#"{ instance_id: "c", links: { cams: ["a", "b", "a", "b/x", "b/x", "b/y"] } }"#,
    );
    let errors = launcher_err(&text);
    assert_eq!(
        codes(&errors),
        [Code::DuplicateLinkTarget, Code::DuplicateLinkTarget],
        "{errors}"
    );
    let found = all(&errors, Code::DuplicateLinkTarget);
    assert_at(
        found[0],
        Code::DuplicateLinkTarget,
        "deployments[1].instances[0].links.cams[2]",
        &text,
        r#""a", "b/x""#,
    );
    assert_eq!(found[0].message, "link `cams` lists `a` twice");
    let (line, col) = pos(&text, r#""a", "b", "a""#);
    assert_eq!(
        help(found[0]),
        format!("`a` is already listed at line {line}, column {col}; a target fills a slot once")
    );
    assert_eq!(found[1].message, "link `cams` lists `b/x` twice");
    assert_eq!(lc(found[1]), pos_nth(&text, r#""b/x""#, 1));
}

#[test]
fn a_vacancy_is_exactly_one_reason() {
    let text = with_instances(
        r#"{ instance_id: "c", links: {
        blank: { vacant: "  " }, none: {}, extra: { vacant: "why", because: "x" }, typo: { vacnat: "why" },
        num: { vacant: 3 }, scalar: 7, nothing: null } }"#,
    );
    let errors = launcher_err(&text);
    let got: Vec<(Code, &str)> = errors.sorted().iter().map(|d| (d.code, key(d))).collect();
    assert_eq!(
        got,
        [
            (
                Code::InvalidVacancy,
                "deployments[1].instances[0].links.blank.vacant"
            ),
            (Code::MissingKey, "deployments[1].instances[0].links.none"),
            (
                Code::UnknownKey,
                "deployments[1].instances[0].links.extra.because"
            ),
            (Code::MissingKey, "deployments[1].instances[0].links.typo"),
            (
                Code::UnknownKey,
                "deployments[1].instances[0].links.typo.vacnat"
            ),
            (
                Code::WrongType,
                "deployments[1].instances[0].links.num.vacant"
            ),
            (Code::WrongType, "deployments[1].instances[0].links.scalar"),
            (Code::WrongType, "deployments[1].instances[0].links.nothing"),
        ],
        "{errors}"
    );
    let d = one(&errors, Code::InvalidVacancy);
    assert_at(
        d,
        Code::InvalidVacancy,
        "deployments[1].instances[0].links.blank.vacant",
        &text,
        r#""  ""#,
    );
    assert_eq!(d.message, "vacancy of link `blank` gives no reason");
    assert_eq!(
        help(d),
        "say why the slot is empty: `{ vacant: \"no camera on this rig\" }`"
    );
    let typo = all(&errors, Code::UnknownKey)[1];
    assert!(help(typo).starts_with("did you mean `vacant`?"), "{typo}");
    let scalar = all(&errors, Code::WrongType)[1];
    assert_at(
        scalar,
        Code::WrongType,
        "deployments[1].instances[0].links.scalar",
        &text,
        "7,",
    );
    assert_eq!(
        scalar.message,
        "expected a target (`\"inst\"` or `\"inst/peer_slot\"`), a list of targets, or `{ vacant: \"<why>\" }` for `deployments[1].instances[0].links.scalar`, found a number"
    );

    let text = with_instances(r#"{ instance_id: "c", links: ["a"] }"#);
    let errors = launcher_err(&text);
    assert_eq!(codes(&errors), [Code::WrongType], "{errors}");
    assert_eq!(
        one(&errors, Code::WrongType).message,
        "expected an object of `link_id: target` for `deployments[1].instances[0].links`, found an array"
    );
}

/// The instance part of every target names an instance of the file; the
/// peer slot after `/` is the plan's to check.
#[test]
fn link_targets_name_instances_of_the_launcher() {
    let text = with_instances(
        r#"{ instance_id: "c", links: { one: "b", typo: "bb/deliberation", list: ["a", "zzz"], self_link: "c", gone: { vacant: "later" } } }"#,
    );
    let errors = launcher_err(&text);
    assert_eq!(
        codes(&errors),
        [Code::UnknownInstanceId, Code::UnknownInstanceId],
        "{errors}"
    );
    let found = all(&errors, Code::UnknownInstanceId);
    assert_at(
        found[0],
        Code::UnknownInstanceId,
        "deployments[1].instances[0].links.typo",
        &text,
        r#""bb/deliberation""#,
    );
    assert_eq!(
        found[0].message,
        "link `typo` on instance `c` names instance `bb`, which no deployment declares"
    );
    assert_eq!(
        help(found[0]),
        "did you mean `b`? instances in this launcher: `a`, `b`, `c`"
    );
    assert_at(
        found[1],
        Code::UnknownInstanceId,
        "deployments[1].instances[0].links.list[1]",
        &text,
        r#""zzz""#,
    );
    assert_eq!(help(found[1]), "instances in this launcher: `a`, `b`, `c`");
}

#[test]
fn instance_ids_are_unique_in_the_slashed_spelling_too() {
    let text = with_instances(r#"{ instance_id: "a" }"#);
    let errors = launcher_err(&text);
    assert_eq!(codes(&errors), [Code::DuplicateInstanceId], "{errors}");
    assert_at(
        one(&errors, Code::DuplicateInstanceId),
        Code::DuplicateInstanceId,
        "deployments[1].instances[0].instance_id",
        &text,
        r#""a" }
    ] }"#,
    );
}

#[test]
fn framework_holds_only_use_sim_time() {
    let text = with_instances(
        r#"{ instance_id: "c", framework: { use_sim_time: "yes", clock: "sim" } },
      { instance_id: "d", framework: true },
      { instance_id: "e", framework: { use_sim_time: false } }"#,
    );
    let errors = launcher_err(&text);
    let got: Vec<(Code, &str)> = errors.sorted().iter().map(|d| (d.code, key(d))).collect();
    assert_eq!(
        got,
        [
            (
                Code::WrongType,
                "deployments[1].instances[0].framework.use_sim_time"
            ),
            (
                Code::UnknownKey,
                "deployments[1].instances[0].framework.clock"
            ),
            (Code::WrongType, "deployments[1].instances[1].framework"),
        ],
        "{errors}"
    );
    let unknown = one(&errors, Code::UnknownKey);
    assert_at(
        unknown,
        Code::UnknownKey,
        "deployments[1].instances[0].framework.clock",
        &text,
        "clock:",
    );
    assert_eq!(
        unknown.message,
        "unknown key `clock` in `deployments[1].instances[0].framework`"
    );
    let l = launcher_ok(&with_instances(
        r#"{ instance_id: "e", framework: { use_sim_time: false } }"#,
    ));
    assert_eq!(
        l.deployments[1].instances[0].framework.use_sim_time,
        Some(false)
    );
}

/// `env_vars` in `launcher/v1`: PeppyOS's stricter shape (a shell
/// identifier, the same forbidden hooks, a shell-safe value). The
/// underscored spelling keeps its own, looser rules.
#[test]
fn env_vars_take_the_slashed_spellings_stricter_shape() {
    let text = with_instances(
        r#"{ instance_id: "c", env_vars: { "has-dash": "x", "1X": "x", ld_preload: "/tmp/e.so", GREETING: "hello world", CMD: "$(whoami)",
           OK_1: "info,my_node=debug", _PATH: "/opt/.venv/bin:/usr/bin", EMPTY: "", URL: "https://example.com/a%20b+c@d" } }"#,
    );
    let errors = launcher_err(&text);
    assert_eq!(errors.len(), 5, "{errors}");
    let found = all(&errors, Code::ForbiddenEnvVar);
    let expected: [(&str, &str, &str); 5] = [
        (
            "has-dash",
            r#""has-dash""#,
            "environment variable name `has-dash` is not a shell identifier",
        ),
        (
            "1X",
            r#""1X""#,
            "environment variable name `1X` is not a shell identifier",
        ),
        (
            "ld_preload",
            "ld_preload",
            "`ld_preload` may not be set by a launcher",
        ),
        (
            "GREETING",
            r#""hello world""#,
            "value of environment variable `GREETING` holds characters a node cannot receive intact",
        ),
        (
            "CMD",
            r#""$(whoami)""#,
            "value of environment variable `CMD` holds characters a node cannot receive intact",
        ),
    ];
    for (d, (name, needle, message)) in found.iter().zip(expected) {
        assert_at(
            d,
            Code::ForbiddenEnvVar,
            &format!("deployments[1].instances[0].env_vars.{name}"),
            &text,
            needle,
        );
        assert_eq!(d.message, message);
    }
    assert_eq!(
        help(found[0]),
        "a name starts with a letter or `_` and holds only letters, digits and `_`"
    );
    assert_eq!(
        help(found[3]),
        "a value may hold letters, digits and `_ - . / : , = @ + %` (no whitespace, quotes or shell metacharacters)"
    );

    // The underscored spelling is unchanged.
    let l = launcher_ok(
        r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "cam:v1" }, instances: [
            { instance_id: "a", env_vars: { "has-dash": "hello world" } } ] }] }"#,
    );
    assert_eq!(
        l.deployments[0].instances[0].env_vars,
        [("has-dash".to_string(), "hello world".to_string())]
    );
}

#[test]
fn core_node_placeholders_are_names_other_than_self() {
    let long = "m".repeat(64);
    let text = format!(
        r#"{{ peppy_schema: "launcher/v1", core_nodes: ["robot", "self", "{long}"],
  deployments: [{{ source: {{ name: "cam:v1" }}, instances: [{{ instance_id: "cam", core_node: "robot" }}] }}] }}"#
    );
    let errors = launcher_err(&text);
    assert_eq!(
        codes(&errors),
        [Code::InvalidName, Code::InvalidName],
        "{errors}"
    );
    let found = all(&errors, Code::InvalidName);
    assert_at(
        found[0],
        Code::InvalidName,
        "core_nodes[1]",
        &text,
        r#""self""#,
    );
    assert_eq!(
        found[0].message,
        "invalid core node name `self`: `self` stands for the machine a command runs on (`--place link@self`)"
    );
    assert_at(
        found[1],
        Code::InvalidName,
        "core_nodes[2]",
        &text,
        &format!("\"{long}\""),
    );
    assert_eq!(
        found[1].message,
        format!("invalid core node name `{long}`: longer than 63 characters")
    );

    // Placement on an undeclared placeholder, as in the underscored spelling.
    let text = r#"{ peppy_schema: "launcher/v1", core_nodes: ["robot_onboard"],
  deployments: [{ source: { name: "cam:v1" }, instances: [{ instance_id: "cam", core_node: "robot_onbaord" }] }] }"#;
    let errors = launcher_err(text);
    assert_eq!(codes(&errors), [Code::UnknownCoreNode], "{errors}");
    let d = one(&errors, Code::UnknownCoreNode);
    assert_at(
        d,
        Code::UnknownCoreNode,
        "deployments[0].instances[0].core_node",
        text,
        r#""robot_onbaord""#,
    );
    assert!(help(d).starts_with("did you mean `robot_onboard`?"), "{d}");

    // The underscored spelling keeps accepting what it accepted.
    let l = launcher_ok(
        r#"{ peppy_schema: "launcher_v1", core_nodes: ["self"],
            deployments: [{ source: { name: "cam:v1" }, instances: [{ instance_id: "cam", core_node: "self" }] }] }"#,
    );
    assert_eq!(l.core_nodes[0].name, "self");
}

/// The slashed spelling's tag rule (a letter first, no dots) on repository
/// sources; peppy's own source kinds stay available (documented extension).
#[test]
fn sources_in_the_slashed_spelling() {
    let text = r#"{ peppy_schema: "launcher/v1", deployments: [
    { source: { name: "cam:0.1.0" }, instances: [{ instance_id: "a" }] },
    { source: { name: "lidar", tag: "v1", url: "x" }, instances: [{ instance_id: "b" }] },
] }"#;
    let errors = launcher_err(text);
    assert_eq!(
        codes(&errors),
        [Code::InvalidTag, Code::InvalidSource],
        "{errors}"
    );
    let d = one(&errors, Code::InvalidTag);
    assert_at(
        d,
        Code::InvalidTag,
        "deployments[0].source.name",
        text,
        r#""cam:0.1.0""#,
    );
    assert!(
        d.message
            .starts_with("invalid tag `0.1.0`: must start with an ASCII letter"),
        "{d}"
    );
    let combined = launcher_err(
        r#"{ peppy_schema: "launcher/v1", deployments: [{ source: { name: "cam:v1", tag: "v1" }, instances: [{ instance_id: "a" }] }] }"#,
    );
    assert_eq!(
        one(&combined, Code::InvalidSource).message,
        "`source.name` `cam:v1` already has a tag"
    );

    let l = launcher_ok(
        r#"{ peppy_schema: "launcher/v1", deployments: [
    { source: { local: "../nodes/recon" }, instances: [{ instance_id: "c" }] },
    { source: { repo: "https://example.invalid/x.git", path: "nodes/imu", ref: "main" }, instances: [{ instance_id: "d" }] },
    { source: { url: "file:///tmp/x.tar.gz", sha256: "0000000000000000000000000000000000000000000000000000000000000000" }, instances: [{ instance_id: "e" }] },
] }"#,
    );
    assert_eq!(
        l.deployments[0].source,
        Source::Local {
            path: PathBuf::from("../nodes/recon")
        }
    );
    assert!(matches!(l.deployments[1].source, Source::Git { .. }));
    assert!(matches!(l.deployments[2].source, Source::Archive { .. }));
    // The underscored spelling still takes dotted versions.
    launcher_ok(
        r#"{ peppy_schema: "launcher_v1", deployments: [{ source: { name: "cam:0.1.0" }, instances: [{ instance_id: "a" }] }] }"#,
    );
}
