//! Names generated Rust cannot hold are located errors, rendered like the
//! schema's own; schema errors render the way cargo prints errors.

use std::path::Path;

use crate::support::fixtures;

/// Writes `doc` as a node document (with the fixture repository) and
/// renders every error of generating it, build-script style then
/// attribute style.
fn errors_of(doc: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("peppy.json5"), doc).unwrap();
    let base = std::fs::canonicalize(dir.path()).unwrap();
    let mut config = peppy_build::Config::new();
    config
        .manifest_dir(&base)
        .repositories_env(None)
        .repository(fixtures().join("repo"));
    let diagnostics = match config.generate() {
        Ok(_) => panic!("expected errors for:\n{doc}"),
        Err(peppy_build::Error::Schema { diagnostics, .. }) => diagnostics,
        Err(e) => panic!("{e}"),
    };
    let mut out = String::new();
    for d in diagnostics.sorted() {
        out.push_str(&peppy_build::render(d, &base));
        out.push_str("\n\n");
    }
    for d in diagnostics.sorted() {
        out.push_str(&peppy_build::macro_support::message(d, &base));
        out.push('\n');
    }
    out.replace(&fixtures().display().to_string(), "[fixtures]")
}

fn node(interfaces: &str, parameters: &str) -> String {
    format!(
        r#"{{
  peppy_schema: "node_v1",
  manifest: {{ name: "clashes", tag: "v1" }},
  interfaces: {interfaces},
  execution: {{ language: "rust", run_cmd: ["x"], parameters: {parameters} }},
}}
"#
    )
}

#[test]
fn two_topics_with_one_module_name() {
    insta::assert_snapshot!(errors_of(&node(
        r#"{ topics: { emits: [
    { name: "video-stream", message_format: { a: "u8" } },
    { name: "video_stream", message_format: { a: "u8" } },
  ] } }"#,
        "{}"
    )));
}

#[test]
fn a_topic_named_like_a_conformed_interface() {
    insta::assert_snapshot!(errors_of(&node(
        r#"{
    conforms_to: [{ name: "depth_camera", tag: "v1" }],
    topics: { emits: [{ name: "depth_camera", message_format: { a: "u8" } }] },
  }"#,
        "{}"
    )));
}

#[test]
fn two_nested_structs_with_one_type_name() {
    insta::assert_snapshot!(errors_of(&node(
        r#"{ topics: { emits: [
    { name: "poses", message_format: {
        foo_bar: { x: "f64" },
        fooBar: { y: "f64" },
        points: { $type: "array", $items: { x: "f32" } },
        points_item: { z: "f32" },
    } },
  ] } }"#,
        "{}"
    )));
}

#[test]
fn a_parameter_group_named_parameters() {
    insta::assert_snapshot!(errors_of(&node(
        "{}",
        r#"{ parameters: { fps: "u16" }, video: { fps: "u16" }, Video: "u8" }"#
    )));
}

#[test]
fn schema_errors_render_like_cargo() {
    insta::assert_snapshot!(errors_of(&node(
        r#"{ topics: { emits: [
    { name: "frames", message_format: { width: "u322", instance_id: "u8" } },
  ] } }"#,
        r#"{ fps: { $type: "u8", $default: 300 } }"#
    )));
}

#[test]
fn a_missing_document_is_named() {
    let err = peppy_build::Config::new()
        .manifest_dir(Path::new("/nonexistent"))
        .repositories_env(None)
        .generate()
        .unwrap_err();
    let text = err.to_string();
    assert!(text.contains("/nonexistent/peppy.json5"), "{text}");
    match err {
        peppy_build::Error::Schema { diagnostics, .. } => {
            let d = diagnostics.iter().next().unwrap();
            let rendered = peppy_build::render(d, Path::new("/nonexistent"));
            assert!(rendered.starts_with("error[CannotRead]"), "{rendered}");
        }
        other => panic!("{other}"),
    }
}
