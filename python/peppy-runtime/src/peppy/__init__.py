"""peppy: the Python runtime of peppy nodes.

Python nodes speak the wire format of docs/WIRE.md over Zenoh, so they
interoperate byte for byte with Rust nodes. Node code starts from its
generated `peppygen` package (`NodeBuilder().run(setup)`); the modules
here are what that package calls.
"""

from .action_states import CancelState, ResultOutcome, ResultStatus
from .errors import (
    FeedbackEnded,
    PeppyError,
    ServiceError,
    ServiceTimeout,
    ServiceUnreachable,
    ShuttingDown,
    StartupError,
    Undeclared,
)
from .node import NodeBuilder, NodeRunner
from .spec import QoSProfile
from .timestamps import Time

__all__ = [
    "CancelState",
    "FeedbackEnded",
    "NodeBuilder",
    "NodeRunner",
    "PeppyError",
    "QoSProfile",
    "ResultOutcome",
    "ResultStatus",
    "ServiceError",
    "ServiceTimeout",
    "ServiceUnreachable",
    "ShuttingDown",
    "StartupError",
    "Time",
    "Undeclared",
]
