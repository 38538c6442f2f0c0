//! Actions: a goal service (accept or reject with a reason), a per-goal
//! feedback stream, a cancel service and a result service that parks the
//! caller until the goal is terminal. Several goals run concurrently on one
//! server; results are kept for a retention period, then reported
//! `Expired`; a worker that drops its goal without finishing it reports
//! `Abandoned`.
//!
//! Keys (see [`crate::wire::keys`]): the action's entry key followed by
//! `/goal`, `/cancel`, `/result`, and `/feedback/<goal_id>`.

//! `server` holds the exposed side (the goal registry, intake, contexts),
//! `client` the consumed side (`send_goal` and the goal a caller holds).

use std::time::Duration;

pub(crate) mod client;
mod server;

pub use client::{GoalClient, send_goal, send_goal_to};
pub use server::{GoalContext, GoalServer, IncomingGoal, next_goal};
pub(crate) use server::{PendingGoal, Registry, goal_intake, server_base_key};

/// How long a terminal goal's result stays available.
pub const DEFAULT_RESULT_RETENTION: Duration = Duration::from_secs(30);

/// How a goal ended, as its caller sees it.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome<R> {
    /// Finished with a result.
    Completed(R),
    /// Cancelled, with a (partial) result.
    Cancelled(R),
    /// The server dropped the goal without a result.
    Abandoned,
    /// The result was not fetched within the retention period.
    Expired,
}

/// The answer to a cancel request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CancelState {
    /// The goal was running; its worker was signalled.
    Signalled = 0,
    /// The goal had already ended.
    AlreadyTerminal = 1,
    /// The server does not know the goal.
    Unknown = 2,
}
