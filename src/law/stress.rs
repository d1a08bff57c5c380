//! 3D stress and consistent spatial tangent of the law
//! (MODEL_NOTES "Kinematics", "Energy and stress"; paper eq 24–30).
//!
//! The energy is written in the invariants Ī1, Ī4 = λ̄f² and J:
//! U = U_I(Ī1) + U_f(√Ī4) + U_J(J), uncoupled as in Weiss, Maker & Govindjee (1996).
//! With ψ_x = ∂U/∂x: ψ_1 = U_I', ψ_4 = W / (2 λ̄f), ψ_J = U_J', where
//! W = ∂U_f/∂λ̄f is the fibre nominal stress of [`super::hill_fibre`].
//!
//! **Stress.** S = 2 ∂U/∂C = 2 Σ ψ_x ∂x/∂C with
//! ∂Ī/∂C = J^(−2/3) G − (Ī/3) C⁻¹ (G = I for Ī1, G = A⊗A for Ī4) and
//! ∂J/∂C = (J/2) C⁻¹. Pushed forward (F · Fᵀ), with B̄ = J^(−2/3) F Fᵀ,
//! Ḡ4 = J^(−2/3) FA⊗FA = λ̄f² a⊗a, the structural tensors are
//! n1 = dev B̄, n4 = λ̄f² dev(a⊗a), nJ = (J/2) I, and the Kirchhoff stress is
//!
//! τ = J σ = 2 U_I' dev B̄ + λ̄f W dev(a⊗a) + J U_J' I,
//!
//! which is eq 30 (MODEL_NOTES form) times J. (Eq 24 of the paper has typos and
//! is not used.)
//!
//! **Tangent.** ℂ = 4 ∂²U/∂C∂C = 4 Σ ψ_xy ∂x/∂C ⊗ ∂y/∂C + 4 Σ ψ_x ∂²x/∂C∂C.
//! With ∂C⁻¹/∂C = −𝕀_{C⁻¹}, the push-forwards are
//! F⋆(∂²Ī/∂C∂C) = −(1/3)(Ḡ⊗I + I⊗Ḡ) + (1/9) Ī I⊗I + (1/3) Ī 𝕀 and
//! F⋆(∂²J/∂C∂C) = (J/4) I⊗I − (J/2) 𝕀 (𝕀 the symmetric identity), so
//!
//! J c = 4 U_I'' n1⊗n1 + 4 U_I' [−(1/3)(B̄⊗I + I⊗B̄) + (1/9) Ī1 I⊗I + (1/3) Ī1 𝕀]
//!     + 4 ψ_44 n4⊗n4 + 4 ψ_4 [−(1/3)(Ḡ4⊗I + I⊗Ḡ4) + (1/9) λ̄f² I⊗I + (1/3) λ̄f² 𝕀]
//!     + J² U_J'' I⊗I + J U_J' (I⊗I − 2 𝕀),
//!
//! with ψ_44 = ∂ψ_4/∂Ī4 = (λ̄f W' − W) / (4 λ̄f³), where W' = dW/dλ̄f is the
//! consistent (algorithmic) derivative through the CE–SEE solve, so the
//! tangent is exact for the step map with the history fixed. c relates the
//! Lie derivative of τ to the rate of deformation: L_v τ = J c : d. For a
//! variation δF = g F (d = sym g) that gives δτ = J c : d + g τ + τ gᵀ, which
//! is what [`LawPoint::kirchhoff_variation`] returns and the tests check
//! against finite differences.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

use super::hill_fibre::{
    fibre_response, fibre_stress, FibreHistory, FibreRate, FibreResponse, FibreStress,
};
use super::isotropic_matrix::matrix_derivatives;
use super::params::Params;
use super::volumetric::volumetric_derivatives;

/// Deviator dev X = X − (tr X / 3) I (as used in eq 30, MODEL_NOTES "Energy
/// and stress").
#[inline]
pub fn dev(x: &Matrix3<f64>) -> Matrix3<f64> {
    x - Matrix3::identity() * (x.trace() / 3.0)
}

/// The Voigt order of the tangents' 6 × 6 forms: (11, 22, 33, 12, 23, 13).
pub const VOIGT_PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)];

/// The stress vector of a symmetric tensor in [`VOIGT_PAIRS`] order.
#[inline]
pub fn voigt(x: &Matrix3<f64>) -> Vector6<f64> {
    Vector6::from_fn(|r, _| x[VOIGT_PAIRS[r]])
}

/// J^(−1/3) for J > 0. Near J = 1 (every nearly incompressible state) by
/// the series 1 − e/3 + 2e²/9 (e = J − 1, relative error ≤ 0.18 |e|³) and
/// two Newton steps on y³ J = 1, y ← y (4 − J y³)/3, each of which about
/// squares the relative error (ε → 2ε²): below 1e-17 for |e| ≤ 0.05, i.e.
/// to rounding; elsewhere 1/cbrt(J).
#[inline]
pub fn inverse_cbrt(j: f64) -> f64 {
    let e = j - 1.0;
    if e.abs() <= 0.05 {
        let mut y = 1.0 - e * (1.0 / 3.0) + e * e * (2.0 / 9.0);
        y *= (4.0 - j * y * y * y) * (1.0 / 3.0);
        y * (4.0 - j * y * y * y) * (1.0 / 3.0)
    } else {
        j.cbrt().recip()
    }
}

/// The kinematic quantities of MODEL_NOTES "Kinematics" at F with
/// J = det F given: B̄ = J^(−2/3) F Fᵀ, Ī1 = tr B̄, λ̄f = |J^(−1/3) F A| and
/// a = J^(−1/3) F A / λ̄f.
#[derive(Clone, Copy, Debug)]
pub struct Kinematics {
    pub j: f64,
    pub b_bar: Matrix3<f64>,
    pub i1_bar: f64,
    pub lambda_f: f64,
    pub a: Vector3<f64>,
}

impl Kinematics {
    /// MODEL_NOTES "Kinematics" at `f` with `j` = det F (> 0) and the
    /// reference unit fibre direction `fibre_dir`.
    #[inline]
    pub fn new(f: &Matrix3<f64>, j: f64, fibre_dir: &Vector3<f64>) -> Kinematics {
        let jm13 = inverse_cbrt(j);
        let b_bar = (f * f.transpose()) * (jm13 * jm13);
        let i1_bar = b_bar.trace();
        let fa = f * fibre_dir * jm13; // J^(−1/3) F A
        let lambda_f = fa.norm();
        Kinematics {
            j,
            b_bar,
            i1_bar,
            lambda_f,
            a: fa / lambda_f,
        }
    }
}

/// The isochoric Kirchhoff stress of eq 30 (its bracket, MODEL_NOTES
/// "Energy and stress") with what a residual needs of the fibre, without the
/// tangent's derivatives: the stress-only twin of [`LawPoint`] (same
/// arithmetic, so the same values).
#[derive(Clone, Copy, Debug)]
pub struct IsochoricStress {
    /// τ_iso = 2 U_I' dev B̄ + λ̄f W dev(a⊗a).
    pub tau: Matrix3<f64>,
    /// det F.
    pub j: f64,
    /// λ̄f.
    pub lambda_f: f64,
    /// W, σ_s and the new history (MODEL_NOTES "Hill fibre").
    pub fibre: FibreStress,
}

impl IsochoricStress {
    /// [`LawPoint::kirchhoff_isochoric`] at `f` with `j` = det F given
    /// (MODEL_NOTES "Kinematics", "Energy and stress", "Hill fibre").
    #[inline]
    pub fn new(
        p: &Params,
        f: &Matrix3<f64>,
        j: f64,
        fibre_dir: &Vector3<f64>,
        activation: f64,
        hist: &FibreHistory,
        rate: FibreRate,
    ) -> IsochoricStress {
        let k = Kinematics::new(f, j, fibre_dir);
        let fibre = fibre_stress(p, k.lambda_f, activation, hist, rate);
        let u1 = matrix_derivatives(k.i1_bar, p.b, p.c).0;
        IsochoricStress {
            tau: dev(&k.b_bar) * (2.0 * u1)
                + dev(&(k.a * k.a.transpose())) * (k.lambda_f * fibre.w),
            j,
            lambda_f: k.lambda_f,
            fibre,
        }
    }
}

/// The law evaluated at one material point at the end of a step: kinematic
/// quantities, scalar energy derivatives and the fibre response.
#[derive(Clone, Debug)]
pub struct LawPoint {
    /// J = det F.
    pub j: f64,
    /// Isochoric left Cauchy–Green tensor B̄ = J^(−2/3) F Fᵀ.
    pub b_bar: Matrix3<f64>,
    /// Ī1 = tr C̄ = tr B̄.
    pub i1_bar: f64,
    /// Modified fibre stretch λ̄f = √(A·C̄A).
    pub lambda_f: f64,
    /// Unit deformed fibre direction a = J^(−1/3) F A / λ̄f.
    pub a: Vector3<f64>,
    /// (U_I', U_I'').
    pub du_i: (f64, f64),
    /// (U_J', U_J'').
    pub du_j: (f64, f64),
    /// W, dW/dλ̄f, ∂W/∂a, the new history.
    pub fibre: FibreResponse,
}

impl LawPoint {
    /// Evaluate the law at deformation gradient `f` (J > 0), reference unit
    /// fibre direction `fibre_dir`, activation level `activation`, fibre
    /// history at the start of the step `hist` and the rate mode `rate`:
    /// the kinematics of MODEL_NOTES "Kinematics", U_I' and U_J' (paper eq 25
    /// and 27) and the fibre's W (MODEL_NOTES "Hill fibre").
    pub fn new(
        p: &Params,
        f: &Matrix3<f64>,
        fibre_dir: &Vector3<f64>,
        activation: f64,
        hist: &FibreHistory,
        rate: FibreRate,
    ) -> LawPoint {
        let k = Kinematics::new(f, f.determinant(), fibre_dir);
        let fibre = fibre_response(p, k.lambda_f, activation, hist, rate);
        LawPoint {
            j: k.j,
            b_bar: k.b_bar,
            i1_bar: k.i1_bar,
            lambda_f: k.lambda_f,
            a: k.a,
            du_i: matrix_derivatives(k.i1_bar, p.b, p.c),
            du_j: volumetric_derivatives(k.j, p.d_comp),
            fibre,
        }
    }

    /// a ⊗ a, with a the unit deformed fibre direction (MODEL_NOTES
    /// "Kinematics"): the structural tensor of eq 30's fibre term.
    fn a_outer(&self) -> Matrix3<f64> {
        self.a * self.a.transpose()
    }

    /// Isochoric (deviatoric) Kirchhoff stress τ_iso = 2 U_I' dev B̄ + λ̄f W dev(a⊗a):
    /// the bracket of eq 30 (MODEL_NOTES "Energy and stress"), i.e. J σ
    /// without the volumetric term J U_J' I.
    pub fn kirchhoff_isochoric(&self) -> Matrix3<f64> {
        dev(&self.b_bar) * (2.0 * self.du_i.0)
            + dev(&self.a_outer()) * (self.lambda_f * self.fibre.w)
    }

    /// Kirchhoff stress τ = J σ (eq 30 times J; MODEL_NOTES "Energy and stress").
    pub fn kirchhoff(&self) -> Matrix3<f64> {
        self.kirchhoff_isochoric() + Matrix3::identity() * (self.j * self.du_j.0)
    }

    /// Cauchy stress σ = (1/J) [2 U_I' dev B̄ + λ̄f W dev(a⊗a)] + U_J' I (eq 30,
    /// MODEL_NOTES "Energy and stress").
    pub fn cauchy(&self) -> Matrix3<f64> {
        self.kirchhoff() / self.j
    }

    /// J c : d for a symmetric `d`: the spatial tangent of the energy of
    /// paper eq 2 (derived in the module docs, "Tangent", as MODEL_NOTES
    /// "Energy and stress" asks instead of eq 24), isochoric plus volumetric
    /// part.
    pub fn tangent_apply(&self, d: &Matrix3<f64>) -> Matrix3<f64> {
        self.tangent_apply_isochoric(d) + self.tangent_apply_volumetric(d)
    }

    /// The isochoric part of J c : d (the U_I and U_f terms, paper eq 3–4, of
    /// the module docs' tangent; MODEL_NOTES "Energy and stress"), for
    /// elements whose volumetric response is taken elsewhere (e.g. on nodal
    /// volumes).
    pub fn tangent_apply_isochoric(&self, d: &Matrix3<f64>) -> Matrix3<f64> {
        let id = Matrix3::identity();
        let tr_d = d.trace();
        let (u1, u11) = self.du_i;
        let (i4, psi4, psi44) = self.fibre_invariant_derivatives();
        let n1 = dev(&self.b_bar);
        let g4 = self.a_outer() * i4;
        let n4 = dev(&g4);
        // Push-forward of ∂²Ī/∂C∂C applied to d.
        let second = |g: &Matrix3<f64>, ibar: f64| -> Matrix3<f64> {
            (g * tr_d + id * g.dot(d)) * (-1.0 / 3.0) + id * (ibar * tr_d / 9.0) + d * (ibar / 3.0)
        };
        n1 * (4.0 * u11 * n1.dot(d))
            + second(&self.b_bar, self.i1_bar) * (4.0 * u1)
            + n4 * (4.0 * psi44 * n4.dot(d))
            + second(&g4, i4) * (4.0 * psi4)
    }

    /// [`Self::tangent_apply_isochoric`] as a 6 × 6 matrix D in the Voigt
    /// notation of [`Self::spatial_tangent_voigt`] (stress components
    /// (11, 22, 33, 12, 23, 13) from strains with engineering shears), formed
    /// term by term from the module docs' tangent, symmetric by construction:
    /// the material part B_aᵀ D B_b of an element stiffness in one pass.
    /// With m = s(I), H = diag(1, 1, 1, ½, ½, ½) (s(d) = H ε) and s(·) a
    /// symmetric tensor's stress vector, each push-forward of ∂²Ī/∂C∂C is
    /// −(1/3)(s(Ḡ) mᵀ + m s(Ḡ)ᵀ) + (Ī/9) m mᵀ + (Ī/3) H.
    pub fn isochoric_tangent_voigt(&self) -> Matrix6<f64> {
        let (u1, u11) = self.du_i;
        let (i4, psi4, psi44) = self.fibre_invariant_derivatives();
        let g4 = self.a_outer() * i4;
        let n1 = voigt(&dev(&self.b_bar));
        let n4 = voigt(&dev(&g4));
        let m = voigt(&Matrix3::identity());
        let h = Matrix6::from_diagonal(&m.map(|d| if d == 1.0 { 1.0 } else { 0.5 }));
        let second = |g: &Vector6<f64>, ibar: f64| -> Matrix6<f64> {
            (g * m.transpose() + m * g.transpose()) * (-1.0 / 3.0)
                + m * m.transpose() * (ibar / 9.0)
                + h * (ibar / 3.0)
        };
        n1 * n1.transpose() * (4.0 * u11)
            + second(&voigt(&self.b_bar), self.i1_bar) * (4.0 * u1)
            + n4 * n4.transpose() * (4.0 * psi44)
            + second(&voigt(&g4), i4) * (4.0 * psi4)
    }

    /// Ī4 = λ̄f², ψ_4 = W / (2 λ̄f) and ψ_44 = (λ̄f W' − W) / (4 λ̄f³) (module
    /// docs, W' the consistent derivative through the CE–SEE solve).
    fn fibre_invariant_derivatives(&self) -> (f64, f64, f64) {
        let (lf, w, dw) = (self.lambda_f, self.fibre.w, self.fibre.dw_dlambda);
        (
            lf * lf,
            w / (2.0 * lf),
            (lf * dw - w) / (4.0 * lf * lf * lf),
        )
    }

    /// The volumetric part of J c : d: J² U_J'' tr(d) I + J U_J' (tr(d) I − 2 d),
    /// the U_J term (paper eq 5, U_J' eq 27) of the module docs' tangent.
    pub fn tangent_apply_volumetric(&self, d: &Matrix3<f64>) -> Matrix3<f64> {
        let (uj, ujj) = self.du_j;
        let (j, tr_d) = (self.j, d.trace());
        Matrix3::identity() * (j * j * ujj * tr_d)
            + (Matrix3::identity() * tr_d - d * 2.0) * (j * uj)
    }

    /// Variation of the Kirchhoff stress τ = J σ (eq 30 times J) for δF = g F:
    /// δτ = J c : sym(g) + g τ + τ gᵀ (module docs, "Tangent"; MODEL_NOTES
    /// "Energy and stress").
    pub fn kirchhoff_variation(&self, g: &Matrix3<f64>) -> Matrix3<f64> {
        let tau = self.kirchhoff();
        let d = (g + g.transpose()) * 0.5;
        self.tangent_apply(&d) + g * tau + tau * g.transpose()
    }

    /// Variation of the isochoric Kirchhoff stress (eq 30's bracket, see
    /// [`LawPoint::kirchhoff_isochoric`]) for δF = g F:
    /// δτ_iso = J c_iso : sym(g) + g τ_iso + τ_iso gᵀ (module docs, "Tangent").
    pub fn kirchhoff_isochoric_variation(&self, g: &Matrix3<f64>) -> Matrix3<f64> {
        let tau = self.kirchhoff_isochoric();
        let d = (g + g.transpose()) * 0.5;
        self.tangent_apply_isochoric(&d) + g * tau + tau * g.transpose()
    }

    /// ∂τ/∂a (a the activation level) at fixed F: λ̄f (∂W/∂a) dev(a⊗a), the
    /// derivative of J × eq 30, where only W depends on the activation (through
    /// σ_c of eq 8 in the CE–SEE solve, MODEL_NOTES "Hill fibre").
    pub fn kirchhoff_activation_derivative(&self) -> Matrix3<f64> {
        dev(&self.a_outer()) * (self.lambda_f * self.fibre.dw_dactivation)
    }

    /// The spatial tangent J c of the energy of paper eq 2 (module docs,
    /// "Tangent"; MODEL_NOTES "Energy and stress") in Voigt notation, order (11, 22, 33, 12, 23, 13),
    /// acting on strain vectors with engineering shears (2 d_12, 2 d_23, 2 d_13).
    /// Symmetric (the law has an energy at fixed history).
    pub fn spatial_tangent_voigt(&self) -> Matrix6<f64> {
        let mut out = Matrix6::zeros();
        for (col, &(k, l)) in VOIGT_PAIRS.iter().enumerate() {
            let mut d = Matrix3::zeros();
            if k == l {
                d[(k, l)] = 1.0;
            } else {
                d[(k, l)] = 0.5;
                d[(l, k)] = 0.5;
            }
            let r = self.tangent_apply(&d);
            for (row, &(i, j)) in VOIGT_PAIRS.iter().enumerate() {
                out[(row, col)] = r[(i, j)];
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::super::isotropic_matrix::matrix_energy;
    use super::super::volumetric::volumetric_energy;
    use super::*;

    /// The isochoric fibre stretch λ̄f = (J^(-2/3) a·C a)^(1/2) of `f` along `dir`.
    fn fibre_stretch(f: &Matrix3<f64>, dir: &Vector3<f64>) -> f64 {
        let j = f.determinant();
        (j.powf(-2.0 / 3.0) * dir.dot(&(f.transpose() * f * dir))).sqrt()
    }

    /// The isotropic matrix and volumetric energies U_I(Ī1) + U_J(J) of `f`
    /// (paper eq 3 and the volumetric penalty).
    fn isotropic_energy(p: &Params, f: &Matrix3<f64>) -> f64 {
        let j = f.determinant();
        let i1 = j.powf(-2.0 / 3.0) * (f.transpose() * f).trace();
        matrix_energy(i1, p.b, p.c) + volumetric_energy(j, p.d_comp)
    }

    /// Energy of the hyperelastic parts with the passive fibre (a = 0): the PE
    /// energy is U_PE = σ0 A (λ̄f − 1)³ / 3 for λ̄f > 1.
    fn passive_energy(p: &Params, f: &Matrix3<f64>, dir: &Vector3<f64>) -> f64 {
        let lf = fibre_stretch(f, dir);
        let upe = if lf > 1.0 {
            p.sigma0 * p.a_pe * (lf - 1.0).powi(3) / 3.0
        } else {
            0.0
        };
        isotropic_energy(p, f) + upe
    }

    fn sample_f(seed: u64) -> Matrix3<f64> {
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
        // Mostly isochoric with a small volume change, as the law imposes.
        let j = f.determinant();
        f * (j.cbrt().recip() * (1.0 + 0.02 * r()))
    }

    /// P = τ F⁻ᵀ (first Piola–Kirchhoff) of `pt` at `f` against central
    /// differences (step 1e-7) of the energy, `du(F+, F−) = U(F+) − U(F−)`,
    /// to 1e-6 of |P|.
    fn assert_piola_is_the_energy_derivative(
        seed: u64,
        f: &Matrix3<f64>,
        pt: &LawPoint,
        du: &dyn Fn(&Matrix3<f64>, &Matrix3<f64>) -> f64,
    ) {
        let piola = pt.kirchhoff() * f.try_inverse().unwrap().transpose();
        let h = 1e-7;
        let scale = piola.norm().max(1.0);
        for i in 0..3 {
            for j in 0..3 {
                let (mut fp, mut fm) = (*f, *f);
                fp[(i, j)] += h;
                fm[(i, j)] -= h;
                let fd = du(&fp, &fm) / (2.0 * h);
                assert!(
                    (fd - piola[(i, j)]).abs() < 1e-6 * scale,
                    "seed {seed} P[{i}{j}]: fd {fd} vs {}",
                    piola[(i, j)]
                );
            }
        }
    }

    #[test]
    fn stress_is_the_derivative_of_the_energy() {
        // P = ∂U/∂F (first Piola–Kirchhoff) = τ F⁻ᵀ; central differences.
        // D = 1e-4 keeps the volumetric term commensurate with the rest for FD accuracy.
        let p = Params {
            d_comp: 1e-4,
            ..Params::default()
        };
        let dir = Vector3::new(1.0, 0.0, 0.0);
        for seed in 1..40u64 {
            let f = sample_f(seed * 7919);
            let pt = LawPoint::new(&p, &f, &dir, 0.0, &FibreHistory::REST, FibreRate::Isometric);
            assert_piola_is_the_energy_derivative(seed, &f, &pt, &|fp, fm| {
                passive_energy(&p, fp, &dir) - passive_energy(&p, fm, &dir)
            });
        }
    }

    /// The same check with the active fibre off the x axis: at a fixed
    /// history, activation and step (MODEL_NOTES "Hill fibre": the CE–SEE
    /// update is a function of λ̄f), the fibre's energy has dU_f/dλ̄f = W =
    /// σ_s + σ_p, so U(F±) differ by U_I + U_J at F± plus ∫ W dλ̄f between
    /// λ̄f(F−) and λ̄f(F+) (5-point Gauss–Legendre on that short interval).
    /// P = τ F⁻ᵀ must be its derivative; a fibre term with a wrong direction,
    /// deviator or factor of λ̄f fails it. The samples cover stretched and
    /// compressed fibres (lengthening and shortening CE branches).
    #[test]
    fn stress_is_the_derivative_of_the_energy_for_an_oblique_active_fibre() {
        let p = Params {
            d_comp: 1e-4,
            ..Params::default()
        };
        let dir = Vector3::new(0.0, 0.6, 0.8);
        let (a, hist, rate) = (0.7, FibreHistory::REST, FibreRate::Step { h: 1e-3 });
        let lambda_f = |f: &Matrix3<f64>| fibre_stretch(f, &dir);
        let fibre_work = |l0: f64, l1: f64| {
            const X: [f64; 5] = [
                -0.906_179_845_938_664,
                -0.538_469_310_105_683,
                0.0,
                0.538_469_310_105_683,
                0.906_179_845_938_664,
            ];
            const W: [f64; 5] = [
                0.236_926_885_056_189,
                0.478_628_670_499_366,
                0.568_888_888_888_889,
                0.478_628_670_499_366,
                0.236_926_885_056_189,
            ];
            let (mid, half) = (0.5 * (l0 + l1), 0.5 * (l1 - l0));
            X.iter()
                .zip(W)
                .map(|(x, w)| w * fibre_response(&p, mid + half * x, a, &hist, rate).w)
                .sum::<f64>()
                * half
        };
        let (mut stretched, mut compressed) = (0, 0);
        for seed in 1..40u64 {
            let f = sample_f(seed * 7919);
            if lambda_f(&f) > 1.0 {
                stretched += 1;
            } else {
                compressed += 1;
            }
            let pt = LawPoint::new(&p, &f, &dir, a, &hist, rate);
            assert_piola_is_the_energy_derivative(seed, &f, &pt, &|fp, fm| {
                isotropic_energy(&p, fp) - isotropic_energy(&p, fm)
                    + fibre_work(lambda_f(fm), lambda_f(fp))
            });
        }
        assert!(
            stretched >= 5 && compressed >= 5,
            "{stretched} stretched, {compressed} compressed"
        );
    }

    #[test]
    fn cauchy_is_eq_30_and_symmetric() {
        let p = Params::default();
        let dir = Vector3::new(0.0, 0.6, 0.8);
        let f = sample_f(42);
        let pt = LawPoint::new(&p, &f, &dir, 0.7, &FibreHistory::REST, FibreRate::Isometric);
        let s = pt.cauchy();
        assert!((s - s.transpose()).norm() < 1e-9 * s.norm());
        let id = Matrix3::identity();
        let eq30 = (dev(&pt.b_bar) * (2.0 * pt.du_i.0)
            + dev(&(pt.a * pt.a.transpose())) * (pt.lambda_f * pt.fibre.w))
            / pt.j
            + id * pt.du_j.0;
        assert!((s - eq30).norm() <= 1e-12 * s.norm());
    }

    /// δτ vs finite differences of τ along δF = g F, for the full law with an
    /// active, rate-dependent fibre (history fixed).
    fn check_tangent(
        p: &Params,
        f: &Matrix3<f64>,
        dir: &Vector3<f64>,
        act: f64,
        hist: &FibreHistory,
        rate: FibreRate,
    ) {
        let pt = LawPoint::new(p, f, dir, act, hist, rate);
        let tau_at = |ff: &Matrix3<f64>| LawPoint::new(p, ff, dir, act, hist, rate).kirchhoff();
        for seed in 99u64..105 {
            let g = sample_f(seed) - Matrix3::identity();
            let e = 1e-7;
            let fd = (tau_at(&((Matrix3::identity() + g * e) * f))
                - tau_at(&((Matrix3::identity() - g * e) * f)))
                / (2.0 * e);
            let an = pt.kirchhoff_variation(&g);
            let scale = an.norm().max(fd.norm());
            assert!(
                (fd - an).norm() < 2e-5 * scale,
                "tangent mismatch: fd\n{fd}\nanalytic\n{an}"
            );
        }
        // Voigt form agrees with the tensor form and is symmetric.
        let c = pt.spatial_tangent_voigt();
        assert!((c - c.transpose()).norm() < 1e-9 * c.norm());
        let d = Matrix3::new(0.3, 0.1, -0.2, 0.1, -0.5, 0.05, -0.2, 0.05, 0.2);
        let dv = nalgebra::Vector6::new(
            d[(0, 0)],
            d[(1, 1)],
            d[(2, 2)],
            2.0 * d[(0, 1)],
            2.0 * d[(1, 2)],
            2.0 * d[(0, 2)],
        );
        let r = pt.tangent_apply(&d);
        let rv = c * dv;
        let rt = nalgebra::Vector6::new(
            r[(0, 0)],
            r[(1, 1)],
            r[(2, 2)],
            r[(0, 1)],
            r[(1, 2)],
            r[(0, 2)],
        );
        assert!((rv - rt).norm() < 1e-9 * rt.norm());
    }

    #[test]
    fn tangent_matches_finite_differences() {
        // FD of a 2 GPa bulk term against kPa shear loses digits; the law is the same.
        let p = Params {
            d_comp: 1e-5,
            ..Params::default()
        };
        let dir = Vector3::new(1.0, 0.0, 0.0);
        for seed in [3u64, 17, 29, 101] {
            let f = sample_f(seed);
            // Passive.
            check_tangent(&p, &f, &dir, 0.0, &FibreHistory::REST, FibreRate::Isometric);
            // Active, isometric equilibrium.
            check_tangent(&p, &f, &dir, 0.8, &FibreHistory::REST, FibreRate::Isometric);
            // Active, a rate-dependent step with history (lengthening and shortening).
            let lf_guess = (f * dir).norm();
            for dm in [-0.01, 0.01] {
                let hist = FibreHistory {
                    lambda_s: 1.05,
                    lambda_m: (1.0 + p.k) * lf_guess - p.k * 1.05 - dm,
                };
                check_tangent(&p, &f, &dir, 0.8, &hist, FibreRate::Step { h: 1e-2 });
            }
        }
        // The default (nearly incompressible) D, with a relative tolerance.
        let p = Params::default();
        check_tangent(
            &p,
            &sample_f(5),
            &dir,
            0.5,
            &FibreHistory::REST,
            FibreRate::Isometric,
        );
    }

    #[test]
    fn isochoric_tangent_matches_finite_differences() {
        // The split used by elements with a separate volumetric term: the
        // isochoric Kirchhoff stress and its variation, at the default D.
        let p = Params::default();
        let dir = Vector3::new(0.8, 0.6, 0.0);
        let hist = FibreHistory {
            lambda_s: 1.3,
            lambda_m: 0.95,
        };
        let rate = FibreRate::Step { h: 1e-3 };
        for seed in [7u64, 19, 23] {
            let f = sample_f(seed);
            let pt = LawPoint::new(&p, &f, &dir, 0.7, &hist, rate);
            let tau_iso = |ff: &Matrix3<f64>| {
                LawPoint::new(&p, ff, &dir, 0.7, &hist, rate).kirchhoff_isochoric()
            };
            let g = sample_f(seed + 100) - Matrix3::identity();
            let e = 1e-7;
            let id = Matrix3::identity();
            let fd = (tau_iso(&((id + g * e) * f)) - tau_iso(&((id - g * e) * f))) / (2.0 * e);
            let an = pt.kirchhoff_isochoric_variation(&g);
            assert!(
                (fd - an).norm() < 1e-5 * an.norm().max(fd.norm()),
                "fd\n{fd}\nan\n{an}"
            );
            // The parts add up to the whole.
            let d = (g + g.transpose()) * 0.5;
            let whole = pt.tangent_apply(&d);
            let parts = pt.tangent_apply_isochoric(&d) + pt.tangent_apply_volumetric(&d);
            assert!((whole - parts).norm() <= 1e-12 * whole.norm());
        }
    }

    /// The closed-form Voigt isochoric tangent applies as
    /// `tangent_apply_isochoric` does, on strains of every kind, passive and
    /// active, and is symmetric to the bit.
    #[test]
    fn isochoric_voigt_tangent_applies_as_the_tensor_form() {
        let p = Params::default();
        let dir = Vector3::new(0.0, 0.6, 0.8);
        for (seed, act) in [(3u64, 0.0), (5, 0.4), (13, 1.0)] {
            let f = sample_f(seed);
            let hist = FibreHistory {
                lambda_s: 1.01,
                lambda_m: 1.05,
            };
            let pt = LawPoint::new(&p, &f, &dir, act, &hist, FibreRate::Step { h: 1e-3 });
            let c = pt.isochoric_tangent_voigt();
            assert_eq!(c, c.transpose());
            for k in 0..4 {
                let g = sample_f(seed * 10 + k) - Matrix3::identity();
                let d = (g + g.transpose()) * 0.5;
                let strain = voigt(&d).zip_map(&voigt(&Matrix3::identity()), |e, m| {
                    if m == 1.0 {
                        e
                    } else {
                        2.0 * e
                    }
                });
                let tensor = voigt(&pt.tangent_apply_isochoric(&d));
                let matrix = c * strain;
                assert!(
                    (tensor - matrix).norm() <= 1e-14 * tensor.norm(),
                    "seed {seed}: {tensor} vs {matrix}"
                );
            }
        }
    }

    #[test]
    fn activation_derivative_matches_finite_differences() {
        let p = Params::default();
        let dir = Vector3::new(1.0, 0.0, 0.0);
        let f = sample_f(11);
        let hist = FibreHistory {
            lambda_s: 1.02,
            lambda_m: 1.0,
        };
        let rate = FibreRate::Step { h: 1e-3 };
        let pt = LawPoint::new(&p, &f, &dir, 0.5, &hist, rate);
        let e = 1e-7;
        let fd = (LawPoint::new(&p, &f, &dir, 0.5 + e, &hist, rate).kirchhoff()
            - LawPoint::new(&p, &f, &dir, 0.5 - e, &hist, rate).kirchhoff())
            / (2.0 * e);
        let an = pt.kirchhoff_activation_derivative();
        assert!(
            (fd - an).norm() < 1e-5 * an.norm().max(1.0),
            "fd\n{fd}\nan\n{an}"
        );
    }

    #[test]
    fn objectivity_under_rotation() {
        // τ(QF) = Q τ(F) Qᵀ.
        let p = Params::default();
        let dir = Vector3::new(1.0, 0.0, 0.0);
        let f = sample_f(8);
        let q = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
        let t1 = LawPoint::new(
            &p,
            &(q * f),
            &dir,
            0.6,
            &FibreHistory::REST,
            FibreRate::Isometric,
        )
        .kirchhoff();
        let t0 =
            LawPoint::new(&p, &f, &dir, 0.6, &FibreHistory::REST, FibreRate::Isometric).kirchhoff();
        assert!((t1 - q * t0 * q.transpose()).norm() < 1e-9 * t0.norm());
    }

    #[test]
    fn stress_free_at_rest() {
        let p = Params::default();
        let pt = LawPoint::new(
            &p,
            &Matrix3::identity(),
            &Vector3::x(),
            0.0,
            &FibreHistory::REST,
            FibreRate::Isometric,
        );
        assert!(pt.cauchy().norm() < 1e-9);
    }

    /// The stress-only path is the same arithmetic as [`LawPoint`]: the
    /// same τ_iso, λ̄f, W, σ_s and history, bit for bit, passive and active,
    /// isometric and rate-dependent.
    #[test]
    fn isochoric_stress_equals_the_law_point_bit_for_bit() {
        let p = Params::default();
        let dir = Vector3::new(0.0, 0.6, 0.8);
        let hist = FibreHistory {
            lambda_s: 1.2,
            lambda_m: 0.95,
        };
        for seed in 1..60u64 {
            let f = sample_f(seed * 104_729);
            for (a, rate) in [
                (0.0, FibreRate::Isometric),
                (0.7, FibreRate::Isometric),
                (0.0, FibreRate::Step { h: 1e-3 }),
                (0.9, FibreRate::Step { h: 1e-3 }),
            ] {
                let pt = LawPoint::new(&p, &f, &dir, a, &hist, rate);
                let st = IsochoricStress::new(&p, &f, f.determinant(), &dir, a, &hist, rate);
                assert_eq!(st.tau, pt.kirchhoff_isochoric(), "seed {seed}, a {a}");
                assert_eq!(st.lambda_f, pt.lambda_f);
                assert_eq!(st.fibre.w, pt.fibre.w);
                assert_eq!(st.fibre.sigma_see, pt.fibre.sigma_see);
                assert_eq!(st.fibre.history, pt.fibre.history);
            }
        }
    }

    /// J^(−1/3) by the series and Newton steps agrees with 1/cbrt to within
    /// 2 ulps across its range, and is continuous where it hands over.
    #[test]
    fn inverse_cbrt_is_accurate_to_rounding() {
        let mut j = 0.9;
        while j < 1.1 {
            let (fast, reference) = (inverse_cbrt(j), j.cbrt().recip());
            assert!(
                (fast - reference).abs() <= 2.0 * f64::EPSILON * reference,
                "J = {j}: {fast} vs {reference}"
            );
            j += 1.3e-5;
        }
        for j in [1e-6, 0.3, 0.95, 1.05, 3.0, 1e6] {
            assert_eq!(inverse_cbrt(j), j.cbrt().recip());
        }
    }
}
