//! `camera_mosaic`: one `from_any` slot (`extras`) taking every depth camera
//! the launcher binds to it. The free-form binding keys never reach the
//! code: producers are told apart by the instance id each frame carries.

#[peppy::node("peppy.json5")]
mod peppygen {}

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use peppygen::consumed_topics::extras_video_stream;
use peppygen::{NodeBuilder, Parameters, Result};

fn main() -> Result<()> {
    NodeBuilder::new().run(|params: Parameters, runner| async move {
        tokio::spawn(async move {
            // `from_core_node` filters by the machine a camera runs on.
            let only = Some(params.only_core_node).filter(|c| !c.is_empty());
            let mut tiles: BTreeMap<String, u64> = BTreeMap::new();
            let mut last = Instant::now();
            while let Ok((producer, frame)) =
                extras_video_stream::on_next_message_received(&runner, only.as_deref()).await
            {
                let count = tiles.entry(producer.clone()).or_insert(0);
                if *count == 0 {
                    println!(
                        "extras: first frame from {producer} ({}x{})",
                        frame.width, frame.height
                    );
                }
                *count += 1;
                if last.elapsed() > Duration::from_secs(1) {
                    last = Instant::now();
                    let row: Vec<String> = tiles.iter().map(|(p, n)| format!("{p}:{n}")).collect();
                    println!("mosaic of {} tiles: {}", tiles.len(), row.join(" "));
                }
            }
        });
        Ok(())
    })
}
