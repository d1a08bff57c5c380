//! `HillMusculotendon1D`'s serialized state ([`MusculotendonState`]: the 1D
//! muscle's state, then the unit's) and its restore: a decoded state becomes
//! a model only if some call sequence reaches it — the muscle's part as
//! strictly as `HillMuscle1D`'s ([`restore_muscle`]), the unit's parameters
//! in their ranges, the scene's constants as compiled in, and the unit's
//! stored outputs consistent with the muscle's committed state
//! ([`check_unit_outputs`]).

use super::{all_variables, MusculotendonModel};
use crate::fmi2::{Model, ModelError};
use crate::fmus::codec::{
    check_output, check_scene_constants, decode_from, encode_onto, wire_struct, MaybeF64,
};
use crate::fmus::hill1d::state::{check_force, muscle_state, restore_muscle, Hill1DState};
use crate::law::musculotendon::StepRates;
use crate::law::params::{L0_RANGE, TENDON_PARAMETERS};
use crate::law::pennation::MIN_COS;
use crate::law::Components;
use crate::muscle1d::musculotendon::Guess;
use crate::muscle1d::{Musculotendon1D, Output, UnitOutput};
use crate::scene::Scene;

wire_struct! {
    /// The state's fields in byte order (the format tests/golden_state.rs
    /// pins).
    pub(super) struct MusculotendonState {
        /// The 1D muscle's state, as `HillMuscle1D` writes it.
        muscle: Hill1DState,
        /// The unit's parameters, in [`TENDON_PARAMETERS`] order.
        tendon: Vec<f64>,
        compliant_tendon: bool,
        /// The path length input (none: the rest path).
        path: MaybeF64,
        path_rate: f64,
        /// The path length at the end of the last step.
        committed_path: f64,
        /// The next step's first guess: dλ/dℓ, the fibre and path rates,
        /// their changes and the last step's length.
        guess: [f64; 6],
        /// Force, stress, fibre length, tendon strain, pennation.
        outputs: [f64; 5],
        /// dF_T/d(activation command, path length).
        dforce: [f64; 2],
    }
}

const MODEL: &str = "HillMusculotendon1D";

/// [`Model::serialize`] of the musculotendon model.
pub(super) fn encode<S: Scene>(m: &MusculotendonModel<S>, out: &mut Vec<u8>) {
    let u = &m.mt;
    let state = MusculotendonState {
        muscle: muscle_state(&u.muscle),
        tendon: TENDON_PARAMETERS.iter().map(|i| u.unit.get(i.id)).collect(),
        compliant_tendon: u.unit.compliant_tendon,
        path: MaybeF64(u.path),
        path_rate: u.path_rate,
        committed_path: u.committed_path,
        guess: [
            u.guess.slope,
            u.guess.rates.fibre_rate,
            u.guess.rates.path_rate,
            u.guess.rates.fibre_accel,
            u.guess.rates.path_accel,
            u.guess.rates.span,
        ],
        outputs: u.outputs,
        dforce: u.dforce,
    };
    encode_onto(&state, out);
}

/// [`Model::deserialize`] of the musculotendon model: decode, then
/// [`restore`].
pub(super) fn decode<S: Scene>(input: &mut &[u8]) -> Result<MusculotendonModel<S>, ModelError> {
    let state: MusculotendonState = decode_from(MODEL, input)?;
    restore(state).map_err(|e| ModelError(format!("{MODEL} state: {e}")))
}

/// The model of a decoded state, if some call sequence reaches it.
fn restore<S: Scene>(s: MusculotendonState) -> Result<MusculotendonModel<S>, String> {
    let MusculotendonState {
        muscle,
        tendon,
        compliant_tendon,
        path,
        path_rate,
        committed_path,
        guess,
        outputs,
        dforce,
    } = s;
    let mut m = MusculotendonModel::<S>::new();
    let u = &mut m.mt;
    restore_muscle(muscle, &mut u.muscle)?;
    if tendon.len() != TENDON_PARAMETERS.len() {
        return Err(format!(
            "{} tendon parameters, expected {}",
            tendon.len(),
            TENDON_PARAMETERS.len()
        ));
    }
    for (info, &v) in TENDON_PARAMETERS.iter().zip(&tendon) {
        u.unit.set(info.id, v).map_err(|e| e.to_string())?;
    }
    u.unit.compliant_tendon = compliant_tendon;
    u.path = path.0;
    u.path_rate = path_rate;
    u.committed_path = committed_path;
    u.guess = Guess {
        slope: guess[0],
        rates: StepRates {
            fibre_rate: guess[1],
            path_rate: guess[2],
            fibre_accel: guess[3],
            path_accel: guess[4],
            span: guess[5],
        },
    };
    u.outputs = outputs;
    u.dforce = dforce;
    if [path_rate, committed_path]
        .iter()
        .chain(&guess)
        .chain(&outputs)
        .chain(&dforce)
        .any(|x| !x.is_finite())
    {
        return Err("a non-finite value".into());
    }
    if committed_path <= 0.0 {
        return Err(format!(
            "committed path length {committed_path} must be > 0"
        ));
    }
    u.check_setup().map_err(|e| e.0)?;
    check_unit_outputs(u)?;
    check_scene_constants(&S::SPEC, &all_variables(), &m)?;
    Ok(m)
}

/// The unit's stored outputs consistent with the muscle's committed state
/// (MODEL_NOTES "Musculotendon unit": outputs): the stress the muscle's,
/// bit for bit; the fibre length the committed stretch times an `L0` in its
/// range; the pennation in [0, α_max]; a slack tendon (ε < 0) carrying
/// nothing and a stretched one pulling; the force of the sign of the
/// muscle's stress when the tendon is rigid (ε = 0). Like `HillMuscle1D`'s
/// check, none needs a parameter: those may have been set since the state
/// was committed, before a new initialization.
fn check_unit_outputs<C: Components>(u: &Musculotendon1D<C>) -> Result<(), String> {
    let out = |o: UnitOutput| u.outputs[o as usize];
    let stress = u.muscle.outputs[Output::Stress as usize];
    check_output("stress", out(UnitOutput::Stress), stress)?;
    let l_m = out(UnitOutput::FibreLength);
    // l_m / λ rounds: L0 may come out an ulp or two outside its range.
    let l0 = l_m / u.muscle.lambda;
    let slack = 1e-12;
    if !(l0 >= L0_RANGE.min * (1.0 - slack) && l0 <= L0_RANGE.max * (1.0 + slack)) {
        return Err(format!(
            "output fibre_length = {l_m} is not the committed stretch {} times an L0 in {L0_RANGE}",
            u.muscle.lambda
        ));
    }
    check_tendon_outputs(
        out(UnitOutput::PennationAngle),
        out(UnitOutput::Force),
        out(UnitOutput::TendonStrain),
        stress,
    )
}

/// A unit's stored pennation in [0, α_max], and its tendon force of the sign
/// its strain gives: a slack tendon (ε < 0) carrying nothing, a stretched
/// one pulling, a rigid one (ε = 0) carrying the muscle's sign. Shared by
/// both units' restore checks.
pub(crate) fn check_tendon_outputs(
    angle: f64,
    force: f64,
    strain: f64,
    stress: f64,
) -> Result<(), String> {
    if !(0.0..=MIN_COS.acos()).contains(&angle) {
        return Err(format!(
            "output pennation = {angle} must be in [0, {}] (the largest angle)",
            MIN_COS.acos()
        ));
    }
    let consistent = if strain < 0.0 {
        force == 0.0
    } else if strain > 0.0 {
        force >= 0.0
    } else {
        force == 0.0 || force.signum() == stress.signum()
    };
    if !consistent {
        return Err(format!(
            "output force = {force} is not a tendon force at tendon_strain = {strain} (muscle stress {stress})"
        ));
    }
    Ok(())
}

/// [`Model::check_stepping_outputs`] of the unit: a stepping instance's
/// parameters are those of its last commit, so every stored output and
/// partial must be the unit's at the committed state (the muscle's force
/// its stress times the area, bit for bit; the unit's outputs recomputed).
pub(super) fn check_stepping<C: Components>(u: &Musculotendon1D<C>) -> Result<(), String> {
    check_force(&u.muscle)?;
    u.check_committed_outputs()
}

#[cfg(test)]
mod tests {
    use super::super::{Musculotendon, Var};
    use super::*;
    use crate::fmus::common::{assert_restore_refuses, restored};
    use crate::law::params::TendonParamId;

    fn stepped() -> Musculotendon {
        let mut m = Musculotendon::new();
        let path = m.get_real(Var::Length);
        m.set_real(Var::Activation, 0.6).unwrap();
        m.set_real(Var::Length, 1.01 * path).unwrap();
        m.initialize().unwrap();
        for _ in 0..3 {
            m.do_step(0.0, 1e-3).unwrap();
        }
        m
    }

    /// The unmodified state round-trips; crafted unit values are refused
    /// naming them: a tendon parameter out of range, a path out of range,
    /// a non-finite guess, outputs no step leaves.
    #[test]
    fn a_restored_state_is_checked() {
        let m = stepped();
        let back = restored(&m).expect("an unmodified state");
        assert_eq!(back, m);
        assert_restore_refuses(
            &m,
            |f| f.mt.unit.tendon_strain_at_f0 = 0.0,
            "parameter tendon_strain_at_F0 = 0",
        );
        assert_restore_refuses(
            &m,
            |f| f.mt.unit.pennation_angle = 2.0,
            "parameter pennation_angle = 2",
        );
        assert_restore_refuses(&m, |f| f.mt.path = Some(1e3), "path length = 1000");
        assert_restore_refuses(&m, |f| f.mt.guess.slope = f64::NAN, "a non-finite value");
        assert_restore_refuses(&m, |f| f.mt.committed_path = -1.0, "committed path");
        let set = |o: UnitOutput, v: f64| move |f: &mut Musculotendon| f.mt.outputs[o as usize] = v;
        assert_restore_refuses(&m, set(UnitOutput::Stress, 1.0), "output stress");
        assert_restore_refuses(&m, set(UnitOutput::FibreLength, 1e3), "output fibre_length");
        assert_restore_refuses(&m, set(UnitOutput::PennationAngle, 1.5), "output pennation");
        assert_restore_refuses(&m, set(UnitOutput::Force, -1.0), "output force = -1");
        assert_restore_refuses(
            &m,
            |f| f.mt.muscle.activation_level = 4.0,
            "activation level = 4",
        );
    }

    /// A parameter set after initialization (before a new one) leaves the
    /// committed outputs as they were: still a reachable state.
    #[test]
    fn parameters_set_since_the_last_commit_still_restore() {
        let mut m = stepped();
        m.set_real(Var::L0, 0.5 * m.mt.muscle.l0).unwrap();
        m.set_real(Var::Tendon(TendonParamId::PennationAngle), 0.3)
            .unwrap();
        m.set_boolean(Var::CompliantTendon, false).unwrap();
        let back = restored(&m).expect("a reachable state");
        assert_eq!(back, m);
    }
}
