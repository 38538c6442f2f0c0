//! Who sends to whom in a checked stack, from its binding plan: the one
//! place `graph` and the security policy read the plan's flows from.

use peppy_schema::{InstancePlan, Origin, ResolvedNode, SlotPlan, StackCheck};

/// The resolved node of an instance.
pub(crate) fn node_of<'a>(stack: &'a StackCheck, id: &str) -> Option<&'a ResolvedNode> {
    stack.node_of(id)
}

/// The instances of the stack whose messages `slot` of `consumer` takes
/// ([`StackCheck::slot_producers`]).
pub(crate) fn slot_producers(
    stack: &StackCheck,
    consumer: &InstancePlan,
    slot: &SlotPlan,
) -> Vec<String> {
    stack.slot_producers(consumer, slot)
}

/// Every other instance emitting a topic named `topic` (an external
/// consumed topic takes any owner's), with the owner it emits under.
pub(crate) fn external_emitters(
    stack: &StackCheck,
    consumer: &InstancePlan,
    topic: &str,
) -> Vec<(String, Origin)> {
    let mut out = Vec::new();
    for p in &stack.plan.instances {
        if p.instance_id == consumer.instance_id {
            continue;
        }
        if let Some(r) = node_of(stack, &p.instance_id) {
            for e in r.emitted_topics.iter().filter(|e| e.decl.name == topic) {
                out.push((p.instance_id.clone(), e.origin.clone()));
            }
        }
    }
    out
}
