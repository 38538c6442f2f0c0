"""`py_depth_camera`: a depth_camera:v1 driver in Python.

It inherits `video_stream` and `video_stream_info` from the interface, so
its generated modules are the interface's, and a Rust consumer's slot on
depth_camera:v1 cannot tell it from a Rust camera.
"""

import asyncio
import sys
import time

from peppygen import NodeBuilder, NodeRunner
from peppygen.emitted_topics import video_stream
from peppygen.exposed_services import video_stream_info
from peppygen.parameters import Parameters


def frame(width: int, height: int, t: int) -> bytes:
    """A gradient moving down one row per frame: mono8 pixels."""
    return bytes(((y + t) * 4) & 0xFF for y in range(height) for _ in range(width))


async def stream(params: Parameters, node_runner: NodeRunner) -> None:
    period = 1.0 / max(params.frames_per_second, 1)
    frame_id = 0
    while True:
        header = video_stream.MessageHeader(stamp=time.time(), frame_id=frame_id)
        pixels = frame(params.width, params.height, frame_id)
        await video_stream.emit(node_runner, header, "mono8", params.width, params.height, pixels)
        frame_id = (frame_id + 1) & 0xFFFFFFFF
        await asyncio.sleep(period)


async def serve_info(params: Parameters, node_runner: NodeRunner) -> None:
    def answer(request: video_stream_info.Request) -> video_stream_info.Response:
        print(f"stream info asked by `{request.instance_id}`", file=sys.stderr, flush=True)
        return video_stream_info.Response(
            params.width, params.height, params.frames_per_second, "mono8"
        )

    while True:
        await video_stream_info.handle_next_request(node_runner, answer)


async def setup(params: Parameters, node_runner: NodeRunner) -> list:
    print(
        f"py_depth_camera `{node_runner.instance_id}`: "
        f"{params.width}x{params.height} @ {params.frames_per_second} fps",
        file=sys.stderr,
        flush=True,
    )
    return [
        asyncio.create_task(stream(params, node_runner)),
        asyncio.create_task(serve_info(params, node_runner)),
    ]


def main() -> None:
    NodeBuilder().run(setup)


if __name__ == "__main__":
    main()
