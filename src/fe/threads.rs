//! The opt-in threads of the element loops: a loop over elements split into
//! contiguous chunks, the first run on the calling thread and the others on
//! scoped threads that end with the call ([`in_order`]); and the rule of how
//! many threads a loop of a given size gets ([`Threads::for_loop`]).
//!
//! Invariant: the results are the same bits for every thread count. Each
//! element's work is a pure function of its index, and its result reaches
//! the caller's `sink` in element order whatever the split, so every sum the
//! sink forms is taken in the order of the one-thread loop.

use std::num::NonZeroUsize;

/// The largest thread count a caller may ask for.
pub const MAX_THREADS: usize = 64;

/// Elements per thread below which a loop of cheap per-element work (the
/// residual's law evaluation) stays on one thread: a spawn and join costs
/// tens of µs, the work of this many elements about as much again.
pub const RESIDUAL_ELEMENTS_PER_THREAD: usize = 4096;

/// The same for the tangent's element work (the law with its derivatives
/// and the 12 × 12 stiffness, about twenty times the residual's per element).
pub const TANGENT_ELEMENTS_PER_THREAD: usize = 256;

/// How many threads the element loops may use: 1 (the default) runs every
/// loop on the calling thread.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Threads(NonZeroUsize);

impl Default for Threads {
    fn default() -> Self {
        Threads::ONE
    }
}

impl Threads {
    pub const ONE: Threads = Threads(NonZeroUsize::MIN);

    /// `n` threads, refused outside 1..=[`MAX_THREADS`].
    pub fn new(n: usize) -> Result<Threads, String> {
        match NonZeroUsize::new(n) {
            Some(t) if n <= MAX_THREADS => Ok(Threads(t)),
            _ => Err(format!(
                "threads = {n} is out of range: must be in [1, {MAX_THREADS}]"
            )),
        }
    }

    pub fn get(self) -> usize {
        self.0.get()
    }

    /// The threads a loop over `n` elements uses: at most one per
    /// `per_thread` elements, at least one.
    pub fn for_loop(self, n: usize, per_thread: usize) -> usize {
        self.get().min(n / per_thread.max(1)).max(1)
    }
}

/// Run `kernel` for every element index in 0..`n` on `threads` threads
/// (contiguous chunks of near-equal size, the first on the calling thread)
/// and hand each result to `sink` in index order: the first chunk's as they
/// are computed, the others' after their thread has finished. A panic in a
/// worker resumes on the calling thread.
pub fn in_order<T, K, S>(threads: usize, n: usize, kernel: K, mut sink: S)
where
    T: Send,
    K: Fn(usize) -> T + Sync,
    S: FnMut(usize, T),
{
    let threads = threads.clamp(1, n.max(1));
    if threads == 1 {
        for e in 0..n {
            sink(e, kernel(e));
        }
        return;
    }
    let bound = |t: usize| t * n / threads;
    std::thread::scope(|s| {
        let kernel = &kernel;
        // A thread the OS refuses (process limits), or whose buffer cannot
        // be allocated, leaves its chunk to the calling thread: the same
        // results, in the same order.
        let workers: Vec<_> = (1..threads)
            .map(|t| {
                std::thread::Builder::new()
                    .spawn_scoped(s, move || {
                        let range = bound(t)..bound(t + 1);
                        let mut results = buffer::<T>(range.len())?;
                        results.extend(range.map(kernel));
                        Some(results)
                    })
                    .ok()
            })
            .collect();
        for e in 0..bound(1) {
            sink(e, kernel(e));
        }
        for (t, worker) in (1..threads).zip(workers) {
            let results = worker.and_then(|w| {
                w.join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            });
            match results {
                Some(results) => {
                    for (e, r) in (bound(t)..).zip(results) {
                        sink(e, r);
                    }
                }
                None => {
                    for e in bound(t)..bound(t + 1) {
                        sink(e, kernel(e));
                    }
                }
            }
        }
    });
}

/// An empty vector with room for `len` results, or `None` when it cannot be
/// allocated (never an abort).
fn buffer<T>(len: usize) -> Option<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).ok()?;
    Some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A buffer too large to allocate is refused, not an abort (its chunk
    /// then runs on the calling thread).
    #[test]
    fn a_buffer_that_cannot_be_allocated_is_refused() {
        assert!(buffer::<[u8; 1 << 20]>(1 << 44).is_none());
        assert_eq!(buffer::<f64>(3).map(|v| v.capacity()), Some(3));
    }

    /// Every index reaches the sink once, in order, for any split; a sum
    /// formed by the sink is the same bits for every thread count.
    #[test]
    fn results_reach_the_sink_in_index_order() {
        for n in [0, 1, 2, 7, 100] {
            let mut reference = 0.0f64;
            for threads in [1, 2, 3, 4, 64] {
                let mut seen = Vec::new();
                let mut sum = 0.0f64;
                in_order(
                    threads,
                    n,
                    |e| 1.0 / (e as f64 + 0.3),
                    |e, v| {
                        seen.push(e);
                        sum += v;
                    },
                );
                assert_eq!(seen, (0..n).collect::<Vec<_>>());
                if threads == 1 {
                    reference = sum;
                }
                assert_eq!(
                    sum.to_bits(),
                    reference.to_bits(),
                    "n {n}, threads {threads}"
                );
            }
        }
    }

    #[test]
    fn thread_counts_outside_the_range_are_refused() {
        assert!(Threads::new(0).is_err());
        assert!(Threads::new(MAX_THREADS + 1).is_err());
        assert_eq!(Threads::new(MAX_THREADS).unwrap().get(), MAX_THREADS);
        assert_eq!(Threads::default(), Threads::ONE);
        let t = Threads::new(4).unwrap();
        assert_eq!(t.for_loop(2592, 256), 4);
        assert_eq!(t.for_loop(600, 256), 2);
        assert_eq!(t.for_loop(100, 256), 1);
    }

    #[test]
    fn a_panic_in_a_worker_reaches_the_caller() {
        let r = std::panic::catch_unwind(|| {
            in_order(2, 10, |e| assert!(e < 7, "element {e}"), |_, ()| {})
        });
        assert!(r.is_err());
    }
}
