//! A participant slot: its claim token, the claims it follows, and the
//! pair that holds while it and its peer claim each other.

use super::*;

/// The current pair of a participant slot; `generation` counts pairs.
#[derive(Debug, Clone, Default)]
pub(super) struct Pair {
    pub(super) generation: u64,
    pub(super) peer: Option<PeerInfo>,
}

/// A claim as read from its token.
#[derive(Debug, Clone)]
pub(super) struct SeenClaim {
    pub(super) role: String,
    pub(super) core: String,
    pub(super) instance: String,
    pub(super) link_id: String,
    pub(super) peer: Option<(String, String)>,
}

impl SeenClaim {
    pub(super) fn read(key: &str, slot: &PairingSlot) -> Option<SeenClaim> {
        let c = Claim::parse(key)?;
        (c.pairing == slot.pairing.name && c.tag == slot.pairing.tag).then(|| SeenClaim {
            role: c.role.to_string(),
            core: c.core.to_string(),
            instance: c.instance.to_string(),
            link_id: c.link_id.to_string(),
            peer: c.peer.map(|(i, l)| (i.to_string(), l.to_string())),
        })
    }

    pub(super) fn claims(&self, instance: &str, link_id: &str) -> bool {
        self.peer
            .as_ref()
            .is_some_and(|(i, l)| i == instance && l == link_id)
    }

    pub(super) fn is(&self, instance: &str, link_id: &str) -> bool {
        self.instance == instance && self.link_id == link_id
    }
}

/// One participant slot of this instance.
pub(crate) struct Participant {
    pub(super) slot: PairingSlot,
    pub(super) ns: String,
    pub(super) core: String,
    pub(super) instance: String,
    pub(super) session: zenoh::Session,
    pub(super) tools: Tools,
    pub(super) state: watch::Sender<Pair>,
    /// The slot it claims (for `node info`).
    pub(super) claiming: Mutex<Option<PairEnd>>,
    pub(super) lanes: Mutex<Vec<Weak<Lane>>>,
    /// Held while lanes are attached: a new pair and a new subscription
    /// never interleave.
    pub(super) transitions: tokio::sync::Mutex<()>,
    /// The publisher of each of its topics, by name, while a handle holds
    /// it: handles declared for one topic share one publisher, as an
    /// emitted topic's do, so the peer hears one sender (one numbering on
    /// a direct link).
    pub(super) senders: tokio::sync::Mutex<HashMap<&'static str, Weak<PairedSender>>>,
}

impl Participant {
    /// Whether a claim's role is this slot's counterpart. Before resolution
    /// filled it in, any other role is.
    pub(super) fn counterpart(&self, role: &str) -> bool {
        if self.slot.counterpart.is_empty() {
            role != self.slot.role
        } else {
            role == self.slot.counterpart
        }
    }

    pub(super) fn claim_key(&self, target: Option<&PairEnd>) -> String {
        let peer = target.and_then(|t| Some((t.instance.as_str(), t.link_id.as_deref()?)));
        Claim {
            pairing: &self.slot.pairing.name,
            tag: &self.slot.pairing.tag,
            role: &self.slot.role,
            core: &self.core,
            instance: &self.instance,
            link_id: &self.slot.link_id,
            peer,
        }
        .key(&self.ns)
    }

    pub(super) fn peer_selector(&self, spec: &ConsumedTopicSpec, peer: &PeerInfo) -> String {
        pairing_topic_selector(
            &self.ns,
            &self.slot.pairing.name,
            &self.slot.pairing.tag,
            spec.name,
            None,
            Some(&peer.producer.instance_id),
            Some(&peer.peer_link_id),
        )
    }

    /// The peer, while paired.
    pub(crate) fn peer(&self) -> Option<PeerInfo> {
        self.state.borrow().peer.clone()
    }

    /// Whether the pair holds, without copying the peer (asked per publish).
    pub(crate) fn is_paired(&self) -> bool {
        self.state.borrow().peer.is_some()
    }

    /// Waits until paired; `None` once `stop` fires.
    pub(super) async fn wait_paired(&self, stop: &CancellationToken) -> Option<PeerInfo> {
        let mut rx = self.state.subscribe();
        tokio::select! {
            r = rx.wait_for(|p| p.peer.is_some()) => r.ok().and_then(|p| p.peer.clone()),
            () = stop.cancelled() => None,
        }
    }

    /// Declares the slot's first claim and starts the task that follows
    /// the pairing's claims.
    pub(super) async fn start(
        self: &Arc<Self>,
        plan: Option<PairEnd>,
        stop: CancellationToken,
    ) -> Result<()> {
        let key = self.claim_key(plan.as_ref());
        let token = self.session.liveliness().declare_token(key.clone()).await?;
        *self.claiming.lock().unwrap_or_else(|p| p.into_inner()) = plan.clone();
        let claims = follow_claims(&self.session, &self.ns, &self.slot).await?;
        let me = self.clone();
        tokio::spawn(async move {
            let mut follow = Follow {
                target: plan,
                claim_key: key,
                token,
                claims: HashMap::new(),
                warned: HashSet::new(),
            };
            me.follow(&mut follow, claims, stop).await;
        });
        Ok(())
    }

    pub(super) async fn follow(
        &self,
        f: &mut Follow,
        claims: Subscriber<FifoChannelHandler<Sample>>,
        stop: CancellationToken,
    ) {
        loop {
            let sample = tokio::select! {
                s = claims.recv_async() => match s {
                    Ok(s) => s,
                    Err(_) => return,
                },
                () = stop.cancelled() => return,
            };
            // What is already queued is read before deciding: the history
            // of a new subscription is one picture, not a sequence.
            let mut peer_went = self.absorb(f, &sample);
            while let Ok(Some(s)) = claims.try_recv() {
                peer_went |= self.absorb(f, &s);
            }
            if let Err(e) = self.step(f, peer_went).await {
                warn!(slot = %self.slot.link_id, error = %e, "pairing: could not follow a change of claims");
            }
        }
    }

    /// Records one claim's arrival or departure; whether it was the
    /// current peer's claim that went.
    pub(super) fn absorb(&self, f: &mut Follow, sample: &Sample) -> bool {
        let key = sample.key_expr().as_str();
        match sample.kind() {
            SampleKind::Put => {
                if let Some(c) = SeenClaim::read(key, &self.slot) {
                    f.claims.insert(key.to_string(), c);
                }
                false
            }
            SampleKind::Delete => {
                let gone = f.claims.remove(key);
                let peer = self.peer();
                gone.zip(peer).is_some_and(|(c, p)| {
                    c.is(&p.producer.instance_id, &p.peer_link_id)
                        && c.claims(&self.instance, &self.slot.link_id)
                })
            }
        }
    }

    /// Decides the slot's claim and pair from the claims seen.
    pub(super) async fn step(&self, f: &mut Follow, peer_went: bool) -> Result<()> {
        let (me, my_link) = (self.instance.as_str(), self.slot.link_id.as_str());
        let theirs = |c: &&SeenClaim| self.counterpart(&c.role) && !c.is(me, my_link);
        // A plan naming only the instance: its one slot of the
        // counterpart role, or the one already claiming this slot.
        if let Some(t) = f.target.as_mut()
            && t.link_id.is_none()
        {
            let of_peer: Vec<&SeenClaim> = f
                .claims
                .values()
                .filter(theirs)
                .filter(|c| c.instance == t.instance)
                .collect();
            let links: HashSet<&str> = of_peer.iter().map(|c| c.link_id.as_str()).collect();
            let chosen = of_peer
                .iter()
                .find(|c| c.claims(me, my_link))
                .map(|c| c.link_id.clone())
                .or_else(|| (links.len() == 1).then(|| of_peer[0].link_id.clone()));
            if let Some(link) = chosen {
                debug!(slot = my_link, peer = %t.instance, peer_slot = %link, "pairing: found the peer's slot");
                t.link_id = Some(link);
            }
        }
        let peer_of = |t: &PairEnd| {
            let link = t.link_id.as_deref()?;
            f.claims
                .values()
                .filter(theirs)
                .find(|c| c.is(&t.instance, link) && c.claims(me, my_link))
                .map(|c| PeerInfo {
                    producer: ProducerRef::new(&c.core, &c.instance),
                    peer_link_id: c.link_id.clone(),
                })
        };
        let mut peer = f.target.as_ref().and_then(peer_of);
        if peer.is_none() {
            // Unpaired: a slot claiming this one becomes its peer.
            let target = f.target.clone();
            let mut claimers: Vec<&SeenClaim> = f
                .claims
                .values()
                .filter(theirs)
                .filter(|c| c.claims(me, my_link))
                .filter(|c| {
                    target
                        .as_ref()
                        .is_none_or(|t| !c.is(&t.instance, t.link_id.as_deref().unwrap_or("")))
                })
                .collect();
            claimers.sort_by(|a, b| (&a.instance, &a.link_id).cmp(&(&b.instance, &b.link_id)));
            if let Some(c) = claimers.first() {
                info!(slot = my_link, peer = %c.instance, peer_slot = %c.link_id, "pairing: taking a new peer that claims this slot");
                f.target = Some(PairEnd {
                    instance: c.instance.clone(),
                    link_id: Some(c.link_id.clone()),
                });
                peer = Some(PeerInfo {
                    producer: ProducerRef::new(&c.core, &c.instance),
                    peer_link_id: c.link_id.clone(),
                });
            }
        } else if let Some(p) = &peer {
            for c in f.claims.values().filter(theirs) {
                if c.claims(me, my_link)
                    && !c.is(&p.producer.instance_id, &p.peer_link_id)
                    && f.warned.insert(format!("{}/{}", c.instance, c.link_id))
                {
                    warn!(slot = my_link, claimer = %format_args!("{}/{}", c.instance, c.link_id), peer = %p.producer.instance_id, "pairing: ignoring a claim on a paired slot");
                }
            }
        }
        let key = self.claim_key(f.target.as_ref());
        if key != f.claim_key {
            let token = self.session.liveliness().declare_token(key.clone()).await?;
            // The old claim goes once the new one is out.
            let old = std::mem::replace(&mut f.token, token);
            let _ = old.undeclare().await;
            f.claim_key = key;
            *self.claiming.lock().unwrap_or_else(|p| p.into_inner()) = f.target.clone();
        }
        let current = self.peer();
        if current != peer || (peer_went && peer.is_some()) {
            self.apply(peer).await;
        }
        Ok(())
    }

    /// Moves to a new pair (or none): every lane starts an empty inbox on
    /// the new peer's keys, or is cleared.
    pub(super) async fn apply(&self, peer: Option<PeerInfo>) {
        let _held = self.transitions.lock().await;
        let generation = self.state.borrow().generation + u64::from(peer.is_some());
        for lane in self.live_lanes() {
            match &peer {
                Some(p) => {
                    let selector = self.peer_selector(lane.spec, p);
                    let label = Label::Peer(p.clone());
                    if let Err(e) = lane
                        .attach(&self.session, selector, label, &p.producer.instance_id)
                        .await
                    {
                        warn!(slot = %self.slot.link_id, topic = lane.spec.name, error = %e, "pairing: could not subscribe to the peer");
                    }
                }
                None => lane.clear(),
            }
        }
        match &peer {
            Some(p) => {
                info!(slot = %self.slot.link_id, peer = %p.producer.instance_id, peer_slot = %p.peer_link_id, "paired")
            }
            None => info!(slot = %self.slot.link_id, "unpaired"),
        }
        self.state.send_replace(Pair { generation, peer });
    }

    pub(super) fn live_lanes(&self) -> Vec<Arc<Lane>> {
        let mut lanes = self.lanes.lock().unwrap_or_else(|p| p.into_inner());
        lanes.retain(|l| l.strong_count() > 0);
        lanes.iter().filter_map(Weak::upgrade).collect()
    }

    /// A new lane of `spec`, attached to the current peer if any.
    pub(super) async fn lane(
        &self,
        spec: &'static ConsumedTopicSpec,
    ) -> Result<(Arc<Lane>, Arc<Notify>)> {
        let notify = Arc::new(Notify::new());
        let lane = Lane::new(spec, self.tools.clone(), notify.clone());
        let _held = self.transitions.lock().await;
        self.lanes
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(Arc::downgrade(&lane));
        if let Some(p) = self.peer() {
            let selector = self.peer_selector(spec, &p);
            let instance = p.producer.instance_id.clone();
            lane.attach(&self.session, selector, Label::Peer(p), &instance)
                .await?;
        }
        Ok((lane, notify))
    }

    pub(super) fn info(&self) -> PairingSlotInfo {
        PairingSlotInfo {
            link_id: self.slot.link_id.clone(),
            pairing: self.slot.pairing.clone(),
            role: self.slot.role.clone(),
            observer: false,
            claiming: self
                .claiming
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .as_ref()
                .map(ToString::to_string),
            peer: self.peer().map(|p| PeerEndInfo {
                core_node: p.producer.core_node,
                instance_id: p.producer.instance_id,
                link_id: p.peer_link_id,
            }),
            sources: Vec::new(),
        }
    }
}

/// What a participant's task keeps between claims.
pub(super) struct Follow {
    /// The slot claimed (or waited for, its slot not yet known).
    pub(super) target: Option<PairEnd>,
    pub(super) claim_key: String,
    pub(super) token: LivelinessToken,
    pub(super) claims: HashMap<String, SeenClaim>,
    /// Claimers ignored while paired, each logged once.
    pub(super) warned: HashSet<String>,
}
