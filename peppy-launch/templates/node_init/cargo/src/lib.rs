//! `{{name}}`: greets on `greeting` every `period_ms`, and counts the
//! greetings it hears from the peers linked to its `peers` slot.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use peppygen::consumed_topics::peers::greeting as peer_greeting;
use peppygen::emitted_topics::greeting;
use peppygen::{NodeRunner, Parameters, Result};

/// Starts the node's tasks: what `main` runs, and what the tests in
/// `tests/` run in-process against the generated harness.
pub async fn setup(params: Parameters, node_runner: Arc<NodeRunner>) -> Result<()> {
    let heard = Arc::new(AtomicU64::new(0));

    // Subscribed before `setup` returns: a node counts as started once it
    // has, so nothing a peer sends after that is missed.
    let mut peers = peer_greeting::subscribe(&node_runner).await?;
    let counted = heard.clone();
    tokio::spawn(async move {
        // `None` once the node is stopping.
        while let Ok(Some((from, message))) = peers.next().await {
            counted.fetch_add(1, Ordering::Relaxed);
            println!("{}: {}", from.instance_id, message.text);
        }
    });

    let publisher = greeting::declare_publisher(&node_runner).await?;
    let token = node_runner.cancellation_token().clone();
    let me = node_runner.instance_id().to_string();
    let period = Duration::from_millis(u64::from(params.period_ms.max(1)));
    tokio::spawn(async move {
        let mut ticks = tokio::time::interval(period);
        for count in 0u64.. {
            tokio::select! {
                _ = token.cancelled() => return,
                _ = ticks.tick() => {}
            }
            let text = format!("hello from {me}");
            let sent = match greeting::build_message(text, count, heard.load(Ordering::Relaxed)) {
                Ok(message) => publisher.publish(message).await,
                Err(e) => Err(e),
            };
            if let Err(e) = sent {
                eprintln!("{me}: greeting not sent: {e}");
                return;
            }
        }
    });

    node_runner.on_shutdown(async {
        println!("{{name}}: goodbye");
    });
    Ok(())
}
