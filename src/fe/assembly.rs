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
//! tangent is positive definite — the usual case — and sparse LU when it is not
//! (a falling force-length branch or compressive instability can make it
//! indefinite). Both symbolic factorisations are computed once per mesh, the
//! LU one only when first needed.

use std::sync::{Arc, OnceLock};

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, Lu, SymbolicLlt, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{MatMut, Side};
use nalgebra::{Matrix3, SMatrix};

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
    /// Symbolic Cholesky (computed with the pattern) and LU (on first use).
    llt: SymbolicLlt<usize>,
    lu: OnceLock<Result<SymbolicLu<usize>, String>>,
}

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
        let llt = SymbolicLlt::try_new(symbolic.as_ref(), Side::Lower)
            .map_err(|e| format!("symbolic Cholesky factorisation failed: {e:?}"))?;
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
            lu: OnceLock::new(),
        })
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
    /// (prescribed rows and columns replaced by the identity).
    pub fn factorize(&self, values: &[f64]) -> Result<Factor, String> {
        let mut constrained = values.to_vec();
        for &s in &self.bc_off_diagonal {
            constrained[s] = 0.0;
        }
        for &s in &self.bc_diagonal {
            constrained[s] = 1.0;
        }
        if constrained.iter().any(|v| !v.is_finite()) {
            return Err("the tangent has a non-finite entry".into());
        }
        let mat = SparseColMatRef::new(self.symbolic_ref(), &constrained);
        if let Ok(llt) = Llt::try_new_with_symbolic(self.llt.clone(), mat, Side::Lower) {
            return Ok(Factor::Cholesky(Arc::new(llt)));
        }
        let symbolic = self
            .lu
            .get_or_init(|| {
                SymbolicLu::try_new(self.symbolic_ref())
                    .map_err(|e| format!("symbolic LU factorisation failed: {e:?}"))
            })
            .clone()?;
        let lu = Lu::try_new_with_symbolic(symbolic, mat)
            .map_err(|e| format!("the tangent is singular (LU: {e:?})"))?;
        Ok(Factor::Lu(Arc::new(lu)))
    }
}

/// A numeric factorisation of the constrained tangent.
#[derive(Clone)]
pub enum Factor {
    Cholesky(Arc<Llt<usize, f64>>),
    Lu(Arc<Lu<usize, f64>>),
}

impl Factor {
    /// Solve K x = b in place (b has length 3 n; prescribed entries of b
    /// come back unchanged, as the constrained matrix has identity rows there).
    pub fn solve_in_place(&self, b: &mut [f64]) {
        let n = b.len();
        let rhs = MatMut::from_column_major_slice_mut(b, n, 1);
        match self {
            Factor::Cholesky(f) => f.solve_in_place(rhs),
            Factor::Lu(f) => f.solve_in_place(rhs),
        }
    }

    /// Whether this is the Cholesky factorisation (the tangent was positive
    /// definite).
    pub fn is_cholesky(&self) -> bool {
        matches!(self, Factor::Cholesky(_))
    }
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

    /// A symmetric positive definite matrix on the pattern: the Cholesky path;
    /// an indefinite one: the LU path; both solve to round-off, with the
    /// prescribed dofs decoupled.
    #[test]
    fn cholesky_and_lu_paths_solve_the_constrained_system() {
        let tets = two_tets();
        let mut prescribed = vec![false; 15];
        prescribed[0] = true;
        prescribed[14] = true;
        let p = Pattern::new(5, &tets, prescribed.clone()).unwrap();
        for (shift, expect_cholesky) in [(20.0, true), (-0.3, false)] {
            let mut values = p.zeros();
            for (e, tet) in tets.iter().enumerate() {
                let r = pseudo_random(144, 11 + e as u64);
                let a = SMatrix::<f64, 12, 12>::from_column_slice(&r);
                let k = a * a.transpose() + SMatrix::<f64, 12, 12>::identity() * shift;
                p.add_element(&mut values, e, tet, &k);
            }
            let f = p.factorize(&values).unwrap();
            assert_eq!(f.is_cholesky(), expect_cholesky, "shift {shift}");
            let mut k = dense(&p, &values);
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
            let r = &k * nalgebra::DVector::from_vec(x.clone())
                - nalgebra::DVector::from_vec(b.clone());
            assert!(r.amax() < 1e-10, "shift {shift}: residual {}", r.amax());
            assert_eq!(x[0], b[0]);
        }
    }
}
