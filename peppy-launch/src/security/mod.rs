//! Security derived from the bindings (docs/SECURITY.md): whether a launch
//! runs secured, the per-launch credentials of its instances, the access
//! policy its router enforces, and the log of what the router refused.

pub(crate) mod denials;
pub(crate) mod keys;
pub(crate) mod policy;

use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::Path;

use peppy_runtime::Login;
use peppy_schema::LauncherDoc;

use crate::up::{RouterError, set_router_option};

/// Whether a launch runs secured, and why, for the line `up` prints.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Decision {
    /// Security on.
    pub(crate) on: bool,
    /// What decided it.
    pub(crate) reason: String,
}

/// Decides from the launcher's `security`, the endpoints the launch's
/// router uses (`listen`, `connect`: the command line's, else its core
/// node's) and `--insecure`. Unset, security is on as soon as the router
/// is reachable beyond loopback, or links to a router that is.
pub(crate) fn decide(
    launcher: &LauncherDoc,
    listen: &[String],
    connect: &[String],
    insecure: bool,
) -> Decision {
    if insecure {
        return Decision {
            on: false,
            reason: "--insecure".into(),
        };
    }
    if let Some((on, loc)) = &launcher.security {
        let line = loc.file.line_col(loc.span.start).line;
        return Decision {
            on: *on,
            reason: format!("`security: {on}` at line {line} of the launcher"),
        };
    }
    // Every machine of a stack must decide alike: the launcher's endpoints
    // count whichever share this is.
    let beyond = listen
        .iter()
        .chain(connect)
        .chain(
            launcher
                .core_nodes
                .iter()
                .flat_map(|c| c.listen.iter().chain(&c.connect)),
        )
        .find(|e| !is_loopback(e));
    match beyond {
        Some(e) => Decision {
            on: true,
            reason: format!("the stack is reachable beyond loopback ({e})"),
        },
        None => Decision {
            on: false,
            reason: "every endpoint is on loopback".into(),
        },
    }
}

/// Whether a Zenoh endpoint (`tcp/127.0.0.1:7447`, `tls/[::1]:7447`,
/// `tcp/localhost:7447`) stays on this machine.
pub(crate) fn is_loopback(endpoint: &str) -> bool {
    let address = endpoint
        .split_once('/')
        .map_or(endpoint, |(_, a)| a)
        .split(['?', '#'])
        .next()
        .unwrap_or_default();
    let host = match address.strip_prefix('[') {
        Some(v6) => v6.split(']').next().unwrap_or_default(),
        None => address.rsplit_once(':').map_or(address, |(h, _)| h),
    };
    host == "localhost"
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

/// The credentials of one launch: one login per instance (its id is its
/// user name) and one for the launching user's tools. Generated afresh by
/// every launch and never printed.
pub(crate) struct Secrets {
    /// Instance id -> its login.
    pub(crate) instances: BTreeMap<String, Login>,
    /// The tools' login ([`policy::OPERATOR`]).
    pub(crate) operator: Login,
    /// `record` and `view`'s read-only login ([`policy::RECORDER`]).
    pub(crate) recorder: Login,
}

impl Secrets {
    /// The user names a launch keeps for itself: no instance may take one.
    pub(crate) fn reserved(user: &str) -> bool {
        user == policy::OPERATOR || user == policy::RECORDER || user.starts_with("peppy-router-")
    }

    /// New random credentials for `instances`.
    pub(crate) fn generate<'a>(
        instances: impl IntoIterator<Item = &'a str>,
    ) -> std::io::Result<Secrets> {
        let login = |user: &str| -> std::io::Result<Login> {
            Ok(Login {
                user: user.to_string(),
                password: password()?,
            })
        };
        Ok(Secrets {
            instances: instances
                .into_iter()
                .map(|id| Ok((id.to_string(), login(id)?)))
                .collect::<std::io::Result<_>>()?,
            operator: login(policy::OPERATOR)?,
            recorder: login(policy::RECORDER)?,
        })
    }

    /// Zenoh's user-password dictionary (`user:password` per line) for the
    /// router, with `extra` logins (other core nodes' routers).
    pub(crate) fn dictionary(&self, extra: &[Login]) -> String {
        self.instances
            .values()
            .chain([&self.operator, &self.recorder])
            .chain(extra)
            .map(|l| format!("{}:{}\n", l.user, l.password))
            .collect()
    }
}

/// 32 random bytes as 64 hex digits.
pub(crate) fn password() -> std::io::Result<String> {
    let mut bytes = [0u8; 32];
    getrandom::fill(&mut bytes).map_err(|e| std::io::Error::other(e.to_string()))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Writes `bytes` to `path` readable and writable by this user only
/// (created that way, so no other user ever sees the contents), replacing
/// any older file whole.
pub(crate) fn write_private(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    let mut file = create_private(&tmp)?;
    file.write_all(bytes)?;
    file.sync_all()?;
    std::fs::rename(&tmp, path)
}

/// A new file at `path` (replacing a leftover one) that only this user can
/// read or write, from the moment it exists.
pub(crate) fn create_private(path: &Path) -> std::io::Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt as _;
    let _ = std::fs::remove_file(path);
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
}

/// What a secured router enforces.
pub(crate) struct RouterGuard {
    /// Zenoh's `access_control` section ([`policy::Policy::access_control`]).
    pub(crate) access_control: serde_json::Value,
    /// The user-password dictionary file ([`Secrets::dictionary`]), private.
    pub(crate) dictionary: std::path::PathBuf,
    /// The router's own login, for the routers it links to.
    pub(crate) login: Option<Login>,
    /// Its TLS settings ([`keys::StackKeys::tls_settings`]), when it links
    /// to other core nodes.
    pub(crate) tls: Vec<(&'static str, serde_json::Value)>,
}

impl RouterGuard {
    /// Adds authentication and access control to a router's configuration.
    pub(crate) fn apply(&self, config: &mut zenoh::Config) -> Result<(), RouterError> {
        set_router_option(
            config,
            "transport/auth/usrpwd/dictionary_file",
            self.dictionary.display().to_string().into(),
        )?;
        if let Some(login) = &self.login {
            login.apply(config).map_err(RouterError::Login)?;
        }
        for (key, value) in &self.tls {
            set_router_option(config, key, value.clone())?;
        }
        set_router_option(config, "access_control", self.access_control.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_endpoints_are_told_apart() {
        for e in [
            "tcp/127.0.0.1:7447",
            "tcp/[::1]:7447",
            "tls/localhost:7447",
            "tcp/127.0.0.1:0",
        ] {
            assert!(is_loopback(e), "{e}");
        }
        for e in [
            "tcp/0.0.0.0:7447",
            "tcp/[::]:7447",
            "tcp/192.0.2.1:7447",
            "tls/robot.local:7447",
        ] {
            assert!(!is_loopback(e), "{e}");
        }
    }

    #[test]
    fn passwords_are_fresh_and_private_files_are_private() {
        use std::os::unix::fs::PermissionsExt as _;
        let a = password().unwrap();
        assert_eq!(a.len(), 64);
        assert_ne!(a, password().unwrap());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("secret");
        write_private(&path, b"x").unwrap();
        write_private(&path, b"y").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"y");
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600);
    }

    #[test]
    fn the_operator_the_recorder_and_every_instance_are_in_the_dictionary() {
        let s = Secrets::generate(["a", "b"]).unwrap();
        let d = s.dictionary(&[]);
        assert_eq!(d.lines().count(), 4);
        assert!(d.contains(&format!("a:{}", s.instances["a"].password)));
        assert!(d.contains(&format!("{}:", policy::OPERATOR)));
        assert!(d.contains(&format!("{}:{}", policy::RECORDER, s.recorder.password)));
        assert!(Secrets::reserved(policy::RECORDER));
        assert!(!format!("{:?}", s.operator).contains(&s.operator.password));
    }
}
