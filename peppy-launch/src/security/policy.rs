//! The access policy of a stack, derived from its binding plan: for every
//! instance, the keys it may publish and serve (its own), and the keys it
//! may receive and call (what its slots are bound to, and the emitters of
//! its external topics). The router enforces it as Zenoh access control
//! ([`Policy::access_control`]); `check --security` prints it.

use std::collections::BTreeSet;

use peppy_runtime::wire::keys::{
    ActionPart, Channel, Claim, ClockSource, EntrySelector, Owner, Space, action_part_key,
    action_parts_selector, clock_sync_key, clock_tick_key, clock_tick_selector,
    core_functions_selector, describe_key, describe_selector, entry_key, entry_selector,
    feedback_selector, format_selector, liveliness_key, namespace_prefix, namespace_selector,
    pairing_topic_key, pairing_topic_selector, space_selector,
};
use peppy_schema::{InstancePlan, Origin, StackCheck};
use serde::Serialize;
use serde_json::{Value as Json, json};

use crate::flows;

/// What every instance of a stack may do on the wire.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Policy {
    /// The namespace every key is under.
    pub(crate) namespace: String,
    /// One entry per instance, in launcher order.
    pub(crate) instances: Vec<InstancePolicy>,
}

/// One instance's grants.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct InstancePolicy {
    /// The instance, which is also its Zenoh user name.
    pub(crate) instance_id: String,
    /// The core node it runs on (`*` when only the launch names it).
    pub(crate) core_node: String,
    /// The node it runs, `name:tag`.
    pub(crate) node: String,
    /// The liveliness token it may hold naming its own node.
    #[serde(skip)]
    pub(crate) token: String,
    /// The claim tokens its pairing slots may hold: their own, on any peer
    /// (a pair holds only while both ends claim each other).
    #[serde(skip)]
    pub(crate) claims: Vec<String>,
    /// Topics (and action feedback) it publishes: its own keys.
    pub(crate) emits: Vec<Grant>,
    /// Services and actions it answers: its own keys.
    pub(crate) serves: Vec<Grant>,
    /// Topics it receives, per slot or external topic, from whom.
    pub(crate) receives: Vec<Grant>,
    /// Services and actions it calls, per slot, on whom.
    pub(crate) calls: Vec<Grant>,
}

/// One line of a policy: an entry, who is on the other side, and the exact
/// keys that carries.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Grant {
    /// `topic video_stream`, `service video_stream_info`, `action move_arm`.
    pub(crate) entry: String,
    /// The slot it goes through (`None`: the instance's own entry, or an
    /// external topic).
    pub(crate) slot: Option<String>,
    /// The instances on the other side (empty for own entries).
    pub(crate) peers: Vec<String>,
    /// The keys (and key expressions) allowed.
    pub(crate) keys: Vec<String>,
    /// The key expressions the instance may subscribe to or send requests
    /// on (wider than `keys`: any core, or every server for a probe); what
    /// comes back is still limited to `keys`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub(crate) selectors: Vec<String>,
}

/// Derives the policy of `stack` in `namespace`. `core_of(instance)` is the
/// core node an instance runs on, `None` when only the launch will name it.
pub(crate) fn derive(
    stack: &StackCheck,
    namespace: &str,
    core_of: &dyn Fn(&InstancePlan) -> Option<String>,
) -> Policy {
    let core = |inst: &InstancePlan| core_of(inst).unwrap_or_else(|| "*".into());
    let core_by_id = |id: &str| {
        stack
            .plan
            .instance(id)
            .map_or_else(|| "*".to_string(), core)
    };
    let instances = stack
        .plan
        .instances
        .iter()
        .map(|inst| {
            let resolved = &stack.deployments[inst.deployment].resolved;
            let me = inst.instance_id.as_str();
            let my_core = core(inst);
            // This instance's own key for one of its entries.
            let mine = |channel, origin: &Origin, name: &str| {
                entry_key(namespace, channel, &owner(origin), name, &my_core, me)
            };
            let mut emits: Vec<Grant> = resolved
                .emitted_topics
                .iter()
                .map(|t| {
                    own(
                        format!("topic {}", t.decl.name),
                        vec![mine(Channel::Topic, &t.origin, &t.decl.name)],
                    )
                })
                .collect();
            let mut serves: Vec<Grant> = resolved
                .exposed_services
                .iter()
                .map(|s| {
                    own(
                        format!("service {}", s.decl.name),
                        vec![mine(Channel::Service, &s.origin, &s.decl.name)],
                    )
                })
                .collect();
            for a in &resolved.exposed_actions {
                let base = mine(Channel::Action, &a.origin, &a.decl.name);
                serves.push(own(
                    format!("action {}", a.decl.name),
                    vec![action_parts_selector(&base)],
                ));
                // Every goal ends its feedback stream, feedback declared or
                // not.
                emits.push(own(
                    format!("action {} feedback", a.decl.name),
                    vec![feedback_selector(&base)],
                ));
            }

            let mut receives = Vec::new();
            for t in &resolved.consumed_topics {
                match (&t.slot, &t.origin) {
                    (Some(slot), Some(origin)) => {
                        let peers = inst
                            .slots
                            .iter()
                            .find(|s| s.link_id == slot.link_id)
                            .map(|s| stack.slot_producers(inst, s))
                            .unwrap_or_default();
                        let o = owner(origin);
                        receives.push(Grant {
                            entry: format!("topic {}", t.name),
                            slot: Some(slot.link_id.clone()),
                            keys: peers
                                .iter()
                                .map(|p| {
                                    entry_key(
                                        namespace,
                                        Channel::Topic,
                                        &o,
                                        &t.name,
                                        &core_by_id(p),
                                        p,
                                    )
                                })
                                .collect(),
                            selectors: vec![entry_selector(
                                namespace,
                                Channel::Topic,
                                Some(&o),
                                &t.name,
                                None,
                                None,
                            )],
                            peers,
                        });
                    }
                    _ => {
                        let emitters = flows::external_emitters(stack, inst, &t.name);
                        receives.push(Grant {
                            entry: format!("topic {}", t.name),
                            slot: None,
                            keys: emitters
                                .iter()
                                .map(|(p, origin)| {
                                    entry_key(
                                        namespace,
                                        Channel::Topic,
                                        &owner(origin),
                                        &t.name,
                                        &core_by_id(p),
                                        p,
                                    )
                                })
                                .collect(),
                            selectors: vec![entry_selector(
                                namespace,
                                Channel::Topic,
                                None,
                                &t.name,
                                None,
                                None,
                            )],
                            peers: emitters.into_iter().map(|(p, _)| p).collect(),
                        });
                    }
                }
            }

            let claims = pair_grants(
                namespace,
                inst,
                resolved,
                &my_core,
                &core_by_id,
                &mut emits,
                &mut receives,
            );

            let mut calls = Vec::new();
            let services = resolved
                .consumed_services
                .iter()
                .map(|c| (Channel::Service, &c.slot, &c.origin, &c.decl.name));
            let actions = resolved
                .consumed_actions
                .iter()
                .map(|c| (Channel::Action, &c.slot, &c.origin, &c.decl.name));
            for (channel, slot, origin, name) in services.chain(actions) {
                let plan = inst.slots.iter().find(|s| s.link_id == slot.link_id);
                let peers = plan
                    .map(|s| stack.slot_producers(inst, s))
                    .unwrap_or_default();
                // Requests name their server by instance only (any core);
                // a slot that does not name one server probes them all.
                let probes = plan.is_some_and(|s| s.named_server().is_none());
                let o = owner(origin);
                let at = |p: &str| entry_key(namespace, channel, &o, name, &core_by_id(p), p);
                let to =
                    |p: &str| entry_selector(namespace, channel, Some(&o), name, None, Some(p));
                let any = entry_selector(namespace, channel, Some(&o), name, None, None);
                let (kind, keys, mut selectors) = match channel {
                    // Every goal ends its feedback stream, so feedback keys
                    // are granted whether or not the action declares any.
                    Channel::Action => (
                        "action",
                        peers
                            .iter()
                            .flat_map(|p| {
                                [action_parts_selector(&at(p)), feedback_selector(&at(p))]
                            })
                            .collect::<Vec<_>>(),
                        peers
                            .iter()
                            .flat_map(|p| {
                                [action_parts_selector(&to(p)), feedback_selector(&to(p))]
                            })
                            .collect::<Vec<_>>(),
                    ),
                    _ => (
                        "service",
                        peers.iter().map(|p| at(p)).collect(),
                        peers.iter().map(|p| to(p)).collect(),
                    ),
                };
                if probes {
                    selectors.push(match channel {
                        Channel::Action => action_part_key(&any, ActionPart::Goal),
                        _ => any,
                    });
                }
                calls.push(Grant {
                    entry: format!("{kind} {name}"),
                    slot: Some(slot.link_id.clone()),
                    peers,
                    keys,
                    selectors,
                });
            }
            InstancePolicy {
                instance_id: me.to_string(),
                token: liveliness_key(namespace, &my_core, me, &inst.node.name, &inst.node.tag),
                claims,
                core_node: my_core,
                node: inst.node.to_string(),
                emits,
                serves,
                receives,
                calls,
            }
        })
        .collect();
    Policy {
        namespace: namespace.to_string(),
        instances,
    }
}

/// What an instance's pairing slots may do: publish the topics its role
/// emits on its own keys, receive the topics it consumes from its planned
/// peer (a participant) or sources (an observer) only, and hold its own
/// claims. Returns the claim keys.
fn pair_grants(
    ns: &str,
    inst: &InstancePlan,
    resolved: &peppy_schema::ResolvedNode,
    my_core: &str,
    core_by_id: &dyn Fn(&str) -> String,
    emits: &mut Vec<Grant>,
    receives: &mut Vec<Grant>,
) -> Vec<String> {
    let me = inst.instance_id.as_str();
    let mut claims = Vec::new();
    for p in &resolved.pairings {
        let (name, tag, link) = (&p.slot.pairing.name, &p.slot.pairing.tag, &p.slot.link_id);
        for t in &p.emitted {
            let topic = &t.topic.decl.name;
            emits.push(Grant {
                entry: format!("topic {topic}"),
                slot: Some(link.clone()),
                peers: Vec::new(),
                keys: vec![pairing_topic_key(ns, name, tag, topic, my_core, me, link)],
                selectors: Vec::new(),
            });
        }
        let ends = inst
            .pairs
            .iter()
            .find(|plan| &plan.link_id == link)
            .map_or(&[][..], |plan| plan.peers.as_slice());
        for t in &p.consumed {
            let topic = &t.topic.decl.name;
            receives.push(Grant {
                entry: format!("topic {topic}"),
                slot: Some(link.clone()),
                peers: ends.iter().map(|e| e.instance.clone()).collect(),
                keys: ends
                    .iter()
                    .map(|e| {
                        pairing_topic_key(
                            ns,
                            name,
                            tag,
                            topic,
                            &core_by_id(&e.instance),
                            &e.instance,
                            e.link_id.as_deref().unwrap_or("*"),
                        )
                    })
                    .collect(),
                selectors: ends
                    .iter()
                    .map(|e| {
                        pairing_topic_selector(
                            ns,
                            name,
                            tag,
                            topic,
                            None,
                            Some(&e.instance),
                            e.link_id.as_deref(),
                        )
                    })
                    .collect(),
            });
        }
        if !p.slot.observer {
            claims.push(
                Claim {
                    pairing: name,
                    tag,
                    role: &p.slot.role,
                    core: my_core,
                    instance: me,
                    link_id: link,
                    peer: Some(("*", "*")),
                }
                .key(ns),
            );
        }
    }
    claims
}

fn own(entry: String, keys: Vec<String>) -> Grant {
    Grant {
        entry,
        slot: None,
        peers: Vec::new(),
        keys,
        selectors: Vec::new(),
    }
}

fn owner(origin: &Origin) -> Owner<'_> {
    match origin {
        Origin::Node(id) => Owner::Node {
            name: &id.name,
            tag: &id.tag,
        },
        Origin::Interface(id) => Owner::Interface {
            name: &id.name,
            tag: &id.tag,
        },
    }
}

/// The Zenoh user name of the operator: the launching user's own tools
/// (`topic echo`, `service call`, ...), which may do anything in the
/// stack's namespace.
pub(crate) const OPERATOR: &str = "peppy-operator";

/// The Zenoh user name of `record` and `view`: they may read every topic
/// and ask every instance for its description and formats, and nothing
/// else (no publication, no service call).
pub(crate) const RECORDER: &str = "peppy-recorder";

impl Policy {
    /// Zenoh's `access_control` configuration enforcing this policy on a
    /// router: deny by default; each instance (by user name) gets its
    /// grants; the operator everything in the namespace; the core nodes'
    /// routers (`core_nodes`: the common names of their certificates,
    /// which only the stack's authority signs) everything, since each
    /// router enforces its own instances.
    pub(crate) fn access_control(&self, core_nodes: &[String]) -> Json {
        let ns = &self.namespace;
        let mut rules = vec![
            // What every instance needs whatever its bindings: to see who
            // is alive (node slots on an interface's key, probes), to ask a
            // producer for the text of a format that differs from its own,
            // and to learn where subscribers and queryables are (declarations
            // carry no data).
            rule(
                "any.live",
                "ingress",
                &["declare_liveliness_subscriber", "liveliness_query"],
                &[space_selector(ns, Space::Live)],
            ),
            // Pairs: every instance may follow the claims of the stack's
            // pairing slots (claims carry no data; what a pair sends is
            // granted per instance below).
            rule(
                "any.pairs",
                "ingress",
                &["declare_liveliness_subscriber", "liveliness_query"],
                &[space_selector(ns, Space::Pair)],
            ),
            rule(
                "any.live.in",
                "egress",
                &["liveliness_token"],
                &[namespace_selector(ns)],
            ),
            rule(
                "any.format",
                "ingress",
                &["query"],
                &[format_selector(ns, None)],
            ),
            rule(
                "any.format.in",
                "egress",
                &["reply"],
                &[format_selector(ns, None)],
            ),
            // The stack clock: every instance follows the ticks and asks
            // the launch's clock; any instance may be the simulator and
            // publish sim ticks. Wall ticks and sync answers come from the
            // launch itself (its router), which no instance may stand in
            // for: no instance publishes wall ticks or answers sync.
            rule(
                "any.clock",
                "ingress",
                &["declare_subscriber"],
                &[clock_tick_selector(ns)],
            ),
            rule(
                "any.clock.ask",
                "ingress",
                &["query"],
                &[clock_sync_key(ns)],
            ),
            rule(
                "any.clock.sim",
                "ingress",
                &["put"],
                &[clock_tick_key(ns, ClockSource::Sim)],
            ),
            rule(
                "any.clock.in",
                "egress",
                &["put"],
                &[clock_tick_selector(ns)],
            ),
            rule(
                "any.clock.answers",
                "egress",
                &["reply"],
                &[clock_sync_key(ns)],
            ),
            // The core node functions (datastore, info, stack list): every
            // instance asks its launch, which alone answers.
            rule(
                "any.stack.ask",
                "ingress",
                &["query"],
                &[core_functions_selector(ns)],
            ),
            rule(
                "any.stack.answers",
                "egress",
                &["reply"],
                &[core_functions_selector(ns)],
            ),
            rule(
                "any.declarations",
                "egress",
                &["declare_subscriber", "declare_queryable"],
                &[namespace_selector(ns)],
            ),
            rule(
                "everything",
                "both",
                &ALL_MESSAGES,
                &[namespace_selector(ns)],
            ),
            rule("links", "both", &ALL_MESSAGES, &["**".to_string()]),
            // The recorder reads: it subscribes to topics and receives
            // their messages, and asks for descriptions and formats.
            rule(
                "recorder.subscribe",
                "ingress",
                &["declare_subscriber"],
                &[space_selector(ns, Space::Topic)],
            ),
            rule(
                "recorder.messages",
                "egress",
                &["put", "declare_subscriber", "declare_queryable"],
                &[space_selector(ns, Space::Topic)],
            ),
            rule(
                "recorder.ask",
                "ingress",
                &["query"],
                &[describe_selector(ns), format_selector(ns, None)],
            ),
            rule(
                "recorder.answers",
                "egress",
                &["reply", "declare_queryable"],
                &[describe_selector(ns), format_selector(ns, None)],
            ),
        ];
        let mut subjects = vec![
            json!({ "id": "operator", "usernames": [OPERATOR] }),
            json!({ "id": "recorder", "usernames": [RECORDER] }),
        ];
        let mut policies = vec![
            json!({ "id": "operator", "rules": ["everything"], "subjects": ["operator"] }),
            json!({
                "id": "recorder",
                "rules": ["recorder.subscribe", "recorder.messages", "recorder.ask", "recorder.answers"],
                "subjects": ["recorder"],
            }),
        ];
        if !core_nodes.is_empty() {
            subjects.push(json!({ "id": "routers", "cert_common_names": core_nodes }));
            policies.push(json!({ "id": "routers", "rules": ["links"], "subjects": ["routers"] }));
        }
        for inst in &self.instances {
            let id = &inst.instance_id;
            let mut mine = vec![
                "any.live".to_string(),
                "any.pairs".to_string(),
                "any.live.in".to_string(),
                "any.format".to_string(),
                "any.format.in".to_string(),
                "any.clock".to_string(),
                "any.clock.ask".to_string(),
                "any.clock.sim".to_string(),
                "any.clock.in".to_string(),
                "any.clock.answers".to_string(),
                "any.stack.ask".to_string(),
                "any.stack.answers".to_string(),
                "any.declarations".to_string(),
            ];
            let mut add = |suffix: &str, flow: &str, messages: &[&str], keys: Vec<String>| {
                if keys.is_empty() {
                    return;
                }
                let rule_id = format!("instance:{id}.{suffix}");
                rules.push(rule(&rule_id, flow, messages, &keys));
                mine.push(rule_id);
            };
            let core = &inst.core_node;
            add(
                "self",
                "ingress",
                &["liveliness_token"],
                vec![inst.token.clone()],
            );
            add(
                "claims",
                "ingress",
                &["liveliness_token"],
                inst.claims.clone(),
            );
            add(
                "self.answers",
                "ingress",
                &["declare_queryable", "reply"],
                vec![format_selector(ns, Some(id)), describe_key(ns, core, id)],
            );
            add(
                "self.asked",
                "egress",
                &["query"],
                vec![
                    format_selector(ns, Some(id)),
                    space_selector(ns, Space::Describe),
                ],
            );
            // A producer also declares a queryable on each emitted key (it
            // answers nothing): Zenoh then sends its messages under a
            // numeric id (WIRE.md §1).
            add(
                "emits",
                "ingress",
                &["put", "delete", "declare_queryable"],
                keys_of(&inst.emits),
            );
            add(
                "serves",
                "ingress",
                &["declare_queryable", "reply"],
                keys_of(&inst.serves),
            );
            // Probes name no server: a server takes queries on any key
            // expression that includes its own.
            add(
                "serves.asked",
                "egress",
                &["query"],
                inst.serves
                    .iter()
                    .flat_map(|g| g.keys.iter().map(|k| widen(k)))
                    .collect(),
            );
            add(
                "receives.subscribe",
                "ingress",
                &["declare_subscriber"],
                selectors_of(&inst.receives),
            );
            add(
                "receives",
                "egress",
                &["put", "delete"],
                keys_of(&inst.receives),
            );
            add(
                "calls",
                "ingress",
                &["query", "declare_subscriber"],
                selectors_of(&inst.calls),
            );
            add(
                "calls.answers",
                "egress",
                &["reply", "put"],
                keys_of(&inst.calls),
            );
            let subject = format!("instance:{id}");
            subjects.push(json!({ "id": subject, "usernames": [id] }));
            policies.push(json!({ "id": subject, "rules": mine, "subjects": [subject] }));
        }
        json!({
            "enabled": true,
            "default_permission": "deny",
            "rules": rules,
            "subjects": subjects,
            "policies": policies,
        })
    }
}

const ALL_MESSAGES: [&str; 9] = [
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "declare_queryable",
    "reply",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
];

fn rule(id: &str, flow: &str, messages: &[&str], keys: &[String]) -> Json {
    let flows = match flow {
        "both" => json!(["ingress", "egress"]),
        one => json!([one]),
    };
    json!({
        "id": id,
        "key_exprs": keys,
        "messages": messages,
        "flows": flows,
        "permission": "allow",
    })
}

fn keys_of(grants: &[Grant]) -> Vec<String> {
    grants
        .iter()
        .flat_map(|g| g.keys.iter().cloned())
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect()
}

fn selectors_of(grants: &[Grant]) -> Vec<String> {
    grants
        .iter()
        .flat_map(|g| g.selectors.iter().cloned())
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect()
}

/// A server's key (or its action's parts) with the core and instance made
/// wild: what a probe asks.
fn widen(key: &str) -> String {
    EntrySelector::parse(key).map_or_else(
        || key.to_string(),
        |server| {
            EntrySelector {
                core: None,
                instance: None,
                ..server
            }
            .to_string()
        },
    )
}

impl Policy {
    /// The policy as a table for a reviewer: per instance, what it may
    /// emit, serve, receive and call, from and on whom, and the keys (under
    /// `peppy/<namespace>/`, which is left out).
    pub(crate) fn table(&self) -> String {
        use std::fmt::Write as _;
        let prefix = namespace_prefix(&self.namespace);
        let short = |k: &str| k.strip_prefix(&prefix).unwrap_or(k).to_string();
        let mut rows: Vec<[String; 4]> = Vec::new();
        let mut out = String::new();
        let _ = writeln!(
            out,
            "access policy (keys under {prefix}; anything not listed is refused by the router):"
        );
        for inst in &self.instances {
            rows.clear();
            let groups = [
                ("emits", &inst.emits, ""),
                ("serves", &inst.serves, ""),
                ("receives", &inst.receives, "from"),
                ("calls", &inst.calls, "on"),
            ];
            for (what, grants, side) in groups {
                for g in grants {
                    let entry = match &g.slot {
                        Some(slot) => format!("{} via {slot}", g.entry),
                        None if side == "from" => format!("{} (external)", g.entry),
                        None => g.entry.clone(),
                    };
                    let peers = if side.is_empty() {
                        String::new()
                    } else if g.peers.is_empty() {
                        format!("{side} nobody in the stack")
                    } else {
                        format!("{side} {}", g.peers.join(", "))
                    };
                    // What a call may ask (by instance, any core); what
                    // the others may carry.
                    let shown = if what == "calls" {
                        &g.selectors
                    } else {
                        &g.keys
                    };
                    let keys: Vec<String> = shown.iter().map(|k| short(k)).collect();
                    rows.push([
                        what.to_string(),
                        entry,
                        peers,
                        if keys.is_empty() {
                            "-".into()
                        } else {
                            keys.join(" ")
                        },
                    ]);
                }
            }
            let _ = writeln!(
                out,
                "\n  {} (core node {})",
                inst.instance_id, inst.core_node
            );
            if rows.is_empty() {
                let _ = writeln!(out, "    (nothing: it only announces itself)");
                continue;
            }
            let width = |i: usize| rows.iter().map(|r| r[i].chars().count()).max().unwrap_or(0);
            let (w0, w1, w2) = (width(0), width(1), width(2));
            for r in &rows {
                let line = format!("    {:w0$}  {:w1$}  {:w2$}  {}", r[0], r[1], r[2], r[3]);
                let _ = writeln!(out, "{}", line.trim_end());
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arm_loop() -> Policy {
        let launcher = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../examples/launchers/robot_arm_loop.json5");
        let stack = peppy_schema::check_launcher(&launcher, &peppy_schema::RepoOptions::default())
            .unwrap_or_else(|d| panic!("{d:?}"));
        derive(&stack, "lab", &|_| Some("robot".to_string()))
    }

    fn of<'a>(p: &'a Policy, id: &str) -> &'a InstancePolicy {
        p.instances.iter().find(|i| i.instance_id == id).unwrap()
    }

    /// A pinned slot asks its producer only (by instance, any core, as the
    /// runtime does), feedback included; the server may end every goal's
    /// feedback stream; tokens name the instance's own node.
    #[test]
    fn the_arm_loop_policy_names_exactly_the_bound_producer() {
        let p = arm_loop();
        let controller = of(&p, "controller");
        let call = controller
            .calls
            .iter()
            .find(|g| g.entry == "action move_arm")
            .unwrap();
        assert_eq!(call.peers, ["arm"]);
        assert_eq!(
            call.selectors,
            [
                "peppy/lab/action/node/robot_arm/v1/move_arm/*/arm/*",
                "peppy/lab/action/node/robot_arm/v1/move_arm/*/arm/feedback/*",
            ],
            "a pinned slot never probes every server"
        );
        assert!(call.keys.iter().all(|k| k.contains("/robot/arm/")));
        let receives = &controller.receives[0];
        assert_eq!(
            receives.keys,
            ["peppy/lab/topic/node/robot_arm/v1/joint_states/robot/arm"]
        );
        let arm = of(&p, "arm");
        assert!(arm.emits.iter().any(
            |g| g.keys == ["peppy/lab/action/node/robot_arm/v1/move_arm/robot/arm/feedback/*"]
        ));
        // The external topic: every instance that emits it.
        let commands = arm
            .receives
            .iter()
            .find(|g| g.entry == "topic joint_commands")
            .unwrap();
        assert_eq!(commands.peers, ["controller"]);

        let acl = p.access_control(&[]);
        let rules = acl["rules"].as_array().unwrap();
        let token = rules
            .iter()
            .find(|r| r["id"] == "instance:arm.self")
            .unwrap();
        assert_eq!(
            token["key_exprs"],
            serde_json::json!(["peppy/lab/live/robot/arm/robot_arm/v1"])
        );
        // No rule hands every reply of the namespace to everyone.
        assert!(!rules.iter().any(|r| {
            r["key_exprs"]
                .as_array()
                .unwrap()
                .contains(&"peppy/lab/**".into())
                && r["messages"].as_array().unwrap().contains(&"reply".into())
                && r["id"] != "everything"
        }));
    }

    /// Every instance follows the clock, asks it and may publish sim
    /// time; none may publish wall ticks or answer sync (the launch does).
    #[test]
    fn every_instance_reads_the_clock_and_only_the_launch_serves_it() {
        let acl = arm_loop().access_control(&[]);
        let rules = acl["rules"].as_array().unwrap();
        let rule = |id: &str| rules.iter().find(|r| r["id"] == id).unwrap();
        let keys = |id: &str| rule(id)["key_exprs"].clone();
        assert_eq!(
            keys("any.clock"),
            serde_json::json!(["peppy/lab/clock/tick/*"])
        );
        assert_eq!(
            keys("any.clock.ask"),
            serde_json::json!(["peppy/lab/clock/sync"])
        );
        assert_eq!(
            keys("any.clock.sim"),
            serde_json::json!(["peppy/lab/clock/tick/sim"])
        );
        assert_eq!(rule("any.clock.in")["flows"], serde_json::json!(["egress"]));
        for policy in acl["policies"].as_array().unwrap() {
            if policy["id"] == "operator" || policy["id"] == "recorder" {
                continue;
            }
            let granted = policy["rules"].as_array().unwrap();
            assert!(granted.contains(&"any.clock".into()), "{policy}");
            assert!(granted.contains(&"any.clock.sim".into()), "{policy}");
        }
        // No instance rule lets anything in on the wall tick or a sync
        // answer.
        let wall = "peppy/lab/clock/tick/wall";
        for r in rules
            .iter()
            .filter(|r| r["flows"] != serde_json::json!(["egress"]))
        {
            let messages = r["messages"].as_array().unwrap();
            let exprs: Vec<&str> = r["key_exprs"]
                .as_array()
                .unwrap()
                .iter()
                .filter_map(|k| k.as_str())
                .collect();
            if r["id"] == "everything" || r["id"] == "links" {
                continue;
            }
            let publishes_wall = messages.contains(&"put".into())
                && exprs
                    .iter()
                    .any(|k| *k == wall || k.ends_with("/clock/tick/*"));
            let answers_sync =
                messages.contains(&"reply".into()) && exprs.iter().any(|k| k.contains("/clock/"));
            assert!(!publishes_wall && !answers_sync, "{r}");
        }
    }

    #[test]
    fn a_server_key_widens_to_what_probes_ask() {
        assert_eq!(
            widen("peppy/lab/service/node/arm/v1/status/robot/arm_1"),
            "peppy/lab/service/node/arm/v1/status/*/*"
        );
        assert_eq!(
            widen("peppy/lab/action/node/arm/v1/move_arm/robot/arm_1/*"),
            "peppy/lab/action/node/arm/v1/move_arm/*/*/*"
        );
    }
}
