//! SPEC 2.3: parameter schemas in `execution.parameters`.

use peppy_schema::{Code, ParamItem, ParamKind, Primitive};
use serde_json::json;

use crate::support::*;

#[test]
fn defaults_are_type_and_range_checked_where_they_are_written() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  execution: {
    language: "rust",
    run_cmd: ["./cam"],
    parameters: {
      fps: { $type: "u8", $default: 300 },
      port: { $type: "u16", $default: -1 },
      gain: { $type: "f32", $default: "high" },
      label: { $type: "string", $default: 5 },
      video: { width: { $type: "u32", $default: -640 }, fine: { $type: "u32", $default: 640 } },
      limits: { $type: "array", $items: "i8", $default: [1, 200, 3] },
      ok: { $type: "u8", $default: 255 },
    },
  },
}"#;
    let errors = node_err(text);
    let found = all(&errors, Code::InvalidDefault);
    assert_eq!(
        errors.len(),
        found.len(),
        "only InvalidDefault expected:\n{errors}"
    );
    let p = "execution.parameters";
    let got: Vec<(&str, (usize, usize))> = found.iter().map(|d| (key(d), lc(d))).collect();
    assert_eq!(
        got,
        [
            (&*format!("{p}.fps.$default"), pos(text, "300")),
            (&*format!("{p}.port.$default"), pos(text, "-1")),
            (&*format!("{p}.gain.$default"), pos(text, r#""high""#)),
            (&*format!("{p}.label.$default"), pos(text, "5 }")),
            (&*format!("{p}.video.width.$default"), pos(text, "-640")),
            (&*format!("{p}.limits.$default"), pos(text, "200")),
        ]
    );
    assert_eq!(
        found[0].message,
        "invalid `$default`: `execution.parameters.fps` expects a `u8` (an integer from 0 to 255), found `300`"
    );
    assert!(
        found[1]
            .message
            .contains("an integer from 0 to 65535), found `-1`"),
        "{}",
        found[1]
    );
    assert!(
        found[2]
            .message
            .contains("expects an `f32` (a finite number), found the string \"high\""),
        "{}",
        found[2]
    );
    assert!(
        found[3].message.contains("expects a `string`, found `5`"),
        "{}",
        found[3]
    );
    assert!(
        found[5].message.contains("from -128 to 127), found `200`"),
        "{}",
        found[5]
    );
}

#[test]
fn defaults_are_not_allowed_everywhere() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  execution: {
    language: "rust",
    run_cmd: ["./cam"],
    parameters: {
      group: { $default: {}, x: "u8" },
      blob: { $type: "bytes", $default: "abc" },
      when: { $type: "time", $default: 0 },
      maybe: { $type: "u8", $optional: true },
      items: { $type: "array", $items: { x: "u8" }, $default: [] },
    },
  },
}"#;
    let errors = node_err(text);
    let got: Vec<(Code, &str)> = errors.sorted().iter().map(|d| (d.code, key(d))).collect();
    assert_eq!(
        got,
        [
            (Code::InvalidDefault, "execution.parameters.group.$default"),
            (Code::InvalidDefault, "execution.parameters.blob.$default"),
            (Code::InvalidDefault, "execution.parameters.when.$default"),
            (Code::OptionalMisuse, "execution.parameters.maybe.$optional"),
            (Code::InvalidDefault, "execution.parameters.items.$default"),
        ]
    );
    assert_eq!(
        all(&errors, Code::InvalidDefault)[1].message,
        "`$default` is not supported for `bytes` parameters"
    );
}

#[test]
fn a_valid_schema_is_carried_in_order_with_its_defaults() {
    let text = node_text(
        "cam",
        "",
        "",
        r#"parameters: {
      fps: { $type: "u16", $default: 30 },
      serial: "string",
      video: { width: { $type: "u32", $default: 640 }, height: { $type: "u32", $default: 480 } },
      gains: { $type: "array", $items: "f64", $length: 2, $default: [1, 2.5] },
      zones: { $type: "array", $items: { x: "u8", y: "u8" } },
    }"#,
    );
    let (node, _) = node_ok(&text);
    let params = &node.execution.parameters;
    let names: Vec<&str> = params.fields.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["fps", "serial", "video", "gains", "zones"]);
    assert!(
        matches!(&params.fields[0].kind, ParamKind::Leaf { ty: Primitive::U16, default: Some(d) } if *d == json!(30))
    );
    assert!(matches!(
        &params.fields[1].kind,
        ParamKind::Leaf {
            ty: Primitive::String,
            default: None
        }
    ));
    assert!(matches!(&params.fields[2].kind, ParamKind::Group(g) if g.len() == 2));
    assert!(matches!(
        &params.fields[3].kind,
        ParamKind::Array { items: ParamItem::Primitive(Primitive::F64), length: Some(2), default: Some(d) } if *d == json!([1, 2.5])
    ));
    assert!(
        matches!(&params.fields[4].kind, ParamKind::Array { items: ParamItem::Object(f), length: None, default: None } if f.len() == 2)
    );

    // At run time, defaults (including whole groups) are filled in and a
    // missing required leaf is named by its dot-path.
    let filled = params
        .resolve(&json!({ "serial": "A1", "zones": [] }))
        .unwrap();
    assert_eq!(
        filled,
        json!({ "fps": 30, "serial": "A1", "video": { "width": 640, "height": 480 }, "gains": [1, 2.5], "zones": [] })
    );
    let errors = params
        .resolve(&json!({ "video": { "width": -5 } }))
        .unwrap_err();
    let paths: Vec<(&str, Code)> = errors.iter().map(|e| (e.path.as_str(), e.code())).collect();
    assert_eq!(
        paths,
        [
            ("serial", Code::MissingParameter),
            ("video.width", Code::ParameterTypeMismatch),
            ("zones", Code::MissingParameter)
        ]
    );
}

/// Arrays follow one grammar, in parameters as in message formats: a fixed
/// `$length` only over numbers or `bool`, at least 1, no arrays of arrays.
#[test]
fn parameter_arrays_follow_the_message_formats_array_rules() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1" },
  execution: {
    language: "rust",
    run_cmd: ["./cam"],
    parameters: {
      names: { $type: "array", $items: "string", $length: 2 },
      empty: { $type: "array", $items: "u8", $length: 0 },
      grid: { $type: "array", $items: { $type: "array", $items: "u8" } },
      pair: { $type: "array", $items: "f64", $length: 2 },
    },
  },
}"#;
    let errors = node_err(text);
    let got: Vec<(Code, &str)> = errors.sorted().iter().map(|d| (d.code, key(d))).collect();
    assert_eq!(
        got,
        [
            (Code::LengthMisuse, "execution.parameters.names.$length"),
            (Code::LengthMisuse, "execution.parameters.empty.$length"),
            (Code::NestedArray, "execution.parameters.grid.$items"),
        ]
    );
    let message = |d: &peppy_schema::Diagnostic| d.message.clone();
    assert_eq!(
        message(all(&errors, Code::LengthMisuse)[0]),
        "`$length` is only allowed when the items are numbers or `bool`"
    );
}
