//! Counts of the factorisations a [`Pattern`] attempted, by kind: what
//! the choice of [`Pattern::factorize`] and [`Pattern::factorize_direction`]
//! costs (failed attempts included), for tests and benchmarks. The counters
//! are relaxed atomics (the pattern is shared between threads); they
//! change no result.

use std::sync::atomic::{AtomicUsize, Ordering};

use super::Pattern;

/// The numeric factorisations attempted since the pattern was built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Attempts {
    /// Single-precision Cholesky factorisations (including failed ones).
    pub single: usize,
    /// f64 Cholesky factorisations (including failed ones).
    pub cholesky: usize,
    /// f64 Cholesky factorisations skipped because they provably fail
    /// (module `indefinite`).
    pub cholesky_skipped: usize,
    /// Supernodal LBLᵀ factorisations.
    pub lblt: usize,
    /// Of which computed in vain: before an f64 Cholesky factorisation that
    /// succeeded (module `indefinite`).
    pub lblt_unused: usize,
    /// Sparse LU factorisations.
    pub lu: usize,
}

/// The pattern's counters behind [`Attempts`].
#[derive(Debug, Default)]
pub(super) struct Counters {
    pub(super) single: AtomicUsize,
    pub(super) cholesky: AtomicUsize,
    pub(super) cholesky_skipped: AtomicUsize,
    pub(super) lblt: AtomicUsize,
    pub(super) lblt_unused: AtomicUsize,
    pub(super) lu: AtomicUsize,
}

/// Add one to `counter`.
pub(super) fn count(counter: &AtomicUsize) {
    counter.fetch_add(1, Ordering::Relaxed);
}

impl Pattern {
    /// The factorisations attempted with this pattern so far, by kind.
    pub fn attempts(&self) -> Attempts {
        let c = &self.counters;
        let get = |a: &AtomicUsize| a.load(Ordering::Relaxed);
        Attempts {
            single: get(&c.single),
            cholesky: get(&c.cholesky),
            cholesky_skipped: get(&c.cholesky_skipped),
            lblt: get(&c.lblt),
            lblt_unused: get(&c.lblt_unused),
            lu: get(&c.lu),
        }
    }
}
