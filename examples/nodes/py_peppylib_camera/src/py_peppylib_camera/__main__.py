"""`py_peppylib_camera`: a depth_camera:v1 driver written as Python nodes
are in PeppyOS's `peppylib` API: a publisher declared once and fed built
messages, a service answered in a loop, the cancellation token ending both,
a shutdown hook, and frames stamped by the stack clock."""

import asyncio
import sys

from peppygen import NodeBuilder, NodeRunner, clock
from peppygen.emitted_topics.camera import video_stream
from peppygen.exposed_services.camera import video_stream_info
from peppygen.parameters import Parameters
from peppylib import CancellationToken


def frame(width: int, height: int, t: int) -> bytes:
    """A gradient moving down one row per frame: mono8 pixels."""
    return bytes(((y + t) * 4) & 0xFF for y in range(height) for _ in range(width))


async def stream(params: Parameters, node_runner: NodeRunner, token: CancellationToken, sent: list) -> None:
    publisher = await video_stream.declare_publisher(node_runner)
    period = 1.0 / max(params.frames_per_second, 1)
    stopping = asyncio.ensure_future(token.cancelled())
    try:
        while not token.is_cancelled():
            stamp_ns = clock.now_ns()
            header = video_stream.MessageHeader(stamp=stamp_ns / 1e9, frame_id=sent[0] & 0xFFFFFFFF)
            pixels = frame(params.width, params.height, sent[0])
            await publisher.publish(
                video_stream.build_message(header, "mono8", params.width, params.height, pixels)
            )
            if sent[0] % 30 == 0:
                print(f"frame {sent[0]} stamped {stamp_ns} ns", flush=True)
            sent[0] += 1
            # Sleep between frames, waking at once when the node stops.
            await asyncio.wait([stopping], timeout=period)
    finally:
        stopping.cancel()


async def serve_info(params: Parameters, node_runner: NodeRunner) -> None:
    def answer(request: video_stream_info.Request) -> video_stream_info.Response:
        print(f"stream info asked by `{request.instance_id}`", flush=True)
        return video_stream_info.Response(
            width=params.width, height=params.height, frames_per_second=params.frames_per_second, encoding="mono8"
        )

    while not node_runner.cancellation_token().is_cancelled():
        await video_stream_info.handle_next_request(node_runner, answer)


async def setup(params: Parameters, node_runner: NodeRunner) -> list:
    await clock.init(node_runner)
    token = node_runner.cancellation_token()
    sent = [0]

    async def report() -> None:
        if params.close_secs > 0:
            print(f"py_peppylib_camera: closing the device ({params.close_secs:g} s)", flush=True)
            await asyncio.sleep(params.close_secs)
        print(f"py_peppylib_camera: stopping after {sent[0]} frames", flush=True)

    node_runner.on_shutdown(report)
    print(
        f"py_peppylib_camera `{node_runner.instance_id}`: "
        f"{params.width}x{params.height} @ {params.frames_per_second} fps",
        file=sys.stderr,
        flush=True,
    )
    return [
        asyncio.create_task(stream(params, node_runner, token, sent)),
        asyncio.create_task(serve_info(params, node_runner)),
    ]


def main() -> None:
    NodeBuilder().run(setup)


if __name__ == "__main__":
    main()
