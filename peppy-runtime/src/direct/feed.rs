//! A pinned entry's subscription through Zenoh, which a sole link moves
//! to the producer's side key.
//!
//! Zenoh delivers a publication to every session with a matching
//! subscription and cannot leave one out, so a consumer that reads a
//! producer over a link and also subscribes to its key receives every
//! message twice, and half the CPU of a small round trip on one host went
//! to the copy it then dropped (docs/PERFORMANCE.md, "Not yet met"). An
//! entry pinned to one producer subscribes to that producer's key alone:
//! once a link to it is answered and the entry knows where the link's
//! numbers stand, it subscribes to the producer's side key for this node
//! (what the link does not carry) and then drops its own; when the link
//! ends it subscribes to its own key again and then drops the side key.
//! Each move declares the new subscription before it undeclares the old,
//! and Zenoh passes a session's declarations to a peer in order, so the
//! producer never publishes a message this entry receives through
//! neither; the producer goes on publishing under an ended link's side
//! key until this entry has left it.

use std::sync::{Arc, Mutex, Weak};

use tracing::{debug, warn};
use zenoh::Session;
use zenoh::key_expr::KeyExpr;
use zenoh::pubsub::Subscriber;

use super::SourceId;
use crate::topics::Intake;

/// How long an entry moved to a key still reads the one it came from.
const LINGER: std::time::Duration = super::HOLD_LIMIT;

/// Which key a pinned entry reads its producer through.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Sole {
    /// The producer's side key for this node.
    pub(crate) side: String,
    /// The producer's topic key: side copies are handed on under it.
    pub(crate) key: KeyExpr<'static>,
    /// The producer's publisher, whose numbers side copies carry.
    pub(crate) source: SourceId,
}

/// A pinned entry's subscription: its own key's, or its producer's side
/// key's while a sole link carries the producer.
#[derive(Debug)]
pub(crate) struct Feed {
    session: Session,
    selector: String,
    intake: Weak<Intake>,
    runtime: tokio::runtime::Handle,
    /// What the entry should read through: `None` its own key.
    want: Mutex<Option<Sole>>,
    /// What it reads through, changed by one move at a time.
    held: tokio::sync::Mutex<Held>,
    /// The side key for which the own key may be left before the linger
    /// ends: the entry has every message the own key alone brought.
    left: Mutex<Option<String>>,
    left_now: tokio::sync::Notify,
    /// The node stopped: nothing is declared again.
    closed: std::sync::atomic::AtomicBool,
}

#[derive(Debug, Default)]
struct Held {
    own: Option<Subscriber<()>>,
    side: Option<(Sole, Subscriber<()>)>,
}

impl Feed {
    /// The feed of `intake`, which reads `selector` through `own`.
    pub(crate) fn new(
        session: Session,
        selector: String,
        intake: &Arc<Intake>,
        own: Subscriber<()>,
    ) -> Arc<Feed> {
        Arc::new(Feed {
            session,
            selector,
            intake: Arc::downgrade(intake),
            runtime: tokio::runtime::Handle::current(),
            want: Mutex::new(None),
            held: tokio::sync::Mutex::new(Held {
                own: Some(own),
                side: None,
            }),
            left: Mutex::new(None),
            left_now: tokio::sync::Notify::new(),
            closed: std::sync::atomic::AtomicBool::new(false),
        })
    }

    /// Undeclares the entry's subscriptions (the node stops), with the
    /// node's others.
    pub(crate) async fn close(&self) {
        self.closed
            .store(true, std::sync::atomic::Ordering::Relaxed);
        let mut held = self.held.lock().await;
        if let Some(own) = held.own.take() {
            let _ = own.undeclare().await;
        }
        if let Some((_, side)) = held.side.take() {
            let _ = side.undeclare().await;
        }
    }

    /// The entry has every message the own key alone brought before its
    /// producer started publishing to `side` what the link does not
    /// carry: the own key can be left now.
    pub(crate) fn leave_own(&self, side: &str) {
        if let Ok(mut left) = self.left.lock() {
            *left = Some(side.to_string());
        }
        self.left_now.notify_waiters();
    }

    /// Waits until the own key may be left for `side`, or the linger ends.
    async fn until_own_left(&self, side: &str) {
        let deadline = tokio::time::Instant::now() + LINGER;
        loop {
            let notified = self.left_now.notified();
            tokio::pin!(notified);
            notified.as_mut().enable();
            if self
                .left
                .lock()
                .map_or(true, |l| l.as_deref() == Some(side))
            {
                return;
            }
            tokio::select! {
                () = tokio::time::sleep_until(deadline) => return,
                () = &mut notified => {}
            }
        }
    }

    /// Moves the entry to `sole`'s side key (`None`: back to its own key),
    /// in the background; moves asked in a row end at the last one.
    pub(crate) fn switch(self: &Arc<Self>, sole: Option<Sole>) {
        match self.want.lock() {
            Ok(mut want) => *want = sole,
            Err(_) => return,
        }
        // A leave for an earlier move to the same side key is not this
        // one's.
        if let Ok(mut left) = self.left.lock() {
            *left = None;
        }
        let feed = self.clone();
        self.runtime.spawn(async move { feed.settle().await });
    }

    /// Brings the subscriptions to what is wanted: the new one declared,
    /// and the old one undeclared a while later. Copies published before
    /// the producer heard of the new subscription may still be on their
    /// way through the old one (a large one takes a while), and some are
    /// on neither the link nor the new key: the old is left only once they
    /// have come. What both bring meanwhile is the same message twice,
    /// numbered, and handed on once.
    async fn settle(&self) {
        let Some(want) = self.declare().await else {
            return;
        };
        match &want {
            // The own key is left as soon as nothing can be on its way
            // through it alone (the producer says from which message on
            // it publishes to the side key).
            Some(sole) => self.until_own_left(&sole.side).await,
            None => tokio::time::sleep(LINGER).await,
        }
        let mut held = self.held.lock().await;
        if self.want.lock().ok().as_deref() != Some(&want) {
            return; // Another move came meanwhile: it ends the old.
        }
        match want {
            Some(_) => {
                if let Some(own) = held.own.take() {
                    let _ = own.undeclare().await;
                }
            }
            None => {
                if let Some((_, side)) = held.side.take() {
                    let _ = side.undeclare().await;
                }
            }
        }
    }

    /// Declares the subscription wanted, if it is not yet: what is wanted,
    /// `None` if nothing is (left) to do.
    async fn declare(&self) -> Option<Option<Sole>> {
        let mut held = self.held.lock().await;
        if self.closed.load(std::sync::atomic::Ordering::Relaxed) {
            return None;
        }
        let want = self.want.lock().ok()?.clone();
        let intake = self.intake.upgrade()?;
        match &want {
            Some(sole) => {
                if held.side.as_ref().map(|(s, _)| s) != Some(sole) {
                    let key = sole.key.clone();
                    let reader = intake.clone();
                    let declared = self
                        .session
                        .declare_subscriber(sole.side.clone())
                        .callback(move |sample| reader.accept_side(&key, sample))
                        .await;
                    match declared {
                        Ok(subscriber) => {
                            if let Some((_, old)) = held.side.replace((sole.clone(), subscriber)) {
                                // A restarted producer's predecessor's.
                                let _ = old.undeclare().await;
                            }
                        }
                        Err(e) => {
                            // Still on its own key: the link's messages and
                            // Zenoh's are merged as before.
                            debug!(error = %e, "a side key could not be subscribed to");
                            return None;
                        }
                    }
                }
                held.own.is_some().then_some(want)
            }
            None => {
                if held.own.is_none() {
                    let reader = intake.clone();
                    let declared = self
                        .session
                        .declare_subscriber(self.selector.clone())
                        .callback(move |sample| reader.accept(sample))
                        .await;
                    match declared {
                        Ok(subscriber) => held.own = Some(subscriber),
                        Err(e) => {
                            // The side key stays: the producer publishes
                            // there for as long as it is read.
                            if !self.session.is_closed() {
                                warn!(selector = self.selector, error = %e, "a consumed topic could not be subscribed to again after its direct link ended");
                            }
                            return None;
                        }
                    }
                }
                held.side.is_some().then_some(want)
            }
        }
    }
}
