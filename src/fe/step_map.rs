//! The FE muscle's step map and its sensitivities: one communication step
//! from the committed state to the inputs (the muscle length at the end of
//! the step, the activation level over it, [`StepLevel`]), the outputs of
//! the result ([`Quantity`], [`outputs`]) and their derivatives with
//! respect to the two inputs.
//!
//! Entry points: [`discretization`] (the fusiform specimen, reused when
//! unchanged), [`Committed::initialize`], [`Committed::step`],
//! [`Committed::partial`] (from [`Committed::force_derivatives`],
//! [`Committed::length_derivative`], [`Committed::output_jacobian`]), [`check_stretch`], [`end_length`].
//!
//! Invariants: a step that fails returns [`StepFailure`] and changes
//! nothing. The derivatives are those of the map that produced the
//! committed state: from the converged tangent for a step in one piece, by
//! central differences of the same pieces from the same start for a step
//! in more ([`Substepped`]); computed on first request, then kept.

use std::fmt;
use std::sync::{Arc, OnceLock};

use crate::fe::discretization::{Discretization, Ends, Evaluation, DERIVATIVE_ITERATIONS};
use crate::fe::mesh::{FibreLayout, Grading, Resolution};
use crate::fe::muscle::Muscle;
use crate::fe::newton::Solution;
use crate::law::activation::{level_at, Decay};
use crate::law::uniaxial::evaluable_stretch_range;
use crate::law::{FibreHistory, FibreRate, Params};

crate::outputs::muscle_outputs! {
    /// The FE muscle's outputs, in the fixed order of [`Outputs`]: the
    /// force is the axial reaction on the moved face; the Cauchy stress
    /// force · length / v (v the current volume: by equilibrium, the volume
    /// average of σ_xx); the fibre, CE and SEE stretches and the active
    /// stress are volume averages (reference volumes).
    pub enum Quantity {
        /// Extremes over the elements of the constrained volume ratio
        /// ([`crate::fe::discretization::ElementState::j_assumed`]).
        VolumeRatioMin,
        VolumeRatioMax,
        /// Largest element modified fibre stretch.
        MaxFibreStretch,
    }
}

/// Number of [`Quantity`] values.
pub const N_QUANTITIES: usize = 12;

/// Every [`Quantity`], indexed by `Quantity as usize`.
pub type Outputs = [f64; N_QUANTITIES];

/// ∂(output)/∂(length, command) of every output ([`Quantity`] order).
pub type OutputJacobian = [[f64; 2]; N_QUANTITIES];

/// The outputs of an evaluation `ev` of `d` at muscle length `length` and
/// activation level `activation`, stresses on the section `area`.
pub fn outputs(
    d: &Discretization,
    area: f64,
    length: f64,
    ev: &Evaluation,
    activation: f64,
) -> Outputs {
    let force = d.reaction(&ev.forces);
    let stress = force / area;
    let (mut v, mut lf, mut lm, mut ls, mut ss) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut jmin, mut jmax, mut lfmax) = (f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for (e, ve) in ev.elements.iter().zip(d.element_reference_volumes()) {
        v += ve;
        lf += ve * e.lambda_f;
        lm += ve * e.history.lambda_m;
        ls += ve * e.history.lambda_s;
        ss += ve * e.sigma_see;
        jmin = jmin.min(e.j_assumed);
        jmax = jmax.max(e.j_assumed);
        lfmax = lfmax.max(e.lambda_f);
    }
    let mut o = [0.0; N_QUANTITIES];
    o[Quantity::Force as usize] = force;
    o[Quantity::Stress as usize] = stress;
    o[Quantity::CauchyStress as usize] = force * length / ev.volume;
    o[Quantity::ActivationLevel as usize] = activation;
    o[Quantity::FibreStretch as usize] = lf / v;
    o[Quantity::CeStretch as usize] = lm / v;
    o[Quantity::SeeStretch as usize] = ls / v;
    o[Quantity::ActiveStress as usize] = ss / v;
    o[Quantity::PassiveStress as usize] = stress - ss / v;
    o[Quantity::VolumeRatioMin as usize] = jmin;
    o[Quantity::VolumeRatioMax as usize] = jmax;
    o[Quantity::MaxFibreStretch as usize] = lfmax;
    o
}

/// The fusiform discretization, clamped, for these geometry and mesh
/// parameters (`reuse` when it is that one already).
pub fn discretization(
    reuse: Option<&Arc<Discretization>>,
    l0: f64,
    area: f64,
    resolution: Resolution,
    grading: Grading,
    fibres: FibreLayout,
) -> Result<Arc<Discretization>, String> {
    if let Some(d) = reuse.filter(|d| built_with(d, l0, area, resolution, grading, fibres)) {
        return Ok(d.clone());
    }
    Discretization::fusiform_graded(l0, area, resolution, grading, fibres, Ends::Clamped)
        .map(Arc::new)
}

/// The stability matrix's FE specimen on its 6 × 1 mesh: L0 5 cm, the FE
/// unit scene's area 8.919 cm² (squat), graded as the default mesh — the
/// tests' hard case for stiff, very compressible laws.
#[cfg(test)]
pub(crate) fn squat_specimen() -> Arc<Discretization> {
    discretization(
        None,
        0.05,
        8.919e-4,
        Resolution {
            n_axial: 6,
            n_radial: 1,
        },
        crate::fe::mesh::LUMPED_GRADING,
        FibreLayout::Axial,
    )
    .expect("the squat specimen")
}

/// Whether `d` is the discretization of this geometry, mesh and fibre
/// layout.
pub fn built_with(
    d: &Discretization,
    l0: f64,
    area: f64,
    resolution: Resolution,
    grading: Grading,
    fibres: FibreLayout,
) -> bool {
    d.l0 == l0
        && d.area == area
        && d.mesh.resolution == resolution
        && d.mesh.grading == grading
        && d.fibres == fibres
}

/// The step length of a rate mode (`None`: isometric).
pub fn rate_step(rate: FibreRate) -> Option<f64> {
    match rate {
        FibreRate::Step { h } => Some(h),
        FibreRate::Isometric => None,
    }
}

/// What the last step's tangent was formed with (for the directional
/// derivatives, recomputed on demand from the committed positions).
#[derive(Clone, Debug, PartialEq)]
pub struct LastStep {
    /// Element histories at the start of the last (sub)step.
    pub start: Vec<FibreHistory>,
    /// `None`: isometric (initialization).
    pub h: Option<f64>,
    /// Activation level at its end.
    pub activation: f64,
    /// ∂(level)/∂(command).
    pub da_du: f64,
}

impl LastStep {
    pub fn rate(&self) -> FibreRate {
        match self.h {
            Some(h) => FibreRate::Step { h },
            None => FibreRate::Isometric,
        }
    }
}

/// The activation level over one step of length `h` (MODEL_NOTES
/// "Activation"): from level `a0` under the command `u` with rate `u_dot`,
/// with or without the dynamics ([`level_at`], which the 1D muscle reads
/// too), at its end and at every τ into it (for substeps).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepLevel {
    pub dynamics: bool,
    pub s: f64,
    pub a0: f64,
    pub u: f64,
    pub u_dot: f64,
    pub h: f64,
    /// The level at the end of the step and ∂(it)/∂u.
    pub end: f64,
    pub d_end_du: f64,
}

impl StepLevel {
    /// `decay` = e^(−S h) ([`Decay`]).
    pub fn new(
        dynamics: bool,
        s: f64,
        a0: f64,
        u: f64,
        u_dot: f64,
        h: f64,
        decay: f64,
    ) -> StepLevel {
        let (end, d_end_du) = level_at(dynamics, a0, u, u_dot, s, h, decay);
        StepLevel {
            dynamics,
            s,
            a0,
            u,
            u_dot,
            h,
            end,
            d_end_du,
        }
    }

    /// The level at τ ∈ [0, h] into the step.
    pub fn at(&self, tau: f64) -> f64 {
        if tau >= self.h {
            return self.end;
        }
        let decay = if self.dynamics {
            (-self.s * tau).exp()
        } else {
            1.0 // unused without the dynamics
        };
        level_at(
            self.dynamics,
            self.a0,
            self.u,
            self.u_dot,
            self.s,
            tau,
            decay,
        )
        .0
    }
}

/// A step that needed substeps (its Newton iteration did not converge in
/// one, or its error was controlled): the muscle it started from and what
/// it was asked. Its directional derivatives are those of the step map —
/// the same pieces from `before` to the inputs — by central differences
/// ([`Committed::output_jacobian`]): the converged tangent of the last
/// substep alone holds that substep's start history fixed, which depends
/// on the step's inputs as well.
#[derive(Clone, Debug)]
pub struct Substepped {
    pub before: Muscle,
    pub level: StepLevel,
    pub end_length: f64,
    /// Its pieces ([`crate::fe::muscle::Advance::pieces`]).
    pub pieces: Vec<(f64, usize)>,
}

/// Relative step of the central differences of a substepped step's map:
/// of L0 for the length, absolute for the command (one-sided at the ends
/// of [0, 1]). With the solver's tolerance of 1e-10 of the force scale
/// ([`crate::fe::newton::RESIDUAL_TOLERANCE`]) the rounding part of the
/// difference is ~1e-10/1e-5 = 1e-5 of the derivative, its truncation part
/// O(1e-10) relative.
pub const STEP_MAP_DIFFERENCE: f64 = 1e-5;

/// Step along the equilibrium's sensitivities (of L0 for the length,
/// absolute for the level) of the central differences that give the
/// outputs' derivatives of a step in one piece
/// ([`Committed::output_jacobian`]): the outputs are evaluated, not
/// solved for, at x ± ε ∂x/∂(L, a), so the difference has no solver
/// tolerance in it, only the rounding of outputs of order 1 (~1e-16/ε) and
/// a truncation of O(ε²).
pub const OUTPUT_DIRECTION_STEP: f64 = 1e-6;

/// An [`OutputJacobian`] from differences: the length column
/// (outputs longer − shorter) / span, the command column
/// (outputs more − less) / span · `da_du` (the level's derivative with
/// respect to the command where the differences were taken in the level).
fn difference_columns(
    length: (&Outputs, &Outputs, f64),
    command: (&Outputs, &Outputs, f64),
    da_du: f64,
) -> OutputJacobian {
    let ((longer, shorter, dl), (more, less, du)) = (length, command);
    std::array::from_fn(|o| {
        [
            (longer[o] - shorter[o]) / dl,
            (more[o] - less[o]) / du * da_du,
        ]
    })
}

/// (dF/dL, dF/da) at a committed state.
type ForceDerivatives = (f64, f64);

/// Why a step was refused (the committed state unchanged).
#[derive(Clone, Debug, PartialEq)]
pub enum StepFailure {
    /// No sequence of substeps converged to `length`.
    NotConverged { length: f64, reason: String },
    /// The converged state has a non-finite output.
    NonFiniteOutput { length: f64 },
}

impl fmt::Display for StepFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StepFailure::NotConverged { length, reason } => {
                write!(f, "length = {length} m: {reason}")
            }
            StepFailure::NonFiniteOutput { length } => {
                write!(f, "non-finite output at length {length} m")
            }
        }
    }
}

/// The muscle's committed state with what its derivatives need: the last
/// step's start and level, the step map when it took substeps, and the
/// derivatives once computed.
#[derive(Clone, Debug)]
pub struct Committed {
    pub muscle: Muscle,
    pub last: LastStep,
    /// The last step, when it took substeps ([`Substepped`]).
    pub substepped: Option<Substepped>,
    /// (dF/dL, dF/du) at the committed state (u the activation command).
    derivatives: OnceLock<Result<(f64, f64), String>>,
    /// dF/dL alone, when it was asked before dF/du
    /// ([`Self::length_derivative`]).
    length_derivative: OnceLock<Result<f64, String>>,
    /// [`Self::output_jacobian`].
    output_derivatives: OnceLock<Result<OutputJacobian, String>>,
}

/// A committed state with its outputs and the Newton iterations that led
/// to it, with the tangents factorised and the residuals evaluated on the
/// way (the solver's counts, [`crate::fe::newton::Solution`]).
#[derive(Clone, Debug)]
pub struct Stepped {
    pub state: Committed,
    pub outputs: Outputs,
    pub iterations: usize,
    pub factorizations: usize,
    pub residuals: usize,
}

impl Committed {
    /// The state (its derivatives not computed yet).
    pub fn new(muscle: Muscle, last: LastStep, substepped: Option<Substepped>) -> Committed {
        Committed {
            muscle,
            last,
            substepped,
            derivatives: OnceLock::new(),
            length_derivative: OnceLock::new(),
            output_derivatives: OnceLock::new(),
        }
    }

    /// The isometric equilibrium at `length` and activation level
    /// `activation` ([`Muscle::isometric`]), `da_du` the level's derivative
    /// with respect to the command; the iterations are the whole
    /// initialization's.
    pub fn initialize(
        disc: Arc<Discretization>,
        p: &Params,
        area: f64,
        length: f64,
        activation: f64,
        da_du: f64,
    ) -> Result<Stepped, String> {
        let (muscle, s) = Muscle::isometric(disc, p, length, activation)?;
        Ok(Self::isometric_state(area, muscle, s, activation, da_du))
    }

    /// [`Self::initialize`] from `self`, an isometric equilibrium at the same
    /// level at another length ([`Muscle::isometric_near`]): the iterations
    /// are this continuation's.
    pub fn initialize_near(
        &self,
        p: &Params,
        area: f64,
        length: f64,
        activation: f64,
        da_du: f64,
    ) -> Result<Stepped, String> {
        let (muscle, s) = self.muscle.isometric_near(p, length, activation)?;
        Ok(Self::isometric_state(area, muscle, s, activation, da_du))
    }

    /// The initial state at isometric equilibrium `muscle` (solution `s`).
    fn isometric_state(
        area: f64,
        muscle: Muscle,
        s: Solution,
        activation: f64,
        da_du: f64,
    ) -> Stepped {
        let n = muscle.disc.n_elements();
        let last = LastStep {
            start: vec![FibreHistory::REST; n],
            h: None,
            activation,
            da_du,
        };
        let outputs = outputs(&muscle.disc, area, muscle.length, &s.evaluation, activation);
        Stepped {
            state: Committed::new(muscle, last, None),
            outputs,
            iterations: s.iterations,
            factorizations: s.factorizations,
            residuals: s.residuals,
        }
    }

    /// One step of length `level.h` to muscle length `end_length`, the
    /// activation level following `level`: [`Muscle::advance`], or with
    /// `substep_tolerance` (a fraction of σ0) [`Muscle::advance_controlled`]
    /// from the CE rates of the last step.
    pub fn step(
        &self,
        p: &Params,
        area: f64,
        level: StepLevel,
        end_length: f64,
        substep_tolerance: Option<f64>,
    ) -> Result<Stepped, StepFailure> {
        self.step_from(p, area, level, end_length, substep_tolerance, 1)
    }

    /// [`Self::step`] whose uncontrolled step tries `first` substeps
    /// first ([`Muscle::advance_from`]).
    pub fn step_from(
        &self,
        p: &Params,
        area: f64,
        level: StepLevel,
        end_length: f64,
        substep_tolerance: Option<f64>,
        first: usize,
    ) -> Result<Stepped, StepFailure> {
        let (muscle, h) = (&self.muscle, level.h);
        let activation = |tau| level.at(tau);
        let adv = match substep_tolerance {
            Some(fraction) => {
                let rates = muscle.ce_rates(&self.last.start, self.last.h);
                let tolerance = fraction * p.sigma0;
                muscle.advance_controlled(p, end_length, h, &activation, tolerance, &rates)
            }
            None => muscle.advance_from(p, end_length, h, &activation, first),
        }
        .map_err(|reason| StepFailure::NotConverged {
            length: end_length,
            reason,
        })?;
        let substepped = (adv.substeps > 1).then(|| Substepped {
            before: muscle.clone(),
            level,
            end_length,
            pieces: adv.pieces.clone(),
        });
        let last = LastStep {
            start: adv.start,
            h: rate_step(adv.rate),
            activation: level.end,
            da_du: level.d_end_du,
        };
        let m = &adv.muscle;
        let outputs = outputs(&m.disc, area, m.length, &adv.solution.evaluation, level.end);
        if outputs.iter().any(|x| !x.is_finite()) {
            return Err(StepFailure::NonFiniteOutput { length: end_length });
        }
        Ok(Stepped {
            state: Committed::new(adv.muscle, last, substepped),
            outputs,
            iterations: adv.iterations,
            factorizations: adv.factorizations,
            residuals: adv.residuals,
        })
    }

    /// ∂`out`/∂(input) of the last step's map, the input the length when
    /// `by_length`, else the activation command: `ActivationLevel`'s
    /// exactly (∂a/∂u; 0 by the length), `Force` and `Stress` from
    /// [`Self::length_derivative`] by the length and
    /// [`Self::force_derivatives`] by the command, the others from
    /// [`Self::output_jacobian`]. `l0` scales the length differences,
    /// `area` the stresses.
    pub fn partial(
        &self,
        out: Quantity,
        by_length: bool,
        p: &Params,
        l0: f64,
        area: f64,
    ) -> Result<f64, String> {
        match out {
            Quantity::ActivationLevel => Ok(if by_length { 0.0 } else { self.last.da_du }),
            Quantity::Force | Quantity::Stress => {
                let d = if by_length {
                    self.length_derivative(p, l0, area)?
                } else {
                    self.force_derivatives(p, l0, area)?.1
                };
                Ok(if out == Quantity::Force { d } else { d / area })
            }
            _ => Ok(self.output_jacobian(p, l0, area)?[out as usize][usize::from(!by_length)]),
        }
    }

    /// (dF/dL, dF/du) of the last step's map at the committed state (u the
    /// activation command): for a step in one piece from the exact tangent
    /// at the committed state ([`Self::tangent_derivatives`]; dF/du =
    /// dF/da · ∂a/∂u), for a step that took substeps by central
    /// differences of its map ([`Self::output_jacobian`]). `l0` scales the
    /// length differences, `area` the stresses.
    pub fn force_derivatives(&self, p: &Params, l0: f64, area: f64) -> Result<(f64, f64), String> {
        self.derivatives
            .get_or_init(|| {
                if self.substepped.is_some() {
                    // The step map's differences give every output at once:
                    // kept for the other outputs' derivatives.
                    let jacobian = self.output_jacobian(p, l0, area)?;
                    let force = jacobian[Quantity::Force as usize];
                    return Ok((force[0], force[1]));
                }
                let ((dl, da), _) = self.tangent_derivatives(p, DERIVATIVE_ITERATIONS)?;
                Ok((dl, da * self.last.da_du))
            })
            .clone()
    }

    /// dF/dL of [`Self::force_derivatives`] without dF/du when that has
    /// not been computed (a coupled master asks for the stiffness alone):
    /// for a step in one piece after a step, the length's solve of
    /// [`Self::tangent_derivatives`] only — the same dF/dL whenever its
    /// activation solve would converge too; else the tangent's
    /// factorisation, as there; a substepped step's from its step map.
    pub fn length_derivative(&self, p: &Params, l0: f64, area: f64) -> Result<f64, String> {
        if let Some(d) = self.derivatives.get() {
            return d.clone().map(|d| d.0);
        }
        self.length_derivative
            .get_or_init(|| {
                if self.substepped.is_some() {
                    return Ok(self.force_derivatives(p, l0, area)?.0);
                }
                let (m, last) = (&self.muscle, &self.last);
                let ev =
                    m.disc
                        .evaluate(p, &m.x, last.activation, &last.start, last.rate(), true)?;
                let factor = match (&m.tangent, last.h) {
                    (Some(cache), Some(_)) => cache.tangent(&m.disc, p).ok().map(|t| &t.factor),
                    _ => None,
                };
                if let Some(factor) = factor {
                    let cap = DERIVATIVE_ITERATIONS;
                    if let Some(d) = m.disc.length_derivative_preconditioned(&ev, factor, cap)? {
                        return Ok(d);
                    }
                }
                Ok(m.disc.force_derivatives(&ev)?.0)
            })
            .clone()
    }

    /// (dF/dL, dF/da) from the exact tangent at the committed state, and
    /// the iterations of its two conjugate-gradient solves (`None`: it was
    /// factorised). After a step, the solves are preconditioned with the
    /// step's latest Newton factor (the muscle's tangent cache, formed from
    /// its anchor when a restored state has not formed it yet, to the same
    /// bits) when it is a Cholesky factor, at most `cap` iterations each
    /// ([`Discretization::force_derivatives_preconditioned`], to ≤ 1e-9
    /// relative of the factorisation's result). Otherwise — no factor, an
    /// indefinite one, CG not converging, or an initialization, whose
    /// derivatives the musculotendon unit's equilibrium and predictor take
    /// as Newton's slope — the tangent's own factorisation
    /// ([`Discretization::force_derivatives`]).
    pub(crate) fn tangent_derivatives(
        &self,
        p: &Params,
        cap: usize,
    ) -> Result<(ForceDerivatives, Option<[usize; 2]>), String> {
        let (m, last) = (&self.muscle, &self.last);
        let ev = m
            .disc
            .evaluate(p, &m.x, last.activation, &last.start, last.rate(), true)?;
        let factor = match (&m.tangent, last.h) {
            (Some(cache), Some(_)) => cache.tangent(&m.disc, p).ok().map(|t| &t.factor),
            _ => None,
        };
        if let Some(factor) = factor {
            if let Some(d) = m.disc.force_derivatives_preconditioned(&ev, factor, cap)? {
                return Ok(((d.length, d.activation), Some(d.iterations)));
            }
        }
        Ok((m.disc.force_derivatives(&ev)?, None))
    }

    /// ∂(output)/∂(length, command) of the last step's map for every
    /// output, on first request. A step in one piece: the equilibrium's
    /// sensitivities ∂x/∂L, ∂x/∂a from the converged tangent (one
    /// factorisation, two solves, [`Discretization::sensitivities`]), and
    /// the outputs evaluated at x ± ε ∂x/∂L (length L ± ε) and
    /// x ± ε ∂x/∂a (level a ± ε, one-sided at the ends of [0, 1]) with the
    /// step's start history ([`OUTPUT_DIRECTION_STEP`]); ∂/∂u = ∂/∂a ·
    /// ∂a/∂u. A substepped step: [`Self::step_map_jacobian`]. The
    /// extremes over the elements (`VolumeRatioMin`/`Max`,
    /// `MaxFibreStretch`) have the derivative of the element that is
    /// extreme, where that does not change within ±ε.
    pub fn output_jacobian(
        &self,
        p: &Params,
        l0: f64,
        area: f64,
    ) -> Result<OutputJacobian, String> {
        self.output_derivatives
            .get_or_init(|| match &self.substepped {
                Some(step) => {
                    step_map_jacobian(step, p, l0, area, || self.piece_jacobian(p, l0, area))
                }
                None => self.piece_jacobian(p, l0, area),
            })
            .clone()
    }

    /// The one-piece part of [`Self::output_jacobian`]: the outputs along
    /// the equilibrium's sensitivities from the converged tangent, the
    /// last (sub)step's start history held fixed.
    fn piece_jacobian(&self, p: &Params, l0: f64, area: f64) -> Result<OutputJacobian, String> {
        let (m, last) = (&self.muscle, &self.last);
        let a = last.activation;
        let ev = m
            .disc
            .evaluate(p, &m.x, a, &last.start, last.rate(), true)?;
        let factor = m
            .disc
            .pattern
            .factorize(ev.tangent.as_ref().ok_or("no tangent")?)?;
        let (dx_dl, dx_da, _) = m.disc.sensitivities(&ev, &factor);
        let at = |dx: &[f64], e: f64, dl: f64, da: f64| -> Result<Outputs, String> {
            let x: Vec<f64> = m.x.iter().zip(dx).map(|(x, d)| x + e * d).collect();
            let ev = m
                .disc
                .evaluate(p, &x, a + da, &last.start, last.rate(), false)?;
            Ok(outputs(&m.disc, area, m.length + dl, &ev, a + da))
        };
        let el = OUTPUT_DIRECTION_STEP * l0;
        let (longer, shorter) = (at(&dx_dl, el, el, 0.0)?, at(&dx_dl, -el, -el, 0.0)?);
        let (up, down) = (
            OUTPUT_DIRECTION_STEP.min(1.0 - a),
            OUTPUT_DIRECTION_STEP.min(a),
        );
        let (more, less) = (at(&dx_da, up, 0.0, up)?, at(&dx_da, -down, 0.0, -down)?);
        Ok(difference_columns(
            (&longer, &shorter, 2.0 * el),
            (&more, &less, up + down),
            last.da_du,
        ))
    }
}

/// `length` over the rest length `l0` within the stretches the law can
/// evaluate ([`evaluable_stretch_range`]), else the message naming both.
pub fn check_stretch(p: &Params, l0: f64, length: f64) -> Result<(), String> {
    let (lo, hi) = evaluable_stretch_range(p);
    let lambda = length / l0;
    if (lo..=hi).contains(&lambda) {
        Ok(())
    } else {
        Err(format!(
            "length = {length} m with L0 = {l0} m (stretch {lambda}) is outside the range the law can evaluate, [{lo:.4}, {hi:.4}]"
        ))
    }
}

/// The length at the end of a step of `h` from `length` moving at `rate`
/// (docs/reference/conventions.md, "Inputs hold over the step"): finite,
/// positive and evaluable ([`check_stretch`] with the rest length `l0`),
/// else the message saying which.
pub fn end_length(length: f64, rate: f64, h: f64, p: &Params, l0: f64) -> Result<f64, String> {
    let end = length + h * rate;
    if !(end.is_finite() && end > 0.0) {
        return Err(format!(
            "length at the end of the step, length + h * der(length) = {end}, must be finite and > 0"
        ));
    }
    check_stretch(p, l0, end)?;
    Ok(end)
}

/// One input's column of [`step_map_jacobian`], the outputs at input
/// x₊ = `xs.0` and x₋ = `xs.1` about x = `xs.2`: (y₊ − y₋)/(x₊ − x₋), or
/// one-sided against the outputs at x (`centre`) where one side failed,
/// `None` where both did or the side left is x itself.
fn difference_column(
    plus: Result<Outputs, String>,
    minus: Result<Outputs, String>,
    xs: (f64, f64, f64),
    centre: impl Fn() -> Result<Outputs, String>,
) -> Result<Option<Outputs>, String> {
    let (x_plus, x_minus, x) = xs;
    let d = |a: &Outputs, b: &Outputs, h: f64| -> Outputs {
        std::array::from_fn(|o| (a[o] - b[o]) / h)
    };
    Ok(match (plus, minus) {
        (Ok(a), Ok(b)) => Some(d(&a, &b, x_plus - x_minus)),
        (Ok(a), Err(_)) if x_plus != x => Some(d(&a, &centre()?, x_plus - x)),
        (Err(_), Ok(b)) if x != x_minus => Some(d(&centre()?, &b, x - x_minus)),
        // Both failed, or the side left is the centre itself (the command
        // at an end of [0, 1]).
        _ => None,
    })
}

/// The outputs' derivatives of a substepped step's map by central
/// differences ([`STEP_MAP_DIFFERENCE`]), each difference the step taken
/// again from the muscle before it in the same pieces. Where the pieces do
/// not converge on one side of an input (a step at the edge of what its
/// Newton iteration takes), that input's column is the one-sided
/// difference from the step re-run at its own inputs; where they converge
/// on neither side, the column of `last_piece` (the last substep's map,
/// its start history fixed: [`Committed::piece_jacobian`]), so that a
/// converged step always has a derivative.
fn step_map_jacobian(
    step: &Substepped,
    p: &Params,
    l0: f64,
    area: f64,
    last_piece: impl Fn() -> Result<OutputJacobian, String>,
) -> Result<OutputJacobian, String> {
    let l = step.level;
    let decay = Decay::new(l.s, l.h).value;
    let outputs_at = |length: f64, command: f64| -> Result<Outputs, String> {
        let level = StepLevel::new(l.dynamics, l.s, l.a0, command, l.u_dot, l.h, decay);
        let adv = step
            .before
            .advance_pieces(p, length, l.h, &|tau| level.at(tau), &step.pieces)?;
        let m = &adv.muscle;
        Ok(outputs(
            &m.disc,
            area,
            m.length,
            &adv.solution.evaluation,
            level.end,
        ))
    };
    let (length, u) = (step.end_length, step.level.u);
    let dl = STEP_MAP_DIFFERENCE * l0;
    let (lo, hi) = (
        (u - STEP_MAP_DIFFERENCE).max(0.0),
        (u + STEP_MAP_DIFFERENCE).min(1.0),
    );
    let centre = OnceLock::new();
    let centre = || centre.get_or_init(|| outputs_at(length, u)).clone();
    let by_length = difference_column(
        outputs_at(length + dl, u),
        outputs_at(length - dl, u),
        (length + dl, length - dl, length),
        centre,
    )?;
    let by_command = difference_column(
        outputs_at(length, hi),
        outputs_at(length, lo),
        (hi, lo, u),
        centre,
    )?;
    let piece = OnceLock::new();
    let from_piece = |k: usize| -> Result<Outputs, String> {
        let j = piece.get_or_init(&last_piece).clone()?;
        Ok(std::array::from_fn(|o| j[o][k]))
    };
    let by_length = match by_length {
        Some(c) => c,
        None => from_piece(0)?,
    };
    let by_command = match by_command {
        Some(c) => c,
        None => from_piece(1)?,
    };
    Ok(std::array::from_fn(|o| [by_length[o], by_command[o]]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A side of a difference that fails gives the one-sided difference
    /// against the centre; both failing give no column; both present the
    /// central one (the centre not asked).
    #[test]
    fn a_failed_side_of_a_difference_falls_back_to_one_side() {
        let y = |v: f64| -> Result<Outputs, String> { Ok([v; N_QUANTITIES]) };
        let fail = || -> Result<Outputs, String> { Err("no convergence".into()) };
        let xs = (1.1, 0.9, 1.0);
        let central = difference_column(y(5.0), y(1.0), xs, || panic!("centre asked")).unwrap();
        assert!(central.unwrap().iter().all(|d| (d - 20.0).abs() < 1e-9));
        let plus_only = difference_column(y(5.0), fail(), xs, || y(2.0)).unwrap();
        assert!(plus_only.unwrap().iter().all(|d| (d - 30.0).abs() < 1e-9));
        let minus_only = difference_column(fail(), y(1.0), xs, || y(2.0)).unwrap();
        assert!(minus_only.unwrap().iter().all(|d| (d - 10.0).abs() < 1e-9));
        assert!(difference_column(fail(), fail(), xs, || y(2.0))
            .unwrap()
            .is_none());
        // At an end of the command's range the side left is the centre:
        // no one-sided difference (it would divide by zero).
        let at_end = (1.0, 0.9, 1.0);
        assert!(difference_column(y(5.0), fail(), at_end, || y(5.0))
            .unwrap()
            .is_none());
        let at_start = (0.1, 0.0, 0.0);
        assert!(difference_column(fail(), y(1.0), at_start, || y(1.0))
            .unwrap()
            .is_none());
        // A centre that cannot be re-run is the error it gives.
        assert!(difference_column(y(5.0), fail(), xs, fail).is_err());
    }
    use crate::fe::mesh::{LUMPED, LUMPED_GRADING};
    use crate::fe::tangent::TangentCache;
    use crate::specimen::{LENGTH as L0, MEAN_AREA};

    /// The default mesh (its Newton factors in single precision when
    /// `single`, else f64), the passive equilibrium at L0, then `steps`
    /// steps of 10 ms stretching 0.5 % each under the command `command`
    /// (activation dynamics on).
    fn stepped(command: f64, steps: usize, single: bool) -> Committed {
        let p = Params::default();
        let mut d = Discretization::fusiform_graded(
            L0,
            MEAN_AREA,
            LUMPED,
            LUMPED_GRADING,
            FibreLayout::Axial,
            Ends::Clamped,
        )
        .unwrap();
        d.pattern.set_single_precision(single);
        let mut state = Committed::initialize(Arc::new(d), &p, MEAN_AREA, L0, 0.0, 0.0)
            .unwrap()
            .state;
        let h = 10e-3;
        let decay = Decay::new(p.s, h).value;
        for k in 1..=steps {
            let level = StepLevel::new(true, p.s, state.last.activation, command, 0.0, h, decay);
            let length = L0 * (1.0 + 0.005 * k as f64);
            state = state
                .step(&p, MEAN_AREA, level, length, None)
                .unwrap()
                .state;
        }
        assert!(state.substepped.is_none());
        state
    }

    /// (dF/dL, dF/da) of `s` by the factorisation of its exact tangent.
    fn factorised(s: &Committed, p: &Params) -> (f64, f64) {
        let (m, last) = (&s.muscle, &s.last);
        let ev = m
            .disc
            .evaluate(p, &m.x, last.activation, &last.start, last.rate(), true)
            .unwrap();
        m.disc.force_derivatives(&ev).unwrap()
    }

    /// On the default mesh after passive and activating 10 ms steps, with
    /// Newton's factor in single and in double precision, the derivatives
    /// by conjugate gradients preconditioned with the step's factor are
    /// the factorisation's to 1e-9 relative.
    #[test]
    fn the_preconditioned_derivatives_are_the_factorisations() {
        let p = Params::default();
        for single in [true, false] {
            for command in [0.0, 0.5] {
                let s = stepped(command, 3, single);
                let ((dl, da), iterations) =
                    s.tangent_derivatives(&p, DERIVATIVE_ITERATIONS).unwrap();
                let (el, ea) = factorised(&s, &p);
                let kind = s
                    .muscle
                    .tangent
                    .as_ref()
                    .unwrap()
                    .tangent(&s.muscle.disc, &p);
                println!(
                    "level {:.3}, {:?}: iterations {iterations:?}, dF/dL {dl} vs {el} ({:e}), dF/da {da} vs {ea} ({:e})",
                    s.last.activation,
                    kind.unwrap().factor.kind(),
                    (dl - el) / el,
                    (da - ea) / ea
                );
                assert!(iterations.is_some(), "the step's factor preconditions");
                assert!(((dl - el) / el).abs() <= 1e-9, "dF/dL {dl} vs {el}");
                assert!(((da - ea) / ea).abs() <= 1e-9, "dF/da {da} vs {ea}");
                assert!(command == 0.0 || s.last.activation > 0.1);
            }
        }
    }

    /// The factorisation is taken, to its bits, when conjugate gradients
    /// hit their cap (1 here), without a factor, and at an
    /// initialization; a state whose factor is not formed yet (as a
    /// restored one) forms it from its anchor, to the same bits.
    #[test]
    fn the_derivatives_fall_back_to_the_factorisation() {
        let p = Params::default();
        let s = stepped(0.5, 2, true);
        let exact = factorised(&s, &p);
        let bits = |d: (f64, f64)| (d.0.to_bits(), d.1.to_bits());
        let (d, iterations) = s.tangent_derivatives(&p, 1).unwrap();
        assert_eq!((bits(d), iterations), (bits(exact), None));
        let with = |tangent| {
            Committed::new(
                Muscle {
                    tangent,
                    ..s.muscle.clone()
                },
                s.last.clone(),
                None,
            )
        };
        let (d, iterations) = with(None)
            .tangent_derivatives(&p, DERIVATIVE_ITERATIONS)
            .unwrap();
        assert_eq!((bits(d), iterations), (bits(exact), None));
        let built = s.tangent_derivatives(&p, DERIVATIVE_ITERATIONS).unwrap();
        assert!(built.1.is_some());
        let anchor = s.muscle.tangent.as_ref().unwrap().anchor.clone();
        let unformed = with(Some(Arc::new(TangentCache::new(anchor))));
        let again = unformed
            .tangent_derivatives(&p, DERIVATIVE_ITERATIONS)
            .unwrap();
        assert_eq!((bits(again.0), again.1), (bits(built.0), built.1));
        let d = s.muscle.disc.clone();
        let init = Committed::initialize(d, &p, MEAN_AREA, 1.02 * L0, 0.0, 0.0)
            .unwrap()
            .state;
        assert!(init.muscle.tangent.is_some());
        let (d, iterations) = init.tangent_derivatives(&p, DERIVATIVE_ITERATIONS).unwrap();
        assert_eq!((bits(d), iterations), (bits(factorised(&init, &p)), None));
    }

    /// The coupled arm's trace (`benches/data/arm_fe_implicit.csv`,
    /// replayed as `fe_realtime`'s in-process arm) with the derivatives by
    /// conjugate gradients and by the factorisation after every step,
    /// alternately timed: iterations, fallbacks, largest relative
    /// difference, mean times, force and dF/dL at the end (`cargo test
    /// --release --lib arm_derivative_census -- --ignored --nocapture`).
    #[test]
    #[ignore]
    fn arm_derivative_census() {
        use std::time::Instant;
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/benches/data/arm_fe_implicit.csv"
        );
        let text = std::fs::read_to_string(path).unwrap();
        let number = |s: &str| -> f64 { s.trim().parse().unwrap() };
        let (mut h, mut start, mut l0, mut area, mut a) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let mut rows = Vec::new();
        for line in text.lines() {
            if let Some(c) = line.strip_prefix("# ") {
                if let Some(v) = c.strip_prefix("H = ") {
                    h = number(v);
                } else if let Some(v) = c.strip_prefix("initial length = ") {
                    start = number(v);
                } else if let Some((name, v)) = c
                    .strip_prefix("parameter ")
                    .and_then(|v| v.split_once(" = "))
                {
                    match name {
                        "L0" => l0 = number(v),
                        "area" => area = number(v),
                        "initial_activation" => a = number(v),
                        _ => panic!("parameter {name}"),
                    }
                }
            } else if !line.starts_with('t') && !line.is_empty() {
                let v: Vec<f64> = line.split(',').map(number).collect();
                rows.push([v[1], v[2], v[3]]);
            }
        }
        let p = Params::default();
        let d = discretization(None, l0, area, LUMPED, LUMPED_GRADING, FibreLayout::Axial).unwrap();
        let mut state = Committed::initialize(d, &p, area, start, a, 0.0)
            .unwrap()
            .state;
        let decay = Decay::new(p.s, h).value;
        let (mut iterations, mut fallbacks, mut worst) = (Vec::new(), 0, (0.0f64, 0.0f64));
        let mut floor = 0.0f64;
        let (mut t_cg, mut t_exact, mut force) = (0.0, 0.0, 0.0);
        let mut last = ((0.0, 0.0), (0.0, 0.0));
        for (k, [length, rate, command]) in rows.iter().copied().enumerate() {
            let level = StepLevel::new(true, p.s, a, command, 0.0, h, decay);
            let end = end_length(length, rate, h, &p, l0).unwrap();
            let stepped = state.step(&p, area, level, end, None).unwrap();
            force = stepped.outputs[Quantity::Force as usize];
            state = stepped.state;
            a = level.end;
            let mut timed = |cg: bool| {
                let t = Instant::now();
                let r = if cg {
                    state
                        .tangent_derivatives(&p, DERIVATIVE_ITERATIONS)
                        .unwrap()
                } else {
                    (factorised(&state, &p), None)
                };
                let dt = t.elapsed().as_secs_f64();
                if cg {
                    t_cg += dt
                } else {
                    t_exact += dt
                }
                r
            };
            let (exact, (cg, its)) = if k % 2 == 0 {
                let e = timed(false).0;
                (e, timed(true))
            } else {
                let c = timed(true);
                (timed(false).0, c)
            };
            match its {
                Some(i) => iterations.push(i),
                None => fallbacks += 1,
            }
            // The rounding floor: CG preconditioned with the exact tangent's own
            // factor (converged at once) against the factorisation.
            let (m, l) = (&state.muscle, &state.last);
            let ev = m
                .disc
                .evaluate(&p, &m.x, l.activation, &l.start, l.rate(), true)
                .unwrap();
            let own = m
                .disc
                .pattern
                .factorize(ev.tangent.as_ref().unwrap())
                .unwrap();
            if let Some(f) = m
                .disc
                .force_derivatives_preconditioned(&ev, &own, 30)
                .unwrap()
            {
                floor = floor.max(((f.length - exact.0) / exact.0).abs());
            }
            worst.0 = worst.0.max(((cg.0 - exact.0) / exact.0).abs());
            worst.1 = worst.1.max(((cg.1 - exact.1) / exact.1).abs());
            last = (cg, exact);
        }
        let n = rows.len() as f64;
        let mean = |i: usize| {
            iterations.iter().map(|v| v[i] as f64).sum::<f64>() / iterations.len() as f64
        };
        let max = |i: usize| iterations.iter().map(|v| v[i]).max().unwrap_or(0);
        println!(
            "{} steps: CG iterations per call, length {:.2} (max {}), activation {:.2} (max {}); fallbacks {fallbacks}",
            rows.len(),
            mean(0),
            max(0),
            mean(1),
            max(1)
        );
        println!(
            "largest relative difference: dF/dL {:e}, dF/da {:e}; dF/dL with the exact factor as preconditioner {floor:e}",
            worst.0, worst.1
        );
        println!(
            "mean ms per derivative: CG {:.3}, factorisation {:.3} (ratio {:.3})",
            t_cg / n * 1e3,
            t_exact / n * 1e3,
            t_cg / t_exact
        );
        println!(
            "force at the end {force:.14} N; dF/dL CG {:.10}, factorised {:.10}; dF/da CG {:.10}, factorised {:.10}",
            last.0 .0, last.1 .0, last.0 .1, last.1 .1
        );
    }
}
