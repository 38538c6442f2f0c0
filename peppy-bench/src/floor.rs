//! The machine's floor under a large shared-memory round trip: the four
//! copies a typed round trip makes (each side decodes what it got into a
//! buffer of its own and encodes its answer into a shared one), handed
//! between two threads by spinning, with no Zenoh, no peppy and no
//! wake-ups. On a virtual machine what two cores pay to hand each other a
//! megabyte moves with where the host puts them; this figure, measured in
//! the same turns as the round trips, says which state a run met.

use std::hint::black_box;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

/// Whose turn it is.
const SINK: u8 = 0;
const SOURCE: u8 = 1;
/// A side gave up waiting: the other stops too.
const STOPPED: u8 = 2;

/// How long a side spins for its turn before giving up (a turn takes a
/// fraction of a millisecond).
const PATIENCE: Duration = Duration::from_secs(1);

/// `count` round trips of `size` bytes, four copies each, after one
/// untimed (which touches the fresh buffers' pages); the time of each in
/// µs (fewer if a side gave up).
pub(crate) fn four_copies(size: usize, count: usize) -> Vec<f64> {
    let ping = Mutex::new(vec![0u8; size]);
    let pong = Mutex::new(vec![0u8; size]);
    let turn = AtomicU8::new(SINK);
    let data = vec![0xa5u8; size];
    std::thread::scope(|s| {
        s.spawn(|| {
            for _ in 0..=count {
                if !wait_for(&turn, SOURCE) {
                    return;
                }
                let got = lock(&ping).clone();
                lock(&pong).copy_from_slice(&got);
                turn.store(SINK, Ordering::Release);
            }
        });
        let mut samples = Vec::with_capacity(count);
        for i in 0..=count {
            let start = Instant::now();
            lock(&ping).copy_from_slice(&data);
            turn.store(SOURCE, Ordering::Release);
            if !wait_for(&turn, SINK) {
                break;
            }
            black_box(lock(&pong).clone());
            if i > 0 {
                samples.push(start.elapsed().as_secs_f64() * 1e6);
            }
        }
        samples
    })
}

fn lock(buffer: &Mutex<Vec<u8>>) -> std::sync::MutexGuard<'_, Vec<u8>> {
    buffer.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Spins until it is `side`'s turn; `false` (and the other side told) after
/// [`PATIENCE`] or once the other side gave up.
fn wait_for(turn: &AtomicU8, side: u8) -> bool {
    let deadline = Instant::now() + PATIENCE;
    let mut spins = 0u32;
    loop {
        match turn.load(Ordering::Acquire) {
            t if t == side => return true,
            STOPPED => return false,
            _ => {}
        }
        std::hint::spin_loop();
        spins = spins.wrapping_add(1);
        if spins.is_multiple_of(1024) && Instant::now() > deadline {
            turn.store(STOPPED, Ordering::Release);
            return false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_round_trip_is_timed() {
        let samples = four_copies(64 << 10, 20);
        assert_eq!(samples.len(), 20);
        assert!(samples.iter().all(|&us| us > 0.0));
    }
}
