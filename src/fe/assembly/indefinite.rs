//! Newton's direction of a tangent that is not positive definite in single
//! precision: whether its f64 Cholesky factorisation can succeed at all,
//! decided from its LBLᵀ factorisation, so that a clearly indefinite tangent
//! skips that failing attempt ([`Pattern::factorize_direction`]).
//!
//! The LBLᵀ factorisation Q K Qᵀ = L B Lᵀ (Q: the fill-reducing and the
//! pivoting permutations) is computed first. With v the eigenvector of B's
//! most negative pivot (a 1 × 1 pivot, or the smaller eigenvalue of a
//! 2 × 2 one), x = Qᵀ L⁻ᵀ v has xᵀ K x ≈ vᵀ B v < 0, and xᵀ K x is then
//! evaluated in f64 from K itself (so whatever L's accuracy, x is only a
//! candidate). An f64 Cholesky factorisation of K that runs to completion
//! (every pivot positive) computes L̂ with L̂ L̂ᵀ = K + ΔK,
//! |ΔK| ≤ γₘ |L̂| |L̂ᵀ|, γₘ = m u / (1 − m u), u = 2⁻⁵³ (Higham, *Accuracy
//! and Stability of Numerical Algorithms*, 2nd ed. 2002, Thm 10.3, whose
//! proof uses only that the pivots' square roots were taken, not that K is
//! definite; m = 2 (t + 4) here, t the most products in one of the
//! factor's inner products, for faer's blocked grouping of the sums, its
//! multiplications by reciprocals and the square root). |L̂| |L̂ᵀ| vanishes
//! outside the factor's filled pattern P, and with ‖l̂ᵢ‖² = kᵢᵢ + Δkᵢᵢ,
//! |l̂ᵢ|·|l̂ⱼ| ≤ √(|kᵢᵢ| |kⱼⱼ|) / (1 − γₘ); L̂ L̂ᵀ being positive
//! semidefinite,
//!
//!   xᵀ K x ≥ −γₘ / (1 − γₘ) · Σ₍ᵢ,ⱼ₎∈P |xᵢ| |xⱼ| √(|kᵢᵢ| |kⱼⱼ|).
//!
//! The evaluated xᵀ K x is within γ₍ₗ₊ₙ₊₁₎ |x|ᵀ |K| |x| of the exact one (Higham
//! §3.1, inner products; l the longest column of K). When the evaluation
//! plus that error is below the bound, both terms multiplied by [`SAFETY`],
//! the f64 Cholesky factorisation must fail and is skipped: the factor is
//! the one [`Pattern::factorize`] reaches after that failure (the LBLᵀ, or
//! LU when the LBLᵀ fails its backward-error test). Otherwise
//! [`Pattern::factorize`]'s order, the LBLᵀ already computed reused when
//! the Cholesky factorisation fails. Either way the factor is the one
//! [`Pattern::factorize`] chooses, to the bit; only its cost differs (a
//! tangent positive definite in f64 but not in f32 pays the LBLᵀ
//! factorisation in vain).

use faer::sparse::linalg::cholesky::supernodal::SupernodalIntranodeLbltRef;
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};

use super::attempts::count;
use super::{BunchKaufman, Factor, Pattern};

/// Factor by which the rounding bounds of the module docs are enlarged
/// before a Cholesky factorisation is declared certain to fail: a margin
/// on worst-case bounds (which the actual errors stay far below) for any
/// operation of faer's kernels they may have missed.
pub const SAFETY: f64 = 16.0;

impl Pattern {
    /// [`Self::factorize_constrained`]'s factor of a matrix whose
    /// single-precision Cholesky factorisation failed at a pivot, the f64
    /// Cholesky factorisation skipped where it provably fails (module docs).
    pub(super) fn factorize_indefinite(&self, constrained: &[f64]) -> Result<Factor, String> {
        let Ok(lblt) = self.factorize_lblt(constrained) else {
            return self.factorize_constrained(constrained);
        };
        if self.cholesky_fails(constrained, &lblt) {
            count(&self.counters.cholesky_skipped);
        } else if let Ok(llt) = self.factorize_llt(constrained) {
            count(&self.counters.lblt_unused);
            return Ok(llt);
        }
        self.accept_lblt(constrained, lblt)
    }

    /// Whether an f64 Cholesky factorisation of `constrained` certainly
    /// fails: the bound of the module docs on the direction of `lblt`'s
    /// most negative pivot (false when it has none).
    pub(super) fn cholesky_fails(&self, constrained: &[f64], lblt: &BunchKaufman) -> bool {
        let Some(x) = negative_direction(lblt) else {
            return false;
        };
        let (q, bound) = self.curvature(constrained, &x);
        q < -bound
    }

    /// xᵀ K x of the `constrained` K, evaluated in f64, and the bound it
    /// must fall below for an f64 Cholesky factorisation of K to fail: the
    /// evaluation's error bound plus the factorisation's (module docs),
    /// times [`SAFETY`]; the bound is NaN when not finite.
    pub(super) fn curvature(&self, constrained: &[f64], x: &[f64]) -> (f64, f64) {
        let n = x.len();
        let col_ptr = self.symbolic.col_ptr();
        let row_idx = self.symbolic.row_idx();
        // xᵀKx, |x|ᵀ|K||x| and wᵢ = |xᵢ| √|kᵢᵢ|, in the Cholesky
        // factorisation's (permuted) order.
        let (mut q, mut magnitude, mut longest) = (0.0, 0.0, 0);
        let mut w = vec![0.0; n];
        for (c, &xc) in x.iter().enumerate() {
            let (mut kx, mut abs_kx, mut diagonal) = (0.0, 0.0, 0.0f64);
            for slot in col_ptr[c]..col_ptr[c + 1] {
                let (r, v) = (row_idx[slot], constrained[slot]);
                kx += v * x[r];
                abs_kx += (v * x[r]).abs();
                if r == c {
                    diagonal = v;
                }
            }
            q += xc * kx;
            magnitude += xc.abs() * abs_kx;
            longest = longest.max(col_ptr[c + 1] - col_ptr[c]);
            w[c] = xc.abs() * diagonal.abs().sqrt();
        }
        let w: Vec<f64> = self.llt.forward.iter().map(|&f| w[f]).collect();
        let (filled, terms) = filled_form(&self.llt.symbolic, &w);
        let gamma = |k: usize| {
            let ku = k as f64 * f64::EPSILON / 2.0;
            ku / (1.0 - ku)
        };
        // The Cholesky factorisation's entries: inner products of at most
        // `terms` products, a division and a square root (reciprocals
        // multiplied in faer's kernels), in any grouping.
        let g = gamma(2 * (terms + 4));
        let factorisation = g / (1.0 - g) * filled;
        let evaluation = gamma(longest + n + 1) * magnitude;
        let bound = SAFETY * (evaluation + factorisation);
        if q.is_finite() && bound.is_finite() {
            (q, bound)
        } else {
            (q, f64::NAN)
        }
    }
}

/// Σ over the pairs (i, j) of the Cholesky factor's filled pattern (both
/// triangles and the diagonal) of wᵢ wⱼ — the bound of the module docs on
/// |x|ᵀ |L̂| |L̂ᵀ| |x| (1 − γ), the entries of |L̂| |L̂ᵀ| being zero outside
/// that pattern — and the largest number of entries left of the diagonal
/// in a row of the factor (the products in one of its inner products).
fn filled_form(symbolic: &SymbolicCholesky<usize>, w: &[f64]) -> (f64, usize) {
    let n = w.len();
    let mut left = vec![0usize; n];
    let mut off = 0.0;
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => {
            let (col_ptr, row_idx) = (s.col_ptr(), s.row_idx());
            for j in 0..n {
                for &r in &row_idx[col_ptr[j]..col_ptr[j + 1]] {
                    if r != j {
                        off += w[r] * w[j];
                        left[r.max(j)] += 1;
                    }
                }
            }
        }
        SymbolicCholeskyRaw::Supernodal(s) => {
            for k in 0..s.n_supernodes() {
                let (start, end) = (s.supernode_begin()[k], s.supernode_end()[k]);
                let pattern = s.supernode(k).pattern();
                // The dense lower triangle of the diagonal block.
                let mut below = 0.0;
                for i in (start..end).rev() {
                    off += w[i] * below;
                    below += w[i];
                    left[i] += i - start;
                }
                // The rows below the block, in every column of it.
                let rows: f64 = pattern.iter().map(|&r| w[r]).sum();
                off += below * rows;
                for &r in pattern {
                    left[r] += end - start;
                }
            }
        }
    }
    let diagonal: f64 = w.iter().map(|v| v * v).sum();
    (diagonal + 2.0 * off, left.into_iter().max().unwrap_or(0))
}

/// x = Qᵀ L⁻ᵀ v for the eigenvector v of the most negative pivot of the
/// supernodal LBLᵀ factorisation (module docs), in the matrix's own order;
/// `None` when every pivot is positive (or the factor not supernodal).
/// The layout is that of faer's solve (`SupernodalIntranodeLbltRef::
/// solve_in_place_no_numeric_permute_with_conj`): per supernode, the
/// diagonal block holds B's diagonal and L's unit lower triangle, a 2 × 2
/// pivot at column i has its off-diagonal entry at `subdiagonal[i]`, and
/// the rows below the block are numbered before pivoting.
fn negative_direction(lblt: &BunchKaufman) -> Option<Vec<f64>> {
    let SymbolicCholeskyRaw::Supernodal(symbolic) = lblt.symbolic.raw() else {
        return None;
    };
    let n = symbolic.nrows();
    let factor = SupernodalIntranodeLbltRef::new(
        symbolic,
        &lblt.values,
        &lblt.subdiagonal,
        lblt.permutation.as_ref(),
    );
    // The most negative eigenvalue of a pivot, its column and eigenvector.
    let mut pivot: Option<(f64, usize, [f64; 2])> = None;
    for s in 0..symbolic.n_supernodes() {
        let node = factor.supernode(s);
        let b = node.val();
        let size = b.ncols();
        let mut k = 0;
        while k < size {
            let i = node.start() + k;
            let off = lblt.subdiagonal[i];
            let (lambda, v, width) = if off == 0.0 {
                (b[(k, k)], [1.0, 0.0], 1)
            } else {
                if k + 1 >= size {
                    return None;
                }
                let (a, c) = (b[(k, k)], b[(k + 1, k + 1)]);
                let lambda = 0.5 * (a + c) - (0.5 * (a - c)).hypot(off);
                // (B − λ) v = 0: of the two forms of v, the longer.
                let (v1, v2) = ([off, lambda - a], [lambda - c, off]);
                let v = if v1[0].hypot(v1[1]) >= v2[0].hypot(v2[1]) {
                    v1
                } else {
                    v2
                };
                (lambda, v, 2)
            };
            if lambda < pivot.map_or(0.0, |p| p.0) {
                pivot = Some((lambda, i, v));
            }
            k += width;
        }
    }
    let (_, i, v) = pivot?;
    let mut y = vec![0.0; n];
    y[i] = v[0];
    if v[1] != 0.0 {
        y[i + 1] = v[1];
    }
    // y ← L⁻ᵀ y, supernodes last to first.
    let inverse = lblt.permutation.arrays().1;
    for s in (0..symbolic.n_supernodes()).rev() {
        let node = factor.supernode(s);
        let l = node.val();
        let (size, start) = (l.ncols(), node.start());
        for j in 0..size {
            let below: f64 = node
                .pattern()
                .iter()
                .enumerate()
                .map(|(k, &row)| l[(size + k, j)] * y[inverse[row]])
                .sum();
            y[start + j] -= below;
        }
        for j in (0..size).rev() {
            let above: f64 = (j + 1..size).map(|r| l[(r, j)] * y[start + r]).sum();
            y[start + j] -= above;
        }
    }
    // x = Qᵀ y: row r of Q K Qᵀ is row fill[pivoting[r]] of K.
    let pivoting = lblt.permutation.arrays().0;
    let mut x = vec![0.0; n];
    for (r, &p) in pivoting.iter().enumerate() {
        let row = match lblt.symbolic.perm() {
            Some(fill) => fill.arrays().0[p],
            None => p,
        };
        x[row] = y[r];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::super::cholesky::tests::mesh;
    use super::*;
    use crate::fe::assembly::{Attempts, FactorKind};
    use crate::fe::discretization::Discretization;
    use crate::law::{FibreHistory, FibreRate, Params};

    /// The tangent at the reference, activation level `level`.
    fn tangent(d: &Discretization, p: &Params, level: f64, rate: FibreRate) -> Vec<f64> {
        let x = d.reference_positions();
        let hist = vec![FibreHistory::REST; d.n_elements()];
        d.evaluate(p, &x, level, &hist, rate, true)
            .unwrap()
            .tangent
            .unwrap()
    }

    /// The rate-free tangent at the reference with the activation level
    /// raised (fibre tension not balanced by pressure: indefinite) gets
    /// the LBLᵀ factor for directions after the failed single-precision
    /// Cholesky factorisation alone, the f64 one skipped; the factor is
    /// the one `factorize` reaches after its failing f64 attempt and
    /// solves to the same bits.
    #[test]
    fn an_indefinite_tangent_skips_the_f64_cholesky_factorisation() {
        let d = mesh(8, 2);
        for level in [0.5, 1.0] {
            let values = tangent(&d, &Params::default(), level, FibreRate::Isometric);
            let before = d.pattern.attempts();
            let f = d.pattern.factorize_direction(&values).unwrap();
            let after = d.pattern.attempts();
            assert_eq!(f.kind(), FactorKind::BunchKaufman, "level {level}");
            let expect = Attempts {
                single: before.single + 1,
                cholesky_skipped: before.cholesky_skipped + 1,
                lblt: before.lblt + 1,
                ..before
            };
            assert_eq!(after, expect, "level {level}");
            let today = d.pattern.factorize(&values).unwrap();
            assert_eq!(d.pattern.attempts().cholesky, after.cholesky + 1);
            assert_eq!(today.kind(), f.kind());
            let b: Vec<f64> = (0..3 * d.n_nodes())
                .map(|i| ((i * 37) % 11) as f64 - 5.0)
                .collect();
            let (mut x, mut y) = (b.clone(), b);
            f.solve_in_place(&mut x);
            today.solve_in_place(&mut y);
            assert!(x.iter().zip(&y).all(|(a, b)| a.to_bits() == b.to_bits()));
            let c = d.pattern.constrained(&values).unwrap();
            let lblt = d.pattern.factorize_lblt(&c).unwrap();
            let x = negative_direction(&lblt).unwrap();
            let (q, bound) = d.pattern.curvature(&c, &x);
            println!("level {level}: xᵀKx {q:e}, bound {bound:e}");
            assert!(q < -100.0 * bound, "level {level}: {q:e} vs {bound:e}");
        }
    }

    /// A positive definite tangent has no negative pivot to certify a
    /// failure with, and neither has one that is positive definite in f64
    /// but not in f32 (a volumetric penalty of 2·10¹⁵ Pa): it keeps its
    /// f64 Cholesky factor (the test
    /// `the_f64_factor_is_taken_where_single_precision_is_not_adequate`),
    /// the LBLᵀ computed first in vain.
    #[test]
    fn a_positive_definite_tangent_is_never_certified_indefinite() {
        let d = mesh(8, 2);
        let stiff = Params {
            d_comp: 1e-15,
            ..Params::default()
        };
        // Whether the single-precision factorisation fails at a pivot.
        for (p, level, fails) in [(Params::default(), 0.5, false), (stiff, 0.0, true)] {
            let values = tangent(&d, &p, level, FibreRate::Step { h: 1e-3 });
            let c = d.pattern.constrained(&values).unwrap();
            let lblt = d.pattern.factorize_lblt(&c).unwrap();
            assert!(!d.pattern.cholesky_fails(&c, &lblt));
            let before = d.pattern.attempts();
            let f = d.pattern.factorize_direction(&values).unwrap();
            let after = d.pattern.attempts();
            assert_eq!(after.cholesky_skipped, before.cholesky_skipped);
            let kind = if fails {
                FactorKind::Cholesky
            } else {
                FactorKind::SingleCholesky
            };
            assert_eq!(f.kind(), kind);
            assert_eq!(after.cholesky, before.cholesky + usize::from(fails));
            assert_eq!(after.lblt_unused, before.lblt_unused + usize::from(fails));
        }
    }
}
