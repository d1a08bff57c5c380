//! The 1D muscle's outputs and their partial derivatives with respect to the
//! inputs (MODEL_NOTES "The 1D Hill reduction": force = σ11 A0 μ², the
//! nominal stress P = τ11 / λ): `Muscle1D::evaluate` forms the outputs of a
//! solved state and what their partials need ([`Jacobian`]), whose
//! [`Muscle1D::partial`] forms each partial on demand.

use super::muscle::Muscle1D;
use crate::law::hill_fibre::ce_stretch;
use crate::law::series_element::see_stiffness;
use crate::law::uniaxial::{cauchy_sensitivity, Sensitivity};
use crate::law::{Components, Uniaxial};

crate::outputs::muscle_outputs! {
    /// The outputs, in the order the muscle stores them
    /// ([`Muscle1D::output`]).
    pub enum Output {
        /// d force / d length of the step map (a partial, not stored: see
        /// [`Muscle1D::output`]).
        Stiffness,
    }
}

/// How many outputs are stored: every [`Output`] but the stiffness.
pub const N_OUT: usize = Output::Stiffness as usize;

/// The inputs, as columns of the partial derivatives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    Activation,
    Length,
}

/// How many inputs there are.
pub(crate) const N_IN: usize = 2;

/// The two inputs, as indices into the sensitivity tables.
pub(crate) const IN_ACTIVATION: usize = Input::Activation as usize;
pub(crate) const IN_LENGTH: usize = Input::Length as usize;

/// The values of one [`Sensitivity`] in [`Jacobian::to_values`], in order.
const SENSITIVITY_LEN: usize = 6;

/// What the partial derivatives of the outputs with respect to the inputs
/// need from the last solve. The partials are formed on demand in
/// [`Muscle1D::partial`]: forming them every step would cost more than the
/// rest of the step's bookkeeping, and only masters that ask for
/// directional derivatives use them.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Jacobian {
    /// Per input (activation, length): total sensitivities of the uniaxial
    /// state at the end of the step with respect to the input (through every
    /// substep of the step).
    pub(crate) sens: [Sensitivity; N_IN],
    /// dP/d(input).
    pub(crate) dnominal: [f64; N_IN],
    /// d(activation level)/d(input): ∂a/∂u and 0.
    pub(crate) dlevel: [f64; N_IN],
    pub(crate) tau11: f64,
    pub(crate) j: f64,
    /// dσ_s/dλs.
    pub(crate) dsigma_see: f64,
}

impl Jacobian {
    /// How many values [`Jacobian::to_values`] gives: per input its
    /// sensitivities, dP and da; then τ11, J and dσ_s/dλs.
    pub const LEN: usize = N_IN * (SENSITIVITY_LEN + 2) + 3;

    /// ∂ output / ∂ input (`column` is IN_ACTIVATION or IN_LENGTH); `k` the
    /// law's SEE ratio, `area` the cross-section.
    pub(crate) fn partial(&self, out: Output, column: usize, k: f64, area: f64) -> f64 {
        let s = &self.sens[column];
        let dnom = self.dnominal[column];
        let dsee = self.dsigma_see * s.lambda_s;
        match out {
            Output::Force => dnom * area,
            Output::Stress => dnom,
            // σ11 = τ11 / J.
            Output::CauchyStress => cauchy_sensitivity(self.tau11, self.j, s),
            Output::ActivationLevel => self.dlevel[column],
            Output::FibreStretch => s.lambda_f,
            // λm = (1 + k) λ̄f − k λs.
            Output::CeStretch => ce_stretch(k, s.lambda_f, s.lambda_s),
            Output::SeeStretch => s.lambda_s,
            Output::ActiveStress => dsee,
            Output::PassiveStress => dnom - dsee,
            // A second derivative: not provided.
            Output::Stiffness => f64::NAN,
        }
    }

    /// One sensitivity's values, in serialized order.
    fn sensitivity_values(s: &Sensitivity) -> [f64; SENSITIVITY_LEN] {
        [s.q, s.j, s.mu, s.tau11, s.lambda_f, s.lambda_s]
    }

    /// Whether every value of [`Jacobian::to_values`] is finite (without
    /// collecting them: this runs every step).
    pub(crate) fn all_finite(&self) -> bool {
        self.sens
            .iter()
            .all(|s| Self::sensitivity_values(s).iter().all(|x| x.is_finite()))
            && self
                .dnominal
                .iter()
                .chain(&self.dlevel)
                .chain(&[self.tau11, self.j, self.dsigma_see])
                .all(|x| x.is_finite())
    }

    /// The values in their serialized order ([`Jacobian::LEN`] of them).
    pub fn to_values(self) -> Vec<f64> {
        let mut v = Vec::with_capacity(Self::LEN);
        for s in &self.sens {
            v.extend(Self::sensitivity_values(s));
        }
        v.extend(self.dnominal);
        v.extend(self.dlevel);
        v.extend([self.tau11, self.j, self.dsigma_see]);
        v
    }

    /// The Jacobian of [`Jacobian::to_values`]'s values (`None` unless there
    /// are [`Jacobian::LEN`] of them).
    pub fn from_values(v: &[f64]) -> Option<Jacobian> {
        if v.len() != Self::LEN {
            return None;
        }
        let sens = |o: usize| Sensitivity {
            q: v[o],
            j: v[o + 1],
            mu: v[o + 2],
            tau11: v[o + 3],
            lambda_f: v[o + 4],
            lambda_s: v[o + 5],
        };
        let rest = N_IN * SENSITIVITY_LEN;
        Some(Jacobian {
            sens: [sens(0), sens(SENSITIVITY_LEN)],
            dnominal: [v[rest], v[rest + 1]],
            dlevel: [v[rest + 2], v[rest + 3]],
            tau11: v[rest + 4],
            j: v[rest + 5],
            dsigma_see: v[rest + 6],
        })
    }
}

impl<C: Components> Muscle1D<C> {
    /// Outputs (in [`Output`] order) and the data of their partials (the
    /// Jacobian) from a solved uniaxial state; `sens` are its total
    /// sensitivities with respect to the inputs (activation, length) and
    /// `da_du` is ∂a/∂u of the step map.
    pub(crate) fn evaluate(
        &self,
        u: &Uniaxial,
        a: f64,
        sens: [Sensitivity; N_IN],
        da_du: f64,
    ) -> ([f64; N_OUT], Jacobian) {
        let fibre = &u.fibre;
        let sigma_s = fibre.sigma_see;
        let nominal = u.nominal_stress();
        let values = [
            nominal * self.area,
            nominal,
            u.cauchy_stress(),
            a,
            u.lambda_f,
            fibre.history.lambda_m,
            fibre.history.lambda_s,
            sigma_s,
            nominal - sigma_s,
        ];
        let mut jacobian = Jacobian {
            tau11: u.tau11,
            j: u.j,
            // dσ_s/dλs = α (σ_s + β) (eq 31).
            dsigma_see: see_stiffness(sigma_s, self.params.alpha, self.params.beta),
            ..Jacobian::default()
        };
        // P = τ11 / λ: dP = dτ11 / λ − τ11 dλ / λ², with dλ/dL = 1/L0 (the
        // stretch at the end of the step is L/L0) and dλ/du = 0.
        let dlambda = [0.0, 1.0 / self.l0];
        for c in [IN_ACTIVATION, IN_LENGTH] {
            if c == IN_ACTIVATION && !C::ACTIVATION_INPUT {
                continue; // no activation input: no such partial
            }
            jacobian.dnominal[c] =
                sens[c].tau11 / u.lambda - u.tau11 * dlambda[c] / (u.lambda * u.lambda);
        }
        jacobian.sens = sens;
        jacobian.dlevel = [da_du, 0.0];
        (values, jacobian)
    }

    /// The value of output `out` after the last step or initialization; the
    /// stiffness is d force / d length of the step map that produced it.
    pub fn output(&self, out: Output) -> f64 {
        match out {
            Output::Stiffness => self.partial(Output::Force, Input::Length),
            o => self.outputs[o as usize],
        }
    }

    /// ∂ `out` / ∂ `input` of the step map that produced the current outputs
    /// (consistent tangent, history fixed; NaN for the stiffness, itself a
    /// partial).
    pub fn partial(&self, out: Output, input: Input) -> f64 {
        self.jacobian
            .partial(out, input as usize, self.params.k, self.area)
    }
}
