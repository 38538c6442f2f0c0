"""`NodeRunner`: a running node's identity, its Zenoh session, what it
declared, and its stop. Generated code passes it to every call."""

from __future__ import annotations

import asyncio
import inspect
import logging
import weakref
from typing import Any, Awaitable, Dict, Iterable, List, Optional, Tuple

from .action_server import Registry
from .action_states import ResultStatus
from .bridge import Mailbox
from .errors import ShuttingDown, StartupError, Undeclared
from .intake import finish
from .keys import entry_key
from .routing import SlotPlan
from .spec import ActionSpec, ConsumedTopicSpec, NodeDescriptor, ServiceSpec, TopicSpec
from .startup import Startup
from .topics import Inbox

log = logging.getLogger("peppy")

TASKS_STOP_BOUND = 0.25
"""How long a stopping node waits for its cancelled tasks (seconds)."""


class NodeRunner:
    """A running node: its identity, its Zenoh session, and what generated
    code uses to publish, receive, serve and call.

    `stopped` is set once the node begins stopping (a signal, `stop()`,
    `shutdown()`); waits then raise `ShuttingDown`.
    """

    def __init__(self, descriptor: NodeDescriptor, startup: Startup, session: Any, parameters: Any) -> None:
        self.descriptor = descriptor
        self.node_name = descriptor.name
        self.node_tag = descriptor.tag
        self.instance_id = startup.instance_id
        self.core_node = startup.core_node
        self.namespace = startup.namespace
        self.parameters = parameters
        self.session = session
        self.loop = asyncio.get_running_loop()
        self.stopped = asyncio.Event()
        self.slots: List[SlotPlan] = list(startup.slots)
        self._slots: Dict[str, SlotPlan] = {s.link_id: s for s in self.slots}
        self._publishers: Dict[TopicSpec, Any] = {}
        self._inboxes: Dict[ConsumedTopicSpec, Inbox] = {}
        self._services: Dict[ServiceSpec, Tuple[Mailbox, str]] = {}
        self._actions: Dict[ActionSpec, Tuple[Mailbox, Registry]] = {}
        self._mailboxes: "weakref.WeakSet[Mailbox]" = weakref.WeakSet()
        self._declared: List[Any] = []
        self._token: Any = None
        self._tasks: "set[asyncio.Task[Any]]" = set()
        self._session_closed = False
        self._shutdown: Optional["asyncio.Future[None]"] = None

    def __repr__(self) -> str:
        return (
            f"NodeRunner(node={self.node_name}:{self.node_tag}, instance_id={self.instance_id!r}, "
            f"namespace={self.namespace!r})"
        )

    def is_stopping(self) -> bool:
        """Whether the node has begun stopping."""
        return self.stopped.is_set()

    @property
    def session_closed(self) -> bool:
        """Whether the Zenoh session is closed (the node has shut down)."""
        return self._session_closed

    def slot(self, link_id: str) -> SlotPlan:
        """The slot named `link_id`, with its binding and filter."""
        try:
            return self._slots[link_id]
        except KeyError:
            raise Undeclared(f"slot `{link_id}`") from None

    def stop(self) -> None:
        """Begins stopping the node, as SIGTERM does: every wait raises
        `ShuttingDown`, and `NodeBuilder.run` shuts the node down."""
        if self.stopped.is_set():
            return
        self.stopped.set()
        for mailbox in list(self._mailboxes):
            mailbox.close()

    async def shutdown(self) -> None:
        """Stops the node: cancels its tasks, abandons unfinished goals,
        undeclares everything and closes the session. Idempotent."""
        if self._shutdown is not None:
            await asyncio.shield(self._shutdown)
            return
        self._shutdown = self.loop.create_future()
        try:
            self.stop()
            await self._cancel_tasks()
            # Requests still queued get no answer: end them, so their
            # callers learn it now rather than at their timeout.
            for mailbox, _ in list(self._services.values()) + list(self._actions.values()):
                for pending in mailbox.take_all():
                    finish(pending.query)
            for _, registry in self._actions.values():
                for goal_id in registry.active_goals():
                    if registry.finish(goal_id, ResultStatus.ABANDONED, b""):
                        log.warning(
                            "action `%s`: goal %s unfinished at shutdown: reported abandoned",
                            registry.spec.name,
                            goal_id,
                        )
            for entity in reversed(self._declared):
                try:
                    entity.undeclare()
                except Exception:
                    pass
            self._declared.clear()
            if self._token is not None:
                try:
                    self._token.undeclare()
                except Exception:
                    pass
            self._session_closed = True
            try:
                await self.loop.run_in_executor(None, self.session.close)
            except Exception as e:
                log.warning("closing the zenoh session: %s", e)
        finally:
            self._shutdown.set_result(None)

    async def _cancel_tasks(self) -> None:
        tasks = [t for t in self._tasks if not t.done() and t is not asyncio.current_task()]
        for t in tasks:
            t.cancel()
        if tasks:
            await asyncio.wait(tasks, timeout=TASKS_STOP_BOUND)

    def adopt(self, tasks: Iterable[Any]) -> None:
        """Keeps the node's tasks: cancelled when it stops, failures logged."""
        for t in tasks:
            if inspect.iscoroutine(t):
                t = self.loop.create_task(t)
            if not isinstance(t, asyncio.Future):
                raise TypeError(f"setup must return asyncio tasks, got {t!r}")
            self._tasks.add(t)
            t.add_done_callback(self._task_done)

    def _task_done(self, task: "asyncio.Future[Any]") -> None:
        self._tasks.discard(task)  # type: ignore[arg-type]
        if task.cancelled():
            return
        exc = task.exception()
        if exc is not None and not isinstance(exc, ShuttingDown):
            log.error("a task of node `%s` failed: %r", self.node_name, exc, exc_info=exc)

    def _spawn(self, coro: Awaitable[Any]) -> None:
        self.adopt([self.loop.create_task(coro)])  # type: ignore[arg-type]

    def _track_mailbox(self, mailbox: Mailbox) -> None:
        if self.stopped.is_set():
            mailbox.close()
        else:
            self._mailboxes.add(mailbox)

    def _publisher(self, spec: TopicSpec) -> Any:
        try:
            return self._publishers[spec]
        except KeyError:
            raise Undeclared(f"emitted topic `{spec.name}`") from None

    def _inbox(self, spec: ConsumedTopicSpec) -> Inbox:
        try:
            return self._inboxes[spec]
        except KeyError:
            raise Undeclared(f"consumed topic `{spec.name}`") from None

    def _service_inbox(self, spec: ServiceSpec) -> Tuple[Mailbox, str]:
        try:
            return self._services[spec]
        except KeyError:
            raise Undeclared(f"exposed service `{spec.name}`") from None

    def _action_server(self, spec: ActionSpec) -> Tuple[Mailbox, Registry]:
        try:
            return self._actions[spec]
        except KeyError:
            raise Undeclared(f"exposed action `{spec.name}`") from None

    def _owner(self, owner: Any) -> str:
        segments = owner.segments(self.node_name, self.node_tag)
        if segments is None:
            raise StartupError("an emitted or exposed entry needs an owner")
        return segments

    def _own_key(self, channel: str, owner: Any, entry: str) -> str:
        return entry_key(self.namespace, channel, self._owner(owner), entry, self.core_node, self.instance_id)

    def _mailbox(self, maxlen: Optional[int] = None) -> Mailbox:
        m = Mailbox(self.loop, maxlen)
        self._track_mailbox(m)
        return m
