//! The spatial problem of the FE muscle: a tetrahedral mesh of the specimen
//! under the law, held at its end faces ([`Ends`]), and at given node
//! positions x its nodal forces R(x) = ∂Π/∂x with the tangent ∂R/∂x and
//! ∂R/∂a (Π the mesh energy of [`crate::fe::element`]: isochoric law per
//! element, volumetric term per node or per element, [`Volumetric`]).
//!
//! Entry points: [`Discretization::fusiform`] (the paper's specimen) or
//! [`Discretization::new`] (any mesh); [`Discretization::evaluate`];
//! [`Discretization::reaction`] (the muscle force) and its derivatives
//! [`Discretization::force_derivatives`] (or with a nearby tangent's factor,
//! [`Discretization::force_derivatives_preconditioned`]),
//! [`Discretization::sensitivities`].
//!
//! Invariants: a discretization is fixed once built (but for its thread
//! count, [`Discretization::set_threads`], which changes no result) and
//! shared by every copy of a muscle's state; an evaluation fails (`Err`) on
//! an inverted element or a non-finite force, never returns one; the forces
//! with and without the tangent are the same bits; every evaluation is the
//! same bits for every thread count.
//!
//! # Boundary conditions ([`Ends`])
//!
//! - `Clamped` (the paper's test): every node of the end face x = 0 fixed;
//!   every node of the face x = L0 moved along the axis by L − L0 and held
//!   laterally.
//! - `Sliding` (homogeneous patch tests): both end faces held only axially
//!   (x = 0 and x = L), plus the three lateral rigid-body modes removed at the
//!   fixed face (the axis node's y and z, the z of the ring node on the +y
//!   axis) — a straight bar then deforms homogeneously.
//!
//! The muscle force is the axial reaction on the moved face, Σ R_x over its
//! nodes (tension positive).

use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::{Matrix3, SMatrix, Vector3};

use crate::fe::assembly::{dot, try_filled, Factor, Pattern};
use crate::fe::element::{nodal_volumes, IsochoricElement, TetReference};
use crate::fe::mesh::{revolve_graded, FibreLayout, Fusiform, Grading, Mesh, Resolution, Section};
use crate::fe::threads::{
    in_order, Threads, RESIDUAL_ELEMENTS_PER_THREAD, TANGENT_ELEMENTS_PER_THREAD,
};
use crate::fe::work::Ledger;
use crate::law::hill_fibre::FibreStress;
use crate::law::stress::IsochoricStress;
use crate::law::volumetric::volumetric_derivatives;
use crate::law::{FibreHistory, FibreRate, LawPoint, Params};

/// How the end faces are held (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ends {
    Clamped,
    Sliding,
}

/// Where the volumetric penalty U_J = (J − 1)²/D acts ([`crate::fe::element`]
/// module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Volumetric {
    /// On nodal volume ratios J_a (average nodal pressure, Bonet & Burton
    /// 1998): one constraint per node; the FE muscle's formulation.
    NodalAverage,
    /// On each element's own J_e: the plain displacement tetrahedron, one
    /// constraint per element. Locks when nearly incompressible; kept to
    /// show that (docs/fe.md, verification item 2).
    Element,
}

/// Iterations each solve of [`Discretization::force_derivatives_preconditioned`]
/// may take before the derivatives fall back to a factorisation of their
/// own: with Newton's reused factor (contracting by ≤ 1/4) CG gains about
/// a factor 10 per iteration, so a solve that has not converged in this
/// many has a preconditioner too far from the tangent to pay.
pub const DERIVATIVE_ITERATIONS: usize = 30;

/// The stopping test of [`Discretization::force_derivatives_preconditioned`]:
/// its estimate of each derivative's error (the product of the energy-norm
/// errors of the solves it takes, each estimated by rᵀK̃⁻¹r) at most this ×
/// the derivative. rᵀK̃⁻¹r is rᵀK⁻¹r to within the extreme eigenvalues of
/// K̃⁻¹K_ff, 1 ± O(θ) for a reused tangent contracting by θ ≤ 1/4; this
/// leaves a factor 100 for an eigenvalue down to 0.01, so the derivatives
/// are those of the exact factorisation to ≤ 1e-9 relative (far below the
/// 1e-5 to which they match finite differences of the step map).
pub const DERIVATIVE_TOLERANCE: f64 = 1e-11;

/// (dF/dL, dF/da) by preconditioned conjugate gradients
/// ([`Discretization::force_derivatives_preconditioned`]) and the
/// iterations each of the two solves took.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IterativeDerivatives {
    pub length: f64,
    pub activation: f64,
    pub iterations: [usize; 2],
}

/// Everything fixed once the geometry, mesh and boundary conditions are
/// chosen: shared (behind an `Arc`) by every copy of a muscle's state.
#[derive(Debug)]
pub struct Discretization {
    pub mesh: Mesh,
    /// Rest length L0 (the mesh length).
    pub l0: f64,
    pub ends: Ends,
    references: Vec<TetReference>,
    /// Per element, the inverse of its reference edge matrix
    /// D_m = [X1 − X0, X2 − X0, X3 − X0] (F = D_s D_m⁻¹).
    dm_inv: Vec<Matrix3<f64>>,
    /// Reference nodal volumes V_a.
    nodal_reference: Vec<f64>,
    /// Per node a: the elements around it and, per element node, its index
    /// in a's patch.
    node_elements: Vec<Vec<(u32, [u8; 4])>>,
    pub pattern: Pattern,
    /// Dofs prescribed by the moved face's axial motion.
    moved_axial: Vec<usize>,
    /// Mean reference cross-section V/L0 of the mesh.
    mean_area: f64,
    /// The diagonal of the reference bounding box ([`Discretization::size`]).
    size: f64,
    /// The nominal mean cross-section the geometry was built for (V0/L0 of
    /// the exact profile; the mesh's differs by its volume error).
    pub area: f64,
    /// Fibre layout the mesh was built with.
    pub fibres: FibreLayout,
    /// The volumetric formulation ([`Volumetric::NodalAverage`] unless
    /// [`Discretization::with_volumetric`] says otherwise).
    pub volumetric: Volumetric,
    /// How many threads the element loops may use ([`Self::set_threads`]).
    threads: AtomicUsize,
    /// The equilibrium solves' work, failed attempts included.
    pub work: Ledger,
}

impl Discretization {
    /// The paper's fusiform muscle scaled to rest length `l0` and mean
    /// cross-section `area` (= V0/L0), meshed at `resolution` with
    /// equal-area cross-sections and uniform slices.
    pub fn fusiform(
        l0: f64,
        area: f64,
        resolution: Resolution,
        fibres: FibreLayout,
        ends: Ends,
    ) -> Result<Discretization, String> {
        Self::fusiform_graded(l0, area, resolution, Grading::UNIFORM, fibres, ends)
    }

    /// The specimen (MODEL_NOTES "Experiments": [`crate::specimen::LENGTH`],
    /// [`crate::specimen::MEAN_AREA`]) as the FMUs mesh it, at `resolution`:
    /// graded by [`crate::fe::mesh::LUMPED_GRADING`], axial fibres, ends
    /// clamped.
    pub fn specimen(resolution: Resolution) -> Result<Discretization, String> {
        Self::fusiform_graded(
            crate::specimen::LENGTH,
            crate::specimen::MEAN_AREA,
            resolution,
            crate::fe::mesh::LUMPED_GRADING,
            FibreLayout::Axial,
            Ends::Clamped,
        )
    }

    /// [`Discretization::fusiform`] with the slices graded toward the end
    /// faces and the rings toward the lateral surface ([`Grading`]).
    pub fn fusiform_graded(
        l0: f64,
        area: f64,
        resolution: Resolution,
        grading: Grading,
        fibres: FibreLayout,
        ends: Ends,
    ) -> Result<Discretization, String> {
        grading.check()?;
        let radial = (area / crate::specimen::MEAN_AREA).sqrt();
        let profile = Fusiform {
            length: l0,
            r_end: crate::specimen::END_RADIUS * radial,
            r_mid: crate::specimen::MID_RADIUS * radial,
        };
        let mut d = Discretization::new(
            revolve_graded(&profile, resolution, fibres, Section::EqualArea, grading),
            ends,
        )?;
        d.area = area;
        d.fibres = fibres;
        Ok(d)
    }

    /// From a mesh (its `fixed_face` at x = 0, `moved_face` at x = length).
    pub fn new(mesh: Mesh, ends: Ends) -> Result<Discretization, String> {
        let n = mesh.nodes.len();
        let references: Vec<TetReference> = (0..mesh.tets.len())
            .map(|e| TetReference::new(&mesh.tet_points(e)))
            .collect();
        if references
            .iter()
            .any(|r| r.volume.is_nan() || r.volume <= 0.0)
        {
            return Err("the mesh has an element of non-positive volume".into());
        }
        let element_volumes: Vec<f64> = references.iter().map(|r| r.volume).collect();
        let dm_inv = (0..mesh.tets.len())
            .map(|e| {
                let x = mesh.tet_points(e);
                Matrix3::from_columns(&[x[1] - x[0], x[2] - x[0], x[3] - x[0]])
                    .try_inverse()
                    .expect("an element of positive volume")
            })
            .collect();
        let nodal_reference = nodal_volumes(n, &mesh.tets, &element_volumes);
        let mut prescribed = vec![false; 3 * n];
        let mut moved_axial = Vec::new();
        match ends {
            Ends::Clamped => {
                for &a in mesh.fixed_face.iter().chain(&mesh.moved_face) {
                    prescribed[3 * a..3 * a + 3].fill(true);
                }
            }
            Ends::Sliding => {
                for &a in mesh.fixed_face.iter().chain(&mesh.moved_face) {
                    prescribed[3 * a] = true;
                }
                // The axis node (disc centre, first in disc order) and the
                // first ring node (on the +y axis, η = (1/n_radial, 0)).
                let centre = mesh.fixed_face[0];
                prescribed[3 * centre + 1] = true;
                prescribed[3 * centre + 2] = true;
                let ring = mesh.fixed_face[1];
                prescribed[3 * ring + 2] = true;
            }
        }
        for &a in &mesh.moved_face {
            moved_axial.push(3 * a);
        }
        let pattern = Pattern::new(n, &mesh.tets, prescribed)?;
        let node_elements = {
            let mut v: Vec<Vec<(u32, [u8; 4])>> = vec![Vec::new(); n];
            for (e, tet) in mesh.tets.iter().enumerate() {
                for &a in tet {
                    let patch = &pattern.patches[a];
                    let local =
                        tet.map(|b| patch.binary_search(&(b as u32)).expect("in patch") as u8);
                    v[a].push((e as u32, local));
                }
            }
            v
        };
        let l0 = mesh.length;
        let mean_area = mesh.volume() / l0;
        let (mut lo, mut hi) = (mesh.nodes[0], mesh.nodes[0]);
        for n in &mesh.nodes {
            lo = lo.inf(n);
            hi = hi.sup(n);
        }
        let size = (hi - lo).norm();
        Ok(Discretization {
            l0,
            ends,
            references,
            dm_inv,
            nodal_reference,
            node_elements,
            pattern,
            moved_axial,
            mean_area,
            size,
            area: mean_area,
            fibres: FibreLayout::Axial,
            volumetric: Volumetric::NodalAverage,
            threads: AtomicUsize::new(1),
            work: Ledger::default(),
            mesh,
        })
    }

    /// The same discretization with another volumetric formulation.
    pub fn with_volumetric(mut self, volumetric: Volumetric) -> Discretization {
        self.volumetric = volumetric;
        self
    }

    /// Let the element loops of [`Self::evaluate`] use up to `threads`
    /// threads (scoped to each call, [`crate::fe::threads`]). An execution
    /// setting, not part of the problem: every result is the same bits for
    /// every count, so it may change between any two calls.
    pub fn set_threads(&self, threads: Threads) {
        self.threads.store(threads.get(), Ordering::Relaxed);
    }

    /// The thread count [`Self::set_threads`] set (1 unless set).
    pub fn threads(&self) -> Threads {
        Threads::new(self.threads.load(Ordering::Relaxed)).unwrap_or_default()
    }

    pub fn n_nodes(&self) -> usize {
        self.mesh.nodes.len()
    }

    pub fn n_elements(&self) -> usize {
        self.mesh.tets.len()
    }

    /// Reference volume of each element.
    pub fn element_reference_volumes(&self) -> impl Iterator<Item = f64> + '_ {
        self.references.iter().map(|r| r.volume)
    }

    /// Reference volume of the mesh.
    pub fn reference_volume(&self) -> f64 {
        self.references.iter().map(|r| r.volume).sum()
    }

    /// The reference positions, flattened.
    pub fn reference_positions(&self) -> Vec<f64> {
        self.mesh
            .nodes
            .iter()
            .flat_map(|p| [p.x, p.y, p.z])
            .collect()
    }

    /// Set the prescribed dofs for the muscle length `length`.
    pub(crate) fn apply_prescribed(&self, x: &mut [f64], length: f64) {
        let p = &self.pattern.prescribed;
        for a in 0..self.n_nodes() {
            let x0 = self.mesh.nodes[a];
            for i in 0..3 {
                if p[3 * a + i] {
                    x[3 * a + i] = x0[i];
                }
            }
        }
        for &d in &self.moved_axial {
            x[d] = length;
        }
    }

    fn element_points(&self, x: &[f64], e: usize) -> [Vector3<f64>; 4] {
        self.mesh.tets[e].map(|a| Vector3::new(x[3 * a], x[3 * a + 1], x[3 * a + 2]))
    }

    /// Evaluate forces (and the tangent) at positions `x` (module docs of
    /// [`crate::fe::element`]). Fails on an inverted element or a non-finite
    /// value.
    pub fn evaluate(
        &self,
        p: &Params,
        x: &[f64],
        activation: f64,
        start: &[FibreHistory],
        rate: FibreRate,
        tangent: bool,
    ) -> Result<Evaluation, String> {
        if !tangent {
            return self.residual(p, x, activation, start, rate);
        }
        self.evaluate_tangent(p, x, activation, start, rate, None)
    }

    /// [`Self::evaluate`] with the tangent, its initial-stress (geometric)
    /// part formed with the nodal pressures `pressure` when given, instead of
    /// those of the nodal volume ratios at `x`, U_J'(J_a(x)): the tangent of
    /// the mixed displacement–pressure problem (pressures as unknowns, the
    /// constraint U_J'(J_a) = p_a as equations), condensed — the matrix of
    /// the Newton iteration that carries the pressures as unknowns
    /// ([`crate::fe::newton`], "Pressures"). The forces are those of `x`
    /// either way.
    pub(crate) fn evaluate_tangent(
        &self,
        p: &Params,
        x: &[f64],
        activation: f64,
        start: &[FibreHistory],
        rate: FibreRate,
        pressure_override: Option<&[f64]>,
    ) -> Result<Evaluation, String> {
        let ne = self.n_elements();
        let nn = self.n_nodes();
        // Pass 1: element volumes, nodal volume ratios and pressures.
        let mut grads = Vec::with_capacity(ne);
        let mut volumes = Vec::with_capacity(ne);
        for e in 0..ne {
            let pts = self.element_points(x, e);
            let (g, v) = crate::fe::element::shape_gradients(&pts);
            let j = v / self.references[e].volume;
            if !(j > 0.0 && j.is_finite()) {
                return Err(format!("element {e} inverted or degenerate (J = {j:e})"));
            }
            grads.push(g);
            volumes.push(v);
        }
        let current_nodal = nodal_volumes(nn, &self.mesh.tets, &volumes);
        let mut j_nodal = vec![0.0; nn];
        let mut pressure = vec![0.0; nn];
        let mut bulk = vec![0.0; nn];
        let mut j_nodal_range = (f64::INFINITY, f64::NEG_INFINITY);
        for a in 0..nn {
            let j = current_nodal[a] / self.nodal_reference[a];
            let (uj, ujj) = volumetric_derivatives(j, p.d_comp);
            j_nodal[a] = j;
            pressure[a] = uj;
            bulk[a] = ujj;
            j_nodal_range = (j_nodal_range.0.min(j), j_nodal_range.1.max(j));
        }
        // Pass 2: element forces (and stiffness). The forces of element e on
        // its nodes are (V_e τ_iso + p̄_e v_e I) ∇N_b (module docs of
        // [`crate::fe::element`]), with the spatial gradients ∇N_b of pass 1;
        // per element on the configured threads ([`crate::fe::threads`]),
        // summed in element order.
        let mut forces = vec![0.0; 3 * nn];
        let mut d_activation = vec![0.0; 3 * nn];
        let mut values = self.pattern.zeros();
        let mut elements = Vec::with_capacity(ne);
        let kernel = |e: usize| -> TangentElement {
            let tet = &self.mesh.tets[e];
            let pts = self.element_points(x, e);
            let reference = &self.references[e];
            let (g, v) = (&grads[e], volumes[e]);
            let f = reference.deformation_gradient(&pts);
            let dir = &self.mesh.fibre[e];
            // The law with its tangent pieces (the same arithmetic as the
            // residual's stress-only `IsochoricStress::new`, so the same stress).
            let point = LawPoint::new(p, &f, dir, activation, &start[e], rate);
            let stress = IsochoricStress {
                tau: point.kirchhoff_isochoric(),
                j: point.j,
                lambda_f: point.lambda_f,
                fibre: FibreStress {
                    w: point.fibre.w,
                    sigma_see: point.fibre.sigma_see,
                    history: point.fibre.history,
                },
            };
            // The pressure the element carries: the mean of its nodal
            // pressures p̄_e, or (plain tetrahedron) U_J'(J_e) of its own J.
            let mean = |pr: &[f64]| 0.25 * (pr[tet[0]] + pr[tet[1]] + pr[tet[2]] + pr[tet[3]]);
            let (p_bar, bulk_e) = match self.volumetric {
                Volumetric::NodalAverage => (mean(&pressure), 0.0),
                Volumetric::Element => volumetric_derivatives(v / reference.volume, p.d_comp),
            };
            // The pressure of the initial-stress part of the tangent.
            let p_geometric = match (self.volumetric, pressure_override) {
                (Volumetric::NodalAverage, Some(pr)) => mean(pr),
                _ => p_bar,
            };
            let s = stress.tau * reference.volume + Matrix3::identity() * (p_bar * v);
            let nodal = g.map(|gb| s * gb);
            let state = ElementState {
                lambda_f: stress.lambda_f,
                j: stress.j,
                j_assumed: match self.volumetric {
                    Volumetric::NodalAverage => mean(&j_nodal),
                    Volumetric::Element => v / reference.volume,
                },
                history: stress.fibre.history,
                sigma_see: stress.fibre.sigma_see,
            };
            let dtau_da = point.kirchhoff_activation_derivative();
            let nodal_da = g.map(|gb| dtau_da * gb * reference.volume);
            let el = IsochoricElement::from_point(point, *g, reference.volume);
            let mut k: SMatrix<f64, 12, 12> = el.stiffness(reference.volume);
            // p̄_e v_e (∇N_b ⊗ ∇N_c − ∇N_c ⊗ ∇N_b), and for the plain
            // tetrahedron (U_J''(J_e)/V_e) (v_e ∇N_b) ⊗ (v_e ∇N_c).
            for b in 0..4 {
                for c in 0..4 {
                    let h = (g[b] * g[c].transpose() - g[c] * g[b].transpose()) * (p_geometric * v)
                        + g[b] * g[c].transpose() * (bulk_e * v * v / reference.volume);
                    for i in 0..3 {
                        for j in 0..3 {
                            k[(3 * b + i, 3 * c + j)] += h[(i, j)];
                        }
                    }
                }
            }
            (nodal, state, nodal_da, k)
        };
        let threads = self.threads().for_loop(ne, TANGENT_ELEMENTS_PER_THREAD);
        in_order(threads, ne, kernel, |e, (nodal, state, nodal_da, k)| {
            let tet = &self.mesh.tets[e];
            for (b, &node) in tet.iter().enumerate() {
                for i in 0..3 {
                    forces[3 * node + i] += nodal[b][i];
                    d_activation[3 * node + i] += nodal_da[b][i];
                }
            }
            elements.push(state);
            self.pattern.add_element(&mut values, e, tet, &k);
        });
        if self.volumetric == Volumetric::NodalAverage {
            // Σ_a (U_J''(J_a) / V_a) ∂v_a/∂x ⊗ ∂v_a/∂x, ∂v_a/∂x = Σ_{e∋a} (v_e/4) ∇N.
            let mut g = Vec::new();
            for (a, (&ujj, v_ref)) in bulk.iter().zip(&self.nodal_reference).enumerate() {
                g.clear();
                g.resize(self.pattern.patches[a].len(), Vector3::zeros());
                for &(e, local) in &self.node_elements[a] {
                    let (ge, v) = (&grads[e as usize], volumes[e as usize]);
                    for b in 0..4 {
                        g[local[b] as usize] += ge[b] * (v / 4.0);
                    }
                }
                self.pattern
                    .add_patch_outer(&mut values, a, &g, ujj / v_ref);
            }
        }
        if forces.iter().any(|f| !f.is_finite()) {
            return Err("a non-finite nodal force".into());
        }
        Ok(Evaluation {
            forces,
            d_activation,
            tangent: Some(values),
            elements,
            volume: volumes.iter().sum(),
            j_nodal_range,
        })
    }

    /// The nodal pressures at `x`, U_J'(J_a), and linearised about `x` at
    /// `x + dx`: U_J'(J_a) + U_J''(J_a) ΔJ_a, ΔJ_a = (1/V_a) Σ_{e∋a} (v_e/4)
    /// Σ_b ∇N_b·Δx_b (∇N_b the spatial shape gradients at `x`) — the
    /// pressures the linearised constraint predicts, without the
    /// second-order volume change ([`crate::fe::newton`], "Pressures").
    pub(crate) fn linearised_pressures(
        &self,
        p: &Params,
        x: &[f64],
        dx: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>), String> {
        let nn = self.n_nodes();
        let ne = self.n_elements();
        let (mut volumes, mut changes) = (Vec::with_capacity(ne), Vec::with_capacity(ne));
        for (e, tet) in self.mesh.tets.iter().enumerate() {
            let (g, v) = crate::fe::element::shape_gradients(&self.element_points(x, e));
            if !(v > 0.0 && v.is_finite()) {
                return Err(format!("element {e} inverted or degenerate"));
            }
            let div: f64 = tet
                .iter()
                .zip(&g)
                .map(|(&a, gb)| gb[0] * dx[3 * a] + gb[1] * dx[3 * a + 1] + gb[2] * dx[3 * a + 2])
                .sum();
            volumes.push(v);
            changes.push(v * div);
        }
        let volume = nodal_volumes(nn, &self.mesh.tets, &volumes);
        let change = nodal_volumes(nn, &self.mesh.tets, &changes);
        let (mut current, mut predicted) = (Vec::with_capacity(nn), Vec::with_capacity(nn));
        for a in 0..nn {
            let v_ref = self.nodal_reference[a];
            let (uj, ujj) = volumetric_derivatives(volume[a] / v_ref, p.d_comp);
            current.push(uj);
            predicted.push(uj + ujj * change[a] / v_ref);
        }
        Ok((current, predicted))
    }

    /// The axial reaction on the moved face.
    pub fn reaction(&self, forces: &[f64]) -> f64 {
        self.moved_axial.iter().map(|&d| forces[d]).sum()
    }

    /// Derivatives of the reaction force at a converged solution: with
    /// respect to the muscle length (all moved-face axial dofs moving
    /// together) and to the activation level, from the converged tangent
    /// (one factorisation, two solves):
    /// dF/dL = eᵀ K (δ + Δx), K_ff Δx_f = −(K δ)_f;
    /// dF/da = eᵀ (∂f/∂a + K Δx), K_ff Δx_f = −(∂f/∂a)_f;
    /// e selects the moved-face axial dofs, δ moves them by 1.
    pub fn force_derivatives(&self, ev: &Evaluation) -> Result<(f64, f64), String> {
        let values = ev.tangent.as_ref().ok_or("no tangent")?;
        let factor: Factor = self.pattern.factorize(values)?;
        let (v, w, _) = self.sensitivities(ev, &factor);
        let mut kx = vec![0.0; 3 * self.n_nodes()];
        self.pattern.multiply(values, &v, &mut kx);
        let df_dl = self.reaction(&kx);
        self.pattern.multiply(values, &w, &mut kx);
        let df_da = self.reaction(&ev.d_activation) + self.reaction(&kx);
        Ok((df_dl, df_da))
    }

    /// [`Self::force_derivatives`] without a factorisation: the two solves
    /// by conjugate gradients preconditioned with `factor`, the Cholesky
    /// factor of a nearby tangent ([`Pattern::conjugate_gradients`]), at
    /// most `cap` iterations each; `None` when either gives up. With
    /// b_L = (K δ)_f, b_a = (∂f/∂a)_f, y_L ≈ K_ff⁻¹ b_L, y_a ≈ K_ff⁻¹ b_a
    /// and their residuals r_L, r_a:
    /// dF/dL = eᵀK δ − (b_Lᵀ y_L + y_Lᵀ r_L),
    /// dF/da = eᵀ∂f/∂a − (b_Lᵀ y_a + y_Lᵀ r_a) —
    /// b_Lᵀ K_ff⁻¹ b_L and b_Lᵀ K_ff⁻¹ b_a each with its adjoint correction,
    /// so that their errors are (y_L − y_L*)ᵀ K (y − y*), the product of the
    /// two solves' energy-norm errors, each estimated by the iteration's
    /// rᵀK̃⁻¹r ([`DERIVATIVE_TOLERANCE`]).
    pub fn force_derivatives_preconditioned(
        &self,
        ev: &Evaluation,
        factor: &Factor,
        cap: usize,
    ) -> Result<Option<IterativeDerivatives>, String> {
        self.preconditioned_derivatives(ev, factor, cap, true)
    }

    /// [`Self::force_derivatives_preconditioned`]'s dF/dL alone: its first
    /// solve only (the same iteration, so the same dF/dL whenever both
    /// solves converge); `None` when it gives up.
    pub fn length_derivative_preconditioned(
        &self,
        ev: &Evaluation,
        factor: &Factor,
        cap: usize,
    ) -> Result<Option<f64>, String> {
        Ok(self
            .preconditioned_derivatives(ev, factor, cap, false)?
            .map(|d| d.length))
    }

    /// [`Self::force_derivatives_preconditioned`], the activation's solve
    /// only when `activation` (else dF/da is NaN and its iterations 0).
    fn preconditioned_derivatives(
        &self,
        ev: &Evaluation,
        factor: &Factor,
        cap: usize,
        activation: bool,
    ) -> Result<Option<IterativeDerivatives>, String> {
        let values = ev.tangent.as_ref().ok_or("no tangent")?;
        let mut delta = try_filled(3 * self.n_nodes(), 0.0, "the derivatives' vectors")?;
        for &d in &self.moved_axial {
            delta[d] = 1.0;
        }
        let mut kd = try_filled(delta.len(), 0.0, "the derivatives' vectors")?;
        self.pattern.multiply(values, &delta, &mut kd);
        let (direct_l, direct_a) = (self.reaction(&kd), self.reaction(&ev.d_activation));
        // b_L: K δ on the free dofs (the solver reads b there only).
        for (k, &pr) in kd.iter_mut().zip(&self.pattern.prescribed) {
            if pr {
                *k = 0.0;
            }
        }
        let b_l = kd;
        let length = |y: &[f64], r: &[f64]| direct_l - (dot(&b_l, y) + dot(y, r));
        let pattern = &self.pattern;
        let tol = DERIVATIVE_TOLERANCE;
        let Some(l) = pattern.conjugate_gradients(values, factor, &b_l, cap, |y, r, rz| {
            rz <= tol * length(y, r).abs()
        })?
        else {
            return Ok(None);
        };
        if !activation {
            return Ok(Some(IterativeDerivatives {
                length: length(&l.y, &l.residual),
                activation: f64::NAN,
                iterations: [l.iterations, 0],
            }));
        }
        let activation = |y: &[f64], r: &[f64]| direct_a - (dot(&b_l, y) + dot(&l.y, r));
        let Some(a) =
            pattern.conjugate_gradients(values, factor, &ev.d_activation, cap, |y, r, rz| {
                rz * l.energy <= (tol * activation(y, r)).powi(2)
            })?
        else {
            return Ok(None);
        };
        Ok(Some(IterativeDerivatives {
            length: length(&l.y, &l.residual),
            activation: activation(&a.y, &a.residual),
            iterations: [l.iterations, a.iterations],
        }))
    }

    /// The forces alone ([`Self::evaluate`] without the tangent), in the
    /// first Piola form: with F = D_s D_m⁻¹ (current and reference edge
    /// matrices), cof F = J F⁻ᵀ, the forces of element e on its nodes b = 1, 2,
    /// 3 are V_e (τ_iso/J + p̄_e I) cof F ∇₀N_b (= (V_e τ_iso + p̄_e v_e I) ∇N_b
    /// of [`crate::fe::element`], as ∇N_b = F⁻ᵀ ∇₀N_b and v_e = J V_e), and
    /// node 0 takes minus their sum (Σ_b ∇₀N_b = 0).
    fn residual(
        &self,
        p: &Params,
        x: &[f64],
        activation: f64,
        start: &[FibreHistory],
        rate: FibreRate,
    ) -> Result<Evaluation, String> {
        let ne = self.n_elements();
        let nn = self.n_nodes();
        let node = |a: usize| Vector3::new(x[3 * a], x[3 * a + 1], x[3 * a + 2]);
        // Pass 1: F and J per element, the nodal volume ratios and pressures.
        let mut deformation = Vec::with_capacity(ne);
        let mut current_nodal = vec![0.0; nn];
        for (e, tet) in self.mesh.tets.iter().enumerate() {
            let x0 = node(tet[0]);
            let ds =
                Matrix3::from_columns(&[node(tet[1]) - x0, node(tet[2]) - x0, node(tet[3]) - x0]);
            let f = ds * self.dm_inv[e];
            let j = f.determinant();
            if !(j > 0.0 && j.is_finite()) {
                return Err(format!("element {e} inverted or degenerate (J = {j:e})"));
            }
            let quarter = 0.25 * j * self.references[e].volume;
            for &a in tet {
                current_nodal[a] += quarter;
            }
            deformation.push((f, j));
        }
        let mut j_nodal = vec![0.0; nn];
        let mut pressure = vec![0.0; nn];
        let mut j_nodal_range = (f64::INFINITY, f64::NEG_INFINITY);
        for a in 0..nn {
            let j = current_nodal[a] / self.nodal_reference[a];
            j_nodal[a] = j;
            pressure[a] = volumetric_derivatives(j, p.d_comp).0;
            j_nodal_range = (j_nodal_range.0.min(j), j_nodal_range.1.max(j));
        }
        // Pass 2: the law and the element forces, per element on the
        // configured threads ([`crate::fe::threads`]), summed in element order.
        let mut forces = vec![0.0; 3 * nn];
        let mut elements = Vec::with_capacity(ne);
        let mut volume = 0.0;
        let kernel = |e: usize| -> ResidualElement {
            let tet = &self.mesh.tets[e];
            let (f, j) = deformation[e];
            let reference = &self.references[e];
            let stress =
                IsochoricStress::new(p, &f, j, &self.mesh.fibre[e], activation, &start[e], rate);
            let (p_bar, j_assumed) = match self.volumetric {
                Volumetric::NodalAverage => (
                    0.25 * (pressure[tet[0]]
                        + pressure[tet[1]]
                        + pressure[tet[2]]
                        + pressure[tet[3]]),
                    0.25 * (j_nodal[tet[0]] + j_nodal[tet[1]] + j_nodal[tet[2]] + j_nodal[tet[3]]),
                ),
                Volumetric::Element => (volumetric_derivatives(j, p.d_comp).0, j),
            };
            let cof = Matrix3::new(
                f[(1, 1)] * f[(2, 2)] - f[(1, 2)] * f[(2, 1)],
                f[(1, 2)] * f[(2, 0)] - f[(1, 0)] * f[(2, 2)],
                f[(1, 0)] * f[(2, 1)] - f[(1, 1)] * f[(2, 0)],
                f[(0, 2)] * f[(2, 1)] - f[(0, 1)] * f[(2, 2)],
                f[(0, 0)] * f[(2, 2)] - f[(0, 2)] * f[(2, 0)],
                f[(0, 1)] * f[(2, 0)] - f[(0, 0)] * f[(2, 1)],
                f[(0, 1)] * f[(1, 2)] - f[(0, 2)] * f[(1, 1)],
                f[(0, 2)] * f[(1, 0)] - f[(0, 0)] * f[(1, 2)],
                f[(0, 0)] * f[(1, 1)] - f[(0, 1)] * f[(1, 0)],
            );
            let m = (stress.tau * (reference.volume / j)
                + Matrix3::identity() * (p_bar * reference.volume))
                * cof;
            // The forces on nodes 1, 2, 3, then node 0's, minus their sum.
            let mut nodal = [Vector3::zeros(); 4];
            for b in 1..4 {
                nodal[b] = m * reference.grad[b];
                nodal[0] -= nodal[b];
            }
            let state = ElementState {
                lambda_f: stress.lambda_f,
                j,
                j_assumed,
                history: stress.fibre.history,
                sigma_see: stress.fibre.sigma_see,
            };
            (nodal, state, j * reference.volume)
        };
        let threads = self.threads().for_loop(ne, RESIDUAL_ELEMENTS_PER_THREAD);
        in_order(threads, ne, kernel, |e, (nodal, state, v)| {
            let tet = &self.mesh.tets[e];
            for b in [1, 2, 3, 0] {
                let a = 3 * tet[b];
                forces[a] += nodal[b][0];
                forces[a + 1] += nodal[b][1];
                forces[a + 2] += nodal[b][2];
            }
            volume += v;
            elements.push(state);
        });
        if forces.iter().any(|f| !f.is_finite()) {
            return Err("a non-finite nodal force".into());
        }
        Ok(Evaluation {
            forces,
            d_activation: Vec::new(),
            tangent: None,
            elements,
            volume,
            j_nodal_range,
        })
    }

    /// The sensitivities of the equilibrium at a tangent evaluation `ev`
    /// with its factorisation `factor`: v = ∂x/∂L (K_ff v_f = −K_fp δ, v = 1
    /// on the moved face's axial dofs), w = ∂x/∂a (K_ff w_f = −(∂R/∂a)_f,
    /// 0 on prescribed dofs), and K δ on the free dofs (how the reaction
    /// changes with them, K being symmetric).
    pub fn sensitivities(
        &self,
        ev: &Evaluation,
        factor: &Factor,
    ) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let values = ev.tangent.as_ref().expect("a tangent evaluation");
        let n = 3 * self.n_nodes();
        let mut delta = vec![0.0; n];
        for &d in &self.moved_axial {
            delta[d] = 1.0;
        }
        let mut kd = vec![0.0; n];
        self.pattern.multiply(values, &delta, &mut kd);
        for (k, &pr) in kd.iter_mut().zip(&self.pattern.prescribed) {
            if pr {
                *k = 0.0;
            }
        }
        let mut v: Vec<f64> = kd.iter().map(|k| -k).collect();
        factor.solve_in_place(&mut v);
        for &d in &self.moved_axial {
            v[d] = 1.0;
        }
        let mut w: Vec<f64> = ev
            .d_activation
            .iter()
            .zip(&self.pattern.prescribed)
            .map(|(x, &pr)| if pr { 0.0 } else { -x })
            .collect();
        factor.solve_in_place(&mut w);
        (v, w, kd)
    }

    /// The specimen's size: the diagonal of its reference bounding box (the
    /// length scale of the solver's position tests; L0 alone is not one for
    /// a specimen wider than long).
    pub fn size(&self) -> f64 {
        self.size
    }

    /// Mean reference cross-section V/L0 of the mesh.
    pub fn mean_area(&self) -> f64 {
        self.mean_area
    }

    /// Where the element volume ratios of `ev` (each element's mean nodal J,
    /// [`ElementState::j_assumed`]) depart from 1, split by the elements'
    /// place relative to the end faces' rims, where a clamped face meets the
    /// free surface and the pressure is singular (docs/fe.md, verification
    /// item 3): `distance` is the distance from the rims beyond which
    /// [`VolumeRatioSpread::beyond`] is taken, `threshold` the deviation whose
    /// volume share [`VolumeRatioSpread::share_over`] counts.
    pub fn volume_ratio_spread(
        &self,
        ev: &Evaluation,
        distance: f64,
        threshold: f64,
    ) -> VolumeRatioSpread {
        let volumes = self.mesh.element_volumes();
        let distances = self.mesh.end_rim_distances();
        let mut spread = VolumeRatioSpread::default();
        let mut over = 0.0;
        for (e, at_rim) in self.mesh.at_an_end_rim().into_iter().enumerate() {
            let dev = (ev.elements[e].j_assumed - 1.0).abs();
            if at_rim {
                spread.touching_a_rim = spread.touching_a_rim.max(dev);
            } else {
                spread.elsewhere = spread.elsewhere.max(dev);
            }
            if distances[e] > distance {
                spread.beyond = spread.beyond.max(dev);
            }
            if dev > threshold {
                over += volumes[e];
            }
        }
        spread.share_over = over / volumes.iter().sum::<f64>();
        spread
    }
}

/// Largest |J − 1| of the element volume ratios by region, and the volume
/// share above a threshold ([`Discretization::volume_ratio_spread`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VolumeRatioSpread {
    /// In the elements with a node on an end face's rim.
    pub touching_a_rim: f64,
    /// In all other elements.
    pub elsewhere: f64,
    /// In the elements whose centroid lies beyond the given distance from the rims.
    pub beyond: f64,
    /// Share of the reference volume whose elements deviate by more than the threshold.
    pub share_over: f64,
}

/// One element's share of a tangent evaluation as its loop hands it to the
/// scatter: nodal forces, state, nodal ∂f/∂a and the 12 × 12 stiffness. A
/// worker thread buffers its chunk of these ([`crate::fe::threads`]), which
/// the memory estimate covers ([`crate::fe::memory::THREAD_BUFFER_BYTES_PER_ELEMENT`]).
pub(crate) type TangentElement = (
    [Vector3<f64>; 4],
    ElementState,
    [Vector3<f64>; 4],
    SMatrix<f64, 12, 12>,
);

/// One element's share of a residual evaluation: nodal forces, state and
/// current volume (buffered as [`TangentElement`]).
pub(crate) type ResidualElement = ([Vector3<f64>; 4], ElementState, f64);

/// What an evaluation keeps per element for outputs and commits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementState {
    pub lambda_f: f64,
    /// det F_e of the linear element (not what the volume constraint acts on).
    pub j: f64,
    /// The volume ratio the formulation constrains: the mean of the element's
    /// nodal J_a (whose pressures p̄_e the element carries).
    pub j_assumed: f64,
    pub history: FibreHistory,
    pub sigma_see: f64,
}

/// Forces and tangent at one configuration.
#[derive(Clone, Debug)]
pub struct Evaluation {
    /// ∂Π/∂x, length 3 n (the reactions at prescribed dofs).
    pub forces: Vec<f64>,
    /// ∂forces/∂a at fixed x.
    pub d_activation: Vec<f64>,
    /// Full (unconstrained) tangent values on the pattern.
    pub tangent: Option<Vec<f64>>,
    pub elements: Vec<ElementState>,
    /// Current mesh volume.
    pub volume: f64,
    /// Range of the nodal volume ratios J_a.
    pub j_nodal_range: (f64, f64),
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The assembled tangent of [`Discretization::evaluate`] against central
    /// differences of its forces, on a perturbed active state (every column).
    #[test]
    fn assembled_tangent_matches_finite_differences_of_the_forces() {
        for volumetric in [Volumetric::NodalAverage, Volumetric::Element] {
            check_tangent(volumetric);
        }
    }

    fn check_tangent(volumetric: Volumetric) {
        let p = Params {
            d_comp: 1e-6,
            ..Params::default()
        };
        let d = Discretization::fusiform(
            0.05,
            crate::specimen::MEAN_AREA,
            Resolution {
                n_axial: 3,
                n_radial: 1,
            },
            FibreLayout::Meridian,
            Ends::Clamped,
        )
        .unwrap()
        .with_volumetric(volumetric);
        let mut x = d.reference_positions();
        for (i, v) in x.iter_mut().enumerate() {
            *v *= 1.0 + 0.02 * (((i * 7919) % 17) as f64 / 17.0 - 0.5);
        }
        let hist = vec![
            FibreHistory {
                lambda_s: 1.01,
                lambda_m: 0.98
            };
            d.n_elements()
        ];
        let rate = FibreRate::Step { h: 1e-3 };
        let ev = d.evaluate(&p, &x, 0.7, &hist, rate, true).unwrap();
        let values = ev.tangent.clone().unwrap();
        let n = x.len();
        let scale = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let mut col = vec![0.0; n];
        let mut unit = vec![0.0; n];
        for j in 0..n {
            unit.iter_mut().for_each(|u| *u = 0.0);
            unit[j] = 1.0;
            d.pattern.multiply(&values, &unit, &mut col);
            let e = 1e-9;
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[j] += e;
            xm[j] -= e;
            let fp = d.evaluate(&p, &xp, 0.7, &hist, rate, false).unwrap().forces;
            let fm = d.evaluate(&p, &xm, 0.7, &hist, rate, false).unwrap().forces;
            for i in 0..n {
                let fd = (fp[i] - fm[i]) / (2.0 * e);
                assert!(
                    (fd - col[i]).abs() < 1e-6 * scale,
                    "{volumetric:?}: K[{i},{j}] = {} vs fd {fd} (scale {scale:e})",
                    col[i]
                );
            }
        }
        // ∂f/∂a against a difference in the activation level.
        let ea = 1e-6;
        let fp = d
            .evaluate(&p, &x, 0.7 + ea, &hist, rate, false)
            .unwrap()
            .forces;
        let fm = d
            .evaluate(&p, &x, 0.7 - ea, &hist, rate, false)
            .unwrap()
            .forces;
        let amax = ev.d_activation.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in 0..n {
            let fd = (fp[i] - fm[i]) / (2.0 * ea);
            assert!((fd - ev.d_activation[i]).abs() < 1e-6 * amax, "df/da[{i}]");
        }
    }

    /// A worker thread's buffer per element fits the memory estimate's
    /// allowance for it.
    #[test]
    fn the_thread_buffers_fit_the_memory_estimate() {
        let allowance = crate::fe::memory::THREAD_BUFFER_BYTES_PER_ELEMENT;
        assert!(std::mem::size_of::<TangentElement>() as f64 <= allowance);
        assert!(std::mem::size_of::<ResidualElement>() as f64 <= allowance);
    }
}
