//! Entries turned around: a mock serves what its slot consumes, the
//! fixture consumes what the node serves. The runtime keeps `&'static`
//! specs, so each turned set is built once per process (a test binary
//! starts the same mocks many times) and leaked.

use std::collections::HashMap;
use std::sync::Mutex;

use crate::spec::NodeDescriptor;

/// A spec's identity: its address (generated specs are statics).
pub(crate) fn address<T>(r: &'static T) -> usize {
    std::ptr::from_ref(r) as usize
}

/// One kind of entries, turned: by the original's address, and in order.
pub(crate) struct Side<T: 'static> {
    by_origin: HashMap<usize, &'static T>,
    pub(crate) list: &'static [&'static T],
}

impl<T: 'static> Side<T> {
    /// Turns each of `from` with `turn`.
    pub(crate) fn of<F: 'static>(from: &'static [&'static F], turn: impl Fn(&F) -> T) -> Side<T> {
        let turned: Vec<(usize, &'static T)> = from
            .iter()
            .map(|f| (address(*f), &*Box::leak(Box::new(turn(f)))))
            .collect();
        Side {
            list: Box::leak(turned.iter().map(|(_, t)| *t).collect()),
            by_origin: turned.into_iter().collect(),
        }
    }

    /// The turned form of `origin`.
    pub(crate) fn get<F>(&self, origin: &'static F) -> Option<&'static T> {
        self.by_origin.get(&address(origin)).copied()
    }
}

/// A turned set: the node description it makes, and its three sides.
pub(crate) struct Turned<Tp: 'static, Sv: 'static, Ac: 'static> {
    pub(crate) descriptor: &'static NodeDescriptor,
    pub(crate) topics: Side<Tp>,
    pub(crate) services: Side<Sv>,
    pub(crate) actions: Side<Ac>,
}

/// The turned set cached under `key` in `cache`, built by `build` the
/// first time.
pub(crate) fn once<T: 'static>(
    cache: &'static Mutex<Vec<(usize, &'static T)>>,
    key: usize,
    build: impl FnOnce() -> T,
) -> &'static T {
    let mut all = cache.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((_, t)) = all.iter().find(|(k, _)| *k == key) {
        return t;
    }
    let t: &'static T = Box::leak(Box::new(build()));
    all.push((key, t));
    t
}
