//! `HillMuscle1D`'s serialized state ([`Hill1DState`], its byte order) and
//! its restore: a decoded state becomes a model only if some call sequence
//! reaches it — every value in its declared range, the scene's constants as
//! compiled in, and the stored outputs and step data exactly those the
//! muscle's committed state gives ([`check_committed`]).

use super::{all_variables, Hill1DModel, SUBSTEP_TOLERANCE_RANGE};
use crate::fmi2::{Model, ModelError};
use crate::fmus::codec::{
    check_output, check_scene_constants, decode_from, encode_onto, wire_struct, MaybeF64,
};
use crate::fmus::common::{check_restored_drive, check_restored_history};
use crate::law::activation::Decay;
use crate::law::{Components, FibreHistory, PARAMETERS};
use crate::muscle1d::{Jacobian, Muscle1D, Output, Predictor, N_OUT};
use crate::scene::Scene;

wire_struct! {
    /// The state's fields in byte order (the format tests/golden_state.rs
    /// pins).
    pub(crate) struct Hill1DState {
        /// The law's parameters, in [`PARAMETERS`] order.
        params: Vec<f64>,
        l0: f64,
        area: f64,
        activation_dynamics: bool,
        initial_activation: f64,
        command: f64,
        /// The length input (none: `L0`).
        length: MaybeF64,
        command_rate: f64,
        length_rate: f64,
        activation_level: f64,
        lambda_s: f64,
        lambda_m: f64,
        lambda: f64,
        q: f64,
        predict_q: [f64; 4],
        predict_lambda_s: [f64; 4],
        /// The step of the cached activation decay (its value follows from S).
        decay_step: MaybeF64,
        outputs: [f64; N_OUT],
        /// [`Jacobian::to_values`].
        jacobian: Vec<f64>,
        ce_rate: f64,
        adaptive_substeps: bool,
        substep_tolerance: f64,
    }
}

const MODEL: &str = "HillMuscle1D";

/// [`Model::serialize`] of the 1D model.
pub(super) fn encode<S: Scene>(m: &Hill1DModel<S>, out: &mut Vec<u8>) {
    encode_onto(&muscle_state(&m.muscle), out);
}

/// The serialized state of the 1D muscle `u` (also the muscle's part of the
/// musculotendon model's state).
pub(crate) fn muscle_state<C: Components>(u: &Muscle1D<C>) -> Hill1DState {
    Hill1DState {
        params: PARAMETERS.iter().map(|i| u.params.get(i.id)).collect(),
        l0: u.l0,
        area: u.area,
        activation_dynamics: u.activation_dynamics,
        initial_activation: u.initial_activation,
        command: u.command,
        length: MaybeF64(u.length),
        command_rate: u.command_rate,
        length_rate: u.length_rate,
        activation_level: u.activation_level,
        lambda_s: u.history.lambda_s,
        lambda_m: u.history.lambda_m,
        lambda: u.lambda,
        q: u.q,
        predict_q: u.predict.q,
        predict_lambda_s: u.predict.lambda_s,
        decay_step: MaybeF64(u.decay.as_ref().map(|d| d.h)),
        outputs: u.outputs,
        jacobian: u.jacobian.to_values(),
        ce_rate: u.ce_rate,
        adaptive_substeps: u.adaptive_substeps,
        substep_tolerance: u.substep_tolerance,
    }
}

/// [`Model::deserialize`] of the 1D model: decode, then
/// [`restore`].
pub(super) fn decode<S: Scene>(input: &mut &[u8]) -> Result<Hill1DModel<S>, ModelError> {
    let state: Hill1DState = decode_from(MODEL, input)?;
    restore(state).map_err(|e| ModelError(format!("{MODEL} state: {e}")))
}

/// The model of a decoded state, if some call sequence reaches it.
fn restore<S: Scene>(s: Hill1DState) -> Result<Hill1DModel<S>, String> {
    let mut m = Hill1DModel::<S>::new();
    restore_muscle(s, &mut m.muscle)?;
    check_scene_constants(&S::SPEC, &all_variables(), &m)?;
    Ok(m)
}

/// The 1D muscle `u` (a new model's) set to the decoded state `s`, if some
/// call sequence reaches it: every value in its range and the stored
/// outputs those of the committed state ([`check_committed`]). The scene's
/// constants are the caller's to check.
pub(crate) fn restore_muscle<C: Components>(
    s: Hill1DState,
    u: &mut Muscle1D<C>,
) -> Result<(), String> {
    let Hill1DState {
        params,
        l0,
        area,
        activation_dynamics,
        initial_activation,
        command,
        length,
        command_rate,
        length_rate,
        activation_level,
        lambda_s,
        lambda_m,
        lambda,
        q,
        predict_q,
        predict_lambda_s,
        decay_step,
        outputs,
        jacobian,
        ce_rate,
        adaptive_substeps,
        substep_tolerance,
    } = s;
    if params.len() != PARAMETERS.len() {
        return Err(format!(
            "{} parameters, expected {}",
            params.len(),
            PARAMETERS.len()
        ));
    }
    for (info, &v) in PARAMETERS.iter().zip(&params) {
        u.params.set(info.id, v).map_err(|e| e.to_string())?;
    }
    u.l0 = l0;
    u.area = area;
    u.activation_dynamics = activation_dynamics;
    u.initial_activation = initial_activation;
    u.command = command;
    u.length = length.0;
    u.command_rate = command_rate;
    u.length_rate = length_rate;
    u.activation_level = activation_level;
    u.history = FibreHistory { lambda_s, lambda_m };
    u.lambda = lambda;
    u.q = q;
    u.predict = Predictor {
        q: predict_q,
        lambda_s: predict_lambda_s,
    };
    u.decay = match decay_step.0 {
        None => None,
        Some(h) if h.is_finite() && h > 0.0 => Some(Decay::new(u.params.s, h)),
        Some(h) => return Err(format!("bad activation decay step {h}")),
    };
    u.outputs = outputs;
    u.jacobian = Jacobian::from_values(&jacobian).ok_or_else(|| {
        format!(
            "{} Jacobian values, expected {}",
            jacobian.len(),
            Jacobian::LEN
        )
    })?;
    u.ce_rate = ce_rate;
    u.adaptive_substeps = adaptive_substeps;
    u.substep_tolerance = substep_tolerance;
    if !SUBSTEP_TOLERANCE_RANGE.contains(substep_tolerance) {
        return Err(format!(
            "substep_tolerance = {substep_tolerance} outside {SUBSTEP_TOLERANCE_RANGE}"
        ));
    }
    let state = [
        command,
        command_rate,
        length_rate,
        activation_level,
        lambda_s,
        lambda_m,
        lambda,
        q,
        ce_rate,
    ];
    if state
        .iter()
        .chain(&predict_q)
        .chain(&predict_lambda_s)
        .chain(&outputs)
        .chain(&jacobian)
        .any(|x| !x.is_finite())
    {
        return Err("a non-finite value".into());
    }
    u.check_setup().map_err(|e| e.0)?;
    check_restored_drive(command, activation_level)
        .and_then(|()| check_restored_history(&[u.history]))
        .map_err(|e| e.0)?;
    if lambda <= 0.0 {
        return Err(format!("stretch {lambda} must be > 0"));
    }
    check_committed(u)?;
    u.refresh_stretch_range();
    Ok(())
}

/// The stored outputs and step data of `u` exactly those its committed state
/// gives (`Muscle1D::evaluate`, MODEL_NOTES "The 1D Hill reduction"): the
/// level, the stretches λ̄f = λ/q, λm and λs as committed; J = q³; the
/// stresses P = τ11/λ, σ11 = τ11/J and P − σ_s from the committed τ11; the
/// length column of d(level). The checks need no parameter (those may have
/// been set since the state was committed, before a new initialization),
/// except the force's: force = P · area with an area in its range, and of
/// the sign of P.
fn check_committed<C: Components>(u: &Muscle1D<C>) -> Result<(), String> {
    let out = |o: Output| u.outputs[o as usize];
    let jac = &u.jacobian;
    let j = u.q * u.q * u.q;
    if jac.j.to_bits() != j.to_bits() {
        return Err(format!(
            "volume ratio {} of the step data is not q^3 = {j} of the committed q",
            jac.j
        ));
    }
    if jac.dlevel[1] != 0.0 || !(0.0..=1.0).contains(&jac.dlevel[0]) {
        return Err(format!(
            "d activation_level / d (activation, length) = {:?}: must be in [0, 1] and 0",
            jac.dlevel
        ));
    }
    let stress = jac.tau11 / u.lambda;
    for (name, o, recomputed) in [
        (
            "activation_level",
            Output::ActivationLevel,
            u.activation_level,
        ),
        ("fibre_stretch", Output::FibreStretch, u.lambda / u.q),
        ("ce_stretch", Output::CeStretch, u.history.lambda_m),
        ("see_stretch", Output::SeeStretch, u.history.lambda_s),
        ("stress", Output::Stress, stress),
        ("cauchy_stress", Output::CauchyStress, jac.tau11 / jac.j),
        (
            "passive_stress",
            Output::PassiveStress,
            stress - out(Output::ActiveStress),
        ),
    ] {
        check_output(name, out(o), recomputed)?;
    }
    let force = out(Output::Force);
    // force / stress rounds: the area may come out an ulp or two outside
    // its range at a bound.
    let area_of_force = force / stress;
    let range = crate::law::params::AREA_RANGE;
    let slack = 1e-12;
    let consistent = if stress == 0.0 {
        force == 0.0
    } else {
        area_of_force >= range.min * (1.0 - slack) && area_of_force <= range.max * (1.0 + slack)
    };
    if !consistent {
        return Err(format!(
            "output force = {force} is not stress {stress} times an area in {range}"
        ));
    }
    Ok(())
}

/// The force exactly the committed nominal stress times the area
/// (`Muscle1D::evaluate`). Only for a stepping instance: before, the area
/// may have been set since the outputs were committed ([`check_committed`]
/// allows any area in its range).
pub(crate) fn check_force<C: Components>(u: &Muscle1D<C>) -> Result<(), String> {
    let (force, stress) = (
        u.outputs[Output::Force as usize],
        u.outputs[Output::Stress as usize],
    );
    let value = stress * u.area;
    if force.to_bits() != value.to_bits() {
        return Err(format!(
            "output force = {force} is not stress {stress} times the area {} ({value})",
            u.area
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::{Hill1D, Var, DEFAULT_L0};
    use super::*;
    use crate::fmus::common::{assert_restore_refuses, restored};
    use crate::scene::shipped::HillActuator1D;

    fn stepped() -> Hill1D {
        let mut m = Hill1D::new();
        m.set_real(Var::Activation, 0.6).unwrap();
        m.set_real(Var::Length, 1.05 * DEFAULT_L0).unwrap();
        m.initialize().unwrap();
        for _ in 0..3 {
            m.do_step(0.0, 1e-3).unwrap();
        }
        m
    }

    /// A restored state is checked as strictly as the calls that produce
    /// its values: an activation command or level outside [0, 1], a
    /// non-positive CE or SEE stretch, a non-positive stretch or a length
    /// outside its range is refused naming it (a crafted state: the
    /// layer's checksum is not a signature), while the unmodified state
    /// round-trips.
    #[test]
    fn a_restored_state_with_unphysical_values_is_refused() {
        let m = stepped();
        let force = Var::Out(Output::Force);
        let back = restored(&m).expect("an unmodified state");
        assert_eq!(back.get_real(force), m.get_real(force));
        assert_restore_refuses(&m, |f| f.muscle.command = 5.0, "activation = 5");
        assert_restore_refuses(&m, |f| f.muscle.command = -3.0, "activation = -3");
        assert_restore_refuses(
            &m,
            |f| f.muscle.activation_level = 4.0,
            "activation level = 4",
        );
        assert_restore_refuses(&m, |f| f.muscle.history.lambda_m = -1.0, "CE stretch -1");
        assert_restore_refuses(&m, |f| f.muscle.history.lambda_s = 0.0, "SEE stretch 0");
        assert_restore_refuses(&m, |f| f.muscle.lambda = -0.5, "stretch -0.5 must be > 0");
        assert_restore_refuses(&m, |f| f.muscle.length = Some(1e3), "length = 1000");
    }

    /// A state whose stored outputs differ from those of its committed state
    /// (the layer's checksum recomputed) is refused naming the output: an
    /// activation level of 5 or −0.5, a CE stretch of −1, a force of 1e30;
    /// so are step data that no step leaves. The unmodified state restores.
    #[test]
    fn stored_outputs_must_be_those_of_the_committed_state() {
        let m = stepped();
        restored(&m).expect("an unmodified state");
        let set = |o: Output, v: f64| move |f: &mut Hill1D| f.muscle.outputs[o as usize] = v;
        let level = Output::ActivationLevel;
        assert_restore_refuses(&m, set(level, 5.0), "output activation_level = 5");
        assert_restore_refuses(&m, set(level, -0.5), "output activation_level = -0.5");
        assert_restore_refuses(&m, set(Output::CeStretch, -1.0), "output ce_stretch = -1");
        assert_restore_refuses(
            &m,
            set(Output::Force, 1e30),
            "output force = 1000000000000000000000000000000",
        );
        let stress = m.muscle.outputs[Output::Stress as usize];
        assert_restore_refuses(&m, set(Output::Stress, stress * 2.0), "output stress");
        assert_restore_refuses(&m, set(Output::ActiveStress, 1.0), "output passive_stress");
        assert_restore_refuses(&m, |f| f.muscle.jacobian.j = 3.0, "volume ratio 3");
        assert_restore_refuses(
            &m,
            |f| f.muscle.jacobian.dlevel[0] = 2.0,
            "d activation_level",
        );
    }

    /// `HillActuator1D` compiles b = 23.46 and S = 50 in: a state with
    /// b = 30 or S = 500 is refused naming the parameter, while its own
    /// state restores.
    #[test]
    fn a_scene_constant_cannot_be_changed_through_a_state() {
        let mut m = Hill1DModel::<HillActuator1D>::new();
        m.set_real(Var::Activation, 1.0).unwrap();
        m.do_step(0.0, 1e-3).unwrap();
        restored(&m).expect("an unmodified state");
        use crate::law::ParamId;
        assert_restore_refuses(
            &m,
            |f| f.muscle.params.set(ParamId::B, 30.0).unwrap(),
            "b = 30.0, but scene HillActuator1D compiles it in as the constant 23.46",
        );
        assert_restore_refuses(
            &m,
            |f| f.muscle.params.set(ParamId::S, 500.0).unwrap(),
            "S = 500.0, but scene HillActuator1D",
        );
        assert_restore_refuses(
            &m,
            |f| f.muscle.adaptive_substeps = false,
            "adaptive_substeps = false, but scene",
        );
    }

    /// A parameter set after initialization (in instantiated mode, before
    /// a new one) leaves the committed outputs as they were: still a state
    /// some call sequence reaches, restored.
    #[test]
    fn parameters_set_since_the_last_commit_still_restore() {
        let mut m = stepped();
        m.set_real(Var::Area, 2.0 * m.muscle.area).unwrap();
        m.set_real(Var::Param(crate::law::ParamId::Sigma0), 5e5)
            .unwrap();
        let back = restored(&m).expect("a reachable state");
        assert_eq!(back, m);
    }
}
