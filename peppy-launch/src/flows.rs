//! Who sends to whom in a checked stack, beside what peppy-schema answers
//! (`StackCheck::slot_producers`): the emitters an external consumed topic
//! takes, for `graph` and the security policy.

use peppy_schema::{InstancePlan, Origin, StackCheck};

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
        if let Some(r) = stack.node_of(&p.instance_id) {
            for e in r.emitted_topics.iter().filter(|e| e.decl.name == topic) {
                out.push((p.instance_id.clone(), e.origin.clone()));
            }
        }
    }
    out
}
