//! Security derived from the bindings, on the wire: a secured stack runs as
//! before, and its router refuses whoever the bindings do not name, from a
//! process with no credentials to an instance of the stack itself acting
//! against its bindings. The attackers are raw Zenoh sessions in this test
//! process, as an attacker's would be.

use std::path::{Path, PathBuf};
use std::time::Duration;

use peppy_runtime::wire::keys::{Channel, Owner, entry_key, namespace_selector};
use serde_json::Value;

use crate::seeds::{BUILD_AND_START, Launch};
use crate::support::{peppy_launch_with, root};

/// The multi-camera stack with a spare camera bound to nothing, secured.
fn secured_cameras(dir: &Path) -> PathBuf {
    let nodes = root().join("examples/nodes");
    let launcher = dir.join("secured_cameras.json5");
    std::fs::write(
        &launcher,
        format!(
            r#"{{ peppy_schema: "launcher_v1", security: true,
                deployments: [
                  {{ source: {{ local: "{nodes}/realsense_d405" }}, instances: [
                      {{ instance_id: "rs_left" }}, {{ instance_id: "rs_right" }},
                      {{ instance_id: "rs_spare" }} ] }},
                  {{ source: {{ local: "{nodes}/zed_2i" }}, instances: [ {{ instance_id: "zed_overhead" }} ] }},
                  {{ source: {{ local: "{nodes}/video_reconstruction" }}, instances: [
                      {{ instance_id: "recon_1",
                         bindings: {{ left_cam: "rs_left", right_cam: "rs_right", any_label: "zed_overhead" }} }} ] }} ] }}"#,
            nodes = nodes.display()
        ),
    )
    .unwrap();
    launcher
}

/// The running launch's record in the test's registry.
pub(crate) fn record(state: &Path) -> Value {
    let dir = state.join("launches");
    let entry = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .find(|e| e.path().extension().is_some_and(|x| x == "json"))
        .unwrap_or_else(|| panic!("no launch registered in {}", dir.display()));
    serde_json::from_slice(&std::fs::read(entry.path()).unwrap()).unwrap()
}

/// An instance's login, from the runtime configuration its launch wrote.
pub(crate) fn login_of(record: &Value, instance: &str) -> (String, String) {
    let path = Path::new(record["run_dir"].as_str().unwrap()).join(format!("{instance}.json"));
    let config: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    // Secured, every message goes through the router: no link past it.
    assert!(config.get("direct_links").is_none(), "{config}");
    let login = &config["zenoh"]["login"];
    (
        login["user"].as_str().unwrap().to_string(),
        login["password"].as_str().unwrap().to_string(),
    )
}

/// A raw Zenoh client of `endpoint`, with or without a login.
pub(crate) async fn attacker(
    endpoint: &str,
    login: Option<(&str, &str)>,
) -> zenoh::Result<zenoh::Session> {
    let mut config = zenoh::Config::default();
    config.insert_json5("mode", r#""client""#).unwrap();
    config
        .insert_json5("connect/endpoints", &format!(r#"["{endpoint}"]"#))
        .unwrap();
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    if let Some((user, password)) = login {
        config
            .insert_json5("transport/auth/usrpwd/user", &format!("{user:?}"))
            .unwrap();
        config
            .insert_json5("transport/auth/usrpwd/password", &format!("{password:?}"))
            .unwrap();
    }
    zenoh::open(config).await
}

pub(crate) fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// The interface every camera of these stacks conforms to.
const DEPTH_CAMERA: Owner<'static> = Owner::Interface {
    name: "depth_camera",
    tag: "v1",
};

/// Publishes 20 messages without a peppy attachment under `rs_left`'s key:
/// a consumer that received them would log that it dropped them.
async fn spoof_rs_left(session: &zenoh::Session, ns: &str, core: &str) {
    let key = entry_key(
        ns,
        Channel::Topic,
        &DEPTH_CAMERA,
        "video_stream",
        core,
        "rs_left",
    );
    for _ in 0..20 {
        session.put(&key, vec![0xffu8; 64]).await.unwrap();
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// The key rs_left serves `video_stream_info` on.
fn rs_left_info_key(ns: &str, core: &str) -> String {
    entry_key(
        ns,
        Channel::Service,
        &DEPTH_CAMERA,
        "video_stream_info",
        core,
        "rs_left",
    )
}

/// Whether rs_left answers `session`'s call of its `video_stream_info`
/// within 2 s.
async fn answered_by_rs_left(session: &zenoh::Session, ns: &str, core: &str) -> bool {
    let replies = session
        .get(rs_left_info_key(ns, core))
        .timeout(Duration::from_secs(2))
        .await
        .unwrap();
    replies.recv_async().await.is_ok()
}

const FORGED: &str = "dropping messages without a valid peppy attachment";

/// A secured multi-camera stack runs as it does unsecured; a process
/// without credentials cannot even connect; an instance of the stack (the
/// spare camera's credentials, as if its process were compromised) can
/// neither publish under another camera's name, nor receive any topic, nor
/// answer another camera's service, and each refusal is logged once by the
/// launch. Run again with `--insecure`, the same forgery reaches the
/// consumer, which shows the test would see it.
#[test]
fn a_secured_stack_admits_only_what_its_bindings_name() {
    let dir = tempfile::tempdir().unwrap();
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let launcher = secured_cameras(dir.path());
    let launcher = launcher.to_str().unwrap();
    let ns = "security-cameras";
    let mut launch = Launch::up_with(launcher, &["--namespace", ns], &[("PEPPY_STATE_DIR", st)]);
    launch.expect("saying security is on", BUILD_AND_START, |l| {
        l.contains("security on (`security: true` at line 1 of the launcher)")
    });
    launch.expect("with recon_1 receiving all three", BUILD_AND_START, |l| {
        l.starts_with("[recon_1]")
            && l.contains("backup_cams<-zed_overhead")
            && l.contains("left_cam<-rs_left")
            && l.contains("right_cam<-rs_right")
    });
    let record = record(st);
    let endpoint = record["connect"][0].as_str().unwrap().to_string();
    let core = record["core_node"].as_str().unwrap().to_string();
    let run_dir = PathBuf::from(record["run_dir"].as_str().unwrap());
    {
        use std::os::unix::fs::PermissionsExt as _;
        for file in ["rs_spare.json", "router.users"] {
            let mode = std::fs::metadata(run_dir.join(file))
                .unwrap()
                .permissions()
                .mode();
            assert_eq!(mode & 0o077, 0, "{file} is readable by others");
        }
    }
    let (spare_user, spare_password) = login_of(&record, "rs_spare");
    let (left_user, _) = login_of(&record, "rs_left");

    let rt = runtime();
    rt.block_on(async {
        // No credentials, or a wrong password: no connection at all.
        assert!(attacker(&endpoint, None).await.is_err());
        assert!(
            attacker(&endpoint, Some((&left_user, "not-the-password")))
                .await
                .is_err()
        );

        let spare = attacker(&endpoint, Some((&spare_user, &spare_password)))
            .await
            .expect("the spare camera's own login is accepted");
        // It consumes nothing, so it receives nothing, though three
        // cameras publish 15 frames a second each (listened to from a
        // second session: a session hears its own publications itself).
        let listener = attacker(&endpoint, Some((&spare_user, &spare_password)))
            .await
            .unwrap();
        let everything = listener
            .declare_subscriber(namespace_selector(ns))
            .await
            .unwrap();
        // It may not call another camera's service...
        assert!(
            !answered_by_rs_left(&spare, ns, &core).await,
            "rs_spare got an answer from rs_left"
        );
        let info_key = rs_left_info_key(ns, &core);
        // ...nor serve it, nor publish under its name.
        let _fake_server = spare
            .declare_queryable(&info_key)
            .callback(|q| {
                tokio::spawn(async move {
                    let _ = q.reply(q.key_expr().clone(), vec![0u8; 8]).await;
                });
            })
            .await
            .unwrap();
        spoof_rs_left(&spare, ns, &core).await;
        tokio::time::sleep(Duration::from_secs(2)).await;
        let received = everything.drain().count();
        assert_eq!(received, 0, "rs_spare received {received} samples");
        spare.close().await.unwrap();
        listener.close().await.unwrap();
    });

    launch.expect("with the forgery refused", Duration::from_secs(10), |l| {
        l.contains(&format!(
            "denied: `rs_spare` may not publish on peppy/{ns}/topic/interface/depth_camera/v1/video_stream/{core}/rs_left"
        ))
    });
    launch.expect(
        "with the fake server refused",
        Duration::from_secs(10),
        |l| l.contains("denied: `rs_spare` may not serve") && l.contains("/rs_left"),
    );
    // The spare camera's own frames match recon_1's from_any subscription,
    // and the router keeps them from it: recon_1's bindings do not name it.
    launch.expect(
        "with rs_spare's frames kept from recon_1",
        Duration::from_secs(10),
        |l| l.contains("denied: `recon_1` may not receive") && l.ends_with("/rs_spare"),
    );
    launch.read_for(Duration::from_secs(2));
    let denials: Vec<&String> = launch
        .seen
        .iter()
        .filter(|l| l.contains("denied:"))
        .collect();
    let mut unique = denials.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(
        denials.len(),
        unique.len(),
        "a denial said twice: {denials:?}"
    );
    assert!(
        !launch.seen.iter().any(|l| l.contains(FORGED)),
        "the forgery reached a consumer:\n{}",
        launch.seen.join("\n")
    );

    // The launching user's tools still see everything, and rs_left answers
    // its own service.
    let info = peppy_launch_with(
        &root(),
        &[
            "service",
            "call",
            "rs_left",
            "video_stream_info",
            "--format",
            "json",
            "--wait",
            "10",
        ],
        &[("PEPPY_STATE_DIR", st)],
    );
    assert_eq!(info.code, 0, "{}", info.stderr);
    assert!(info.stdout.contains(r#""width":160"#), "{}", info.stdout);

    // `record` logs in as the recorder, which reads every topic...
    let file = st.join("secured.mcap");
    let recorded = peppy_launch_with(
        &root(),
        &[
            "record",
            "-o",
            file.to_str().unwrap(),
            "--duration",
            "3",
            "--wait",
            "10",
        ],
        &[("PEPPY_STATE_DIR", st)],
    );
    assert_eq!(recorded.code, 0, "{}", recorded.stderr);
    for camera in ["rs_left", "rs_right", "rs_spare", "zed_overhead"] {
        assert!(
            recorded
                .stderr
                .contains(&format!("/{camera}/video_stream ")),
            "{camera} not recorded: {}",
            recorded.stderr
        );
    }
    // ...and may do nothing else: publish as a camera, or call a service.
    let recorder = &record["recorder_login"];
    let (user, password) = (
        recorder["user"].as_str().unwrap(),
        recorder["password"].as_str().unwrap(),
    );
    assert_eq!(user, "peppy-recorder");
    rt.block_on(async {
        let session = attacker(&endpoint, Some((user, password)))
            .await
            .expect("the recorder's login is accepted");
        assert!(
            !answered_by_rs_left(&session, ns, &core).await,
            "the recorder got an answer from rs_left"
        );
        spoof_rs_left(&session, ns, &core).await;
        session.close().await.unwrap();
    });
    launch.expect(
        "with the recorder's publication refused",
        Duration::from_secs(10),
        |l| l.contains("denied: `peppy-recorder` may not publish on") && l.ends_with("/rs_left"),
    );
    assert_eq!(launch.stop(), 0);

    // The control: the same forgery with security off reaches recon_1.
    // Direct links off: recon_1's slot is pinned to rs_left, so once
    // linked it reads rs_left through the link and its side key alone
    // and hears no other publisher under rs_left's key (docs/WIRE.md,
    // "Direct links"); the control is about Zenoh's open key space.
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let mut launch = Launch::up_with(
        launcher,
        &["--namespace", ns, "--insecure"],
        &[
            ("PEPPY_STATE_DIR", st),
            ("PEPPY_DIRECT_LINKS", std::path::Path::new("off")),
        ],
    );
    launch.expect("warning that security is off", BUILD_AND_START, |l| {
        l.contains("WARNING: security is OFF (--insecure)")
    });
    launch.expect("with recon_1 receiving", BUILD_AND_START, |l| {
        l.starts_with("[recon_1]") && l.contains("left_cam<-rs_left")
    });
    let record = self::record(st);
    let endpoint = record["connect"][0].as_str().unwrap().to_string();
    let core = record["core_node"].as_str().unwrap().to_string();
    rt.block_on(async {
        let open = attacker(&endpoint, None)
            .await
            .expect("an open stack admits anyone");
        spoof_rs_left(&open, ns, &core).await;
        open.close().await.unwrap();
    });
    launch.expect(
        "with the forgery reaching recon_1",
        Duration::from_secs(10),
        |l| l.starts_with("[recon_1]") && l.contains(FORGED),
    );
    assert_eq!(launch.stop(), 0);
}

/// `check --security` prints the policy a reviewer audits: per instance
/// what it may emit, serve, receive and call, from and on whom; as JSON
/// too.
#[test]
fn check_security_prints_the_policy() {
    let run = peppy_launch_with(
        &root(),
        &[
            "check",
            "examples/launchers/multi_camera.json5",
            "--security",
            "--namespace",
            "lab",
        ],
        &[],
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    let out = &run.stdout;
    assert!(
        out.contains("security: off under `up` (every endpoint is on loopback;"),
        "{out}"
    );
    assert!(
        out.contains("access policy (keys under peppy/lab/;"),
        "{out}"
    );
    let recon = &out[out.find("\n  recon_1 (core node *)").expect(out)..];
    for line in [
        "receives  topic video_stream via left_cam",
        "from rs_left",
        "topic/interface/depth_camera/v1/video_stream/*/rs_left",
        "calls     service video_stream_info via left_cam",
        "from zed_overhead",
    ] {
        assert!(recon.contains(line), "`{line}` missing:\n{recon}");
    }
    let rs_left = &out[out.find("\n  rs_left (core node *)").expect(out)..];
    assert!(
        rs_left.lines().any(|l| l.trim_start().starts_with("emits")
            && l.contains("topic video_stream")
            && l.ends_with("topic/interface/depth_camera/v1/video_stream/*/rs_left")),
        "{rs_left}"
    );

    let json = peppy_launch_with(
        &root(),
        &[
            "check",
            "examples/launchers/multi_camera.json5",
            "--security",
            "--namespace",
            "lab",
            "--format",
            "json",
        ],
        &[],
    );
    let v: Value = serde_json::from_str(&json.stdout).unwrap();
    assert_eq!(v["security"]["on"], false);
    let recon = v["security"]["policy"]["instances"]
        .as_array()
        .unwrap()
        .iter()
        .find(|i| i["instance_id"] == "recon_1")
        .unwrap();
    let left = recon["receives"]
        .as_array()
        .unwrap()
        .iter()
        .find(|g| g["slot"] == "left_cam")
        .unwrap();
    assert_eq!(left["peers"], serde_json::json!(["rs_left"]));
    assert_eq!(
        left["keys"],
        serde_json::json!(["peppy/lab/topic/interface/depth_camera/v1/video_stream/*/rs_left"])
    );
}

/// A launch reachable beyond loopback runs secured without being asked,
/// and the arm loop (a linked topic, an external topic and an action)
/// works unchanged.
#[test]
fn the_arm_loop_runs_secured_when_its_router_is_reachable() {
    let listen = format!("tcp/0.0.0.0:{}", crate::machines::free_port());
    let state = tempfile::tempdir().unwrap();
    let mut launch = Launch::up_with(
        "examples/launchers/robot_arm_loop.json5",
        &["--listen", &listen, "--namespace", "security-arm"],
        &[("PEPPY_STATE_DIR", state.path())],
    );
    launch.expect("saying security is on", BUILD_AND_START, |l| {
        l.contains(&format!(
            "security on (the stack is reachable beyond loopback ({listen}))"
        ))
    });
    crate::seeds::arm_loop_runs(&mut launch);
    assert!(
        !launch.seen.iter().any(|l| l.contains("denied:")),
        "a bound flow was refused:\n{}",
        launch.seen.join("\n")
    );
    assert_eq!(launch.stop(), 0);
}
