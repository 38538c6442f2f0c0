"""The benchmark's source as a Python node: answers `ping_reliable` (from
the sink, through the slot `sink`) with
`pong_reliable`, the ping decoded into its generated dataclass and the pong
encoded from it, as the Rust source does. A Rust sink pinging it measures
a Python consumer of a Rust producer (and the Rust consumer of a Python
producer on the way back).

Usage: bench_source.py PLAN (the node's runtime config, with
`bench_source_gen`, the node's generated package, importable). Prints
`{"ready": true}` once it serves, and answers until stdin closes.
"""

import asyncio
import json
import sys
import traceback

import bench_source_gen
from bench_source_gen import consumed_topics as consumed
from bench_source_gen import emitted_topics as emitted


async def answer(node) -> None:
    try:
        while True:
            _, ping = await consumed.sink_ping_reliable.on_next_message_received(node)
            await emitted.pong_reliable.emit(node, ping.seq, ping.sent_ns, ping.data)
    except asyncio.CancelledError:
        raise
    except BaseException:
        # The benchmark sees only a sink that waits: say why.
        traceback.print_exc()
        raise


async def main() -> None:
    node = await bench_source_gen.NodeBuilder().with_runtime_config(sys.argv[1]).start()
    task = asyncio.create_task(answer(node))
    print(json.dumps({"ready": True}), flush=True)
    await asyncio.get_running_loop().run_in_executor(None, sys.stdin.read)
    task.cancel()
    await node.shutdown()


if __name__ == "__main__":
    asyncio.run(main())
