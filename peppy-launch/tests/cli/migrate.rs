//! `peppy-launch migrate`: every example document, rewritten in the slashed
//! spelling, still reads, and every example launcher still plans the same
//! producers into the same slots.

use std::path::{Path, PathBuf};

use peppy_schema::{RepoOptions, SlotBinding, SourceFile, check_launcher, parse_document};

use crate::support::{peppy_launch, root};

/// The examples' documents, copied (no sources, no build output).
fn copy_examples(to: &Path) {
    crate::support::copy_documents(&root().join("examples"), to);
}

/// The examples' documents, relative to `examples/`.
fn documents(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for sub in ["interfaces", "launchers"] {
        for e in std::fs::read_dir(dir.join(sub)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "json5") {
                out.push(p.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    for e in std::fs::read_dir(dir.join("nodes")).unwrap() {
        let p = e.unwrap().path().join("peppy.json5");
        if p.is_file() {
            out.push(p.strip_prefix(dir).unwrap().to_path_buf());
        }
    }
    out.sort();
    out
}

/// Each slot's producers, the way `launcher_v1` routing and `launcher/v1` links
/// both mean them: a bound from_any slot's producers are a set's.
fn producers(b: &SlotBinding) -> Vec<String> {
    match b {
        SlotBinding::Pinned { producer } => vec![producer.clone()],
        SlotBinding::FromAnyBound { producers } | SlotBinding::Set { producers, .. } => {
            let mut p = producers.clone();
            p.sort();
            p
        }
        SlotBinding::FromAnyUnbound => panic!("an unbound from_any slot survived migration"),
    }
}

#[test]
fn every_example_migrates_to_a_valid_document_and_the_same_plan() {
    let tmp = tempfile::tempdir().unwrap();
    copy_examples(tmp.path());
    let docs = documents(tmp.path());
    assert!(docs.len() >= 15, "examples found: {docs:?}");
    let args: Vec<String> = docs.iter().map(|p| p.display().to_string()).collect();
    let mut argv = vec!["migrate", "--write"];
    argv.extend(args.iter().map(String::as_str));

    // The originals' plans, before anything is rewritten.
    let options = RepoOptions {
        explicit: Vec::new(),
        env: Some(Default::default()),
        last: Vec::new(),
    };
    let launchers: Vec<&PathBuf> = docs.iter().filter(|p| p.starts_with("launchers")).collect();
    let before: Vec<_> = launchers
        .iter()
        .map(|l| check_launcher(&tmp.path().join(l), &options).ok())
        .collect();
    assert!(
        before[..].iter().filter(|b| b.is_some()).count() >= launchers.len() - 1,
        "only the deliberately wrong launcher fails to check"
    );

    let run = peppy_launch(tmp.path(), &argv);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(
        run.stderr.contains(
            "launchers/multi_camera.json5:27:13: not carried: free-form binding key `any_label`"
        ),
        "{}",
        run.stderr
    );
    assert!(
        run.stderr.contains(
            "nodes/robot_arm/peppy.json5:24:9: not carried: external consumed topic `joint_commands`"
        ),
        "{}",
        run.stderr
    );

    for doc in &docs {
        let text = std::fs::read_to_string(tmp.path().join(doc)).unwrap();
        assert!(
            !text.contains("_v1\""),
            "{} still names an underscored schema id:\n{text}",
            doc.display()
        );
        let file = SourceFile::new(tmp.path().join(doc), text.clone());
        match parse_document(&file, &peppy_schema::sha256_hex(text.as_bytes())) {
            Ok(_) => {}
            // A version-like tag (`0.1.0`) is not a slashed-spelling tag; renaming it
            // would break every reference, so it is reported, not rewritten.
            Err(d) if doc.starts_with("nodes/gripper") => {
                assert!(
                    d.iter().any(|d| d.code == peppy_schema::Code::InvalidTag),
                    "{d:?}"
                );
                assert!(run.stderr.contains("nodes/gripper/peppy.json5: not carried: the migrated text does not validate: invalid `manifest.tag` `0.1.0`"), "{}", run.stderr);
            }
            Err(d) => panic!(
                "{} does not validate after migration: {d:?}\n{text}",
                doc.display()
            ),
        }
    }
    // Comments survive.
    let camera =
        std::fs::read_to_string(tmp.path().join("nodes/realsense_d405/peppy.json5")).unwrap();
    assert!(camera.contains("// Inherits video_stream"), "{camera}");
    assert!(
        camera.contains(
            r#"implements: [{ name: "depth_camera", tag: "v1", link_id: "depth_camera" }]"#
        ),
        "{camera}"
    );
    assert!(
        camera.contains(r#"{ link_id: "depth_camera", name: "video_stream_info" }"#),
        "{camera}"
    );

    for (l, before) in launchers.iter().zip(before) {
        let Some(before) = before else { continue };
        let after = check_launcher(&tmp.path().join(l), &options)
            .unwrap_or_else(|d| panic!("{} no longer checks: {d:?}", l.display()));
        assert_eq!(after.plan.instances.len(), before.plan.instances.len());
        for (b, a) in before.plan.instances.iter().zip(&after.plan.instances) {
            assert_eq!(a.instance_id, b.instance_id);
            let slots = |p: &peppy_schema::InstancePlan| -> Vec<(String, Vec<String>)> {
                p.slots
                    .iter()
                    .map(|s| (s.link_id.clone(), producers(&s.binding)))
                    .collect()
            };
            assert_eq!(
                slots(a),
                slots(b),
                "{} instance {}",
                l.display(),
                a.instance_id
            );
        }
    }
}

#[test]
fn a_document_in_the_slashed_spelling_is_left_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("c.json5");
    let text = "// kept\n{ peppy_schema: \"contract/v1\", manifest: { name: \"c\", tag: \"v1\" }, interfaces: {} }\n";
    std::fs::write(&path, text).unwrap();
    let run = peppy_launch(tmp.path(), &["migrate", "--write", "c.json5"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(
        run.stderr
            .contains("c.json5: already in the slashed spelling (interface): left alone"),
        "{}",
        run.stderr
    );
    assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
    assert_eq!(run.stdout, "");
}
