use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The workspace root, where `examples/` lives.
pub(crate) fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace root")
        .to_path_buf()
}

pub(crate) struct Run {
    pub(crate) code: i32,
    pub(crate) stdout: String,
    pub(crate) stderr: String,
}

/// Runs `peppy-launch args...` in `dir` with no colour and no inherited
/// repository list.
pub(crate) fn peppy_launch(dir: &Path, args: &[&str]) -> Run {
    peppy_launch_with(dir, args, &[])
}

/// [`peppy_launch`] with extra environment variables. A command that has
/// not ended after [`COMMAND_BOUND`] is killed and the test fails.
pub(crate) fn peppy_launch_with(dir: &Path, args: &[&str], env: &[(&str, &Path)]) -> Run {
    peppy_launch_in(&[], dir, args, env)
}

/// [`peppy_launch_with`] run through `wrapper` (e.g. `ip netns exec NS`).
pub(crate) fn peppy_launch_in(
    wrapper: &[&str],
    dir: &Path,
    args: &[&str],
    env: &[(&str, &Path)],
) -> Run {
    let child = peppy_launch_command(wrapper)
        .args(args)
        .current_dir(dir)
        .env("NO_COLOR", "1")
        .env_remove("PEPPY_REPOSITORIES")
        .envs(env.iter().copied())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run peppy-launch");
    let Output {
        status,
        stdout,
        stderr,
    } = wait_bounded(child, COMMAND_BOUND, &format!("peppy-launch {args:?}"));
    Run {
        code: status.code().expect("exited normally, not by a signal"),
        stdout: String::from_utf8(stdout).expect("utf-8 stdout"),
        stderr: String::from_utf8(stderr).expect("utf-8 stderr"),
    }
}

/// `peppy-launch`, run through `wrapper` (e.g. `ip netns exec NS`), which
/// must exec into it so that signals reach it.
pub(crate) fn peppy_launch_command(wrapper: &[&str]) -> Command {
    let program = env!("CARGO_BIN_EXE_peppy-launch");
    let mut c = match wrapper.split_first() {
        Some((first, rest)) => {
            let mut c = Command::new(first);
            c.args(rest).arg(program);
            c
        }
        None => Command::new(program),
    };
    // The user's repository list is empty: no test searches what a `repo
    // add` or `repo refresh` on this machine left in the cache. A test of
    // the list sets its own.
    c.env("PEPPY_CONFIG_DIR", empty_user_config());
    c
}

/// A configuration directory whose repository list is empty.
pub(crate) fn empty_user_config() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/empty_user_config")
}

/// The longest a single command of a test may take. A command that
/// builds a node may be the first to build it cold, or wait on cargo's
/// lock while another test does: on a slow day of the two-core CI
/// machine such an `up --detach` was still compiling after 180 s. This
/// only stops a hang; nothing here is timed.
pub(crate) const COMMAND_BOUND: Duration = Duration::from_secs(600);

/// Waits for `child` (its output read as it comes), killing it and failing
/// the test once `bound` has passed.
pub(crate) fn wait_bounded(mut child: Child, bound: Duration, what: &str) -> Output {
    use std::io::Read as _;
    let pipe = |r: Option<Box<dyn std::io::Read + Send>>| {
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            if let Some(mut r) = r {
                let _ = r.read_to_end(&mut buf);
            }
            buf
        })
    };
    let out = pipe(child.stdout.take().map(|p| Box::new(p) as _));
    let err = pipe(child.stderr.take().map(|p| Box::new(p) as _));
    let deadline = Instant::now() + bound;
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for the child") {
            break status;
        }
        if Instant::now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "{what} did not end within {bound:?}; stderr:\n{}",
                String::from_utf8_lossy(&err.join().unwrap_or_default())
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Output {
        status,
        stdout: out.join().unwrap_or_default(),
        stderr: err.join().unwrap_or_default(),
    }
}

/// The `path:line:col: ...` lines of a human report.
pub(crate) fn jump_lines(stderr: &str) -> Vec<&str> {
    stderr
        .lines()
        .filter(|l| l.contains(": error: ") || l.contains(": warning: "))
        .filter(|l| !l.trim_start().starts_with(['×', '⚠', '│', '·', '╭']))
        .collect()
}

/// A headless browser for screenshot tests (see [`debian_tool`]).
pub(crate) fn headless_browser() -> Option<PathBuf> {
    debian_tool("chromium", "chromium")
}

/// A command from the Debian packages: on the PATH, else installed with
/// apt-get when this process may (root, as in CI). Elsewhere the test says
/// loudly that it cannot run; in CI (`CI=true`) that is a failure, never a
/// silent pass.
pub(crate) fn debian_tool(command: &str, package: &str) -> Option<PathBuf> {
    static FOUND: std::sync::Mutex<Vec<(String, Option<PathBuf>)>> =
        std::sync::Mutex::new(Vec::new());
    // One install at a time (dpkg takes a lock), each package once.
    let mut found = FOUND.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, path)) = found.iter().find(|(c, _)| c == command) {
        return path.clone();
    }
    let path = find_or_install(command, package);
    found.push((command.to_string(), path.clone()));
    path
}

fn on_path(name: &str) -> Option<PathBuf> {
    std::env::var_os("PATH")?
        .to_str()?
        .split(':')
        .chain(["/usr/sbin", "/sbin"])
        .map(|d| Path::new(d).join(name))
        .find(|p| p.is_file())
}

fn find_or_install(command: &str, package: &str) -> Option<PathBuf> {
    if let Some(found) = on_path(command) {
        return Some(found);
    }
    // SAFETY: getuid has no preconditions.
    let root = unsafe { libc::getuid() } == 0;
    if root && on_path("apt-get").is_some() {
        let install = || {
            Command::new("apt-get")
                .args(["install", "-y", "-q", "--no-install-recommends", package])
                .env("DEBIAN_FRONTEND", "noninteractive")
                .output()
                .is_ok_and(|o| o.status.success())
        };
        let installed = install()
            || (Command::new("apt-get")
                .args(["update", "-q"])
                .output()
                .is_ok_and(|o| o.status.success())
                && install());
        if installed && let Some(found) = on_path(command) {
            return Some(found);
        }
    }
    let why = format!(
        "`{command}` is not installed and could not be installed with apt-get (package {package})"
    );
    assert!(std::env::var("CI").as_deref() != Ok("true"), "{why}");
    eprintln!("\n!!! SKIPPED: {why}\n");
    None
}

/// An RGB image.
pub(crate) struct Image {
    pub(crate) width: usize,
    pub(crate) height: usize,
    /// Row-major RGB pixels.
    pub(crate) pixels: Vec<[u8; 3]>,
}

/// Decodes the 8-bit RGB or RGBA, non-interlaced PNG a browser writes.
pub(crate) fn decode_png(bytes: &[u8]) -> Image {
    use std::io::Read as _;
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "a PNG file");
    let (mut pos, mut idat, mut header) = (8, Vec::new(), None);
    while pos + 8 <= bytes.len() {
        let len = u32::from_be_bytes(bytes[pos..pos + 4].try_into().unwrap()) as usize;
        let kind = &bytes[pos + 4..pos + 8];
        let data = &bytes[pos + 8..pos + 8 + len];
        match kind {
            b"IHDR" => header = Some(data.to_vec()),
            b"IDAT" => idat.extend_from_slice(data),
            _ => {}
        }
        pos += 12 + len;
    }
    let h = header.expect("an IHDR chunk");
    let width = u32::from_be_bytes(h[0..4].try_into().unwrap()) as usize;
    let height = u32::from_be_bytes(h[4..8].try_into().unwrap()) as usize;
    let channels = match (h[8], h[9], h[12]) {
        (8, 2, 0) => 3,
        (8, 6, 0) => 4,
        other => panic!("unsupported PNG (depth, colour type, interlace) {other:?}"),
    };
    let mut raw = Vec::new();
    flate2::read::ZlibDecoder::new(&idat[..])
        .read_to_end(&mut raw)
        .unwrap();
    let stride = width * channels;
    let mut prev = vec![0u8; stride];
    let mut pixels = Vec::with_capacity(width * height);
    for row in raw.chunks(stride + 1).take(height) {
        let (filter, line) = (row[0], &row[1..]);
        let mut cur = vec![0u8; stride];
        for i in 0..stride {
            let a = if i >= channels { cur[i - channels] } else { 0 };
            let b = prev[i];
            let c = if i >= channels { prev[i - channels] } else { 0 };
            cur[i] = line[i].wrapping_add(match filter {
                0 => 0,
                1 => a,
                2 => b,
                3 => ((u16::from(a) + u16::from(b)) / 2) as u8,
                4 => paeth(a, b, c),
                f => panic!("PNG filter {f}"),
            });
        }
        pixels.extend(cur.chunks(channels).map(|p| [p[0], p[1], p[2]]));
        prev = cur;
    }
    assert_eq!(pixels.len(), width * height, "every row decoded");
    Image {
        width,
        height,
        pixels,
    }
}

fn paeth(a: u8, b: u8, c: u8) -> u8 {
    let p = i16::from(a) + i16::from(b) - i16::from(c);
    let (pa, pb, pc) = (
        (p - i16::from(a)).abs(),
        (p - i16::from(b)).abs(),
        (p - i16::from(c)).abs(),
    );
    if pa <= pb && pa <= pc {
        a
    } else if pb <= pc {
        b
    } else {
        c
    }
}

/// Runs `cargo ARGS` in the workspace root, bounded, and fails the test
/// with cargo's stderr when it fails.
pub(crate) fn cargo(args: &[&str]) -> Output {
    let child = Command::new(env!("CARGO"))
        .args(args)
        .current_dir(root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run cargo");
    let out = wait_bounded(child, COMMAND_BOUND, &format!("cargo {args:?}"));
    assert!(
        out.status.success(),
        "cargo {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The debug executable of the workspace's example node package `name`,
/// built first (nothing to do when `cargo test` built it already).
pub(crate) fn example_binary(name: &str) -> PathBuf {
    cargo(&["build", "--quiet", "-p", name]);
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target"))
        .join("debug")
        .join(name)
}

/// Copies the documents under `from` into `to`: not run directories, Python
/// environments (their links would not copy), sources or build output.
pub(crate) fn copy_documents(from: &Path, to: &Path) {
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name();
        if name.to_string_lossy().starts_with('.')
            || ["src", "target", "__pycache__"].iter().any(|n| name == *n)
        {
            continue;
        }
        let dest = to.join(&name);
        if entry.file_type().unwrap().is_dir() {
            std::fs::create_dir_all(&dest).unwrap();
            copy_documents(&entry.path(), &dest);
        } else {
            std::fs::copy(entry.path(), dest).unwrap();
        }
    }
}
