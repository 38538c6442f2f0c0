"""peppy: the Python runtime of peppy nodes.

Python nodes speak the wire format of docs/WIRE.md over Zenoh, so they
interoperate byte for byte with Rust nodes. Node code starts from its
generated `peppygen` package (`NodeBuilder().run(setup)`); the modules
here are what that package calls.
"""

from . import clock
from .action_states import CancelState, ResultOutcome, ResultStatus
from .cancellation import CancellationToken
from .errors import (
    ActionFeedbackProducerGone,
    ClockNotReady,
    FeedbackEnded,
    PeppyError,
    ServiceError,
    ServiceTimeout,
    ServiceUnreachable,
    ShuttingDown,
    StartupError,
    TargetNotBound,
    Undeclared,
    WrongTopic,
)
from .node import NodeBuilder, NodeRunner
from .pairing import ObservedSource, PeerInfo
from .producer import ProducerRef
from .spec import QoSProfile
from .standalone import StandaloneConfig
from .timestamps import Time

__all__ = [
    "ActionFeedbackProducerGone",
    "CancelState",
    "CancellationToken",
    "ClockNotReady",
    "FeedbackEnded",
    "NodeBuilder",
    "NodeRunner",
    "ObservedSource",
    "PeerInfo",
    "PeppyError",
    "ProducerRef",
    "QoSProfile",
    "ResultOutcome",
    "ResultStatus",
    "ServiceError",
    "ServiceTimeout",
    "ServiceUnreachable",
    "ShuttingDown",
    "StandaloneConfig",
    "StartupError",
    "TargetNotBound",
    "Time",
    "Undeclared",
    "WrongTopic",
    "clock",
]
