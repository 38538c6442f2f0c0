//! Composed launchers end to end, on the small family in
//! tests/fixtures/composed (one camera or two, with or without a viewer,
//! the project's example nodes): `resolve` and its `--list`, `check` and
//! `graph` with `--with`, `check --all-selections` and `repo index --check`.

use std::path::PathBuf;

use crate::support::{jump_lines, peppy_launch, root};

fn fixture() -> PathBuf {
    root().join("peppy-launch/tests/fixtures/composed")
}

fn examples() -> String {
    root().join("examples").display().to_string()
}

#[test]
fn resolve_lists_every_selection_and_refused_ones_with_their_reason() {
    let run = peppy_launch(&fixture(), &["resolve", "cameras.json5", "--list"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert_eq!(
        run.stdout.lines().collect::<Vec<_>>(),
        [
            "camera=single",
            "camera=single,inspector=viewer",
            "camera=pair  refused by constraint 1: the second camera is only there for the viewer",
            "camera=pair,inspector=viewer",
        ]
    );
    assert_eq!(run.stderr.trim(), "4 selections, 1 refused by constraints");
}

#[test]
fn resolve_prints_a_flat_launcher_that_checks_and_resolves_to_itself() {
    let dir = fixture();
    let run = peppy_launch(
        &dir,
        &[
            "resolve",
            "cameras.json5",
            "--with",
            "pair",
            "--with",
            "inspector=viewer",
        ],
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert_eq!(
        run.stderr.lines().collect::<Vec<_>>(),
        [
            "components: camera=pair  inspector=viewer",
            "adjustments applied:",
            "  viewer.links.cameras: + cam_b  (fragments/pair.json5)",
            "adjustments skipped:",
            "  cam_a: guard camera=single is not met  (cameras.json5 (base))",
            "constraints checked: 1 hold",
        ]
    );
    let tmp = tempfile::tempdir().unwrap();
    let flat = tmp.path().join("flat.json5");
    std::fs::write(&flat, &run.stdout).unwrap();
    let flat_arg = flat.display().to_string();
    let again = peppy_launch(tmp.path(), &["resolve", &flat_arg]);
    assert_eq!(again.code, 0, "{}", again.stderr);
    assert_eq!(again.stdout, run.stdout);
    let check = peppy_launch(tmp.path(), &["check", &flat_arg, "--repo", &examples()]);
    assert_eq!(check.code, 0, "{}", check.stderr);
    // A flat launcher has nothing to select.
    let with = peppy_launch(tmp.path(), &["resolve", &flat_arg, "--with", "pair"]);
    assert_eq!(with.code, 2);
    assert!(
        with.stderr.contains("(WithOnFlatLauncher)"),
        "{}",
        with.stderr
    );
}

#[test]
fn check_and_graph_say_which_selection_they_describe() {
    let dir = fixture();
    let repo = examples();
    let run = peppy_launch(
        &dir,
        &[
            "check",
            "cameras.json5",
            "--with",
            "pair,viewer",
            "--repo",
            &repo,
        ],
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(
        run.stdout
            .contains("components: camera=pair  inspector=viewer\n"),
        "{}",
        run.stdout
    );
    assert!(
        run.stdout
            .lines()
            .any(|l| l.trim_start().starts_with("cameras  <- cam_a, cam_b")),
        "{}",
        run.stdout
    );
    let json = peppy_launch(
        &dir,
        &[
            "check",
            "cameras.json5",
            "--repo",
            &repo,
            "--format",
            "json",
        ],
    );
    assert_eq!(json.code, 0, "{}", json.stderr);
    let v: serde_json::Value = serde_json::from_str(&json.stdout).unwrap();
    assert_eq!(v["selection"], "camera=single (default)  inspector=(off)");

    let graph = peppy_launch(
        &dir,
        &[
            "graph",
            "cameras.json5",
            "--with",
            "viewer",
            "--repo",
            &repo,
        ],
    );
    assert_eq!(graph.code, 0, "{}", graph.stderr);
    assert!(graph.stdout.starts_with("digraph"), "{}", graph.stdout);
    assert!(
        graph
            .stderr
            .contains("components: camera=single (default)  inspector=viewer"),
        "{}",
        graph.stderr
    );
}

#[test]
fn a_refused_or_mistyped_selection_is_a_located_error() {
    let dir = fixture();
    let text = std::fs::read_to_string(dir.join("cameras.json5")).unwrap();
    let line_of = |needle: &str| text.lines().position(|l| l.contains(needle)).unwrap() + 1;
    let run = peppy_launch(&dir, &["resolve", "cameras.json5", "--with", "pair"]);
    assert_eq!(run.code, 2);
    assert!(run.stdout.is_empty(), "{}", run.stdout);
    let lines = jump_lines(&run.stderr);
    assert_eq!(lines.len(), 1, "{}", run.stderr);
    assert!(
        lines[0].starts_with(&format!(
            "cameras.json5:{}:",
            line_of("when: { camera: \"pair\" }") - 1
        )),
        "{}",
        lines[0]
    );
    assert!(
        lines[0]
            .ends_with("the second camera is only there for the viewer (ConstraintUnsatisfied)"),
        "{}",
        lines[0]
    );

    let run = peppy_launch(
        &dir,
        &[
            "up",
            "cameras.json5",
            "--with",
            "camera=par",
            "--repo",
            &examples(),
        ],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr.contains("help: did you mean `camera=pair`?"),
        "{}",
        run.stderr
    );
    assert!(
        run.stderr.contains("nothing was built or started"),
        "{}",
        run.stderr
    );
}

#[test]
fn every_selection_is_checked_and_the_index_holds_the_composition_checks() {
    let dir = fixture();
    let run = peppy_launch(
        &dir,
        &[
            "check",
            "cameras.json5",
            "--all-selections",
            "--repo",
            &examples(),
        ],
    );
    assert_eq!(run.code, 0, "{}\n{}", run.stdout, run.stderr);
    assert_eq!(
        run.stdout.lines().collect::<Vec<_>>(),
        [
            "valid    --with camera=single (1 instance)",
            "valid    --with camera=single,inspector=viewer (2 instances)",
            "refused  --with camera=pair: constraint 1 says: the second camera is only there for the viewer",
            "valid    --with camera=pair,inspector=viewer (3 instances)",
            "4 selections: 3 valid, 1 refused by constraints, 0 invalid",
        ]
    );
    let run = peppy_launch(&dir, &["repo", "index", "--check", "."]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(
        run.stdout.contains(
            "composed launchers: 1, 4 selections (1 refused by their constraints), each checked"
        ),
        "{}",
        run.stdout
    );
    // `validate` on the directory reads the launcher (its default
    // selection) and leaves the fragments to it.
    let run = peppy_launch(&dir, &["validate", "."]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(run.stderr.contains("2 documents checked"), "{}", run.stderr);

    // A constraint refusing every selection with an option fails the index check.
    let tmp = tempfile::tempdir().unwrap();
    crate::support::copy_documents(&dir, tmp.path());
    let launcher = tmp.path().join("cameras.json5");
    let text = std::fs::read_to_string(&launcher).unwrap().replace(
        "when: { camera: \"pair\" },\n      requires: [{ inspector: \"viewer\" }],",
        "forbids: [{ camera: \"pair\" }],",
    );
    std::fs::write(&launcher, text).unwrap();
    let run = peppy_launch(tmp.path(), &["repo", "index", "--check", "."]);
    assert_eq!(run.code, 2, "{}", run.stdout);
    assert!(run.stderr.contains("(OptionUnreachable)"), "{}", run.stderr);
}

/// The composed example, launched for two of its selections: the slots are
/// filled as each selection says.
#[test]
fn the_camera_rig_example_runs_as_each_selection_says() {
    use crate::seeds::{BUILD_AND_START, Launch};
    use std::time::Duration;
    const RIG: &str = "examples/launchers/camera_rig.json5";

    // The default: the RealSense alone, the overhead slot vacant.
    let mut launch = Launch::up(RIG, &[]);
    launch.expect("naming the viewer's camera", BUILD_AND_START, |l| {
        l.starts_with("[viewer]") && l.contains("cameras: linked to front_cam")
    });
    launch.expect(
        "with the overhead slot vacant",
        Duration::from_secs(30),
        |l| l.starts_with("[viewer]") && l.contains("overhead: vacant"),
    );
    launch.expect(
        "with the RealSense's frames",
        Duration::from_secs(30),
        |l| {
            l.starts_with("[viewer]") && l.contains("cameras: first frame from front_cam (160x120)")
        },
    );
    assert!(
        !launch.seen.iter().any(|l| l.starts_with("[mosaic]")),
        "no inspector unless chosen"
    );
    drop(launch);

    // The simulator with the mosaic: the fragment's adjustment links the
    // overhead camera to the viewer, the base's adds it to the mosaic.
    let mut launch = Launch::up(RIG, &["--with", "sim,mosaic"]);
    launch.expect("naming the selection", BUILD_AND_START, |l| {
        l.contains("components: camera=sim  inspector=mosaic")
    });
    launch.expect("with the overhead camera linked", BUILD_AND_START, |l| {
        l.starts_with("[viewer]") && l.contains("overhead: linked to overhead_cam")
    });
    for camera in ["front_cam", "overhead_cam"] {
        launch.expect("with the mosaic tiling it", Duration::from_secs(30), |l| {
            l.starts_with("[mosaic]") && l.contains(&format!("extras: first frame from {camera}"))
        });
    }
}
