//! The launcher's limit on open files. A launch holds about four
//! descriptors per instance (its log, two pipes, a pidfd) beside Zenoh's
//! sockets, so the usual soft limit of 1024 caps a launch near 250
//! instances, and Zenoh panics rather than fails when it runs out while
//! starting. The launcher raises its own soft limit to the hard one, as
//! servers do; the nodes it starts get the limit it was started with.

use std::sync::OnceLock;

/// The limit this process was started with, once raised.
static STARTED_WITH: OnceLock<libc::rlimit> = OnceLock::new();

/// Raises this process's soft limit on open files to its hard limit. Where
/// that is refused the limit stays as it was: running out is then a
/// located start failure, as it always was.
pub(crate) fn raise() {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes the struct it is given; setrlimit reads it.
    unsafe {
        if libc::getrlimit(libc::RLIMIT_NOFILE, &mut limit) != 0 || limit.rlim_cur >= limit.rlim_max
        {
            return;
        }
        let raised = libc::rlimit {
            rlim_cur: limit.rlim_max,
            rlim_max: limit.rlim_max,
        };
        if libc::setrlimit(libc::RLIMIT_NOFILE, &raised) == 0 {
            let _ = STARTED_WITH.set(limit);
        }
    }
}

/// In a child between fork and exec: puts back the limit the launcher was
/// started with, so a node sees the limit it would have started by hand
/// (code built on `select` expects descriptors under 1024). Only reads a
/// set `OnceLock` and makes one system call: safe after fork.
pub(crate) fn restore_in_child() -> std::io::Result<()> {
    if let Some(limit) = STARTED_WITH.get() {
        // SAFETY: setrlimit reads the struct it is given.
        if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, limit) } != 0 {
            return Err(std::io::Error::last_os_error());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    /// The limit is raised to the hard one, and a child gets the one this
    /// process started with (asked of a real child: `sh -c 'ulimit -n'`).
    #[test]
    fn the_launcher_raises_its_limit_and_its_children_keep_theirs() {
        use std::os::unix::process::CommandExt as _;
        let read = || {
            let mut l = libc::rlimit {
                rlim_cur: 0,
                rlim_max: 0,
            };
            // SAFETY: getrlimit writes the struct it is given.
            assert_eq!(unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut l) }, 0);
            l
        };
        let before = read();
        super::raise();
        let after = read();
        assert_eq!(after.rlim_cur, after.rlim_max);
        let mut child = std::process::Command::new("sh");
        child.args(["-c", "ulimit -n"]);
        // SAFETY: the hook only reads a set OnceLock and calls setrlimit.
        unsafe { child.pre_exec(super::restore_in_child) };
        let out = child.output().unwrap();
        let seen = String::from_utf8_lossy(&out.stdout).trim().to_string();
        let expected = if before.rlim_cur == libc::RLIM_INFINITY {
            "unlimited".to_string()
        } else {
            before.rlim_cur.to_string()
        };
        assert_eq!(seen, expected);
    }
}
