//! What recording costs: `peppy-launch record` on a stack of three cameras
//! sending 1 MiB frames at 30 Hz (optimised nodes), against the `mcap`
//! crate's writer alone storing the same frames as raw bytes. Figures: the
//! stack's CPU with and without the recorder, the recorder's own CPU next
//! to the bare writer's, and the frames the recording lacks (counted from
//! the cameras' own frame ids, which run without a gap when nothing is
//! lost).

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use crate::launch::{Build, build_examples, cameras_launcher};
use crate::procs::{Proc, free_port};
use crate::roles::Res;
use crate::stats::{Figure, Row};

const GROUP: &str = "record: 3 cameras, 1 MiB frames at 30 Hz (optimised nodes)";
const CAMERAS: usize = 3;
const SIDE: u32 = 1024;
const HZ: u32 = 30;

/// CPU seconds (user + system) `pid` has used.
fn cpu_seconds(pid: u32) -> f64 {
    crate::roles::cpu_ms_of(&pid.to_string()) / 1e3
}

/// CPU of `pids` over `window`, as % of one core.
fn cpu_over(pids: &[u32], window: Duration) -> f64 {
    let total = |pids: &[u32]| pids.iter().map(|p| cpu_seconds(*p)).sum::<f64>();
    let (before, at) = (total(pids), Instant::now());
    std::thread::sleep(window);
    (total(pids) - before) / at.elapsed().as_secs_f64() * 100.0
}

fn percent(value: f64) -> Figure {
    Figure::Value {
        value,
        unit: "% of one core".into(),
    }
}

pub(crate) fn record(quick: bool) -> Res<Vec<Row>> {
    let window = Duration::from_secs(if quick { 4 } else { 10 });
    let launcher = build_examples(Build::Optimised)?;
    let dir = tempfile::tempdir()?;
    let file = cameras_launcher(
        dir.path(),
        CAMERAS,
        &format!("width: {SIDE}, height: {SIDE}, frames_per_second: {HZ}"),
    )?;
    let state = dir.path().join("state");
    let router = free_port()?;
    let ns = format!("record-{router}");
    let mut up = Command::new(&launcher);
    up.args([
        "up",
        &file.display().to_string(),
        "--no-build",
        "--namespace",
        &ns,
        "--listen",
        &format!("tcp/127.0.0.1:{router}"),
    ])
    .env("PEPPY_STATE_DIR", &state)
    .env(
        "CARGO_TARGET_DIR",
        Build::Optimised.target_dir().ok_or("no target")?,
    );
    let up = Proc::spawn(up, "peppy-launch up")?;
    // Every camera started (`started `cam_0` (...) as pid N`), then a
    // moment for the frames to flow.
    let deadline = Instant::now() + Duration::from_secs(60);
    let pids = loop {
        let pids: Vec<u32> = up
            .stderr()
            .lines()
            .filter_map(|l| l.rsplit_once(" as pid ")?.1.trim().parse().ok())
            .collect();
        if pids.len() == CAMERAS {
            break pids;
        }
        if Instant::now() > deadline {
            return Err(format!("the cameras did not start:\n{}", up.stderr()).into());
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    std::thread::sleep(Duration::from_secs(3));
    let mut stack: Vec<u32> = pids.clone();
    stack.push(up.pid());
    let idle = cpu_over(&stack, window);

    let recording = dir.path().join("cameras.mcap");
    let mut record = Command::new(&launcher);
    record
        .args(["record", "-o", &recording.display().to_string()])
        .args(["--namespace", &ns, "--wait", "10"])
        .env("PEPPY_STATE_DIR", &state);
    let recorder = Proc::spawn(record, "peppy-launch record")?;
    std::thread::sleep(Duration::from_secs(2));
    let mut all = stack.clone();
    all.push(recorder.pid());
    let recorder_before = cpu_seconds(recorder.pid());
    let at = Instant::now();
    let busy = cpu_over(&all, window);
    let recorder_cpu =
        (cpu_seconds(recorder.pid()) - recorder_before) / at.elapsed().as_secs_f64() * 100.0;
    let recorder_stderr = recorder.stderr();
    recorder.interrupt(Duration::from_secs(60));
    up.interrupt(Duration::from_secs(30));
    let (frames, lost) = count_frames(&recording)
        .map_err(|e| format!("{e}\nthe recorder said:\n{recorder_stderr}"))?;
    let writer = bare_writer(frames.max(1), dir.path())?;
    let stack_with = busy - recorder_cpu;
    Ok(vec![
        Row::new(
            GROUP,
            "stack CPU, no recorder".into(),
            None,
            Some(percent(idle)),
        ),
        Row::new(
            GROUP,
            "stack CPU while recording (recorder not counted)".into(),
            Some(percent(idle)),
            Some(percent(stack_with)),
        )
        .against("no recorder"),
        Row::new(
            GROUP,
            "recorder CPU (decode, JSON, zstd, write)".into(),
            Some(percent(writer)),
            Some(percent(recorder_cpu)),
        )
        .against("mcap writer alone, raw bytes")
        .with_note("the mcap crate's writer, zstd level 1, writing the same frames as raw bytes"),
        Row::new(
            GROUP,
            format!("frames lost of {frames} recorded"),
            None,
            Some(Figure::Value {
                value: lost as f64,
                unit: "frames".into(),
            }),
        ),
    ])
}

/// Frames in the recording, and how many of the cameras' frame ids between
/// each camera's first and last are missing.
fn count_frames(path: &Path) -> Res<(u64, u64)> {
    let bytes = std::fs::read(path)?;
    let mut ids: BTreeMap<String, Vec<u64>> = BTreeMap::new();
    for message in mcap::MessageStream::new(&bytes)? {
        let message = message?;
        let value: serde_json::Value = serde_json::from_slice(&message.data)?;
        let id = value["header"]["frame_id"]
            .as_u64()
            .ok_or("a frame without a frame id")?;
        ids.entry(message.channel.topic.clone())
            .or_default()
            .push(id);
    }
    if ids.len() != CAMERAS {
        return Err(format!("{} cameras recorded, not {CAMERAS}", ids.len()).into());
    }
    let (mut frames, mut lost) = (0, 0);
    for list in ids.values() {
        frames += list.len() as u64;
        let span = list.iter().max().unwrap_or(&0) - list.iter().min().unwrap_or(&0) + 1;
        lost += span - list.len() as u64;
    }
    Ok((frames, lost))
}

/// CPU of the `mcap` crate's writer alone storing `frames` frames of 1 MiB
/// (drawn as the camera draws them) as raw bytes, as % of one core at the
/// cameras' combined rate.
fn bare_writer(frames: u64, dir: &Path) -> Res<f64> {
    let file = std::fs::File::create(dir.join("bare.mcap"))?;
    let mut out = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_level(1)
        .compression_threads(0)
        .create(std::io::BufWriter::new(file))?;
    let schema = out.add_schema("frame", "", b"")?;
    let channel = out.add_channel(schema, "/frames", "raw", &BTreeMap::new())?;
    let frame = |t: u64| -> Vec<u8> {
        (0..SIDE as u64)
            .flat_map(|y| (0..SIDE as u64).map(move |x| (x + y + t) as u8))
            .collect()
    };
    let drawn: Vec<Vec<u8>> = (0..HZ as u64).map(frame).collect();
    let before = crate::roles::cpu_ms();
    for i in 0..frames {
        out.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channel,
                sequence: i as u32,
                log_time: i,
                publish_time: i,
            },
            &drawn[(i % u64::from(HZ)) as usize],
        )?;
    }
    out.finish()?;
    let cpu_s = (crate::roles::cpu_ms() - before) / 1e3;
    let seconds_of_frames = frames as f64 / (CAMERAS as f64 * f64::from(HZ));
    Ok(cpu_s / seconds_of_frames * 100.0)
}
