"""`NodeRunner`: a running node's identity, its Zenoh session, what it
declared, and its stop. Generated code passes it to every call."""

from __future__ import annotations

import asyncio
import inspect
import logging
import time
import weakref
from typing import Any, Awaitable, Callable, Dict, Iterable, List, Optional, Tuple, Union

from .action_server import Registry
from .action_states import ResultStatus
from .bridge import Mailbox
from .cancellation import CancellationToken
from .errors import ShuttingDown, StartupError, TargetNotBound, Undeclared
from .intake import finish
from .keys import entry_key
from .producer import ProducerRef
from .routing import SlotPlan
from .spec import ActionSpec, ConsumedTopicSpec, NodeDescriptor, ServiceSpec, TopicSpec
from .startup import DEFAULT_SHUTDOWN_GRACE, Startup
from .topics import Inbox

log = logging.getLogger("peppy")

TASKS_STOP_BOUND = 0.25
"""How long a stopping node waits for its cancelled tasks (seconds)."""

ShutdownHook = Callable[[], Any]
"""A function, or an `async def`, run once when the node stops."""


class NodeRunner:
    """A running node: its identity, its Zenoh session, and what generated
    code uses to publish, receive, serve and call.

    `stopped` is set once the node begins stopping (a signal, `stop()`,
    `shutdown()`, its cancellation token cancelled); waits for what arrives
    then raise `ShuttingDown` (the peppylib API: return None). The node's own
    calls (publish, services, actions) go on while its shutdown hooks run,
    until messaging closes.
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
        self.pairs = list(startup.pairs)
        # Pairing slots by link_id (`peppy.pairing`), started with the node.
        self._pairings: Dict[str, Any] = {}
        self._publishers: Dict[TopicSpec, Any] = {}
        self._inboxes: Dict[ConsumedTopicSpec, Inbox] = {}
        self._services: Dict[ServiceSpec, Tuple[Mailbox, str]] = {}
        self._actions: Dict[ActionSpec, Tuple[Mailbox, Registry]] = {}
        # Intakes (what arrives for the node: topic inboxes, requests and
        # goals to serve) close when the node begins stopping; the
        # mailboxes of its own calls stay open while its shutdown hooks run.
        self._intakes: "weakref.WeakSet[Mailbox]" = weakref.WeakSet()
        self._mailboxes: "weakref.WeakSet[Mailbox]" = weakref.WeakSet()
        self._hooks: List[Tuple[str, ShutdownHook]] = []
        self._hooks_pending = False
        self._use_sim_time = startup.use_sim_time
        self.shutdown_grace = startup.shutdown_grace_secs or DEFAULT_SHUTDOWN_GRACE
        self._cancel_token = CancellationToken(self.stop)
        self._bound: Dict[str, List[ProducerRef]] = {
            s.link_id: [ProducerRef(startup.producer_cores.get(p, self.core_node), p) for p in s.binding.producers]
            for s in self.slots
        }
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

    def use_sim_time(self) -> bool:
        """Whether this node follows the stack's sim time (`peppy.clock`)."""
        return self._use_sim_time

    def cancellation_token(self) -> CancellationToken:
        """The node's stop: cancelled when the node begins stopping;
        cancelling it stops the node."""
        return self._cancel_token

    def on_shutdown(self, hook: ShutdownHook) -> None:
        """Runs `hook` (a function or an `async def`, no arguments) when the
        node stops: after its cancellation token is cancelled and before its
        messaging closes, so the hook can still publish and call. Hooks run
        one at a time, the last registered first, all within one window of
        `shutdown_grace_secs`; a hook that raises is logged and skipped, one
        still running when the window ends is cut off (and the rest
        skipped), each named in the log by its `__qualname__`."""
        if not callable(hook):
            raise TypeError(f"a shutdown hook is a function or an async function, got {hook!r}")
        name = getattr(hook, "__qualname__", None) or repr(hook)
        self._hooks.append((name, hook))

    def bound_producers(self, link_id: str) -> List[ProducerRef]:
        """The producers bound to slot `link_id`, in link order (empty for a
        vacant or empty slot). Fixed for the instance's life."""
        self.slot(link_id)
        return list(self._bound.get(link_id, ()))

    def bound_producer(self, link_id: str) -> Optional[ProducerRef]:
        """The first producer bound to slot `link_id`, None when it has none."""
        producers = self.bound_producers(link_id)
        return producers[0] if producers else None

    def ensure_target_bound(self, link_id: str, target: Union[ProducerRef, str, None]) -> str:
        """The instance id of `target` once it is one of slot `link_id`'s
        bound producers; `TargetNotBound` (a `ValueError`) otherwise."""
        bound = [p.instance_id for p in self.bound_producers(link_id)]
        instance = target.instance_id if isinstance(target, ProducerRef) else target
        if not isinstance(instance, str) or instance not in bound:
            raise TargetNotBound(link_id, str(instance), bound)
        return instance

    def refuses_calls(self) -> bool:
        """Whether new calls are refused: once messaging closes, or once the
        node begins stopping when it has no shutdown hook still to run."""
        return self._session_closed or (self.stopped.is_set() and not self._hooks_pending)

    def stop(self) -> None:
        """Begins stopping the node, as SIGTERM does: the cancellation token
        is cancelled, waits for what arrives end (`ShuttingDown`), and
        `NodeBuilder.run` shuts the node down."""
        if self.stopped.is_set():
            return
        self.stopped.set()
        self._hooks_pending = bool(self._hooks)
        self._cancel_token.cancel()
        for mailbox in list(self._intakes):
            mailbox.close()
        if not self._hooks_pending:
            self._close_calls()

    def _close_calls(self) -> None:
        self._hooks_pending = False
        for mailbox in list(self._mailboxes):
            mailbox.close()

    async def _run_hooks(self) -> None:
        """Runs the shutdown hooks, last registered first, in one grace window."""
        hooks = list(reversed(self._hooks))
        self._hooks.clear()
        if not hooks:
            return
        grace = self.shutdown_grace
        deadline = time.monotonic() + grace
        for i, (name, hook) in enumerate(hooks):
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                _skipped(hooks[i:], grace)
                return
            try:
                result = hook()
            except Exception as e:
                log.error("shutdown hook `%s` failed: %r; skipped", name, e, exc_info=e)
                continue
            if not inspect.isawaitable(result):
                continue
            task = asyncio.ensure_future(result)
            done, _ = await asyncio.wait({task}, timeout=remaining)
            if not done:
                task.cancel()
                await asyncio.wait({task}, timeout=TASKS_STOP_BOUND)
                log.warning("shutdown hook `%s` overran the %g s grace window; cut off", name, grace)
                _skipped(hooks[i + 1 :], grace)
                return
            if task.cancelled():
                log.warning("shutdown hook `%s` was cancelled", name)
                continue
            exc = task.exception()
            if exc is not None:
                log.error("shutdown hook `%s` failed: %r; skipped", name, exc, exc_info=exc)

    async def shutdown(self) -> None:
        """Stops the node: cancels its token, runs its shutdown hooks (within
        the grace window), abandons unfinished goals, undeclares everything,
        closes the session, then cancels its tasks. Idempotent."""
        if self._shutdown is not None:
            await asyncio.shield(self._shutdown)
            return
        self._shutdown = self.loop.create_future()
        try:
            self.stop()
            try:
                await self._run_hooks()
            finally:
                self._close_calls()
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
            await self._cancel_tasks()
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

    def _track_mailbox(self, mailbox: Mailbox, intake: bool = False) -> None:
        if intake:
            if self.stopped.is_set():
                mailbox.close()
            else:
                self._intakes.add(mailbox)
        elif self.refuses_calls():
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

    def _mailbox(self, maxlen: Optional[int] = None, intake: bool = False) -> Mailbox:
        m = Mailbox(self.loop, maxlen)
        self._track_mailbox(m, intake)
        return m


def _skipped(hooks: List[Tuple[str, ShutdownHook]], grace: float) -> None:
    if hooks:
        names = ", ".join(f"`{n}`" for n, _ in hooks)
        log.warning("shutdown hooks skipped, the %g s grace window being over: %s", grace, names)
