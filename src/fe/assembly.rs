//! Sparse assembly of the FE muscle's tangent and its direct solution.
//!
//! The tangent of the mesh energy (module docs of [`crate::fe::element`]) has
//! a 3 × 3 block for every pair of nodes that share a *node patch*: the
//! isochoric element stiffness couples the nodes of one tetrahedron, and the
//! average-nodal-pressure term Σ_a (U_J''(J_a)/V_a) ∂v_a/∂x ⊗ ∂v_a/∂x couples
//! all nodes of the elements around a node a (its patch), i.e. the nodes two
//! edges apart. The pattern is built once per mesh at node level (sorted
//! neighbour lists including the node itself) and stored as a scalar
//! compressed-sparse-column matrix whose column 3j + c holds, for each
//! neighbour i of j in order, the rows 3i, 3i + 1, 3i + 2 — so the entry (r, c)
//! of block (i, j) is at `col_ptr[3j + c] + 3 k + r`, k the position of i in
//! j's neighbour list. Element and patch contributions scatter through
//! precomputed positions k.
//!
//! Prescribed degrees of freedom (Dirichlet conditions) stay in the matrix:
//! their rows and columns are zeroed and their diagonal set to 1 before the
//! factorisation, which keeps it symmetric; the full (unconstrained) values are
//! kept for the reaction forces' derivatives.
//!
//! Solution: faer's sparse Cholesky (LLᵀ, AMD ordering) while the constrained
//! tangent is positive definite — the usual case. When it is not (a falling
//! force-length branch, fibre tension not yet balanced by pressure in a
//! Newton iterate, compressive instability), the symmetric indefinite
//! factorisation LBLᵀ on the same ordering: Bunch–Kaufman pivoting (1 × 1 and
//! 2 × 2 pivots) within the supernodes, which keeps the symmetric structure
//! and costs about as much as a Cholesky factorisation, far less than
//! sparse LU (the ratios are in BENCHMARKS.md, `cargo bench --bench
//! fe_init`).
//! Pivoting confined to a supernode is not guaranteed stable, so an LBLᵀ
//! factorisation is accepted only when it solves a probe system to a
//! backward error of at most [`MAX_BACKWARD_ERROR`]; otherwise sparse LU with
//! partial pivoting. Which factorisation a matrix gets depends on the matrix
//! alone (a state restored elsewhere refactorises to the same bits). The
//! symbolic factorisations are computed once per mesh, the LBLᵀ and LU ones
//! when first needed. The Cholesky factorisation works on the matrix
//! permuted once per mesh by its AMD ordering: each factorisation gathers
//! the constrained values into the permuted triangle through a fixed map
//! instead of faer sorting and permuting the whole matrix, to the same bits.
//! For Newton's directions the same Cholesky factorisation in single
//! precision is taken where it is adequate for the matrix, the f64 one
//! otherwise ([`Pattern::factorize_direction`], module `cholesky`); when
//! the single-precision one fails at a pivot, the LBLᵀ factorisation comes
//! first and the f64 Cholesky one is skipped where it provably fails
//! (module `indefinite`), to the same factor. [`Pattern::attempts`] counts
//! the factorisations attempted, by kind. A
//! system with a tangent close to one already factorised is solved by
//! conjugate gradients with that factor as the preconditioner
//! ([`Pattern::conjugate_gradients`], module `pcg`).

use std::sync::{Arc, OnceLock};

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::solvers::Solve;
use faer::perm::Perm;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, IntranodeLbltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::linalg::{LuError, SupernodalThreshold};
use faer::sparse::{FaerError, SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{MatMut, Side};
use nalgebra::{Matrix3, SMatrix};

mod attempts;
mod cholesky;
mod indefinite;
mod pcg;
pub use attempts::Attempts;
pub use cholesky::{Cholesky, Precision, MAX_SINGLE_ERROR};
pub use pcg::{dot, Iterate};

/// The node-level sparsity of the tangent and the scatter positions.
#[derive(Debug)]
pub struct Pattern {
    /// Number of nodes (the matrix is 3 n × 3 n).
    pub n_nodes: usize,
    /// Sorted neighbour list per node (including itself).
    pub neighbours: Vec<Vec<u32>>,
    /// Scalar CSC structure.
    symbolic: SymbolicSparseColMat<usize>,
    /// Per element, the position k of node `tet[a]` in the neighbour list of
    /// node `tet[b]`, at `[4 b + a]`.
    element_pos: Vec<[u32; 16]>,
    /// Per node a: its patch (sorted nodes of the elements around a).
    pub patches: Vec<Vec<u32>>,
    /// Per node a: for patch nodes (p, q), the position of p in q's neighbour
    /// list, at `[m q_local + p_local]` (m the patch size).
    patch_pos: Vec<Vec<u32>>,
    /// Slots of the off-diagonal entries in prescribed rows or columns, and of
    /// the prescribed diagonals.
    bc_off_diagonal: Vec<usize>,
    bc_diagonal: Vec<usize>,
    /// Whether each dof is prescribed.
    pub prescribed: Vec<bool>,
    /// Symbolic Cholesky (computed with the pattern) on the AMD-permuted
    /// matrix, supernodal LBLᵀ and LU (on first use).
    llt: Arc<PermutedCholesky>,
    lblt: OnceLock<Result<Arc<SymbolicCholesky<usize>>, String>>,
    lu: OnceLock<Result<SymbolicLu<usize>, String>>,
    /// Whether [`Self::factorize_direction`] may take the single-precision
    /// factor (default; off: always [`Self::factorize`]'s, for comparisons).
    single: bool,
    /// The factorisations attempted, by kind ([`Self::attempts`]).
    counters: attempts::Counters,
}

/// Largest backward error ‖K x − b‖∞ / (‖K‖∞ ‖x‖∞ + ‖b‖∞) of the probe solve
/// at which an LBLᵀ factorisation is accepted (module docs). A backward-stable
/// factorisation gives a few ulps or less (4.5e-18 on the default mesh's
/// indefinite tangent of `cargo bench --bench fe_init`); a pivot growth that
/// spoils the solve shows as orders of magnitude more.
pub const MAX_BACKWARD_ERROR: f64 = 1e-12;

impl Pattern {
    /// The pattern of a mesh with `n_nodes` nodes and tetrahedra `tets`, with
    /// the dofs `prescribed` (length 3 n) held by Dirichlet conditions.
    pub fn new(
        n_nodes: usize,
        tets: &[[usize; 4]],
        prescribed: Vec<bool>,
    ) -> Result<Pattern, String> {
        assert_eq!(prescribed.len(), 3 * n_nodes);
        // Patches: the nodes of the elements around each node.
        let mut patches: Vec<Vec<u32>> = vec![Vec::new(); n_nodes];
        for tet in tets {
            for &a in tet {
                patches[a].extend(tet.iter().map(|&b| b as u32));
            }
        }
        for p in &mut patches {
            p.sort_unstable();
            p.dedup();
        }
        // Neighbours: j ~ i when both lie in one patch.
        let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n_nodes];
        for p in &patches {
            for &j in p {
                neighbours[j as usize].extend_from_slice(p);
            }
        }
        for n in &mut neighbours {
            n.sort_unstable();
            n.dedup();
        }
        let pos = |i: usize, j: usize| -> u32 {
            neighbours[j]
                .binary_search(&(i as u32))
                .expect("pattern covers the pair") as u32
        };
        let element_pos = tets
            .iter()
            .map(|tet| {
                let mut k = [0u32; 16];
                for b in 0..4 {
                    for a in 0..4 {
                        k[4 * b + a] = pos(tet[a], tet[b]);
                    }
                }
                k
            })
            .collect();
        let patch_pos = patches
            .iter()
            .map(|p| {
                let mut v = Vec::with_capacity(p.len() * p.len());
                for &q in p {
                    for &pp in p {
                        v.push(pos(pp as usize, q as usize));
                    }
                }
                v
            })
            .collect();
        // Scalar CSC.
        let n = 3 * n_nodes;
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0usize);
        for nb in &neighbours {
            for _c in 0..3 {
                for &i in nb {
                    row_idx.extend([3 * i as usize, 3 * i as usize + 1, 3 * i as usize + 2]);
                }
                col_ptr.push(row_idx.len());
            }
        }
        let mut bc_off_diagonal = Vec::new();
        let mut bc_diagonal = Vec::new();
        for col in 0..n {
            for (slot, &row) in row_idx
                .iter()
                .enumerate()
                .take(col_ptr[col + 1])
                .skip(col_ptr[col])
            {
                if prescribed[row] || prescribed[col] {
                    if row == col {
                        bc_diagonal.push(slot);
                    } else {
                        bc_off_diagonal.push(slot);
                    }
                }
            }
        }
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let llt = Arc::new(PermutedCholesky::new(symbolic.as_ref())?);
        Ok(Pattern {
            n_nodes,
            neighbours,
            symbolic,
            element_pos,
            patches,
            patch_pos,
            bc_off_diagonal,
            bc_diagonal,
            prescribed,
            llt,
            lblt: OnceLock::new(),
            lu: OnceLock::new(),
            single: true,
            counters: Default::default(),
        })
    }

    /// Let [`Self::factorize_direction`] take the single-precision factor
    /// (`true`, the default) or not.
    pub fn set_single_precision(&mut self, on: bool) {
        self.single = on;
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.symbolic.row_idx().len()
    }

    /// Number of values the Cholesky factor stores (faer's symbolic
    /// analysis with the default AMD ordering, as [`Self::factorize`] uses):
    /// its memory and, twice per triangular solve, its flops.
    pub fn factor_values(&self) -> usize {
        faer::sparse::linalg::cholesky::factorize_symbolic_cholesky(
            self.symbolic_ref(),
            Side::Lower,
            faer::sparse::linalg::cholesky::SymmetricOrdering::Amd,
            Default::default(),
        )
        .map_or(0, |s| s.len_val())
    }

    fn symbolic_ref(&self) -> SymbolicSparseColMatRef<'_, usize> {
        self.symbolic.as_ref()
    }

    /// Slot of entry (r, c) of block (i, j) where k is i's position in j's list.
    #[inline]
    fn slot(&self, j: usize, c: usize, k: u32, r: usize) -> usize {
        self.symbolic.col_ptr()[3 * j + c] + 3 * k as usize + r
    }

    /// A zeroed value array for this pattern.
    pub fn zeros(&self) -> Vec<f64> {
        vec![0.0; self.nnz()]
    }

    /// Add an element's 12 × 12 matrix (rows/columns ordered (node, component)).
    pub fn add_element(
        &self,
        values: &mut [f64],
        e: usize,
        tet: &[usize; 4],
        k: &SMatrix<f64, 12, 12>,
    ) {
        let pos = &self.element_pos[e];
        for b in 0..4 {
            for c in 0..3 {
                let col = 3 * tet[b] + c;
                let base = self.symbolic.col_ptr()[col];
                for a in 0..4 {
                    let at = base + 3 * pos[4 * b + a] as usize;
                    for r in 0..3 {
                        values[at + r] += k[(3 * a + r, 3 * b + c)];
                    }
                }
            }
        }
    }

    /// Add `coefficient · g gᵀ` for a vector g over node `a`'s patch (one
    /// `Vector3` per patch node, in patch order).
    pub fn add_patch_outer(
        &self,
        values: &mut [f64],
        a: usize,
        g: &[nalgebra::Vector3<f64>],
        coefficient: f64,
    ) {
        let patch = &self.patches[a];
        let m = patch.len();
        let pos = &self.patch_pos[a];
        for (ql, &q) in patch.iter().enumerate() {
            let gq = g[ql] * coefficient;
            for (pl, _) in patch.iter().enumerate() {
                let block: Matrix3<f64> = g[pl] * gq.transpose();
                let k = pos[m * ql + pl];
                for c in 0..3 {
                    let at = self.slot(q as usize, c, k, 0);
                    for r in 0..3 {
                        values[at + r] += block[(r, c)];
                    }
                }
            }
        }
    }

    /// y = K x for the full (unconstrained) values.
    pub fn multiply(&self, values: &[f64], x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        let col_ptr = self.symbolic.col_ptr();
        let row_idx = self.symbolic.row_idx();
        for (col, &xc) in x.iter().enumerate() {
            if xc == 0.0 {
                continue;
            }
            for slot in col_ptr[col]..col_ptr[col + 1] {
                y[row_idx[slot]] += values[slot] * xc;
            }
        }
    }

    /// Factorise the constrained tangent built from the full `values`
    /// (prescribed rows and columns replaced by the identity): Cholesky, else
    /// LBLᵀ when it passes the backward-error test, else LU (module docs);
    /// `Err` when LU's probe solve is not finite (a singular tangent).
    pub fn factorize(&self, values: &[f64]) -> Result<Factor, String> {
        let constrained = self.constrained(values)?;
        self.factorize_constrained(&constrained)
    }

    /// [`Self::factorize`] of the constrained values.
    fn factorize_constrained(&self, constrained: &[f64]) -> Result<Factor, String> {
        if let Ok(llt) = self.factorize_llt(constrained) {
            return Ok(llt);
        }
        let lblt = self.factorize_lblt(constrained)?;
        self.accept_lblt(constrained, lblt)
    }

    /// [`Self::factorize_constrained`] after its Cholesky factorisation
    /// failed: `lblt` when it passes the backward-error test, else LU.
    fn accept_lblt(&self, constrained: &[f64], lblt: BunchKaufman) -> Result<Factor, String> {
        let lblt = Factor::BunchKaufman(Arc::new(lblt));
        if self.backward_error(constrained, &lblt) <= MAX_BACKWARD_ERROR {
            return Ok(lblt);
        }
        let lu = self.factorize_lu(constrained)?;
        if self.backward_error(constrained, &lu).is_nan() {
            return Err("the tangent is singular (LU: a zero pivot)".into());
        }
        Ok(lu)
    }

    /// The factorisation `kind` of the constrained tangent, whatever the
    /// matrix (no backward-error test), with the probe solve's backward
    /// error: for tests and benchmarks of [`Self::factorize`]'s choice.
    pub fn factorize_as(&self, values: &[f64], kind: FactorKind) -> Result<(Factor, f64), String> {
        let constrained = self.constrained(values)?;
        let factor = match kind {
            FactorKind::Cholesky => self.factorize_llt(&constrained)?,
            FactorKind::BunchKaufman => {
                Factor::BunchKaufman(Arc::new(self.factorize_lblt(&constrained)?))
            }
            FactorKind::Lu => self.factorize_lu(&constrained)?,
            FactorKind::SingleCholesky => self.factorize_single(&constrained)?,
        };
        let error = self.backward_error(&constrained, &factor);
        Ok((factor, error))
    }

    /// The constrained values: prescribed rows and columns zeroed, their
    /// diagonal 1; `Err` on a non-finite entry.
    fn constrained(&self, values: &[f64]) -> Result<Vec<f64>, String> {
        let mut constrained = try_filled(values.len(), 0.0, "the constrained tangent")?;
        constrained.copy_from_slice(values);
        for &s in &self.bc_off_diagonal {
            constrained[s] = 0.0;
        }
        for &s in &self.bc_diagonal {
            constrained[s] = 1.0;
        }
        if constrained.iter().any(|v| !v.is_finite()) {
            return Err("the tangent has a non-finite entry".into());
        }
        Ok(constrained)
    }

    /// The Cholesky factorisation of the constrained values; `Err` when they
    /// are not (numerically) positive definite. The values are gathered
    /// into the permuted triangle ([`PermutedCholesky`]) and factorised
    /// there without faer's own permutation of the matrix.
    fn factorize_llt(&self, constrained: &[f64]) -> Result<Factor, String> {
        attempts::count(&self.counters.cholesky);
        Ok(Factor::Cholesky(Arc::new(Cholesky::<f64>::new(
            &self.llt,
            constrained,
            &self.prescribed,
        )?)))
    }

    /// The supernodal LBLᵀ factorisation of the constrained values, with
    /// Bunch–Kaufman pivoting within the supernodes (AMD ordering; the
    /// supernodal structure is forced: faer's simplicial variant does not
    /// pivot).
    fn factorize_lblt(&self, constrained: &[f64]) -> Result<BunchKaufman, String> {
        let symbolic = self
            .lblt
            .get_or_init(|| {
                let params = CholeskySymbolicParams {
                    supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
                    ..Default::default()
                };
                factorize_symbolic_cholesky(
                    self.symbolic_ref(),
                    Side::Lower,
                    SymmetricOrdering::Amd,
                    params,
                )
                .map(Arc::new)
                .map_err(|e| format!("symbolic LBLT factorisation failed: {e:?}"))
            })
            .clone()?;
        attempts::count(&self.counters.lblt);
        let n = symbolic.nrows();
        // Fallible: the factor is the FE muscle's largest allocation
        // (crate::fe::memory), and its failure an error, not an abort.
        let mut values = try_filled(symbolic.len_val(), 0.0, "the LBLT factor")?;
        let mut subdiagonal = try_filled(n, 0.0, "the LBLT factor")?;
        let mut forward = try_filled(n, 0usize, "the LBLT factor")?;
        let mut inverse = try_filled(n, 0usize, "the LBLT factor")?;
        let par = faer::get_global_parallelism();
        let mut scratch = MemBuffer::try_new(
            symbolic.factorize_numeric_intranode_lblt_scratch::<f64>(par, Default::default()),
        )
        .map_err(|e| format!("LBLT factorisation: {e:?}"))?;
        symbolic.factorize_numeric_intranode_lblt(
            &mut values,
            &mut subdiagonal,
            &mut forward,
            &mut inverse,
            SparseColMatRef::new(self.symbolic_ref(), constrained),
            Side::Lower,
            par,
            MemStack::new(&mut scratch),
            Default::default(),
        );
        // The pivoting permutation as faer returns it, checked here (an
        // error, not faer's panic) and kept as faer's permutation for the
        // solves.
        let permutation = forward
            .iter()
            .enumerate()
            .all(|(i, &f)| inverse.get(f) == Some(&i));
        if !permutation {
            return Err("LBLT factorisation: invalid pivoting permutation".into());
        }
        Ok(BunchKaufman {
            symbolic,
            values,
            subdiagonal,
            permutation: Perm::new_checked(forward.into(), inverse.into(), n),
        })
    }

    /// The sparse LU factorisation (partial pivoting) of the constrained
    /// values.
    fn factorize_lu(&self, constrained: &[f64]) -> Result<Factor, String> {
        let symbolic = self
            .lu
            .get_or_init(|| {
                SymbolicLu::try_new(self.symbolic_ref())
                    .map_err(|e| format!("symbolic LU factorisation failed: {e:?}"))
            })
            .clone()?;
        attempts::count(&self.counters.lu);
        let mat = SparseColMatRef::new(self.symbolic_ref(), constrained);
        // faer's LU allocates fallibly; its failure is an error here.
        let lu = Lu::try_new_with_symbolic(symbolic, mat).map_err(|e| match e {
            LuError::Generic(FaerError::OutOfMemory) => {
                "out of memory for the LU factor of the tangent".to_string()
            }
            e => format!("the tangent is singular (LU: {e:?})"),
        })?;
        Ok(Factor::Lu(Arc::new(lu)))
    }

    /// The probe right-hand side b_i = 1 + (i mod 7)/7 of the factor tests.
    fn probe(n: usize) -> Vec<f64> {
        (0..n).map(|i| 1.0 + (i % 7) as f64 / 7.0).collect()
    }

    /// Backward error ‖K x − b‖∞ / (‖K‖∞ ‖x‖∞ + ‖b‖∞) of `factor`'s solution x
    /// of K x = b, K the `constrained` matrix and b the fixed vector
    /// b_i = 1 + (i mod 7)/7 (module docs); NaN when the solve is not finite
    /// (a zero pivot).
    fn backward_error(&self, constrained: &[f64], factor: &Factor) -> f64 {
        let n = 3 * self.n_nodes;
        let b = Self::probe(n);
        let mut x = b.clone();
        factor.solve_in_place(&mut x);
        let mut kx = vec![0.0; n];
        self.multiply(constrained, &x, &mut kx);
        // Max norm, NaN when any entry is (f64::max would skip it).
        let norm = |v: &mut dyn Iterator<Item = f64>| {
            v.fold(0.0f64, |m, a| {
                if m.is_nan() || a.is_nan() {
                    f64::NAN
                } else {
                    m.max(a.abs())
                }
            })
        };
        let col_ptr = self.symbolic.col_ptr();
        // ‖K‖∞ as the largest column sum (K symmetric).
        let k_norm = norm(&mut (0..n).map(|c| {
            constrained[col_ptr[c]..col_ptr[c + 1]]
                .iter()
                .map(|v| v.abs())
                .sum::<f64>()
        }));
        let residual = norm(&mut kx.iter().zip(&b).map(|(a, c)| a - c));
        let scale = k_norm * norm(&mut x.iter().copied()) + norm(&mut b.iter().copied());
        if residual.is_finite() && scale.is_finite() {
            residual / scale
        } else {
            f64::NAN
        }
    }
}

/// The Cholesky factorisation's symbolic part on the matrix permuted once
/// and for all by faer's AMD ordering of the pattern: the permuted
/// matrix's triangle that faer's numeric factorisation reads (lower for its
/// supernodal variant, upper for its simplicial one) with, per entry, the
/// slot of the pattern it comes from (the original lower triangle's, as
/// faer takes it); its symbolic analysis with the identity ordering is
/// that of the AMD ordering (same elimination tree, column counts and
/// supernodes: the same graph), with the same choice of variant. So a
/// factorisation gathers its values instead of having faer sort and
/// permute the whole matrix each time, and factorises to the same bits.
#[derive(Debug)]
struct PermutedCholesky {
    /// Symbolic factorisation of the permuted matrix (identity ordering).
    symbolic: SymbolicCholesky<usize>,
    /// The triangle the numeric factorisation reads, its side and sources.
    numeric: SymbolicSparseColMat<usize>,
    side: Side,
    source: Vec<usize>,
    /// The AMD ordering: row i of the permuted matrix is row `forward[i]`.
    forward: Vec<usize>,
}

impl PermutedCholesky {
    fn new(a: SymbolicSparseColMatRef<'_, usize>) -> Result<PermutedCholesky, String> {
        let failed = |e| format!("symbolic Cholesky factorisation failed: {e:?}");
        let amd =
            factorize_symbolic_cholesky(a, Side::Lower, SymmetricOrdering::Amd, Default::default())
                .map_err(failed)?;
        let n = a.nrows();
        let (forward, inverse) = match amd.perm() {
            Some(perm) => {
                let (f, i) = perm.arrays();
                (f.to_vec(), i.to_vec())
            }
            None => ((0..n).collect(), (0..n).collect()),
        };
        let supernodal = matches!(amd.raw(), SymbolicCholeskyRaw::Supernodal(_));
        // The original lower triangle's entries at their permuted places,
        // as (column, row, slot) of the permuted lower triangle.
        let mut lower = Vec::new();
        for col in 0..n {
            for slot in a.col_ptr()[col]..a.col_ptr()[col + 1] {
                let row = a.row_idx()[slot];
                if row >= col {
                    let (i, j) = (inverse[row], inverse[col]);
                    lower.push((i.min(j), i.max(j), slot));
                }
            }
        }
        let csc = |entries: &mut Vec<(usize, usize, usize)>| {
            entries.sort_unstable();
            let mut col_ptr = vec![0usize; n + 1];
            for &(c, _, _) in entries.iter() {
                col_ptr[c + 1] += 1;
            }
            for c in 0..n {
                col_ptr[c + 1] += col_ptr[c];
            }
            let rows = entries.iter().map(|e| e.1).collect();
            let source = entries.iter().map(|e| e.2).collect::<Vec<_>>();
            (
                SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows),
                source,
            )
        };
        let mut upper: Vec<_> = lower.iter().map(|&(c, r, s)| (r, c, s)).collect();
        let (upper, upper_source) = csc(&mut upper);
        let threshold = if supernodal {
            SupernodalThreshold::FORCE_SUPERNODAL
        } else {
            SupernodalThreshold::FORCE_SIMPLICIAL
        };
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: threshold,
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(
            upper.as_ref(),
            Side::Upper,
            SymmetricOrdering::Identity,
            params,
        )
        .map_err(failed)?;
        let (numeric, side, source) = if supernodal {
            let (l, s) = csc(&mut lower);
            (l, Side::Lower, s)
        } else {
            (upper, Side::Upper, upper_source)
        };
        Ok(PermutedCholesky {
            symbolic,
            numeric,
            side,
            source,
            forward,
        })
    }
}

/// A supernodal LBLᵀ factorisation ([`Pattern::factorize`]): the factor's
/// values, the 2 × 2 pivots' subdiagonal and the pivoting permutation, with
/// the symbolic structure they belong to.
pub struct BunchKaufman {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<f64>,
    subdiagonal: Vec<f64>,
    permutation: Perm<usize>,
}

impl BunchKaufman {
    fn solve_in_place(&self, b: &mut [f64]) {
        let n = b.len();
        let par = faer::get_global_parallelism();
        let factor = IntranodeLbltRef::new(
            &self.symbolic,
            &self.values,
            &self.subdiagonal,
            self.permutation.as_ref(),
        );
        let mut scratch = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(1, par));
        factor.solve_in_place_with_conj(
            faer::Conj::No,
            MatMut::from_column_major_slice_mut(b, n, 1),
            par,
            MemStack::new(&mut scratch),
        );
    }
}

/// A numeric factorisation of the constrained tangent.
#[derive(Clone)]
pub enum Factor {
    Cholesky(Arc<Cholesky<f64>>),
    /// The single-precision Cholesky factor of Newton's directions
    /// ([`Pattern::factorize_direction`]).
    SingleCholesky(Arc<Cholesky<f32>>),
    BunchKaufman(Arc<BunchKaufman>),
    Lu(Arc<Lu<usize, f64>>),
}

/// Which factorisation [`Pattern::factorize`] chose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FactorKind {
    Cholesky,
    SingleCholesky,
    BunchKaufman,
    Lu,
}

impl Factor {
    /// Solve K x = b in place (b has length 3 n; prescribed entries of b
    /// come back unchanged, as the constrained matrix has identity rows there).
    pub fn solve_in_place(&self, b: &mut [f64]) {
        let n = b.len();
        match self {
            Factor::Cholesky(f) => f.solve_in_place(b),
            Factor::SingleCholesky(f) => f.solve_in_place(b),
            Factor::BunchKaufman(f) => f.solve_in_place(b),
            Factor::Lu(f) => f.solve_in_place(MatMut::from_column_major_slice_mut(b, n, 1)),
        }
    }

    /// Which factorisation this is (Cholesky: the tangent was positive
    /// definite).
    pub fn kind(&self) -> FactorKind {
        match self {
            Factor::Cholesky(_) => FactorKind::Cholesky,
            Factor::SingleCholesky(_) => FactorKind::SingleCholesky,
            Factor::BunchKaufman(_) => FactorKind::BunchKaufman,
            Factor::Lu(_) => FactorKind::Lu,
        }
    }
}

/// A vector of `n` copies of `value`, its memory reserved fallibly: `Err`
/// naming `what` and the size when the allocator refuses (an error the FMU
/// returns, where `vec!` would abort the host process).
pub fn try_filled<T: Clone>(n: usize, value: T, what: &str) -> Result<Vec<T>, String> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| {
        format!(
            "out of memory for {what}: {n} values of {} bytes",
            std::mem::size_of::<T>()
        )
    })?;
    v.resize(n, value);
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, Vector3};

    /// A 2-tet mesh sharing a face: every pair of its 5 nodes is coupled.
    fn two_tets() -> Vec<[usize; 4]> {
        vec![[0, 1, 2, 3], [1, 2, 3, 4]]
    }

    fn dense(p: &Pattern, values: &[f64]) -> DMatrix<f64> {
        let n = 3 * p.n_nodes;
        let mut d = DMatrix::zeros(n, n);
        let col_ptr = p.symbolic.col_ptr();
        let row_idx = p.symbolic.row_idx();
        for col in 0..n {
            for s in col_ptr[col]..col_ptr[col + 1] {
                d[(row_idx[s], col)] += values[s];
            }
        }
        d
    }

    fn pseudo_random(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    #[test]
    fn element_and_patch_scatter_land_where_a_dense_assembly_puts_them() {
        let tets = two_tets();
        let p = Pattern::new(5, &tets, vec![false; 15]).unwrap();
        let mut values = p.zeros();
        let mut expect = DMatrix::<f64>::zeros(15, 15);
        for (e, tet) in tets.iter().enumerate() {
            let r = pseudo_random(144, 7 + e as u64);
            let k = SMatrix::<f64, 12, 12>::from_column_slice(&r);
            p.add_element(&mut values, e, tet, &k);
            for a in 0..4 {
                for b in 0..4 {
                    for i in 0..3 {
                        for j in 0..3 {
                            expect[(3 * tet[a] + i, 3 * tet[b] + j)] += k[(3 * a + i, 3 * b + j)];
                        }
                    }
                }
            }
        }
        for a in 0..5 {
            let patch = &p.patches[a];
            let r = pseudo_random(3 * patch.len(), 100 + a as u64);
            let g: Vec<Vector3<f64>> = r
                .chunks(3)
                .map(|c| Vector3::new(c[0], c[1], c[2]))
                .collect();
            p.add_patch_outer(&mut values, a, &g, 2.5);
            for (pl, &pn) in patch.iter().enumerate() {
                for (ql, &qn) in patch.iter().enumerate() {
                    for i in 0..3 {
                        for j in 0..3 {
                            expect[(3 * pn as usize + i, 3 * qn as usize + j)] +=
                                2.5 * g[pl][i] * g[ql][j];
                        }
                    }
                }
            }
        }
        assert!((dense(&p, &values) - &expect).amax() < 1e-14);
        // The product with the full values.
        let x = pseudo_random(15, 3);
        let mut y = vec![0.0; 15];
        p.multiply(&values, &x, &mut y);
        let y_dense = &expect * nalgebra::DVector::from_vec(x);
        assert!(y
            .iter()
            .zip(y_dense.iter())
            .all(|(a, b)| (a - b).abs() < 1e-13));
    }

    /// The two-tet pattern with dofs 0 and 14 prescribed.
    fn constrained_two_tets() -> (Pattern, Vec<bool>) {
        let mut prescribed = vec![false; 15];
        prescribed[0] = true;
        prescribed[14] = true;
        (
            Pattern::new(5, &two_tets(), prescribed.clone()).unwrap(),
            prescribed,
        )
    }

    /// Values on the pattern: per element A Aᵀ + shift I (A pseudo-random).
    fn shifted_gram(p: &Pattern, shift: f64) -> Vec<f64> {
        let mut values = p.zeros();
        for (e, tet) in two_tets().iter().enumerate() {
            let r = pseudo_random(144, 11 + e as u64);
            let a = SMatrix::<f64, 12, 12>::from_column_slice(&r);
            let k = a * a.transpose() + SMatrix::<f64, 12, 12>::identity() * shift;
            p.add_element(&mut values, e, tet, &k);
        }
        values
    }

    /// The Cholesky factorisation on the once-permuted matrix solves to the
    /// same bits as faer's own (which permutes the matrix at every
    /// factorisation): on a tangent of a mesh large enough for the
    /// supernodal variant, and on the two tetrahedra (simplicial).
    #[test]
    fn permuted_cholesky_solves_to_faers_bits() {
        use crate::fe::discretization::{Discretization, Ends};
        use crate::fe::mesh::{FibreLayout, Resolution};
        use crate::law::{FibreHistory, FibreRate, Params};
        use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
        let faer_solve = |p: &Pattern, values: &[f64], b: &mut [f64]| {
            let constrained = p.constrained(values).unwrap();
            let symbolic = SymbolicLlt::try_new(p.symbolic_ref(), Side::Lower).unwrap();
            let mat = SparseColMatRef::new(p.symbolic_ref(), &constrained);
            let llt = Llt::try_new_with_symbolic(symbolic, mat, Side::Lower).unwrap();
            let n = b.len();
            llt.solve_in_place(MatMut::from_column_major_slice_mut(b, n, 1));
        };
        let d = Discretization::fusiform(
            0.05,
            crate::specimen::MEAN_AREA,
            Resolution {
                n_axial: 8,
                n_radial: 2,
            },
            FibreLayout::Meridian,
            Ends::Clamped,
        )
        .unwrap();
        let x = d.reference_positions();
        let hist = vec![
            FibreHistory {
                lambda_s: 1.0,
                lambda_m: 1.0
            };
            d.n_elements()
        ];
        let ev = d
            .evaluate(
                &Params::default(),
                &x,
                0.0,
                &hist,
                FibreRate::Step { h: 1e-3 },
                true,
            )
            .unwrap();
        let values = ev.tangent.unwrap();
        let (constrained, _) = constrained_two_tets();
        let gram = shifted_gram(&constrained, 0.5);
        for (p, values) in [(&d.pattern, &values), (&constrained, &gram)] {
            assert!(
                matches!(p.llt.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_))
                    == (p.n_nodes > 5)
            );
            let f = p.factorize(values).unwrap();
            assert_eq!(f.kind(), FactorKind::Cholesky, "{} nodes", p.n_nodes);
            let b = pseudo_random(3 * p.n_nodes, 7);
            let (mut ours, mut theirs) = (b.clone(), b);
            f.solve_in_place(&mut ours);
            faer_solve(p, values, &mut theirs);
            assert!(ours
                .iter()
                .zip(&theirs)
                .all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }

    /// The largest residual |K x − b| of `f`'s solve of the constrained
    /// dense system, and whether prescribed entry 0 came back unchanged.
    fn dense_residual(p: &Pattern, prescribed: &[bool], values: &[f64], f: &Factor) -> (f64, bool) {
        let mut k = dense(p, values);
        for d in 0..15 {
            if prescribed[d] {
                for o in 0..15 {
                    k[(d, o)] = 0.0;
                    k[(o, d)] = 0.0;
                }
                k[(d, d)] = 1.0;
            }
        }
        let b = pseudo_random(15, 5);
        let mut x = b.clone();
        f.solve_in_place(&mut x);
        let r =
            &k * nalgebra::DVector::from_vec(x.clone()) - nalgebra::DVector::from_vec(b.clone());
        (r.amax(), x[0] == b[0])
    }

    /// A symmetric positive definite matrix on the pattern: the Cholesky
    /// path; an indefinite one: the LBLᵀ path (Cholesky refuses it, its
    /// probe backward error is at round-off); LU forced on the same matrix.
    /// Each solves to round-off, with the prescribed dofs decoupled.
    #[test]
    fn cholesky_lblt_and_lu_paths_solve_the_constrained_system() {
        let (p, prescribed) = constrained_two_tets();
        for (shift, expect) in [
            (20.0, FactorKind::Cholesky),
            (-0.3, FactorKind::BunchKaufman),
        ] {
            let values = shifted_gram(&p, shift);
            let f = p.factorize(&values).unwrap();
            assert_eq!(f.kind(), expect, "shift {shift}");
            let (r, kept) = dense_residual(&p, &prescribed, &values, &f);
            assert!(r < 1e-10 && kept, "shift {shift}: residual {r}");
        }
        let values = shifted_gram(&p, -0.3);
        assert!(p.factorize_as(&values, FactorKind::Cholesky).is_err());
        let (lu, error) = p.factorize_as(&values, FactorKind::Lu).unwrap();
        assert_eq!(lu.kind(), FactorKind::Lu);
        assert!(error < 1e-14, "LU probe backward error {error:e}");
        let (r, kept) = dense_residual(&p, &prescribed, &values, &lu);
        assert!(r < 1e-10 && kept, "LU: residual {r}");
        let (_, error) = p.factorize_as(&values, FactorKind::BunchKaufman).unwrap();
        assert!(error < 1e-14, "LBLT probe backward error {error:e}");
    }

    /// The backward-error test can fail: a factorisation of another matrix
    /// does not pass it for this one, and a singular matrix (zero on the
    /// free dofs) gets no factorisation at all (its probe solves are not
    /// finite: not accepted as LBLᵀ, and refused after LU).
    #[test]
    fn the_backward_error_test_rejects_what_does_not_solve_the_matrix() {
        let (p, _) = constrained_two_tets();
        let indefinite = shifted_gram(&p, -0.3);
        let (other, _) = p
            .factorize_as(&shifted_gram(&p, -0.1), FactorKind::BunchKaufman)
            .unwrap();
        let constrained = p.constrained(&indefinite).unwrap();
        let error = p.backward_error(&constrained, &other);
        assert!(error > 1e3 * MAX_BACKWARD_ERROR, "{error:e}");
        let singular = p.zeros();
        let (_, error) = p.factorize_as(&singular, FactorKind::BunchKaufman).unwrap();
        assert!(error.is_nan(), "{error:e}");
        let e = p
            .factorize(&singular)
            .err()
            .expect("a singular tangent is refused");
        assert!(e.contains("singular"), "{e}");
    }

    /// An allocation the allocator cannot serve is an error naming what it
    /// was for, not an abort of the process.
    #[test]
    fn an_impossible_allocation_is_an_error() {
        let e = try_filled(usize::MAX / 16, 0.0f64, "the LBLT factor").unwrap_err();
        assert!(e.contains("out of memory for the LBLT factor"), "{e}");
        assert_eq!(try_filled(3, 1.5, "x").unwrap(), vec![1.5; 3]);
    }
}
