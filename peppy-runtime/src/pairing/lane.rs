//! A consumed pairing topic from one sender: its Zenoh subscription and
//! the inbox of the current pair, and the fan-in an observer reads.

use super::*;

/// Who a lane's messages are from, handed out with each message.
#[derive(Debug, Clone)]
pub(super) enum Label {
    Peer(PeerInfo),
    Source(ObservedSource),
}

/// The inbox of the current pair (or source run) of one lane.
pub(super) struct Current {
    /// Shared with the direct links it reads (they hold it weakly, so a
    /// new pair's intake ends the old one's reading).
    pub(super) intake: Arc<Intake>,
    pub(super) inbox: Inbox,
    pub(super) label: Label,
}

/// One consumed pairing topic from one sender (the peer, or one observed
/// source): a Zenoh subscription on the sender's key, and the inbox of the
/// current pair.
pub(crate) struct Lane {
    pub(super) spec: &'static ConsumedTopicSpec,
    pub(super) tools: Tools,
    pub(super) current: Mutex<Option<Current>>,
    pub(super) subscriber: tokio::sync::Mutex<Option<(String, Subscriber<()>)>>,
    /// Shared by the lanes one subscription reads.
    pub(super) notify: Arc<Notify>,
}

impl Lane {
    pub(super) fn new(
        spec: &'static ConsumedTopicSpec,
        tools: Tools,
        notify: Arc<Notify>,
    ) -> Arc<Lane> {
        Arc::new(Lane {
            spec,
            tools,
            current: Mutex::new(None),
            subscriber: tokio::sync::Mutex::new(None),
            notify,
        })
    }

    /// Zenoh's callback: queued only while a pair (or run) is current (the
    /// intake tells the fan-in).
    pub(super) fn accept(&self, sample: Sample) {
        let current = self.current.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(c) = current.as_ref() {
            c.intake.accept(sample);
        }
    }

    /// Starts a new pair (or run): an empty inbox that admits `instance`
    /// only, then a subscription on `selector` unless one is held already.
    pub(super) async fn attach(
        self: &Arc<Self>,
        session: &zenoh::Session,
        selector: String,
        label: Label,
        instance: &str,
    ) -> Result<()> {
        self.reset(label, instance);
        let mut held = self.subscriber.lock().await;
        if held.as_ref().is_some_and(|(s, _)| *s == selector) {
            return Ok(());
        }
        // Weak: the subscription must not keep its own lane alive.
        let lane = Arc::downgrade(self);
        let subscriber = session
            .declare_subscriber(selector.clone())
            .callback(move |s| {
                if let Some(lane) = lane.upgrade() {
                    lane.accept(s);
                }
            })
            .await?;
        *held = Some((selector, subscriber));
        Ok(())
    }

    /// A fresh inbox: whatever the previous one held is dropped with it.
    /// On a launch's host the sender is read over a direct link, as a
    /// consumed topic's producer is.
    pub(super) fn reset(&self, label: Label, instance: &str) {
        let (intake, inbox) = Intake::new(
            self.spec,
            RouteFilter::Pin(instance.to_string()),
            None,
            self.tools.declarer.clone(),
            self.tools.mismatch.clone(),
        );
        let intake = intake
            .with_notify(self.notify.clone())
            .linked(self.tools.direct.as_ref());
        *self.current.lock().unwrap_or_else(|p| p.into_inner()) = Some(Current {
            intake,
            inbox,
            label,
        });
    }

    /// No pair: nothing is queued, and what was is dropped.
    pub(super) fn clear(&self) {
        *self.current.lock().unwrap_or_else(|p| p.into_inner()) = None;
    }

    /// How many of the current pair's (or run's) messages came over a
    /// direct link.
    pub(super) fn received_over_direct_links(&self) -> u64 {
        let current = self.current.lock().unwrap_or_else(|p| p.into_inner());
        current.as_ref().map_or(0, |c| {
            c.inbox
                .backlog
                .direct
                .load(std::sync::atomic::Ordering::Relaxed)
        })
    }

    /// The next queued message, without waiting.
    pub(super) fn take(&self) -> Option<(Label, Delivery)> {
        let current = self.current.lock().unwrap_or_else(|p| p.into_inner());
        let c = current.as_ref()?;
        topics::take_ready(&c.inbox, self.spec).map(|d| (c.label.clone(), d))
    }
}

/// The lanes one subscription reads, in turn.
pub(super) struct FanIn {
    pub(super) lanes: Vec<Arc<Lane>>,
    pub(super) notify: Arc<Notify>,
    pub(super) turn: usize,
}

impl FanIn {
    /// How many messages of its lanes' current pairs came over a direct
    /// link.
    pub(super) fn received_over_direct_links(&self) -> u64 {
        self.lanes
            .iter()
            .map(|l| l.received_over_direct_links())
            .sum()
    }

    /// The next message of any lane; `None` once the node stops.
    pub(super) async fn next(&mut self, stop: &CancellationToken) -> Option<(Label, Delivery)> {
        loop {
            if stop.is_cancelled() {
                return None;
            }
            let n = self.lanes.len();
            for k in 0..n {
                let i = (self.turn + k) % n;
                if let Some(got) = self.lanes[i].take() {
                    self.turn = i + 1;
                    return Some(got);
                }
            }
            // A message queued since the scan left a permit: no wake-up
            // is lost.
            tokio::select! {
                () = self.notify.notified() => {}
                () = stop.cancelled() => return None,
            }
        }
    }
}
