//! The worker pool of ingest and build: `workers` scoped threads take items `0..n` in order, each
//! with its own state made on its first item (GDAL handles, say); the first failure stops every
//! worker from taking more, and a panicking worker is reported, not propagated.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Why a pool stopped before its last item.
#[derive(Debug, PartialEq)]
pub enum Stopped<E> {
    /// An item (or a worker's state) failed with this error: the first, in worker order.
    Failed(E),
    /// A worker panicked.
    Panicked,
}

/// Runs `work(state, i)` for every `i` in `0..n` on `workers` threads (at least one, at most
/// `n`); `init` makes a worker's state before its first item.
pub fn run<S, E: Send>(
    n: usize,
    workers: usize,
    init: impl Fn() -> Result<S, E> + Sync,
    work: impl Fn(&mut S, usize) -> Result<(), E> + Sync,
) -> Result<(), Stopped<E>> {
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let results: Vec<Result<(), Stopped<E>>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers.clamp(1, n.max(1)))
            .map(|_| {
                scope.spawn(|| -> Result<(), E> {
                    let mut state = None;
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= n || failed.load(Ordering::Relaxed) {
                            return Ok(());
                        }
                        let r = match &mut state {
                            Some(s) => work(s, i),
                            None => init().and_then(|s| work(state.insert(s), i)),
                        };
                        if let Err(e) = r {
                            failed.store(true, Ordering::Relaxed);
                            return Err(e);
                        }
                    }
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| match h.join() {
                Ok(r) => r.map_err(Stopped::Failed),
                Err(_) => Err(Stopped::Panicked),
            })
            .collect()
    });
    results.into_iter().collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    #[test]
    fn every_item_once_then_the_first_failure_stops_the_rest() {
        let seen = Mutex::new(Vec::new());
        let r: Result<(), Stopped<String>> = run(
            100,
            4,
            || Ok(()),
            |_, i| {
                seen.lock().expect("lock").push(i);
                Ok(())
            },
        );
        assert_eq!(r, Ok(()));
        let mut v = seen.into_inner().expect("lock");
        v.sort_unstable();
        assert_eq!(v, (0..100).collect::<Vec<_>>());

        let taken = AtomicUsize::new(0);
        let r = run(
            1000,
            2,
            || Ok(()),
            |_, i| {
                taken.fetch_add(1, Ordering::Relaxed);
                if i == 3 {
                    Err(format!("item {i}"))
                } else {
                    Ok(())
                }
            },
        );
        assert_eq!(r, Err(Stopped::Failed("item 3".to_string())));
        assert!(taken.load(Ordering::Relaxed) < 1000);
        let r = run(5, 2, || Err::<(), _>("no state".to_string()), |_, _| Ok(()));
        assert_eq!(r, Err(Stopped::Failed("no state".to_string())));
    }

    #[test]
    fn a_panicking_worker_is_reported() {
        let r: Result<(), Stopped<String>> = run(
            10,
            2,
            || Ok(()),
            |_, i| {
                assert!(i != 5, "boom");
                Ok(())
            },
        );
        assert_eq!(r, Err(Stopped::Panicked));
    }
}
