//! An observer slot: its sources, each followed through its liveliness
//! token so a restarted source's old messages are dropped.

use super::*;

/// One source of an observer slot.
pub(super) struct Source {
    pub(super) instance: String,
    /// From the plan, or learned from the source's claim.
    pub(super) link_id: Mutex<Option<String>>,
    pub(super) planned_link: Option<String>,
    /// From the source's presence token.
    pub(super) core: Mutex<Option<String>>,
    pub(super) live: AtomicBool,
    pub(super) lanes: Mutex<Vec<Weak<Lane>>>,
}

/// One observer slot of this instance.
pub(crate) struct Observer {
    pub(super) slot: PairingSlot,
    pub(super) ns: String,
    pub(super) own_core: String,
    pub(super) session: zenoh::Session,
    pub(super) tools: Tools,
    pub(super) sources: Vec<Source>,
    pub(super) transitions: tokio::sync::Mutex<()>,
}

impl Observer {
    pub(super) fn source_info(&self, s: &Source) -> ObservedSource {
        let core = s.core.lock().unwrap_or_else(|p| p.into_inner()).clone();
        let link = s.link_id.lock().unwrap_or_else(|p| p.into_inner()).clone();
        ObservedSource {
            producer: ProducerRef::new(core.unwrap_or_else(|| self.own_core.clone()), &s.instance),
            source_link_id: link.unwrap_or_default(),
        }
    }

    pub(super) fn selector(&self, spec: &ConsumedTopicSpec, s: &Source) -> String {
        pairing_topic_selector(
            &self.ns,
            &self.slot.pairing.name,
            &self.slot.pairing.tag,
            spec.name,
            None,
            Some(&s.instance),
            s.planned_link.as_deref(),
        )
    }

    /// The sources, in link order.
    pub(crate) fn sources(&self) -> Vec<ObservedSource> {
        self.sources.iter().map(|s| self.source_info(s)).collect()
    }

    pub(super) async fn start(self: &Arc<Self>, stop: CancellationToken) -> Result<()> {
        if self.sources.is_empty() {
            return Ok(());
        }
        let live = self
            .session
            .liveliness()
            .declare_subscriber(all_liveliness_selector(&self.ns))
            .history(true)
            .await?;
        let claims = follow_claims(&self.session, &self.ns, &self.slot).await?;
        let me = self.clone();
        tokio::spawn(async move {
            loop {
                tokio::select! {
                    s = live.recv_async() => match s {
                        Ok(s) => me.presence(&s).await,
                        Err(_) => return,
                    },
                    s = claims.recv_async() => match s {
                        Ok(s) => me.claim(&s),
                        Err(_) => return,
                    },
                    () = stop.cancelled() => return,
                }
            }
        });
        Ok(())
    }

    /// A source's presence token came or went: a new run starts with
    /// empty inboxes.
    pub(super) async fn presence(&self, sample: &Sample) {
        let Some((core, instance)) = parse_liveliness_key(sample.key_expr().as_str()) else {
            return;
        };
        let Some(source) = self.sources.iter().find(|s| s.instance == instance) else {
            return;
        };
        match sample.kind() {
            SampleKind::Delete => source.live.store(false, Ordering::Relaxed),
            SampleKind::Put => {
                *source.core.lock().unwrap_or_else(|p| p.into_inner()) = Some(core);
                if source.live.swap(true, Ordering::Relaxed) {
                    return;
                }
                let _held = self.transitions.lock().await;
                let label = Label::Source(self.source_info(source));
                let lanes: Vec<Arc<Lane>> = {
                    let mut lanes = source.lanes.lock().unwrap_or_else(|p| p.into_inner());
                    lanes.retain(|l| l.strong_count() > 0);
                    lanes.iter().filter_map(Weak::upgrade).collect()
                };
                for lane in lanes {
                    lane.reset(label.clone(), &source.instance);
                }
                debug!(slot = %self.slot.link_id, source = %source.instance, "observing a new run of a source");
            }
        }
    }

    /// A claim of the watched role tells a source's slot when the plan
    /// did not.
    pub(super) fn claim(&self, sample: &Sample) {
        if sample.kind() != SampleKind::Put {
            return;
        }
        let Some(c) = SeenClaim::read(sample.key_expr().as_str(), &self.slot) else {
            return;
        };
        if c.role != self.slot.role {
            return;
        }
        for s in self.sources.iter().filter(|s| s.instance == c.instance) {
            if s.planned_link.is_none() {
                *s.link_id.lock().unwrap_or_else(|p| p.into_inner()) = Some(c.link_id.clone());
            }
            let mut core = s.core.lock().unwrap_or_else(|p| p.into_inner());
            core.get_or_insert_with(|| c.core.clone());
        }
    }

    /// One lane per source, sharing one wake-up.
    pub(super) async fn fan_in(&self, spec: &'static ConsumedTopicSpec) -> Result<FanIn> {
        let notify = Arc::new(Notify::new());
        let mut lanes = Vec::new();
        let _held = self.transitions.lock().await;
        for s in &self.sources {
            let lane = Lane::new(spec, self.tools.clone(), notify.clone());
            s.lanes
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push(Arc::downgrade(&lane));
            let label = Label::Source(self.source_info(s));
            lane.attach(&self.session, self.selector(spec, s), label, &s.instance)
                .await?;
            lanes.push(lane);
        }
        Ok(FanIn {
            lanes,
            notify,
            turn: 0,
        })
    }

    pub(super) fn info(&self) -> PairingSlotInfo {
        PairingSlotInfo {
            link_id: self.slot.link_id.clone(),
            pairing: self.slot.pairing.clone(),
            role: self.slot.role.clone(),
            observer: true,
            claiming: None,
            peer: None,
            sources: self
                .sources
                .iter()
                .map(|s| {
                    let o = self.source_info(s);
                    SourceInfo {
                        core_node: o.producer.core_node,
                        instance_id: o.producer.instance_id,
                        link_id: (!o.source_link_id.is_empty()).then_some(o.source_link_id),
                        live: s.live.load(Ordering::Relaxed),
                    }
                })
                .collect(),
        }
    }
}
