use crate::support::{jump_lines, peppy_launch, root};

#[test]
fn every_example_document_is_valid() {
    let run = peppy_launch(&root(), &["validate", "examples"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(run.stderr.contains("valid: "), "{}", run.stderr);
    // Only the legacy-form example warns, naming the new spellings.
    let lines = jump_lines(&run.stderr);
    assert!(
        lines
            .iter()
            .all(|l| l.contains(": warning: ") && l.ends_with("(LegacySpelling)")),
        "{lines:?}"
    );
    assert!(
        lines
            .iter()
            .all(|l| l.starts_with("examples/nodes/gripper/peppy.json5:")),
        "{lines:?}"
    );
}

#[test]
fn invalid_documents_exit_2_with_sorted_located_errors() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("peppy.json5"),
        r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1.2" },
  interfaces: { topics: { emits: [
    { name: "frames", qos_profil: "sensor_data", message_format: { big: "u322", instance_id: "u8" } },
  ] } },
  execution: { language: "rust", run_cmd: ["./cam"] },
}"#,
    )
    .unwrap();
    std::fs::write(dir.path().join("notes.json5"), "{ unrelated: true }").unwrap();
    let run = peppy_launch(dir.path(), &["validate", "."]);
    assert_eq!(run.code, 2);
    let lines = jump_lines(&run.stderr);
    assert_eq!(lines.len(), 4, "{}", run.stderr);
    assert!(
        lines[0].starts_with("./peppy.json5:3:33: error: invalid `manifest.tag` `v1.2`"),
        "{}",
        lines[0]
    );
    assert!(
        lines[1].starts_with("./peppy.json5:5:23: error: unknown key `qos_profil`"),
        "{}",
        lines[1]
    );
    assert!(
        lines[2].starts_with("./peppy.json5:5:73: error: unknown type `u322`"),
        "{}",
        lines[2]
    );
    assert!(
        lines[3].contains("`instance_id` is reserved"),
        "{}",
        lines[3]
    );
    assert!(run.stderr.contains("did you mean `qos_profile`?"));
    assert!(run.stderr.contains("did you mean `u32`?"));
    assert!(
        run.stderr.contains("1 document checked, 1 invalid"),
        "a non-peppy json5 file is skipped: {}",
        run.stderr
    );
}

#[test]
fn json_output_lists_documents() {
    let run = peppy_launch(
        &root(),
        &[
            "validate",
            "--format",
            "json",
            "examples/interfaces",
            "examples/nodes/robot_arm",
        ],
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    let v: serde_json::Value = serde_json::from_str(&run.stdout).unwrap();
    let kinds: Vec<&str> = v["documents"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["interface", "node"]);
    assert_eq!(v["errors"], 0);
}

#[test]
fn hostile_input_is_an_error_not_a_crash() {
    let dir = tempfile::tempdir().unwrap();
    let deep = format!("{}1{}", "[".repeat(100_000), "]".repeat(100_000));
    std::fs::write(dir.path().join("deep.json5"), deep).unwrap();
    std::fs::write(dir.path().join("binary.json5"), [0xff, 0xfe, 0x00, 0x41]).unwrap();
    std::fs::write(dir.path().join("empty.json5"), "").unwrap();
    let run = peppy_launch(
        dir.path(),
        &[
            "validate",
            "--format",
            "json",
            "deep.json5",
            "binary.json5",
            "empty.json5",
        ],
    );
    assert_eq!(run.code, 2, "{}", run.stderr);
    let v: serde_json::Value = serde_json::from_str(&run.stdout).unwrap();
    let codes: Vec<&str> = v["documents"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["diagnostics"][0]["code"].as_str().unwrap())
        .collect();
    assert_eq!(codes, ["NestingTooDeep", "Syntax", "Syntax"]);
}

/// A document that never ends (a device whose size says 0, as a pipe or a
/// file still being written may) is refused as too large once it passes
/// the size limit, instead of being read until memory runs out.
#[test]
fn a_document_that_never_ends_is_refused_as_too_large() {
    let limit = peppy_schema::MAX_DOCUMENT_BYTES;
    let run = peppy_launch(&root(), &["validate", "/dev/zero"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(
        run.stderr.contains(&format!(
            "document is more than {limit} bytes; peppy documents may be at most {limit} bytes"
        )),
        "{}",
        run.stderr
    );
    let run = peppy_launch(&root(), &["validate", "--format", "json", "/dev/zero"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    let v: serde_json::Value = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(
        v["documents"][0]["diagnostics"][0]["code"], "DocumentTooLarge",
        "{v}"
    );
}

#[test]
fn usage_errors_exit_2() {
    assert_eq!(peppy_launch(&root(), &["validate"]).code, 2);
    assert_eq!(peppy_launch(&root(), &["frobnicate"]).code, 2);
    let missing = peppy_launch(&root(), &["validate", "no/such/path"]);
    assert_eq!(missing.code, 2);
    assert!(missing.stderr.contains("`no/such/path` does not exist"));
}

#[test]
fn reference_documents_stay_valid() {
    let run = peppy_launch(&root(), &["validate", "--format", "json", "docs/reference"]);
    assert_eq!(run.code, 0, "{}{}", run.stdout, run.stderr);
    let v: serde_json::Value = serde_json::from_str(&run.stdout).unwrap();
    let mut kinds: Vec<&str> = v["documents"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["kind"].as_str().unwrap())
        .collect();
    kinds.sort();
    assert_eq!(kinds, ["interface", "launcher", "node", "pairing"]);
    assert_eq!(
        v["warnings"], 0,
        "reference documents use current spellings only"
    );
}
