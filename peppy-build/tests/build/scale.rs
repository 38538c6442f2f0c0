//! Generation time of a large node: 100 topics with nested formats, 20
//! services, 10 actions (the issue's budget is 50 ms for 100 topics; the
//! bound here is loose so a busy machine does not fail it).

use std::fmt::Write as _;
use std::time::{Duration, Instant};

#[test]
fn a_hundred_topics_generate_fast() {
    let mut emits = String::new();
    for i in 0..100 {
        write!(
            emits,
            r#"{{ name: "topic_{i}", message_format: {{ header: {{ stamp: "time", frame_id: "u32" }}, data: {{ $type: "array", $items: "f32", $length: 16 }}, points: {{ $type: "array", $items: {{ x: "f32", y: "f32" }} }}, note: {{ $type: "string", $optional: true }} }} }},"#
        )
        .unwrap();
    }
    let mut services = String::new();
    for i in 0..20 {
        write!(services, r#"{{ name: "service_{i}", request_message_format: {{ a: "u32" }}, response_message_format: {{ b: "string" }} }},"#).unwrap();
    }
    let mut actions = String::new();
    for i in 0..10 {
        write!(actions, r#"{{ name: "action_{i}", goal_service: {{ request_message_format: {{ a: "u32" }} }}, feedback_topic: {{ message_format: {{ p: "f32" }} }}, result_service: {{ response_message_format: {{ ok: "bool" }} }} }},"#).unwrap();
    }
    let doc = format!(
        r#"{{ peppy_schema: "node_v1", manifest: {{ name: "big", tag: "v1" }},
             interfaces: {{ topics: {{ emits: [{emits}] }}, services: {{ exposes: [{services}] }}, actions: {{ exposes: [{actions}] }} }},
             execution: {{ language: "rust", run_cmd: ["x"] }} }}"#
    );
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("peppy.json5"), doc).unwrap();
    let mut config = peppy_build::Config::new();
    config.manifest_dir(dir.path()).repositories_env(None);

    let mut best = Duration::MAX;
    let mut best_pretty = Duration::MAX;
    for _ in 0..20 {
        let start = Instant::now();
        let generated = config.generate().unwrap();
        best = best.min(start.elapsed());
        let start = Instant::now();
        let text = peppy_build::pretty(&generated.tokens).unwrap();
        best_pretty = best_pretty.min(start.elapsed());
        assert!(text.contains("pub mod topic_99"));
    }
    let check =
        peppy_schema::check_node(&dir.path().join("peppy.json5"), &Default::default()).unwrap();
    let mut best_gen = Duration::MAX;
    for _ in 0..20 {
        let start = Instant::now();
        let _ = peppy_build::generate(&check.resolved).unwrap();
        best_gen = best_gen.min(start.elapsed());
    }
    eprintln!("generate alone {best_gen:?}");
    eprintln!(
        "100 topics, 20 services, 10 actions: resolve + generate {best:?}, pretty-print {best_pretty:?}"
    );
    assert!(best < Duration::from_secs(2), "{best:?}");
}
