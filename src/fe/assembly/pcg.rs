//! Preconditioned conjugate gradients on the constrained tangent K_ff with
//! the Cholesky factor of a nearby tangent K̃ as the preconditioner
//! ([`Pattern::conjugate_gradients`]): solves with an exact tangent without
//! a factorisation of its own, where Newton's reused factor
//! ([`crate::fe::tangent`]) is close to it (K̃⁻¹K_ff near the identity, so
//! a few iterations reach round-off).
//!
//! The iteration is flexible CG (β = z_{k+1}ᵀ(r_{k+1} − r_k) / z_kᵀr_k, the
//! Polak–Ribière form; Golub & Ye 1999, Notay 2000): a single-precision
//! factor applies K̃⁻¹ only to its rounding, a slightly different operator
//! for every vector, under which plain CG's β loses its implicit
//! orthogonality and flexible CG does not. It ends when the caller's test
//! of (y, r, rᵀz) holds, and gives up (`None`) at the iteration cap, on
//! non-positive curvature dᵀK d ≤ 0 (K_ff is not positive definite on the
//! Krylov space), on rᵀz < 0 or NaN (the preconditioner is not), and for a
//! factor that is not Cholesky's (an indefinite K̃).
//!
//! Invariants: sequential arithmetic in a fixed order, so the same bits on
//! every run and thread count; the vectors are allocated fallibly; the
//! returned residual is b − K_ff y recomputed, not the recurrence's.

use super::{try_filled, Factor, Pattern};

/// A converged iteration ([`Pattern::conjugate_gradients`]).
#[derive(Clone, Debug)]
pub struct Iterate {
    /// y ≈ K_ff⁻¹ b (0 on the prescribed dofs).
    pub y: Vec<f64>,
    /// b − K_ff y, recomputed (0 on the prescribed dofs).
    pub residual: Vec<f64>,
    /// rᵀ K̃⁻¹ r of the recurrence's residual at the accepted iterate: about
    /// the squared energy-norm error ‖y − K_ff⁻¹ b‖²_K.
    pub energy: f64,
    /// Products with K_ff (iterations) taken.
    pub iterations: usize,
}

/// Σ aᵢ bᵢ in index order.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl Pattern {
    /// y = K_ff x on the free dofs, 0 on the prescribed ones (x read on the
    /// free dofs only), from the full `values`: column by column through
    /// the node-level neighbour lists (one index per 3 × 1 block).
    pub fn multiply_free(&self, values: &[f64], x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        let col_ptr = self.symbolic.col_ptr();
        for (j, nb) in self.neighbours.iter().enumerate() {
            for c in 0..3 {
                let col = 3 * j + c;
                let xc = x[col];
                if xc == 0.0 || self.prescribed[col] {
                    continue;
                }
                let base = col_ptr[col];
                let column = &values[base..base + 3 * nb.len()];
                for (block, &i) in column.chunks_exact(3).zip(nb) {
                    let i = 3 * i as usize;
                    let target = &mut y[i..i + 3];
                    target[0] += block[0] * xc;
                    target[1] += block[1] * xc;
                    target[2] += block[2] * xc;
                }
            }
        }
        for (v, &p) in y.iter_mut().zip(&self.prescribed) {
            if p {
                *v = 0.0;
            }
        }
    }

    /// Solve K_ff y = b_f (K from the full `values`; b read on the free
    /// dofs) by flexible CG from y = 0, preconditioned with `factor`
    /// (module docs): `accept(y, r, rᵀz)` is asked before each iteration,
    /// with the recurrence's residual r and z = K̃⁻¹r; `None` when it has
    /// not accepted after `cap` iterations or the iteration breaks down;
    /// `Err` only when memory is refused.
    pub fn conjugate_gradients(
        &self,
        values: &[f64],
        factor: &Factor,
        b: &[f64],
        cap: usize,
        mut accept: impl FnMut(&[f64], &[f64], f64) -> bool,
    ) -> Result<Option<Iterate>, String> {
        if !matches!(factor, Factor::Cholesky(_) | Factor::SingleCholesky(_)) {
            return Ok(None);
        }
        let n = b.len();
        let what = "the conjugate gradients' vectors";
        let mut free = try_filled(n, 0.0, what)?;
        for ((f, &v), &p) in free.iter_mut().zip(b).zip(&self.prescribed) {
            if !p {
                *f = v;
            }
        }
        let mut y = try_filled(n, 0.0, what)?;
        let mut r = try_filled(n, 0.0, what)?;
        r.copy_from_slice(&free);
        let mut z = try_filled(n, 0.0, what)?;
        z.copy_from_slice(&r);
        factor.solve_in_place(&mut z);
        let mut rz = dot(&r, &z);
        let mut d = try_filled(n, 0.0, what)?;
        d.copy_from_slice(&z);
        let mut q = try_filled(n, 0.0, what)?;
        let mut previous = try_filled(n, 0.0, what)?;
        let mut iterations = 0;
        loop {
            if rz.is_nan() || rz < 0.0 {
                return Ok(None);
            }
            if accept(&y, &r, rz) {
                break;
            }
            if iterations == cap {
                return Ok(None);
            }
            self.multiply_free(values, &d, &mut q);
            let curvature = dot(&d, &q);
            if curvature.is_nan() || curvature <= 0.0 {
                return Ok(None);
            }
            let alpha = rz / curvature;
            previous.copy_from_slice(&r);
            for (((yi, ri), di), qi) in y.iter_mut().zip(r.iter_mut()).zip(&d).zip(&q) {
                *yi += alpha * di;
                *ri -= alpha * qi;
            }
            z.copy_from_slice(&r);
            factor.solve_in_place(&mut z);
            let next = dot(&r, &z);
            let beta = (next - dot(&z, &previous)) / rz;
            for (di, zi) in d.iter_mut().zip(&z) {
                *di = zi + beta * *di;
            }
            rz = next;
            iterations += 1;
        }
        self.multiply_free(values, &y, &mut q);
        for (f, kq) in free.iter_mut().zip(&q) {
            *f -= kq;
        }
        Ok(Some(Iterate {
            y,
            residual: free,
            energy: rz,
            iterations,
        }))
    }
}
