//! The planner's simulations on every core: the search of
//! [`super::FixedProgram::spend_by_simulation`] runs one fixed-point simulation per reference
//! run, and they are independent. Scoped threads, one per available core, pull indices from a
//! shared counter — not rayon's pool: a search runs inside rayon tasks (every board of a
//! keyboard planned at once), holding its program's search slot ([`super::plan_cache`]); a
//! rayon worker waiting for its jobs may steal another task that asks for the same slot on
//! the same thread, which would deadlock. Results never depend on the thread count: `map`
//! returns in index order and `find` only says whether (and where) something failed.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Threads for `n` independent jobs: the available cores, at most `n`, at least 1.
fn threads(n: usize) -> usize {
    std::thread::available_parallelism()
        .map_or(1, |t| t.get())
        .min(n)
        .max(1)
}

/// `f(0) … f(n − 1)` computed on every core, in index order.
pub(crate) fn map<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let t = threads(n);
    if t == 1 {
        return (0..n).map(f).collect();
    }
    let next = AtomicUsize::new(0);
    let mut out: Vec<(usize, T)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..t)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= n {
                            break mine;
                        }
                        mine.push((i, f(i)));
                    }
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    out.sort_by_key(|(i, _)| *i);
    out.into_iter().map(|(_, x)| x).collect()
}

/// The position of an item of `items` for which `fails` holds, or `None` when it holds for
/// none; checked on every core, no new item started once one failed. When several fail,
/// which one is returned depends on timing (a caller may only use it as a hint).
pub(crate) fn find<T: Sync>(items: &[T], fails: impl Fn(&T) -> bool + Sync) -> Option<usize> {
    let t = threads(items.len());
    if t == 1 {
        return items.iter().position(fails);
    }
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let found = AtomicUsize::new(usize::MAX);
    std::thread::scope(|s| {
        for _ in 0..t {
            s.spawn(|| {
                while !stop.load(Ordering::Relaxed) {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= items.len() {
                        break;
                    }
                    if fails(&items[i]) {
                        found.fetch_min(i, Ordering::Relaxed);
                        stop.store(true, Ordering::Relaxed);
                    }
                }
            });
        }
    });
    let i = found.load(Ordering::Relaxed);
    (i != usize::MAX).then_some(i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_keeps_the_order_and_find_finds_a_failure_or_none() {
        assert_eq!(
            map(100, |i| i * i),
            (0..100).map(|i| i * i).collect::<Vec<_>>()
        );
        assert_eq!(map(0, |i| i), Vec::<usize>::new());
        let items: Vec<u32> = (0..50).collect();
        assert_eq!(find(&items, |&x| x > 100), None);
        assert_eq!(find(&items, |&x| x == 37), Some(37));
        let i = find(&items, |&x| x % 10 == 9).expect("a failure");
        assert_eq!(items[i] % 10, 9);
    }
}
