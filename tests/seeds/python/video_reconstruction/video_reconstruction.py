"""Seed 000's consumer fragment, run as a node: the page leaves `Frame`,
`reconstruct` and the task it runs in to the reader; here `reconstruct`
prints which producers it has frames from whenever that set changes."""

import asyncio

from peppygen import NodeBuilder, NodeRunner
from peppygen.consumed_topics.extras_video_stream import Message as Frame

_seen: list = []


def reconstruct(frames_by_producer: dict) -> None:
    producers = sorted(frames_by_producer)
    if producers != _seen:
        _seen[:] = producers
        print(f"reconstructing from {', '.join(producers)}")


async def consume(node_runner: NodeRunner) -> None:
    # seed 000: begin
    from peppygen.consumed_topics import extras_video_stream

    frames_by_producer: dict[str, Frame] = {}

    while True:
        instance_id, frame = await extras_video_stream.on_next_message_received(node_runner)
        # Use the returned id as a runtime key; do not compare against a hard-coded name.
        frames_by_producer[instance_id] = frame
        reconstruct(frames_by_producer)
    # seed 000: end


async def setup(_params, node_runner: NodeRunner) -> list:
    return [asyncio.create_task(consume(node_runner))]


def main() -> None:
    NodeBuilder().run(setup)
