use crate::support::{jump_lines, peppy_launch, root};

#[test]
fn multi_camera_plan_names_every_slot_and_producer() {
    let run = peppy_launch(&root(), &["check", "examples/launchers/multi_camera.json5"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    let recon = run
        .stdout
        .split("recon_1")
        .nth(1)
        .expect("recon_1 in the plan");
    let slot = |link: &str| {
        recon
            .lines()
            .find(|l| l.trim_start().starts_with(link))
            .unwrap_or_else(|| panic!("{link} in {recon}"))
            .to_string()
    };
    assert!(slot("left_cam").contains("<- rs_left") && slot("left_cam").contains("pinned"));
    assert!(slot("right_cam").contains("<- rs_right"));
    assert!(
        slot("backup_cams").contains("<- zed_overhead") && slot("backup_cams").contains("from_any")
    );
    assert!(
        run.stdout
            .contains(r#"parameters: {"width":160,"height":120,"frames_per_second":10}"#),
        "{}",
        run.stdout
    );
}

#[test]
fn unbound_from_any_slot_prints_any() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("stack.json5"),
        r#"{ peppy_schema: "launcher_v1", deployments: [
                { source: { name: "realsense_d405:v1" }, instances: [{ instance_id: "cam" }] },
                { source: { name: "camera_mosaic:v1" }, instances: [{ instance_id: "mosaic" }] },
            ] }"#,
    )
    .unwrap();
    let repo = root().join("examples");
    let run = peppy_launch(
        dir.path(),
        &["check", "stack.json5", "--repo", repo.to_str().unwrap()],
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(
        run.stdout.lines().any(|l| l.contains("extras <- (any)")),
        "{}",
        run.stdout
    );
}

#[test]
fn json_plan_is_machine_readable() {
    let run = peppy_launch(
        &root(),
        &[
            "check",
            "--format",
            "json",
            "examples/launchers/three_realsense.json5",
        ],
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    let v: serde_json::Value = serde_json::from_str(&run.stdout).expect("json on stdout");
    assert_eq!(v["valid"], true);
    let mosaic = v["plan"]["instances"]
        .as_array()
        .unwrap()
        .iter()
        .find(|i| i["instance_id"] == "mosaic_1")
        .unwrap();
    let extras = &mosaic["slots"][0];
    assert_eq!(extras["link_id"], "extras");
    assert_eq!(extras["binding"]["kind"], "from_any_bound");
    assert_eq!(
        extras["binding"]["producers"],
        serde_json::json!(["rs_front", "rs_back_left", "rs_back_right"])
    );
    assert_eq!(extras["filter"]["kind"], "only_from");
}

#[test]
fn non_conforming_producer_is_rejected_with_a_jump_line() {
    let run = peppy_launch(
        &root(),
        &["check", "examples/launchers/wrong_interface.json5"],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stdout.is_empty(),
        "no plan for an invalid stack: {}",
        run.stdout
    );
    let lines = jump_lines(&run.stderr);
    assert_eq!(lines.len(), 1, "{}", run.stderr);
    assert!(
        lines[0].starts_with("examples/launchers/wrong_interface.json5:21:55: error: binding `right_cam` on instance `recon_1`"),
        "{}",
        lines[0]
    );
    assert!(lines[0].ends_with("(BindingInterfaceNotConformed)"));
    assert!(run.stderr.contains("nothing was built or started"));
    // The snippet points at the offending value.
    assert!(
        run.stderr
            .contains(r#"bindings: { left_cam: "rs_left", right_cam: "impostor" },"#)
    );
}

#[test]
fn json_errors_carry_code_and_position() {
    let run = peppy_launch(
        &root(),
        &[
            "check",
            "--format=json",
            "examples/launchers/wrong_interface.json5",
        ],
    );
    assert_eq!(run.code, 2);
    let v: serde_json::Value = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(v["valid"], false);
    assert!(v["plan"].is_null());
    let d = &v["diagnostics"][0];
    assert_eq!(d["code"], "BindingInterfaceNotConformed");
    assert_eq!(
        (d["line"].as_u64(), d["column"].as_u64()),
        (Some(21), Some(55))
    );
    assert_eq!(
        d["key_path"],
        "deployments[2].instances[0].bindings.right_cam"
    );
}

#[test]
fn every_error_of_a_stack_is_reported_in_one_run() {
    let dir = tempfile::tempdir().unwrap();
    let launcher = r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { name: "realsense_d405:v1" }, instances: [{ instance_id: "cam", arguments: { width: -1 } }] },
    { source: { name: "video_reconstruction:v1" }, instances: [
      { instance_id: "recon", bindings: { left_cam: "cam", typo_slot: "recon" } },
    ] },
    { source: { name: "no_such_node:v1" }, instances: [{ instance_id: "ghost" }] },
  ],
}"#;
    std::fs::write(dir.path().join("bad.json5"), launcher).unwrap();
    let repo = root().join("examples");
    let run = peppy_launch(
        dir.path(),
        &["check", "bad.json5", "--repo", repo.to_str().unwrap()],
    );
    assert_eq!(run.code, 2);
    let lines = jump_lines(&run.stderr);
    let codes: Vec<&str> = lines
        .iter()
        .map(|l| l.rsplit('(').next().unwrap().trim_end_matches(')'))
        .collect();
    assert_eq!(
        codes,
        [
            "ParameterTypeMismatch",
            "PinnedSlotUnbound",
            "DeadBindingKey",
            "DependencyNotFound"
        ],
        "{}",
        run.stderr
    );
    // Sorted by position, each with its line.
    assert!(lines[0].starts_with("bad.json5:4:100: "), "{}", lines[0]);
    assert!(lines[3].starts_with("bad.json5:8:15: "), "{}", lines[3]);
}

#[test]
fn missing_launcher_is_a_clean_error() {
    let run = peppy_launch(&root(), &["check", "does/not/exist.json5"]);
    assert_eq!(run.code, 2);
    assert!(
        run.stderr
            .contains("does/not/exist.json5: error: cannot read"),
        "{}",
        run.stderr
    );
}

#[test]
fn readme_commands_on_the_arm_loop() {
    let check = peppy_launch(
        &root(),
        &["check", "examples/launchers/robot_arm_loop.json5"],
    );
    assert_eq!(check.code, 0, "{}", check.stderr);
    assert!(
        check.stdout.contains("robot_arm <- arm"),
        "{}",
        check.stdout
    );
    assert!(
        check
            .stdout
            .contains(r#"parameters: {"step":0.05,"max_velocity":1.0}"#),
        "{}",
        check.stdout
    );
    let graph = peppy_launch(
        &root(),
        &["graph", "examples/launchers/robot_arm_loop.json5"],
    );
    assert_eq!(graph.code, 0, "{}", graph.stderr);
    assert!(graph.stdout.starts_with("digraph \"robot_arm_loop\" {"));
    assert!(
        graph
            .stdout
            .contains(r#""arm" -> "controller" [label="robot_arm"];"#),
        "{}",
        graph.stdout
    );
    assert!(
        graph.stdout.contains(
            r#""controller" -> "arm" [label="joint_commands (external)", style=dotted];"#
        )
    );
}

#[test]
fn graph_draws_any_edges_for_unbound_from_any_slots() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("stack.json5"),
        r#"{ peppy_schema: "launcher_v1", deployments: [
                { source: { name: "realsense_d405:v1" }, instances: [{ instance_id: "cam" }] },
                { source: { name: "camera_mosaic:v1" }, instances: [{ instance_id: "mosaic" }] },
                { source: { name: "video_reconstruction:v1" }, instances: [{ instance_id: "recon", bindings: { left_cam: "cam", right_cam: "cam" } }] },
            ] }"#,
    )
    .unwrap();
    let repo = root().join("examples");
    let graph = peppy_launch(
        dir.path(),
        &["graph", "stack.json5", "--repo", repo.to_str().unwrap()],
    );
    assert_eq!(graph.code, 0, "{}", graph.stderr);
    // mosaic's extras takes any camera: a dashed edge from `cam`.
    assert!(
        graph
            .stdout
            .contains(r#""cam" -> "mosaic" [label="extras (any)", style=dashed];"#),
        "{}",
        graph.stdout
    );
    // recon's backup_cams excludes `cam` (pinned by its siblings): an (any) placeholder.
    assert!(
        graph.stdout.contains(
            r#""recon.backup_cams.any" -> "recon" [label="backup_cams (any)", style=dashed];"#
        ),
        "{}",
        graph.stdout
    );
}

#[test]
fn graph_output_writes_a_standalone_html_page_naming_every_instance() {
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("arm.html");
    let launcher = root().join("examples/launchers/robot_arm_loop.json5");
    let graph = peppy_launch(
        dir.path(),
        &[
            "graph",
            launcher.to_str().unwrap(),
            "--output",
            page.to_str().unwrap(),
        ],
    );
    assert_eq!(graph.code, 0, "{}", graph.stderr);
    assert_eq!(graph.stdout, "");
    assert!(
        graph
            .stderr
            .trim_end()
            .ends_with("arm.html (2 instances, 2 edges)"),
        "{}",
        graph.stderr
    );
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert!(html.contains("<svg "), "an inline picture");
    for instance in ["arm", "controller"] {
        assert!(html.contains(&format!("<td>{instance}</td>")), "{html}");
    }
    let refused = peppy_launch(
        dir.path(),
        &["graph", launcher.to_str().unwrap(), "--output", "arm.png"],
    );
    assert_eq!(refused.code, 2, "{}", refused.stderr);
    assert!(refused.stderr.contains(".svg, .html"), "{}", refused.stderr);
}

/// The HTML graph in a real (headless) browser: the picture is drawn, with
/// dark strokes and text on a light page, where the page puts it.
#[test]
fn the_html_graph_renders_in_a_headless_browser() {
    let Some(browser) = crate::support::headless_browser() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("stack.html");
    let launcher = root().join("examples/launchers/multi_camera.json5");
    let graph = peppy_launch(
        dir.path(),
        &[
            "graph",
            launcher.to_str().unwrap(),
            "-o",
            page.to_str().unwrap(),
        ],
    );
    assert_eq!(graph.code, 0, "{}", graph.stderr);
    let shot = dir.path().join("shot.png");
    let chromium = std::process::Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--no-first-run",
            "--hide-scrollbars",
            "--window-size=800,600",
            &format!("--user-data-dir={}", dir.path().join("profile").display()),
            &format!("--screenshot={}", shot.display()),
            &format!("file://{}", page.display()),
        ])
        .env("HOME", dir.path())
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let run = crate::support::wait_bounded(
        chromium,
        std::time::Duration::from_secs(90),
        "chromium --screenshot",
    );
    assert!(
        shot.exists(),
        "no screenshot: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let image = crate::support::decode_png(&std::fs::read(&shot).unwrap());
    assert_eq!((image.width, image.height), (800, 600));
    let dark = |p: &[u8; 3]| p.iter().all(|&c| c < 128);
    let ink = image.pixels.iter().filter(|p| dark(p)).count();
    let share = ink as f64 / image.pixels.len() as f64;
    assert!(
        (0.005..0.25).contains(&share),
        "{:.3} of the page is ink",
        share
    );
    // The picture comes first on the page: ink in its top half's left and
    // right parts (the cameras and the reconstruction).
    let ink_in = |x0: usize, x1: usize| {
        (40..400).any(|y| (x0..x1).any(|x| dark(&image.pixels[y * image.width + x])))
    };
    assert!(ink_in(20, 200) && ink_in(280, 460), "the graph is drawn");
}

#[test]
fn a_container_node_is_planned_by_check_and_refused_by_up() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("boxed")).unwrap();
    std::fs::write(
        dir.path().join("boxed/peppy.json5"),
        r#"{ peppy_schema: "node_v1", manifest: { name: "boxed", tag: "v1" },
             execution: { language: "python", container: { def_file: "boxed.def" } } }"#,
    )
    .unwrap();
    std::fs::write(
        dir.path().join("stack.json5"),
        r#"{ peppy_schema: "launcher_v1", deployments: [
                { source: { local: "boxed" }, instances: [{ instance_id: "b" }] },
            ] }"#,
    )
    .unwrap();
    for (command, code, severity) in [("check", 0, "warning"), ("up", 2, "error")] {
        let run = peppy_launch(dir.path(), &[command, "stack.json5"]);
        assert_eq!(run.code, code, "{command}: {}", run.stderr);
        let lines = jump_lines(&run.stderr);
        assert!(
            lines.iter().any(|l| l.starts_with("stack.json5:2:")
                && l.contains(&format!("{severity}: `boxed:v1` runs in a container"))
                && l.ends_with("(UnsupportedExecution)")),
            "{command}: {}",
            run.stderr
        );
    }
    assert!(!dir.path().join(".peppy").exists(), "up started nothing");
}
