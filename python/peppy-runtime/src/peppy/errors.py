"""The errors peppy calls raise; the same cases and wording as the Rust runtime."""

from __future__ import annotations

from typing import Optional


class PeppyError(Exception):
    """Base of every error a peppy runtime call raises."""


def _on(instance: Optional[str]) -> str:
    return f" on `{instance}`" if instance else ""


class ServiceUnreachable(PeppyError, ConnectionError):
    """No server of the service (or action) answered (a `ConnectionError`)."""

    def __init__(self, service: str, instance: Optional[str] = None) -> None:
        self.service = service
        self.instance = instance
        # PeppyOS's names for the same two.
        self.service_name = service
        self.instance_id = instance
        super().__init__(f"service `{service}`{_on(instance)} is unreachable: no server answered")


class ServiceTimeout(PeppyError, TimeoutError):
    """A server accepted the request (it acked) but did not answer in time (a `TimeoutError`)."""

    def __init__(self, service: str, instance: Optional[str] = None) -> None:
        self.service = service
        self.instance = instance
        # PeppyOS's names for the same two.
        self.service_name = service
        self.instance_id = instance
        super().__init__(f"service `{service}`{_on(instance)} accepted the request but did not reply in time")


class ServiceError(PeppyError, RuntimeError):
    """The server answered with an error: its handler failed, or the formats differ (a `RuntimeError`)."""

    def __init__(self, service: str, instance: str, reason: str) -> None:
        self.service = service
        self.instance = instance
        # PeppyOS's names for the same two.
        self.service_name = service
        self.instance_id = instance
        self.reason = reason
        super().__init__(f"service `{service}` failed on `{instance}`: {reason}")


class ShuttingDown(PeppyError):
    """The node is stopping: waits end, new calls are refused."""

    def __init__(self) -> None:
        super().__init__("the node is shutting down")


class StartupError(PeppyError):
    """Start-up inputs are missing or invalid (flags, runtime config, bindings, parameters)."""


class FeedbackEnded(PeppyError, RuntimeError):
    """A goal's feedback stream has ended: the goal is terminal (a `RuntimeError`)."""

    def __init__(self, action: str) -> None:
        self.action = action
        super().__init__(f"the feedback stream of action `{action}` has ended")


class ActionFeedbackProducerGone(PeppyError, ConnectionError):
    """The server a goal was sent to went away (its process died, its host
    was lost) without closing the goal's feedback stream (a
    `ConnectionError`); the goal's result is ABANDONED."""

    def __init__(self, action: str, instance: Optional[str] = None) -> None:
        self.action = action
        self.instance = instance
        super().__init__(f"action `{action}`{_on(instance)} went away before closing the feedback stream")


class Undeclared(PeppyError):
    """An entry or slot was used that this node does not declare."""

    def __init__(self, what: str) -> None:
        self.what = what
        super().__init__(f"`{what}` is not declared by this node")


class TargetNotBound(PeppyError, ValueError):
    """A service or action was called on a producer its slot is not bound
    to (a `ValueError`): the peppylib API names the target, one of the slot's
    `bound_producer(s)`."""

    def __init__(self, slot: str, target: str, bound: "list[str]") -> None:
        self.slot = slot
        self.target = target
        self.bound = list(bound)
        where = f" (it is bound to {', '.join(bound)})" if bound else " (it is bound to no producer)"
        super().__init__(f"`{target}` is not bound to slot `{slot}`{where}")


class WrongTopic(PeppyError, ValueError):
    """A message built for one topic was handed to another topic's publisher."""

    def __init__(self, publisher: str, message: str) -> None:
        self.publisher = publisher
        self.message = message
        super().__init__(f"a message of topic `{message}` cannot be published on topic `{publisher}`")


class ClockNotReady(PeppyError, RuntimeError):
    """The stack clock has no time to give yet (a `RuntimeError`): `init`
    was not called, or, following sim time, no sim tick has arrived (or the
    launcher has seen none, for `synchronize`)."""

    def __init__(self, why: str = "the clock is not ready") -> None:
        super().__init__(why)
