//! Rendered error listings, snapshotted so their wording is reviewed.

use std::path::Path;

use peppy_schema::Diagnostics;

use crate::support::*;

/// Jump lines (relative to `base`), each followed by its help.
fn listing(errors: &Diagnostics, base: &Path) -> String {
    let mut out = String::new();
    for d in errors.sorted() {
        out.push_str(&d.jump_line(Some(base)));
        out.push('\n');
        if let Some(h) = &d.help {
            out.push_str(&format!("    help: {h}\n"));
        }
    }
    out
}

#[test]
fn node_document_errors() {
    let text = r#"// A camera driver with one mistake per line.
{
  peppy_schema: "node_v1",
  manifest: {
    name: "cam",
    tag: "1.0",
    depends_on: {
      nodes: [
        { name: "imu", tag: "v1", link_id: "imu" },
        { name: "gps", tag: "v1", link_id: "imu" },
      ],
      interfaces: [{ name: "clock", tag: "v1", link_id: "clk", from_any: "yes" }],
    },
  },
  interfaces: {
    topics: {
      emits: [
        { name: "frame", qos_profil: "sensor_data", message_format: { width: "u322", instance_id: "string" } },
        { name: "frame" },
      ],
      consumes: [
        { link_id: "imu", name: "accel", message_format: { x: "f32" } },
        { name: "weather" },
        { link_id: "gyro", name: "rate" },
      ],
    },
    services: {
      exposes: [{ name: "shutdown" }],
      consumes: [{ name: "calibrate" }],
    },
  },
  execution: {
    language: "rust",
    run_cmd: ["./cam"],
    container: { def_file: "cam.def" },
    parameters: { fps: { $type: "u8", $default: 300 } },
  },
}
"#;
    let errors = NodeDocParse::errors("/stack/nodes/cam/peppy.json5", text);
    insta::assert_snapshot!(
        "node_document_errors",
        listing(&errors, Path::new("/stack"))
    );
}

#[test]
fn launcher_errors() {
    let tree = Tree::new();
    tree.write(
        peppy_schema::REPOSITORIES_FILE,
        r#"[{ type: "fs", path: "repo" }]"#,
    );
    tree.write(
        "repo/cam.json5",
        &interface_text(
            "cam",
            "v1",
            r#"topics: [{ name: "frame", message_format: { w: "u32" } }]"#,
        ),
    );
    tree.write(
        "repo/cam_a/peppy.json5",
        &node_text(
            "cam_a",
            "",
            r#"conforms_to: [{ name: "cam", tag: "v1" }]"#,
            r#"parameters: { fps: { $type: "u16", $default: 30 } }"#,
        ),
    );
    tree.write("repo/plain/peppy.json5", &node_text("plain", "", "", ""));
    tree.write(
        "repo/fusion/peppy.json5",
        &node_text(
            "fusion",
            r#"interfaces: [
        { name: "cam", tag: "v1", link_id: "left" },
        { name: "cam", tag: "v1", link_id: "right" },
      ],
      nodes: [{ name: "plain", tag: "v1", link_id: "base" }]"#,
            "",
            "",
        ),
    );
    let path = tree.write(
        "stacks/demo.json5",
        r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { local: "../repo/cam_a" }, instances: [{ instance_id: "a1", arguments: { fps: -1, gain: 2 } }] },
    { source: { name: "plain", tag: "v1" }, instances: [{ instance_id: "p1" }] },
    {
      source: { name: "fusion:v1" },
      instances: [{ instance_id: "f1", bindings: { left: "p1", base: "a1", spare: "p1" } }],
    },
  ],
}
"#,
    );
    let errors = stack_err(&path);
    insta::assert_snapshot!("launcher_errors", listing(&errors, &tree.root()));
}

/// Parses a node document that must fail, under a given path.
struct NodeDocParse;

impl NodeDocParse {
    fn errors(path: &str, text: &str) -> Diagnostics {
        match peppy_schema::NodeDoc::parse(path, text) {
            Ok(_) => panic!("expected errors"),
            Err(e) => e,
        }
    }
}
