//! `camera_viewer`: a node in today's spelling (`node/v1`) and today's node
//! API. Its module paths nest consumed entries under their slot
//! (`consumed_topics::cameras::video_stream`), each slot says what the
//! launcher linked to it, and frames arrive through held subscriptions.

#[peppy::node("peppy.json5")]
mod peppygen {}

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use peppygen::consumed_topics::{cameras, overhead};
use peppygen::{NodeBuilder, Parameters, Result};

fn main() -> Result<()> {
    NodeBuilder::new().run(|_params: Parameters, runner| async move {
        let linked: Vec<String> = cameras::bound_producers(&runner)
            .iter()
            .map(ToString::to_string)
            .collect();
        println!("cameras: linked to {}", linked.join(", "));
        match overhead::bound_producer(&runner) {
            Some(camera) => println!("overhead: linked to {camera}"),
            None => println!("overhead: vacant"),
        }
        // Subscribed before setup returns: nothing sent from now on is missed.
        let mut frames_in = cameras::video_stream::subscribe(&runner).await?;
        let mut overhead_in = overhead::video_stream::subscribe(&runner).await?;
        tokio::spawn(async move {
            let mut frames: BTreeMap<String, u64> = BTreeMap::new();
            let mut last = Instant::now();
            while let Ok(Some((camera, frame))) = frames_in.next().await {
                let count = frames.entry(camera.to_string()).or_insert(0);
                if *count == 0 {
                    println!(
                        "cameras: first frame from {camera} ({}x{})",
                        frame.width, frame.height
                    );
                }
                *count += 1;
                if last.elapsed() > Duration::from_secs(5) {
                    last = Instant::now();
                    let row: Vec<String> = frames.iter().map(|(c, n)| format!("{c}:{n}")).collect();
                    println!("viewing {}", row.join(" "));
                }
            }
        });
        tokio::spawn(async move {
            while let Ok(Some((camera, frame))) = overhead_in.next().await {
                println!("overhead: frame {} from {camera}", frame.header.frame_id);
            }
        });
        Ok(())
    })
}
