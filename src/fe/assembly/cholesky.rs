//! The Cholesky factor of the constrained tangent on the matrix permuted
//! once per mesh ([`PermutedCholesky`]), in double or single precision, and
//! its triangular solves.
//!
//! Single precision: the same supernodal LLᵀ of the same permuted matrix
//! with its values rounded to f32 — half the factor's memory, half the
//! memory traffic of a solve (which streams the factor twice) and twice the
//! SIMD width of the factorisation's dense kernels. Its solution of K x = b
//! has a relative error of about κ(K)·2⁻²⁴, so it serves only where the
//! solution is a direction that an f64 residual then judges: the Newton
//! corrections and the predictor's sensitivities of the reused tangent
//! ([`Pattern::factorize_direction`], [`crate::fe::tangent`]); derivatives
//! that are outputs keep the f64 factor ([`Pattern::factorize`]). The single
//! factor is taken when (1) every constrained value lies in f32's normal
//! range, (2) its factorisation succeeds (the matrix is positive definite in
//! f32) and (3) on the fixed probe b of [`Pattern::backward_error`], one step
//! of f64 iterative refinement estimates the relative error of its solution,
//! ‖K̂⁻¹(b − K x̂)‖∞ / ‖x̂‖∞, at most [`MAX_SINGLE_ERROR`] (an ill-conditioned
//! tangent — a huge volumetric penalty — fails it); otherwise the f64
//! factorisation of [`Pattern::factorize`]. All three depend on the matrix
//! alone, so a restored state refactorises to the same factor.
//!
//! A solve allocates nothing: the permuted right-hand side and faer's
//! workspace are allocated (fallibly) with the factor and reused under a
//! lock. The single-precision solve scales the right-hand side by a power of
//! two (exact) so that its largest entry is in [1, 2): no f32 overflow or
//! underflow whatever the residual's units.

use std::sync::{Arc, Mutex};

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::LltRef;
use faer::sparse::SparseColMatRef;
use faer::traits::ComplexField;
use faer::MatMut;

use super::attempts::count;
use super::{try_filled, Factor, Pattern, PermutedCholesky};

/// Largest estimated relative error of the single-precision factor's
/// solution of the probe system at which it is taken (module docs): a
/// direction this close to the f64 one changes the contraction of the
/// (modified) Newton iteration by at most this, against the
/// [`crate::fe::tangent::REFRESH_CONTRACTION`] of a reused tangent.
pub const MAX_SINGLE_ERROR: f64 = 2e-2;

/// The precisions a Cholesky factor is kept in.
pub trait Precision: ComplexField + Copy + Send + Sync + 'static {
    /// Whether this is single precision (its right-hand sides are scaled).
    const SINGLE: bool;
    fn from_f64(v: f64) -> Self;
    fn to_f64(self) -> f64;
}

impl Precision for f64 {
    const SINGLE: bool = false;
    fn from_f64(v: f64) -> Self {
        v
    }
    fn to_f64(self) -> f64 {
        self
    }
}

impl Precision for f32 {
    const SINGLE: bool = true;
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    fn to_f64(self) -> f64 {
        self as f64
    }
}

/// Why a Cholesky factorisation failed: at a pivot that is not positive
/// (the matrix is not numerically positive definite in that precision), or
/// otherwise (memory, single precision's range or probe); its message
/// either way.
#[derive(Debug)]
pub(super) enum Failure {
    Pivot(String),
    Other(String),
}

impl From<Failure> for String {
    fn from(f: Failure) -> String {
        match f {
            Failure::Pivot(s) | Failure::Other(s) => s,
        }
    }
}

impl From<String> for Failure {
    fn from(s: String) -> Failure {
        Failure::Other(s)
    }
}

/// A solve's workspace: the permuted right-hand side and faer's scratch.
struct Workspace<T> {
    y: Vec<T>,
    stack: MemBuffer,
}

/// A Cholesky factorisation ([`Pattern::factorize`],
/// [`Pattern::factorize_direction`]) of the permuted matrix
/// ([`PermutedCholesky`]) in precision `T`, with its solve's workspace.
pub struct Cholesky<T> {
    order: Arc<PermutedCholesky>,
    values: Vec<T>,
    /// Single precision: the prescribed dofs, whose entries of b a solve
    /// leaves as they are (the exact solution there: identity rows and
    /// columns) instead of rounding them to f32; empty in f64.
    prescribed: Vec<bool>,
    workspace: Mutex<Workspace<T>>,
}

impl<T: Precision> Cholesky<T> {
    /// Factorise the constrained values (rounded to `T`) gathered into the
    /// permuted triangle; `Err` when they are not (numerically) positive
    /// definite or memory is refused.
    pub(super) fn new(
        order: &Arc<PermutedCholesky>,
        constrained: &[f64],
        prescribed: &[bool],
    ) -> Result<Cholesky<T>, Failure> {
        let what = if T::SINGLE {
            "the single-precision Cholesky factor"
        } else {
            "the Cholesky factor"
        };
        let zero = T::from_f64(0.0);
        let mut permuted = try_filled(order.source.len(), zero, what)?;
        for (p, &s) in permuted.iter_mut().zip(&order.source) {
            *p = T::from_f64(constrained[s]);
        }
        let symbolic = &order.symbolic;
        let mut values = try_filled(symbolic.len_val(), zero, what)?;
        let par = faer::get_global_parallelism();
        let mut scratch = MemBuffer::try_new(
            symbolic.factorize_numeric_llt_scratch::<T>(par, Default::default()),
        )
        .map_err(|e| Failure::Other(format!("not positive definite (Cholesky: {e:?})")))?;
        symbolic
            .factorize_numeric_llt(
                &mut values,
                SparseColMatRef::new(order.numeric.as_ref(), &permuted),
                order.side,
                Default::default(),
                par,
                MemStack::new(&mut scratch),
                Default::default(),
            )
            .map_err(|e| Failure::Pivot(format!("not positive definite (Cholesky: {e:?})")))?;
        let n = order.forward.len();
        let workspace = Workspace {
            y: try_filled(n, zero, what)?,
            stack: MemBuffer::try_new(symbolic.solve_in_place_scratch::<T>(1, par))
                .map_err(|_| Failure::Other(format!("out of memory for {what}'s solve")))?,
        };
        let prescribed = if T::SINGLE {
            let mut p = try_filled(prescribed.len(), false, what)?;
            p.copy_from_slice(prescribed);
            p
        } else {
            Vec::new()
        };
        Ok(Cholesky {
            order: order.clone(),
            values,
            prescribed,
            workspace: Mutex::new(workspace),
        })
    }

    /// Solve with the permuted factor: b permuted (and, in single
    /// precision, scaled by a power of two), solved, permuted back (what
    /// faer's own permuted solve does), in the preallocated workspace.
    pub(super) fn solve_in_place(&self, b: &mut [f64]) {
        let n = b.len();
        let scale = if T::SINGLE {
            power_of_two_scale(b)
        } else {
            1.0
        };
        let mut guard = self.workspace.lock().unwrap_or_else(|e| e.into_inner());
        let Workspace { y, stack } = &mut *guard;
        let forward = &self.order.forward;
        for (yi, &f) in y.iter_mut().zip(forward) {
            *yi = T::from_f64(b[f] * scale);
        }
        let par = faer::get_global_parallelism();
        LltRef::new(&self.order.symbolic, &self.values).solve_in_place_with_conj(
            faer::Conj::No,
            MatMut::from_column_major_slice_mut(y, n, 1),
            par,
            MemStack::new(stack),
        );
        for (&f, v) in forward.iter().zip(y.iter()) {
            if !(T::SINGLE && self.prescribed[f]) {
                b[f] = v.to_f64() / scale;
            }
        }
    }
}

/// 2⁻ᵉ with 2ᵉ ≤ max |bᵢ| < 2ᵉ⁺¹ (1 when b is zero or not finite; e
/// clamped to ±1000): dividing by it is exact.
fn power_of_two_scale(b: &[f64]) -> f64 {
    let m = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if m == 0.0 || !m.is_finite() {
        return 1.0;
    }
    let e = m.log2().floor().clamp(-1000.0, 1000.0) as i32;
    // The bits of 2^(−e): biased exponent 1023 − e, zero mantissa.
    f64::from_bits(((1023 - e) as u64) << 52)
}

impl Pattern {
    /// Factorise the constrained tangent built from the full `values` for
    /// Newton directions: the single-precision Cholesky factor when it is
    /// adequate for the matrix (module docs), else [`Self::factorize`]'s.
    pub fn factorize_direction(&self, values: &[f64]) -> Result<Factor, String> {
        let constrained = self.constrained(values)?;
        if self.single {
            match self.single_cholesky(&constrained) {
                Ok(single) => return Ok(single),
                // Not positive definite in f32: perhaps not in f64 either
                // (module `indefinite`).
                Err(Failure::Pivot(_)) => return self.factorize_indefinite(&constrained),
                Err(Failure::Other(_)) => {}
            }
        }
        self.factorize_constrained(&constrained)
    }

    /// The single-precision Cholesky factor of the constrained values, `Err`
    /// naming which of the module docs' conditions fails.
    pub(super) fn factorize_single(&self, constrained: &[f64]) -> Result<Factor, String> {
        self.single_cholesky(constrained).map_err(String::from)
    }

    /// [`Self::factorize_single`], its failure at a pivot told apart.
    fn single_cholesky(&self, constrained: &[f64]) -> Result<Factor, Failure> {
        let in_range = |v: &f64| {
            let a = v.abs();
            a == 0.0 || (a >= f32::MIN_POSITIVE as f64 && a <= f32::MAX as f64)
        };
        if !constrained.iter().all(in_range) {
            return Err(Failure::Other(
                "a value out of single precision's normal range".into(),
            ));
        }
        count(&self.counters.single);
        let factor = Factor::SingleCholesky(Arc::new(Cholesky::<f32>::new(
            &self.llt,
            constrained,
            &self.prescribed,
        )?));
        let error = self.single_error(constrained, &factor);
        if error <= MAX_SINGLE_ERROR {
            Ok(factor)
        } else {
            Err(Failure::Other(format!(
                "single precision's estimated relative error {error:e} on the probe"
            )))
        }
    }

    /// The relative error of `factor`'s solution x̂ of K x = b (the probe b
    /// of [`Self::backward_error`]) estimated by one step of iterative
    /// refinement in f64: ‖K̂⁻¹(b − K x̂)‖∞ / ‖x̂‖∞; NaN when not finite.
    pub(super) fn single_error(&self, constrained: &[f64], factor: &Factor) -> f64 {
        let n = 3 * self.n_nodes;
        let b = Self::probe(n);
        let mut x = b.clone();
        factor.solve_in_place(&mut x);
        let mut r = vec![0.0; n];
        self.multiply(constrained, &x, &mut r);
        r.iter_mut().zip(&b).for_each(|(r, b)| *r = b - *r);
        factor.solve_in_place(&mut r);
        let norm = |v: &[f64]| {
            v.iter().fold(0.0f64, |m, a| {
                if m.is_nan() || a.is_nan() {
                    f64::NAN
                } else {
                    m.max(a.abs())
                }
            })
        };
        let (dx, x) = (norm(&r), norm(&x));
        if dx.is_finite() && x.is_finite() && x > 0.0 {
            dx / x
        } else {
            f64::NAN
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::fe::assembly::FactorKind;
    use crate::fe::discretization::{Discretization, Ends};
    use crate::fe::mesh::{FibreLayout, Resolution, LUMPED};
    use crate::fe::muscle::Muscle;
    use crate::law::{FibreHistory, FibreRate, Params};
    use crate::specimen::{LENGTH as L0, MEAN_AREA};

    /// The fusiform specimen's clamped mesh, meridian fibres.
    pub(crate) fn mesh(n_axial: usize, n_radial: usize) -> Discretization {
        Discretization::fusiform(
            L0,
            MEAN_AREA,
            Resolution { n_axial, n_radial },
            FibreLayout::Meridian,
            Ends::Clamped,
        )
        .unwrap()
    }

    /// The tangent at `x` (the reference when `None`), level 0, 1 ms step.
    fn tangent(d: &Discretization, p: &Params, x: Option<&[f64]>) -> Vec<f64> {
        let reference = d.reference_positions();
        let hist = vec![FibreHistory::REST; d.n_elements()];
        let x = x.unwrap_or(&reference);
        d.evaluate(p, x, 0.0, &hist, FibreRate::Step { h: 1e-3 }, true)
            .unwrap()
            .tangent
            .unwrap()
    }

    fn amax(v: &[f64]) -> f64 {
        v.iter().fold(0.0f64, |m, a| m.max(a.abs()))
    }

    /// The default (lumped, graded) mesh.
    fn default_mesh() -> Arc<Discretization> {
        Arc::new(Discretization::specimen(LUMPED).unwrap())
    }

    /// The default mesh, and its passive equilibrium at 1.1 L0.
    fn default_mesh_stretched() -> (Arc<Discretization>, Vec<f64>) {
        let d = default_mesh();
        let (m, _) = Muscle::isometric(d.clone(), &Params::default(), 1.1 * L0, 0.0).unwrap();
        (d, m.x)
    }

    /// On the default mesh's tangent at 1.1 L0 the single factor is taken,
    /// solves the constrained system to a backward error of at most 1e-6
    /// (f32's unit roundoff is 6e-8), its solution is within
    /// [`MAX_SINGLE_ERROR`] of the f64 one, and prescribed entries of b
    /// come back unchanged.
    #[test]
    fn the_single_factor_solves_the_constrained_system() {
        let (d, x) = default_mesh_stretched();
        let values = tangent(&d, &Params::default(), Some(&x));
        let f = d.pattern.factorize_direction(&values).unwrap();
        assert_eq!(f.kind(), FactorKind::SingleCholesky);
        let constrained = d.pattern.constrained(&values).unwrap();
        let backward = d.pattern.backward_error(&constrained, &f);
        let estimate = d.pattern.single_error(&constrained, &f);
        let f64_factor = d.pattern.factorize(&values).unwrap();
        let n = 3 * d.n_nodes();
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        let (mut x32, mut x64) = (b.clone(), b.clone());
        f.solve_in_place(&mut x32);
        f64_factor.solve_in_place(&mut x64);
        let diff: Vec<f64> = x32.iter().zip(&x64).map(|(a, b)| a - b).collect();
        let error = amax(&diff) / amax(&x64);
        println!("backward error {backward:e}, estimate {estimate:e}, error {error:e}");
        assert!(backward <= 1e-6, "backward error {backward:e}");
        assert!(estimate <= MAX_SINGLE_ERROR && error <= MAX_SINGLE_ERROR);
        for (i, &pr) in d.pattern.prescribed.iter().enumerate() {
            if pr {
                assert_eq!(x32[i].to_bits(), b[i].to_bits());
            }
        }
        // Scaled by 2^±100 the right-hand side solves to the same digits.
        let (mut big, mut small) = (b.clone(), b.clone());
        big.iter_mut().for_each(|v| *v *= 2f64.powi(100));
        small.iter_mut().for_each(|v| *v *= 2f64.powi(-100));
        f.solve_in_place(&mut big);
        f.solve_in_place(&mut small);
        for ((x, b), s) in x32.iter().zip(&big).zip(&small) {
            assert_eq!(x.to_bits(), (b * 2f64.powi(-100)).to_bits());
            assert_eq!(x.to_bits(), (s * 2f64.powi(100)).to_bits());
        }
    }

    /// Out of f32's range, or too ill-conditioned for f32 (a volumetric
    /// penalty of 2·10¹⁵ Pa), the direction's factor is the f64 one.
    #[test]
    fn the_f64_factor_is_taken_where_single_precision_is_not_adequate() {
        let d = mesh(8, 2);
        let mut values = tangent(&d, &Params::default(), None);
        values.iter_mut().for_each(|v| *v *= 1e39);
        let constrained = d.pattern.constrained(&values).unwrap();
        let e = d.pattern.factorize_single(&constrained).err().unwrap();
        assert!(e.contains("range"), "{e}");
        let f = d.pattern.factorize_direction(&values).unwrap();
        assert_eq!(f.kind(), FactorKind::Cholesky);
        let stiff = Params {
            d_comp: 1e-15,
            ..Params::default()
        };
        let values = tangent(&d, &stiff, None);
        let constrained = d.pattern.constrained(&values).unwrap();
        let e = d.pattern.factorize_single(&constrained).err().unwrap();
        assert!(e.contains("error") || e.contains("positive"), "{e}");
        let before = d.pattern.attempts();
        let f = d.pattern.factorize_direction(&values).unwrap();
        assert_eq!(f.kind(), FactorKind::Cholesky);
        // Not skipped as indefinite (module `indefinite`): attempted.
        let after = d.pattern.attempts();
        assert_eq!(after.cholesky, before.cholesky + 1);
        assert_eq!(after.cholesky_skipped, before.cholesky_skipped);
    }

    /// Newton's solves with the single factor end where those with the f64
    /// factor do, to the solver's tolerance: an activated isometric
    /// equilibrium with a stiff series element (α = 100), the same with a
    /// volumetric penalty 100 times the default (D = 1e-11: on this coarse
    /// mesh some of its tangents pass the tests in f32, some fall back),
    /// and the extreme of level 1 at 1.3 L0; each followed by five 1 ms
    /// steps of stretch. `expect`: the factor of the last tangent, where the
    /// case decides it.
    #[test]
    fn newton_with_the_single_factor_ends_at_the_f64_equilibrium() {
        let stiff_see = Params {
            alpha: 100.0,
            ..Params::default()
        };
        let stiff_volume = Params {
            d_comp: 1e-11,
            ..stiff_see
        };
        for (p, stretch, level, expect) in [
            (stiff_see, 1.1, 0.5, Some(FactorKind::SingleCholesky)),
            (stiff_volume, 1.1, 0.5, None),
            (Params::default(), 1.3, 1.0, None),
        ] {
            let run = |single: bool| {
                let mut d = mesh(6, 1);
                d.pattern.set_single_precision(single);
                let d = Arc::new(d);
                let (mut m, s) = Muscle::isometric(d.clone(), &p, stretch * L0, level).unwrap();
                let mut forces = vec![d.reaction(&s.evaluation.forces)];
                for k in 1..=5 {
                    let l = (stretch + 0.002 * k as f64) * L0;
                    let r = m.advance(&p, l, 1e-3, &|_| level).unwrap();
                    forces.push(d.reaction(&r.solution.evaluation.forces));
                    m = r.muscle;
                }
                let kind = m
                    .tangent
                    .as_ref()
                    .map(|c| c.tangent(&d, &p).unwrap().factor.kind());
                (forces, m.x, kind, d.size())
            };
            let (f32s, x32, kind, size) = run(true);
            let (f64s, x64, _, _) = run(false);
            let dx: Vec<f64> = x32.iter().zip(&x64).map(|(a, b)| a - b).collect();
            println!(
                "α {} D {:e} at {stretch} L0, level {level}: {kind:?}, forces {f32s:?} vs {f64s:?}, positions {:e}",
                p.alpha,
                p.d_comp,
                amax(&dx)
            );
            if expect.is_some() {
                assert_eq!(kind, expect);
            }
            for (a, b) in f32s.iter().zip(&f64s) {
                let tolerance = 1e-10 * a.abs().max(p.sigma0 * MEAN_AREA);
                assert!((a - b).abs() <= tolerance, "{a} vs {b}");
            }
            assert!(amax(&dx) <= 1e-10 * size, "positions {:e}", amax(&dx));
        }
    }

    /// Which factor the stepping takes on the default mesh: a passive pull
    /// of 300 steps of 1 ms to 1.06 L0, then the level raised to 1 over
    /// 100 steps and held for 100 (`cargo test --release --lib
    /// single_precision_census -- --ignored --nocapture`).
    #[test]
    #[ignore]
    fn single_precision_census() {
        let p = Params::default();
        let d = default_mesh();
        let (mut m, _) = Muscle::isometric(d.clone(), &p, L0, 0.0).unwrap();
        let mut seen: Vec<*const crate::fe::tangent::TangentCache> = Vec::new();
        let (mut single, mut double) = (0, 0);
        for k in 1..=500usize {
            let l = L0 * (1.0 + 0.06 * (k.min(300) as f64 / 300.0));
            let level = ((k as f64 - 300.0) / 100.0).clamp(0.0, 1.0);
            let r = m.advance(&p, l, 1e-3, &|_| level).unwrap();
            m = r.muscle;
            if let Some(c) = &m.tangent {
                let ptr = Arc::as_ptr(c);
                if c.is_built() && !seen.contains(&ptr) {
                    seen.push(ptr);
                    match c.tangent(&d, &p).unwrap().factor.kind() {
                        FactorKind::SingleCholesky => single += 1,
                        kind => {
                            double += 1;
                            let a = &c.anchor;
                            let ev = d
                                .evaluate_tangent(
                                    &p,
                                    &a.x,
                                    a.activation,
                                    &a.start,
                                    a.rate,
                                    a.pressure.as_deref(),
                                )
                                .unwrap();
                            let constrained =
                                d.pattern.constrained(ev.tangent.as_ref().unwrap()).unwrap();
                            let why = d.pattern.factorize_single(&constrained).err();
                            println!("step {k}, level {level}: {kind:?}, {why:?}");
                        }
                    }
                }
            }
        }
        println!("tangents factorised: single {single}, f64 {double}");
    }

    /// Unit costs on the default mesh at 10 % strain, f64 and f32 run
    /// alternately (`cargo test --release --lib single_precision_unit_costs
    /// -- --ignored --nocapture`), a residual and a residual with the
    /// tangent, and the probe's error estimate against the volumetric
    /// penalty.
    #[test]
    #[ignore]
    fn single_precision_unit_costs() {
        use std::time::Instant;
        let p = Params::default();
        let (d, x) = default_mesh_stretched();
        let values = tangent(&d, &p, Some(&x));
        let median = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let rounds = 15;
        let (mut fa, mut fb, mut sa, mut sb) = (vec![], vec![], vec![], vec![]);
        let constrained = d.pattern.constrained(&values).unwrap();
        let f64_factor = d.pattern.factorize(&values).unwrap();
        let single = |c: &[f64]| {
            Cholesky::<f32>::new(&d.pattern.llt, c, &d.pattern.prescribed)
                .map(|f| Factor::SingleCholesky(Arc::new(f)))
        };
        let f32_factor = single(&constrained).unwrap();
        let mut fc = vec![];
        let mut b = vec![1.0; 3 * d.n_nodes()];
        for _ in 0..rounds {
            let t = Instant::now();
            let _f = d.pattern.factorize(&values).unwrap();
            fa.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            let _f = single(&constrained).unwrap();
            fb.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            let _f = d.pattern.factorize_direction(&values).unwrap();
            fc.push(t.elapsed().as_secs_f64());
            for _ in 0..5 {
                let t = Instant::now();
                f64_factor.solve_in_place(&mut b);
                sa.push(t.elapsed().as_secs_f64());
                let t = Instant::now();
                f32_factor.solve_in_place(&mut b);
                sb.push(t.elapsed().as_secs_f64());
            }
        }
        let t = Instant::now();
        let estimate = d.pattern.single_error(&constrained, &f32_factor);
        let probe = t.elapsed().as_secs_f64();
        println!(
            "default mesh {} dofs, {} factor values; factorize_direction: {:?}",
            3 * d.n_nodes(),
            d.pattern.factor_values(),
            d.pattern.factorize_direction(&values).unwrap().kind()
        );
        let fc = median(fc);
        let (fa, fb, sa, sb) = (median(fa), median(fb), median(sa), median(sb));
        println!(
            "factorise f64 {:.3} ms, f32 {:.3} ms ({:.2}); factorize_direction {:.3} ms ({:.2}); probe {:.3} ms",
            fa * 1e3,
            fb * 1e3,
            fb / fa,
            fc * 1e3,
            fc / fa,
            probe * 1e3
        );
        println!(
            "solve f64 {:.3} ms, f32 {:.3} ms ({:.2}); estimate {estimate:e}",
            sa * 1e3,
            sb * 1e3,
            sb / sa
        );
        // The other unit costs of a Newton iteration at the same state: a
        // residual, and a residual with the assembled tangent.
        let hist = vec![FibreHistory::REST; d.n_elements()];
        let rate = FibreRate::Step { h: 1e-3 };
        let (mut ra, mut ta) = (vec![], vec![]);
        for _ in 0..rounds {
            let t = Instant::now();
            let _e = d.evaluate(&p, &x, 0.0, &hist, rate, false).unwrap();
            ra.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            let _e = d.evaluate(&p, &x, 0.0, &hist, rate, true).unwrap();
            ta.push(t.elapsed().as_secs_f64());
        }
        println!(
            "residual {:.3} ms, residual with the tangent {:.3} ms",
            median(ra) * 1e3,
            median(ta) * 1e3
        );
        for d_comp in [1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15] {
            let q = Params { d_comp, ..p };
            let values = tangent(&d, &q, Some(&x));
            let constrained = d.pattern.constrained(&values).unwrap();
            let r = d.pattern.factorize_single(&constrained);
            let estimate = single(&constrained).map(|f| d.pattern.single_error(&constrained, &f));
            let f64_factor = d.pattern.factorize(&values).unwrap();
            let (mut x32, mut x64) = (vec![1.0; b.len()], vec![1.0; b.len()]);
            if let Ok(f) = single(&constrained) {
                f.solve_in_place(&mut x32);
            }
            f64_factor.solve_in_place(&mut x64);
            let dx: Vec<f64> = x32.iter().zip(&x64).map(|(a, b)| a - b).collect();
            println!(
                "D {d_comp:e}: estimate {estimate:?}, error on ones {:e}, taken {}",
                amax(&dx) / amax(&x64),
                r.is_ok()
            );
        }
    }
}
