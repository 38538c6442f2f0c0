//! Today's Python node API, for `node/v1` documents: built messages and
//! held publishers, held subscriptions yielding `(ProducerRef, Message)`,
//! calls and goals aimed at a bound producer, `GoalDecision`, and the
//! slot's `bound_producer(s)` in every consumed module, on the `peppy`
//! runtime's `peppy.today`. Message types and `SPEC`s are the seeds'.

use peppy_schema::names::type_prefix;
use peppy_schema::{ActionDecl, Cardinality, Provided, QosProfile, ResolvedCall, ResolvedTopic};
use peppy_schema::{ResolvedNode, ServiceDecl, TopicDecl};

use super::messages::{fields_of, message};
use super::modules::{action_types, owner, params, qos, with_identity};
use super::source::{Source, py_string};

/// The imports today's modules add to the common header.
pub(super) const IMPORTS: &str =
    "from peppy import today as _today\nfrom peppy.producer import ProducerRef";

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

fn slot_accessor(out: &mut Source, node: &ResolvedNode, link_id: &str) {
    let cardinality = node.node.dependency(link_id).map(|d| d.cardinality);
    if cardinality.is_some() {
        accessor(out, link_id, cardinality);
        out.blank();
        out.blank();
    }
}

pub(super) fn emitted_topic(out: &mut Source, p: &Provided<TopicDecl>) {
    let d = &p.decl;
    let format = message(
        out,
        "Message",
        "Message",
        d.format.as_ref(),
        &format!("A message of topic `{}`.", d.name),
    );
    out.line(&format!(
        "SPEC = _s.TopicSpec({}, {}, {}, {format})",
        owner(Some(&p.origin), true),
        py_string(&d.name),
        qos(d.qos)
    ));
    out.line("\"\"\"What the runtime knows about this topic.\"\"\"");
    out.line(&format!("TOPIC_NAME = {}", py_string(&d.name)));
    out.line(&format!("QOS = {}", qos(d.qos)));
    out.blank();
    out.blank();
    let (ps, inits) = params(&[], "Message", fields_of(d.format.as_ref()));
    out.line(&format!("def build_message({ps}) -> bytes:"));
    out.indent();
    out.docstring(&format!(
        "One message of `{}`, the fields in declaration order, encoded for `publisher.publish`.",
        d.name
    ));
    out.line(&format!(
        "return _today.build_message(SPEC, Message({inits}))"
    ));
    out.dedent();
    out.blank();
    out.blank();
    out.line("async def declare_publisher(node_runner: NodeRunner) -> _today.Publisher:");
    out.indent();
    out.docstring(&format!(
        "The publisher of `{}`: `await publisher.publish(build_message(...))`.",
        d.name
    ));
    out.line("return await _today.declare_publisher(node_runner, SPEC)");
    out.dedent();
}

pub(super) fn consumed_topic(out: &mut Source, node: &ResolvedNode, t: &ResolvedTopic) {
    let format = message(
        out,
        "Message",
        "Message",
        t.format.as_ref(),
        &format!("A message of topic `{}`.", t.name),
    );
    let link = t
        .slot
        .as_ref()
        .map_or("None".to_string(), |s| py_string(&s.link_id));
    out.line(&format!(
        "SPEC = _s.ConsumedTopicSpec({link}, {}, {}, {}, {format})",
        owner(t.origin.as_ref(), false),
        py_string(&t.name),
        qos(t.qos)
    ));
    out.line("\"\"\"What the runtime knows about this topic.\"\"\"");
    out.line(&format!("TOPIC_NAME = {}", py_string(&t.name)));
    out.blank();
    out.blank();
    if let Some(slot) = &t.slot {
        slot_accessor(out, node, &slot.link_id);
    }
    out.line(&format!(
        r#"class Subscription(_today.Subscription):
    """Topic `{name}`, held: messages are queued from the node's start, so
    none is lost between calls. `await sub.next()` gives `(producer, message)`,
    None once the node stops; `async for producer, message in sub` reads until then."""

    async def next(self) -> Optional[Tuple[ProducerRef, Message]]:
        return await super().next()


async def subscribe(node_runner: NodeRunner) -> Subscription:
    """Holds topic `{name}` (subscribed when the node started)."""
    return Subscription(node_runner, SPEC)"#,
        name = t.name
    ));
}

pub(super) fn consumed_service(
    out: &mut Source,
    node: &ResolvedNode,
    c: &ResolvedCall<ServiceDecl>,
) {
    let d = &c.decl;
    let prefix = type_prefix(&d.name);
    let request = message(
        out,
        "Request",
        &prefix,
        d.request.as_ref(),
        &format!("A request of service `{}`.", d.name),
    );
    let response = message(
        out,
        "ResponseData",
        "ResponseData",
        d.response.as_ref(),
        &format!("The response data of service `{}`.", d.name),
    );
    with_identity(
        out,
        "Response",
        "A response, with the server's identity.",
        "ResponseData",
    );
    out.line(&format!(
        "SPEC = _s.ConsumedServiceSpec({}, {}, {}, {request}, {response})",
        py_string(&c.slot.link_id),
        owner(Some(&c.origin), false),
        py_string(&d.name)
    ));
    out.line(&format!("SERVICE_NAME = {}", py_string(&d.name)));
    out.line(&format!("LINK_ID = {}", py_string(&c.slot.link_id)));
    out.blank();
    out.blank();
    slot_accessor(out, node, &c.slot.link_id);
    let (arg, value) = if d.request.is_some() {
        (", request: Request", "request")
    } else {
        ("", "Request()")
    };
    out.line(&format!(
        "async def poll(node_runner: NodeRunner, target: ProducerRef{arg}, timeout: float) -> Response:"
    ));
    out.indent();
    out.docstring(&format!(
        "Calls `{}` on `target`, a producer bound to slot `{}`; `timeout` in seconds.\n\
         Raises `ValueError` (target not bound), `ConnectionError` (no server answered),\n\
         `TimeoutError` (acked, no answer in time) or `RuntimeError` (the handler's error).",
        d.name, c.slot.link_id
    ));
    out.line(&format!(
        "instance_id, core_node, data = await _today.poll(node_runner, SPEC, target, {value}, timeout)"
    ));
    out.line("return Response(instance_id, core_node, data)");
    out.dedent();
}

pub(super) fn exposed_action(out: &mut Source, p: &Provided<ActionDecl>) {
    let d = &p.decl;
    let t = action_types(&d.name);
    let goal = message(
        out,
        "GoalRequestData",
        "Goal",
        d.goal.as_ref(),
        &format!("The goal data of action `{}`.", d.name),
    );
    let feedback = message(
        out,
        &t.feedback,
        &t.feedback,
        d.feedback.as_ref().map(|f| &f.format),
        &format!("A feedback message of action `{}`.", d.name),
    );
    let result = message(
        out,
        &t.result,
        &t.result,
        d.result.as_ref(),
        &format!("The result of action `{}`.", d.name),
    );
    let fb_qos = d.feedback.as_ref().map_or(QosProfile::Standard, |f| f.qos);
    out.line(&format!(
        "SPEC = _s.ActionSpec({}, {}, {goal}, {feedback}, {result})",
        owner(Some(&p.origin), true),
        py_string(&d.name)
    ));
    out.line(&format!("ACTION_NAME = {}", py_string(&d.name)));
    out.line(&format!("FEEDBACK_QOS = {}", qos(fb_qos)));
    out.blank();
    out.blank();
    let (fb_params, fb_inits) = params(
        &["self"],
        &t.feedback,
        fields_of(d.feedback.as_ref().map(|f| &f.format)),
    );
    let (res_params, res_inits) = params(&["self"], &t.result, fields_of(d.result.as_ref()));
    out.line(&format!(
        r#"@dataclass
class GoalRequest:
    """A goal, with the caller's identity."""
    instance_id: str
    core_node: str
    data: GoalRequestData


class GoalDecision:
    """What the decider returns: `GoalDecision.accept()` or `GoalDecision.reject(reason)`."""

    def __init__(self, accepted: bool, reason: Optional[str] = None, response: Any = None) -> None:
        self.accepted = accepted
        self.reason = reason
        self.response = response

    def __repr__(self) -> str:
        return f"GoalDecision(accepted={{self.accepted}}, reason={{self.reason!r}})"

    @classmethod
    def accept(cls, response: Any = None) -> "GoalDecision":
        return cls(True, None, response)

    @classmethod
    def reject(cls, reason: Optional[str] = None, response: Any = None) -> "GoalDecision":
        return cls(False, reason, response)


class GoalContext:
    """An accepted goal: read its request, publish feedback, watch for a cancel,
    then `complete` or `complete_cancelled` it (a goal left unfinished is
    reported abandoned to its caller)."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        self._request = GoalRequest(inner.instance_id, inner.core_node, inner.goal)

    def request(self) -> GoalRequest:
        return self._request

    def goal_id(self) -> str:
        return self._inner.goal_id

    async def cancel_signal(self) -> None:
        """Returns once the caller asks to cancel the goal."""
        await self._inner.cancel_signal.wait()

    def is_cancelled(self) -> bool:
        return self._inner.is_cancelled()

    async def publish_feedback({fb_params}) -> None:
        await self._inner.publish_feedback({feedback_type}({fb_inits}))

    async def complete({res_params}) -> None:
        await self._inner.complete({result_type}({res_inits}))

    async def complete_cancelled({res_params}) -> None:
        await self._inner.complete_cancelled({result_type}({res_inits}))


class ActionHandle:
    """Serves action `{name}`: `await ActionHandle.expose(node_runner)`, then
    `await handle.handle_goal_next_request(decide)` for each goal."""

    def __init__(self, server: Any) -> None:
        self._server = server

    @classmethod
    async def expose(cls, node_runner: NodeRunner) -> "ActionHandle":
        return cls(_actions.GoalServer(node_runner, SPEC))

    async def handle_goal_next_request(self, decide: Callable[[GoalRequest], Any]) -> Optional[GoalContext]:
        """Waits for the next goal `decide` accepts (`decide` returns a
        `GoalDecision`, or an awaitable of one): rejected goals are answered
        and skipped, and one `decide` raises on is rejected with its text.
        Returns the accepted goal's context, or None once the node stops."""

        def decision(instance_id: str, core_node: str, data: GoalRequestData) -> Any:
            return decide(GoalRequest(instance_id, core_node, data))

        inner = await _today.next_accepted_goal(self._server, decision)
        return None if inner is None else GoalContext(inner)"#,
        feedback_type = t.feedback,
        result_type = t.result,
        name = d.name,
    ));
}

pub(super) fn consumed_action(out: &mut Source, node: &ResolvedNode, c: &ResolvedCall<ActionDecl>) {
    let d = &c.decl;
    let t = action_types(&d.name);
    let goal = message(
        out,
        "GoalRequest",
        "Goal",
        d.goal.as_ref(),
        &format!("A goal of action `{}`.", d.name),
    );
    let feedback = message(
        out,
        "FeedbackMessage",
        &t.feedback,
        d.feedback.as_ref().map(|f| &f.format),
        &format!("A feedback message of action `{}`.", d.name),
    );
    let result = message(
        out,
        "ResultResponseData",
        &t.result,
        d.result.as_ref(),
        &format!("The result of action `{}`.", d.name),
    );
    out.line(&format!(
        "SPEC = _s.ConsumedActionSpec({}, {}, {}, {goal}, {feedback}, {result})",
        py_string(&c.slot.link_id),
        owner(Some(&c.origin), false),
        py_string(&d.name)
    ));
    out.line(&format!("TARGET_ACTION_NAME = {}", py_string(&d.name)));
    out.line(&format!("LINK_ID = {}", py_string(&c.slot.link_id)));
    out.line("ResultStatus = _actions.ResultStatus");
    out.line("CancelState = _actions.CancelState");
    out.blank();
    out.blank();
    slot_accessor(out, node, &c.slot.link_id);
    let (goal_arg, goal_value) = if d.goal.is_some() {
        ("\n        request: GoalRequest,", "request")
    } else {
        ("", "GoalRequest()")
    };
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
        self.data: Any = None
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
        return cls(await _today.fire_goal_at(node_runner, SPEC, target, {goal_value}, timeout, feedback_qos))

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
        goal_doc = if d.goal.is_some() { " request," } else { "" },
    ));
}
