//! The parts of the peppylib Python node API, for `node/v1` documents,
//! that have no emit-API counterpart: held publishers, held subscriptions
//! yielding `(ProducerRef, Message)`, goals aimed at a bound producer,
//! `GoalDecision`, and the slot's `bound_producer(s)` in every consumed
//! module, on the `peppy` runtime's `peppy.peppylib_api`. Each entry's
//! module is written by one function in [`super::modules`], for both
//! APIs; it calls these where the peppylib API's shape differs.

use peppy_schema::{ActionDecl, Cardinality, ResolvedCall, ResolvedNode};

use super::modules::GoalServerShape;
use super::source::{Source, py_string};

/// The imports the peppylib API's modules add to the common header.
pub(super) const IMPORTS: &str =
    "from peppy import peppylib_api as _peppylib\nfrom peppy.producer import ProducerRef";

/// The slot `link_id`'s accessor: `bound_producer(node_runner)` for `one`
/// (a `ProducerRef`) and `zero_or_one` (`Optional[ProducerRef]`),
/// `bound_producers(node_runner)` (a list, in link order) for the others.
pub(super) fn accessor(out: &mut Source, link_id: &str, cardinality: Option<Cardinality>) {
    let link = py_string(link_id);
    match cardinality {
        Some(Cardinality::One) => {
            out.line("def bound_producer(node_runner: NodeRunner) -> ProducerRef:");
            out.indent();
            out.docstring(&format!(
                "The producer bound to slot `{link_id}` (cardinality `one`), fixed at start-up:\n\
                 the `target` of this slot's calls and goals."
            ));
            out.line(&format!("return node_runner.bound_producer({link})"));
            out.dedent();
        }
        Some(Cardinality::ZeroOrOne) => {
            out.line("def bound_producer(node_runner: NodeRunner) -> Optional[ProducerRef]:");
            out.indent();
            out.docstring(&format!(
                "The producer bound to slot `{link_id}` (cardinality `zero_or_one`), `None` when vacant."
            ));
            out.line(&format!("return node_runner.bound_producer({link})"));
            out.dedent();
        }
        Some(c @ (Cardinality::OneOrMore | Cardinality::ZeroOrMore)) => {
            out.line("def bound_producers(node_runner: NodeRunner) -> List[ProducerRef]:");
            out.indent();
            out.docstring(&format!(
                "The producers bound to slot `{link_id}` (cardinality `{c}`), in link order."
            ));
            out.line(&format!("return node_runner.bound_producers({link})"));
            out.dedent();
        }
        None => {}
    }
}

/// The slot's accessor in a module consumed through it (as in the slot's
/// package), when the node declares the slot.
pub(super) fn slot_accessor(out: &mut Source, node: &ResolvedNode, link_id: &str) {
    let cardinality = node.node.dependency(link_id).map(|d| d.cardinality);
    if cardinality.is_some() {
        accessor(out, link_id, cardinality);
        out.blank();
        out.blank();
    }
}

/// `declare_publisher`: the held publisher of topic `name`.
pub(super) fn declare_publisher(out: &mut Source, name: &str) {
    out.line("async def declare_publisher(node_runner: NodeRunner) -> _peppylib.Publisher:");
    out.indent();
    out.docstring(&format!(
        "The publisher of `{name}`: `await publisher.publish(build_message(...))`."
    ));
    out.line("return await _peppylib.declare_publisher(node_runner, SPEC)");
    out.dedent();
}

/// `Subscription` and `subscribe`: topic `name`, held.
pub(super) fn subscription(out: &mut Source, name: &str) {
    out.line(&format!(
        r#"class Subscription(_peppylib.Subscription):
    """Topic `{name}`, held: messages are queued from the node's start, so
    none is lost between calls. `await sub.next()` gives `(producer, message)`,
    None once the node stops; `async for producer, message in sub` reads until then."""

    async def next(self) -> Optional[Tuple[ProducerRef, Message]]:
        return await super().next()


async def subscribe(node_runner: NodeRunner) -> Subscription:
    """Holds topic `{name}` (subscribed when the node started)."""
    return Subscription(node_runner, SPEC)"#
    ));
}

/// The peppylib API's exposed action: the decider returns a `GoalDecision`, rejected
/// goals are skipped, and `cancel_signal` is awaited.
pub(super) const GOAL_SERVER: GoalServerShape = GoalServerShape {
    decision: r#"class GoalDecision:
    """What the decider returns: `GoalDecision.accept()` (`accept(response)`
    when the action declares a goal response) or `GoalDecision.reject(reason)`
    (`reject(reason, response)` to send one with the rejection)."""

    def __init__(self, accepted: bool, reason: Optional[str] = None, response: Any = None) -> None:
        self.accepted = accepted
        self.reason = reason
        self.response = response

    def __repr__(self) -> str:
        return f"GoalDecision(accepted={self.accepted}, reason={self.reason!r})"

    @classmethod
    def accept(cls, response: Any = None) -> "GoalDecision":
        return cls(True, None, response)

    @classmethod
    def reject(cls, reason: Optional[str] = None, response: Any = None) -> "GoalDecision":
        return cls(False, reason, response)"#,
    context_head: r#"    """An accepted goal: read its request, publish feedback, watch for a cancel,
    then `complete` or `complete_cancelled` it (a goal left unfinished is
    reported abandoned to its caller)."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        self._request = GoalRequest(inner.instance_id, inner.core_node, inner.goal)

    def request(self) -> GoalRequest:
        return self._request"#,
    cancel_signal: r#"    async def cancel_signal(self) -> None:
        """Returns once the caller asks to cancel the goal."""
        await self._inner.cancel_signal.wait()"#,
    handle_doc: "`await ActionHandle.expose(node_runner)`, then
    `await handle.handle_goal_next_request(decide)` for each goal.",
    expose_def: "async def",
    next_goal: r#"    async def handle_goal_next_request(self, decide: Callable[[GoalRequest], Any]) -> Optional[GoalContext]:
        """Waits for the next goal `decide` accepts (`decide` returns a
        `GoalDecision`, or an awaitable of one): rejected goals are answered
        and skipped, and one `decide` raises on is rejected with its text.
        Returns the accepted goal's context, or None once the node stops."""

        def decision(instance_id: str, core_node: str, data: GoalRequestData) -> Any:
            return decide(GoalRequest(instance_id, core_node, data))

        inner = await _peppylib.next_accepted_goal(self._server, decision)"#,
};

/// The peppylib API's goal client: a goal aimed at a bound producer, with the
/// decision's `accepted` and `reason` on the handle.
pub(super) fn goal_client(out: &mut Source, c: &ResolvedCall<ActionDecl>, goal_value: &str) {
    let d = &c.decl;
    out.line(&format!(
        r#"@dataclass
class ResultResponse:
    """How a goal ended, with the server's identity: `status` (a `ResultStatus`),
    and `data` for COMPLETED and CANCELLED (None for ABANDONED and EXPIRED)."""
    core_node: str
    instance_id: str
    status: Any
    data: Optional[ResultResponseData]


@dataclass
class CancelResponse:
    """The answer to a cancel, with the server's identity: `state` (a `CancelState`)."""
    core_node: str
    instance_id: str
    state: Any


class ActionHandle:
    """A goal sent to action `{name}` through slot `{link}`:
    `await ActionHandle.fire_goal(node_runner, target,{goal_doc} timeout, feedback_qos)`;
    check `handle.accepted` (and `handle.reason`)."""

    def __init__(self, client: Any) -> None:
        self._client = client
        self.accepted: bool = client.accepted
        self.reason: Optional[str] = client.error_message
        self.data: Any = client.data
        self.instance_id: str = client.instance_id
        self.core_node: str = client.core_node

    def __repr__(self) -> str:
        return f"ActionHandle(goal_id={{self.goal_id()!r}}, accepted={{self.accepted}}, reason={{self.reason!r}})"

    @classmethod
    async def fire_goal(
        cls,
        node_runner: NodeRunner,
        target: ProducerRef,{goal_arg}
        timeout: float,
        feedback_qos: QoSProfile = QoSProfile.STANDARD,
    ) -> "ActionHandle":
        """Sends the goal to `target`, a producer bound to slot `{link}` (`timeout` in
        seconds), and returns once the server decided. Raises `ValueError` (target
        not bound), `ConnectionError` (no server answered) or `TimeoutError`."""
        return cls(await _peppylib.fire_goal_at(node_runner, SPEC, target, {goal_value}, timeout, feedback_qos))

    def goal_id(self) -> str:
        return self._client.goal_id

    async def on_next_feedback_message(self) -> FeedbackMessage:
        """The next feedback message; `RuntimeError` once the goal has ended
        and its feedback was read."""
        return await self._client.next_feedback()

    async def get_result(self, timeout: float) -> ResultResponse:
        """Waits (up to `timeout` seconds) until the goal is terminal."""
        status, data = await self._client.get_result(timeout)
        return ResultResponse(self.core_node, self.instance_id, status, data)

    async def cancel_goal(self, timeout: float) -> CancelResponse:
        """Asks the server to cancel the goal."""
        state = await self._client.cancel(timeout)
        return CancelResponse(self.core_node, self.instance_id, state)"#,
        name = d.name,
        link = c.slot.link_id,
        goal_arg = if d.goal.is_some() { "\n        request: GoalRequest," } else { "" },
        goal_doc = if d.goal.is_some() { " request," } else { "" },
    ));
}
