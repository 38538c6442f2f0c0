// The Rust code of both seed pages exactly as they print it (the Python
// code is in tests/seeds/python, checked here too): only the line
// breaks the pages lost are restored (and indentation added), every token
// and comment is the page's. Each snippet sits between `seed <page>: begin`
// and `end` lines; around it is only what a page leaves to the reader (the
// node document, and for a fragment the function it runs in).
// `snippets_are_the_seeds_text` keeps the snippets verbatim.
#![deny(warnings)]

/// Seed 000 (interface conformance), "Multiple producer instances under
/// the same node identity": a `from_any` slot's consumer keeping state per
/// producer. A fragment; it runs inside a node's async code.
#[rustfmt::skip]
#[allow(dead_code)] // compiled, not run: the pages' code is the check
mod seed_000_from_any_consumer {
    #[peppy::node("tests/e2e/api/video_reconstruction.json5")]
    mod peppygen {}

    type Frame = peppygen::consumed_topics::extras_video_stream::Message;

    fn reconstruct(_frames: &std::collections::HashMap<String, Frame>) {}

    async fn consume(node_runner: peppygen::NodeRunner) -> peppygen::Result<()> {
        // seed 000: begin
        use peppygen::consumed_topics::extras_video_stream;
        use std::collections::HashMap;

        let mut frames_by_producer: HashMap<String, Frame> = HashMap::new();

        loop {
            let (instance_id, frame) = extras_video_stream::on_next_message_received(
                &node_runner,
                None,
            ).await?;
            // Use the returned id as a runtime key; do not compare against a hard-coded name.
            frames_by_producer.insert(instance_id, frame);
            reconstruct(&frames_by_producer);
        }
        // seed 000: end
    }
}

/// Seed 002 (bidirectional communication), "Receiving external messages":
/// `robot_arm`, a legacy `schema_version: 1` node reading the external
/// topic `joint_commands` (three arguments: core node and instance).
#[rustfmt::skip]
#[allow(dead_code)] // compiled, not run: the pages' code is the check
mod seed_002_robot_arm {
    #[peppy::node("tests/e2e/api/legacy_robot_arm.json5")]
    mod peppygen {}

    // seed 002: begin
    use peppygen::consumed_topics::joint_commands;
    use peppygen::emitted_topics::joint_states;
    use peppygen::{NodeBuilder, Parameters, Result};

    fn main() -> Result<()> {
        NodeBuilder::new().run(|_args: Parameters, node_runner| async move {
            let node_runner_clone = node_runner.clone();
            tokio::spawn(async move {
                loop {
                    let (instance_id, command) = joint_commands::on_next_message_received(
                        &node_runner_clone,
                        None,
                        None,
                    )
                    .await
                    .expect("failed to receive joint command");

                    println!(
                        "received from {}: target={:?} max_vel={}",
                        instance_id, command.target_positions, command.max_velocity
                    );

                    // Drive the joints, then report state
                    let _ = joint_states::emit(
                        &node_runner_clone,
                        command.target_positions,
                        [0.0, 0.0, 0.0],
                        std::time::SystemTime::now(),
                    )
                    .await;
                }
            });

            Ok(())
        })
    }
    // seed 002: end
}

/// Seed 002, the other side: `arm_controller`, a legacy node reading its
/// linked topic `robot_arm_joint_states` with the legacy three arguments.
/// (The page's loop leaves `instance_id` unused.)
#[rustfmt::skip]
#[allow(unused_variables, dead_code)] // compiled, not run: the pages' code is the check
mod seed_002_arm_controller {
    #[peppy::node("tests/e2e/api/legacy_arm_controller.json5")]
    mod peppygen {}

    // seed 002: begin
    use peppygen::consumed_topics::robot_arm_joint_states;
    use peppygen::emitted_topics::joint_commands;
    use peppygen::{NodeBuilder, Parameters, Result};

    fn main() -> Result<()> {
        NodeBuilder::new().run(|_args: Parameters, node_runner| async move {
            let node_runner_clone = node_runner.clone();
            tokio::spawn(async move {
                loop {
                    // Linked topic: module name is <local_node_id>_<topic_name>
                    let (instance_id, state) = robot_arm_joint_states::on_next_message_received(
                        &node_runner_clone,
                        None,
                        None,
                    )
                    .await
                    .expect("failed to receive joint state");

                    // Compute next target based on current state
                    let target = compute_next_target(&state.positions);

                    let _ = joint_commands::emit(
                        &node_runner_clone,
                        target,
                        1.0, // max_velocity
                    )
                    .await;
                }
            });

            Ok(())
        })
    }

    fn compute_next_target(current: &[f64; 3]) -> [f64; 3] {
        // Trajectory planning logic
        [current[0] + 0.1, current[1], current[2]]
    }
    // seed 002: end
}

/// The Python snippets, beside their seed documents in `tests/seeds/python`
/// (run by peppy-launch's tests), marked with `# seed <page>: begin`.
const PYTHON_SOURCES: [&str; 3] = [
    include_str!("../../seeds/python/video_reconstruction/video_reconstruction.py"),
    include_str!("../../seeds/python/robot_arm/robot_arm.py"),
    include_str!("../../seeds/python/arm_controller/arm_controller.py"),
];

/// The snippets (Rust here, then Python), whitespace removed, as SHA-256 of
/// what the pages print (whitespace removed the same way): an edit to a
/// snippet fails here. With the pages at hand (`PEPPY_SEEDS_DIR`, or
/// `../shared/seeds` beside the checkout), each snippet is also found in
/// its page's text.
#[test]
fn snippets_are_the_seeds_text() {
    use sha2::{Digest, Sha256};
    let mut found = snippets(include_str!("seeds.rs"));
    for source in PYTHON_SOURCES {
        found.extend(snippets(source));
    }
    let pages: Vec<&str> = found.iter().map(|(page, _)| page.as_str()).collect();
    assert_eq!(
        pages,
        ["000", "002", "002", "000", "002", "002"],
        "the snippets found"
    );
    let hashes: Vec<String> = found
        .iter()
        .map(|(_, text)| {
            Sha256::digest(text.as_bytes())
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect()
        })
        .collect();
    assert_eq!(
        hashes, SNIPPET_HASHES,
        "a snippet differs from the seed's text"
    );

    let dir = std::env::var_os("PEPPY_SEEDS_DIR").map_or_else(
        || std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/seeds"),
        std::path::PathBuf::from,
    );
    let Ok(entries) = std::fs::read_dir(&dir) else {
        eprintln!(
            "seed pages not at {}: the snippets are checked by their hashes alone",
            dir.display()
        );
        return;
    };
    let texts: Vec<(String, String)> = entries
        .filter_map(|e| {
            let path = e.ok()?.path();
            let name = path.file_name()?.to_str()?.to_owned();
            let text = std::fs::read_to_string(&path).ok()?;
            Some((name, squeeze(&text)))
        })
        .collect();
    for (page, snippet) in &found {
        let (_, text) = texts
            .iter()
            .find(|(name, _)| name.starts_with(&format!("{page}_")))
            .unwrap_or_else(|| panic!("seed page {page} not in {}", dir.display()));
        assert!(
            text.contains(snippet.as_str()),
            "a snippet of seed {page} is not in the page's text"
        );
    }
}

/// The hashes of the snippets, in order: this file's three, then the
/// Python ones.
const SNIPPET_HASHES: [&str; 6] = [
    "f2f1eaeb1630e187d109caa4a42a8324f9e3fdaeb8f9a7def69e764f2438d21f",
    "17c1f41a35e43a7e5813353b66bf20ef341178c057e3dcdcaa82187ed778544b",
    "f03026d9ee201ceb854cb51a40d0f9c3c94ab42c5179dfa3238f8545795d7833",
    "6c09a451edc10053a335aa8b290c7e175bec7dadb07e6c6c6ed5740c94b5dddb",
    "1d1c8dde06e13e2932aeebe701deaa8675e467181deb05bb3c9c5f7acfd75a97",
    "0a9518e18f80ecc52886180728bf27ca4f9e21325568b1597e49e1f2b8b9d5de",
];

/// `(page, text without whitespace)` of each marked snippet in `source`.
fn snippets(source: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut current: Option<(String, String)> = None;
    for line in source.lines() {
        let trimmed = line.trim();
        let marker = trimmed
            .strip_prefix("// seed ")
            .or_else(|| trimmed.strip_prefix("# seed "));
        match marker.and_then(|m| m.split_once(": ")) {
            Some((page, "begin")) => current = Some((page.to_owned(), String::new())),
            Some((_, "end")) => out.extend(current.take()),
            _ => {
                if let Some((_, text)) = &mut current {
                    text.push_str(&squeeze(line));
                }
            }
        }
    }
    out
}

fn squeeze(text: &str) -> String {
    text.chars().filter(|c| !c.is_whitespace()).collect()
}
