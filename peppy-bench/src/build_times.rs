//! What building costs: generating a node's code from documents of 10, 100
//! and 1000 topics, and cargo's no-op build, rebuild after a `peppy.json5`
//! edit and rebuild after a `main.rs` edit of an example node.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant, SystemTime};

use crate::roles::Res;
use crate::stats::{Figure, Row};
use crate::workspace;

const GROUP: &str = "build";

pub(crate) fn build(quick: bool) -> Res<Vec<Row>> {
    let mut rows = Vec::new();
    let tries = if quick { 3 } else { 10 };
    for topics in [10usize, 100, 1000] {
        let (best, generating) = codegen(topics, tries)?;
        rows.push(
            Row::new(
                GROUP,
                format!("code generation, {topics} topics"),
                None,
                Some(Figure::Value {
                    value: best.as_secs_f64() * 1e3,
                    unit: "ms".into(),
                }),
            )
            .with_note(format!(
                "{:.1} ms per 100 topics; best of {tries}, resolve + generate ({:.1} ms, what `#[peppy::node]` pays) + format",
                best.as_secs_f64() * 1e3 * 100.0 / topics as f64,
                generating.as_secs_f64() * 1e3
            )),
        );
    }
    let node = workspace().join("examples/nodes/realsense_d405");
    let cargo_build = || -> Res<Duration> {
        let start = Instant::now();
        let status = Command::new(crate::cargo())
            .args(["build", "-p", "realsense_d405", "--quiet"])
            .current_dir(workspace())
            .status()?;
        if !status.success() {
            return Err("cargo build -p realsense_d405 failed".into());
        }
        Ok(start.elapsed())
    };
    eprintln!("peppy-bench: building realsense_d405 once before timing it…");
    cargo_build()?;
    let secs = |d: Duration| Figure::Value {
        value: d.as_secs_f64(),
        unit: "s".into(),
    };
    let noop = cargo_build()?;
    rows.push(Row::new(
        GROUP,
        "realsense_d405: no-op cargo build".into(),
        None,
        Some(secs(noop)),
    ));
    for (file, what) in [
        ("peppy.json5", "after editing its peppy.json5"),
        ("src/main.rs", "after editing its main.rs"),
    ] {
        touch(&node.join(file))?;
        let took = cargo_build()?;
        rows.push(Row::new(
            GROUP,
            format!("realsense_d405: rebuild {what}"),
            None,
            Some(secs(took)),
        ));
    }
    Ok(rows)
}

/// Marks a file changed, as an editor's save does, without changing it.
fn touch(path: &Path) -> Res<()> {
    std::fs::File::options()
        .append(true)
        .open(path)?
        .set_modified(SystemTime::now())?;
    Ok(())
}

/// The best of `tries` generations of a node of `topics` topics (each with
/// a nested header, an array and an optional field, one topic per line as
/// a person writes them), formatted as the build script writes it; and the
/// best of the generations alone.
fn codegen(topics: usize, tries: usize) -> Res<(Duration, Duration)> {
    let mut emits = String::new();
    for i in 0..topics {
        write!(
            emits,
            "\n  {{ name: \"topic_{i}\", message_format: {{ header: {{ stamp: \"time\", frame_id: \"u32\" }}, data: {{ $type: \"array\", $items: \"f32\", $length: 16 }}, note: {{ $type: \"string\", $optional: true }} }} }},"
        )?;
    }
    let doc = format!(
        r#"{{ peppy_schema: "node_v1", manifest: {{ name: "big", tag: "v1" }},
             interfaces: {{ topics: {{ emits: [{emits}] }} }},
             execution: {{ language: "rust", run_cmd: ["x"] }} }}"#
    );
    let dir = tempfile::tempdir()?;
    std::fs::write(dir.path().join("peppy.json5"), doc)?;
    let mut config = peppy_build::Config::new();
    config.manifest_dir(dir.path()).repositories_env(None);
    let (mut best, mut generating) = (Duration::MAX, Duration::MAX);
    for _ in 0..tries {
        let start = Instant::now();
        let generated = config.generate().map_err(|e| format!("{e:?}"))?;
        generating = generating.min(start.elapsed());
        let text = peppy_build::pretty(&generated.tokens).map_err(|e| format!("{e:?}"))?;
        best = best.min(start.elapsed());
        if !text.contains(&format!("topic_{}", topics - 1)) {
            return Err("the generated code misses a topic".into());
        }
    }
    Ok((best, generating))
}
