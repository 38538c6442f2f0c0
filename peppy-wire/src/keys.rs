//! Zenoh key expressions: every key and selector of peppy is built (and
//! read back) here, so the shape of a key is written down once
//! (docs/WIRE.md §1; the Python runtime's twin is `peppy/keys.py`, and
//! `tests/golden/wire.json` holds the keys both must build). Every key
//! starts with `peppy/<namespace>/`, so two stacks in different namespaces
//! never see each other's traffic; the sender's identity (core node and
//! instance id) is in the key, so a subscriber can pin a producer with the
//! key alone.
//!
//! ```text
//! peppy/<ns>/topic/<kind>/<name>/<tag>/<topic>/<core>/<instance>
//! peppy/<ns>/service/<kind>/<name>/<tag>/<service>/<core>/<instance>
//! peppy/<ns>/action/<kind>/<name>/<tag>/<action>/<core>/<instance>/<goal|cancel|result>
//! peppy/<ns>/action/<kind>/<name>/<tag>/<action>/<core>/<instance>/feedback/<goal_id>
//! peppy/<ns>/topic/pairing/<pairing>/<tag>/<topic>/<core>/<instance>/<link_id>
//! peppy/<ns>/pair/<pairing>/<tag>/<role>/<core>/<instance>/<link_id>/<peer_instance>/<peer_link_id>
//! peppy/<ns>/live/<core>/<instance>/<node>/<tag>
//! peppy/<ns>/format/<fingerprint as 16 hex>/<instance>
//! peppy/<ns>/describe/<core>/<instance>
//! peppy/<ns>/core/<core>/<launch>
//! peppy/<ns>/clock/tick/<wall|sim>
//! peppy/<ns>/clock/sync
//! ```
//!
//! `<kind>` is `node` for a node's own declarations and `interface` for
//! entries inherited through `conforms_to`: the two never match each other.
//! A pairing's topics are `topic/pairing/...`, published under the sender's
//! instance and pairing slot; `pair/...` are the claim tokens of pairing
//! slots (docs/PAIRINGS.md §3), `~/~` for a slot claiming nobody.

use std::fmt;

/// Whose contract an entry belongs to on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Owner<'a> {
    /// A node's own declaration.
    Node {
        /// Node name.
        name: &'a str,
        /// Node tag.
        tag: &'a str,
    },
    /// An entry of a conformed interface.
    Interface {
        /// Interface name.
        name: &'a str,
        /// Interface tag.
        tag: &'a str,
    },
}

impl fmt::Display for Owner<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Owner::Node { name, tag } => write!(f, "node/{name}/{tag}"),
            Owner::Interface { name, tag } => write!(f, "interface/{name}/{tag}"),
        }
    }
}

/// The three kinds of entry keys.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// Topic publications.
    Topic,
    /// Service queries.
    Service,
    /// Action sub-services and feedback.
    Action,
}

impl Channel {
    fn parse(s: &str) -> Option<Channel> {
        match s {
            "topic" => Some(Channel::Topic),
            "service" => Some(Channel::Service),
            "action" => Some(Channel::Action),
            _ => None,
        }
    }
}

/// What a key of a namespace is about: its third segment, after
/// `peppy/<ns>/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Space {
    /// Topic publications (and the queryables producers declare on them).
    Topic,
    /// Service queryables.
    Service,
    /// Action sub-services and feedback.
    Action,
    /// Instances' liveliness tokens.
    Live,
    /// Pairing slots' claim tokens.
    Pair,
    /// Where instances answer the canonical text of their formats.
    Format,
    /// Where instances answer their descriptions.
    Describe,
    /// Launches' core node tokens.
    Core,
    /// The stack clock: ticks and synchronization (docs/WIRE.md, "Clock").
    Clock,
    /// What a core node (a launch) answers its nodes: the datastore, its
    /// info and its stack listing (docs/WIRE.md, "Core node functions").
    Stack,
}

impl Space {
    /// The segment: `topic`, `service`, `action`, `live`, `pair`,
    /// `format`, `describe`, `core` or `clock`.
    pub fn as_str(self) -> &'static str {
        match self {
            Space::Topic => "topic",
            Space::Service => "service",
            Space::Action => "action",
            Space::Live => "live",
            Space::Pair => "pair",
            Space::Format => "format",
            Space::Describe => "describe",
            Space::Core => "core",
            Space::Clock => "clock",
            Space::Stack => "stack",
        }
    }
}

impl From<Channel> for Space {
    fn from(channel: Channel) -> Space {
        match channel {
            Channel::Topic => Space::Topic,
            Channel::Service => Space::Service,
            Channel::Action => Space::Action,
        }
    }
}

/// `peppy/<ns>/<space>/<parts...>`, sized once.
fn key(ns: &str, space: Space, parts: &[&str]) -> String {
    let space = space.as_str();
    let len = "peppy/".len()
        + ns.len()
        + 1
        + space.len()
        + parts.iter().map(|p| p.len() + 1).sum::<usize>();
    let mut key = String::with_capacity(len);
    key.push_str("peppy/");
    key.push_str(ns);
    key.push('/');
    key.push_str(space);
    for part in parts {
        key.push('/');
        key.push_str(part);
    }
    key
}

/// `peppy/<ns>/`: what every key of namespace `ns` starts with.
pub fn namespace_prefix(ns: &str) -> String {
    format!("peppy/{ns}/")
}

/// `peppy/<ns>/**`: every key of namespace `ns`.
pub fn namespace_selector(ns: &str) -> String {
    format!("peppy/{ns}/**")
}

/// `peppy/<ns>/<space>/**`: every key of one space of namespace `ns`
/// (every topic, every liveliness token, ...).
pub fn space_selector(ns: &str, space: Space) -> String {
    key(ns, space, &["**"])
}

/// Whether `s` can be one key segment: non-empty, no `/`, and none of
/// zenoh's special characters.
pub fn is_segment(s: &str) -> bool {
    // Every reply of a call checks its sender's two segments: an ASCII
    // segment is checked byte by byte, without decoding chars.
    let reserved = |c: char| matches!(c, '/' | '*' | '$' | '#' | '?' | '@') || c.is_whitespace();
    !s.is_empty()
        && if s.is_ascii() {
            !s.bytes().any(|b| reserved(char::from(b)))
        } else {
            !s.chars().any(reserved)
        }
}

/// The key one producer instance publishes on (or serves) for an entry.
pub fn entry_key(
    ns: &str,
    channel: Channel,
    owner: &Owner<'_>,
    entry: &str,
    core: &str,
    instance: &str,
) -> String {
    entry_selector(ns, channel, Some(owner), entry, Some(core), Some(instance))
}

/// A selector over producers: `None` parts match any value.
pub fn entry_selector(
    ns: &str,
    channel: Channel,
    owner: Option<&Owner<'_>>,
    entry: &str,
    core: Option<&str>,
    instance: Option<&str>,
) -> String {
    // Not `format!`ted: a service call builds its server's selector on
    // every call, and `key` sizes the key once.
    let (kind, name, tag) = match owner {
        Some(Owner::Node { name, tag }) => ("node", *name, *tag),
        Some(Owner::Interface { name, tag }) => ("interface", *name, *tag),
        None => ("*", "*", "*"),
    };
    let (core, instance) = (core.unwrap_or("*"), instance.unwrap_or("*"));
    key(
        ns,
        channel.into(),
        &[kind, name, tag, entry, core, instance],
    )
}

/// An entry key or selector by its named parts: what [`entry_selector`]
/// (and [`action_part_key`], [`feedback_key`] below an action) build, read
/// back by [`EntrySelector::parse`]. A tool changes one part (a producer
/// pinned, any server) by name rather than by counting segments; `None`
/// parts are wildcards.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EntrySelector<'a> {
    /// The namespace.
    pub ns: &'a str,
    /// Topic, service or action.
    pub channel: Channel,
    /// The entry's owner; `None` for any owner (`*/*/*`).
    pub owner: Option<Owner<'a>>,
    /// The entry (topic, service, action) name.
    pub entry: &'a str,
    /// The producer's core node; `None` for any.
    pub core: Option<&'a str>,
    /// The producer's instance id; `None` for any.
    pub instance: Option<&'a str>,
    /// What follows the instance: an action's part (`goal`, `*`,
    /// `feedback/<goal_id>`), `None` when nothing does.
    pub part: Option<&'a str>,
}

impl<'a> EntrySelector<'a> {
    /// Reads an entry key or selector back into its parts. `None` for
    /// anything [`entry_selector`] cannot build: another shape, `**`, a
    /// wildcard in only part of the owner, or a part that is neither a
    /// segment nor `*`.
    pub fn parse(key_expr: &'a str) -> Option<EntrySelector<'a>> {
        let mut parts = key_expr.splitn(10, '/');
        // A missing part reads as empty, which no check below accepts.
        let [peppy, ns, channel, kind, name, tag, entry, core, instance] =
            std::array::from_fn(|_| parts.next().unwrap_or(""));
        let part = parts.next();
        let wild = |s: &'a str| match s {
            "*" => Some(None),
            s if is_segment(s) => Some(Some(s)),
            _ => None,
        };
        let owner = match (kind, wild(name)?, wild(tag)?) {
            ("node", Some(name), Some(tag)) => Some(Owner::Node { name, tag }),
            ("interface", Some(name), Some(tag)) => Some(Owner::Interface { name, tag }),
            ("*", None, None) => None,
            _ => return None,
        };
        let part_ok = |p: &str| p.split('/').all(|s| s == "*" || is_segment(s));
        if peppy != "peppy" || !is_segment(ns) || !is_segment(entry) || !part.is_none_or(part_ok) {
            return None;
        }
        Some(EntrySelector {
            ns,
            channel: Channel::parse(channel)?,
            owner,
            entry,
            core: wild(core)?,
            instance: wild(instance)?,
            part,
        })
    }
}

impl fmt::Display for EntrySelector<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let base = entry_selector(
            self.ns,
            self.channel,
            self.owner.as_ref(),
            self.entry,
            self.core,
            self.instance,
        );
        match self.part {
            Some(part) => write!(f, "{base}/{part}"),
            None => f.write_str(&base),
        }
    }
}

/// The parts of an action below its entry key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ActionPart {
    /// Goals: sent, acked, accepted or rejected.
    Goal,
    /// Cancel requests.
    Cancel,
    /// Result requests (parked until the goal is terminal).
    Result,
}

impl ActionPart {
    /// `goal`, `cancel` or `result`.
    pub fn as_str(self) -> &'static str {
        match self {
            ActionPart::Goal => "goal",
            ActionPart::Cancel => "cancel",
            ActionPart::Result => "result",
        }
    }
}

/// `<action key or selector>/<goal|cancel|result>`.
pub fn action_part_key(action: &str, part: ActionPart) -> String {
    format!("{action}/{}", part.as_str())
}

/// `<action key or selector>/*`: an action's goal, cancel and result
/// queryables (not its feedback, which is two segments further down).
pub fn action_parts_selector(action: &str) -> String {
    format!("{action}/*")
}

/// `<action key or selector>/feedback/<goal_id>`: one goal's feedback.
pub fn feedback_key(action: &str, goal_id: &str) -> String {
    format!("{action}/feedback/{goal_id}")
}

/// `<action key or selector>/feedback/*`: the feedback of every goal.
pub fn feedback_selector(action: &str) -> String {
    feedback_key(action, "*")
}

/// `peppy/<ns>/format/<fingerprint as 16 hex>/<instance>`: where an instance
/// answers the canonical text of a format it emits.
pub fn format_key(ns: &str, fingerprint: u64, instance: &str) -> String {
    key(
        ns,
        Space::Format,
        &[&format!("{fingerprint:016x}"), instance],
    )
}

/// `peppy/<ns>/format/*/<instance>`: every format text `instance` answers,
/// or every instance's with `None`.
pub fn format_selector(ns: &str, instance: Option<&str>) -> String {
    key(ns, Space::Format, &["*", instance.unwrap_or("*")])
}

/// The liveliness token an instance holds while it is up:
/// `peppy/<ns>/live/<core>/<instance>/<node>/<tag>`.
pub fn liveliness_key(ns: &str, core: &str, instance: &str, node: &str, tag: &str) -> String {
    key(ns, Space::Live, &[core, instance, node, tag])
}

/// `peppy/<ns>/describe/<core>/<instance>`: where an instance answers its
/// `InstanceInfo` (`peppy_runtime::describe`).
pub fn describe_key(ns: &str, core: &str, instance: &str) -> String {
    key(ns, Space::Describe, &[core, instance])
}

/// Every instance's description key in `ns`.
pub fn describe_selector(ns: &str) -> String {
    key(ns, Space::Describe, &["*", "*"])
}

/// `peppy/<ns>/core/<core>/<launch>`: the token a launch (named by its
/// router's Zenoh id) holds for its core node while it runs, so the other
/// machines of a stack see it come and go.
pub fn core_key(ns: &str, core: &str, launch: &str) -> String {
    key(ns, Space::Core, &[core, launch])
}

/// Every core node's token in `ns`.
pub fn core_selector(ns: &str) -> String {
    key(ns, Space::Core, &["*", "*"])
}

/// `(core, launch)` of a core node token's key.
pub fn parse_core_key(key: &str) -> Option<(&str, &str)> {
    let rest = key.strip_prefix("peppy/")?;
    let (_ns, rest) = rest.split_once('/')?;
    let rest = rest.strip_prefix("core/")?;
    let (core, launch) = rest.split_once('/')?;
    (is_segment(core) && is_segment(launch)).then_some((core, launch))
}

/// Which time a clock tick carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ClockSource {
    /// The launcher's OS clock (ns since the Unix epoch).
    Wall,
    /// A simulator's time.
    Sim,
}

impl ClockSource {
    /// `wall` or `sim`.
    pub fn as_str(self) -> &'static str {
        match self {
            ClockSource::Wall => "wall",
            ClockSource::Sim => "sim",
        }
    }

    /// The byte a sync query names it with: 0 wall, 1 sim.
    pub fn as_byte(self) -> u8 {
        match self {
            ClockSource::Wall => 0,
            ClockSource::Sim => 1,
        }
    }

    /// The source a sync query's byte names, if any.
    pub fn from_byte(b: u8) -> Option<ClockSource> {
        match b {
            0 => Some(ClockSource::Wall),
            1 => Some(ClockSource::Sim),
            _ => None,
        }
    }
}

/// `peppy/<ns>/clock/tick/<wall|sim>`: where the launcher (wall) or a
/// simulator (sim) publishes the time, 8 bytes of u64 little-endian ns.
pub fn clock_tick_key(ns: &str, source: ClockSource) -> String {
    key(ns, Space::Clock, &["tick", source.as_str()])
}

/// `peppy/<ns>/clock/tick/*`: both tick keys.
pub fn clock_tick_selector(ns: &str) -> String {
    key(ns, Space::Clock, &["tick", "*"])
}

/// `peppy/<ns>/clock/sync`: where each launch answers clock
/// synchronization queries.
pub fn clock_sync_key(ns: &str) -> String {
    key(ns, Space::Clock, &["sync"])
}

/// A core node function a launch answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CoreFunction {
    /// The key/value store (`datastore::{store, get, list, remove}`).
    Datastore,
    /// What the core node is (`info`).
    Info,
    /// Its nodes and their instances (`stack::list`).
    List,
}

impl CoreFunction {
    /// The key's last segment.
    pub fn as_str(self) -> &'static str {
        match self {
            CoreFunction::Datastore => "datastore",
            CoreFunction::Info => "info",
            CoreFunction::List => "list",
        }
    }
}

/// `peppy/<ns>/stack/<core>/<function>`: where core node `core` answers
/// its nodes' calls of `function`.
pub fn core_function_key(ns: &str, core: &str, function: CoreFunction) -> String {
    key(ns, Space::Stack, &[core, function.as_str()])
}

/// `peppy/<ns>/stack/**`: every core node function of `ns`.
pub fn core_functions_selector(ns: &str) -> String {
    key(ns, Space::Stack, &["**"])
}

/// The tokens of every instance in `ns`.
pub fn all_liveliness_selector(ns: &str) -> String {
    key(ns, Space::Live, &["*", "*", "*", "*"])
}

/// The tokens of every instance of node `node:tag` in `ns`.
pub fn liveliness_selector(ns: &str, node: &str, tag: &str) -> String {
    key(ns, Space::Live, &["*", "*", node, tag])
}

/// The token of one instance, whatever node it says it runs.
pub fn instance_liveliness_selector(ns: &str, core: &str, instance: &str) -> String {
    key(ns, Space::Live, &[core, instance, "*", "*"])
}

/// `(core, instance)` of a liveliness token's key.
pub fn parse_liveliness_key(key: &str) -> Option<(String, String)> {
    let mut parts = key.split('/');
    if parts.next()? != "peppy" {
        return None;
    }
    let _ns = parts.next()?;
    if parts.next()? != "live" {
        return None;
    }
    let core = parts.next()?;
    let instance = parts.next()?;
    (is_segment(core) && is_segment(instance)).then(|| (core.to_string(), instance.to_string()))
}

/// The sender identity at the end of an entry key.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Sender {
    /// The owner kind, `node` or `interface`.
    pub kind: String,
    /// The owner's name.
    pub name: String,
    /// The owner's tag.
    pub tag: String,
    /// The entry (topic, service, action) name.
    pub entry: String,
    /// The sender's core node.
    pub core: String,
    /// The sender's instance id.
    pub instance: String,
}

/// Parses `peppy/<ns>/<channel>/<kind>/<name>/<tag>/<entry>/<core>/<instance>[/...]`.
pub fn parse_entry_key(key: &str) -> Option<Sender> {
    let s = split_entry_key(key)?;
    Some(Sender {
        kind: s.kind.to_string(),
        name: s.name.to_string(),
        tag: s.tag.to_string(),
        entry: s.entry.to_string(),
        core: s.core.to_string(),
        instance: s.instance.to_string(),
    })
}

/// An entry key's parts, borrowed from the key: [`Sender`] without copying.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SenderRef<'a> {
    /// The owner kind, `node` or `interface`.
    pub kind: &'a str,
    /// The owner's name.
    pub name: &'a str,
    /// The owner's tag.
    pub tag: &'a str,
    /// The entry (topic, service, action) name.
    pub entry: &'a str,
    /// The sender's core node.
    pub core: &'a str,
    /// The sender's instance id.
    pub instance: &'a str,
}

/// [`parse_entry_key`] without copying the parts out of `key`.
pub fn split_entry_key(key: &str) -> Option<SenderRef<'_>> {
    // One pass over the bytes (`/` is ASCII, so every cut is on a char
    // boundary): `str::split` searches afresh for each of the nine parts,
    // and every reply of a call is parsed.
    let mut parts = [""; 9];
    let (mut found, mut start) = (0, 0);
    for (at, _) in key.bytes().enumerate().filter(|&(_, b)| b == b'/') {
        parts[found] = &key[start..at];
        found += 1;
        start = at + 1;
        if found == parts.len() {
            break;
        }
    }
    if found < parts.len() {
        parts[found] = &key[start..];
        found += 1;
    }
    let [peppy, _ns, _channel, kind, name, tag, entry, core, instance] = parts;
    if found < parts.len() || peppy != "peppy" || (kind != "node" && kind != "interface") {
        return None;
    }
    let s = SenderRef {
        kind,
        name,
        tag,
        entry,
        core,
        instance,
    };
    (is_segment(s.core) && is_segment(s.instance)).then_some(s)
}

/// The owner kind segment of a pairing's topic keys.
const PAIRING_KIND: &str = "pairing";

/// What a claim token names in place of a peer while its slot claims nobody.
pub const NO_PEER: &str = "~";

/// `peppy/<ns>/topic/pairing/<pairing>/<tag>/<topic>/<core>/<instance>/<link_id>`:
/// the key an instance publishes a pairing topic on through its pairing
/// slot `link_id`.
pub fn pairing_topic_key(
    ns: &str,
    pairing: &str,
    tag: &str,
    topic: &str,
    core: &str,
    instance: &str,
    link_id: &str,
) -> String {
    key(
        ns,
        Space::Topic,
        &[PAIRING_KIND, pairing, tag, topic, core, instance, link_id],
    )
}

/// A selector over a pairing topic's senders: `None` parts match any
/// value (a paired slot pins its peer's instance and slot, any core).
pub fn pairing_topic_selector(
    ns: &str,
    pairing: &str,
    tag: &str,
    topic: &str,
    core: Option<&str>,
    instance: Option<&str>,
    link_id: Option<&str>,
) -> String {
    pairing_topic_key(
        ns,
        pairing,
        tag,
        topic,
        core.unwrap_or("*"),
        instance.unwrap_or("*"),
        link_id.unwrap_or("*"),
    )
}

/// The parts of a pairing topic's key, borrowed from the key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PairingSender<'a> {
    /// The pairing's name.
    pub pairing: &'a str,
    /// The pairing's tag.
    pub tag: &'a str,
    /// The topic.
    pub topic: &'a str,
    /// The sender's core node.
    pub core: &'a str,
    /// The sender's instance id.
    pub instance: &'a str,
    /// The sender's pairing slot.
    pub link_id: &'a str,
}

/// Reads a pairing topic's key back; `None` for anything
/// [`pairing_topic_key`] does not build (a wildcard included).
pub fn parse_pairing_topic_key(key: &str) -> Option<PairingSender<'_>> {
    let mut parts = key.split('/');
    let mut next = || parts.next().filter(|s| is_segment(s));
    let (peppy, _ns, space, kind) = (next()?, next()?, next()?, next()?);
    if peppy != "peppy" || space != Space::Topic.as_str() || kind != PAIRING_KIND {
        return None;
    }
    let sender = PairingSender {
        pairing: next()?,
        tag: next()?,
        topic: next()?,
        core: next()?,
        instance: next()?,
        link_id: next()?,
    };
    parts.next().is_none().then_some(sender)
}

/// A pairing slot's claim: the liveliness token a participant slot holds
/// for its node's life, naming the slot it is paired with or waiting for
/// (docs/PAIRINGS.md §3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Claim<'a> {
    /// The pairing's name.
    pub pairing: &'a str,
    /// The pairing's tag.
    pub tag: &'a str,
    /// The role the claiming slot plays.
    pub role: &'a str,
    /// The claimer's core node.
    pub core: &'a str,
    /// The claimer's instance id.
    pub instance: &'a str,
    /// The claimer's pairing slot.
    pub link_id: &'a str,
    /// The claimed slot, `(instance, link_id)`; `None` while claiming
    /// nobody.
    pub peer: Option<(&'a str, &'a str)>,
}

impl<'a> Claim<'a> {
    /// `peppy/<ns>/pair/<pairing>/<tag>/<role>/<core>/<instance>/<link_id>/<peer_instance>/<peer_link_id>`.
    pub fn key(&self, ns: &str) -> String {
        let (peer, peer_link) = self.peer.unwrap_or((NO_PEER, NO_PEER));
        key(
            ns,
            Space::Pair,
            &[
                self.pairing,
                self.tag,
                self.role,
                self.core,
                self.instance,
                self.link_id,
                peer,
                peer_link,
            ],
        )
    }

    /// Reads a claim token's key back; `None` for anything
    /// [`Claim::key`] does not build.
    pub fn parse(key: &'a str) -> Option<Claim<'a>> {
        let mut parts = key.split('/');
        let mut next = || parts.next().filter(|s| is_segment(s));
        let (peppy, _ns, space) = (next()?, next()?, next()?);
        if peppy != "peppy" || space != Space::Pair.as_str() {
            return None;
        }
        let mut claim = Claim {
            pairing: next()?,
            tag: next()?,
            role: next()?,
            core: next()?,
            instance: next()?,
            link_id: next()?,
            peer: None,
        };
        claim.peer = match (next()?, next()?) {
            (NO_PEER, NO_PEER) => None,
            (NO_PEER, _) | (_, NO_PEER) => return None,
            peer => Some(peer),
        };
        parts.next().is_none().then_some(claim)
    }
}

/// `peppy/<ns>/pair/<pairing>/<tag>/*/*/*/*/*/*`: every claim of one
/// pairing, whoever makes it.
pub fn claim_selector(ns: &str, pairing: &str, tag: &str) -> String {
    key(
        ns,
        Space::Pair,
        &[pairing, tag, "*", "*", "*", "*", "*", "*"],
    )
}

#[cfg(test)]
mod tests {
    // Every key of the wire, and how each reads back, is a golden vector
    // shared with the Python runtime (`tests/golden/wire.json`, checked
    // by `tests/runtime/golden.rs`); what only this module does is here.
    use super::*;

    /// Selectors read back by name: one part changed, the rest as built.
    #[test]
    fn entry_selectors_read_back_by_their_parts() {
        let arm = Owner::Node {
            name: "arm",
            tag: "v1",
        };
        let goal = action_part_key(
            &entry_key("lab", Channel::Action, &arm, "move", "robot", "arm_1"),
            ActionPart::Goal,
        );
        let parsed = EntrySelector::parse(&goal).unwrap();
        assert_eq!(
            parsed,
            EntrySelector {
                ns: "lab",
                channel: Channel::Action,
                owner: Some(arm),
                entry: "move",
                core: Some("robot"),
                instance: Some("arm_1"),
                part: Some("goal"),
            }
        );
        assert_eq!(parsed.to_string(), goal);
        let any_server = EntrySelector {
            core: None,
            instance: None,
            ..parsed
        };
        assert_eq!(
            any_server.to_string(),
            "peppy/lab/action/node/arm/v1/move/*/*/goal"
        );
        let external = entry_selector("lab", Channel::Topic, None, "ticks", None, None);
        let back = EntrySelector::parse(&external).unwrap();
        assert_eq!((back.owner, back.core, back.instance), (None, None, None));
        assert_eq!(back.to_string(), external);
        let action = EntrySelector {
            part: None,
            ..any_server
        };
        let feedback = feedback_selector(&action.to_string());
        assert_eq!(
            EntrySelector::parse(&feedback).unwrap().part,
            Some("feedback/*")
        );
        for bad in [
            "peppy/lab/topic/node/*/*/t/c/i",
            "peppy/lab/topic/*/x/v1/t/c/i",
            "peppy/lab/topic/node/x/v1/t/c",
            "peppy/lab/topic/node/x/v1/t/**/i",
            "peppy/lab/topic/node/x/v1/t/c/i/",
            "peppy/lab/topic/node/x/v1/t/c/i/**",
            "peppy/lab/live/node/x/v1/t/c/i",
            "peppy/*/topic/node/x/v1/t/c/i",
            "other/lab/topic/node/x/v1/t/c/i",
            "",
        ] {
            assert_eq!(EntrySelector::parse(bad), None, "{bad:?}");
        }
    }
}
