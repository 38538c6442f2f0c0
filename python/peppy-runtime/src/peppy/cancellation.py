"""`CancellationToken`: the node's stop, as the peppylib node API hands it
out (`node_runner.cancellation_token()`)."""

from __future__ import annotations

import asyncio
from typing import Callable, List, Optional


class CancellationToken:
    """Cancelled once, for good. The node's token is cancelled when the node
    begins stopping (a signal, the launcher, setup failing); cancelling it
    from code stops the node the same way."""

    def __init__(self, on_cancel: Optional[Callable[[], None]] = None) -> None:
        self._cancelled = False
        self._waiters: List["asyncio.Future[None]"] = []
        self._on_cancel = on_cancel
        self._children: List["CancellationToken"] = []

    def __repr__(self) -> str:
        return f"CancellationToken(cancelled={self._cancelled})"

    def is_cancelled(self) -> bool:
        """Whether the token is cancelled."""
        return self._cancelled

    def cancel(self) -> None:
        """Cancels the token (and its children); later calls do nothing."""
        if self._cancelled:
            return
        self._cancelled = True
        waiters, self._waiters = self._waiters, []
        for w in waiters:
            if not w.done():
                w.set_result(None)
        for child in self._children:
            child.cancel()
        if self._on_cancel is not None:
            self._on_cancel()

    async def cancelled(self) -> None:
        """Returns once the token is cancelled (at once if it is)."""
        if self._cancelled:
            return
        waiter = asyncio.get_running_loop().create_future()
        self._waiters.append(waiter)
        try:
            await waiter
        finally:
            if waiter in self._waiters:
                self._waiters.remove(waiter)

    def child_token(self) -> "CancellationToken":
        """A token cancelled with this one, that can also be cancelled alone."""
        child = CancellationToken()
        if self._cancelled:
            child.cancel()
        else:
            self._children.append(child)
        return child
