//! `topic list`, `topic echo` and `topic pub`.

use std::collections::{BTreeMap, HashMap};
use std::time::Duration;

use peppy_runtime::describe::InstanceInfo;
use peppy_runtime::wire::attachment;
use peppy_runtime::wire::keys::{Channel, Owner, entry_key};
use peppy_schema::{MessageFormat, QosProfile};
use serde_json::json;

use super::dynamic;
use super::nodes::table;
use super::stream::{Limits, Selection, Tap, TopicArg, sender_owner, topic_names};
use super::{Observer, SelectError, owner_label, print_json};
use crate::cli::{EchoArgs, Format, ListArgs, PubArgs};
use crate::error::{InspectError, LaunchError, Result, SetupError, UsageError};
use crate::report;
use crate::runs::now_ms;

/// One topic of the running stack: an owner's entry, or an external
/// topic only consumers name.
#[derive(Debug, Default)]
struct TopicRow {
    qos: Option<QosProfile>,
    format: String,
    producers: Vec<String>,
    consumers: Vec<String>,
}

/// Topics by `(owner, name)`; `owner` is `None` for a topic only external
/// consumers name.
fn topics(all: &BTreeMap<String, InstanceInfo>) -> BTreeMap<(Option<String>, String), TopicRow> {
    let mut rows: BTreeMap<(Option<String>, String), TopicRow> = BTreeMap::new();
    for i in all.values() {
        for t in &i.emits {
            let row = rows
                .entry((Some(owner_label(&t.owner)), t.name.clone()))
                .or_default();
            row.qos = Some(t.qos);
            row.format = t.format.canonical.clone();
            row.producers.push(i.instance_id.clone());
        }
    }
    for i in all.values() {
        for t in &i.consumes {
            let who = match &t.slot {
                Some(slot) => format!("{}.{slot}", i.instance_id),
                None => format!("{} (external)", i.instance_id),
            };
            let owners: Vec<Option<String>> = match &t.owner {
                Some(o) => vec![Some(owner_label(o))],
                // An external topic takes every owner's topic of its name.
                None => rows
                    .keys()
                    .filter(|(o, n)| o.is_some() && n == &t.name)
                    .map(|(o, _)| o.clone())
                    .collect(),
            };
            let owners = if owners.is_empty() {
                vec![None]
            } else {
                owners
            };
            for owner in owners {
                let row = rows.entry((owner, t.name.clone())).or_default();
                if row.format.is_empty() {
                    row.format = t.format.canonical.clone();
                }
                row.consumers.push(who.clone());
            }
        }
    }
    rows
}

fn joined(v: &[String]) -> String {
    if v.is_empty() {
        "-".into()
    } else {
        v.join(", ")
    }
}

pub(crate) async fn list(args: ListArgs) -> Result {
    let observer = Observer::open(&args.stack).await?;
    let all = observer.describe_all().await?;
    let rows = topics(&all);
    if args.format == Format::Json {
        let list: Vec<_> = rows
            .iter()
            .map(|((owner, name), r)| {
                json!({
                    "topic": name,
                    "owner": owner,
                    "qos": r.qos.map(QosProfile::as_str),
                    "format": r.format,
                    "producers": r.producers,
                    "consumers": r.consumers,
                })
            })
            .collect();
        print_json(&serde_json::Value::Array(list));
        return Ok(());
    }
    if rows.is_empty() {
        println!(
            "no topics: no instance is running in {}",
            observer.reach.what
        );
        return Ok(());
    }
    let table_rows: Vec<Vec<String>> = rows
        .iter()
        .map(|((owner, name), r)| {
            vec![
                name.clone(),
                owner.clone().unwrap_or_else(|| "(external)".into()),
                r.qos.map_or("-", QosProfile::as_str).to_string(),
                joined(&r.producers),
                joined(&r.consumers),
                r.format.clone(),
            ]
        })
        .collect();
    print!(
        "{}",
        table(
            &["TOPIC", "OWNER", "QOS", "PRODUCERS", "CONSUMERS", "FORMAT"],
            &table_rows
        )
    );
    Ok(())
}

pub(crate) async fn echo(args: EchoArgs) -> Result {
    let observer = Observer::open(&args.stack).await?;
    let all = observer.describe_some().await?;
    let mut selection = Selection::new(&args.select, &observer.reach.namespace, &all)?;
    let tap = Tap::of(&observer, &selection, true).await?;
    let mut limits = Limits::new(&args.stream);
    if args.once {
        limits.count = Some(1);
    }
    let mut cache = HashMap::new();
    let mut shown = 0u64;
    let mut warned = std::collections::HashSet::new();
    while !limits.reached(shown) {
        let Some(r) = tap.next(&limits).await else {
            break;
        };
        selection.learn(&observer, &r.sender).await;
        if !selection.keeps(&r.sender, r.fingerprint) {
            continue;
        }
        let Some(fp) = r.fingerprint else {
            if warned.insert((r.sender.instance.clone(), 0)) {
                eprintln!(
                    "note: dropping samples from `{}` without a peppy attachment",
                    r.sender.instance
                );
            }
            continue;
        };
        let format = selection
            .format(&observer, &mut cache, fp, &r.sender.instance)
            .await;
        let decoded = match format.as_ref().map(|f| dynamic::decode(f, &r.payload)) {
            Some(Ok(v)) => v,
            Some(Err(e)) => {
                if warned.insert((r.sender.instance.clone(), fp)) {
                    eprintln!(
                        "note: a message from `{}` does not decode with its format: {e}",
                        r.sender.instance
                    );
                }
                continue;
            }
            None => {
                if warned.insert((r.sender.instance.clone(), fp)) {
                    eprintln!(
                        "note: `{}` sends format {fp:016x}, which no instance describes; its messages are skipped",
                        r.sender.instance
                    );
                }
                continue;
            }
        };
        shown += 1;
        print_message(args.format, &selection.topic, &r.sender, shown, &decoded);
    }
    if tap.dropped() > 0 {
        eprintln!(
            "note: {} messages were skipped because printing fell behind the topic",
            tap.dropped()
        );
    }
    limits.outcome(shown, "messages")
}

fn print_message(
    format: Format,
    topic: &str,
    sender: &peppy_runtime::wire::keys::Sender,
    n: u64,
    value: &dynamic::Dyn,
) {
    match format {
        Format::Json => print_json(&json!({
            "topic": topic,
            "owner": sender_owner(sender),
            "from": sender.instance,
            "core": sender.core,
            "seq": n,
            "received_at_ms": now_ms(),
            "message": dynamic::to_json(value),
        })),
        Format::Human => {
            println!(
                "--- {topic} from {} ({}) #{n}",
                sender.instance,
                sender_owner(sender)
            );
            print!("{}", dynamic::to_text(value));
        }
    }
}

/// Where `topic pub` publishes: a producer's key, so consumers bound to
/// that producer take the message as theirs.
struct PubTarget {
    key: String,
    qos: QosProfile,
    format: String,
    fingerprint: u64,
}

fn pub_target(args: &PubArgs, ns: &str, all: &BTreeMap<String, InstanceInfo>) -> Result<PubTarget> {
    let topic = TopicArg::parse(&args.topic)?;
    let name = topic.name.clone();
    let emitters = topic.emitters(all);
    let producers = || {
        emitters
            .iter()
            .map(|(i, _)| i.instance_id.clone())
            .collect::<Vec<_>>()
    };
    let chosen = match (&args.as_instance, emitters.as_slice()) {
        (Some(id), _) => emitters.iter().find(|(i, _)| &i.instance_id == id),
        (None, [one]) => Some(one),
        (None, []) => None,
        (None, _) => {
            return Err(SelectError::SeveralProducers {
                topic: args.topic.clone(),
                producers: producers(),
            }
            .into());
        }
    };
    if let Some((_, t)) = chosen {
        return Ok(PubTarget {
            key: t.key.clone(),
            qos: t.qos,
            format: t.format.canonical.clone(),
            fingerprint: t.format.fingerprint,
        });
    }
    if let Some(id) = &args.as_instance
        && !emitters.is_empty()
    {
        return Err(SelectError::NotAProducer {
            instance: id.clone(),
            topic: args.topic.clone(),
            producers: producers(),
        }
        .into());
    }
    // Nobody emits it: an external topic reaches its consumers from any
    // owner, so the command publishes under its own name.
    let external = all
        .values()
        .flat_map(|i| i.consumes.iter())
        .find(|t| t.name == name && t.slot.is_none());
    match external {
        Some(t) => Ok(PubTarget {
            key: entry_key(
                ns,
                Channel::Topic,
                &Owner::Node {
                    name: "peppy-launch",
                    tag: "cli",
                },
                &name,
                "cli",
                args.as_instance.as_deref().unwrap_or("peppy-launch"),
            ),
            qos: t.qos,
            format: t.format.canonical.clone(),
            fingerprint: t.format.fingerprint,
        }),
        None => Err(SelectError::NotPublishable {
            topic: args.topic.clone(),
            topics: topic_names(all),
        }
        .into()),
    }
}

/// Encodes the user's JSON5 against `canonical`; a wrong field is shown in
/// the text. `None` text means an empty message.
pub(crate) fn encode_arg(canonical: &str, origin: &str, text: Option<&str>) -> Result<Vec<u8>> {
    let format =
        MessageFormat::from_canonical(canonical).map_err(InspectError::UnreadableFormat)?;
    let text = match text {
        Some(t) => t,
        None if format.fields.is_empty() => "{}",
        None => {
            return Err(UsageError::NoValue {
                origin: origin.to_string(),
                format: canonical.to_string(),
            }
            .into());
        }
    };
    dynamic::encode_text(&format, origin, text).map_err(|diags| {
        report::print_human(&diags);
        LaunchError::Invalid {
            errors: diags.error_count(),
        }
    })
}

pub(crate) async fn publish(args: PubArgs) -> Result {
    if let Some(rate) = args.rate
        && !(rate.is_finite() && rate > 0.0 && rate <= 100_000.0)
    {
        return Err(UsageError::Rate { rate }.into());
    }
    let observer = Observer::open(&args.stack).await?;
    let all = observer.describe_some().await?;
    let target = pub_target(&args, &observer.reach.namespace, &all)?;
    let payload = encode_arg(&target.format, "message", args.value.as_deref())?;
    let publisher =
        peppy_runtime::tool::publisher(&observer.session, target.key.clone(), target.qos)
            .await
            .map_err(SetupError::Publisher)?;
    wait_for_subscribers(&publisher, Duration::from_secs(2)).await;
    let limits = Limits::new(&args.stream);
    let count = match (args.rate, limits.count) {
        (None, None) => Some(1),
        (_, n) => n,
    };
    let period = args.rate.map(|r| Duration::from_secs_f64(1.0 / r));
    let mut tick = tokio::time::interval(period.unwrap_or(Duration::from_millis(1)));
    let mut sent = 0u64;
    let stop = super::interrupted();
    while count.is_none_or(|n| sent < n) {
        tokio::select! {
            _ = tick.tick() => {}
            () = limits.expired() => break,
            () = stop.cancelled() => break,
        }
        publisher
            .put(payload.clone())
            .attachment(attachment::topic(target.fingerprint))
            .await
            .map_err(InspectError::Publish)?;
        sent += 1;
    }
    eprintln!("published {sent} message(s) on {}", target.key);
    // Let the last message leave before the session closes.
    tokio::time::sleep(Duration::from_millis(100)).await;
    limits.outcome(sent, "messages")
}

/// Waits (bounded) until some subscriber matches, so a single message is
/// not published before the stack's routes reach this session.
pub(crate) async fn wait_for_subscribers(
    publisher: &zenoh::pubsub::Publisher<'_>,
    bound: Duration,
) {
    let deadline = tokio::time::Instant::now() + bound;
    while tokio::time::Instant::now() < deadline {
        if publisher
            .matching_status()
            .await
            .is_ok_and(|s| s.matching())
        {
            return;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    eprintln!("note: no consumer is subscribed to this topic yet; publishing anyway");
}
