//! `node list` and `node info`.

use peppy_runtime::describe::{InstanceInfo, PairingSlotInfo};
use peppy_schema::{RouteFilter, SlotBinding};

use super::{Observer, owner_label, print_json};
use crate::cli::{Format, ListArgs, NodeInfoArgs};
use crate::error::Result;
use crate::runs::{human_duration, now_ms};

/// A plain-text table: columns padded to their widest cell.
pub(crate) fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let mut widths: Vec<usize> = header.iter().map(|h| h.len()).collect();
    for row in rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: Vec<&str>| {
        let padded: Vec<String> = cells
            .iter()
            .zip(&widths)
            .map(|(c, w)| format!("{c:<w$}"))
            .collect();
        padded.join("  ").trim_end().to_string() + "\n"
    };
    let mut out = line(header.to_vec());
    for row in rows {
        out += &line(row.iter().map(String::as_str).collect());
    }
    out
}

fn names<T>(items: &[T], name: impl Fn(&T) -> &str) -> String {
    if items.is_empty() {
        return "-".into();
    }
    let mut v: Vec<&str> = items.iter().map(name).collect();
    v.dedup();
    v.join(", ")
}

/// The description as JSON, with its uptime.
pub(crate) fn info_json(info: &InstanceInfo, now: u64) -> serde_json::Value {
    let mut v = serde_json::to_value(info).expect("a description serializes");
    v["uptime_ms"] = (info.uptime(now).as_millis() as u64).into();
    v
}

pub(crate) async fn list(args: ListArgs) -> Result {
    let observer = Observer::open(&args.stack).await?;
    let all = observer.describe_all().await?;
    let now = now_ms();
    if args.format == Format::Json {
        let list: Vec<_> = all.values().map(|i| info_json(i, now)).collect();
        print_json(&serde_json::Value::Array(list));
        return Ok(());
    }
    if all.is_empty() {
        println!("no instance is running in {}", observer.reach.what);
        return Ok(());
    }
    let rows: Vec<Vec<String>> = all
        .values()
        .map(|i| {
            let mut serves: Vec<&str> = i.services.iter().map(|s| s.name.as_str()).collect();
            serves.extend(i.actions.iter().map(|a| a.name.as_str()));
            vec![
                i.instance_id.clone(),
                i.node.to_string(),
                i.core_node.clone(),
                i.pid.to_string(),
                human_duration(i.uptime(now)),
                names(&i.emits, |t| &t.name),
                names(&i.consumes, |t| &t.name),
                if serves.is_empty() {
                    "-".into()
                } else {
                    serves.join(", ")
                },
            ]
        })
        .collect();
    print!(
        "{}",
        table(
            &[
                "INSTANCE", "NODE", "CORE", "PID", "UPTIME", "EMITS", "CONSUMES", "SERVES"
            ],
            &rows
        )
    );
    Ok(())
}

pub(crate) async fn info(args: NodeInfoArgs) -> Result {
    let observer = Observer::open(&args.stack).await?;
    let info = observer.describe_one(&args.instance).await?;
    let now = now_ms();
    if args.format == Format::Json {
        print_json(&info_json(&info, now));
    } else {
        print!("{}", info_text(&info, now));
    }
    Ok(())
}

/// What a slot is bound to, for people.
pub(crate) fn binding_text(binding: &SlotBinding, filter: &RouteFilter) -> String {
    match (binding, filter) {
        (SlotBinding::Pinned { producer }, _) => format!("pinned to {producer}"),
        (SlotBinding::FromAnyBound { producers }, _) => format!("from {}", producers.join(", ")),
        (
            SlotBinding::Set {
                vacant: Some(why), ..
            },
            _,
        ) => format!("vacant ({why})"),
        (SlotBinding::Set { producers, .. }, _) if producers.is_empty() => "nothing linked".into(),
        (SlotBinding::Set { producers, .. }, _) => format!("linked to {}", producers.join(", ")),
        (SlotBinding::FromAnyUnbound, RouteFilter::AnyExcept(ex)) if !ex.is_empty() => {
            let ex: Vec<&str> = ex.iter().map(String::as_str).collect();
            format!("from any, except {}", ex.join(", "))
        }
        (SlotBinding::FromAnyUnbound, _) => "from any".into(),
    }
}

/// A pairing slot and its state, for people: the role it plays and its
/// peer (or what it waits for), or the role it observes and its sources.
pub(crate) fn pairing_text(p: &PairingSlotInfo) -> String {
    if p.observer {
        let sources: Vec<String> = p
            .sources
            .iter()
            .map(|x| {
                let at = match &x.link_id {
                    Some(l) => format!("{}/{l}", x.instance_id),
                    None => x.instance_id.clone(),
                };
                format!("{at} ({})", if x.live { "live" } else { "not running" })
            })
            .collect();
        let sources = if sources.is_empty() {
            "no sources".to_string()
        } else {
            sources.join(", ")
        };
        return format!("pairing {} observes {}: {sources}", p.pairing, p.role);
    }
    let state = match (&p.peer, &p.claiming) {
        (Some(peer), _) => format!(
            "paired with {}/{} (core node {})",
            peer.instance_id, peer.link_id, peer.core_node
        ),
        (None, Some(target)) => format!("not paired, waiting for {target}"),
        (None, None) => "not paired, waiting for a peer to link to it".into(),
    };
    format!("pairing {} plays {}: {state}", p.pairing, p.role)
}

/// `node info` for people.
pub(crate) fn info_text(i: &InstanceInfo, now: u64) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "{} ({})", i.instance_id, i.node);
    let _ = writeln!(s, "  core node  {}", i.core_node);
    let _ = writeln!(s, "  namespace  {}", i.namespace);
    let _ = writeln!(s, "  pid        {}", i.pid);
    let _ = writeln!(s, "  uptime     {}", human_duration(i.uptime(now)));
    if !i.slots.is_empty() {
        let _ = writeln!(s, "slots");
        let width = i.slots.iter().map(|x| x.link_id.len()).max().unwrap_or(0);
        for slot in &i.slots {
            let _ = writeln!(
                s,
                "  {:width$}  {} {}: {}",
                slot.link_id,
                slot.kind.as_str(),
                slot.target,
                binding_text(&slot.binding, &slot.filter)
            );
        }
    }
    if !i.pairings.is_empty() {
        let _ = writeln!(s, "pairings");
        let width = i
            .pairings
            .iter()
            .map(|x| x.link_id.len())
            .max()
            .unwrap_or(0);
        for p in &i.pairings {
            let _ = writeln!(s, "  {:width$}  {}", p.link_id, pairing_text(p));
        }
    }
    if !i.emits.is_empty() {
        let _ = writeln!(s, "emits");
        for t in &i.emits {
            let _ = writeln!(
                s,
                "  {}  ({}, {})  {}",
                t.name,
                owner_label(&t.owner),
                t.qos.as_str(),
                t.format.canonical
            );
        }
    }
    if !i.consumes.is_empty() {
        let _ = writeln!(s, "consumes");
        for t in &i.consumes {
            let from = match (&t.slot, &t.owner) {
                (Some(slot), Some(o)) => format!("slot {slot}, {}", owner_label(o)),
                _ => "external, any owner".into(),
            };
            let _ = writeln!(s, "  {}  ({from})  {}", t.name, t.format.canonical);
        }
    }
    if !i.services.is_empty() {
        let _ = writeln!(s, "services");
        for x in &i.services {
            let _ = writeln!(
                s,
                "  {}  ({})  {} -> {}",
                x.name,
                owner_label(&x.owner),
                x.request.canonical,
                x.response.canonical
            );
        }
    }
    if !i.actions.is_empty() {
        let _ = writeln!(s, "actions");
        for a in &i.actions {
            let _ = writeln!(
                s,
                "  {}  ({})  goal {}  feedback {}  result {}",
                a.name,
                owner_label(&a.owner),
                a.goal.canonical,
                a.feedback.canonical,
                a.result.canonical
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairing_slots_say_their_state() {
        use peppy_runtime::describe::{PeerEndInfo, SourceInfo};
        let mut p = PairingSlotInfo {
            link_id: "follower".into(),
            pairing: peppy_schema::Identity::new("joint_link", "v1"),
            role: "leader".into(),
            observer: false,
            claiming: Some("arm/leader".into()),
            peer: None,
            sources: Vec::new(),
        };
        assert_eq!(
            pairing_text(&p),
            "pairing joint_link:v1 plays leader: not paired, waiting for arm/leader"
        );
        p.peer = Some(PeerEndInfo {
            core_node: "launch-1".into(),
            instance_id: "arm".into(),
            link_id: "leader".into(),
        });
        assert_eq!(
            pairing_text(&p),
            "pairing joint_link:v1 plays leader: paired with arm/leader (core node launch-1)"
        );
        p.observer = true;
        p.role = "follower".into();
        p.sources = vec![
            SourceInfo {
                core_node: "launch-1".into(),
                instance_id: "arm".into(),
                link_id: Some("leader".into()),
                live: true,
            },
            SourceInfo {
                core_node: "launch-1".into(),
                instance_id: "arm_2".into(),
                link_id: None,
                live: false,
            },
        ];
        assert_eq!(
            pairing_text(&p),
            "pairing joint_link:v1 observes follower: arm/leader (live), arm_2 (not running)"
        );
    }

    #[test]
    fn tables_pad_columns_to_the_widest_cell() {
        let t = table(
            &["A", "LONG"],
            &[
                vec!["wide cell".into(), "x".into()],
                vec!["y".into(), "".into()],
            ],
        );
        assert_eq!(t, "A          LONG\nwide cell  x\ny\n");
    }
}
