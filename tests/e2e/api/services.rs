#![deny(warnings)]

#[peppy::node("tests/e2e/api/services.json5")]
mod peppygen {}

use std::time::Duration;

use peppygen::consumed_services::{cam_video_stream_info, front_reset};
use peppygen::exposed_services::{command, echo, status, trigger};
use peppygen::{NodeRunner, Result};

async fn serve(runner: &NodeRunner) -> Result<()> {
    echo::handle_next_request(runner, |request: echo::Request| {
        let _: (&str, &str) = (&request.instance_id, &request.core_node);
        Ok(echo::Response::new(
            request.data.text,
            echo::ResponseMeta {
                id: request.data.meta.id,
            },
        ))
    })
    .await?;
    trigger::handle_next_request(runner, |request| {
        let _ = request.instance_id;
        Ok(())
    })
    .await?;
    status::handle_next_request(runner, |_| Ok(status::Response::new(true))).await?;
    command::handle_next_request(runner, |request| {
        if request.data.code == 0 {
            return Err("code 0 is reserved".into());
        }
        Ok(())
    })
    .await
}

async fn call(runner: &NodeRunner) -> Result<()> {
    let info = cam_video_stream_info::poll(runner, Duration::from_secs(1)).await?;
    let _: (String, String, u32, u32, u8, String) = (
        info.instance_id,
        info.core_node,
        info.data.width,
        info.data.height,
        info.data.frames_per_second,
        info.data.encoding,
    );
    let reset = front_reset::poll(
        runner,
        Duration::from_secs(1),
        front_reset::Request::new(true),
    )
    .await?;
    let _: (bool, Option<String>) = (reset.data.ok, reset.data.note);
    let literal = front_reset::Request { hard: false };
    front_reset::poll(runner, Duration::from_millis(10), literal).await?;
    Ok(())
}

#[test]
fn compiles_and_runs() {
    let _ = (serve, call);
}
