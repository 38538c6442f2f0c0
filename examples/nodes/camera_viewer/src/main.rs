//! `camera_viewer`: a node in today's spelling (`node/v1`). Its module
//! paths nest consumed entries under their slot (`consumed_topics::cameras::
//! video_stream`), and each slot says what the launcher linked to it.

#[peppy::node("peppy.json5")]
mod peppygen {}

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use peppygen::consumed_topics::{cameras, overhead};
use peppygen::{NodeBuilder, Parameters, Result};

fn main() -> Result<()> {
    NodeBuilder::new().run(|_params: Parameters, runner| async move {
        println!(
            "cameras: linked to {}",
            cameras::bound_producers(&runner).join(", ")
        );
        match overhead::bound_producer(&runner) {
            Some(camera) => println!("overhead: linked to {camera}"),
            None => println!("overhead: vacant"),
        }
        let watch = runner.clone();
        tokio::spawn(async move {
            let mut frames: BTreeMap<String, u64> = BTreeMap::new();
            let mut last = Instant::now();
            while let Ok((camera, frame)) =
                cameras::video_stream::on_next_message_received(&watch, None).await
            {
                let count = frames.entry(camera.clone()).or_insert(0);
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
            while let Ok((camera, frame)) =
                overhead::video_stream::on_next_message_received(&runner, None).await
            {
                println!("overhead: frame {} from {camera}", frame.header.frame_id);
            }
        });
        Ok(())
    })
}
