"""Actions (docs/WIRE.md §4): a goal service that accepts or rejects, a
feedback stream per goal, a cancel service, and a result service that
parks the caller until the goal is terminal. Several goals run at once on
one server; results are kept for a retention period, then reported
`EXPIRED`; a goal dropped unfinished is reported `ABANDONED`.

The exposed side is in `action_server`, the consumed side in
`action_client`; this module is what generated code imports."""

from .action_client import GoalClient, fire_goal
from .action_server import DEFAULT_RESULT_RETENTION, GoalContext, GoalServer
from .action_states import CancelState, ResultOutcome, ResultStatus

__all__ = [
    "CancelState",
    "DEFAULT_RESULT_RETENTION",
    "GoalClient",
    "GoalContext",
    "GoalServer",
    "ResultOutcome",
    "ResultStatus",
    "fire_goal",
]
