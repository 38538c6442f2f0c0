//! Unix-socket links between the processes of one launch on one host.
//!
//! A launch's router listens on a Unix socket beside its TCP endpoints,
//! and each instance it starts connects to the router and listens on a
//! Unix socket of its own, so two instances of one launch talk over a
//! Unix socket instead of the loopback TCP stack: about a tenth less
//! time per small round trip (docs/PERFORMANCE.md, "Links on one host").
//! Everything that crosses machines (other core nodes, `--connect`,
//! `--listen`, tools on another host) stays on the router's TCP or TLS
//! endpoints. The sockets live in a directory only the launching user can
//! enter (0700), removed when the launch ends.

use std::path::{Path, PathBuf};

/// Set to `tcp` to keep every link of a launch on loopback TCP (the
/// behaviour before Unix-socket links, for comparison).
pub(crate) const LINK_ENV: &str = "PEPPY_LOCAL_LINK";

/// Set to `off` to keep a launch's topics on Zenoh alone, without direct
/// links between its instances (for comparison).
pub(crate) const DIRECT_ENV: &str = "PEPPY_DIRECT_LINKS";

/// The longest socket path used: `sockaddr_un` holds 108 bytes on Linux
/// (104 on macOS), with room for the `.lock` file Zenoh puts beside it.
const MAX_PATH: usize = 96;

/// This launch's socket directory, removed on drop.
#[derive(Debug)]
pub(crate) struct LocalLinks {
    dir: PathBuf,
}

impl LocalLinks {
    /// A fresh private directory for this launch's sockets, in the user's
    /// runtime directory (`$XDG_RUNTIME_DIR`) or the temporary one; `None`
    /// (TCP throughout) where there are no Unix sockets, when the user
    /// asked for TCP, or when no short enough path can be made.
    pub(crate) fn create() -> Option<LocalLinks> {
        if !cfg!(unix) || std::env::var(LINK_ENV).is_ok_and(|v| v.eq_ignore_ascii_case("tcp")) {
            return None;
        }
        let base = std::env::var_os("XDG_RUNTIME_DIR")
            .map(PathBuf::from)
            .filter(|d| d.is_dir())
            .unwrap_or_else(std::env::temp_dir);
        remove_stale(&base);
        let stamp = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let dir = base.join(format!("peppy-{}-{stamp:08x}", std::process::id()));
        let links = LocalLinks { dir };
        if links.socket("router").len() > MAX_PATH || private_dir(&links.dir).is_err() {
            return None;
        }
        Some(links)
    }

    /// The router's Unix endpoint.
    pub(crate) fn router(&self) -> String {
        self.endpoint("router")
    }

    /// The Unix endpoint instance number `index` of the launch listens on
    /// (by number: an instance id can be longer than a socket path allows).
    pub(crate) fn instance(&self, index: usize) -> Option<String> {
        let name = format!("i{index}");
        (self.socket(&name).len() <= MAX_PATH).then(|| self.endpoint(&name))
    }

    /// The directory where the launch's instances hand topic messages to
    /// each other over direct links (peppy-runtime's `direct` module), or
    /// `None` when the user turned them off or their sockets' names would
    /// not fit.
    pub(crate) fn direct(&self) -> Option<std::path::PathBuf> {
        if std::env::var(DIRECT_ENV).is_ok_and(|v| v.eq_ignore_ascii_case("off")) {
            return None;
        }
        (self.socket("d0123456789abcdef").len() <= MAX_PATH).then(|| self.dir.clone())
    }

    fn socket(&self, name: &str) -> String {
        self.dir.join(format!("{name}.sock")).display().to_string()
    }

    fn endpoint(&self, name: &str) -> String {
        format!("unixsock-stream/{}", self.socket(name))
    }
}

impl Drop for LocalLinks {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Removes the socket directories of launches that ended without removing
/// theirs (a launcher killed with SIGKILL): `peppy-<pid>-…` whose launcher
/// is gone. A directory of another user's is left alone (its removal
/// fails).
fn remove_stale(base: &Path) {
    let Ok(entries) = std::fs::read_dir(base) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix("peppy-"))
            .and_then(|rest| rest.split_once('-'))
            .and_then(|(pid, _)| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if !crate::runs::pid_alive(pid) && entry.path().join("router.sock").exists() {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Makes `dir`, enterable by its owner only: a socket can be connected to
/// by anyone who can reach it.
#[cfg(unix)]
fn private_dir(dir: &Path) -> std::io::Result<()> {
    use std::os::unix::fs::DirBuilderExt;
    std::fs::DirBuilder::new().mode(0o700).create(dir)
}

#[cfg(not(unix))]
fn private_dir(_: &Path) -> std::io::Result<()> {
    Err(std::io::ErrorKind::Unsupported.into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_launch_gets_a_private_socket_directory_removed_at_its_end() {
        let Some(links) = LocalLinks::create() else {
            return;
        };
        let dir = links.dir.clone();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&dir).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o700);
        }
        assert!(links.router().starts_with("unixsock-stream/"));
        assert!(links.router().ends_with("/router.sock"));
        assert!(links.instance(3).unwrap().ends_with("/i3.sock"));
        if std::env::var_os(DIRECT_ENV).is_none() {
            assert_eq!(links.direct().as_deref(), Some(dir.as_path()));
        }
        drop(links);
        assert!(!dir.exists());
    }

    #[test]
    fn a_killed_launchs_sockets_are_removed_by_the_next_launch() {
        let base = tempfile::tempdir().unwrap();
        // No process has pid 2^22 + 1 (above Linux's pid_max limit).
        let stale = base.path().join("peppy-4194305-0000abcd");
        let other = base.path().join("peppy-notes");
        for dir in [&stale, &other] {
            std::fs::create_dir(dir).unwrap();
            std::fs::write(dir.join("router.sock"), "").unwrap();
        }
        let mine = base
            .path()
            .join(format!("peppy-{}-0000abcd", std::process::id()));
        std::fs::create_dir(&mine).unwrap();
        std::fs::write(mine.join("router.sock"), "").unwrap();
        remove_stale(base.path());
        assert!(!stale.exists());
        assert!(other.exists() && mine.exists());
    }
}
