//! Who sends to whom in a checked stack, from its binding plan: the one
//! place `graph` and the security policy read the plan's flows from.

use peppy_schema::{
    InstancePlan, NodeDoc, Origin, Producer, ResolvedNode, SlotBinding, SlotKind, SlotPlan,
    StackCheck, conformances,
};

/// The resolved node of an instance.
pub(crate) fn node_of<'a>(stack: &'a StackCheck, id: &str) -> Option<&'a ResolvedNode> {
    stack
        .plan
        .instance(id)
        .map(|i| &stack.deployments[i.deployment].resolved)
}

/// Whether `producer` can fill a slot: the binding engine's rule.
pub(crate) fn fills(kind: SlotKind, target: &peppy_schema::Identity, producer: &NodeDoc) -> bool {
    let conforms = conformances(producer);
    Producer {
        node: &producer.identity(),
        conforms_to: &conforms,
    }
    .fits(kind, target)
}

/// The instances of the stack whose messages `slot` of `consumer` takes:
/// its pinned producer, its bound producers, or, for an unbound `from_any`
/// slot, every other instance that fits it and its filter accepts.
pub(crate) fn slot_producers(
    stack: &StackCheck,
    consumer: &InstancePlan,
    slot: &SlotPlan,
) -> Vec<String> {
    match &slot.binding {
        SlotBinding::Pinned { producer } => vec![producer.clone()],
        SlotBinding::Set { producers, .. } => producers.clone(),
        SlotBinding::FromAnyBound { .. } => match &slot.filter {
            peppy_schema::RouteFilter::OnlyFrom(set) => set.iter().cloned().collect(),
            _ => Vec::new(),
        },
        SlotBinding::FromAnyUnbound => stack
            .plan
            .instances
            .iter()
            .filter(|p| p.instance_id != consumer.instance_id)
            .filter(|p| {
                node_of(stack, &p.instance_id)
                    .is_some_and(|r| fills(slot.kind, &slot.target, &r.node))
            })
            .filter(|p| slot.filter.accepts(&p.instance_id))
            .map(|p| p.instance_id.clone())
            .collect(),
    }
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
