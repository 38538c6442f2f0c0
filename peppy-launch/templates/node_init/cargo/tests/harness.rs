//! `{{name}}` booted in-process under its generated harness
//! (`peppygen::fixtures`): a mock peer plays its `peers` slot.

use std::time::Duration;

use peppygen::consumed_topics::peers::greeting as peer_greeting;
use peppygen::fixtures::harness::{Config, Harness};
use peppygen::{Parameters, Result};

const TIMEOUT: Duration = Duration::from_secs(10);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn greets_and_counts_the_greetings_it_hears() -> Result<()> {
    let config = Config {
        parameters: Some(Parameters { period_ms: 20 }),
        // One mock peer in the `peers` slot (it takes any number).
        peers_instances: 1,
        ..Config::default()
    };
    let (mut harness, mocks) = Harness::start_with(config, {{crate}}::setup).await?;

    let first = harness
        .emitted
        .greeting
        .next_within(TIMEOUT)
        .await?
        .expect("the node greets");
    assert_eq!(first.heard, 0);

    // A peer greets once: the node's later greetings count it.
    let peer = &mocks.deps.peers[0];
    peer.greeting
        .publish(&peer_greeting::Message {
            text: "hello from a mock peer".to_string(),
            count: 0,
            heard: 0,
        })
        .await?;
    let deadline = tokio::time::Instant::now() + TIMEOUT;
    loop {
        let greeting = harness
            .emitted
            .greeting
            .next_within(TIMEOUT)
            .await?
            .expect("the node greets");
        if greeting.heard == 1 {
            break;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "the peer's greeting was never counted"
        );
    }
    harness.shutdown().await
}
