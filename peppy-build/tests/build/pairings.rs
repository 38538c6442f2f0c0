//! The Python package of nodes with pairing slots (docs/PAIRINGS.md §4):
//! `paired_topics.<link_id>.<topic>` modules in PeppyOS's shapes, the
//! descriptor's pairing slots and topics, and the test surfaces' pairing
//! peers and observed sources.

use std::collections::BTreeMap;
use std::path::Path;

const ARM_LINK: &str = r#"{
  peppy_schema: "pairing/v1",
  manifest: { name: "arm_link", tag: "v1" },
  roles: ["commander", "arm"],
  topics: [
    { emitted_by: "commander", name: "setpoint", message_format: { position: "f64" } },
    { emitted_by: "arm", name: "state", qos_profile: "sensor_data", message_format: { position: "f64", joint: { name: "string" } } },
    { emitted_by: "arm", name: "fault", message_format: { code: "u16" } },
  ],
}
"#;

/// An arm (participant, role `arm`) that also watches other arms.
const ARM: &str = r#"{
  peppy_schema: "node/v1",
  manifest: {
    name: "arm", tag: "v1",
    depends_on: {
      pairings: [{ name: "arm_link", tag: "v1", role: "arm", link_id: "commander" }],
      pairing_observers: [{ name: "arm_link", tag: "v1", role: "arm", link_id: "others", cardinality: "zero_or_more" }],
    },
  },
  interfaces: {
    topics: {
      emits: [{ link_id: "commander", name: "state" }, { link_id: "commander", name: "fault" }],
      consumes: [{ link_id: "commander", name: "setpoint" }, { link_id: "others", name: "state" }],
    },
  },
  execution: { language: "python", run_cmd: ["python", "-m", "arm"] },
}
"#;

/// A commander whose one arm is optional, watching one arm through `watched`.
const COMMANDER: &str = r#"{
  peppy_schema: "node/v1",
  manifest: {
    name: "commander", tag: "v1",
    depends_on: {
      pairings: [{ name: "arm_link", tag: "v1", role: "commander", link_id: "arm", optional: true }],
      pairing_observers: [{ name: "arm_link", tag: "v1", role: "arm", link_id: "watched" }],
    },
  },
  interfaces: {
    topics: {
      emits: [{ link_id: "arm", name: "setpoint" }],
      consumes: [{ link_id: "watched", name: "fault" }],
    },
  },
  execution: { language: "python", run_cmd: ["python", "-m", "commander"] },
}
"#;

/// The Python package of `doc`, generated against a repository holding
/// the pairing: path -> text.
fn package_of(doc: &str) -> BTreeMap<String, String> {
    let dir = tempfile::tempdir().unwrap();
    let root = std::fs::canonicalize(dir.path()).unwrap();
    write(&root.join("repo/pairings/arm_link.json5"), ARM_LINK);
    write(&root.join("node/peppy.json5"), doc);
    let mut c = peppy_build::Config::new();
    c.manifest_dir(root.join("node"))
        .repositories_env(None)
        .repository(root.join("repo"));
    let generated = c.generate().unwrap_or_else(|e| panic!("{e}"));
    let files =
        peppy_build::python_package(&generated.check.resolved).unwrap_or_else(|d| panic!("{d}"));
    files
        .into_iter()
        .map(|(p, text)| (p.display().to_string(), text))
        .collect()
}

fn write(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

fn has_all(text: &str, needles: &[&str]) {
    for n in needles {
        assert!(text.contains(n), "missing `{n}` in:\n{text}");
    }
}

#[test]
fn a_participant_sends_its_role_topics_and_receives_its_peers() {
    let files = package_of(ARM);
    for path in [
        "paired_topics/__init__.py",
        "paired_topics/commander/__init__.py",
        "paired_topics/commander/state.py",
        "paired_topics/commander/fault.py",
        "paired_topics/commander/setpoint.py",
        "paired_topics/others/state.py",
        "mock/pairings/commander.py",
        "mock/observed/others.py",
    ] {
        assert!(files.contains_key(path), "no {path} in {:?}", files.keys());
    }
    // Pairing topics are none of the node's own topics.
    let entries = |category: &str| -> Vec<&String> {
        files
            .keys()
            .filter(|p| p.starts_with(category) && !p.ends_with("__init__.py"))
            .collect()
    };
    assert!(
        entries("emitted_topics/").is_empty(),
        "{:?}",
        entries("emitted_topics/")
    );
    assert!(
        entries("consumed_topics/").is_empty(),
        "{:?}",
        entries("consumed_topics/")
    );

    let state = &files["paired_topics/commander/state.py"];
    has_all(
        state,
        &[
            "TOPIC_NAME = \"state\"",
            "LINK_ID = \"commander\"",
            "PAIRING_NAME = \"arm_link\"",
            "PAIRING_TAG = \"v1\"",
            "QOS = QoSProfile.SENSOR_DATA",
            "class MessageJoint:",
            "SPEC = _s.PairingTopicSpec(LINK_ID, PAIRING_NAME, PAIRING_TAG, TOPIC_NAME, QOS, _c.Format(Message, \"{position:f64,joint:{name:string}}\"",
            ", True)",
            "def paired(node_runner: NodeRunner) -> Optional[PeerInfo]:",
            "async def wait_paired(node_runner: NodeRunner) -> PeerInfo:",
            "def build_message(position: float, joint: MessageJoint) -> bytes:",
            "async def declare_publisher(node_runner: NodeRunner) -> _pairing.PairedPublisher:",
        ],
    );
    assert!(!state.contains("def subscribe("), "{state}");

    let setpoint = &files["paired_topics/commander/setpoint.py"];
    has_all(
        setpoint,
        &[
            ", False)",
            "async def next(self) -> Optional[Tuple[PeerInfo, Message]]:",
            "async def subscribe(node_runner: NodeRunner) -> Subscription:",
            "async def wait_paired(",
        ],
    );
    assert!(!setpoint.contains("def build_message("), "{setpoint}");

    let observed = &files["paired_topics/others/state.py"];
    has_all(
        observed,
        &[
            "LINK_ID = \"others\"",
            "def sources(node_runner: NodeRunner) -> List[ObservedSource]:",
            "async def next(self) -> Optional[Tuple[ObservedSource, Message]]:",
        ],
    );
    for absent in ["def source(", "def paired(", "def build_message("] {
        assert!(!observed.contains(absent), "{absent} in:\n{observed}");
    }

    let init = &files["__init__.py"];
    has_all(
        init,
        &[
            "pairings=(_s.PairingSlotSpec(\"commander\", \"arm_link\", \"v1\", \"arm\", \"commander\", False, False, \"one\"), _s.PairingSlotSpec(\"others\", \"arm_link\", \"v1\", \"arm\", \"commander\", True, False, \"zero_or_more\"),),",
            "pairing_topics=(_paired_topics__commander__state, _paired_topics__commander__fault, _paired_topics__commander__setpoint, _paired_topics__others__state,),",
        ],
    );

    let peer = &files["mock/pairings/commander.py"];
    has_all(
        peer,
        &[
            "class Mock(_testing.PairingMock):",
            "state: _testing.PeerTap[_state.Message]",
            "setpoint: _testing.PeerTopicMock[_setpoint.Message]",
            "from ...paired_topics.commander import state as _state",
        ],
    );
    has_all(
        &files["mock/observed/others.py"],
        &[
            "class Mock(_testing.ObservedMock):",
            "state: _testing.PeerTopicMock[_state.Message]",
        ],
    );
    has_all(
        &files["fixtures/harness.py"],
        &[
            "from ..mock.pairings import commander as _mock_pairings_commander",
            "from ..mock.observed import others as _mock_observed_others",
            "\"commander\": _mock_pairings_commander.Mock",
            "\"others\": _mock_observed_others.Mock",
        ],
    );
}

#[test]
fn an_observer_of_one_source_has_source_and_an_optional_peer_may_start_unpaired() {
    let files = package_of(COMMANDER);
    let fault = &files["paired_topics/watched/fault.py"];
    has_all(
        fault,
        &["def source(node_runner: NodeRunner) -> ObservedSource:"],
    );
    assert!(!fault.contains("def sources("), "{fault}");
    has_all(
        &files["mock/pairings/arm.py"],
        &[
            "; with `<link_id>_vacant=True` it runs unpaired",
            "setpoint: _testing.PeerTap[_setpoint.Message]",
        ],
    );
    // The commander receives nothing from its arm: only what it sends.
    assert!(!files.contains_key("paired_topics/arm/state.py"));
}

/// The whole package of the arm, for review.
#[test]
fn python_package_with_pairings() {
    let files = package_of(ARM);
    let mut text = String::new();
    for (path, body) in files.iter().filter(|(p, _)| {
        p.starts_with("paired_topics/")
            || p.starts_with("mock/pairings")
            || p.starts_with("mock/observed")
            || *p == "__init__.py"
    }) {
        text.push_str(&format!("=== {path} ===\n{body}\n"));
    }
    insta::assert_snapshot!(text);
}
