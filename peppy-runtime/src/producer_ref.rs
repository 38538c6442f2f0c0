//! Which producer a message came from, or a request goes to, as the
//! peppylib node API names it: [`ProducerRef`], and the never-empty bound set of a
//! `one_or_more` slot.

use std::fmt;

/// One producer instance: the launch (core node) that started it and its
/// instance id. Instance ids are unique in a stack, so `instance_id` alone
/// names the producer; `core_node` says where it runs.
#[derive(
    Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct ProducerRef {
    /// The launch (core node) that started the producer.
    pub core_node: String,
    /// The producer's instance id.
    pub instance_id: String,
}

impl ProducerRef {
    /// A producer from its core node and instance id.
    pub fn new(core_node: impl Into<String>, instance_id: impl Into<String>) -> Self {
        ProducerRef {
            core_node: core_node.into(),
            instance_id: instance_id.into(),
        }
    }

    /// What an accessor hands out for a slot that holds no producer it
    /// should (only reachable when start-up checks were bypassed): a call
    /// to it fails with `Error::TargetNotBound` instead of the node
    /// panicking.
    pub(crate) const UNBOUND: ProducerRef = ProducerRef {
        core_node: String::new(),
        instance_id: String::new(),
    };
}

impl fmt::Display for ProducerRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.instance_id)
    }
}

/// The producers bound to a `one_or_more` slot: never empty, so
/// [`first`](NonEmptyProducers::first) needs no `Option`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NonEmptyProducers<'a>(&'a [ProducerRef]);

impl<'a> NonEmptyProducers<'a> {
    /// The set, if it is not empty.
    pub fn new(producers: &'a [ProducerRef]) -> Option<Self> {
        (!producers.is_empty()).then_some(NonEmptyProducers(producers))
    }

    /// The first producer, in link order.
    pub fn first(&self) -> &'a ProducerRef {
        &self.0[0]
    }

    /// Every producer, in link order.
    pub fn as_slice(&self) -> &'a [ProducerRef] {
        self.0
    }

    /// How many producers the slot holds (at least one).
    #[allow(clippy::len_without_is_empty)]
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// The producers, in link order.
    pub fn iter(&self) -> std::slice::Iter<'a, ProducerRef> {
        self.0.iter()
    }
}

impl std::ops::Deref for NonEmptyProducers<'_> {
    type Target = [ProducerRef];

    fn deref(&self) -> &[ProducerRef] {
        self.0
    }
}

impl<'a> IntoIterator for NonEmptyProducers<'a> {
    type Item = &'a ProducerRef;
    type IntoIter = std::slice::Iter<'a, ProducerRef>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}
