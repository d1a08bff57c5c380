//! The linear tetrahedron with an average-nodal-pressure volumetric term
//! (Bonet & Burton 1998), the locking-free element of the FE muscle.
//!
//! The strain energy of the mesh is split as the law is (MODEL_NOTES "Energy
//! and stress"):
//!
//! Π(x) = Σ_e V_e W_iso(F_e) + Σ_a V_a U_J(J_a),
//!
//! - W_iso = U_I(Ī1) + U_f(λ̄f): the isochoric part, per element, from the
//!   element's constant deformation gradient F_e (its Kirchhoff stress and
//!   tangent are [`LawPoint::kirchhoff_isochoric`] and
//!   [`LawPoint::kirchhoff_isochoric_variation`]);
//! - U_J(J) = (J − 1)²/D: the volumetric part, per node, on the nodal volume
//!   ratio J_a = v_a / V_a with the nodal volumes v_a = Σ_{e∋a} v_e / 4 (V_a in
//!   the reference). With one volume constraint per node instead of one per
//!   element, the nearly incompressible tetrahedron does not lock.
//!
//! **Isochoric forces and stiffness** of an element with reference volume V_e
//! and spatial shape-function gradients ∇N_a = F⁻ᵀ ∇₀N_a:
//! f_a = V_e τ_iso ∇N_a, and for δx_b, with g = δx_b ⊗ ∇N_b,
//! δf_a = V_e (δτ_iso − τ_iso gᵀ) ∇N_a (since δ(F⁻ᵀ) = −gᵀ F⁻ᵀ), where δτ_iso
//! is the Kirchhoff variation of the law for δF = g F. As δτ_iso = J c_iso :
//! sym(g) + g τ_iso + τ_iso gᵀ, that is the material part V_e B_aᵀ D B_b plus
//! the geometric part V_e (∇N_a · τ_iso ∇N_b) I (D the Voigt form of J c_iso).
//!
//! **Volumetric forces and stiffness.** With p_a = U_J'(J_a) and
//! ∂v_e/∂x_b = v_e ∇N_b: f = Σ_a p_a ∂v_a/∂x = Σ_e p̄_e v_e ∇N_b with the
//! element pressure p̄_e = (1/4) Σ_{a∈e} p_a. The Hessian:
//! K = Σ_a (U_J''(J_a) / V_a) (∂v_a/∂x) ⊗ (∂v_a/∂x) + Σ_e p̄_e ∂²v_e/∂x², with
//! ∂²v_e/∂x_b∂x_c = v_e (∇N_b ⊗ ∇N_c − ∇N_c ⊗ ∇N_b) (from δv_e = v_e tr g and
//! δ∇N_b = −gᵀ ∇N_b).

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use crate::law::volumetric::{volumetric_derivatives, volumetric_energy};
use crate::law::{FibreHistory, FibreRate, LawPoint, Params};

/// Reference geometry of one tetrahedron: shape-function gradients ∇₀N_a and
/// volume V_e.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TetReference {
    pub grad: [Vector3<f64>; 4],
    pub volume: f64,
}

/// Signed volume det[x1 − x0, x2 − x0, x3 − x0] / 6.
pub fn signed_volume(x: &[Vector3<f64>; 4]) -> f64 {
    (x[1] - x[0]).dot(&(x[2] - x[0]).cross(&(x[3] - x[0]))) / 6.0
}

/// Gradients of the linear shape functions of a tetrahedron with nodes `x`
/// (positive volume): ∇N_a = ∂v/∂x_a / v, ∇N_0 = −Σ_{a>0} ∇N_a.
pub fn shape_gradients(x: &[Vector3<f64>; 4]) -> ([Vector3<f64>; 4], f64) {
    let v = signed_volume(x);
    // ∂v/∂x_1 = (x2 − x0) × (x3 − x0) / 6, and cyclically.
    let g1 = (x[2] - x[0]).cross(&(x[3] - x[0])) / (6.0 * v);
    let g2 = (x[3] - x[0]).cross(&(x[1] - x[0])) / (6.0 * v);
    let g3 = (x[1] - x[0]).cross(&(x[2] - x[0])) / (6.0 * v);
    ([-(g1 + g2 + g3), g1, g2, g3], v)
}

impl TetReference {
    /// From the reference node positions (positive orientation required).
    pub fn new(x_ref: &[Vector3<f64>; 4]) -> TetReference {
        let (grad, volume) = shape_gradients(x_ref);
        TetReference { grad, volume }
    }

    /// F = Σ_a x_a ⊗ ∇₀N_a.
    pub fn deformation_gradient(&self, x: &[Vector3<f64>; 4]) -> Matrix3<f64> {
        (0..4).fold(Matrix3::zeros(), |f, a| f + x[a] * self.grad[a].transpose())
    }
}

/// The isochoric response of one element at the end of a step.
#[derive(Clone, Debug)]
pub struct IsochoricElement {
    /// The law at the element's F (with the element's fibre response and new
    /// history).
    pub point: LawPoint,
    /// Internal forces f_a = V_e τ_iso ∇N_a.
    pub forces: [Vector3<f64>; 4],
    /// Spatial shape-function gradients ∇N_a.
    pub grad: [Vector3<f64>; 4],
}

impl IsochoricElement {
    /// Evaluate element `reference` at current nodes `x` (module docs).
    pub fn new(
        p: &Params,
        reference: &TetReference,
        x: &[Vector3<f64>; 4],
        fibre: &Vector3<f64>,
        activation: f64,
        hist: &FibreHistory,
        rate: FibreRate,
    ) -> IsochoricElement {
        let f = reference.deformation_gradient(x);
        let point = LawPoint::new(p, &f, fibre, activation, hist, rate);
        let f_inv_t = f.try_inverse().expect("element with J > 0").transpose();
        let grad = reference.grad.map(|g| f_inv_t * g);
        let tau = point.kirchhoff_isochoric();
        let forces = grad.map(|g| tau * g * reference.volume);
        IsochoricElement {
            point,
            forces,
            grad,
        }
    }

    /// From the law already evaluated at the element's F, with the spatial
    /// gradients ∇N_a = F⁻ᵀ ∇₀N_a (e.g. [`shape_gradients`] of the current
    /// nodes) and the reference volume V_e: f_a = V_e τ_iso ∇N_a.
    pub fn from_point(point: LawPoint, grad: [Vector3<f64>; 4], reference_volume: f64) -> Self {
        let tau = point.kirchhoff_isochoric();
        let forces = grad.map(|g| tau * g * reference_volume);
        IsochoricElement {
            point,
            forces,
            grad,
        }
    }

    /// The 12 × 12 isochoric stiffness ∂f_a/∂x_b (module docs), rows and
    /// columns ordered (node, component): the blocks
    /// K_ab = V_e (B_aᵀ D B_b + (∇N_a · τ_iso ∇N_b) I), D the law's isochoric
    /// tangent in Voigt form ([`LawPoint::isochoric_tangent_voigt`]), B_a
    /// the strain–displacement matrix of ∇N_a ([`strain_displacement`]).
    /// Formed for a ≤ b and mirrored: symmetric to the bit.
    pub fn stiffness(&self, reference_volume: f64) -> nalgebra::SMatrix<f64, 12, 12> {
        let tau = self.point.kirchhoff_isochoric();
        let d = self.point.isochoric_tangent_voigt();
        let b = self.grad.map(|g| strain_displacement(&g));
        let db = b.map(|bb| d * bb);
        let tau_grad = self.grad.map(|g| tau * g);
        let mut k = nalgebra::SMatrix::<f64, 12, 12>::zeros();
        for a in 0..4 {
            for c in a..4 {
                let geometric = self.grad[a].dot(&tau_grad[c]);
                let mut block = b[a].transpose() * db[c];
                for i in 0..3 {
                    block[(i, i)] += geometric;
                }
                block *= reference_volume;
                for i in 0..3 {
                    for j in 0..3 {
                        k[(3 * a + i, 3 * c + j)] = block[(i, j)];
                        k[(3 * c + j, 3 * a + i)] = block[(i, j)];
                    }
                }
            }
        }
        k
    }
}

/// The strain–displacement matrix B of a shape-function gradient g: the
/// strains (engineering shears, [`crate::law::stress::VOIGT_PAIRS`] order)
/// of the velocity gradient u ⊗ g are B u; Bᵀ s = σ g for the stress vector
/// s of σ.
pub fn strain_displacement(g: &Vector3<f64>) -> nalgebra::SMatrix<f64, 6, 3> {
    let mut b = nalgebra::SMatrix::<f64, 6, 3>::zeros();
    for (r, &(i, j)) in crate::law::stress::VOIGT_PAIRS.iter().enumerate() {
        // sym(u ⊗ g)_ij = (u_i g_j + u_j g_i)/2, doubled off the diagonal.
        b[(r, i)] += g[j];
        if i != j {
            b[(r, j)] += g[i];
        }
    }
    b
}

/// The average-nodal-pressure volumetric term of a whole mesh (module docs):
/// energy Σ_a V_a U_J(J_a), forces and the (dense, for now) Hessian.
pub struct NodalVolumetric {
    /// Σ_a V_a U_J(J_a).
    pub energy: f64,
    /// J_a per node.
    pub volume_ratio: Vec<f64>,
    /// ∂Π_vol/∂x, length 3 N.
    pub forces: DVector<f64>,
}

/// Reference nodal volumes V_a = Σ_{e∋a} V_e / 4.
pub fn nodal_volumes(n_nodes: usize, tets: &[[usize; 4]], element_volumes: &[f64]) -> Vec<f64> {
    let mut v = vec![0.0; n_nodes];
    for (tet, &ve) in tets.iter().zip(element_volumes) {
        for &a in tet {
            v[a] += ve / 4.0;
        }
    }
    v
}

fn nodes_of(x: &[Vector3<f64>], tet: &[usize; 4]) -> [Vector3<f64>; 4] {
    tet.map(|a| x[a])
}

impl NodalVolumetric {
    /// Evaluate at current positions `x`, with reference nodal volumes
    /// `reference_nodal` ([`nodal_volumes`] of the reference mesh).
    pub fn new(
        p: &Params,
        x: &[Vector3<f64>],
        tets: &[[usize; 4]],
        reference_nodal: &[f64],
    ) -> NodalVolumetric {
        let volumes: Vec<f64> = tets
            .iter()
            .map(|t| signed_volume(&nodes_of(x, t)))
            .collect();
        let current = nodal_volumes(x.len(), tets, &volumes);
        let volume_ratio: Vec<f64> = current
            .iter()
            .zip(reference_nodal)
            .map(|(v, v0)| v / v0)
            .collect();
        let energy = volume_ratio
            .iter()
            .zip(reference_nodal)
            .map(|(&j, &v0)| v0 * volumetric_energy(j, p.d_comp))
            .sum();
        let pressure: Vec<f64> = volume_ratio
            .iter()
            .map(|&j| volumetric_derivatives(j, p.d_comp).0)
            .collect();
        let mut forces = DVector::zeros(3 * x.len());
        for tet in tets {
            let (grad, v) = shape_gradients(&nodes_of(x, tet));
            let p_bar = tet.iter().map(|&a| pressure[a]).sum::<f64>() / 4.0;
            for (b, &node) in tet.iter().enumerate() {
                let f = grad[b] * (p_bar * v);
                for i in 0..3 {
                    forces[3 * node + i] += f[i];
                }
            }
        }
        NodalVolumetric {
            energy,
            volume_ratio,
            forces,
        }
    }

    /// The Hessian ∂²Π_vol/∂x² (dense; module docs).
    pub fn stiffness(
        &self,
        p: &Params,
        x: &[Vector3<f64>],
        tets: &[[usize; 4]],
        reference_nodal: &[f64],
    ) -> DMatrix<f64> {
        let n = 3 * x.len();
        let mut k = DMatrix::zeros(n, n);
        // ∂v_a/∂x for every node a, as dense vectors (fine for the sizes this is used at).
        let mut dva = vec![DVector::<f64>::zeros(n); x.len()];
        let pressure: Vec<f64> = self
            .volume_ratio
            .iter()
            .map(|&j| volumetric_derivatives(j, p.d_comp).0)
            .collect();
        for tet in tets {
            let (grad, v) = shape_gradients(&nodes_of(x, tet));
            let p_bar = tet.iter().map(|&a| pressure[a]).sum::<f64>() / 4.0;
            for &a in tet {
                for (b, &node) in tet.iter().enumerate() {
                    for i in 0..3 {
                        dva[a][3 * node + i] += v * grad[b][i] / 4.0;
                    }
                }
            }
            // p̄_e ∂²v_e/∂x_b∂x_c = p̄_e v_e (∇N_b ⊗ ∇N_c − ∇N_c ⊗ ∇N_b).
            for (b, &nb) in tet.iter().enumerate() {
                for (c, &nc) in tet.iter().enumerate() {
                    let h = (grad[b] * grad[c].transpose() - grad[c] * grad[b].transpose())
                        * (p_bar * v);
                    for i in 0..3 {
                        for j in 0..3 {
                            k[(3 * nb + i, 3 * nc + j)] += h[(i, j)];
                        }
                    }
                }
            }
        }
        for (a, d) in dva.iter().enumerate() {
            let (_, ujj) = volumetric_derivatives(self.volume_ratio[a], p.d_comp);
            k += d * d.transpose() * (ujj / reference_nodal[a]);
        }
        k
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fe::mesh::{cylinder, fusiform, FibreLayout};
    use crate::law::isotropic_matrix::matrix_energy;

    fn sample(seed: u64) -> Matrix3<f64> {
        let mut s = seed;
        let mut r = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut f: Matrix3<f64> = Matrix3::identity();
        for i in 0..3 {
            for j in 0..3 {
                f[(i, j)] += 0.3 * r();
            }
        }
        f
    }

    fn reference_tet() -> [Vector3<f64>; 4] {
        [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.1, 0.0),
            Vector3::new(0.2, 0.9, 0.1),
            Vector3::new(0.1, 0.2, 1.1),
        ]
    }

    /// Isochoric energy of the passive element: V_e (U_I + U_PE), with
    /// U_PE = σ0 A (λ̄f − 1)³/3 for λ̄f > 1.
    fn passive_isochoric_energy(
        p: &Params,
        r: &TetReference,
        x: &[Vector3<f64>; 4],
        dir: &Vector3<f64>,
    ) -> f64 {
        let f = r.deformation_gradient(x);
        let j = f.determinant();
        let c = f.transpose() * f;
        let i1 = j.powf(-2.0 / 3.0) * c.trace();
        let lf = (j.powf(-2.0 / 3.0) * dir.dot(&(c * dir))).sqrt();
        let upe = if lf > 1.0 {
            p.sigma0 * p.a_pe * (lf - 1.0).powi(3) / 3.0
        } else {
            0.0
        };
        r.volume * (matrix_energy(i1, p.b, p.c) + upe)
    }

    #[test]
    fn deformation_gradient_is_exact_for_affine_motion() {
        let x0 = reference_tet();
        let r = TetReference::new(&x0);
        let f = Matrix3::identity() + sample(3);
        let x = x0.map(|p| f * p + Vector3::new(0.3, -0.2, 1.0));
        assert!((r.deformation_gradient(&x) - f).norm() < 1e-13);
        assert!((r.volume - signed_volume(&x0)).abs() < 1e-15);
    }

    #[test]
    fn isochoric_forces_are_the_gradient_of_the_energy() {
        let p = Params::default();
        let dir = Vector3::new(1.0, 0.0, 0.0);
        let x0 = reference_tet();
        let r = TetReference::new(&x0);
        for seed in [5u64, 11, 17] {
            let f = Matrix3::identity() + sample(seed);
            let x = x0.map(|q| f * q);
            let el = IsochoricElement::new(
                &p,
                &r,
                &x,
                &dir,
                0.0,
                &FibreHistory::REST,
                FibreRate::Isometric,
            );
            for a in 0..4 {
                for i in 0..3 {
                    let h = 1e-7;
                    let (mut xp, mut xm) = (x, x);
                    xp[a][i] += h;
                    xm[a][i] -= h;
                    let fd = (passive_isochoric_energy(&p, &r, &xp, &dir)
                        - passive_isochoric_energy(&p, &r, &xm, &dir))
                        / (2.0 * h);
                    let scale = el.forces.iter().map(|v| v.norm()).fold(1.0, f64::max);
                    assert!(
                        (fd - el.forces[a][i]).abs() < 1e-6 * scale,
                        "seed {seed} f[{a}][{i}]: fd {fd} vs {}",
                        el.forces[a][i]
                    );
                }
            }
        }
    }

    #[test]
    fn isochoric_stiffness_matches_finite_differences_with_an_active_fibre() {
        let p = Params::default();
        let dir = Vector3::new(0.6, 0.8, 0.0);
        let hist = FibreHistory {
            lambda_s: 1.4,
            lambda_m: 0.9,
        };
        let rate = FibreRate::Step { h: 1e-3 };
        let x0 = reference_tet();
        let r = TetReference::new(&x0);
        let f = Matrix3::identity() + sample(29) * 0.5;
        let x = x0.map(|q| f * q);
        let el = IsochoricElement::new(&p, &r, &x, &dir, 0.8, &hist, rate);
        let k = el.stiffness(r.volume);
        let forces = |xx: &[Vector3<f64>; 4]| {
            IsochoricElement::new(&p, &r, xx, &dir, 0.8, &hist, rate).forces
        };
        let scale = k.norm();
        for b in 0..4 {
            for j in 0..3 {
                let e = 1e-7;
                let (mut xp, mut xm) = (x, x);
                xp[b][j] += e;
                xm[b][j] -= e;
                let (fp, fm) = (forces(&xp), forces(&xm));
                for a in 0..4 {
                    for i in 0..3 {
                        let fd = (fp[a][i] - fm[a][i]) / (2.0 * e);
                        assert!(
                            (fd - k[(3 * a + i, 3 * b + j)]).abs() < 1e-6 * scale,
                            "K[{a}{i},{b}{j}]: fd {fd} vs {}",
                            k[(3 * a + i, 3 * b + j)]
                        );
                    }
                }
            }
        }
        // Symmetric (an energy at fixed history).
        assert!((k - k.transpose()).norm() < 1e-9 * scale);
    }

    /// The stiffness from the Voigt tangent equals, to rounding, the one
    /// built column by column from the law's Kirchhoff variation (module
    /// docs: δf_a = V_e (δτ_iso − τ_iso gᵀ) ∇N_a for g = e_j ⊗ ∇N_b), passive
    /// and active, fibres stretched and shortened, backward Euler and
    /// isometric.
    #[test]
    fn voigt_stiffness_equals_the_law_variation_column_by_column() {
        let p = Params::default();
        let dir = Vector3::new(0.6, 0.0, 0.8);
        let x0 = reference_tet();
        let r = TetReference::new(&x0);
        let cases = [
            (31u64, 0.0, 1.0, FibreRate::Step { h: 1e-3 }),
            (37, 0.8, 1.2, FibreRate::Step { h: 1e-3 }),
            (41, 1.0, 0.8, FibreRate::Step { h: 1e-2 }),
            (43, 0.5, 1.1, FibreRate::Isometric),
        ];
        for (seed, act, lm, rate) in cases {
            let hist = FibreHistory {
                lambda_s: 1.0 + 0.05 * act,
                lambda_m: lm,
            };
            let f = Matrix3::identity() + sample(seed) * 0.4;
            let x = x0.map(|q| f * q);
            let el = IsochoricElement::new(&p, &r, &x, &dir, act, &hist, rate);
            let k = el.stiffness(r.volume);
            let tau = el.point.kirchhoff_isochoric();
            let mut reference = nalgebra::SMatrix::<f64, 12, 12>::zeros();
            for b in 0..4 {
                for j in 0..3 {
                    let mut u = Vector3::zeros();
                    u[j] = 1.0;
                    let g = u * el.grad[b].transpose();
                    let dtau = el.point.kirchhoff_isochoric_variation(&g) - tau * g.transpose();
                    for a in 0..4 {
                        let df = dtau * el.grad[a] * r.volume;
                        for i in 0..3 {
                            reference[(3 * a + i, 3 * b + j)] = df[i];
                        }
                    }
                }
            }
            let scale = reference.norm();
            assert!(
                (k - reference).norm() <= 1e-13 * scale,
                "case {seed}: {:e} of {scale:e}",
                (k - reference).norm()
            );
            assert_eq!(k, k.transpose(), "case {seed}: not symmetric to the bit");
        }
    }

    fn mesh_positions(m: &crate::fe::mesh::Mesh, f: &Matrix3<f64>) -> Vec<Vector3<f64>> {
        m.nodes.iter().map(|&q| f * q).collect()
    }

    #[test]
    fn nodal_volumetric_forces_and_hessian_match_finite_differences() {
        let p = Params {
            d_comp: 1e-4,
            ..Params::default()
        };
        let mesh = cylinder(0.01, 0.003, 2, 1);
        let x0: Vec<Vector3<f64>> = mesh.nodes.to_vec();
        let reference: Vec<f64> = mesh
            .tets
            .iter()
            .map(|t| signed_volume(&nodes_of(&x0, t)))
            .collect();
        let v0 = nodal_volumes(x0.len(), &mesh.tets, &reference);
        // A non-affine perturbation so that the nodal J differ.
        let mut x = mesh_positions(&mesh, &(Matrix3::identity() + sample(41) * 0.2));
        for (a, q) in x.iter_mut().enumerate() {
            q[0] += 1e-4 * ((a * 7919 % 13) as f64 - 6.0);
        }
        let vol = NodalVolumetric::new(&p, &x, &mesh.tets, &v0);
        let k = vol.stiffness(&p, &x, &mesh.tets, &v0);
        let scale_f = vol.forces.amax();
        let scale_k = k.amax();
        for dof in 0..3 * x.len() {
            let e = 1e-8;
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[dof / 3][dof % 3] += e;
            xm[dof / 3][dof % 3] -= e;
            let (vp, vm) = (
                NodalVolumetric::new(&p, &xp, &mesh.tets, &v0),
                NodalVolumetric::new(&p, &xm, &mesh.tets, &v0),
            );
            let fd_f = (vp.energy - vm.energy) / (2.0 * e);
            assert!(
                (fd_f - vol.forces[dof]).abs() < 1e-6 * scale_f,
                "force {dof}: fd {fd_f} vs {}",
                vol.forces[dof]
            );
            let fd_k = (&vp.forces - &vm.forces) / (2.0 * e);
            for row in 0..3 * x.len() {
                assert!(
                    (fd_k[row] - k[(row, dof)]).abs() < 1e-5 * scale_k,
                    "K[{row},{dof}]: fd {} vs {}",
                    fd_k[row],
                    k[(row, dof)]
                );
            }
        }
        assert!((&k - k.transpose()).amax() < 1e-9 * scale_k);
    }

    #[test]
    fn an_isochoric_motion_has_no_volumetric_force() {
        // Every nodal J is 1 under a volume-preserving affine map: no
        // pressure, whatever the mesh (here the default fusiform one).
        let p = Params::default();
        let mesh = fusiform(12, 2, FibreLayout::Axial);
        let x0: Vec<Vector3<f64>> = mesh.nodes.to_vec();
        let reference: Vec<f64> = mesh
            .tets
            .iter()
            .map(|t| signed_volume(&nodes_of(&x0, t)))
            .collect();
        let v0 = nodal_volumes(x0.len(), &mesh.tets, &reference);
        let f = Matrix3::from_diagonal(&Vector3::new(1.2, 1.2f64.powf(-0.5), 1.2f64.powf(-0.5)));
        let vol = NodalVolumetric::new(&p, &mesh_positions(&mesh, &f), &mesh.tets, &v0);
        assert!(vol.volume_ratio.iter().all(|&j| (j - 1.0).abs() < 1e-12));
        assert!(vol.forces.amax() < 1e-6, "{}", vol.forces.amax());
    }
}
