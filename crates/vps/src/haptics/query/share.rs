//! Work shared between the calling thread and the pool: the caller takes part instead of
//! waiting.
//!
//! `par_iter` from outside the pool hands all the work to the pool and puts the caller to
//! sleep until it is done. On two cores that cost the first query after opening about 1 ms:
//! the scheduler queued the second pool thread it woke behind the first, on the same core,
//! for 2.5 ms, while the caller slept on the other (a scheduler trace of `vps contact`,
//! `docs/PERFORMANCE.md`, "The caller takes part"). Here the caller works through the items
//! with the pool's threads, so the cores it leaves idle are only those the pool cannot fill.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// `task(state, i)` for every `i` in `0..n`, on the calling thread and on at most one fewer of
/// the pool's threads than the pool has (so that as many threads work as there are, the caller
/// among them). Each takes the next item no one has taken, and makes its `state` (a cursor,
/// say) with `make_state` before its first item, so a thread that finds no item left makes
/// none. The results come back in item order, whichever thread made them; or the error of
/// the first item that failed, as a walk of the items in order would give it. After an item
/// fails no thread starts one after it: items are taken in order, so every item before the
/// first that fails has been taken, and runs.
///
/// The scope ends when every job it spawned has run, so a pool thread that takes a job late
/// (busy with other work, or queued by the scheduler behind another thread) still holds the
/// caller up, though it finds no item left; right after opening a voxmap, the jobs queue
/// behind what opening left for each pool thread to make. Waiting for them needs no `unsafe`
/// and no `'static` copy of the query's data, which detached jobs would.
pub(super) fn share<S, R: Send, E: Send>(
    n: usize,
    make_state: impl Fn() -> S + Sync,
    task: impl Fn(&mut S, usize) -> Result<R, E> + Sync,
) -> Result<Vec<R>, E> {
    let next = AtomicUsize::new(0);
    // The first item known to have failed; items after it are not started.
    let failed = AtomicUsize::new(usize::MAX);
    let results: Vec<Mutex<Option<Result<R, E>>>> = (0..n).map(|_| Mutex::new(None)).collect();
    let work = || {
        let mut state = None;
        loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            if i >= n || i > failed.load(Ordering::Relaxed) {
                return;
            }
            let state = state.get_or_insert_with(&make_state);
            let r = task(state, i);
            if r.is_err() {
                failed.fetch_min(i, Ordering::Relaxed);
            }
            // A lock taken once per item, by one thread: it only hands the result over.
            *results[i].lock().unwrap_or_else(|e| e.into_inner()) = Some(r);
        }
    };
    let helpers = helpers().min(n.saturating_sub(1));
    rayon::in_place_scope(|scope| {
        for _ in 0..helpers {
            scope.spawn(|_| work());
        }
        work();
    });
    // In item order, the first failure comes before any item not started.
    results
        .into_iter()
        .map(|r| {
            r.into_inner()
                .unwrap_or_else(|e| e.into_inner())
                .expect("every item up to the first that fails is taken once and finished before the scope ends")
        })
        .collect()
}

/// Threads that [`share`] would set to work besides the caller.
pub(super) fn helpers() -> usize {
    rayon::current_num_threads().saturating_sub(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;
    use std::thread::ThreadId;
    use std::time::Instant;

    /// The items run, each once, and which threads ran them.
    fn run(n: usize, micros: u64) -> (Vec<usize>, Vec<(usize, ThreadId)>) {
        let ran = Mutex::new(Vec::new());
        let out = share(
            n,
            || std::thread::current().id(),
            |id, i| {
                ran.lock().unwrap().push((i, *id));
                std::thread::sleep(std::time::Duration::from_micros(micros));
                Ok::<_, ()>(i * 3)
            },
        );
        (out.unwrap(), ran.into_inner().unwrap())
    }

    /// Every item once, results in item order, on pools of one thread and of more threads
    /// than items; no more threads at work than the pool has.
    #[test]
    fn every_item_runs_once_and_comes_back_in_order() {
        for threads in [1, 2, 3, 8] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            for n in [0, 1, 2, 5, 200] {
                let (out, ran) = pool.install(|| run(n, 20));
                assert_eq!(
                    out,
                    (0..n).map(|i| i * 3).collect::<Vec<_>>(),
                    "{threads} threads, {n} items"
                );
                let items: HashSet<usize> = ran.iter().map(|r| r.0).collect();
                assert_eq!((ran.len(), items.len()), (n, n));
                let workers: HashSet<ThreadId> = ran.iter().map(|r| r.1).collect();
                assert!(workers.len() <= threads, "{} threads at work", workers.len());
            }
        }
    }

    /// The error of the first item that fails comes back, whatever the threads, every item
    /// before it having run; on one thread no item after it starts.
    #[test]
    fn the_first_failure_comes_back_and_stops_the_items_after_it() {
        for threads in [1, 2, 3, 8] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let ran = AtomicUsize::new(0);
            let out = pool.install(|| {
                share(
                    500,
                    || (),
                    |(), i| {
                        ran.fetch_add(1, Ordering::Relaxed);
                        std::thread::sleep(std::time::Duration::from_micros(50));
                        if i == 60 || i == 61 || i == 300 {
                            Err(i)
                        } else {
                            Ok(i)
                        }
                    },
                )
            });
            assert_eq!(out, Err(60), "{threads} threads");
            // How many the other threads start before item 60 fails depends on the scheduler.
            let ran = ran.into_inner();
            assert!(ran >= 61, "{threads} threads ran {ran} items");
            if threads == 1 {
                assert_eq!(ran, 61);
            }
        }
    }

    /// From outside the pool the calling thread works too, and with no helper it does all.
    #[test]
    fn a_caller_outside_the_pool_takes_part() {
        let caller = std::thread::current().id();
        let caller_started = AtomicUsize::new(0);
        let ran = Mutex::new(Vec::new());
        // The pool's threads hold their first item until the caller has taken one (or 10 s
        // have passed), so that a caller stalled on a loaded machine cannot find every item
        // taken; the caller's items never wait.
        share(
            64,
            || std::thread::current().id(),
            |id, i| {
                if *id == caller {
                    caller_started.store(1, Ordering::Release);
                } else {
                    let start = Instant::now();
                    while caller_started.load(Ordering::Acquire) == 0 && start.elapsed().as_secs() < 10 {
                        std::thread::sleep(std::time::Duration::from_micros(100));
                    }
                }
                ran.lock().unwrap().push((i, *id));
                Ok::<_, ()>(())
            },
        )
        .unwrap();
        let ran = ran.into_inner().unwrap();
        assert_eq!(ran.len(), 64);
        assert!(ran.iter().any(|r| r.1 == caller), "the caller ran none of 64 items");
        if helpers() == 0 {
            assert!(ran.iter().all(|r| r.1 == caller));
        }
    }
}
