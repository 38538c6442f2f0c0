//! `graph --live`: the running stack as it is: the instances that answer,
//! drawn in their core node's frame when there are several, and an arrow
//! for every flow a consumer's routing actually admits, labelled with the
//! rate measured while sampling. Instances the launch started that no
//! longer answer are drawn greyed out.

use std::collections::{BTreeMap, HashMap};
use std::time::Duration;

use peppy_runtime::describe::{ConsumedTopic, EmittedTopic, InstanceInfo};
use peppy_runtime::wire::keys::parse_entry_key;
use peppy_schema::SlotBinding;

use super::Observer;
use super::rates::hz;
use crate::drawing::{DrawEdge, DrawNode, Drawing, EdgeStyle, NodeState};
use crate::error::{LaunchError, Result};

/// Messages seen per `(producer instance, topic)` while sampling.
pub(crate) type Counts = HashMap<(String, String), u64>;

/// Counts every topic message of the namespace for `window`.
pub(crate) async fn sample(observer: &Observer, window: Duration) -> Result<Counts> {
    let counts = std::sync::Arc::new(std::sync::Mutex::new(Counts::new()));
    let sink = counts.clone();
    let subscriber = observer
        .session
        .declare_subscriber(format!("peppy/{}/topic/**", observer.reach.namespace))
        .callback(move |sample| {
            if let Some(s) = parse_entry_key(sample.key_expr().as_str())
                && let Ok(mut c) = sink.lock()
            {
                *c.entry((s.instance, s.entry)).or_default() += 1;
            }
        })
        .await
        .map_err(|e| LaunchError::Setup(format!("cannot sample the topics: {e}")))?;
    tokio::time::sleep(window).await;
    drop(subscriber);
    let counts = counts.lock().map(|c| c.clone()).unwrap_or_default();
    Ok(counts)
}

/// Whether a consumer's routing of `consumed` admits `emitted` from
/// `producer`: same topic and owner (any owner for an external topic), the
/// slot's filter, and for a node slot on an interface's key, the node.
pub(crate) fn admits(
    consumed: &ConsumedTopic,
    producer: &InstanceInfo,
    emitted: &EmittedTopic,
) -> bool {
    consumed.name == emitted.name
        && consumed.owner.as_ref().is_none_or(|o| o == &emitted.owner)
        && consumed.filter.accepts(&producer.instance_id)
        && consumed
            .members_of
            .as_ref()
            .is_none_or(|node| node == &producer.node)
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
                .filter(|e| admits(consumed, producer, e))
            {
                let (rate, flowing) =
                    rate_label(counts, &producer.instance_id, &emitted.name, window);
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
            SlotBinding::FromAnyBound { producers } => producers.iter().collect(),
            SlotBinding::FromAnyUnbound => Vec::new(),
        };
        let slot_prefix = format!("{} ·", slot.link_id);
        for p in producers {
            let drawn = picture.edges.iter().any(|e| {
                &e.from == p && e.to == consumer.instance_id && e.label.starts_with(&slot_prefix)
            });
            if !drawn {
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
