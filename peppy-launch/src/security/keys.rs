//! The keys of a stack placed over several machines: a certificate per core
//! node, signed by a certificate authority of the stack's own, so that the
//! routers of its core nodes link over mutually authenticated TLS and no
//! other router (another stack's, an attacker's) can link in; and a link
//! secret their routers' logins derive from.
//!
//! `peppy-launch keys LAUNCHER` creates them once, on one machine, under
//! `<state>/stacks/<launcher>-<hash of its core node names>/`; the
//! directory is copied to every machine of the stack. They are reused by
//! every launch until the launcher's core nodes change (which names a new
//! directory) or `keys --rotate` replaces them. The authority's private key
//! is never stored: it signs the core nodes' certificates once and is
//! dropped, so no core node can be added without new keys for all.

use std::path::{Path, PathBuf};

use peppy_runtime::Login;
use peppy_schema::LauncherDoc;
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use sha2::{Digest, Sha256};

use super::write_private;

/// Why the stack's keys could not be made or used.
#[derive(Debug, thiserror::Error)]
pub enum KeysError {
    /// A file or directory of the keys could not be written.
    #[error("cannot create the stack's keys: {source}")]
    Write {
        /// The file or directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A key or certificate could not be generated or signed.
    #[error("cannot create the stack's keys: {0}")]
    Certificate(#[source] rcgen::Error),
    /// No random bytes for the link secret.
    #[error("cannot create the stack's keys: {0}")]
    Random(#[source] std::io::Error),
    /// Security is on and this core node's keys are not in the keys'
    /// directory.
    #[error(
        "security is on, and core node {core} has no keys ({} is missing): create them once with `peppy-launch keys {}` on one machine and copy {} to every machine of the stack (or run with --insecure)",
        missing.display(),
        launcher.display(),
        dir.display()
    )]
    Missing {
        /// The core node.
        core: String,
        /// The first file missing.
        missing: PathBuf,
        /// The launcher, for the command that creates the keys.
        launcher: PathBuf,
        /// The keys' directory.
        dir: PathBuf,
    },
    /// The link secret cannot be read.
    #[error("cannot read {}: {source}", path.display())]
    ReadSecret {
        /// The secret's file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// The stack authority's certificate.
const CA: &str = "ca.pem";
/// The secret the routers' passwords derive from.
const SECRET: &str = "link.secret";
/// Where each core node's certificate and key are.
const CORES: &str = "cores";

/// `<dir>/cores/<core>.<ext>`: apart from the authority's files, whatever
/// a core node is called.
fn core_file(dir: &Path, core: &str, ext: &str) -> PathBuf {
    dir.join(CORES).join(format!("{core}.{ext}"))
}

/// Where a launcher's keys live: named by the launcher's file name and its
/// core nodes, so renaming or adding a core node asks for new keys.
pub(crate) fn dir_for(launcher: &LauncherDoc) -> PathBuf {
    let stem = launcher
        .file
        .path()
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("stack");
    let mut names: Vec<&str> = launcher
        .core_nodes
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    names.sort_unstable();
    let digest = Sha256::digest(names.join("\n").as_bytes());
    let hash: String = digest[..4].iter().map(|b| format!("{b:02x}")).collect();
    crate::runs::state_dir()
        .join("stacks")
        .join(format!("{stem}-{hash}"))
}

/// `peppy-launch keys LAUNCHER [--rotate]`.
pub(crate) fn run(args: &crate::cli::KeysArgs) -> crate::error::Result {
    use crate::error::LaunchError;
    let launcher = match LauncherDoc::load(&args.launcher) {
        Ok((doc, _)) => doc,
        Err(diags) => {
            crate::report::print_human(&diags);
            return Err(LaunchError::Invalid {
                errors: diags.error_count(),
            });
        }
    };
    if launcher.core_nodes.is_empty() {
        return Err(crate::error::UsageError::NoCoreNodes {
            launcher: args.launcher.clone(),
        }
        .into());
    }
    // `--place`: the keys are the machines', as `up --place` asks for them.
    let launcher = if args.placing.place.is_empty() {
        launcher
    } else {
        let placement = crate::placement::read_places(
            &launcher,
            &args.placing.place,
            &mut crate::placement::host_core_node,
        )?;
        launcher.placed(&placement)
    };
    let dir = dir_for(&launcher);
    let names: Vec<&str> = launcher
        .core_nodes
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    if dir.join(CA).is_file() && !args.rotate {
        eprintln!(
            "peppy-launch: keys for core nodes {} exist in {} (kept; --rotate replaces them)",
            names.join(", "),
            dir.display()
        );
    } else {
        create(&dir, &names)?;
        eprintln!(
            "peppy-launch: {} keys for core nodes {} in {}",
            if args.rotate { "new" } else { "created" },
            names.join(", "),
            dir.display()
        );
    }
    eprintln!(
        "peppy-launch: copy it into the state directory's `stacks/` on every machine of the stack, keeping it private (e.g. `scp -rp {} HOST:.local/state/peppy/stacks/`)",
        dir.display(),
    );
    println!("{}", dir.display());
    Ok(())
}

/// Creates (or replaces) the keys of a stack of `core_nodes` in `dir`.
pub(crate) fn create(dir: &Path, core_nodes: &[&str]) -> Result<(), KeysError> {
    let at = |path: &Path| {
        let path = path.to_path_buf();
        move |source| KeysError::Write { path, source }
    };
    let cert = KeysError::Certificate;
    std::fs::create_dir_all(dir).map_err(at(dir))?;
    {
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700)).map_err(at(dir))?;
    }
    let ca_key = KeyPair::generate().map_err(cert)?;
    let mut ca = CertificateParams::new(Vec::<String>::new()).map_err(cert)?;
    ca.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    ca.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
    ca.distinguished_name
        .push(DnType::CommonName, "peppy stack authority");
    let ca_cert = ca.self_signed(&ca_key).map_err(cert)?;
    let issuer = Issuer::from_params(&ca, &ca_key);
    std::fs::create_dir_all(dir.join(CORES)).map_err(at(&dir.join(CORES)))?;
    for core in core_nodes {
        let key = KeyPair::generate().map_err(cert)?;
        let mut params = CertificateParams::new(Vec::<String>::new()).map_err(cert)?;
        // The common name is what the routers' access control knows a core
        // node by.
        params.distinguished_name.push(DnType::CommonName, *core);
        params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        params.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ];
        let signed = params.signed_by(&key, &issuer).map_err(cert)?;
        let (pem, private) = (core_file(dir, core, "pem"), core_file(dir, core, "key"));
        std::fs::write(&pem, signed.pem()).map_err(at(&pem))?;
        write_private(&private, key.serialize_pem().as_bytes()).map_err(at(&private))?;
    }
    let secret = dir.join(SECRET);
    write_private(
        &secret,
        super::password().map_err(KeysError::Random)?.as_bytes(),
    )
    .map_err(at(&secret))?;
    // Last: a directory with the authority's certificate is complete.
    std::fs::write(dir.join(CA), ca_cert.pem()).map_err(at(&dir.join(CA)))
}

/// One core node's view of the stack's keys. No `Debug`: it holds the
/// link secret.
#[derive(Clone)]
pub(crate) struct StackKeys {
    dir: PathBuf,
    me: String,
    secret: String,
    core_nodes: Vec<String>,
}

impl StackKeys {
    /// The keys of core node `me` in `dir`, refused with what to do when
    /// they are missing.
    pub(crate) fn load(
        dir: &Path,
        me: &str,
        core_nodes: &[&str],
        launcher: &Path,
    ) -> Result<StackKeys, KeysError> {
        let missing = [
            CA.to_string(),
            SECRET.to_string(),
            format!("{CORES}/{me}.pem"),
            format!("{CORES}/{me}.key"),
        ]
        .into_iter()
        .find(|f| !dir.join(f).is_file());
        if let Some(file) = missing {
            return Err(KeysError::Missing {
                core: me.to_string(),
                missing: dir.join(file),
                launcher: launcher.to_path_buf(),
                dir: dir.to_path_buf(),
            });
        }
        let secret =
            std::fs::read_to_string(dir.join(SECRET)).map_err(|source| KeysError::ReadSecret {
                path: dir.join(SECRET),
                source,
            })?;
        Ok(StackKeys {
            dir: dir.to_path_buf(),
            me: me.to_string(),
            secret: secret.trim().to_string(),
            core_nodes: core_nodes.iter().map(|c| c.to_string()).collect(),
        })
    }

    /// The core nodes' names: their certificates' common names.
    pub(crate) fn core_nodes(&self) -> &[String] {
        &self.core_nodes
    }

    /// The login core node `core`'s router presents to the routers it
    /// links to.
    pub(crate) fn router_login(&self, core: &str) -> Login {
        let digest = Sha256::digest(format!("{}/{core}", self.secret).as_bytes());
        Login {
            user: format!("peppy-router-{core}"),
            password: digest.iter().map(|b| format!("{b:02x}")).collect(),
        }
    }

    /// Every core node router's login, for a router's dictionary.
    pub(crate) fn router_logins(&self) -> Vec<Login> {
        self.core_nodes
            .iter()
            .map(|c| self.router_login(c))
            .collect()
    }

    /// Zenoh's TLS settings for this core node's router: its certificate
    /// both ways, the stack's authority as the only one trusted, and the
    /// other side's certificate required.
    pub(crate) fn tls_settings(&self) -> Vec<(&'static str, serde_json::Value)> {
        let path = |f: String| serde_json::Value::from(self.dir.join(f).display().to_string());
        let cert = path(format!("{CORES}/{}.pem", self.me));
        let key = path(format!("{CORES}/{}.key", self.me));
        vec![
            (
                "transport/link/tls/root_ca_certificate",
                path(CA.to_string()),
            ),
            ("transport/link/tls/listen_certificate", cert.clone()),
            ("transport/link/tls/listen_private_key", key.clone()),
            ("transport/link/tls/connect_certificate", cert),
            ("transport/link/tls/connect_private_key", key),
            ("transport/link/tls/enable_mtls", true.into()),
            // Certificates name core nodes, not hosts: what is checked is
            // that the stack's authority signed them.
            ("transport/link/tls/verify_name_on_connect", false.into()),
        ]
    }
}

/// `tcp/...` as `tls/...`: links between core nodes of a secured stack.
pub(crate) fn over_tls(endpoint: &str) -> String {
    match endpoint.strip_prefix("tcp/") {
        Some(rest) => format!("tls/{rest}"),
        None => endpoint.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_created_private_and_loaded() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().unwrap();
        let keys = dir.path().join("stack");
        create(&keys, &["robot", "workstation"]).unwrap();
        for f in ["cores/robot.key", "cores/workstation.key", SECRET] {
            let mode = std::fs::metadata(keys.join(f))
                .unwrap()
                .permissions()
                .mode();
            assert_eq!(mode & 0o077, 0, "{f}");
        }
        assert!(
            !keys.join("ca.key").exists(),
            "the authority's key is never kept"
        );
        let pem = std::fs::read_to_string(keys.join("cores/robot.pem")).unwrap();
        assert!(pem.starts_with("-----BEGIN CERTIFICATE-----"));
        let robot = StackKeys::load(
            &keys,
            "robot",
            &["robot", "workstation"],
            Path::new("l.json5"),
        )
        .unwrap();
        let station = StackKeys::load(
            &keys,
            "workstation",
            &["robot", "workstation"],
            Path::new("l.json5"),
        )
        .unwrap();
        // Both sides derive the same logins.
        assert_eq!(
            robot.router_login("workstation"),
            station.router_login("workstation")
        );
        assert_ne!(
            robot.router_login("robot").password,
            robot.router_login("workstation").password
        );
        let Err(missing) = StackKeys::load(&keys, "lab", &["lab"], Path::new("l.json5")) else {
            panic!("keys for a core node that has none");
        };
        assert!(
            matches!(&missing, KeysError::Missing { core, missing, .. }
                if core == "lab" && missing.ends_with("cores/lab.pem")),
            "{missing}"
        );
        let text = missing.to_string();
        assert!(text.contains("cores/lab.pem is missing"), "{text}");
        assert!(text.contains("peppy-launch keys l.json5"), "{text}");
        assert_eq!(over_tls("tcp/0.0.0.0:7447"), "tls/0.0.0.0:7447");
        assert_eq!(over_tls("tls/[::1]:7447"), "tls/[::1]:7447");
    }
}
