//! The FE musculotendon unit: the FE muscle in series with a tendon, at a
//! pennation angle, driven by the length of its whole path (MODEL_NOTES
//! "Musculotendon unit"; docs/design/musculotendon.md).
//!
//! Entry points: [`MusculotendonFE::initialize`] (static equilibrium at the
//! initial path length and activation level), [`MusculotendonFE::step`],
//! [`MusculotendonFE::output`] and [`MusculotendonFE::partial`].
//!
//! Each communication step solves the equilibrium
//! F_T(ℓ − L_M cos α) = F_M(L_M) cos α for the fibre length L_M with
//! [`solve_equilibrium`], F_M(L_M) being the axial force after the FE step
//! map from the committed state to end length L_M ([`Committed::step`], its
//! substeps and error control included). The scalar solve costs a few FE
//! solves: its first trial is L_M extrapolated from the last two steps
//! ([`Guess::trial`]: second order in the step), its slope dF_M/dL_M the last step's secant
//! (Newton's slope only: the partials use the consistent tangent); each
//! later trial of a step taken in one piece starts its Newton iteration
//! from the previous trial's solution moved by ∂x/∂L·ΔL ([`warm_step`]),
//! with the tangent it holds: where that iteration would form a tangent
//! (its reused one stale in the soft modes a small correction measures)
//! the trial steps cold instead, which mostly needs none — unless this
//! step's cold trial already had to form one. A cold trial starts from
//! the substep count of the step's last cold trial ([`Committed::step_from`]),
//! so that F_M(L_M) is one map, not a jump between two counts' maps.
//! The partial derivatives are the equilibrium's implicit ones with the FE
//! step map's consistent dF_M/dL_M and dF_M/du
//! ([`Committed::force_derivatives`], formed on first request).
//!
//! Invariants: a step that cannot be completed (no equilibrium in the
//! evaluable range, past the largest pennation angle, or the FE step's own
//! failures) is an error and changes nothing (every method takes `&self`);
//! a rigid tendon without pennation takes the plain FE step at length
//! ℓ − L_TS, bit for bit.

use std::sync::Arc;

use crate::fe::discretization::Discretization;
use crate::fe::muscle::Muscle;
use crate::fe::newton::{Budget, RESIDUAL_TOLERANCE};
use crate::fe::step_map::{
    check_stretch, Committed, LastStep, Outputs, Quantity, StepFailure, StepLevel, Stepped,
};
use crate::fe::tangent::{Increment, Trend};
use crate::law::musculotendon::{
    solve_equilibrium, Equilibrium, EquilibriumError, MuscleForce, StepRates, Tolerance, Unit,
    TRUST,
};
use crate::law::uniaxial::evaluable_stretch_range;
use crate::law::{solve_uniaxial, FibreHistory, FibreRate, Params};

/// Tolerance of the equilibrium's residual F_M cos α − F_T, relative to
/// max(F0, |F_T|) ([`Unit::equilibrium_tolerance`]): ten times the FE
/// solve's own force tolerance ([`crate::fe::newton::RESIDUAL_TOLERANCE`],
/// relative to max(σ0 A, |F_M|)), below which F_M(L_M) is not determined.
pub const EQUILIBRIUM_RTOL: f64 = 1e-9;

/// The force change, in FE force tolerances, over which two trials give
/// Newton's slope dF_M/dL_M (their secant, then uncertain by ~3 %).
const SECANT_RESOLUTION: f64 = 30.0;

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
}

/// Number of [`UnitOutput`] values.
pub const N_UNIT: usize = 5;

/// What the next step's first trial extrapolates from: dL_M/dℓ of the last
/// step (`slope`), the rates of L_M (m/s) and of the path ([`StepRates`]),
/// Newton's slope dF_M/dL_M (`stiffness`, N/m) and the root's offset from
/// the committed L_M (`offset`, m: [`root_offset`]). They change the cost,
/// not the result beyond the equilibrium's tolerance on one substep count
/// (a first trial that needs more substeps than the root puts the step on
/// that count's map: [`Trials`]).
///
/// The rates are those of the roots, not of the committed fibre lengths:
/// a committed L_M lies anywhere within the equilibrium's tolerance of its
/// root, and extrapolating to second order amplifies that scatter about
/// 4.4× (√(3² + 3² + 1)), more than the tolerance the first trial must hit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Guess {
    pub slope: f64,
    pub stiffness: f64,
    pub rates: StepRates,
    pub offset: f64,
}

/// The largest root offset kept, relative to L_M: a Newton correction of
/// a residual within the equilibrium's tolerance is far smaller unless
/// dR/dL_M is nearly 0 (a slack tendon on a slack muscle), where the root
/// is not determined and the committed L_M is as good a start.
const ROOT_OFFSET_MAX: f64 = 1e-6;

/// The Newton correction −R/R_L from the accepted fibre length `fibre`
/// towards the equilibrium's exact root, R the residual F_M cos α − F_T
/// there and R_L = dR/dL_M with Newton's slope; 0 where R_L is not
/// positive or the correction exceeds [`ROOT_OFFSET_MAX`] L_M.
fn root_offset(residual: f64, r_l: f64, fibre: f64) -> f64 {
    let offset = -residual / r_l;
    if r_l > 0.0 && offset.abs() <= ROOT_OFFSET_MAX * fibre {
        offset
    } else {
        0.0
    }
}

impl Guess {
    /// The guess after a step of length `h` that moved L_M by `dfibre` and
    /// the path by `dpath` ([`StepRates::after`]; no rates after a step too short
    /// to give them).
    fn after(&self, h: f64, dfibre: f64, dpath: f64) -> Guess {
        Guess {
            rates: self.rates.after(h, dfibre, dpath).unwrap_or_default(),
            ..*self
        }
    }

    /// The first trial's L_M for a step of length `h` from fibre length
    /// `fibre` that moves the path by `dpath`: L_M's change extrapolated
    /// (its rate linear in time through the last two steps' mean rates),
    /// plus dL_M/dℓ times the path's change beyond the path's own
    /// extrapolation — second order in the step for smooth inputs. The
    /// rates' changes are used only for a step within a factor 2 of the
    /// last (beyond, the rates alone: first order).
    fn trial(&self, h: f64, fibre: f64, dpath: f64) -> f64 {
        let t = &self.rates;
        let near = t.span > 0.0 && (0.5..=2.0).contains(&(h / t.span));
        let change = |rate: f64, accel: f64| t.change(rate, if near { accel } else { 0.0 }, 0.0, h);
        fibre
            + change(t.fibre_rate, t.fibre_accel)
            + self.slope * (dpath - change(t.path_rate, t.path_accel))
    }
}

/// The unit after a step or initialization.
#[derive(Clone, Debug)]
pub struct MusculotendonFE {
    /// The FE muscle, its length L_M.
    pub muscle: Committed,
    /// Its outputs ([`crate::fe::step_map::outputs`]).
    pub muscle_outputs: Outputs,
    /// The path length at the end of the last step.
    pub path: f64,
    pub guess: Guess,
    /// In [`UnitOutput`] order.
    pub outputs: [f64; N_UNIT],
    /// FE Newton iterations (linear solves) of the last step, every trial.
    pub iterations: usize,
    /// FE step maps the last step evaluated (trials).
    pub trials: u32,
    /// Tangents factorised and residuals evaluated by the last step's FE
    /// solves, every trial (not part of the saved state: 0 when restored).
    pub factorizations: usize,
    pub residuals: usize,
}

/// The muscle's geometry and law: what every call needs.
#[derive(Clone, Copy, Debug)]
pub struct Setup<'a> {
    pub params: &'a Params,
    pub l0: f64,
    pub area: f64,
    pub unit: &'a Unit,
}

impl Setup<'_> {
    /// The fibre lengths the law can evaluate.
    fn range(&self) -> (f64, f64) {
        let (lo, hi) = evaluable_stretch_range(self.params);
        (lo * self.l0, hi * self.l0)
    }

    /// The first trial of the initialization's equilibrium at path `path`
    /// and level `activation`: the fibre length where the law in
    /// homogeneous uniaxial stress (the 1D reduction, isometric) balances
    /// the tendon, solved to 1e-6 F0, where that is at L0 or longer; else
    /// (or where the law cannot be solved) the rigid tendon's fibre length.
    /// Lengthened, the clamped FE specimen carries somewhat more than the
    /// uniaxial law, and the law's root, which has the tendon's stretch,
    /// lies 3.5–22× nearer the FE root than the rigid length (unit tests);
    /// shortened, the clamps hold back the lateral bulging the fibres'
    /// shortening needs, the FE's active force falls far below the law's,
    /// and the tendon is nearly slack at the FE root: the rigid length is
    /// nearer there.
    fn first_trial(&self, path: f64, activation: f64) -> f64 {
        let unit = self.unit;
        let rigid = unit
            .pennation
            .fibre_length_of(path - unit.tendon.slack_length)
            .unwrap_or(self.l0)
            .clamp(self.range().0, self.range().1);
        let force = |l: f64| {
            solve_uniaxial(
                self.params,
                l / self.l0,
                activation,
                &FibreHistory::REST,
                FibreRate::Isometric,
                1.0,
            )
            .map(|u| MuscleForce::of_uniaxial(&u, self.area, self.l0))
        };
        solve_equilibrium(
            unit,
            path,
            self.range(),
            rigid,
            Tolerance::Fixed(1e-6 * unit.tendon.f0),
            None,
            force,
        )
        .ok()
        .map(|eq| eq.fibre_length)
        .filter(|&l| l >= self.l0)
        .unwrap_or(rigid)
    }

    /// The equilibrium's tolerance (N) where the tendon carries
    /// `tendon_force` ([`Unit::equilibrium_tolerance`]).
    #[cfg(test)]
    fn tol(&self, tendon_force: f64) -> f64 {
        self.unit
            .equilibrium_tolerance(EQUILIBRIUM_RTOL, tendon_force)
    }
}

/// The message of an equilibrium that failed at path length `path`.
fn unsolvable(e: EquilibriumError<StepFailure>, path: f64) -> StepFailure {
    match e.reason() {
        Ok(reason) => StepFailure::NotConverged {
            length: path,
            reason: format!("path length {path} m: {reason}"),
        },
        Err(error) => error,
    }
}

/// The step of `from` to end length `length` started from `warm`, a
/// solution of the same step (same start, level and rate) at another end
/// length, instead of from the committed state's predictor: the FE step in
/// one piece of one substep ([`Muscle::advance_in`]) with the muscle's
/// predictor record replaced by one increment that makes its prediction
/// warm's positions plus ∂x/∂L·(length − warm's length)
/// ([`crate::fe::newton`], "Predictor"), then the committed record pushed
/// with this step's real increment, as a cold step leaves it, all within
/// `budget` ([`Budget::without_factorizations`]: warm's tangent only).
/// `None` where that does not apply or does not converge (the caller
/// steps cold).
fn warm_step(
    from: &Committed,
    warm: &Committed,
    p: &Params,
    area: f64,
    level: &StepLevel,
    length: f64,
    budget: Budget,
) -> Option<Stepped> {
    let (m0, h) = (&from.muscle, level.h);
    if warm.substepped.is_some() || warm.last.h != Some(h) {
        return None;
    }
    let w = &warm.muscle;
    let da = level.end - level.at(0.0);
    let seed = Trend {
        increments: vec![Increment {
            dx: vec![0.0; w.x.len()],
            dl: 0.0,
            da,
            h,
        }],
        contraction: w.trend.contraction,
    };
    let start = Muscle {
        disc: m0.disc.clone(),
        x: w.x.clone(),
        history: m0.history.clone(),
        length: w.length,
        tangent: w.tangent.clone(),
        trend: seed,
        tolerance: m0.tolerance,
    };
    let adv = start
        .advance_in(p, length, h, &|tau| level.at(tau), 1, budget)
        .ok()?;
    let s = &adv.solution;
    let increment = Increment {
        dx: s.x.iter().zip(&m0.x).map(|(a, b)| a - b).collect(),
        dl: length - m0.length,
        da,
        h,
    };
    let muscle = Muscle {
        trend: m0.trend.push(increment, adv.muscle.trend.contraction),
        ..adv.muscle
    };
    let outputs =
        crate::fe::step_map::outputs(&muscle.disc, area, muscle.length, &s.evaluation, level.end);
    if outputs.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let last = LastStep {
        start: adv.start,
        h: Some(h),
        activation: level.end,
        da_du: level.d_end_du,
    };
    Some(Stepped {
        state: Committed::new(muscle, last, None),
        outputs,
        iterations: adv.iterations,
        factorizations: adv.factorizations,
        residuals: adv.residuals,
    })
}

/// The trial closure's record: the last FE step evaluated (the accepted one
/// when the solve returns), the slope estimate and the work.
struct Trials {
    kept: Option<Stepped>,
    last: Option<(f64, f64)>,
    slope: f64,
    iterations: usize,
    factorizations: usize,
    residuals: usize,
    trials: u32,
    cold_factorised: bool,
    /// The substep count the cold trials start from: the last cold
    /// trial's, so that the step map the equilibrium solves on keeps one
    /// count (a count switching between trials makes F_M(L_M)
    /// discontinuous, and the root search ends in the jump; where it
    /// still does after the count grew, [`MusculotendonFE::step`] solves
    /// again at the grown count).
    substeps: usize,
}

impl Trials {
    fn new(slope: f64) -> Self {
        Trials {
            kept: None,
            last: None,
            slope,
            iterations: 0,
            factorizations: 0,
            residuals: 0,
            trials: 0,
            cold_factorised: false,
            substeps: 1,
        }
    }

    /// The record for a new search of the same step from Newton's slope
    /// `slope` (not a secant that may span the jump): its work and
    /// substep count kept, its trials forgotten.
    fn restart(self, slope: f64) -> Self {
        Trials {
            kept: None,
            last: None,
            slope,
            cold_factorised: false,
            ..self
        }
    }

    /// Record trial `s` at fibre length `l`: its force with Newton's slope,
    /// the secant through the last trial where the force difference is
    /// [`SECANT_RESOLUTION`] times the FE solve's force tolerance or more
    /// (`f0` the force scale).
    fn record(&mut self, l: f64, s: Stepped, f0: f64) -> MuscleForce {
        let f = s.outputs[Quantity::Force as usize];
        if let Some((l1, f1)) = self.last {
            let secant = (f - f1) / (l - l1);
            let noise = RESIDUAL_TOLERANCE * f.abs().max(f0);
            if (f - f1).abs() >= SECANT_RESOLUTION * noise && secant.is_finite() {
                self.slope = secant;
            }
        }
        self.last = Some((l, f));
        self.iterations += s.iterations;
        self.factorizations += s.factorizations;
        self.residuals += s.residuals;
        self.trials += 1;
        self.kept = Some(s);
        MuscleForce {
            force: f,
            stiffness: self.slope,
        }
    }
}

impl MusculotendonFE {
    /// Static equilibrium at path length `path` and activation level
    /// `activation` (MODEL_NOTES "Musculotendon unit": initialization): the
    /// FE muscle's isometric equilibrium ([`Committed::initialize`]) at the
    /// fibre length where it balances the tendon, Newton's slope its
    /// consistent dF/dL. Each trial after the first continues from the
    /// last trial's equilibrium ([`Committed::initialize_near`]; cold where
    /// that does not converge). `da_du` is the level's derivative with
    /// respect to the command.
    pub fn initialize(
        disc: Arc<Discretization>,
        s: &Setup,
        path: f64,
        activation: f64,
        da_du: f64,
    ) -> Result<MusculotendonFE, String> {
        let guess = s.first_trial(path, activation);
        let mut t = Trials::new(0.0);
        solve_equilibrium(
            s.unit,
            path,
            s.range(),
            guess,
            Tolerance::Scaled(EQUILIBRIUM_RTOL),
            Some(TRUST),
            |l| {
                // From the last trial's equilibrium where that converges.
                let near = t.kept.as_ref().and_then(|k| {
                    k.state
                        .initialize_near(s.params, s.area, l, activation, da_du)
                        .ok()
                });
                let st = match near {
                    Some(st) => st,
                    None => {
                        Committed::initialize(disc.clone(), s.params, s.area, l, activation, da_du)
                            .map_err(|reason| StepFailure::NotConverged { length: l, reason })?
                    }
                };
                let (k, _) = st
                    .state
                    .force_derivatives(s.params, s.l0, s.area)
                    .map_err(|reason| StepFailure::NotConverged { length: l, reason })?;
                let force = t.record(l, st, s.unit.tendon.f0).force;
                t.slope = k;
                Ok(MuscleForce {
                    force,
                    stiffness: k,
                })
            },
        )
        .map_err(|e| unsolvable(e, path).to_string())?;
        let st = t.kept.take().expect("the equilibrium evaluates the muscle");
        let mut done = Self::finish(s, path, st, t, Guess::default());
        let (dl, _) = done.fibre_derivatives(s, true)?;
        done.guess.slope = dl;
        Ok(done)
    }

    /// One step of length `level.h` to path length `path`, the activation
    /// level following `level`, with `substep_tolerance` as
    /// [`Committed::step`]'s (module docs). The rigid tendon takes one FE
    /// step at L_M cos α = ℓ − L_TS.
    pub fn step(
        &self,
        s: &Setup,
        level: StepLevel,
        path: f64,
        substep_tolerance: Option<f64>,
    ) -> Result<MusculotendonFE, StepFailure> {
        let h = level.h;
        let g = &self.guess;
        let l_now = self.outputs[UnitOutput::FibreLength as usize];
        let root_now = l_now + g.offset;
        // A guess is only a start: one that overflows (a restored state's
        // guess is any finite numbers) starts from the committed length.
        let predicted = Some(g.trial(h, root_now, path - self.path))
            .filter(|x| x.is_finite())
            .unwrap_or(l_now);
        let mut t = Trials::new(g.stiffness);
        // Solved again from the start, at the grown count, when the search
        // ended in the jump between the maps of two substep counts.
        let eq = loop {
            let first = t.substeps;
            match self.equilibrium(s, &level, path, predicted, substep_tolerance, &mut t) {
                Err(EquilibriumError::Discontinuous { .. }) if t.substeps > first => {
                    t = t.restart(g.stiffness);
                }
                r => break r.map_err(|e| unsolvable(e, path))?,
            }
        };
        debug_assert_eq!(
            eq.fibre_length,
            t.kept.as_ref().map_or(0.0, |k| k.state.muscle.length)
        );
        let st = t.kept.take().expect("the equilibrium evaluates the muscle");
        let l_end = st.state.muscle.length;
        let mut done = Self::finish(s, path, st, t, *g);
        if done.outputs.iter().any(|x| !x.is_finite()) {
            return Err(StepFailure::NonFiniteOutput { length: l_end });
        }
        // dL_M/dℓ of the equilibrium and the root's offset, with Newton's
        // slope: the next guess.
        let pen = s.unit.pennation.at(l_end);
        let (slope, offset) = if s.unit.compliant {
            let f_m = done.muscle_outputs[Quantity::Force as usize];
            let kt = s.unit.tendon.force(path - pen.projection).1;
            let r_l = done.guess.stiffness * pen.cos + f_m * pen.dcos + kt * pen.dprojection;
            let slope = kt / r_l;
            let slope = if slope.is_finite() { slope } else { 0.0 };
            (slope, root_offset(eq.residual, r_l, l_end))
        } else {
            (pen.cos, 0.0)
        };
        let root_end = l_end + offset;
        done.guess = Guess {
            slope,
            offset,
            ..done.guess.after(h, root_end - root_now, path - self.path)
        };
        Ok(done)
    }

    /// The equilibrium of [`Self::step`] from first trial `predicted`, its
    /// trials recorded in `t` (their cold steps from `t.substeps` substeps).
    fn equilibrium(
        &self,
        s: &Setup,
        level: &StepLevel,
        path: f64,
        predicted: f64,
        substep_tolerance: Option<f64>,
        t: &mut Trials,
    ) -> Result<Equilibrium, EquilibriumError<StepFailure>> {
        solve_equilibrium(
            s.unit,
            path,
            s.range(),
            predicted,
            Tolerance::Scaled(EQUILIBRIUM_RTOL),
            Some(TRUST),
            |l| {
                check_stretch(s.params, s.l0, l)
                    .map_err(|reason| StepFailure::NotConverged { length: l, reason })?;
                // Warm starts skip the error control: only without it.
                let disc = &self.muscle.muscle.disc;
                let budget = if t.cold_factorised {
                    Budget::for_step(disc)
                } else {
                    Budget::without_factorizations(disc)
                };
                let warm = t
                    .kept
                    .as_ref()
                    .filter(|_| substep_tolerance.is_none())
                    .and_then(|w| {
                        warm_step(&self.muscle, &w.state, s.params, s.area, level, l, budget)
                    });
                let st = match warm {
                    Some(st) => st,
                    None => {
                        let st = self.muscle.step_from(
                            s.params,
                            s.area,
                            *level,
                            l,
                            substep_tolerance,
                            t.substeps,
                        )?;
                        t.cold_factorised = st.factorizations > 0;
                        if let (None, Some(sub)) = (substep_tolerance, &st.state.substepped) {
                            t.substeps = sub.pieces.iter().map(|&(_, n)| n).max().unwrap_or(1);
                        }
                        st
                    }
                };
                Ok(t.record(l, st, s.unit.tendon.f0))
            },
        )
    }

    /// The unit at the accepted trial `st` on path `path`.
    fn finish(s: &Setup, path: f64, st: Stepped, t: Trials, guess: Guess) -> MusculotendonFE {
        let unit = s.unit;
        let l_m = st.state.muscle.length;
        let pen = unit.pennation.at(l_m);
        let f_m = st.outputs[Quantity::Force as usize];
        let (strain, force) = if unit.compliant {
            let lt = path - pen.projection;
            (unit.tendon.strain(lt), unit.tendon.force(lt).0)
        } else {
            (0.0, f_m * pen.cos)
        };
        let outputs = [
            force,
            st.outputs[Quantity::Stress as usize],
            l_m,
            strain,
            pen.angle,
        ];
        MusculotendonFE {
            muscle: st.state,
            muscle_outputs: st.outputs,
            path,
            guess: Guess {
                stiffness: t.slope,
                ..guess
            },
            outputs,
            iterations: t.iterations,
            trials: t.trials,
            factorizations: t.factorizations,
            residuals: t.residuals,
        }
    }

    /// The value of `out`.
    pub fn output(&self, out: UnitOutput) -> f64 {
        self.outputs[out as usize]
    }

    /// (dL_M/d(input), dF_T/d(input)) of the last step's map, the input the
    /// path length when `by_length`, else the activation command: the
    /// equilibrium's implicit derivatives (MODEL_NOTES "Musculotendon
    /// unit"; [`solve_equilibrium`]) with the FE step map's consistent
    /// k = dF_M/dL_M and dF_M/du ([`Committed::force_derivatives`]).
    /// Compliant, with R_L = k cos α + F_M d cos α/dL_M + k_T/cos α:
    /// dL_M/dℓ = k_T/R_L, dL_M/du = −cos α (dF_M/du)/R_L, and
    /// dF_T = k_T (dℓ − dL_M/cos α). Rigid: dL_M/dℓ = cos α, dL_M/du = 0,
    /// dF_T = (k cos α + F_M d cos α/dL_M) dL_M + cos α dF_M/du du.
    fn fibre_derivatives(&self, s: &Setup, by_length: bool) -> Result<(f64, f64), String> {
        let (k, du) = self.muscle.force_derivatives(s.params, s.l0, s.area)?;
        let l_m = self.outputs[UnitOutput::FibreLength as usize];
        let pen = s.unit.pennation.at(l_m);
        let f_m = self.muscle_outputs[Quantity::Force as usize];
        let k_m = k * pen.cos + f_m * pen.dcos;
        let dpath = if by_length { 1.0 } else { 0.0 };
        let dfu = if by_length { 0.0 } else { du };
        let (dl, df) = if s.unit.compliant {
            let kt = s.unit.tendon.force(self.path - pen.projection).1;
            let r_l = k_m + kt * pen.dprojection;
            if r_l.is_nan() || r_l <= 0.0 {
                return Err(format!(
                    "the equilibrium at fibre length {l_m} m is not regular (dR/dL_M = {r_l:e})"
                ));
            }
            let dl = (kt * dpath - pen.cos * dfu) / r_l;
            (dl, kt * (dpath - pen.dprojection * dl))
        } else {
            let dl = pen.cos * dpath;
            (dl, k_m * dl + pen.cos * dfu)
        };
        Ok((dl, df))
    }

    /// ∂`out`/∂(input) of the last step's map (history fixed), the input the
    /// path length when `by_length`, else the activation command: the
    /// force's and the fibre length's from [`Self::fibre_derivatives`], the
    /// others chained through the fibre length; the stiffness output is
    /// `partial(Force, true)`.
    pub fn partial(&self, s: &Setup, out: UnitOutput, by_length: bool) -> Result<f64, String> {
        let (dl, df) = self.fibre_derivatives(s, by_length)?;
        let l_m = self.outputs[UnitOutput::FibreLength as usize];
        let pen = s.unit.pennation.at(l_m);
        Ok(match out {
            UnitOutput::Force => df,
            UnitOutput::FibreLength => dl,
            UnitOutput::Stress => {
                let (k, du) = self.muscle.force_derivatives(s.params, s.l0, s.area)?;
                (k * dl + if by_length { 0.0 } else { du }) / s.area
            }
            UnitOutput::TendonStrain if s.unit.compliant => {
                let dpath = if by_length { 1.0 } else { 0.0 };
                (dpath - pen.dprojection * dl) / s.unit.tendon.slack_length
            }
            UnitOutput::TendonStrain => 0.0,
            // sin α = h/L_M: cos α dα = −(sin α/L_M) dL_M.
            UnitOutput::PennationAngle => -(pen.angle.sin() / l_m) * dl / pen.cos,
        })
    }
}

#[cfg(test)]
mod tests;
