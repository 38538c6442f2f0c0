// Both spellings of the entry point compile: the generated `NodeBuilder`
// defaults its parameter type to this node's `Parameters`.
#![deny(warnings)]

#[peppy::node("tests/e2e/api/node_builder.json5")]
mod peppygen {}

use std::sync::{Arc, OnceLock};

use peppygen::{NodeBuilder, NodeRunner, Parameters, Result, StandaloneConfig};

/// A lone node on a loopback port of its own choosing: nothing connects to
/// it and it scouts for nobody.
fn args(extra: &[&str]) -> Vec<String> {
    let mut args = vec!["node", "--listen", "tcp/127.0.0.1:0"];
    args.extend_from_slice(extra);
    args.into_iter().map(String::from).collect()
}

// Each entry point stops its node from `setup` and returns the `fps` it was
// given.

fn inferred(args: Vec<String>) -> Result<u16> {
    let fps = OnceLock::new();
    let seen = &fps;
    NodeBuilder::new()
        .with_args(args)
        .with_runtime_config(None)
        .run(|params: Parameters, runner: Arc<NodeRunner>| async move {
            let _ = seen.set(params.fps);
            let token: &peppy::CancellationToken = runner.cancellation_token();
            token.cancel();
            Ok(())
        })?;
    Ok(*fps.get().expect("setup ran"))
}

fn explicit(args: Vec<String>) -> Result<u16> {
    let fps = OnceLock::new();
    let seen = &fps;
    let fallback = Parameters { fps: 60 };
    NodeBuilder::<Parameters>::new()
        .with_args(args)
        .with_runtime_config(None)
        .standalone(StandaloneConfig::new().with_parameters(&fallback))
        .run(|params, runner| async move {
            let _ = (params.fps, runner.instance_id());
            let _ = seen.set(params.fps);
            runner.cancellation_token().cancel();
            Ok(())
        })?;
    Ok(*fps.get().expect("setup ran"))
}

fn through_the_facade(args: Vec<String>) -> peppy::Result<u16> {
    let fps = OnceLock::new();
    let seen = &fps;
    peppy::NodeBuilder::<Parameters>::new()
        .with_args(args)
        .with_runtime_config(None)
        .run(|params, runner| async move {
            let _ = seen.set(params.fps);
            runner.cancellation_token().cancel();
            Ok(())
        })?;
    Ok(*fps.get().expect("setup ran"))
}

/// Each entry point runs its node to the end (`run` owns its runtime, so
/// this is a plain test): the document's default, the standalone fallback,
/// and a `key=value` flag over both.
#[test]
fn every_entry_point_runs_the_node_with_its_parameters() {
    assert_eq!(inferred(args(&[])).unwrap(), 30);
    assert_eq!(explicit(args(&[])).unwrap(), 60);
    assert_eq!(explicit(args(&["fps=15"])).unwrap(), 15);
    assert_eq!(through_the_facade(args(&["fps=24"])).unwrap(), 24);
    let _: peppygen::QoSProfile = peppy::QoSProfile::Reliable;
    let _: Option<peppygen::Error> = None;
}
