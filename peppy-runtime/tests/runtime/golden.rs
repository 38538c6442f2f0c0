//! The golden vectors the Rust and Python runtimes share
//! (`tests/golden/wire.json`, docs/WIRE.md): every key, attachment and
//! format fingerprint there, built and read back by this runtime; and the
//! rules both runtimes apply (plans, route filters, named servers, grace
//! windows, instance descriptions, `info` answers), from the same vectors. The
//! message vectors are encoded and decoded from their format text by the
//! launcher's `inspect::dynamic` (its tests read the same file), the codec
//! walk that needs no generated type.

use peppy_runtime::spec::FormatSpec;
use peppy_runtime::wire::attachment::{
    self, END_OF_FEEDBACK, QueryHeader, QueryKind, ReplyStatus, parse_reply, parse_topic,
};
use peppy_runtime::wire::keys::{
    self, ActionPart, Channel, Claim, EntrySelector, Owner, Space, is_segment, parse_core_key,
    parse_entry_key, parse_liveliness_key, parse_pairing_topic_key, split_entry_key,
};
use peppy_schema::MessageFormat;
use serde_json::{Value, json};

/// The shared file, read afresh by each test.
fn golden() -> Value {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/golden/wire.json");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// `"01 0a ff"` as bytes.
fn hex(text: &str) -> Vec<u8> {
    let digits: String = text.split_whitespace().collect();
    assert!(digits.len().is_multiple_of(2), "odd hex `{text}`");
    (0..digits.len())
        .step_by(2)
        .map(|i| {
            u8::from_str_radix(&digits[i..i + 2], 16).unwrap_or_else(|e| panic!("{text}: {e}"))
        })
        .collect()
}

/// A fingerprint written as 16 hex digits.
fn fingerprint(v: &Value) -> u64 {
    let text = v.as_str().unwrap_or_else(|| panic!("fingerprint {v}"));
    assert_eq!(text.len(), 16, "fingerprint `{text}`: 16 hex digits");
    u64::from_str_radix(text, 16).unwrap()
}

fn text<'a>(args: &'a Value, name: &str) -> &'a str {
    args[name]
        .as_str()
        .unwrap_or_else(|| panic!("argument `{name}` of {args}"))
}

/// A string, or `null` for a wildcard.
fn wild<'a>(args: &'a Value, name: &str) -> Option<&'a str> {
    match &args[name] {
        Value::Null => None,
        v => Some(
            v.as_str()
                .unwrap_or_else(|| panic!("argument `{name}` of {args}")),
        ),
    }
}

fn owner(v: &Value) -> Option<Owner<'_>> {
    let (name, tag) = match v {
        Value::Null => return None,
        v => (text(v, "name"), text(v, "tag")),
    };
    Some(match text(v, "kind") {
        "node" => Owner::Node { name, tag },
        "interface" => Owner::Interface { name, tag },
        other => panic!("owner kind `{other}`"),
    })
}

fn channel(name: &str) -> Channel {
    match name {
        "topic" => Channel::Topic,
        "service" => Channel::Service,
        "action" => Channel::Action,
        other => panic!("channel `{other}`"),
    }
}

fn space(name: &str) -> Space {
    [
        Space::Topic,
        Space::Service,
        Space::Action,
        Space::Live,
        Space::Pair,
        Space::Format,
        Space::Describe,
        Space::Core,
        Space::Clock,
        Space::Stack,
    ]
    .into_iter()
    .find(|s| s.as_str() == name)
    .unwrap_or_else(|| panic!("space `{name}`"))
}

/// What `wire::keys::<function>` builds from `args`.
fn build(function: &str, a: &Value) -> String {
    let s = |name| text(a, name);
    match function {
        "entry_key" => keys::entry_key(
            s("ns"),
            channel(s("channel")),
            &owner(&a["owner"]).expect("an entry key's owner"),
            s("entry"),
            s("core"),
            s("instance"),
        ),
        "entry_selector" => keys::entry_selector(
            s("ns"),
            channel(s("channel")),
            owner(&a["owner"]).as_ref(),
            s("entry"),
            wild(a, "core"),
            wild(a, "instance"),
        ),
        "action_part_key" => {
            let part = [ActionPart::Goal, ActionPart::Cancel, ActionPart::Result]
                .into_iter()
                .find(|p| p.as_str() == s("part"))
                .unwrap_or_else(|| panic!("action part {a}"));
            keys::action_part_key(s("action"), part)
        }
        "action_parts_selector" => keys::action_parts_selector(s("action")),
        "feedback_key" => keys::feedback_key(s("action"), s("goal_id")),
        "feedback_selector" => keys::feedback_selector(s("action")),
        "format_key" => keys::format_key(s("ns"), fingerprint(&a["fingerprint"]), s("instance")),
        "format_selector" => keys::format_selector(s("ns"), wild(a, "instance")),
        "liveliness_key" => {
            keys::liveliness_key(s("ns"), s("core"), s("instance"), s("node"), s("tag"))
        }
        "liveliness_selector" => keys::liveliness_selector(s("ns"), s("node"), s("tag")),
        "all_liveliness_selector" => keys::all_liveliness_selector(s("ns")),
        "instance_liveliness_selector" => {
            keys::instance_liveliness_selector(s("ns"), s("core"), s("instance"))
        }
        "describe_key" => keys::describe_key(s("ns"), s("core"), s("instance")),
        "describe_selector" => keys::describe_selector(s("ns")),
        "core_key" => keys::core_key(s("ns"), s("core"), s("launch")),
        "core_selector" => keys::core_selector(s("ns")),
        "namespace_prefix" => keys::namespace_prefix(s("ns")),
        "namespace_selector" => keys::namespace_selector(s("ns")),
        "space_selector" => keys::space_selector(s("ns"), space(s("space"))),
        "clock_tick_key" => keys::clock_tick_key(
            s("ns"),
            [keys::ClockSource::Wall, keys::ClockSource::Sim]
                .into_iter()
                .find(|c| c.as_str() == s("source"))
                .unwrap_or_else(|| panic!("clock source {a}")),
        ),
        "clock_tick_selector" => keys::clock_tick_selector(s("ns")),
        "clock_sync_key" => keys::clock_sync_key(s("ns")),
        "pairing_topic_key" => keys::pairing_topic_key(
            s("ns"),
            s("pairing"),
            s("tag"),
            s("topic"),
            s("core"),
            s("instance"),
            s("link_id"),
        ),
        "pairing_topic_selector" => keys::pairing_topic_selector(
            s("ns"),
            s("pairing"),
            s("tag"),
            s("topic"),
            wild(a, "core"),
            wild(a, "instance"),
            wild(a, "link_id"),
        ),
        "claim_key" => {
            let peer = &a["peer"];
            let peer = (!peer.is_null()).then(|| (text(peer, "instance"), text(peer, "link_id")));
            Claim {
                pairing: s("pairing"),
                tag: s("tag"),
                role: s("role"),
                core: s("core"),
                instance: s("instance"),
                link_id: s("link_id"),
                peer,
            }
            .key(s("ns"))
        }
        "claim_selector" => keys::claim_selector(s("ns"), s("pairing"), s("tag")),
        "core_function_key" => keys::core_function_key(
            s("ns"),
            s("core"),
            match s("function") {
                "datastore" => keys::CoreFunction::Datastore,
                "info" => keys::CoreFunction::Info,
                "list" => keys::CoreFunction::List,
                other => panic!("no core function `{other}`"),
            },
        ),
        other => panic!("wire::keys has no `{other}`"),
    }
}

#[test]
fn every_golden_key_is_built_as_written() {
    let golden = golden();
    let vectors = golden["keys"]["build"].as_array().unwrap();
    assert!(!vectors.is_empty());
    for v in vectors {
        let function = v["fn"].as_str().unwrap();
        let key = v["key"].as_str().unwrap();
        assert_eq!(build(function, &v["args"]), key, "{v}");
        // Entry keys and selectors read back into the parts they were
        // built from.
        let entry = [
            "entry_key",
            "entry_selector",
            "action_part_key",
            "action_parts_selector",
            "feedback_key",
            "feedback_selector",
        ];
        if entry.contains(&function) {
            let parsed = EntrySelector::parse(key).unwrap_or_else(|| panic!("{key}"));
            assert_eq!(parsed.to_string(), key);
            if let Some(o) = owner(&v["args"]["owner"]) {
                assert_eq!(parsed.owner, Some(o), "{v}");
            }
        }
    }
}

#[test]
fn every_golden_key_is_parsed_as_written() {
    let golden = golden();
    for v in golden["keys"]["parse"].as_array().unwrap() {
        let key = v["key"].as_str().unwrap();
        let parts = match v["fn"].as_str().unwrap() {
            "parse_entry_key" => {
                let owned = parse_entry_key(key).map(|s| {
                    json!({ "kind": s.kind, "name": s.name, "tag": s.tag,
                            "entry": s.entry, "core": s.core, "instance": s.instance })
                });
                let borrowed = split_entry_key(key).map(|s| {
                    json!({ "kind": s.kind, "name": s.name, "tag": s.tag,
                            "entry": s.entry, "core": s.core, "instance": s.instance })
                });
                assert_eq!(owned, borrowed, "{key}");
                owned
            }
            "parse_liveliness_key" => parse_liveliness_key(key)
                .map(|(core, instance)| json!({ "core": core, "instance": instance })),
            "parse_core_key" => {
                parse_core_key(key).map(|(core, launch)| json!({ "core": core, "launch": launch }))
            }
            "parse_pairing_topic_key" => parse_pairing_topic_key(key).map(|p| {
                json!({ "pairing": p.pairing, "tag": p.tag, "topic": p.topic,
                        "core": p.core, "instance": p.instance, "link_id": p.link_id })
            }),
            "parse_claim_key" => Claim::parse(key).map(|c| {
                let peer = c
                    .peer
                    .map(|(instance, link_id)| json!({ "instance": instance, "link_id": link_id }));
                json!({ "pairing": c.pairing, "tag": c.tag, "role": c.role, "core": c.core,
                        "instance": c.instance, "link_id": c.link_id, "peer": peer })
            }),
            other => panic!("wire::keys has no `{other}`"),
        };
        assert_eq!(parts.unwrap_or(Value::Null), v["parts"], "{key:?}");
    }
    let segments = &golden["keys"]["segments"];
    for (list, valid) in [("valid", true), ("invalid", false)] {
        for s in segments[list].as_array().unwrap() {
            let s = s.as_str().unwrap();
            assert_eq!(is_segment(s), valid, "{s:?}");
        }
    }
}

#[test]
fn every_golden_attachment_is_encoded_and_read_as_written() {
    let golden = golden();
    let a = &golden["attachments"];
    let list = |name: &str| a[name].as_array().unwrap_or_else(|| panic!("{name}"));
    for v in list("topic") {
        let fp = fingerprint(&v["fingerprint"]);
        let bytes = hex(v["hex"].as_str().unwrap());
        assert_eq!(attachment::topic(fp), bytes, "{v}");
        assert_eq!(parse_topic(&bytes), Some(fp), "{v}");
    }
    for v in list("topic_rejected") {
        assert_eq!(parse_topic(&hex(v.as_str().unwrap())), None, "{v}");
    }
    assert_eq!(
        END_OF_FEEDBACK.as_slice(),
        hex(a["end_of_feedback"].as_str().unwrap())
    );
    for v in list("query") {
        let header = QueryHeader {
            kind: match text(v, "kind") {
                "request" => QueryKind::Request,
                "probe" => QueryKind::Probe,
                other => panic!("query kind `{other}`"),
            },
            fingerprint: fingerprint(&v["fingerprint"]),
            core: text(v, "core").into(),
            instance: text(v, "instance").into(),
        };
        let bytes = hex(text(v, "hex"));
        assert_eq!(header.encode(), bytes, "{v}");
        assert_eq!(QueryHeader::decode(&bytes), Some(header), "{v}");
    }
    for v in list("query_rejected") {
        assert_eq!(QueryHeader::decode(&hex(v.as_str().unwrap())), None, "{v}");
    }
    for v in list("reply") {
        let status = match text(v, "status") {
            "ack" => ReplyStatus::Ack,
            "ok" => ReplyStatus::Ok,
            "handler_error" => ReplyStatus::HandlerError,
            "format_mismatch" => ReplyStatus::FormatMismatch,
            "present" => ReplyStatus::Present,
            other => panic!("reply status `{other}`"),
        };
        let fp = fingerprint(&v["fingerprint"]);
        let bytes = hex(text(v, "hex"));
        assert_eq!(attachment::reply(status, fp), bytes, "{v}");
        assert_eq!(parse_reply(&bytes), Some((status, fp)), "{v}");
    }
    for v in list("reply_rejected") {
        assert_eq!(parse_reply(&hex(v.as_str().unwrap())), None, "{v}");
    }
}

/// Every format of the file, the messages' included: its canonical text
/// reads back as itself (so a tool can decode from it), and hashes to
/// the fingerprint written.
#[test]
fn every_golden_format_has_its_fingerprint() {
    let golden = golden();
    let formats = golden["fingerprints"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| (text(v, "canonical"), &v["fingerprint"]));
    let messages = golden["messages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| (text(v, "format"), &v["fingerprint"]));
    let mut no_payload = false;
    for (canonical, fp) in formats.chain(messages) {
        let fp = fingerprint(fp);
        if canonical == FormatSpec::EMPTY.canonical {
            assert_eq!(fp, FormatSpec::EMPTY.fingerprint);
            no_payload = true;
            continue;
        }
        let format =
            MessageFormat::from_canonical(canonical).unwrap_or_else(|e| panic!("{canonical}: {e}"));
        assert_eq!(format.canonical(), canonical);
        assert_eq!(
            format.fingerprint(),
            fp,
            "{canonical}: {:016x}",
            format.fingerprint()
        );
    }
    assert!(no_payload, "the file pins the format with no payload");
}

/// Whether a node takes a binding for a slot it declares (§8), as the
/// Python runtime judges it from the same vectors.
#[test]
fn golden_plans_fit_as_written() {
    let vectors = golden();
    let cases = vectors["plans"].as_array().expect("plans");
    assert!(cases.len() >= 20, "{} plan vectors", cases.len());
    for case in cases {
        let slot: peppy_schema::Dependency = serde_json::from_value(json!({
            "kind": "interface",
            "target": { "name": "cam", "tag": "v1" },
            "link_id": "s",
            "from_any": case["from_any"],
            "cardinality": case["cardinality"],
            "sha256": null,
        }))
        .unwrap_or_else(|e| panic!("{case}: {e}"));
        let plan: peppy_schema::SlotPlan = serde_json::from_value(json!({
            "link_id": "s",
            "kind": "interface",
            "target": { "name": "cam", "tag": "v1" },
            "binding": case["binding"],
            "filter": { "kind": "any" },
        }))
        .unwrap_or_else(|e| panic!("{case}: {e}"));
        let fits = peppy_schema::fit_plan(std::slice::from_ref(&slot), vec![plan]).is_ok();
        assert_eq!(Some(fits), case["fits"].as_bool(), "{case}");
    }
}

/// The datastore's requests encode, and a fresh store answers them, as the
/// golden steps say (the Python runtime's tests check the same steps).
#[test]
fn the_datastore_speaks_the_golden_steps() {
    use peppy_runtime::datastore::{golden_request, golden_steps, golden_store_request};

    let golden = golden();
    let steps = golden["datastore"].as_array().unwrap();
    let hex = |s: &str| -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    };
    let key = "calibration/wrist";
    let op = |op: &str, key: &str| golden_request(op, key).expect(op);
    let ours = [
        golden_store_request(key, br#"{"x":1}"#, "application/json", "arm_left"),
        op("get", key),
        op("list", ""),
        op("remove", key),
        op("get", key),
        op("remove", key),
    ];
    assert_eq!(steps.len(), ours.len());
    let requests: Vec<Vec<u8>> = steps
        .iter()
        .map(|s| hex(s["request"].as_str().unwrap()))
        .collect();
    assert_eq!(requests, ours);
    for (step, reply) in steps.iter().zip(golden_steps(&requests)) {
        assert_eq!(
            reply.unwrap(),
            hex(step["reply"].as_str().unwrap()),
            "{step}"
        );
    }
}

/// `PEPPY_SHUTDOWN_GRACE_SECS` as every reader takes it (the node, the
/// launcher, Python): one rule, the same windows.
#[test]
fn grace_windows_are_read_as_the_vectors_say() {
    let cases = golden()["grace"].as_array().expect("grace vectors").clone();
    assert!(cases.len() >= 8);
    for case in cases {
        let text = case["text"].as_str().expect("text");
        let got = peppy_schema::grace_window_text(text).ok();
        let want = case["secs"]
            .as_f64()
            .map(std::time::Duration::from_secs_f64);
        assert_eq!(got, want, "{case}");
    }
}

/// Which producers a slot's route filter lets through, the filter as the
/// plan writes it (§8), as the Python runtime judges it from the same
/// vectors; and the filters neither runtime reads.
#[test]
fn golden_route_filters_accept_as_written() {
    let golden = golden();
    let vectors = &golden["route_filters"];
    let cases = vectors["accepts"]
        .as_array()
        .expect("route_filters.accepts");
    assert!(cases.len() >= 12, "{} route filter vectors", cases.len());
    for case in cases {
        let filter: peppy_schema::RouteFilter = serde_json::from_value(case["filter"].clone())
            .unwrap_or_else(|e| panic!("{case}: {e}"));
        let accepts = filter.accepts(text(case, "instance"));
        assert_eq!(Some(accepts), case["accepts"].as_bool(), "{case}");
    }
    let rejected = vectors["rejected"]
        .as_array()
        .expect("route_filters.rejected");
    assert!(rejected.len() >= 5, "{} rejected filters", rejected.len());
    for bad in rejected {
        assert!(
            serde_json::from_value::<peppy_schema::RouteFilter>(bad.clone()).is_err(),
            "{bad} was read"
        );
    }
}

/// The server a request through a slot goes to without probing (`null`:
/// it probes), as the Python runtime's `target.named_server` says from the
/// same vectors.
#[test]
fn golden_named_servers_are_as_written() {
    let golden = golden();
    let cases = golden["named_servers"].as_array().expect("named_servers");
    assert!(cases.len() >= 10, "{} named-server vectors", cases.len());
    for case in cases {
        let plan: peppy_schema::SlotPlan = serde_json::from_value(json!({
            "link_id": "s",
            "kind": "interface",
            "target": { "name": "cam", "tag": "v1" },
            "binding": case["binding"],
            "filter": case["filter"],
        }))
        .unwrap_or_else(|e| panic!("{case}: {e}"));
        assert_eq!(plan.named_server(), case["server"].as_str(), "{case}");
    }
}

/// The description an instance answers on its describe key (§9): built
/// from the vector's inputs as `NodeRunner::describe` and the node's
/// consumed routes build it, written byte for byte as the Python runtime
/// writes it, read back, and trusted by `InstanceInfo::check`.
#[test]
fn golden_descriptions_are_built_as_written() {
    use peppy_runtime::describe::{
        ConsumedTopic, DESCRIBE_VERSION, EmittedTopic, FormatInfo, InstanceInfo, OwnerInfo,
        ServedAction, ServedService, SlotInfo,
    };
    use peppy_schema::{Identity, QosProfile, RouteFilter, SlotKind, SlotPlan};

    let golden = golden();
    let vectors = golden["describe"].as_array().expect("describe");
    assert!(vectors.len() >= 2, "{} description vectors", vectors.len());
    for v in vectors {
        let about = text(v, "about");
        let (ns, core, instance) = (text(v, "namespace"), text(v, "core"), text(v, "instance"));
        let node: Identity = serde_json::from_value(v["node"].clone()).expect("node");
        let plans: Vec<SlotPlan> =
            serde_json::from_value(v["slots"].clone()).unwrap_or_else(|e| panic!("{about}: {e}"));
        let list = |name: &str| {
            v[name]
                .as_array()
                .unwrap_or_else(|| panic!("`{name}` of {about}"))
        };
        // An entry's owner: the node's own, anyone's (`None`), or a node's
        // or an interface's.
        let owner_of = |o: &Value| -> Option<OwnerInfo> {
            let kind = match text(o, "kind") {
                "own" => {
                    return Some(OwnerInfo {
                        kind: SlotKind::Node,
                        name: node.name.clone(),
                        tag: node.tag.clone(),
                    });
                }
                "any" => return None,
                "node" => SlotKind::Node,
                "interface" => SlotKind::Interface,
                other => panic!("owner kind `{other}`"),
            };
            Some(OwnerInfo {
                kind,
                name: text(o, "name").into(),
                tag: text(o, "tag").into(),
            })
        };
        let served =
            |o: &Value| owner_of(o).unwrap_or_else(|| panic!("a served entry has an owner: {o}"));
        let format_info = |f: &Value| FormatInfo {
            canonical: text(f, "canonical").into(),
            fingerprint: fingerprint(&f["fingerprint"]),
        };
        let qos = |q: &Value| -> QosProfile {
            serde_json::from_value(q.clone()).unwrap_or_else(|e| panic!("qos {q}: {e}"))
        };
        let key = |channel: Channel, o: &OwnerInfo, name: &str| -> String {
            keys::entry_key(ns, channel, &o.as_owner(), name, core, instance)
        };

        let emits: Vec<EmittedTopic> = list("emits")
            .iter()
            .map(|t| {
                let owner = served(&t["owner"]);
                EmittedTopic {
                    key: key(Channel::Topic, &owner, text(t, "name")),
                    owner,
                    name: text(t, "name").into(),
                    qos: qos(&t["qos"]),
                    format: format_info(&t["format"]),
                }
            })
            .collect();
        let consumes: Vec<ConsumedTopic> = list("consumes")
            .iter()
            .map(|c| {
                let slot = c["slot"].as_str().map(|link| {
                    plans
                        .iter()
                        .find(|p| p.link_id == link)
                        .unwrap_or_else(|| panic!("no slot `{link}` in {about}"))
                });
                let owner = owner_of(&c["owner"]);
                // The slot's filter (any for an external topic); a pinned
                // slot subscribes to its producer only.
                let filter = slot.map_or(RouteFilter::Any, |p| p.filter.clone());
                let pinned = match &filter {
                    RouteFilter::Pin(p) => Some(p.as_str()),
                    _ => None,
                };
                let resolved = owner.as_ref().map(OwnerInfo::as_owner);
                let selector = keys::entry_selector(
                    ns,
                    Channel::Topic,
                    resolved.as_ref(),
                    text(c, "name"),
                    None,
                    pinned,
                );
                // A node slot read on an interface's key keeps its node's
                // instances only.
                let members_of = match (slot, &owner) {
                    (Some(p), Some(o))
                        if p.kind == SlotKind::Node && o.kind == SlotKind::Interface =>
                    {
                        Some(p.target.clone())
                    }
                    _ => None,
                };
                ConsumedTopic {
                    slot: slot.map(|p| p.link_id.clone()),
                    owner,
                    name: text(c, "name").into(),
                    qos: qos(&c["qos"]),
                    format: format_info(&c["format"]),
                    selector,
                    filter,
                    members_of,
                }
            })
            .collect();
        let services: Vec<ServedService> = list("services")
            .iter()
            .map(|s| {
                let owner = served(&s["owner"]);
                ServedService {
                    key: key(Channel::Service, &owner, text(s, "name")),
                    owner,
                    name: text(s, "name").into(),
                    request: format_info(&s["request"]),
                    response: format_info(&s["response"]),
                }
            })
            .collect();
        let actions: Vec<ServedAction> = list("actions")
            .iter()
            .map(|a| {
                let owner = served(&a["owner"]);
                ServedAction {
                    key: key(Channel::Action, &owner, text(a, "name")),
                    owner,
                    name: text(a, "name").into(),
                    goal: format_info(&a["goal"]),
                    feedback: format_info(&a["feedback"]),
                    result: format_info(&a["result"]),
                }
            })
            .collect();
        let info = InstanceInfo {
            version: DESCRIBE_VERSION,
            instance_id: instance.into(),
            core_node: core.into(),
            namespace: ns.into(),
            node: node.clone(),
            pid: v["pid"]
                .as_u64()
                .and_then(|p| u32::try_from(p).ok())
                .expect("pid"),
            started_at_ms: v["started_at_ms"].as_u64().expect("started_at_ms"),
            slots: plans
                .iter()
                .map(|p| SlotInfo {
                    link_id: p.link_id.clone(),
                    kind: p.kind,
                    target: p.target.clone(),
                    binding: p.binding.clone(),
                    filter: p.filter.clone(),
                })
                .collect(),
            emits,
            consumes,
            services,
            actions,
            pairings: Vec::new(),
        };
        let written = text(v, "json");
        assert_eq!(info.to_json(), written, "{about}");
        assert_eq!(
            InstanceInfo::from_json(written.as_bytes()).unwrap_or_else(|e| panic!("{about}: {e}")),
            info,
            "{about}"
        );
        assert_eq!(
            info.check(ns, &keys::describe_key(ns, core, instance)),
            Ok(()),
            "{about}"
        );
    }
}

/// A core node's `info` answer, read as the Python runtime's
/// `info_from_body` reads it (`null`: refused); a `written` one is the
/// text this runtime's core node writes for those fields.
#[test]
fn golden_info_answers_are_read_as_written() {
    use peppy_runtime::info::InfoResponse;

    let golden = golden();
    let vectors = golden["info"].as_array().expect("info");
    assert!(vectors.len() >= 5, "{} info vectors", vectors.len());
    for v in vectors {
        let about = text(v, "about");
        let body = text(v, "json");
        let read = serde_json::from_str::<InfoResponse>(body).ok();
        let fields = read
            .as_ref()
            .map(|r| serde_json::to_value(r).expect("an info answer serializes"));
        assert_eq!(fields.unwrap_or(Value::Null), v["reads"], "{about}");
        if v["written"].as_bool() == Some(true) {
            let read = read.as_ref().unwrap_or_else(|| panic!("{about}: not read"));
            assert_eq!(
                serde_json::to_string(read).expect("an info answer serializes"),
                body,
                "{about}"
            );
        }
    }
}
