"""The errors peppy calls raise; the same cases and wording as the Rust runtime."""

from __future__ import annotations

from typing import Optional


class PeppyError(Exception):
    """Base of every error a peppy runtime call raises."""


def _on(instance: Optional[str]) -> str:
    return f" on `{instance}`" if instance else ""


class ServiceUnreachable(PeppyError):
    """No server of the service (or action) answered."""

    def __init__(self, service: str, instance: Optional[str] = None) -> None:
        self.service = service
        self.instance = instance
        super().__init__(f"service `{service}`{_on(instance)} is unreachable: no server answered")


class ServiceTimeout(PeppyError, TimeoutError):
    """A server accepted the request (it acked) but did not answer in time."""

    def __init__(self, service: str, instance: Optional[str] = None) -> None:
        self.service = service
        self.instance = instance
        super().__init__(f"service `{service}`{_on(instance)} accepted the request but did not reply in time")


class ServiceError(PeppyError):
    """The server answered with an error: its handler failed, or the formats differ."""

    def __init__(self, service: str, instance: str, reason: str) -> None:
        self.service = service
        self.instance = instance
        self.reason = reason
        super().__init__(f"service `{service}` failed on `{instance}`: {reason}")


class ShuttingDown(PeppyError):
    """The node is stopping: waits end, new calls are refused."""

    def __init__(self) -> None:
        super().__init__("the node is shutting down")


class StartupError(PeppyError):
    """Start-up inputs are missing or invalid (flags, runtime config, bindings, parameters)."""


class FeedbackEnded(PeppyError):
    """A goal's feedback stream has ended: the goal is terminal."""

    def __init__(self, action: str) -> None:
        self.action = action
        super().__init__(f"the feedback stream of action `{action}` has ended")


class Undeclared(PeppyError):
    """An entry or slot was used that this node does not declare."""

    def __init__(self, what: str) -> None:
        self.what = what
        super().__init__(f"`{what}` is not declared by this node")
