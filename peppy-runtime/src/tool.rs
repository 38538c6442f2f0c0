//! Requests without generated code, for tools such as `peppy-launch
//! service call` and `action send-goal`. A tool reads an instance's
//! [`InstanceInfo`](crate::describe::InstanceInfo), encodes the body from
//! the format's canonical text, and sends it through the same request
//! client nodes use, so a tool's call fails the way a node's call does.
//!
//! A tool is not an instance: it holds no liveliness token and serves
//! nothing, so it never fills a slot. It names itself in the query header
//! (`caller`) so servers can log who asked.

use std::time::Duration;

use tokio::time::Instant;
use tokio_util::sync::CancellationToken;

use crate::actions::client::{GoalOpening, open_goal};
use crate::describe::{ServedAction, ServedService};
use crate::error::Result;
use crate::request::Request;
use crate::wire::attachment::{QueryHeader, QueryKind};
use crate::wire::keys::action_part_key;

pub use crate::actions::GoalClient;
pub use crate::wire::codec::Raw;

/// Who is asking: shown to servers in the query header.
#[derive(Debug, Clone)]
pub struct ToolCaller {
    session: zenoh::Session,
    core: String,
    instance: String,
    stop: CancellationToken,
}

impl ToolCaller {
    /// A caller on `session`, naming itself `core`/`instance`.
    pub fn new(session: zenoh::Session, core: &str, instance: &str) -> ToolCaller {
        ToolCaller {
            session,
            core: core.to_string(),
            instance: instance.to_string(),
            stop: CancellationToken::new(),
        }
    }

    fn header(&self, fingerprint: u64) -> Vec<u8> {
        QueryHeader {
            kind: QueryKind::Request,
            fingerprint,
            core: self.core.clone(),
            instance: self.instance.clone(),
        }
        .encode()
    }

    /// Calls `service` on the instance that described it and returns the
    /// encoded response.
    pub async fn call(
        &self,
        service: &ServedService,
        instance: &str,
        request: Vec<u8>,
        timeout: Duration,
    ) -> Result<Vec<u8>> {
        let describe = format!("{} (service)", service.name);
        let answer = Request {
            session: &self.session,
            stop: &self.stop,
            key: service.key.clone(),
            keys: None,
            header: self.header(service.request.fingerprint),
            payload: request,
            deadline: Instant::now() + timeout,
            describe: &describe,
            instance,
            // A tool's session serves nothing.
            remote: true,
            request_format: &service.request.canonical,
            response: Some((
                service.response.fingerprint,
                service.response.canonical.as_str(),
            )),
        }
        .send()
        .await?;
        Ok(answer.body.to_bytes().into_owned())
    }

    /// Sends a goal to `action` on the instance that described it and waits
    /// for the decision. Read feedback and the result as [`Raw`] bodies.
    pub async fn send_goal(
        &self,
        action: &ServedAction,
        instance: &str,
        goal: Vec<u8>,
        timeout: Duration,
    ) -> Result<GoalClient> {
        let describe = format!("{} (action goal)", action.name);
        open_goal(GoalOpening {
            session: &self.session,
            stop: &self.stop,
            messaging: &self.stop,
            action: &action.name,
            describe: &describe,
            selector: action_part_key(&action.key, crate::wire::keys::ActionPart::Goal),
            keys: None,
            feedback_base: action.key.clone(),
            header: self.header(action.goal.fingerprint),
            server: instance,
            remote: true,
            goal: (action.goal.fingerprint, &action.goal.canonical),
            feedback_fingerprint: action.feedback.fingerprint,
            result: (action.result.fingerprint, &action.result.canonical),
            body: goal,
            deadline: Instant::now() + timeout,
        })
        .await
    }
}

/// A publisher on `key` with the Zenoh settings of `qos`, declared exactly
/// as a node declares its emitted topics.
pub async fn publisher(
    session: &zenoh::Session,
    key: String,
    qos: peppy_schema::QosProfile,
) -> Result<zenoh::pubsub::Publisher<'static>> {
    Ok(session
        .declare_publisher(key)
        .congestion_control(crate::qos::congestion(qos))
        .priority(crate::qos::priority(qos))
        .express(crate::qos::express(qos))
        .await?)
}
