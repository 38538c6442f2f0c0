// The document has one error; the code below names the generated module
// tree and re-exports, and sees only that one error.
#[peppy::node("usage/stubs_keep_one_error.json5")]
mod peppygen {}

use peppygen::{NodeBuilder, NodeRunner, Parameters, QoSProfile, Result, StandaloneConfig};
#[allow(unused_imports)]
use peppygen::{consumed_services, consumed_topics, emitted_topics, exposed_services, parameters};

fn main() -> Result<()> {
    let _ = (QoSProfile::Reliable, StandaloneConfig::new());
    let _: Option<&NodeRunner> = None;
    NodeBuilder::new()
        .standalone(StandaloneConfig::new())
        .run(|_params: Parameters, _runner| async move { Ok(()) })
}
