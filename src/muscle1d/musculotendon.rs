//! The 1D musculotendon unit: the 1D muscle in series with a tendon, at a
//! pennation angle, driven by the length of its whole path (MODEL_NOTES
//! "Musculotendon unit").
//!
//! Entry points: [`Musculotendon1D::initialize`] (static equilibrium at the
//! initial path length and activation level), [`Musculotendon1D::step`] and
//! [`Musculotendon1D::output`] / [`Musculotendon1D::partial`].
//!
//! Each step is the muscle's step map ([`super::step`]) with its pieces'
//! ends coupled to the path: the path length moves linearly from where it
//! was to the input (plus h times its derivative), and at the end of every
//! piece of the error-controlled step the fibre length L_M is where the
//! tendon and the muscle are in equilibrium,
//! F_T(ℓ − L_M cos α) = F_M(L_M) cos α ([`solve_equilibrium`]), F_M being
//! the force of the piece's CE–SEE step ending at L_M. Only the solve at the
//! root is kept, so the muscle's history is advanced for the L_M the piece
//! settles on. The partial derivatives chain the equilibrium's implicit
//! derivatives through the pieces.
//!
//! Invariants: a step that cannot be completed (no equilibrium in the
//! evaluable range, past the largest pennation angle, or the muscle's own
//! failures) is an error and changes nothing; a rigid tendon without
//! pennation is exactly (bit for bit) the plain muscle at length ℓ − L_TS.

use super::error::{Discard, SetupError};
use super::muscle::Muscle1D;
use super::outputs::{Input, Jacobian, IN_ACTIVATION, IN_LENGTH, N_IN, N_OUT};
use super::step::{combine, PieceEnd, Solved, StepStatistics, Stepped};
use crate::law::musculotendon::{
    solve_equilibrium, EquilibriumError, MuscleForce, StepRates, Tolerance, Unit, UnitParams,
};
use crate::law::params::LENGTH_RANGE;
use crate::law::uniaxial::{evaluable_stretch_range, Sensitivity};
use crate::law::{solve_uniaxial_with, Components, FibreHistory, FibreRate, Uniaxial};
use std::cell::Cell;

/// Tolerance of the equilibrium's residual F_M cos α − F_T, relative to F0
/// ([`Tolerance::Fixed`]: the law's force is solved to rounding).
pub const EQUILIBRIUM_RTOL: f64 = 1e-10;

/// The unit's outputs (MODEL_NOTES "Musculotendon unit": outputs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnitOutput {
    /// The tendon force F_T (N), what the path carries.
    Force,
    /// The muscle's nominal stress F_M / area (Pa).
    Stress,
    /// L_M (m).
    FibreLength,
    /// ε.
    TendonStrain,
    /// α (rad).
    PennationAngle,
    /// dF_T/dℓ of the step map (N/m; a partial: see
    /// [`Musculotendon1D::output`]).
    Stiffness,
}

const N_UNIT: usize = UnitOutput::Stiffness as usize;

/// The 1D muscle in series with a tendon at a pennation angle. The muscle's
/// command (`muscle.command`, `muscle.command_rate`) is the unit's; its
/// length input is not read (the unit sets the fibre length).
#[derive(Clone, Debug, PartialEq)]
pub struct Musculotendon1D<C: Components> {
    pub muscle: Muscle1D<C>,
    pub(crate) unit: UnitParams,
    /// The path length input; `None` until set, when the path is
    /// L_TS + L0 cos α0 (the fibres at L0, the tendon at its slack length).
    pub(crate) path: Option<f64>,
    pub(crate) path_rate: f64,
    // Committed state beyond the muscle's.
    /// The path length at the end of the last step.
    pub(crate) committed_path: f64,
    /// The first guess of the next step's pieces only (they change the
    /// cost, not the result beyond the equilibrium's tolerance): dλ/dℓ of
    /// the last step, and its rates of λ and of the path (1/s, m/s; 0 after
    /// initialization).
    pub(crate) guess: Guess,
    pub(crate) outputs: [f64; N_UNIT],
    /// dF_T/d(activation command), dF_T/dℓ of the last step.
    pub(crate) dforce: [f64; N_IN],
    /// Evaluations of the muscle in the last step (a diagnostic, not state).
    evaluations: Diagnostic,
}

/// A count that is not part of the state: equal to every other.
#[derive(Clone, Copy, Debug, Default)]
struct Diagnostic(u32);

impl PartialEq for Diagnostic {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// What the first guess of a piece's fibre stretch extrapolates from: the
/// last step's dλ/dℓ (`slope`), and the rates of λ (1/s) and of the path
/// ([`StepRates`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Guess {
    pub(crate) slope: f64,
    pub(crate) rates: StepRates,
}

impl Guess {
    /// The guess after a step of length `h` that moved λ by `dlambda` and
    /// the path by `dpath`, with the step's dλ/dℓ `slope`; a step too short
    /// to give rates leaves none ([`StepRates::after`]).
    fn after(&self, slope: f64, h: f64, dlambda: f64, dpath: f64) -> Guess {
        match self.rates.after(h, dlambda, dpath) {
            Some(rates) => Guess { slope, rates },
            None => Guess {
                slope: if slope.is_finite() { slope } else { 0.0 },
                rates: StepRates::default(),
            },
        }
    }
}

/// The pieces' ends of a step of length `h` on a path from `from` to `to`:
/// the equilibrium at the path interpolated linearly.
struct PathEnds<'a> {
    unit: &'a Unit,
    from: f64,
    to: f64,
    l0: f64,
    area: f64,
    /// The fibre lengths the law can evaluate.
    range: (f64, f64),
    h: f64,
    guess: Guess,
    tol: f64,
    /// Evaluations of the muscle by the equilibrium, summed over the pieces
    /// (tried and accepted).
    evaluations: Cell<u32>,
}

impl PathEnds<'_> {
    /// The path at fraction `frac` of the step (the end exactly when `last`).
    fn path(&self, frac: f64, last: bool) -> f64 {
        if last {
            self.to
        } else {
            self.from + (self.to - self.from) * frac
        }
    }
}

/// The message of an equilibrium that failed at path length `path`.
fn unsolvable(e: EquilibriumError<Discard>, path: f64) -> Discard {
    match e.reason() {
        Ok(reason) => Discard::Unsolvable(format!("path length = {path} m: {reason}")),
        Err(error) => error,
    }
}

impl PieceEnd for PathEnds<'_> {
    const COUPLED: bool = true;

    /// The first guess: λ's change over the piece extrapolated (its rate
    /// linear in time through the last two steps' mean rates), plus dλ/dℓ
    /// times the path's change beyond its own extrapolation (second order
    /// in the step for smooth inputs: the cost, not the result).
    fn stretch(&self, lambda: f64, from: f64, frac: f64, last: bool) -> f64 {
        let g = &self.guess;
        let (t0, t1) = (from * self.h, frac * self.h);
        let dpath = self.path(frac, last) - self.path(from, false);
        let (fibre, path) = g.rates.changes(t0, t1);
        lambda + fibre + g.slope * (dpath - path)
    }

    /// The equilibrium at the piece's path; d λ/d(path input) is
    /// (dL_M/dℓ)·frac/L0 and d λ/dτ11 is (dL_M/dF̃)·area/(λ L0)
    /// (F_M = τ11 area / λ at fixed λ).
    fn solve<F>(&self, frac: f64, last: bool, guess: f64, mut law: F) -> Result<Solved, Discard>
    where
        F: FnMut(f64) -> Result<Uniaxial, Discard>,
    {
        let path = self.path(frac, last);
        let mut kept = None;
        let eq = solve_equilibrium(
            self.unit,
            path,
            self.range,
            guess * self.l0,
            Tolerance::Fixed(self.tol),
            None,
            |l_m| {
                let u = law(l_m / self.l0)?;
                let m = MuscleForce::of_uniaxial(&u, self.area, self.l0);
                kept = Some(u);
                Ok(m)
            },
        )
        .map_err(|e| unsolvable(e, path))?;
        let u = kept.expect("the equilibrium evaluates the muscle");
        self.evaluations
            .set(self.evaluations.get() + eq.evaluations);
        let dpath = if last { 1.0 } else { frac };
        Ok(Solved {
            dlambda_dinput: eq.dfibre_dpath * dpath / self.l0,
            dlambda_dtau: eq.dfibre_dforce * self.area / (u.lambda * self.l0),
            u,
        })
    }
}

impl<C: Components> Musculotendon1D<C> {
    /// The unit around `muscle` with parameters `unit`, its path input
    /// unset. Not yet initialized.
    pub fn new(muscle: Muscle1D<C>, unit: UnitParams) -> Self {
        Musculotendon1D {
            muscle,
            unit,
            path: None,
            path_rate: 0.0,
            committed_path: 0.0,
            guess: Guess::default(),
            evaluations: Diagnostic::default(),
            outputs: [0.0; N_UNIT],
            dforce: [0.0; N_IN],
        }
    }

    /// The tendon and pennation of the current parameters; F0 = σ0 · area.
    pub fn unit(&self) -> Unit {
        let m = &self.muscle;
        Unit::new(&self.unit, m.l0, m.params.sigma0 * m.area)
    }

    /// The path length input (L_TS + L0 cos α0 until set).
    pub fn path(&self) -> f64 {
        self.path
            .unwrap_or_else(|| self.unit.rest_path(self.muscle.l0))
    }

    /// Set the path length input (m) for the next step.
    pub fn set_path(&mut self, path: f64) {
        self.path = Some(path);
    }

    /// Set the path's rate (m/s) for the next step (an input derivative).
    pub fn set_path_rate(&mut self, rate: f64) {
        self.path_rate = rate;
    }

    /// Set the activation command u ∈ [0, 1] for the next step.
    pub fn set_command(&mut self, u: f64) {
        self.muscle.command = u;
    }

    fn tol(&self) -> f64 {
        EQUILIBRIUM_RTOL * self.muscle.params.sigma0 * self.muscle.area
    }

    /// The muscle's setup and the unit's parameters are valid.
    pub fn check_setup(&self) -> Result<(), SetupError> {
        self.muscle.check_setup()?;
        self.unit
            .validate()
            .map_err(|e| SetupError(e.to_string()))?;
        let path = self.path();
        if !LENGTH_RANGE.contains(path) {
            return Err(SetupError(format!(
                "path length = {path} is out of range: must be {LENGTH_RANGE}"
            )));
        }
        Ok(())
    }

    /// Static equilibrium at the initial path length and activation level
    /// (MODEL_NOTES "Musculotendon unit": initialization): the isometric
    /// solve of the muscle ([`Muscle1D::initialize`]'s) at the fibre length
    /// where it balances the tendon.
    pub fn initialize(&mut self) -> Result<(), SetupError> {
        self.check_setup()?;
        let m = &self.muscle;
        let (a, da_du) = if m.activation_dynamics {
            (m.initial_activation, 0.0)
        } else {
            (m.command, 1.0)
        };
        let muscle = &self.muscle;
        let stretch_range = evaluable_stretch_range(&muscle.params);
        let unit = self.unit();
        let path = self.path();
        let (l0, area) = (muscle.l0, muscle.area);
        let range = (stretch_range.0 * l0, stretch_range.1 * l0);
        let guess = unit
            .pennation
            .fibre_length_of(path - unit.tendon.slack_length)
            .unwrap_or(l0);
        let mut kept = None;
        let eq = solve_equilibrium(
            &unit,
            path,
            range,
            guess,
            Tolerance::Fixed(self.tol()),
            None,
            |l_m| {
                let u = solve_uniaxial_with::<C>(
                    &muscle.params,
                    l_m / l0,
                    a,
                    &FibreHistory::REST,
                    FibreRate::Isometric,
                    1.0,
                )
                .map_err(|e| Discard::Unsolvable(muscle.unsolvable(l_m, &e.0)))?;
                let f = MuscleForce::of_uniaxial(&u, area, l0);
                kept = Some(u);
                Ok(f)
            },
        )
        .map_err(|e| match unsolvable(e, path) {
            Discard::Unsolvable(s) => SetupError(s),
            other => SetupError(format!("{other:?}")),
        })?;
        let u: Uniaxial = kept.expect("the equilibrium evaluates the muscle");
        u.fibre
            .history
            .check_physical(muscle.params.k, u.lambda_f)
            .map_err(|e| SetupError(format!("fibre length = {} m: {e}", eq.fibre_length)))?;
        // The fibre length's partials: through the force at fixed L_M
        // (activation) and the path.
        let dforce_da = u.dnominal_dactivation() * area * da_du;
        let dlambda = [eq.dfibre_dforce * dforce_da / l0, eq.dfibre_dpath / l0];
        let sens = [
            combine(&[(&u.d_dactivation, da_du), (&u.d_dlambda, dlambda[0])]),
            combine(&[(&u.d_dlambda, dlambda[1])]),
        ];
        let stats = StepStatistics {
            substeps: 1,
            rejected_substeps: 0,
            lateral_iterations: u.iterations,
            ce_iterations: u.ce_iterations,
            at_rest: false,
        };
        let (outputs, jacobian) = muscle.evaluate(&u, a, sens, da_du);
        let jacobian = rechain(jacobian, &u, &sens, dlambda);
        if outputs.iter().any(|x| !x.is_finite()) || !jacobian.all_finite() {
            return Err(SetupError(
                muscle.unsolvable(eq.fibre_length, "a non-finite output"),
            ));
        }
        let (unit_outputs, dforce) =
            self.unit_outputs(&unit, path, &u, &outputs, &jacobian, dlambda);
        if unit_outputs.iter().chain(&dforce).any(|x| !x.is_finite()) {
            return Err(SetupError(
                muscle.unsolvable(eq.fibre_length, "a non-finite output"),
            ));
        }
        self.muscle.stretch_range = stretch_range;
        self.muscle.length = Some(eq.fibre_length);
        self.muscle.commit(&u, a, None, outputs, jacobian, stats);
        let guess = Guess {
            slope: dlambda[IN_LENGTH],
            ..Guess::default()
        };
        self.commit(path, guess, unit_outputs, dforce);
        Ok(())
    }

    /// One step of length `h` to the path length input (plus `h` times its
    /// derivative), the command held (or linear) over it: the muscle's step
    /// map with every piece ending in equilibrium with the tendon (module
    /// docs). Committed only on success; the input derivatives hold for
    /// this one step.
    pub fn step(&mut self, h: f64) -> Result<(), Discard> {
        let path = self.path() + h * self.path_rate;
        if !(path.is_finite() && path > 0.0) {
            return Err(Discard::Unsolvable(format!(
                "path length at the end of the step, length + h * der(length) = {path}, must be finite and > 0"
            )));
        }
        let unit = self.unit();
        let m = &self.muscle;
        let (decay, a_end) = m.end_level(h);
        // The rigid tendon without pennation evaluates the muscle once per
        // piece tried, as the plain muscle.
        let mut evaluations = 0;
        let Stepped {
            u,
            a,
            da_du,
            sens,
            dlambda,
            stats,
        } = if !unit.compliant && unit.pennation.height == 0.0 {
            // L_M = ℓ − L_TS: the plain muscle's step, exactly.
            let lambda = (path - unit.tendon.slack_length) / m.l0;
            if !(m.stretch_range.0..=m.stretch_range.1).contains(&lambda) {
                return Err(Discard::Unsolvable(
                    m.unsolvable(lambda * m.l0, "not attempted"),
                ));
            }
            m.solve_step(h, lambda, a_end)?
        } else {
            let ends = PathEnds {
                unit: &unit,
                from: self.committed_path,
                to: path,
                l0: m.l0,
                area: m.area,
                range: (m.stretch_range.0 * m.l0, m.stretch_range.1 * m.l0),
                h,
                guess: self.guess,
                tol: self.tol(),
                evaluations: Cell::new(0),
            };
            let stepped = m.solve_step_to(h, &ends, a_end)?;
            evaluations = ends.evaluations.get();
            stepped
        };
        let (outputs, jacobian) = m.evaluate(&u, a, sens, da_du);
        let jacobian = rechain(jacobian, &u, &sens, dlambda);
        Muscle1D::<C>::check_outputs(&outputs, &jacobian, u.lambda, h)?;
        let (unit_outputs, dforce) =
            self.unit_outputs(&unit, path, &u, &outputs, &jacobian, dlambda);
        if unit_outputs.iter().chain(&dforce).any(|x| !x.is_finite()) {
            return Err(Discard::Unsolvable(format!(
                "non-finite tendon force or derivative at path length {path} m"
            )));
        }
        let guess = self.guess.after(
            dlambda[IN_LENGTH],
            h,
            u.lambda - self.muscle.lambda,
            path - self.committed_path,
        );
        self.muscle.length = Some(u.lambda * self.muscle.l0);
        self.muscle
            .finish_step(&u, a, h, decay, outputs, jacobian, stats);
        self.commit(path, guess, unit_outputs, dforce);
        self.evaluations = Diagnostic(evaluations.max(stats.substeps + stats.rejected_substeps));
        self.path_rate = 0.0;
        Ok(())
    }

    fn commit(&mut self, path: f64, guess: Guess, outputs: [f64; N_UNIT], dforce: [f64; N_IN]) {
        self.committed_path = path;
        self.guess = guess;
        self.outputs = outputs;
        self.dforce = dforce;
    }

    /// The unit's outputs at the solved muscle state `u` on path `path`
    /// (MODEL_NOTES "Musculotendon unit"), and dF_T/d(command, path) from
    /// the end stretch's partials `dlambda` and the muscle's (`jacobian`,
    /// with respect to the unit's inputs): compliant, F_T = F0 f_T(ε) and
    /// dF_T = k_T (dℓ − (1/cos α) dL_M); rigid, F_T = F_M cos α and
    /// dF_T = dF_M cos α + F_M (d cos α/dL_M) dL_M.
    fn unit_outputs(
        &self,
        unit: &Unit,
        path: f64,
        u: &Uniaxial,
        outputs: &[f64; N_OUT],
        jacobian: &Jacobian,
        dlambda: [f64; N_IN],
    ) -> ([f64; N_UNIT], [f64; N_IN]) {
        let (l0, area) = (self.muscle.l0, self.muscle.area);
        let l_m = u.lambda * l0;
        let pen = unit.pennation.at(l_m);
        let f_m = u.nominal_stress() * area;
        let dpath = [0.0, 1.0];
        let mut dforce = [0.0; N_IN];
        let (strain, force) = if unit.compliant {
            let lt = path - pen.projection;
            let (ft, kt) = unit.tendon.force(lt);
            for c in [IN_ACTIVATION, IN_LENGTH] {
                dforce[c] = kt * (dpath[c] - pen.dprojection * l0 * dlambda[c]);
            }
            (unit.tendon.strain(lt), ft)
        } else {
            for c in [IN_ACTIVATION, IN_LENGTH] {
                dforce[c] =
                    jacobian.dnominal[c] * area * pen.cos + f_m * pen.dcos * l0 * dlambda[c];
            }
            (0.0, f_m * pen.cos)
        };
        let stress = outputs[super::outputs::Output::Stress as usize];
        ([force, stress, l_m, strain, pen.angle], dforce)
    }

    /// The stored outputs and dF_T/d(command, path) recomputed from the
    /// committed state (the path, the muscle's stretch, stress and
    /// partials) and the parameters, as [`Self::unit_outputs`] computed them
    /// at the commit: `Err` names the first that differs. For a restored
    /// state, where nothing else ties them to the muscle. The values are
    /// the same expressions of the same numbers, so they must agree to
    /// rounding (the partials of L_M come back through the muscle's
    /// sensitivities, an ulp or so from the end stretch's).
    pub fn check_committed_outputs(&self) -> Result<(), String> {
        use super::outputs::Output;
        let unit = self.unit();
        let (l0, area) = (self.muscle.l0, self.muscle.area);
        let l_m = self.muscle.lambda * l0;
        let pen = unit.pennation.at(l_m);
        let f_m = self.muscle.outputs[Output::Stress as usize] * area;
        let dl =
            [Input::Activation, Input::Length].map(|i| self.partial(UnitOutput::FibreLength, i));
        let dpath = [0.0, 1.0];
        let (force, strain, dforce) = if self.unit.compliant_tendon {
            let lt = self.committed_path - pen.projection;
            let (ft, kt) = unit.tendon.force(lt);
            let df = [0, 1].map(|c| kt * (dpath[c] - pen.dprojection * dl[c]));
            (ft, unit.tendon.strain(lt), df)
        } else {
            let dn = self.muscle.jacobian.dnominal;
            let df = [0, 1].map(|c| dn[c] * area * pen.cos + f_m * pen.dcos * dl[c]);
            (f_m * pen.cos, 0.0, df)
        };
        let f0 = self.muscle.params.sigma0 * area;
        let close = |a: f64, b: f64, scale: f64, rtol: f64| {
            (a - b).abs() <= rtol * scale.max(a.abs()).max(b.abs())
        };
        let stored = |o: UnitOutput| self.outputs[o as usize];
        let checks = [
            ("force", stored(UnitOutput::Force), force, f0, 1e-12),
            (
                "fibre_length",
                stored(UnitOutput::FibreLength),
                l_m,
                l0,
                1e-14,
            ),
            (
                "pennation",
                stored(UnitOutput::PennationAngle),
                pen.angle,
                1e-12,
                1e-12,
            ),
            (
                "tendon_strain",
                stored(UnitOutput::TendonStrain),
                strain,
                1e-12,
                1e-12,
            ),
            // The stiffness (and the force's activation partial) against the
            // series of tendon and muscle at this state.
            (
                "d force / d activation",
                self.dforce[IN_ACTIVATION],
                dforce[IN_ACTIVATION],
                f0,
                1e-8,
            ),
            (
                "stiffness",
                self.dforce[IN_LENGTH],
                dforce[IN_LENGTH],
                f0 / l0,
                1e-8,
            ),
        ];
        for (name, got, want, scale, rtol) in checks {
            if !close(got, want, scale, rtol) {
                return Err(format!(
                    "output {name} = {got} is not the unit's at the committed state ({want})"
                ));
            }
        }
        Ok(())
    }

    /// How many times the last step evaluated the muscle's piece law
    /// (uniaxial solves, over every piece tried): its substeps for a rigid
    /// tendon without pennation, more where the equilibrium is solved.
    pub fn last_step_evaluations(&self) -> u32 {
        self.evaluations.0
    }

    /// The value of `out` after the last step or initialization; the
    /// stiffness is dF_T/dℓ of the step map that produced it.
    pub fn output(&self, out: UnitOutput) -> f64 {
        match out {
            UnitOutput::Stiffness => self.dforce[IN_LENGTH],
            o => self.outputs[o as usize],
        }
    }

    /// ∂ `out` / ∂ `input` of the step map (consistent tangent, history
    /// fixed) for the force and stiffness-free outputs: the force's from the
    /// unit, the others through the muscle's partials (NaN for the
    /// stiffness, itself a partial).
    pub fn partial(&self, out: UnitOutput, input: Input) -> f64 {
        use super::outputs::Output;
        let c = input as usize;
        match out {
            UnitOutput::Force => self.dforce[c],
            UnitOutput::Stress => self.muscle.partial(Output::Stress, input),
            UnitOutput::FibreLength => {
                // L_M = λ L0 with λ = λ̄f q.
                let s = &self.muscle.jacobian.sens[c];
                let m = &self.muscle;
                (m.q * s.lambda_f + m.outputs[Output::FibreStretch as usize] * s.q) * m.l0
            }
            UnitOutput::TendonStrain | UnitOutput::PennationAngle => {
                let dl = self.partial(UnitOutput::FibreLength, input);
                let pen = self
                    .unit()
                    .pennation
                    .at(self.outputs[UnitOutput::FibreLength as usize]);
                if out == UnitOutput::PennationAngle {
                    // sin α = h / L_M: cos α dα = −(sin α / L_M) dL_M.
                    let l = self.outputs[UnitOutput::FibreLength as usize];
                    -(pen.angle.sin() / l) * dl / pen.cos
                } else if self.unit.compliant_tendon {
                    let dpath = if input == Input::Length { 1.0 } else { 0.0 };
                    (dpath - pen.dprojection * dl) / self.unit.tendon_slack_length
                } else {
                    0.0
                }
            }
            UnitOutput::Stiffness => f64::NAN,
        }
    }
}

/// The muscle's Jacobian with P's partials re-chained for an end stretch
/// that moves with the inputs by `dlambda` (P = τ11/λ:
/// dP = dτ11/λ − τ11 dλ/λ², MODEL_NOTES "The 1D Hill reduction"), so that
/// the muscle's partials are with respect to the unit's inputs.
fn rechain(
    mut jacobian: Jacobian,
    u: &Uniaxial,
    sens: &[Sensitivity; N_IN],
    dlambda: [f64; N_IN],
) -> Jacobian {
    for c in [IN_ACTIVATION, IN_LENGTH] {
        jacobian.dnominal[c] =
            sens[c].tau11 / u.lambda - u.tau11 * dlambda[c] / (u.lambda * u.lambda);
    }
    jacobian
}

#[cfg(test)]
mod tests;
