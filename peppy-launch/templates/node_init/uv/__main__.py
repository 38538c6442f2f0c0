"""`{{name}}`: greets on `greeting` every `period_ms`, and counts the
greetings it hears from the peers linked to its `peers` slot."""

import asyncio

from peppygen import NodeBuilder, NodeRunner
from peppygen.consumed_topics.peers import greeting as peer_greeting
from peppygen.emitted_topics import greeting
from peppygen.parameters import Parameters


async def listen(subscription, heard: list) -> None:
    # The loop ends once the node is stopping.
    async for producer, message in subscription:
        heard[0] += 1
        print(f"{producer.instance_id}: {message.text}", flush=True)


async def greet(params: Parameters, node_runner: NodeRunner, heard: list) -> None:
    publisher = await greeting.declare_publisher(node_runner)
    token = node_runner.cancellation_token()
    stopping = asyncio.ensure_future(token.cancelled())
    count = 0
    try:
        while not token.is_cancelled():
            text = f"hello from {node_runner.instance_id}"
            await publisher.publish(greeting.build_message(text, count, heard[0]))
            count += 1
            # Sleep between greetings, waking at once when the node stops.
            await asyncio.wait([stopping], timeout=max(params.period_ms, 1) / 1000)
    finally:
        stopping.cancel()


async def setup(params: Parameters, node_runner: NodeRunner) -> list:
    heard = [0]
    # Subscribed before `setup` returns: a node counts as started once it
    # has, so nothing a peer sends after that is missed.
    subscription = await peer_greeting.subscribe(node_runner)
    node_runner.on_shutdown(lambda: print("{{name}}: goodbye", flush=True))
    return [
        asyncio.create_task(listen(subscription, heard)),
        asyncio.create_task(greet(params, node_runner, heard)),
    ]


def main() -> None:
    NodeBuilder().run(setup)


if __name__ == "__main__":
    main()
