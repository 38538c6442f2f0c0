//! The bound-producer accessors generated code offers per slot of a
//! `node/v1` node (`consumed_topics::<link_id>::bound_producer` and
//! friends).

use crate::node::NodeRunner;

/// The first producer bound to slot `link_id`: the one producer of a
/// `one` slot (start-up refuses a plan that binds it to anything else), or
/// of a `zero_or_one` slot (`None` when vacant).
pub fn bound_producer<'a>(runner: &'a NodeRunner, link_id: &str) -> Option<&'a str> {
    runner.bound_producers(link_id).first().map(String::as_str)
}

/// The producers bound to slot `link_id`, in link order.
pub fn bound_producers<'a>(runner: &'a NodeRunner, link_id: &str) -> &'a [String] {
    runner.bound_producers(link_id)
}
