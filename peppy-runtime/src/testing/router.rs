//! A harness's private Zenoh router: one per harness, on a loopback port
//! of its own, so tests running in parallel share no messaging state.

use std::time::Duration;

use tracing::debug;

use crate::error::{Error, Result};
use crate::startup::Endpoints;

/// How many free ports a harness tries before giving up: another process
/// may take the port the kernel named between its release and the
/// router's bind.
const PORT_ATTEMPTS: usize = 8;

/// A running private router and the endpoint the harness's sessions
/// connect to.
pub(crate) struct PrivateRouter {
    session: zenoh::Session,
    pub(crate) port: u16,
}

impl PrivateRouter {
    /// Starts a router listening on a free port of 127.0.0.1 (no
    /// multicast scouting, no gossip beyond its own clients).
    pub(crate) async fn start() -> Result<PrivateRouter> {
        let mut last = String::new();
        for _ in 0..PORT_ATTEMPTS {
            let port = free_port()?;
            let endpoints = Endpoints {
                mode: Some("router".into()),
                listen: vec![format!("tcp/127.0.0.1:{port}")],
                ..Endpoints::default()
            };
            let config = endpoints.zenoh_config()?;
            match zenoh::open(config).await {
                Ok(session) => return Ok(PrivateRouter { session, port }),
                Err(e) => {
                    debug!(
                        port,
                        "the test router could not listen: {e}; trying another port"
                    );
                    last = e.to_string();
                }
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        Err(Error::Startup(format!(
            "cannot start the test harness's router on 127.0.0.1 after {PORT_ATTEMPTS} ports: {last}"
        )))
    }

    /// The router's own session (the harness serves the clock on it).
    pub(crate) fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// Closes the router.
    pub(crate) async fn close(&self) {
        let _ = self.session.close().await;
    }
}

/// A port of 127.0.0.1 free at the moment of asking.
fn free_port() -> Result<u16> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0")
        .map_err(|e| Error::Startup(format!("cannot find a free loopback port: {e}")))?;
    listener
        .local_addr()
        .map(|a| a.port())
        .map_err(|e| Error::Startup(format!("cannot find a free loopback port: {e}")))
}
