//! The bound-producer accessors generated code offers per slot of a
//! `node/v1` node (`consumed_topics::<link_id>::bound_producer` and
//! friends).

use crate::node::NodeRunner;
use crate::producer_ref::{NonEmptyProducers, ProducerRef};

/// The first producer bound to slot `link_id`: the one producer of a
/// `one` slot (start-up refuses a plan that binds it to anything else), or
/// of a `zero_or_one` slot (`None` when vacant).
pub fn bound_producer<'a>(runner: &'a NodeRunner, link_id: &str) -> Option<&'a ProducerRef> {
    runner.bound_producer_refs(link_id).first()
}

/// The producers bound to slot `link_id`, in link order.
pub fn bound_producers<'a>(runner: &'a NodeRunner, link_id: &str) -> &'a [ProducerRef] {
    runner.bound_producer_refs(link_id)
}

/// Whether `target` is one of the producers bound to `link_id`: the
/// peppylib API's calls go to an explicit target, checked before anything
/// is sent.
pub(crate) fn check_target(
    runner: &NodeRunner,
    link_id: &str,
    target: &ProducerRef,
) -> crate::Result<()> {
    let bound = runner.bound_producer_refs(link_id);
    if !target.instance_id.is_empty() && bound.iter().any(|p| p.instance_id == target.instance_id) {
        return Ok(());
    }
    Err(crate::Error::TargetNotBound {
        slot: link_id.to_string(),
        target: if target.instance_id.is_empty() {
            "(no producer)".to_string()
        } else {
            target.instance_id.clone()
        },
        bound: bound.iter().map(|p| p.instance_id.clone()).collect(),
    })
}

/// The one producer of a `one` slot, for the peppylib API. Start-up
/// refuses a plan that binds the slot to anything else; were it bypassed,
/// the accessor hands out a producer no call reaches (`Error::TargetNotBound`)
/// rather than panicking.
pub fn sole_bound_producer<'a>(runner: &'a NodeRunner, link_id: &str) -> &'a ProducerRef {
    runner
        .bound_producer_refs(link_id)
        .first()
        .unwrap_or(&UNBOUND)
}

static UNBOUND: ProducerRef = ProducerRef::UNBOUND;

/// The producer of a `zero_or_one` slot, `None` when it is vacant.
pub fn optional_bound_producer<'a>(
    runner: &'a NodeRunner,
    link_id: &str,
) -> Option<&'a ProducerRef> {
    runner.bound_producer_refs(link_id).first()
}

/// The producers of a `one_or_more` slot, never empty. Start-up refuses
/// an empty set; were it bypassed, the set holds the unreachable producer
/// of [`sole_bound_producer`].
pub fn non_empty_bound_producers<'a>(
    runner: &'a NodeRunner,
    link_id: &str,
) -> NonEmptyProducers<'a> {
    NonEmptyProducers::new(runner.bound_producer_refs(link_id))
        .or_else(|| NonEmptyProducers::new(std::slice::from_ref(&UNBOUND)))
        .expect("a one-element slice is not empty")
}
