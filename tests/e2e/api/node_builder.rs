// Both spellings of the entry point compile: the generated `NodeBuilder`
// defaults its parameter type to this node's `Parameters`.
#![deny(warnings)]

#[peppy::node("tests/e2e/api/node_builder.json5")]
mod peppygen {}

use std::sync::Arc;

use peppygen::{NodeBuilder, NodeRunner, Parameters, Result, StandaloneConfig};

fn inferred() -> Result<()> {
    NodeBuilder::new().run(|params: Parameters, runner: Arc<NodeRunner>| async move {
        let _: u16 = params.fps;
        let token: &peppy::CancellationToken = runner.cancellation_token();
        token.cancel();
        Ok(())
    })
}

fn explicit() -> Result<()> {
    let fallback = Parameters { fps: 60 };
    NodeBuilder::<Parameters>::new()
        .standalone(StandaloneConfig::new().with_parameters(&fallback))
        .run(|params, runner| async move {
            let _ = (params.fps, runner.instance_id());
            Ok(())
        })
}

fn through_the_facade() -> peppy::Result<()> {
    peppy::NodeBuilder::<Parameters>::new().run(|_, _| async { Ok(()) })
}

#[test]
fn compiles_and_runs() {
    let _ = (inferred, explicit, through_the_facade);
    let _: peppygen::QoSProfile = peppy::QoSProfile::Reliable;
    let _: Option<peppygen::Error> = None;
}
