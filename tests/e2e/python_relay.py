"""Relays every message shape of the `shapes` fixture through Python.

A Python `shapes_client` (bound to the Rust producer) decodes each message
into the generated dataclasses; a Python `shapes` instance re-encodes it
field by field and publishes it. A Rust client bound to the Python
producer then sees exactly what the Rust producer sent, or nothing at all
(a fingerprint that differed would make it drop the messages).

Usage: python_relay.py CLIENT_PLAN SERVER_PLAN (the two nodes' runtime
configs, planned by the test as `peppy-launch plan` plans a node)
Prints the Python side's fingerprints as one JSON line, then `ready`, and
relays until stdin closes.
"""

import asyncio
import dataclasses
import json
import sys
import traceback

import client_gen
import shapes_gen
from client_gen import consumed_topics as c
from shapes_gen import emitted_topics as e

PAIRS = {
    "everything": (c.shapes_everything, e.everything),
    "nested": (c.shapes_nested, e.nested),
    "optionals": (c.shapes_optionals, e.optionals),
    "keywords": (c.shapes_keywords, e.keywords),
    "tick": (c.shapes_tick, e.tick),
    "video_stream": (c.shapes_video_stream, e.video_stream),
}


async def relay(client, server, source, target) -> None:
    try:
        while True:
            _, message = await source.on_next_message_received(client)
            values = [getattr(message, f.name) for f in dataclasses.fields(message)]
            await target.emit(server, *values)
    except asyncio.CancelledError:
        raise
    except BaseException:
        # A relay that fails must say why: the test sees only silence.
        traceback.print_exc()
        raise


async def main() -> None:
    client_plan, server_plan = sys.argv[1:3]
    client = await client_gen.NodeBuilder().with_runtime_config(client_plan).start()
    server = await shapes_gen.NodeBuilder().with_runtime_config(server_plan).start()
    prints = {
        name: [source.SPEC.format.fingerprint, target.SPEC.format.fingerprint]
        for name, (source, target) in PAIRS.items()
    }
    print(json.dumps(prints), flush=True)
    tasks = [
        asyncio.create_task(relay(client, server, source, target))
        for source, target in PAIRS.values()
    ]
    print("ready", flush=True)
    await asyncio.get_running_loop().run_in_executor(None, sys.stdin.read)
    for t in tasks:
        t.cancel()
    await client.shutdown()
    await server.shutdown()


if __name__ == "__main__":
    asyncio.run(main())
