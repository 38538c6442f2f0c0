//! `graph --live`: the running stack as it is: the instances that answer,
//! drawn in their core node's frame when there are several, and an arrow
//! for every flow a consumer's routing actually admits, labelled with the
//! rate measured while sampling. Instances the launch started that no
//! longer answer are drawn greyed out.

use std::collections::{BTreeMap, HashMap};
use std::time::Duration;

use peppy_runtime::describe::{ConsumedTopic, EmittedTopic, InstanceInfo};
use peppy_runtime::wire::keys::{Space, parse_entry_key, space_selector};
use peppy_schema::SlotBinding;

use super::Observer;
use super::rates::hz;
use super::stream::slot_keeps;
use crate::drawing::{DrawEdge, DrawNode, Drawing, EdgeStyle, NodeState};
use crate::error::{Result, SetupError};

/// Messages seen per `(producer instance, topic)` while sampling.
pub(crate) type Counts = HashMap<(String, String), u64>;

/// Counts every topic message of the namespace for `window`.
pub(crate) async fn sample(observer: &Observer, window: Duration) -> Result<Counts> {
    let counts = std::sync::Arc::new(std::sync::Mutex::new(Counts::new()));
    let sink = counts.clone();
    let subscriber = observer
        .session
        .declare_subscriber(space_selector(&observer.reach.namespace, Space::Topic))
        .callback(move |sample| {
            if let Some(s) = parse_entry_key(sample.key_expr().as_str())
                && let Ok(mut c) = sink.lock()
            {
                *c.entry((s.instance, s.entry)).or_default() += 1;
            }
        })
        .await
        .map_err(SetupError::Sample)?;
    tokio::time::sleep(window).await;
    drop(subscriber);
    let counts = counts.lock().map(|c| c.clone()).unwrap_or_default();
    Ok(counts)
}

/// Whether a consumer's routing of `consumed` takes `emitted` from
/// `producer`: same topic and owner (any owner for an external topic), the
/// slot's filter, and for a node slot on an interface's key, the node. (The
/// consumer then still drops samples of another format.)
pub(crate) fn routes(
    consumed: &ConsumedTopic,
    producer: &InstanceInfo,
    emitted: &EmittedTopic,
) -> bool {
    consumed.name == emitted.name
        && consumed.owner.as_ref().is_none_or(|o| o == &emitted.owner)
        && slot_keeps(consumed, &producer.instance_id, Some(&producer.node))
}

fn rate_label(counts: &Counts, producer: &str, topic: &str, window: Duration) -> (String, bool) {
    let n = counts
        .get(&(producer.to_string(), topic.to_string()))
        .copied()
        .unwrap_or(0);
    if n == 0 {
        ("idle".into(), false)
    } else {
        (hz(n as f64 / window.as_secs_f64()), true)
    }
}

/// The picture of the running stack.
pub(crate) fn drawing(
    title: &str,
    all: &BTreeMap<String, InstanceInfo>,
    expected: &[(String, String)],
    counts: &Counts,
    window: Duration,
) -> Drawing {
    let cores: std::collections::BTreeSet<&str> =
        all.values().map(|i| i.core_node.as_str()).collect();
    let mut picture = Drawing {
        title: title.to_string(),
        ..Drawing::default()
    };
    for i in all.values() {
        picture.nodes.push(DrawNode {
            id: i.instance_id.clone(),
            label: i.instance_id.clone(),
            detail: i.node.to_string(),
            cluster: (cores.len() > 1).then(|| i.core_node.clone()),
            state: NodeState::Up,
        });
    }
    for (id, node) in expected.iter().filter(|(id, _)| !all.contains_key(id)) {
        picture.nodes.push(DrawNode {
            id: id.clone(),
            label: id.clone(),
            detail: format!("{node} (not running)"),
            cluster: None,
            state: NodeState::Down,
        });
    }
    for consumer in all.values() {
        topic_edges(consumer, all, counts, window, &mut picture);
        binding_edges(consumer, all, &mut picture);
    }
    picture
}

fn topic_edges(
    consumer: &InstanceInfo,
    all: &BTreeMap<String, InstanceInfo>,
    counts: &Counts,
    window: Duration,
    picture: &mut Drawing,
) {
    for consumed in &consumer.consumes {
        for producer in all.values() {
            for emitted in producer
                .emits
                .iter()
                .filter(|e| routes(consumed, producer, e))
            {
                let (rate, flowing) = if emitted.format.fingerprint == consumed.format.fingerprint {
                    rate_label(counts, &producer.instance_id, &emitted.name, window)
                } else {
                    ("dropped: formats differ".into(), false)
                };
                let label = match &consumed.slot {
                    Some(slot) => format!("{slot} · {} {rate}", emitted.name),
                    None => format!("{} {rate}", emitted.name),
                };
                let style = match (&consumed.slot, flowing) {
                    (None, _) => EdgeStyle::Dotted,
                    (Some(_), true) => EdgeStyle::Solid,
                    (Some(_), false) => EdgeStyle::Dashed,
                };
                picture.edges.push(DrawEdge {
                    from: producer.instance_id.clone(),
                    to: consumer.instance_id.clone(),
                    label,
                    style,
                });
            }
        }
    }
}

/// Bound slots that carry no topic (services, actions) still get their
/// arrow, from every bound producer that runs or was started.
fn binding_edges(
    consumer: &InstanceInfo,
    all: &BTreeMap<String, InstanceInfo>,
    picture: &mut Drawing,
) {
    for slot in &consumer.slots {
        let producers: Vec<&String> = match &slot.binding {
            SlotBinding::Pinned { producer } => vec![producer],
            SlotBinding::FromAnyBound { producers } | SlotBinding::Set { producers, .. } => {
                producers.iter().collect()
            }
            SlotBinding::FromAnyUnbound => Vec::new(),
        };
        for p in producers {
            // Drawn already by `topic_edges` when a topic of the slot flows
            // from `p`.
            let carries_topic = all.get(p).is_some_and(|producer| {
                consumer
                    .consumes
                    .iter()
                    .filter(|c| c.slot.as_deref() == Some(slot.link_id.as_str()))
                    .any(|c| producer.emits.iter().any(|e| routes(c, producer, e)))
            });
            if !carries_topic {
                let style = if all.contains_key(p) {
                    EdgeStyle::Solid
                } else {
                    EdgeStyle::Dashed
                };
                picture.edges.push(DrawEdge {
                    from: p.clone(),
                    to: consumer.instance_id.clone(),
                    label: slot.link_id.clone(),
                    style,
                });
            }
        }
    }
}

/// `graph --live`: joins the stack, describes it, samples its flows.
pub(crate) async fn picture(args: &crate::cli::StackArgs, window: Duration) -> Result<Drawing> {
    let observer = Observer::open(args).await?;
    let all = observer.describe_all().await?;
    let counts = sample(&observer, window).await?;
    let title = args
        .launcher
        .as_ref()
        .and_then(|l| l.file_stem())
        .map_or_else(
            || observer.reach.namespace.clone(),
            |s| s.to_string_lossy().into_owned(),
        );
    Ok(drawing(
        &title,
        &all,
        &observer.reach.expected,
        &counts,
        window,
    ))
}

#[cfg(test)]
mod tests {
    use peppy_runtime::describe::{FormatInfo, OwnerInfo, SlotInfo};
    use peppy_schema::{Identity, QosProfile, RouteFilter, SlotKind};

    use super::*;

    fn camera_owner() -> OwnerInfo {
        OwnerInfo {
            kind: SlotKind::Interface,
            name: "depth_camera".into(),
            tag: "v1".into(),
        }
    }

    fn format(fingerprint: u64) -> FormatInfo {
        FormatInfo {
            canonical: format!("{{x:u{fingerprint}}}"),
            fingerprint,
        }
    }

    fn instance(id: &str, node: &str) -> InstanceInfo {
        InstanceInfo {
            version: 1,
            instance_id: id.into(),
            core_node: "c".into(),
            namespace: "lab".into(),
            node: Identity::new(node, "v1"),
            pid: 1,
            started_at_ms: 0,
            slots: Vec::new(),
            emits: Vec::new(),
            consumes: Vec::new(),
            services: Vec::new(),
            actions: Vec::new(),
            pairings: Vec::new(),
        }
    }

    fn camera(id: &str, fingerprint: u64) -> InstanceInfo {
        let mut i = instance(id, "cam");
        i.emits.push(EmittedTopic {
            owner: camera_owner(),
            name: "video".into(),
            qos: QosProfile::SensorData,
            format: format(fingerprint),
            key: String::new(),
        });
        i
    }

    fn slot_topic(slot: &str, filter: RouteFilter) -> ConsumedTopic {
        ConsumedTopic {
            slot: Some(slot.into()),
            owner: Some(camera_owner()),
            name: "video".into(),
            qos: QosProfile::SensorData,
            format: format(8),
            selector: String::new(),
            filter,
            members_of: None,
        }
    }

    #[test]
    fn edges_follow_the_consumers_routing_with_measured_rates() {
        let mut recon = instance("recon", "recon");
        recon.consumes = vec![
            slot_topic("left", RouteFilter::Pin("cam_l".into())),
            slot_topic(
                "extras",
                RouteFilter::AnyExcept(["cam_l".to_string()].into()),
            ),
        ];
        recon.slots.push(SlotInfo {
            link_id: "arm".into(),
            kind: SlotKind::Node,
            target: Identity::new("arm", "v1"),
            binding: peppy_schema::SlotBinding::Pinned {
                producer: "arm_1".into(),
            },
            filter: RouteFilter::Pin("arm_1".into()),
        });
        let all: BTreeMap<String, InstanceInfo> = [
            recon,
            camera("cam_l", 8),
            camera("cam_x", 8),
            camera("cam_old", 16),
        ]
        .into_iter()
        .map(|i| (i.instance_id.clone(), i))
        .collect();
        let counts: Counts = [(("cam_l".to_string(), "video".to_string()), 30)].into();
        let expected = [("ghost".to_string(), "cam:v1".to_string())];
        let picture = drawing("t", &all, &expected, &counts, Duration::from_secs(2));
        let edges: Vec<(&str, &str, &str, EdgeStyle)> = picture
            .edges
            .iter()
            .map(|e| (e.from.as_str(), e.to.as_str(), e.label.as_str(), e.style))
            .collect();
        assert_eq!(
            edges,
            [
                ("cam_l", "recon", "left · video 15.0 Hz", EdgeStyle::Solid),
                (
                    "cam_old",
                    "recon",
                    "extras · video dropped: formats differ",
                    EdgeStyle::Dashed
                ),
                ("cam_x", "recon", "extras · video idle", EdgeStyle::Dashed),
                ("arm_1", "recon", "arm", EdgeStyle::Dashed),
            ]
        );
        let ghost = picture.nodes.iter().find(|n| n.id == "ghost").unwrap();
        assert_eq!(ghost.state, NodeState::Down);
        assert!(
            picture.nodes.iter().all(|n| n.cluster.is_none()),
            "one core node, no frames"
        );
    }
}
