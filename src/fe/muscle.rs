//! The lumped 3D finite-element muscle: quasi-static equilibrium of a
//! tetrahedral mesh under the law, one end held, the other moved along the
//! axis (issue 3; the paper's test specimen, MODEL_NOTES "Co-simulation
//! conventions" for the inputs).
//!
//! # Problem
//!
//! Find node positions x with R(x) = ∂Π/∂x = 0 at every free degree of
//! freedom, Π the mesh energy of [`crate::fe::element`] (isochoric law per
//! element, average-nodal-pressure volumetric term per node), at the end of
//! each step: the CE–SEE history of every element advances with the step
//! (`FibreRate::Step { h }`, backward Euler as in the 1D model) and is
//! committed only when the step converges. Inertia is neglected (as in the
//! paper).
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
//!
//! # Solver
//!
//! Each (sub)step is solved by [`crate::fe::newton`]: Newton's method with
//! the consistent tangent of the law (including the CE–SEE history's
//! dλs/dλ̄f, [`crate::law::stress::LawPoint`]) assembled into a sparse
//! matrix ([`crate::fe::assembly`]) and factorised by sparse Cholesky (LU
//! when the tangent is indefinite), the factorisation reused across
//! iterations and steps while it contracts, from an extrapolating predictor,
//! with an affine-covariant damping and convergence test. When a step does
//! not converge, [`Muscle::advance`] retries it by continuation in its inputs
//! (same physics, [`Discretization::solve_step_continued`]) and then splits
//! it into 2, 4, … [`MAX_SUBSTEPS`] substeps (length linear in time,
//! activation level exact); if that fails too, the step is refused and
//! nothing has changed. Initialization ([`Muscle::isometric`]) ramps the
//! length, then the activation level, and relaxes to the isometric
//! equilibrium where the ramp fails.

use std::sync::Arc;

use nalgebra::{Matrix3, SMatrix, Vector3};

use crate::fe::assembly::{Factor, Pattern};
use crate::fe::element::{nodal_volumes, IsochoricElement, TetReference};
use crate::fe::mesh::{revolve_graded, FibreLayout, Fusiform, Grading, Mesh, Resolution, Section};
pub use crate::fe::newton::{
    Budget, Increment, Solution, Solved, StepInput, TangentCache, Trend, RESIDUAL_TOLERANCE,
};
use crate::law::force_length::force_length;
use crate::law::hill_fibre::{backward_euler_error, FibreStress};
use crate::law::stress::IsochoricStress;
use crate::law::volumetric::volumetric_derivatives;
use crate::law::{FibreHistory, FibreRate, LawPoint, Params};
use crate::step_control::MAX_CONTROLLED_TRIES;

/// Largest number of substeps a step is split into before it is refused.
pub const MAX_SUBSTEPS: usize = 64;
/// Substep counts up to which a failed (sub)step is retried by continuation
/// ([`Discretization::solve_step_continued`]) before it is split further.
const CONTINUED_SUBSTEPS: usize = 2;
/// Steps of 1 ms over which [`Muscle::isometric`]'s relaxation raises the
/// activation level before holding it.
pub(crate) const RELAX_RAMP: usize = 8;
/// Increments of the isometric activation ramp at initialization before it
/// turns to relaxation ([`Muscle::isometric`]).
const ACTIVATION_RAMP: usize = 4;

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
    /// show that (issue 3, verification item 2).
    Element,
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
            mesh,
        })
    }

    /// The same discretization with another volumetric formulation.
    pub fn with_volumetric(mut self, volumetric: Volumetric) -> Discretization {
        self.volumetric = volumetric;
        self
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
        // [`crate::fe::element`]), with the spatial gradients ∇N_b of pass 1.
        let mut forces = vec![0.0; 3 * nn];
        let mut d_activation = vec![0.0; 3 * nn];
        let mut values = self.pattern.zeros();
        let mut elements = Vec::with_capacity(ne);
        for e in 0..ne {
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
            for (b, &node) in tet.iter().enumerate() {
                let fb = s * g[b];
                forces[3 * node] += fb[0];
                forces[3 * node + 1] += fb[1];
                forces[3 * node + 2] += fb[2];
            }
            elements.push(ElementState {
                lambda_f: stress.lambda_f,
                j: stress.j,
                j_assumed: match self.volumetric {
                    Volumetric::NodalAverage => {
                        0.25 * (j_nodal[tet[0]]
                            + j_nodal[tet[1]]
                            + j_nodal[tet[2]]
                            + j_nodal[tet[3]])
                    }
                    Volumetric::Element => v / reference.volume,
                },
                history: stress.fibre.history,
                sigma_see: stress.fibre.sigma_see,
            });
            {
                let dtau_da = point.kirchhoff_activation_derivative();
                for (b, &node) in tet.iter().enumerate() {
                    let fa = dtau_da * g[b] * reference.volume;
                    for i in 0..3 {
                        d_activation[3 * node + i] += fa[i];
                    }
                }
                let el = IsochoricElement::from_point(point, *g, reference.volume);
                let mut k: SMatrix<f64, 12, 12> = el.stiffness(reference.volume);
                // p̄_e v_e (∇N_b ⊗ ∇N_c − ∇N_c ⊗ ∇N_b), and for the plain
                // tetrahedron (U_J''(J_e)/V_e) (v_e ∇N_b) ⊗ (v_e ∇N_c).
                for b in 0..4 {
                    for c in 0..4 {
                        let h = (g[b] * g[c].transpose() - g[c] * g[b].transpose())
                            * (p_geometric * v)
                            + g[b] * g[c].transpose() * (bulk_e * v * v / reference.volume);
                        for i in 0..3 {
                            for j in 0..3 {
                                k[(3 * b + i, 3 * c + j)] += h[(i, j)];
                            }
                        }
                    }
                }
                self.pattern.add_element(&mut values, e, tet, &k);
            }
        }
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
        // Pass 2: the law and the element forces.
        let mut forces = vec![0.0; 3 * nn];
        let mut elements = Vec::with_capacity(ne);
        let mut volume = 0.0;
        for (e, tet) in self.mesh.tets.iter().enumerate() {
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
            let mut f0 = Vector3::zeros();
            for (&node, grad) in tet.iter().zip(&reference.grad).skip(1) {
                let fb = m * grad;
                f0 -= fb;
                let a = 3 * node;
                forces[a] += fb[0];
                forces[a + 1] += fb[1];
                forces[a + 2] += fb[2];
            }
            let a = 3 * tet[0];
            forces[a] += f0[0];
            forces[a + 1] += f0[1];
            forces[a + 2] += f0[2];
            volume += j * reference.volume;
            elements.push(ElementState {
                lambda_f: stress.lambda_f,
                j,
                j_assumed,
                history: stress.fibre.history,
                sigma_see: stress.fibre.sigma_see,
            });
        }
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

/// The muscle's state between steps (shared discretization + per-instance
/// fields): what [`Muscle::advance`] reads and commits.
#[derive(Clone, Debug)]
pub struct Muscle {
    pub disc: Arc<Discretization>,
    /// Converged positions, flattened.
    pub x: Vec<f64>,
    /// Committed fibre history per element.
    pub history: Vec<FibreHistory>,
    /// Muscle length of the converged state.
    pub length: f64,
    /// The tangent the next step starts with ([`crate::fe::newton`]).
    pub tangent: Option<Arc<TangentCache>>,
    /// The last steps' increments, for the predictor.
    pub trend: Trend,
    /// The solver's convergence test ([`StepInput::tolerance`]).
    pub tolerance: f64,
}

/// Result of [`Muscle::advance`].
#[derive(Clone, Debug)]
pub struct Advance {
    pub muscle: Muscle,
    /// The last substep's converged solution.
    pub solution: Solution,
    /// Its starting history, rate and end activation level (what its
    /// tangent is formed with).
    pub start: Vec<FibreHistory>,
    pub rate: FibreRate,
    pub activation: f64,
    /// Newton iterations summed over the substeps.
    pub iterations: usize,
    /// Tangents formed and factorised, summed over the substeps.
    pub factorizations: usize,
    /// Residual evaluations, summed over the substeps.
    pub residuals: usize,
    /// Substeps taken, summed over the pieces.
    pub substeps: usize,
    /// The step's pieces: the time each ends at (the last at h) and the
    /// equal substeps it took ([`Muscle::advance_pieces`] takes the same
    /// again); one piece unless the time error was controlled.
    pub pieces: Vec<(f64, usize)>,
}

impl Muscle {
    /// The muscle at rest (reference positions, unloaded history).
    pub fn at_rest(disc: Arc<Discretization>) -> Muscle {
        let x = disc.reference_positions();
        let n = disc.n_elements();
        let l0 = disc.l0;
        Muscle {
            disc,
            x,
            history: vec![FibreHistory::REST; n],
            length: l0,
            tangent: None,
            trend: Trend::default(),
            tolerance: RESIDUAL_TOLERANCE,
        }
    }

    /// Isometric equilibrium at `length` and activation level `activation`
    /// (initialization, MODEL_NOTES "Co-simulation conventions"): the
    /// passive equilibrium at `length` (`Self::isometric_ramp` from rest),
    /// then, for an active muscle, the level raised to `activation` by the
    /// same ramp at that length; when that fails, by relaxation
    /// (`Self::relax_isometric`). The solution's counts are those of every
    /// converged solve of the way there (the passive ramp, then the level's
    /// ramp or the relaxation steps and the final solve; attempts that failed
    /// and were retried in more increments or substeps are not counted).
    pub fn isometric(
        disc: Arc<Discretization>,
        p: &Params,
        length: f64,
        activation: f64,
    ) -> Result<(Muscle, Solution), String> {
        let rest = Muscle::at_rest(disc);
        let (passive, s) = rest.isometric_ramp(p, length, 0.0, 0.0, MAX_SUBSTEPS)?;
        if activation == 0.0 {
            return Ok((passive, s));
        }
        let (active, a) = match passive.isometric_ramp(p, length, 0.0, activation, ACTIVATION_RAMP)
        {
            Ok(done) => done,
            Err(ramp) => passive.relax_isometric(p, activation).map_err(|relax| {
                format!("{ramp}; relaxing to it at the activation level held: {relax}")
            })?,
        };
        Ok((
            active,
            a.with_counts_added(s.iterations, s.factorizations, s.residuals),
        ))
    }

    /// From this isometric equilibrium (at activation level `from`), the
    /// isometric equilibrium at `length` and activation level `activation`:
    /// length and level approached together in 1, 2, 4, … `max_increments`
    /// increments (path-independent: the isometric fibre has no rate, so the
    /// increments only guide Newton).
    fn isometric_ramp(
        &self,
        p: &Params,
        length: f64,
        from: f64,
        activation: f64,
        max_increments: usize,
    ) -> Result<(Muscle, Solution), String> {
        let disc = &self.disc;
        let a0 = from;
        let mut last_error = String::new();
        let mut n = 1;
        while n <= max_increments {
            let mut x = self.x.clone();
            let mut cache = None;
            let mut result = None;
            let (mut iterations, mut factorizations, mut residuals) = (0, 0, 0);
            for i in 1..=n {
                // Each increment is a step's worth of work.
                let budget = Budget::for_step(disc);
                let at = |i: usize| (i as f64 / n as f64, (i - 1) as f64 / n as f64);
                let (u, u0) = at(i);
                let input = StepInput {
                    x: &x,
                    length_start: self.length + (length - self.length) * u0,
                    length: self.length + (length - self.length) * u,
                    activation_start: a0 + (activation - a0) * u0,
                    activation: a0 + (activation - a0) * u,
                    start: &self.history,
                    rate: FibreRate::Isometric,
                    trend: None,
                    tolerance: self.tolerance,
                    budget: &budget,
                };
                match disc.solve_step(p, &input, cache.take()) {
                    Ok(s) => {
                        iterations += s.solution.iterations;
                        residuals += s.solution.residuals;
                        factorizations += s.solution.factorizations;
                        x = s.solution.x.clone();
                        cache = Some(s.cache);
                        result = Some(s.solution);
                    }
                    Err(e) => {
                        last_error = e;
                        result = None;
                        break;
                    }
                }
            }
            if let Some(s) = result {
                let history = s.evaluation.elements.iter().map(|e| e.history).collect();
                return Ok((
                    Muscle {
                        disc: disc.clone(),
                        x: s.x.clone(),
                        history,
                        length,
                        tangent: cache,
                        trend: Trend::default(),
                        tolerance: self.tolerance,
                    },
                    Solution {
                        iterations,
                        residuals,
                        factorizations,
                        ..s
                    },
                ));
            }
            n *= 2;
        }
        Err(format!(
            "no isometric equilibrium at length {length} m and activation level {activation} in up to {max_increments} increments: {last_error}"
        ))
    }

    /// The isometric equilibrium at this length and activation level
    /// `activation` as the steady state of the rate-dependent muscle held at
    /// that length and level (from this state): the level raised over
    /// `RELAX_RAMP` steps of 1 ms, then held in steps of the CE–SEE law with
    /// growing length h = 1 ms, 2 ms, 4 ms, … until the contractile elements
    /// stop moving (every |Δλm| below 1e-12), then the isometric solve from
    /// there. In steady state λ̇m = 0, f_v = 1 and σ_s = σ0 a f_λ: the
    /// isometric equilibrium. Why: with the fibres of the clamped specimen
    /// partly on the descending limb of f_λ (negative active stiffness), the
    /// rate-free isometric problem can defeat Newton's method from the
    /// passive state, while the force-velocity relation regularises the
    /// rate-dependent one. The counts are summed over the relaxation steps
    /// and the final solve.
    fn relax_isometric(&self, p: &Params, activation: f64) -> Result<(Muscle, Solution), String> {
        let mut m = self.clone();
        let mut h = 1e-3;
        let mut steps = 0;
        let (mut iterations, mut factorizations, mut residuals) = (0, 0, 0);
        // The level is raised over the first RELAX_RAMP steps (pseudo-time:
        // only the steady state counts), then held while h doubles.
        while h <= 1e6 {
            let (a0, a1) = if steps < RELAX_RAMP {
                let at = |k: usize| activation * k as f64 / RELAX_RAMP as f64;
                (at(steps), at(steps + 1))
            } else {
                (activation, activation)
            };
            let r = m.advance(p, m.length, h, &|tau| a0 + (a1 - a0) * tau / h)?;
            steps += 1;
            iterations += r.iterations;
            factorizations += r.factorizations;
            residuals += r.residuals;
            let moved = r
                .solution
                .evaluation
                .elements
                .iter()
                .zip(&m.history)
                .fold(0.0f64, |d, (e, old)| {
                    d.max((e.history.lambda_m - old.lambda_m).abs())
                });
            m = r.muscle;
            if steps < RELAX_RAMP {
                continue;
            }
            if moved <= 1e-12 {
                break;
            }
            h *= 2.0;
        }
        // The exact isometric equilibrium from the relaxed state (a level
        // ramp of one increment: the level is already there).
        let relaxed = Muscle {
            tangent: Some(Arc::new(TangentCache::new(crate::fe::newton::Anchor {
                x: m.x.clone(),
                activation,
                start: m.history.clone(),
                rate: FibreRate::Isometric,
                pressure: None,
            }))),
            trend: Trend::default(),
            ..m
        };
        let (done, s) = relaxed
            .isometric_ramp(p, relaxed.length, activation, activation, 1)
            .map_err(|e| format!("after {steps} relaxation steps: {e}"))?;
        Ok((
            done,
            s.with_counts_added(iterations, factorizations, residuals),
        ))
    }

    /// Advance over a step of length `h` to muscle length `length`, the
    /// activation level following `activation(τ)` for τ in [0, h] (exact
    /// dynamics). Tries 1, 2, 4, … [`MAX_SUBSTEPS`] substeps (length linear
    /// in τ, [`Self::advance_in`]); `Err` with the last failure when none
    /// converges (self unchanged).
    pub fn advance(
        &self,
        p: &Params,
        length: f64,
        h: f64,
        activation: &dyn Fn(f64) -> f64,
    ) -> Result<Advance, String> {
        let mut last_error = String::new();
        let mut n = 1;
        while n <= MAX_SUBSTEPS {
            match self.advance_in(p, length, h, activation, n) {
                Ok(done) => return Ok(done),
                Err(e) => last_error = e,
            }
            n *= 2;
        }
        Err(format!(
            "the step to length {length} m did not converge, even in {MAX_SUBSTEPS} substeps: {last_error}"
        ))
    }

    /// The step of [`Self::advance`] in exactly `n` equal substeps (length
    /// linear in τ, the level `activation(τ)` at each substep's ends);
    /// `Err` with the failure of the first substep that does not converge.
    /// With `n` fixed this is a smooth map of the step's inputs, which
    /// the directional derivatives of a substepped step differentiate.
    pub fn advance_in(
        &self,
        p: &Params,
        length: f64,
        h: f64,
        activation: &dyn Fn(f64) -> f64,
        n: usize,
    ) -> Result<Advance, String> {
        let disc = &self.disc;
        let budget = Budget::for_step(disc);
        let mut last_error = String::new();
        let hs = h / n as f64;
        let mut x = self.x.clone();
        let mut hist = self.history.clone();
        let mut cache = self.tangent.clone();
        let mut trend = self.trend.clone();
        let mut l_prev = self.length;
        let mut iterations = 0;
        let mut factorizations = 0;
        let mut residuals = 0;
        let mut done = None;
        for i in 1..=n {
            let tau = h * i as f64 / n as f64;
            let l = self.length + (length - self.length) * i as f64 / n as f64;
            let rate = FibreRate::Step { h: hs };
            let a_start = activation(h * (i - 1) as f64 / n as f64);
            let a_end = activation(tau);
            let input = StepInput {
                x: &x,
                length_start: l_prev,
                length: l,
                activation_start: a_start,
                activation: a_end,
                start: &hist,
                rate,
                trend: Some(&trend),
                tolerance: self.tolerance,
                budget: &budget,
            };
            // Continuation (a path in the inputs, same physics) on the
            // whole step and its halves; finer substeps in time without
            // it, so that a hopeless step ends in bounded work.
            let solved = if n <= CONTINUED_SUBSTEPS {
                disc.solve_step_continued(p, &input, cache.take())
            } else {
                disc.solve_step(p, &input, cache.take())
            };
            match solved {
                Ok(Solved {
                    solution: s,
                    cache: c,
                    contraction,
                }) => {
                    iterations += s.iterations;
                    factorizations += s.factorizations;
                    residuals += s.residuals;
                    let new_hist: Vec<FibreHistory> =
                        s.evaluation.elements.iter().map(|e| e.history).collect();
                    if let Some((e, err)) =
                        s.evaluation
                            .elements
                            .iter()
                            .enumerate()
                            .find_map(|(e, el)| {
                                el.history
                                    .check_physical(p.k, el.lambda_f)
                                    .err()
                                    .map(|m| (e, m))
                            })
                    {
                        last_error = format!("element {e}: {err}");
                        done = None;
                        break;
                    }
                    trend = trend.push(
                        Increment {
                            dx: s.x.iter().zip(&x).map(|(a, b)| a - b).collect(),
                            dl: l - l_prev,
                            da: a_end - a_start,
                            h: hs,
                        },
                        contraction,
                    );
                    x = s.x.clone();
                    l_prev = l;
                    cache = Some(c);
                    let start = std::mem::replace(&mut hist, new_hist);
                    done = Some((s, start, rate, a_end));
                }
                Err(e) => {
                    last_error = e;
                    done = None;
                    break;
                }
            }
        }
        if let Some((solution, start, rate, activation)) = done {
            return Ok(Advance {
                muscle: Muscle {
                    disc: disc.clone(),
                    x,
                    history: hist,
                    length,
                    tangent: cache,
                    trend,
                    tolerance: self.tolerance,
                },
                solution,
                start,
                rate,
                activation,
                iterations,
                factorizations,
                residuals,
                substeps: n,
                pieces: vec![(h, n)],
            });
        }
        Err(last_error)
    }
}

/// The shortest piece of an error-controlled step, as a fraction of the
/// step: such a piece is accepted whatever its estimate (a jump of the
/// rates — an activation jump with S h ≫ 1, the start of a length ramp —
/// is not resolved further). 2⁻²⁰, not the 1D model's 2⁻⁴⁰: the
/// estimate's rates are differences of solved fibre stretches over the
/// piece, and the equilibrium solve leaves them uncertain by up to its
/// tolerance (~1e-10), which over a piece of h 2⁻²⁰ is a rate of at most
/// ~1e-4/h — small against the CE rates the estimate compares — where
/// over h 2⁻⁴⁰ it would be ~100/h and pollute the next piece's estimate.
pub const FINEST_PIECE: f64 = 1.0 / (1u64 << 20) as f64;

impl Muscle {
    /// The CE rates λ̇m per element of a committed (sub)step that started
    /// from `start` and took `h` (0 for an isometric one): the rates the
    /// next piece's error estimate starts from.
    pub fn ce_rates(&self, start: &[FibreHistory], h: Option<f64>) -> Vec<f64> {
        match h {
            Some(h) => self
                .history
                .iter()
                .zip(start)
                .map(|(e, s)| (e.lambda_m - s.lambda_m) / h)
                .collect(),
            None => vec![0.0; self.history.len()],
        }
    }

    /// Estimated local error of the CE–SEE update over the piece `piece`
    /// taken from this muscle, as SEE stress [Pa]: the largest over the
    /// elements of [`crate::law::hill_fibre::backward_euler_error`], with
    /// the rates `rates` at the piece's start and its backward-Euler rates
    /// at the end (returned, for the next piece); `levels` the activation
    /// level at the piece's ends. No error where the CE can carry nothing
    /// at the end (σ0 a f_λ = 0: σ_s = 0 exactly), nor where the SEE is
    /// slack at both ends (λs ≤ 1: the CE follows the kinematics, no ODE).
    pub fn piece_error(
        &self,
        p: &Params,
        piece: &Advance,
        rates: &[f64],
        levels: (f64, f64),
    ) -> (f64, Vec<f64>) {
        let h = match piece.rate {
            FibreRate::Step { h } => h,
            FibreRate::Isometric => return (0.0, vec![0.0; rates.len()]),
        };
        let cap = p.fv_max() * p.sigma0 * levels.0.max(levels.1);
        let end_rates = piece.muscle.ce_rates(&piece.start, Some(h));
        let mut worst = 0.0f64;
        for (((e, before), &r0), &r1) in piece
            .solution
            .evaluation
            .elements
            .iter()
            .zip(&self.history)
            .zip(rates)
            .zip(&end_rates)
        {
            let drive = p.sigma0 * levels.1 * force_length(e.lambda_f, p.lambda_opt).0;
            let slack = e.history.lambda_s <= 1.0 && before.lambda_s <= 1.0;
            if drive == 0.0 || slack {
                continue;
            }
            // NaN propagates (max ignores it): make it the worst.
            let err = backward_euler_error(p, cap, r0, r1, h);
            worst = if err.is_nan() {
                f64::INFINITY
            } else {
                worst.max(err)
            };
        }
        (worst, end_rates)
    }

    /// The step of [`Self::advance`] in pieces whose estimated local error
    /// of the CE–SEE update ([`Self::piece_error`]) stays below `tolerance`
    /// (SEE stress, Pa), as the 1D model's substeps do: the whole step
    /// first; a rejected piece is tried again shorter, by the factor
    /// 0.9 √(tolerance/error) (backward Euler's local error is second order
    /// in its length) within [1/4, 0.9]; after an accepted piece the next is
    /// up to 4× longer. A piece of [`FINEST_PIECE`] h is accepted whatever
    /// its estimate, and after [`MAX_CONTROLLED_TRIES`] tries the rest of the
    /// step is one piece. Each piece is [`Self::advance`] over its part of
    /// the step (length linear in time, the level `activation(τ)`), with
    /// its own substeps when Newton needs them. `rates`: the CE rates at
    /// the step's start ([`Self::ce_rates`] of the last step). `Err` when a
    /// piece does not converge (self unchanged).
    pub fn advance_controlled(
        &self,
        p: &Params,
        length: f64,
        h: f64,
        activation: &dyn Fn(f64) -> f64,
        tolerance: f64,
        rates: &[f64],
    ) -> Result<Advance, String> {
        let at = |tau: f64| self.length + (length - self.length) * (tau / h).min(1.0);
        // The muscle the next piece starts from: self, then the last
        // accepted piece's.
        let mut accepted: Option<Muscle> = None;
        let mut rates = rates.to_vec();
        let (mut tau, mut hs) = (0.0, h);
        let (mut pieces, mut tries) = (Vec::new(), 0);
        let (mut iterations, mut factorizations, mut residuals, mut substeps) = (0, 0, 0, 0);
        loop {
            tries += 1;
            let last_try = tries >= MAX_CONTROLLED_TRIES;
            let end = if last_try || tau + hs >= h * (1.0 - 1e-12) {
                h
            } else {
                tau + hs
            };
            let piece_h = end - tau;
            let start = tau;
            let m = accepted.as_ref().unwrap_or(self);
            let piece = m.advance(p, at(end), piece_h, &|s| activation(start + s))?;
            iterations += piece.iterations;
            factorizations += piece.factorizations;
            residuals += piece.residuals;
            let levels = (activation(start), activation(end));
            let (err, end_rates) = m.piece_error(p, &piece, &rates, levels);
            let finest = piece_h <= FINEST_PIECE * h * (1.0 + 1e-9);
            if err <= tolerance || finest || last_try {
                substeps += piece.substeps;
                pieces.push((end, piece.substeps));
                rates = end_rates;
                let grow = if err > 0.0 {
                    (0.9 * (tolerance / err).sqrt()).min(4.0)
                } else {
                    4.0
                };
                hs = (piece_h * grow).max(FINEST_PIECE * h);
                tau = end;
                if end == h {
                    return Ok(Advance {
                        iterations,
                        factorizations,
                        residuals,
                        substeps,
                        pieces,
                        ..piece
                    });
                }
                accepted = Some(piece.muscle);
            } else {
                let shrink = if err.is_finite() {
                    (0.9 * (tolerance / err).sqrt()).clamp(0.25, 0.9)
                } else {
                    0.25
                };
                hs = (piece_h * shrink).max(FINEST_PIECE * h);
            }
        }
    }

    /// The step in the pieces `pieces` ([`Advance::pieces`]: end times, the
    /// last `h`, and each piece's equal substeps), without error control:
    /// with the pieces fixed, a smooth map of the step's inputs, which the
    /// directional derivatives of a step in more than one substep
    /// differentiate.
    pub fn advance_pieces(
        &self,
        p: &Params,
        length: f64,
        h: f64,
        activation: &dyn Fn(f64) -> f64,
        pieces: &[(f64, usize)],
    ) -> Result<Advance, String> {
        let at = |tau: f64| self.length + (length - self.length) * (tau / h).min(1.0);
        let mut tau = 0.0;
        let mut done: Option<Advance> = None;
        for &(end, n) in pieces {
            let start = tau;
            let m = done.as_ref().map_or(self, |d| &d.muscle);
            let piece = m.advance_in(p, at(end), end - start, &|s| activation(start + s), n)?;
            tau = end;
            done = Some(piece);
        }
        done.ok_or_else(|| "a step of no pieces".to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fe::mesh::cylinder;
    use crate::law::{solve_uniaxial, Uniaxial};

    fn patch(n_axial: usize, n_radial: usize) -> Arc<Discretization> {
        Arc::new(
            Discretization::new(cylinder(0.01, 0.003, n_axial, n_radial), Ends::Sliding).unwrap(),
        )
    }

    /// The FE force on a sliding-end cylinder vs the 1D reduction's nominal
    /// stress × the cylinder's mesh cross-section (the inscribed polygon).
    fn area_of(d: &Discretization) -> f64 {
        d.reference_volume() / d.l0
    }

    #[test]
    fn homogeneous_patch_reproduces_the_uniaxial_reduction_passive() {
        let p = Params::default();
        let d = patch(3, 2);
        for stretch in [0.9, 1.05, 1.2] {
            let (_, s) = Muscle::isometric(d.clone(), &p, stretch * d.l0, 0.0).unwrap();
            let f = d.reaction(&s.evaluation.forces);
            let u: Uniaxial = solve_uniaxial(
                &p,
                stretch,
                0.0,
                &FibreHistory::REST,
                FibreRate::Isometric,
                1.0,
            )
            .unwrap();
            let f1 = u.nominal_stress() * area_of(&d);
            assert!(
                ((f - f1) / f1).abs() < 1e-6,
                "stretch {stretch}: FE {f} vs 1D {f1} (rel {:e})",
                (f - f1) / f1
            );
            // Homogeneous: every element has the same J and fibre stretch.
            let (jmin, jmax) = s
                .evaluation
                .elements
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), e| {
                    (a.min(e.j), b.max(e.j))
                });
            assert!((jmax - jmin) < 1e-9, "{jmin} {jmax}");
            assert!(((jmin - u.j) / u.j).abs() < 1e-8, "{jmin} vs {}", u.j);
        }
    }

    /// Active patch: a sequence of steps with the activation rising while
    /// the bar is stretched and released (CE–SEE history advancing in every
    /// element) gives the 1D reduction's force at every step.
    #[test]
    fn homogeneous_patch_reproduces_the_uniaxial_reduction_active() {
        let p = Params::default();
        let d = patch(2, 1);
        let (mut m, _) = Muscle::isometric(d.clone(), &p, d.l0, 0.0).unwrap();
        let mut hist = FibreHistory::REST;
        let mut q = 1.0;
        let h = 1e-3;
        let mut a_prev = 0.0;
        for (k, stretch) in [1.0, 1.02, 1.05, 1.08, 1.06, 1.03].into_iter().enumerate() {
            let a = (0.2 * (k + 1) as f64).min(1.0);
            let a0 = a_prev;
            let r = m
                .advance(&p, stretch * d.l0, h, &|tau| a0 + (a - a0) * tau / h)
                .unwrap();
            let f = d.reaction(&r.solution.evaluation.forces);
            let u = solve_uniaxial(&p, stretch, a, &hist, FibreRate::Step { h }, q).unwrap();
            let f1 = u.nominal_stress() * area_of(&d);
            assert!(
                ((f - f1) / f1).abs() < 1e-6,
                "step {k}: FE {f} vs 1D {f1} (rel {:e})",
                (f - f1) / f1
            );
            let e0 = r.solution.evaluation.elements[0];
            assert!((e0.history.lambda_s - u.fibre.history.lambda_s).abs() < 1e-9);
            hist = u.fibre.history;
            q = u.q;
            a_prev = a;
            m = r.muscle;
        }
    }

    #[test]
    fn force_derivatives_match_finite_differences() {
        let p = Params::default();
        let d = Arc::new(
            Discretization::fusiform(
                0.05,
                crate::specimen::MEAN_AREA,
                Resolution {
                    n_axial: 6,
                    n_radial: 1,
                },
                FibreLayout::Axial,
                Ends::Clamped,
            )
            .unwrap(),
        );
        let (m, _) = Muscle::isometric(d.clone(), &p, 0.05 * 1.1, 0.3).unwrap();
        let h = 1e-3;
        let step = |l: f64, a: f64| m.advance(&p, l, h, &|_| a).unwrap();
        let (l, a) = (0.05 * 1.12, 0.5);
        let base = step(l, a);
        let ev = d
            .evaluate(&p, &base.solution.x, a, &base.start, base.rate, true)
            .unwrap();
        let (dfdl, dfda) = d.force_derivatives(&ev).unwrap();
        let f = |s: &Advance| d.reaction(&s.solution.evaluation.forces);
        let el = 1e-7;
        let fd_l = (f(&step(l + el, a)) - f(&step(l - el, a))) / (2.0 * el);
        let ea = 1e-6;
        let fd_a = (f(&step(l, a + ea)) - f(&step(l, a - ea))) / (2.0 * ea);
        assert!(
            ((dfdl - fd_l) / fd_l).abs() < 1e-5,
            "dF/dL {dfdl} vs fd {fd_l}"
        );
        assert!(
            ((dfda - fd_a) / fd_a).abs() < 1e-5,
            "dF/da {dfda} vs fd {fd_a}"
        );
    }

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
}
