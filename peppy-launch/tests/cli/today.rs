//! Today's PeppyOS spelling end to end: a `node/v1` node linked by a
//! `launcher/v1` file to nodes of the seeds' spelling is checked, planned
//! and run like any stack, its slots filled exactly as linked.

use std::time::Duration;

use crate::seeds::{BUILD_AND_START, Launch};
use crate::support::{peppy_launch, root};

const VIEWER: &str = "examples/launchers/camera_viewer.json5";

#[test]
fn check_prints_todays_links_as_planned() {
    let run = peppy_launch(&root(), &["check", VIEWER]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    // A `node/v1` consumer's slots are named as it names them: contracts.
    for expected in [
        "cameras  <- rs_left, rs_right",
        "overhead <- (vacant: no overhead camera on this bench)",
    ] {
        assert!(
            run.stdout
                .lines()
                .any(|l| l.trim_start().starts_with(expected)),
            "no `{expected}` in:\n{}",
            run.stdout
        );
    }
}

#[test]
fn a_todays_stack_runs_with_its_slots_as_linked() {
    let mut launch = Launch::up(VIEWER, &[]);
    launch.expect(
        "naming the cameras slot's producers",
        BUILD_AND_START,
        |l| l.starts_with("[viewer]") && l.contains("cameras: linked to rs_left, rs_right"),
    );
    launch.expect(
        "saying the overhead slot is vacant",
        Duration::from_secs(30),
        |l| l.starts_with("[viewer]") && l.contains("overhead: vacant"),
    );
    for camera in ["rs_left (160x120)", "rs_right (64x48)"] {
        launch.expect("with a first frame", Duration::from_secs(30), |l| {
            l.starts_with("[viewer]") && l.contains(&format!("cameras: first frame from {camera}"))
        });
    }
}

#[test]
fn run_takes_link_flags_and_refuses_what_the_links_rules_refuse() {
    // One node started by hand, through the same engine. Keys and
    // vacancies are judged first, and alone: a vacancy on a slot that
    // cannot be empty says only that.
    let vacant = |args: &[&str]| {
        let mut all = vec!["run", "examples/nodes/camera_viewer"];
        all.extend_from_slice(args);
        peppy_launch(&root(), &all)
    };
    let run = vacant(&["--vacant-link", "cameras=none on the bench"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(
        run.stderr.contains(
            "slot `cameras` (cardinality one_or_more) cannot be vacant (LinkVacantInvalid)"
        ),
        "{}",
        run.stderr
    );
    assert!(!run.stderr.contains("`overhead`"), "{}", run.stderr);
    // Then what is left out: the optional slot must be linked or vacated.
    let run = vacant(&["--link", "cameras@rs_left"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(
        run.stderr.contains("slot `overhead`")
            && run
                .stderr
                .contains("is not linked (BindingSlotUnfulfilled)"),
        "{}",
        run.stderr
    );
    assert!(
        run.stderr.contains("--vacant-link 'overhead=<why>'"),
        "{}",
        run.stderr
    );
}
