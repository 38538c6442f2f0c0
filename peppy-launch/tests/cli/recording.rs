//! `record` and `replay` on real stacks: the multi-camera example recorded
//! into an MCAP file that the official `mcap` Python package reads and
//! checks against each message's schema and the cameras' own frames; the
//! file replayed into a reconstruction running alone, which sees what it
//! saw live; a recorder killed with SIGKILL; and files replay refuses.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::machines::free_port;
use crate::seeds::{BUILD_AND_START, Launch};
use crate::support::{Run, peppy_launch_with, root, wait_bounded};

/// Reads a recording with the `mcap` package (and checks every message
/// against its channel's JSON Schema with `jsonschema`), recomputes each
/// camera's frame from its frame id as the example drivers draw it, and
/// prints per channel: messages, first and last frame id, and whether the
/// frame ids run without a gap.
const CHECK_PY: &str = r#"
import base64, json, sys
import jsonschema
from mcap.reader import make_reader

def drawn(node, w, h, t):
    if node.startswith("realsense_d405"):
        return bytes((x + y + t) % 256 for y in range(h) for x in range(w))
    return b"".join(bytes([((y + t) // 4 * 16) % 256]) * w for y in range(h))

channels = {}
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f)
    assert reader.get_header().profile == "peppy"
    summary = reader.get_summary()
    assert summary is not None, "no summary"
    for schema, channel, message in reader.iter_messages():
        assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
        value = json.loads(message.data)
        jsonschema.validate(value, json.loads(schema.data))
        node = channel.metadata["peppy.node"]
        frame = base64.b64decode(value["frame"])
        t = value["header"]["frame_id"]
        assert frame == drawn(node, value["width"], value["height"], t), (channel.topic, t)
        channels.setdefault(channel.topic, []).append(t)
    counts = summary.statistics.channel_message_counts
for topic, ids in sorted(channels.items()):
    gapless = ids == list(range(ids[0], ids[0] + len(ids)))
    print(json.dumps({"topic": topic, "messages": len(ids), "first": ids[0], "last": ids[-1], "gapless": gapless}))
print(json.dumps({"summary": sum(counts.values())}))
"#;

fn uv() -> std::path::PathBuf {
    peppy_launch::uv().expect("uv")
}

/// Runs `command` (bounded by `bound`), which must succeed, and reads its
/// stdout as one JSON value per line.
fn json_lines_of(mut command: Command, bound: Duration, what: &str) -> Vec<serde_json::Value> {
    let child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    let out = wait_bounded(child, bound, what);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{what}: {stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect()
}

/// A bare Zenoh peer listening on `endpoint`: a stand-in for a stack that
/// replay publishes into or a recorder reads, on a runtime of its own.
pub(crate) fn bare_stack(endpoint: &str) -> (tokio::runtime::Runtime, zenoh::Session) {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let session = rt.block_on(async {
        let mut config = zenoh::Config::default();
        config
            .insert_json5("listen/endpoints", &format!(r#"["{endpoint}"]"#))
            .unwrap();
        config
            .insert_json5("scouting/multicast/enabled", "false")
            .unwrap();
        zenoh::open(config).await.unwrap()
    });
    (rt, session)
}

/// Runs [`CHECK_PY`] on `file`: one JSON value per line.
fn check_with_mcap_package(file: &Path) -> Vec<serde_json::Value> {
    let script = file.with_extension("py");
    std::fs::write(&script, CHECK_PY).unwrap();
    let mut check = Command::new(uv());
    check
        .args(["run", "--quiet", "--no-project", "--with", "mcap==1.6.0"])
        .args(["--with", "jsonschema==4.26.0", "python"])
        .arg(&script)
        .arg(file);
    json_lines_of(check, Duration::from_secs(300), "the mcap package's check")
}

/// The channel of every message a recording without a summary holds up to
/// its last whole record, read as the `mcap` package's stream reader reads
/// a file being recovered.
fn read_killed_recording(file: &Path) -> Vec<String> {
    let script = r#"
import json, sys
from mcap.stream_reader import StreamReader
from mcap.records import Channel, Message, Footer
channels, footer = {}, False
try:
    for record in StreamReader(open(sys.argv[1], "rb"), skip_magic=False).records:
        if isinstance(record, Channel):
            channels[record.id] = record.topic
        elif isinstance(record, Message):
            print(json.dumps(channels[record.channel_id]))
        elif isinstance(record, Footer):
            footer = True
except Exception as e:
    print(f"stopped: {type(e).__name__}", file=sys.stderr)
assert not footer, "a killed recorder wrote no footer"
"#;
    let mut read = Command::new(uv());
    read.args(["run", "--quiet", "--no-project", "--with", "mcap==1.6.0"])
        .args(["python", "-c", script])
        .arg(file);
    json_lines_of(read, Duration::from_secs(300), "the mcap stream reader")
        .into_iter()
        .map(|topic| topic.as_str().unwrap_or_default().to_string())
        .collect()
}

/// Serves the stack of `namespace` with `view` and reads it with Foxglove's
/// own WebSocket client ([`read_with_foxglove`]).
fn foxglove_client(
    state: &Path,
    namespace: &str,
    wanted: (u32, u32),
    suffix: &str,
    calls: u32,
) -> Vec<serde_json::Value> {
    let Some(client) = foxglove_client_dir(state) else {
        return Vec::new();
    };
    let port = free_port();
    let port_arg = port.to_string();
    let mut view = Launch::start(
        &[],
        &[
            "view",
            "--namespace",
            namespace,
            "--port",
            &port_arg,
            "--wait",
            "10",
        ],
        &[("PEPPY_STATE_DIR", state)],
    );
    view.expect("the view serving", Duration::from_secs(60), |l| {
        l.starts_with("serving ")
    });
    let seen = read_with_foxglove(&client, port, wanted, suffix, calls);
    assert_eq!(view.stop(), 0, "the view stops cleanly on Ctrl-C");
    seen
}

/// Foxglove's own WebSocket protocol client (npm's
/// `@foxglove/ws-protocol`), installed under `state`; `None` where Node.js
/// cannot be had (outside CI only).
fn foxglove_client_dir(state: &Path) -> Option<std::path::PathBuf> {
    crate::support::debian_tool("node", "nodejs")?;
    let npm = crate::support::debian_tool("npm", "npm")?;
    let client = state.join("foxglove_client");
    std::fs::create_dir_all(&client).unwrap();
    let fixture = root().join("peppy-launch/tests/fixtures/foxglove_client");
    for file in ["package.json", "client.js"] {
        std::fs::copy(fixture.join(file), client.join(file)).unwrap();
    }
    let install = Command::new(&npm)
        .args(["install", "--no-audit", "--no-fund", "--loglevel", "error"])
        .current_dir(&client)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let installed = wait_bounded(install, Duration::from_secs(300), "npm install");
    assert!(
        installed.status.success(),
        "{}",
        String::from_utf8_lossy(&installed.stderr)
    );
    Some(client)
}

/// Reads the view on `port` with the client in `client`: `per_channel`
/// messages of each of (at least) `channels` channels, and `calls` calls of
/// services whose name ends with `suffix`. One JSON value per channel and
/// call.
fn read_with_foxglove(
    client: &Path,
    port: u16,
    (channels, per_channel): (u32, u32),
    suffix: &str,
    calls: u32,
) -> Vec<serde_json::Value> {
    let node = crate::support::debian_tool("node", "nodejs").unwrap();
    let mut client_run = Command::new(node);
    client_run
        .arg("client.js")
        .arg(format!("ws://127.0.0.1:{port}"))
        .args([
            &per_channel.to_string(),
            suffix,
            &calls.to_string(),
            &channels.to_string(),
            "60",
        ])
        // The subprotocol the Foxglove SDK's server speaks (the protocol
        // of `foxglove.websocket.v1`, renamed).
        .arg("foxglove.sdk.v1")
        .current_dir(client);
    json_lines_of(client_run, Duration::from_secs(120), "the Foxglove client")
}

/// The client's report of channel `topic`, with at least one message.
fn channel<'a>(seen: &'a [serde_json::Value], topic: &str) -> &'a serde_json::Value {
    let found = seen
        .iter()
        .find(|v| v["topic"] == topic)
        .unwrap_or_else(|| panic!("no channel {topic}: {seen:#?}"));
    assert!(
        !found["messages"].as_array().unwrap().is_empty(),
        "no message on {topic}: {found}"
    );
    found
}

fn launch(state: &Path, args: &[&str]) -> Run {
    peppy_launch_with(&root(), args, &[("PEPPY_STATE_DIR", state)])
}

/// The last `reconstructing from ...` counts of a reconstruction's output:
/// frames per `slot<-producer`.
fn reconstructed(lines: &[String]) -> BTreeMap<String, u64> {
    let last = lines
        .iter()
        .rev()
        .find_map(|l| l.split_once("reconstructing from "))
        .map(|(_, counts)| counts.to_string())
        .unwrap_or_default();
    last.split_whitespace()
        .filter_map(|c| c.rsplit_once(':'))
        .map(|(slot, n)| (slot.to_string(), n.parse().unwrap()))
        .collect()
}

/// Five seconds of the multi-camera stack: every frame the file holds is
/// the frame its camera drew, no frame id is missing, and replayed into a
/// reconstruction running alone, each slot receives exactly what was
/// recorded from its camera.
#[test]
fn a_recorded_stack_replays_into_its_consumer() {
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let file = st.join("cameras.mcap");
    let file_arg = file.to_str().unwrap();
    let mut stack = Launch::up_with(
        "examples/launchers/multi_camera.json5",
        &["--namespace", "record-multi-camera"],
        &[("PEPPY_STATE_DIR", st)],
    );
    stack.expect("with recon_1's summary", BUILD_AND_START, |l| {
        l.starts_with("[recon_1]") && l.contains("reconstructing from")
    });
    let recorded = launch(
        st,
        &["record", "-o", file_arg, "--duration", "5", "--wait", "10"],
    );
    assert_eq!(recorded.code, 0, "{}", recorded.stderr);
    assert!(
        recorded.stderr.contains("on 3 channels"),
        "{}",
        recorded.stderr
    );
    // A recorder killed outright leaves the chunks it closed readable
    // (one a second at least): only rs_left, by pattern.
    let killed = st.join("killed.mcap");
    let mut recorder = crate::support::peppy_launch_command(&[])
        .args(["record", "rs_left/*", "-o", killed.to_str().unwrap()])
        .env("PEPPY_STATE_DIR", st)
        .current_dir(root())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_secs(5));
    recorder.kill().unwrap();
    recorder.wait().unwrap();
    let recovered = read_killed_recording(&killed);
    assert!(recovered.len() >= 15, "{recovered:?}");
    assert!(
        recovered.iter().all(|t| t == "/rs_left/video_stream"),
        "{recovered:?}"
    );
    // The same stack live in Foxglove's own client: every camera's topic
    // as JSON and as an image, every camera's service callable.
    let seen = foxglove_client(st, "record-multi-camera", (6, 3), "/video_stream_info", 3);
    // Without Node.js (outside CI only: debian_tool says so) nothing is seen.
    let cameras = if seen.is_empty() {
        Vec::new()
    } else {
        vec!["rs_left", "rs_right", "zed_overhead"]
    };
    for camera in cameras {
        let json = channel(&seen, &format!("/{camera}/video_stream"));
        assert_eq!(
            (json["encoding"].as_str(), json["schemaEncoding"].as_str()),
            (Some("json"), Some("jsonschema"))
        );
        let frame = &json["messages"][0];
        assert_eq!(frame["width"], 160, "{frame}");
        assert_eq!(frame["frame"]["len"], 160 * 120, "{frame}");
        assert!(
            frame["header"]["stamp"]["sec"].as_u64().unwrap() > 0,
            "{frame}"
        );
        let image = channel(&seen, &format!("/{camera}/video_stream/image"));
        assert_eq!(
            (image["encoding"].as_str(), image["schemaName"].as_str()),
            (Some("protobuf"), Some("foxglove.RawImage"))
        );
        let picture = &image["messages"][0];
        assert_eq!(
            (
                &picture["width"],
                &picture["height"],
                &picture["encoding"],
                &picture["step"]
            ),
            (
                &serde_json::json!(160),
                &serde_json::json!(120),
                &serde_json::json!("mono8"),
                &serde_json::json!(160)
            ),
            "{picture}"
        );
        assert_eq!(picture["data"]["len"], 160 * 120, "{picture}");
        let info = seen
            .iter()
            .find(|v| v["service"] == format!("/{camera}/video_stream_info"))
            .unwrap_or_else(|| panic!("no call of {camera}'s service: {seen:#?}"));
        let fps = if camera == "zed_overhead" { 10 } else { 15 };
        assert_eq!(info["response"]["frames_per_second"], fps, "{info}");
    }

    let again = launch(st, &["record", "-o", file_arg, "--duration", "1"]);
    assert_eq!(again.code, 2, "an existing file is kept: {}", again.stderr);
    assert!(again.stderr.contains("--force"), "{}", again.stderr);
    assert_eq!(stack.stop(), 0);

    let checked = check_with_mcap_package(&file);
    let channels: BTreeMap<String, u64> = checked
        .iter()
        .filter(|v| v.get("topic").is_some())
        .map(|v| {
            assert_eq!(v["gapless"], true, "a frame is missing: {v}");
            (
                v["topic"].as_str().unwrap().to_string(),
                v["messages"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        channels.keys().collect::<Vec<_>>(),
        [
            "/rs_left/video_stream",
            "/rs_right/video_stream",
            "/zed_overhead/video_stream"
        ]
    );
    assert!(channels.values().all(|n| *n >= 30), "{channels:?}");
    let total: u64 = channels.values().sum();
    assert_eq!(checked.last().unwrap()["summary"], total);

    // The reconstruction alone, its slots bound to the recorded cameras.
    let port = free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let mut recon = Launch::start(
        &[],
        &[
            "run",
            "examples/nodes/video_reconstruction",
            "--instance-id",
            "recon_1",
            "--bind",
            "left_cam@rs_left,right_cam@rs_right",
            "--namespace",
            "replay-multi-camera",
            "--listen",
            &endpoint,
        ],
        &[("PEPPY_STATE_DIR", st)],
    );
    recon.expect("the node up", BUILD_AND_START, |l| l.contains("node up"));
    let narrow = st.join("narrow.mcap");
    write_recording(&narrow, "{width:u32}", &[r#"{"width":160}"#]);
    let refused = launch(
        st,
        &[
            "replay",
            narrow.to_str().unwrap(),
            "--connect",
            &endpoint,
            "--namespace",
            "replay-multi-camera",
            "--wait",
            "10",
        ],
    );
    assert_eq!(refused.code, 2, "{}", refused.stderr);
    assert!(
        refused
            .stderr
            .contains("recon_1.left_cam reads `video_stream` as {header:"),
        "{}",
        refused.stderr
    );
    let replayed = launch(
        st,
        &[
            "replay",
            file_arg,
            "--connect",
            &endpoint,
            "--namespace",
            "replay-multi-camera",
            "--wait",
            "10",
        ],
    );
    assert_eq!(replayed.code, 0, "{}", replayed.stderr);
    assert!(
        replayed
            .stderr
            .contains(&format!("replayed {total} messages")),
        "{}",
        replayed.stderr
    );
    // The node prints its counts once a second.
    recon.read_for(Duration::from_secs(3));
    let (_, seen) = recon.stop_seen();
    let counts = reconstructed(&seen);
    assert_eq!(
        counts,
        BTreeMap::from([
            (
                "backup_cams<-zed_overhead".to_string(),
                channels["/zed_overhead/video_stream"]
            ),
            (
                "left_cam<-rs_left".to_string(),
                channels["/rs_left/video_stream"]
            ),
            (
                "right_cam<-rs_right".to_string(),
                channels["/rs_right/video_stream"]
            ),
        ]),
        "{seen:#?}"
    );
}

/// A recording as `record` writes one: `rs_left`'s `video_stream` in
/// `format`, one message per JSON text, a millisecond apart.
fn write_recording(path: &Path, format: &str, messages: &[&str]) {
    write_recording_in_chunks(path, format, messages, 1 << 20);
}

/// [`write_recording`], starting a new chunk once one holds `chunk_size`
/// bytes.
fn write_recording_in_chunks(path: &Path, format: &str, messages: &[&str], chunk_size: u64) {
    let fingerprint = peppy_schema::MessageFormat::from_canonical(format)
        .unwrap()
        .fingerprint();
    // Plain and without checksums, so a test can forge its bytes.
    let mut out = mcap::WriteOptions::new()
        .profile("peppy")
        .compression(None)
        .calculate_chunk_crcs(false)
        .calculate_data_section_crc(false)
        .calculate_summary_section_crc(false)
        .chunk_size(Some(chunk_size))
        .create(std::io::BufWriter::new(
            std::fs::File::create(path).unwrap(),
        ))
        .unwrap();
    let schema = out.add_schema("video_stream", "jsonschema", b"{}").unwrap();
    let metadata = BTreeMap::from(
        [
            ("peppy.topic", "video_stream".to_string()),
            ("peppy.owner", "interface/depth_camera:v1".into()),
            ("peppy.core", "core".into()),
            ("peppy.instance", "rs_left".into()),
            ("peppy.format", format.into()),
            ("peppy.fingerprint", format!("{fingerprint:016x}")),
        ]
        .map(|(k, v)| (k.to_string(), v)),
    );
    let channel = out
        .add_channel(schema, "/rs_left/video_stream", "json", &metadata)
        .unwrap();
    for (i, m) in messages.iter().enumerate() {
        let t = 1_000_000_000 + i as u64 * 1_000_000;
        out.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channel,
                sequence: i as u32,
                log_time: t,
                publish_time: t,
            },
            m.as_bytes(),
        )
        .unwrap();
    }
    out.finish().unwrap();
}

/// Files replay cannot replay are refused before anything is published,
/// each with its reason: not MCAP, another encoding, metadata that is not
/// peppy's, a format that is not its fingerprint, nothing in the window,
/// and a file cut before its first message.
#[test]
fn replay_refuses_files_it_cannot_replay() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let replay = |file: &Path, extra: &[&str]| {
        let mut args = vec!["replay", file.to_str().unwrap()];
        args.extend_from_slice(extra);
        // No stack is reached: every refusal comes first.
        args.extend(["--connect", "tcp/127.0.0.1:9", "--wait", "1"]);
        launch(d, &args)
    };
    let refused = |file: &Path, extra: &[&str], says: &str| {
        let run = replay(file, extra);
        assert_eq!(run.code, 2, "{says}: {}", run.stderr);
        assert!(run.stderr.contains(says), "{says}: {}", run.stderr);
        assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    };

    let text = d.join("notes.mcap");
    std::fs::write(&text, "not a recording").unwrap();
    refused(&text, &[], "is not an MCAP file");
    refused(&d.join("missing.mcap"), &[], "cannot read");

    let cdr = d.join("cdr.mcap");
    {
        let mut out = mcap::Writer::new(std::io::BufWriter::new(
            std::fs::File::create(&cdr).unwrap(),
        ))
        .unwrap();
        let schema = out.add_schema("Image", "ros2msg", b"uint32 width").unwrap();
        let channel = out
            .add_channel(schema, "/camera", "cdr", &BTreeMap::new())
            .unwrap();
        out.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channel,
                sequence: 0,
                log_time: 1,
                publish_time: 1,
            },
            &[0, 1, 0, 0, 160, 0, 0, 0],
        )
        .unwrap();
        out.finish().unwrap();
    }
    refused(&cdr, &[], "channel `/camera` is encoded as `cdr`");

    let good = d.join("good.mcap");
    write_recording(&good, "{width:u32}", &[r#"{"width":1}"#, r#"{"width":2}"#]);
    let bytes = std::fs::read(&good).unwrap();
    let forged = d.join("forged.mcap");
    let text = String::from_utf8_lossy(&bytes).into_owned();
    assert!(text.contains("{width:u32}"));
    // Same length, another format: the fingerprint no longer matches.
    std::fs::write(
        &forged,
        replace_bytes(&bytes, b"{width:u32}", b"{width:u16}"),
    )
    .unwrap();
    refused(&forged, &[], "its format's fingerprint is");
    let unowned = d.join("unowned.mcap");
    std::fs::write(
        &unowned,
        replace_bytes(
            &bytes,
            b"interface/depth_camera:v1",
            b"interface/depth_camera/v1",
        ),
    )
    .unwrap();
    refused(
        &unowned,
        &[],
        "`peppy.owner` is `interface/depth_camera/v1`",
    );
    refused(
        &good,
        &["--start", "5"],
        "holds no message to replay in the chosen window",
    );
    refused(
        &good,
        &["no_such_topic"],
        "holds no message to replay in the chosen window",
    );
    refused(&good, &["--as", "rs_left"], "expected OLD=NEW");
    refused(&good, &["--rate", "0"], "--rate 0 is out of range");

    // A recorder that cannot reach its stack leaves no empty file behind.
    let nowhere = d.join("nowhere.mcap");
    let run = launch(
        d,
        &[
            "record",
            "-o",
            nowhere.to_str().unwrap(),
            "--connect",
            "tcp/127.0.0.1:9",
            "--wait",
            "1",
        ],
    );
    assert_ne!(run.code, 0, "{}", run.stderr);
    assert!(run.stderr.contains("cannot reach"), "{}", run.stderr);
    assert!(!nowhere.exists());

    // Cut inside its first chunk: the magic is there, no message is.
    let cut = d.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 3]).unwrap();
    let run = replay(&cut, &[]);
    assert_ne!(run.code, 0, "{}", run.stderr);
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    assert!(run.stderr.contains("cut.mcap"), "{}", run.stderr);
}

/// Where `needle` first is in `haystack`.
fn find_bytes(haystack: &[u8], needle: &[u8]) -> usize {
    haystack
        .windows(needle.len())
        .position(|w| w == needle)
        .expect("the bytes are there")
}

fn replace_bytes(haystack: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
    assert_eq!(from.len(), to.len());
    let mut out = haystack.to_vec();
    let mut found = false;
    for i in 0..=out.len() - from.len() {
        if &out[i..i + from.len()] == from {
            out[i..i + from.len()].copy_from_slice(to);
            found = true;
        }
    }
    assert!(found);
    out
}

/// The arm loop under `up --view`, in Foxglove's client: fixed arrays,
/// times and an external topic decode with the schemas the view
/// advertises.
#[test]
fn the_arm_loop_in_foxglove() {
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let Some(client) = foxglove_client_dir(st) else {
        return;
    };
    let port = free_port().to_string();
    let mut stack = Launch::up_with(
        "examples/launchers/robot_arm_loop.json5",
        &["--namespace", "view-arm-loop", &format!("--view={port}")],
        &[("PEPPY_STATE_DIR", st)],
    );
    stack.expect("the controller cycling", BUILD_AND_START, |l| {
        l.starts_with("[controller]") && l.contains("cycle 20:")
    });
    stack.expect("the view serving", Duration::from_secs(60), |l| {
        l.starts_with("serving ") && l.contains(&format!("ws://127.0.0.1:{port}"))
    });
    let seen = read_with_foxglove(&client, port.parse().unwrap(), (2, 2), "-", 0);
    assert_eq!(stack.stop(), 0);
    let states = channel(&seen, "/arm/joint_states");
    let joints = &states["messages"][0];
    assert_eq!(joints["positions"].as_array().unwrap().len(), 3, "{joints}");
    assert!(
        joints["timestamp"]["nsec"].as_u64().unwrap() < 1_000_000_000,
        "{joints}"
    );
    let commands = channel(&seen, "/controller/joint_commands");
    let command = &commands["messages"][0];
    assert_eq!(
        command["target_positions"].as_array().unwrap().len(),
        3,
        "{command}"
    );
    assert!(command["max_velocity"].is_number(), "{command}");
    assert!(
        !seen
            .iter()
            .any(|v| v["topic"].as_str().is_some_and(|t| t.ends_with("/image"))),
        "no image in the arm loop: {seen:#?}"
    );
}

/// What replay puts on the wire, seen by a bare Zenoh session standing in
/// for a stack: each message under its producer's key (renamed by `--as`),
/// in the recorded format's bytes with its fingerprint attached, in order,
/// each after a sim tick of its recorded time (`--clock`); `--start` and
/// `--end` cut the window.
#[test]
fn replay_publishes_what_was_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let file = d.join("widths.mcap");
    let widths: Vec<String> = (1..=5).map(|w| format!(r#"{{"width":{w}}}"#)).collect();
    write_recording(
        &file,
        "{width:u32}",
        &widths.iter().map(String::as_str).collect::<Vec<_>>(),
    );
    let fingerprint = peppy_schema::MessageFormat::from_canonical("{width:u32}")
        .unwrap()
        .fingerprint();
    let port = free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let ns = "replay-wire";
    let (rt, session) = bare_stack(&endpoint);
    let everything = rt.block_on(async {
        session
            .declare_subscriber(format!("peppy/{ns}/**"))
            .await
            .unwrap()
    });
    let replay = |extra: &[&str]| {
        let mut args = vec![
            "replay",
            file.to_str().unwrap(),
            "--connect",
            &endpoint,
            "--namespace",
            ns,
            "--wait",
            "1",
        ];
        args.extend_from_slice(extra);
        let run = launch(d, &args);
        assert_eq!(run.code, 0, "{}", run.stderr);
        // Give the last samples time to arrive.
        std::thread::sleep(Duration::from_millis(300));
        everything
            .drain()
            .map(|s| {
                let key = s.key_expr().as_str().to_string();
                let attachment = s.attachment().map(|a| a.to_bytes().into_owned());
                (key, s.payload().to_bytes().into_owned(), attachment)
            })
            .collect::<Vec<_>>()
    };
    let key = peppy_runtime::wire::keys::entry_key(
        ns,
        peppy_runtime::wire::keys::Channel::Topic,
        &peppy_runtime::wire::keys::Owner::Interface {
            name: "depth_camera",
            tag: "v1",
        },
        "video_stream",
        "core",
        "cam_a",
    );
    let tick = format!("peppy/{ns}/clock/tick/sim");
    let attachment = Some(peppy_runtime::wire::attachment::topic(fingerprint));

    let seen = replay(&["--as", "rs_left=cam_a", "--clock"]);
    let mut expected = Vec::new();
    for w in 1..=5u32 {
        let t: u64 = 1_000_000_000 + u64::from(w - 1) * 1_000_000;
        expected.push((tick.clone(), t.to_le_bytes().to_vec(), None));
        expected.push((key.clone(), w.to_le_bytes().to_vec(), attachment.clone()));
    }
    assert_eq!(seen, expected);

    // A recording whose recorder was killed ends inside a chunk and has
    // no summary: what precedes its last chunk is replayed, with a note.
    let chunked = d.join("chunked.mcap");
    write_recording_in_chunks(
        &chunked,
        "{width:u32}",
        &widths.iter().map(String::as_str).collect::<Vec<_>>(),
        1,
    );
    let whole = std::fs::read(&chunked).unwrap();
    let killed = d.join("killed.mcap");
    // The fourth message's chunk starts after the third's: cut inside it.
    let fourth = find_bytes(&whole, br#"{"width":4}"#);
    std::fs::write(&killed, &whole[..fourth]).unwrap();
    let run = launch(
        d,
        &[
            "replay",
            killed.to_str().unwrap(),
            "--connect",
            &endpoint,
            "--namespace",
            ns,
            "--wait",
            "1",
        ],
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(run.stderr.contains("ends early"), "{}", run.stderr);
    std::thread::sleep(Duration::from_millis(300));
    let replayed: Vec<Vec<u8>> = everything
        .drain()
        .map(|s| s.payload().to_bytes().into_owned())
        .collect();
    assert_eq!(
        replayed,
        [1u32, 2, 3].map(|w| w.to_le_bytes().to_vec()),
        "{}",
        run.stderr
    );

    let seen = replay(&[
        "--as",
        "rs_left=cam_a",
        "--start",
        "0.002",
        "--end",
        "0.003",
    ]);
    let widths: Vec<Vec<u8>> = seen
        .iter()
        .map(|(k, payload, _)| {
            assert_eq!(k, &key);
            payload.clone()
        })
        .collect();
    assert_eq!(widths, [3u32.to_le_bytes(), 4u32.to_le_bytes()]);
    rt.block_on(async {
        drop(everything);
        session.close().await.unwrap();
    });
}

/// A producer that starts after the recording did is picked up, and one
/// that changes format mid-run gets a channel of its own with its new
/// schema: a bare Zenoh session plays the producer, answering its formats'
/// texts as a node does, and sends something with no format nobody
/// describes, which is skipped and counted.
#[test]
fn a_format_change_mid_run_gets_a_new_channel() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let file = d.join("changed.mcap");
    let port = free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let ns = "record-format-change";
    let formats = ["{width:u32}", "{width:u32,height:u32}"];
    let fingerprints: Vec<u64> = formats
        .iter()
        .map(|f| {
            peppy_schema::MessageFormat::from_canonical(f)
                .unwrap()
                .fingerprint()
        })
        .collect();
    let (rt, session) = bare_stack(&endpoint);
    let _answers = rt.block_on(async {
        let mut answers = Vec::new();
        for (format, fp) in formats.iter().zip(&fingerprints) {
            let text = format.to_string();
            answers.push(
                session
                    .declare_queryable(peppy_runtime::wire::keys::format_key(ns, *fp, "cam"))
                    .callback(move |q| {
                        let text = text.clone();
                        tokio::spawn(async move {
                            let _ = q.reply(q.key_expr().clone(), text).await;
                        });
                    })
                    .await
                    .unwrap(),
            );
        }
        answers
    });
    let mut recorder = Launch::start(
        &[],
        &[
            "record",
            "-o",
            file.to_str().unwrap(),
            "--connect",
            &endpoint,
            "--namespace",
            ns,
            "--wait",
            "1",
        ],
        &[],
    );
    // Subscribed once it says where it records.
    recorder.expect("the recorder started", Duration::from_secs(60), |l| {
        l.starts_with("recording ")
    });
    let key = peppy_runtime::wire::keys::entry_key(
        ns,
        peppy_runtime::wire::keys::Channel::Topic,
        &peppy_runtime::wire::keys::Owner::Node {
            name: "sensor",
            tag: "v1",
        },
        "size",
        "core",
        "cam",
    );
    rt.block_on(async {
        // The producer starts after the recorder, once the recorder's
        // subscription has reached it (as a node's first message would
        // wait for its route).
        let publisher = session.declare_publisher(key.clone()).await.unwrap();
        let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
        while !publisher.matching_status().await.unwrap().matching() {
            assert!(
                tokio::time::Instant::now() < deadline,
                "the recorder never subscribed"
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let publisher = &publisher;
        let put = |payload: Vec<u8>, fp: Option<u64>| async move {
            let mut put = publisher.put(payload);
            if let Some(fp) = fp {
                put = put.attachment(peppy_runtime::wire::attachment::topic(fp));
            }
            put.await.unwrap();
            tokio::time::sleep(Duration::from_millis(50)).await;
        };
        for w in 1..=3u32 {
            put(w.to_le_bytes().to_vec(), Some(fingerprints[0])).await;
        }
        for w in 4..=5u32 {
            let mut both = w.to_le_bytes().to_vec();
            both.extend(10u32.to_le_bytes());
            put(both, Some(fingerprints[1])).await;
        }
        put(vec![1, 2, 3], Some(0x0bad)).await;
        put(vec![1, 2, 3], None).await;
    });
    // The last samples reach the recorder before Ctrl-C ends it.
    recorder.expect("the last message counted", Duration::from_secs(30), |l| {
        l.contains("recording ") && l.contains(" 5 messages")
    });
    let (code, lines) = recorder.stop_seen();
    let stderr = lines.join("\n");
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("recorded 5 messages on 2 channels"),
        "{stderr}"
    );
    assert!(
        stderr.contains("format 0000000000000bad is described by nobody"),
        "{stderr}"
    );
    assert!(stderr.contains("no peppy attachment"), "{stderr}");

    let bytes = std::fs::read(&file).unwrap();
    let mut seen: Vec<(String, String, String)> = Vec::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        let schema = message.channel.schema.as_ref().unwrap();
        let schema: serde_json::Value = serde_json::from_slice(&schema.data).unwrap();
        let fields: Vec<String> = schema["properties"]
            .as_object()
            .unwrap()
            .keys()
            .cloned()
            .collect();
        seen.push((
            message.channel.topic.clone(),
            fields.join(","),
            String::from_utf8(message.data.to_vec()).unwrap(),
        ));
    }
    let expected: Vec<(String, String, String)> = [
        ("width", r#"{"width":1}"#),
        ("width", r#"{"width":2}"#),
        ("width", r#"{"width":3}"#),
        ("width,height", r#"{"width":4,"height":10}"#),
        ("width,height", r#"{"width":5,"height":10}"#),
    ]
    .map(|(fields, json)| {
        (
            "/cam/size".to_string(),
            fields.to_string(),
            json.to_string(),
        )
    })
    .into();
    assert_eq!(seen, expected);
    rt.block_on(async { session.close().await.unwrap() });
}
