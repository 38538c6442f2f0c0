//! SPEC 2.1 / 2.2: message formats, through node and interface documents.

use peppy_schema::{Code, FieldType, InterfaceDoc, Primitive};

use crate::support::*;

#[test]
fn format_errors_are_located_with_their_key_paths() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  interfaces: {
    topics: {
      emits: [
        { name: "frame", message_format: {
            ok: "u32",
            big: "u322",
            header: { instance_id: "u32", stamp: "time" },
          } },
        { name: "empty", message_format: {} },
      ],
    },
    services: {
      exposes: [
        { name: "info", request_message_format: { flag: { $type: "bool", $optional: true } } },
      ],
    },
    actions: {
      exposes: [
        { name: "scan", feedback_topic: { message_format: {
            grid: { $type: "array", $items: { $type: "array", $items: "u8" } },
            names: { $type: "array", $items: "string", $length: 2 },
            "foo-bar": "u8",
            dist: { $type: "f32", $unit: "m" },
          } } },
      ],
    },
  },
  execution: { language: "rust", run_cmd: ["./cam"] },
}"#;
    let errors = node_err(text);
    let got: Vec<(Code, &str, (usize, usize))> = errors
        .sorted()
        .iter()
        .map(|d| (d.code, key(d), lc(d)))
        .collect();
    let e = "interfaces.topics.emits";
    let f = "interfaces.actions.exposes[0].feedback_topic.message_format";
    assert_eq!(
        got,
        [
            (
                Code::UnknownType,
                &*format!("{e}[0].message_format.big"),
                pos(text, r#""u322""#)
            ),
            (
                Code::ReservedFieldName,
                &*format!("{e}[0].message_format.header.instance_id"),
                pos(text, "instance_id")
            ),
            (
                Code::EmptyMessageFormat,
                &*format!("{e}[1].message_format"),
                pos(text, "{}")
            ),
            (
                Code::OptionalMisuse,
                "interfaces.services.exposes[0].request_message_format.flag.$optional",
                pos(text, "true } }")
            ),
            (
                Code::NestedArray,
                &*format!("{f}.grid.$items"),
                pos(text, r#"{ $type: "array", $items: "u8" }"#)
            ),
            (
                Code::LengthMisuse,
                &*format!("{f}.names.$length"),
                pos(text, "2 },")
            ),
            (
                Code::InvalidFieldName,
                &*format!("{f}.foo-bar"),
                pos(text, r#""foo-bar""#)
            ),
            (
                Code::UnknownKey,
                &*format!("{f}.dist.$unit"),
                pos(text, "$unit")
            ),
        ]
    );
    let big = one(&errors, Code::UnknownType);
    assert_eq!(big.message, "unknown type `u322`");
    assert!(help(big).starts_with("did you mean `u32`?"), "{big}");
    let optional = one(&errors, Code::OptionalMisuse);
    assert!(
        optional.message.contains("scalars have no presence bit"),
        "{optional}"
    );
    assert!(
        help(one(&errors, Code::EmptyMessageFormat))
            .contains("omit the key for a message with no payload")
    );
}

#[test]
fn optional_is_for_root_level_strings_bytes_time_arrays_and_objects() {
    let ok = node_text(
        "cam",
        "",
        r#"topics: { emits: [{ name: "t", message_format: {
            note: { $type: "string", $optional: true },
            blob: { $type: "bytes", $optional: true },
            stamp: { $type: "time", $optional: true },
            list: { $type: "array", $items: "u8", $optional: true },
            pose: { $type: "object", x: "f64", $optional: true },
            flag: { $type: "bool", $optional: false },
        } }] }"#,
        "",
    );
    let (node, _) = node_ok(&ok);
    let fields = &node.emits[0].format.as_ref().unwrap().fields;
    let optional: Vec<(&str, bool)> = fields
        .iter()
        .map(|f| (f.name.as_str(), f.optional))
        .collect();
    assert_eq!(
        optional,
        [
            ("note", true),
            ("blob", true),
            ("stamp", true),
            ("list", true),
            ("pose", true),
            ("flag", false)
        ]
    );

    let nested = node_text(
        "cam",
        "",
        r#"topics: { emits: [{ name: "t", message_format: {
            header: { note: { $type: "string", $optional: true } },
            items: { $type: "array", $items: { $type: "string", $optional: true } },
        } }] }"#,
        "",
    );
    let errors = node_err(&nested);
    let found = all(&errors, Code::OptionalMisuse);
    assert_eq!(found.len(), 2, "{errors}");
    assert_eq!(
        key(found[0]),
        "interfaces.topics.emits[0].message_format.header.note.$optional"
    );
    assert!(
        found[0]
            .message
            .contains("only allowed on root-level fields")
    );
    assert_eq!(
        key(found[1]),
        "interfaces.topics.emits[0].message_format.items.$items.$optional"
    );
    assert!(found[1].message.contains("array items"));
}

#[test]
fn canonical_form_keeps_key_order_and_resolves_aliases() {
    let text = node_text(
        "cam",
        "",
        r#"topics: { emits: [{ name: "pose", message_format: {
            z: "double",
            y: "f64",
            x: "float",
            label: "str",
            note: { $type: "string", $optional: true },
            pts: { $type: "array", $items: { b: "u8", a: "i8" } },
            fixed: { $type: "array", $items: "u8", $length: 4 },
            header: { $type: "object", stamp: "time", frame_id: "u32" },
            type: "bool",
        } }] }"#,
        "",
    );
    let (node, _) = node_ok(&text);
    let format = node.emits[0].format.as_ref().unwrap();
    assert_eq!(
        format.canonical(),
        "{z:f64,y:f64,x:f32,label:string,note:string?,pts:[{b:u8,a:i8}],fixed:[u8;4],header:{stamp:time,frame_id:u32},type:bool}"
    );
    let names: Vec<&str> = format.fields.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "z", "y", "x", "label", "note", "pts", "fixed", "header", "type"
        ]
    );
    assert_eq!(format.fields[0].ty, FieldType::Primitive(Primitive::F64));
    assert_eq!(
        format.fields[6].ty,
        FieldType::array(FieldType::Primitive(Primitive::U8), Some(4))
    );
    // Field locations point at the keys.
    assert_eq!(
        format.fields[2].loc.key_path,
        "interfaces.topics.emits[0].message_format.x"
    );

    // Reordering changes the format and its fingerprint; aliases do not.
    let swapped = text.replace(
        "z: \"double\",\n            y: \"f64\",",
        "y: \"f64\",\n            z: \"double\",",
    );
    let (other, _) = node_ok(&swapped);
    let other_format = other.emits[0].format.as_ref().unwrap();
    assert!(other_format.canonical().starts_with("{y:f64,z:f64,"));
    assert_ne!(other_format.fingerprint(), format.fingerprint());
    let aliased = text
        .replace("z: \"double\"", "z: \"f64\"")
        .replace("label: \"str\"", "label: \"string\"");
    let (same, _) = node_ok(&aliased);
    assert_eq!(
        same.emits[0].format.as_ref().unwrap().fingerprint(),
        format.fingerprint()
    );
    assert_eq!(same.emits[0].format.as_ref().unwrap(), format);
}

#[test]
fn action_and_service_formats() {
    let text = node_text(
        "arm",
        "",
        r#"actions: { exposes: [{
            name: "move",
            goal_service: { request_message_format: { target: "f64" }, response_message_format: { ok: "bool" } },
            feedback_topic: { qos_profile: "reliable", message_format: { progress: "f32" } },
            result_service: { response_message_format: { reached: "bool" } },
        }] },
        services: { exposes: [{ name: "home", response_message_format: { done: "bool" } }] }"#,
        "",
    );
    let (node, warnings) = node_ok(&text);
    // The goal response is fixed by the framework: a warning, not an error.
    let w = one(&warnings, Code::IgnoredKey);
    assert_eq!(
        key(w),
        "interfaces.actions.exposes[0].goal_service.response_message_format"
    );
    let a = &node.exposed_actions[0];
    assert_eq!(a.goal.as_ref().unwrap().canonical(), "{target:f64}");
    assert_eq!(
        a.feedback.as_ref().unwrap().format.canonical(),
        "{progress:f32}"
    );
    assert_eq!(a.feedback.as_ref().unwrap().qos.as_str(), "reliable");
    assert_eq!(a.result.as_ref().unwrap().canonical(), "{reached:bool}");
    let s = &node.exposed_services[0];
    assert!(s.request.is_none());
    assert_eq!(s.response.as_ref().unwrap().canonical(), "{done:bool}");

    // A feedback topic needs its format.
    let text = node_text(
        "arm",
        "",
        r#"actions: { exposes: [{ name: "move", feedback_topic: { qos_profile: "reliable" } }] }"#,
        "",
    );
    let errors = node_err(&text);
    assert_eq!(
        key(one(&errors, Code::MissingKey)),
        "interfaces.actions.exposes[0].feedback_topic"
    );
}

#[test]
fn interface_documents_use_the_same_rules() {
    let text = r#"{
  peppy_schema: "interface_v1",
  manifest: { name: "depth_camera", tag: "v1" },
  interfaces: {
    topics: [{ name: "video_stream", message_format: { frame: { $type: "array", $items: "u8", $length: 0 } } }],
    services: [{ name: "shutdown" }],
    actions: [{ name: "a" }, { name: "a" }],
  },
}"#;
    let errors = InterfaceDoc::parse("depth_camera.json5", text).unwrap_err();
    let got: Vec<(Code, &str)> = errors.sorted().iter().map(|d| (d.code, key(d))).collect();
    assert_eq!(
        got,
        [
            (
                Code::LengthMisuse,
                "interfaces.topics[0].message_format.frame.$length"
            ),
            (Code::ReservedServiceName, "interfaces.services[0].name"),
            (Code::DuplicateEntryName, "interfaces.actions[1].name"),
        ]
    );
    let (doc, _) = InterfaceDoc::parse(
        "depth_camera.json5",
        r#"{ peppy_schema: "interface_v1", manifest: { name: "depth_camera", tag: "v1" }, interfaces: {} }"#,
    )
    .unwrap();
    assert_eq!(doc.identity.to_string(), "depth_camera:v1");
    assert_eq!(doc.sha256, peppy_schema::sha256_hex(
        br#"{ peppy_schema: "interface_v1", manifest: { name: "depth_camera", tag: "v1" }, interfaces: {} }"#
    ));
    // An interface has no emits/consumes split and no execution.
    let errors = InterfaceDoc::parse(
        "x.json5",
        r#"{ peppy_schema: "interface_v1", manifest: { name: "x", tag: "v1" }, interfaces: { topics: { emits: [] } }, execution: {} }"#,
    )
    .unwrap_err();
    assert_eq!(error_codes(&errors), [Code::WrongType, Code::UnknownKey]);
}
