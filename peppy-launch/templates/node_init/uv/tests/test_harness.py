"""`{{name}}` booted in-process under its generated harness
(`peppygen.fixtures`): a mock peer plays its `peers` slot."""

import time

from peppygen.consumed_topics.peers import greeting as peer_greeting
from peppygen.fixtures import harness

from {{module}}.__main__ import setup

WAIT = 10.0


async def test_greets_and_counts_the_greetings_it_hears():
    # One mock peer in the `peers` slot (it takes any number).
    async with harness.start(setup, parameters={"period_ms": 20}, peers_instances=1) as h:
        first = await h.emitted.greeting.next(WAIT)
        assert first.heard == 0

        # A peer greets once: the node's later greetings count it.
        await h.mocks.deps.peers[0].greeting.publish(
            peer_greeting.Message(text="hello from a mock peer", count=0, heard=0)
        )
        deadline = time.monotonic() + WAIT
        while (await h.emitted.greeting.next(WAIT)).heard != 1:
            assert time.monotonic() < deadline, "the peer's greeting was never counted"
