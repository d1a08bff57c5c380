//! The work the equilibrium solves of one discretization have done, every
//! attempt counted: residual evaluations, tangents formed and factorised,
//! linear solves. A step reports the work of the attempts that converged
//! (its substeps, continuation parts and fallbacks that led to the
//! solution); the failed attempts before it — a substep count, a
//! continuation or an initialization ramp that did not converge — return
//! only their error. The ledger counts both, so that a benchmark can
//! report what a step really cost. Relaxed atomics (the discretization is
//! shared between threads): they change no result.

use std::sync::atomic::{AtomicUsize, Ordering};

/// Counts of the solves' work.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Work {
    pub residuals: usize,
    pub factorizations: usize,
    pub solves: usize,
}

impl std::ops::Sub for Work {
    type Output = Work;

    fn sub(self, earlier: Work) -> Work {
        Work {
            residuals: self.residuals - earlier.residuals,
            factorizations: self.factorizations - earlier.factorizations,
            solves: self.solves - earlier.solves,
        }
    }
}

/// The running [`Work`] of a discretization since it was built.
#[derive(Debug, Default)]
pub struct Ledger {
    residuals: AtomicUsize,
    factorizations: AtomicUsize,
    solves: AtomicUsize,
}

impl Ledger {
    /// The work so far.
    pub fn work(&self) -> Work {
        let get = |a: &AtomicUsize| a.load(Ordering::Relaxed);
        Work {
            residuals: get(&self.residuals),
            factorizations: get(&self.factorizations),
            solves: get(&self.solves),
        }
    }

    pub(crate) fn residual(&self) {
        self.residuals.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn factorization(&self) {
        self.factorizations.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn solve(&self) {
        self.solves.fetch_add(1, Ordering::Relaxed);
    }
}
