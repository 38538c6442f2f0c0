//! Two machines on one host: two network namespaces joined by a veth pair,
//! addressed from the documentation range 192.0.2.0/24, with no route out.
//! Each test gets its own pair (named after the process and a counter), so
//! tests run in parallel; the namespaces (and with them the veth pair) are
//! deleted when the test ends, also when it fails.

use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

/// The address of the first host; the second is `192.0.2.2`.
pub(crate) const HOST_A: &str = "192.0.2.1";

/// Two namespaces, `a` at 192.0.2.1 and `b` at 192.0.2.2.
pub(crate) struct TwoHosts {
    pub(crate) a: String,
    pub(crate) b: String,
    veth_a: String,
}

fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("ip {args:?}: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

impl TwoHosts {
    /// Creates the pair; `None` (said loudly, a failure in CI) when this
    /// machine cannot.
    pub(crate) fn new() -> Option<TwoHosts> {
        crate::support::debian_tool("ip", "iproute2")?;
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let tag = format!(
            "{}x{}",
            std::process::id() % 100_000,
            NEXT.fetch_add(1, Ordering::Relaxed)
        );
        let hosts = TwoHosts {
            a: format!("peppy-{tag}-a"),
            b: format!("peppy-{tag}-b"),
            // Interface names hold at most 15 bytes.
            veth_a: format!("pv{tag}a"),
        };
        let veth_b = format!("pv{tag}b");
        let made = (|| {
            ip(&["netns", "add", &hosts.a])?;
            ip(&["netns", "add", &hosts.b])?;
            ip(&[
                "link",
                "add",
                &hosts.veth_a,
                "type",
                "veth",
                "peer",
                "name",
                &veth_b,
            ])?;
            ip(&["link", "set", &hosts.veth_a, "netns", &hosts.a])?;
            ip(&["link", "set", &veth_b, "netns", &hosts.b])?;
            ip(&[
                "-n",
                &hosts.a,
                "addr",
                "add",
                &format!("{HOST_A}/24"),
                "dev",
                &hosts.veth_a,
            ])?;
            ip(&[
                "-n",
                &hosts.b,
                "addr",
                "add",
                "192.0.2.2/24",
                "dev",
                &veth_b,
            ])?;
            for (ns, dev) in [(&hosts.a, &hosts.veth_a), (&hosts.b, &veth_b)] {
                ip(&["-n", ns, "link", "set", dev, "up"])?;
                ip(&["-n", ns, "link", "set", "lo", "up"])?;
            }
            Ok::<(), String>(())
        })();
        match made {
            Ok(()) => Some(hosts),
            Err(why) => {
                // Dropping `hosts` removes whatever was made.
                let why = format!("cannot create network namespaces: {why}");
                assert!(std::env::var("CI").as_deref() != Ok("true"), "{why}");
                eprintln!("\n!!! SKIPPED: {why}\n");
                None
            }
        }
    }

    /// The command prefix that runs a program on host `ns`.
    pub(crate) fn on<'a>(&self, ns: &'a str) -> [&'a str; 4] {
        ["ip", "netns", "exec", ns]
    }

    /// Takes the link down (`false`) or up (`true`), as a cable pulled
    /// from host `a`.
    pub(crate) fn link(&self, up: bool) {
        ip(&[
            "-n",
            &self.a,
            "link",
            "set",
            &self.veth_a,
            if up { "up" } else { "down" },
        ])
        .unwrap();
    }
}

impl Drop for TwoHosts {
    fn drop(&mut self) {
        let _ = ip(&["netns", "del", &self.a]);
        let _ = ip(&["netns", "del", &self.b]);
        // Left in the root namespace if setting up stopped half-way.
        let _ = ip(&["link", "del", &self.veth_a]);
    }
}
