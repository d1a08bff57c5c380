//! What goes wrong in the 1D muscle, and the messages that say so: a setup
//! the law cannot take ([`SetupError`]) and a step that cannot be taken
//! ([`Discard`]; the muscle is then unchanged). Each message names the
//! variable at fault and what would make it solvable.

use super::muscle::Muscle1D;
use crate::law::params::{out_of_range, AREA_RANGE, L0_RANGE, LENGTH_RANGE};
use crate::law::Components;

/// The muscle cannot be set up or initialized: the message names the
/// variable and its valid range, or why the law has no equilibrium there.
#[derive(Clone, Debug, PartialEq)]
pub struct SetupError(pub String);

/// A step that cannot be taken; the muscle is unchanged.
#[derive(Clone, Debug, PartialEq)]
pub enum Discard {
    /// The law cannot be solved over the step: the message says why and what
    /// to change.
    Unsolvable(String),
    /// The CE–SEE root lies on a branch of f_v (eq 12) that the components
    /// leave out ([`crate::law::Components::FV_SHORTENING`],
    /// `FV_LENGTHENING`): the CE carries `sigma_see` (Pa) while its stretch
    /// rate `rate` (1/s) is on that branch (lengthening when > 0).
    AbsentFvBranch { rate: f64, sigma_see: f64 },
}

impl<C: Components> Muscle1D<C> {
    /// The setup the law can take: every parameter in its range, `L0`, `area`
    /// and the length in theirs, `initial_activation` in [0, 1].
    pub fn check_setup(&self) -> Result<(), SetupError> {
        self.params
            .validate()
            .map_err(|e| SetupError(e.to_string()))?;
        L0_RANGE.check("L0", self.l0).map_err(SetupError)?;
        AREA_RANGE.check("area", self.area).map_err(SetupError)?;
        if !(0.0..=1.0).contains(&self.initial_activation) {
            return Err(SetupError(out_of_range(
                "initial_activation",
                self.initial_activation,
                "in [0, 1]",
            )));
        }
        LENGTH_RANGE
            .check("length", self.length())
            .map_err(SetupError)
    }

    /// Message for a length at which the law cannot be solved: names the
    /// variables and the range of length/L0 the law can evaluate
    /// ([`crate::law::uniaxial::evaluable_stretch_range`]).
    pub(crate) fn unsolvable(&self, length: f64, why: &str) -> String {
        let (lo, hi) = self.stretch_range;
        let lambda = length / self.l0;
        if (lo..=hi).contains(&lambda) {
            // The stretch is evaluable at J = 1: the volume change is what
            // overflows the law (a soft volumetric term, large D).
            format!(
                "no finite equilibrium at length = {length} m (length/L0 = {lambda}): the volume change \
                 the law allows with D = {} 1/Pa grows until its matrix term c exp(b (I1bar - 3)) overflows; \
                 a smaller D (stiffer volumetric term) keeps J near 1; solver: {why}",
                self.params.d_comp
            )
        } else {
            format!(
                "length = {length} m with L0 = {} m (stretch length/L0 = {lambda}) is outside the range the law \
                 can evaluate: keep length/L0 within [{lo:.4}, {hi:.4}] (where the matrix term \
                 c exp(b (I1bar - 3)) is finite, b = {}); solver: {why}",
                self.l0, self.params.b
            )
        }
    }

    /// Message for a step (or substep) of length `h` that changes the stretch
    /// by `dlambda` and whose law cannot be solved: when 1/h or the stretch
    /// rate dlambda / h of the backward-Euler CE update (MODEL_NOTES "Hill
    /// fibre") is not finite, the step is too short to be evaluated and the
    /// message names `communicationStepSize`; otherwise [`Self::unsolvable`].
    pub(crate) fn unsolvable_step(&self, length: f64, dlambda: f64, h: f64, why: &str) -> String {
        if (1.0 / h).is_finite() && (dlambda / h).is_finite() {
            return self.unsolvable(length, why);
        }
        format!(
            "communicationStepSize too short: a step of {h:e} s to length = {length} m (length/L0 changes by \
             {dlambda}) has a non-finite 1/h or stretch rate, so the CE update (backward Euler) cannot be \
             evaluated; use a longer step; solver: {why}"
        )
    }
}
