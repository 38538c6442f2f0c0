//! Direct links need Unix sockets: elsewhere every topic stays on Zenoh
//! alone, through the same calls.

use std::path::{Path, PathBuf};

/// Which publisher a Zenoh sample comes from.
pub(crate) type SourceId = ([u8; 16], u32);

/// The source id of a publisher or a sample's source info.
pub(crate) fn source_id(id: &zenoh::session::EntityGlobalId) -> SourceId {
    (id.zid().to_le_bytes(), id.eid())
}

/// Where a node's socket would be.
pub(crate) fn socket_path(dir: &Path, _core: &str, _instance: &str) -> PathBuf {
    dir.to_path_buf()
}

pub(crate) mod outlet {
    use std::path::Path;
    use std::sync::Arc;

    use peppy_schema::QosProfile;
    use tokio_util::sync::CancellationToken;
    use zenoh::Wait;
    use zenoh::bytes::ZBytes;
    use zenoh::pubsub::Publisher;

    /// An emitted topic, published through Zenoh only.
    #[derive(Debug)]
    pub(crate) struct DirectOutlet;

    impl DirectOutlet {
        pub(crate) fn new(
            _session: &zenoh::Session,
            _publisher: &Publisher<'static>,
            _readers: std::sync::Arc<std::sync::atomic::AtomicBool>,
            _qos: QosProfile,
            _fingerprint: u64,
        ) -> Self {
            DirectOutlet
        }

        pub(crate) fn close(&self) {}

        pub(crate) fn links(&self) -> usize {
            0
        }

        pub(crate) fn sole_readers(&self) -> bool {
            false
        }

        pub(crate) fn publish(
            &self,
            publisher: &Publisher<'static>,
            payload: ZBytes,
            attachment: ZBytes,
        ) -> zenoh::Result<()> {
            publisher.put(payload).attachment(attachment).wait()
        }

        pub(crate) fn carries_alone(&self, _len: usize) -> bool {
            false
        }

        pub(crate) fn place(
            &self,
            _len: usize,
            _encode: impl FnOnce(&mut [u8]) -> bool,
        ) -> Option<Placed> {
            None
        }

        pub(crate) fn publish_placed(
            &self,
            _publisher: &Publisher<'static>,
            placed: Placed,
            _attachment: ZBytes,
        ) -> zenoh::Result<()> {
            match placed {}
        }
    }

    /// No message is placed in a link's memory.
    #[derive(Debug)]
    pub(crate) enum Placed {}

    impl Placed {
        pub(crate) fn len(&self) -> usize {
            match *self {}
        }

        pub(crate) fn copied(self) -> ZBytes {
            match self {}
        }
    }

    /// No socket.
    #[derive(Debug)]
    pub(crate) struct Listener;

    /// No topic is served.
    #[derive(Debug, Default)]
    pub(crate) struct Outlets;

    impl Outlets {
        pub(crate) fn add(&self, _outlet: &Arc<DirectOutlet>) {}

        pub(crate) fn close_all(&self) {}
    }

    pub(crate) fn serve(
        _path: &Path,
        _outlets: Arc<Outlets>,
        _shared: bool,
        _token: CancellationToken,
    ) -> Option<Listener> {
        None
    }
}

pub(crate) mod inlet {
    use std::path::PathBuf;
    use std::sync::Arc;

    use tokio_util::sync::CancellationToken;

    use crate::topics::{Arrival, Intake};

    /// A consumer that reads through Zenoh only.
    #[derive(Debug)]
    pub(crate) struct Consumer;

    impl Consumer {
        pub(crate) fn new(
            _dir: PathBuf,
            _name: String,
            _shared: bool,
            _runtime: tokio::runtime::Handle,
            _token: CancellationToken,
        ) -> Arc<Consumer> {
            Arc::new(Consumer)
        }
    }

    /// No links.
    #[derive(Debug)]
    pub(crate) struct Inlet;

    /// Every message is queued.
    pub(crate) enum Route {
        Take(Arrival),
        #[allow(dead_code)]
        Handled,
    }

    impl Inlet {
        pub(crate) fn new(_consumer: Arc<Consumer>) -> Inlet {
            Inlet
        }

        pub(crate) fn bind(&self, _intake: &Arc<Intake>) {}

        pub(crate) fn route(
            &self,
            arrival: Arrival,
            _source: Option<(super::SourceId, u32)>,
        ) -> Route {
            Route::Take(arrival)
        }
    }
}
