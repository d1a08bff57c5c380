//! `HillMusculotendonFE`'s serialized state ([`MusculotendonFEState`]: the
//! parameters and inputs, then the committed unit: the FE muscle as
//! `HillMuscleFE` writes it, then the unit's part) and its restore: a
//! decoded state becomes a model only if some call sequence reaches it —
//! every parameter in its range, the FE muscle restored as strictly as
//! `HillMuscleFE`'s ([`restore_committed`]), its stored outputs those of the
//! restored positions, and the unit's outputs consistent with the muscle
//! ([`check_unit_outputs`]).

use super::{all_variables, check_mesh, MusculotendonFEModel, Var};
use crate::fe::musculotendon::{Guess, MusculotendonFE, UnitOutput, N_UNIT};
use crate::fe::step_map::{Quantity, N_QUANTITIES};
use crate::fmi2::{Model, ModelError};
use crate::fmus::codec::{
    check_output, check_scene_constants, decode_from, encode_onto, wire_struct, MaybeF64,
};
use crate::fmus::common::{check_range, check_restored_drive, check_unit_interval};
use crate::fmus::hillfe::state::{
    check_law_quantities, committed_state, recompute, restore_committed, CommittedState,
};
use crate::fmus::musculotendon1d::state::check_tendon_outputs;
use crate::law::activation::Decay;
use crate::law::musculotendon::StepRates;
use crate::law::params::{AREA_RANGE, L0_RANGE, TENDON_PARAMETERS};
use crate::law::{Params, PARAMETERS};
use crate::scene::Scene;

wire_struct! {
    /// The state's fields in byte order (the format tests/golden_state.rs
    /// pins).
    pub(super) struct MusculotendonFEState {
        /// The law's parameters, in [`PARAMETERS`] order.
        params: Vec<f64>,
        l0: f64,
        area: f64,
        /// The unit's parameters, in [`TENDON_PARAMETERS`] order.
        tendon: Vec<f64>,
        compliant_tendon: bool,
        activation_dynamics: bool,
        initial_activation: f64,
        adaptive_substeps: bool,
        substep_tolerance: f64,
        n_axial: i32,
        n_radial: i32,
        axial_grading: f64,
        radial_grading: f64,
        fibre_layout: i32,
        command: f64,
        command_rate: f64,
        path: MaybeF64,
        path_rate: f64,
        decay_step: MaybeF64,
        committed: Option<UnitState>,
    }
}

wire_struct! {
    /// The committed unit.
    pub(super) struct UnitState {
        /// The FE muscle, as `HillMuscleFE` writes it.
        muscle: CommittedState,
        muscle_outputs: [f64; N_QUANTITIES],
        /// The path length at the end of the last step.
        path: f64,
        /// The next step's first guess: dL_M/dℓ, the fibre and path rates,
        /// Newton's slope, the rates' changes, the last step's length and
        /// the root's offset ([`Guess`]).
        guess: [f64; 8],
        /// Force, stress, fibre length, tendon strain, pennation.
        outputs: [f64; N_UNIT],
        iterations: u64,
        trials: u64,
    }
}

const MODEL: &str = "HillMusculotendonFE";

/// [`Model::serialize`] of the model.
pub(super) fn encode<S: Scene>(m: &MusculotendonFEModel<S>, out: &mut Vec<u8>) {
    let committed = m.state.as_ref().map(|u| UnitState {
        muscle: committed_state(&u.muscle),
        muscle_outputs: u.muscle_outputs,
        path: u.path,
        guess: [
            u.guess.slope,
            u.guess.rates.fibre_rate,
            u.guess.rates.path_rate,
            u.guess.stiffness,
            u.guess.rates.fibre_accel,
            u.guess.rates.path_accel,
            u.guess.rates.span,
            u.guess.offset,
        ],
        outputs: u.outputs,
        iterations: u.iterations as u64,
        trials: u64::from(u.trials),
    });
    let state = MusculotendonFEState {
        params: PARAMETERS.iter().map(|i| m.params.get(i.id)).collect(),
        l0: m.l0,
        area: m.area,
        tendon: TENDON_PARAMETERS.iter().map(|i| m.unit.get(i.id)).collect(),
        compliant_tendon: m.unit.compliant_tendon,
        activation_dynamics: m.activation_dynamics,
        initial_activation: m.initial_activation,
        adaptive_substeps: m.adaptive_substeps,
        substep_tolerance: m.substep_tolerance,
        n_axial: m.n_axial,
        n_radial: m.n_radial,
        axial_grading: m.grading.axial,
        radial_grading: m.grading.radial,
        fibre_layout: m.fibre_layout,
        command: m.command,
        command_rate: m.command_rate,
        path: MaybeF64(m.path),
        path_rate: m.path_rate,
        decay_step: MaybeF64(m.decay.map(|d| d.h)),
        committed,
    };
    encode_onto(&state, out);
}

/// [`Model::deserialize`] of the model: decode, then [`restore`].
pub(super) fn decode<S: Scene>(input: &mut &[u8]) -> Result<MusculotendonFEModel<S>, ModelError> {
    let state: MusculotendonFEState = decode_from(MODEL, input)?;
    restore(state).map_err(|e| ModelError(format!("{MODEL} state: {e}")))
}

/// The model of a decoded state, if some call sequence reaches it.
fn restore<S: Scene>(s: MusculotendonFEState) -> Result<MusculotendonFEModel<S>, String> {
    let err = |e: ModelError| e.0;
    let mut m = MusculotendonFEModel::<S>::blank();
    if s.params.len() != PARAMETERS.len() {
        return Err(format!("{} parameters", s.params.len()));
    }
    for (info, &v) in PARAMETERS.iter().zip(&s.params) {
        m.params.set(info.id, v).map_err(|e| e.to_string())?;
    }
    if s.tendon.len() != TENDON_PARAMETERS.len() {
        return Err(format!("{} tendon parameters", s.tendon.len()));
    }
    for (info, &v) in TENDON_PARAMETERS.iter().zip(&s.tendon) {
        m.unit.set(info.id, v).map_err(|e| e.to_string())?;
    }
    m.unit.compliant_tendon = s.compliant_tendon;
    m.l0 = s.l0;
    m.area = s.area;
    m.activation_dynamics = s.activation_dynamics;
    m.initial_activation = s.initial_activation;
    m.adaptive_substeps = s.adaptive_substeps;
    m.set_real(Var::SubstepTolerance, s.substep_tolerance)
        .map_err(err)?;
    m.set_integer(Var::NAxial, s.n_axial).map_err(err)?;
    m.set_integer(Var::NRadial, s.n_radial).map_err(err)?;
    m.set_real(Var::AxialGrading, s.axial_grading)
        .map_err(err)?;
    m.set_real(Var::RadialGrading, s.radial_grading)
        .map_err(err)?;
    m.set_integer(Var::FibreLayout, s.fibre_layout)
        .map_err(err)?;
    check_mesh(m.n_axial, m.n_radial, m.fibre_layout, m.grading).map_err(err)?;
    m.command = s.command;
    m.command_rate = s.command_rate;
    m.path = s.path.0;
    m.path_rate = s.path_rate;
    m.decay = match s.decay_step.0 {
        None => None,
        Some(h) if h.is_finite() && h > 0.0 => Some(Decay::new(m.params.s, h)),
        Some(h) => return Err(format!("bad activation decay step {h}")),
    };
    m.check_setup().map_err(err)?;
    if ![m.command, m.command_rate, m.path_rate]
        .iter()
        .all(|x| x.is_finite())
    {
        return Err("a non-finite value".into());
    }
    check_unit_interval("activation", m.command).map_err(err)?;
    if let Some(u) = s.committed {
        m.state = Some(restore_unit(u, &m.params)?);
    }
    if let Some(st) = &m.state {
        check_restored_drive(m.command, st.muscle.last.activation).map_err(err)?;
    }
    check_scene_constants(&S::SPEC, &all_variables(), &m)?;
    Ok(m)
}

/// The committed unit of `u`: its muscle restored and its outputs checked.
fn restore_unit(u: UnitState, p: &Params) -> Result<MusculotendonFE, String> {
    let muscle = restore_committed(u.muscle)?;
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    let all_finite =
        finite(&[u.path]) && finite(&u.guess) && finite(&u.outputs) && finite(&u.muscle_outputs);
    if !all_finite || u.path <= 0.0 {
        return Err("a non-finite value or a path length <= 0".into());
    }
    let mt = MusculotendonFE {
        muscle,
        muscle_outputs: u.muscle_outputs,
        path: u.path,
        guess: Guess {
            slope: u.guess[0],
            stiffness: u.guess[3],
            rates: StepRates {
                fibre_rate: u.guess[1],
                path_rate: u.guess[2],
                fibre_accel: u.guess[4],
                path_accel: u.guess[5],
                span: u.guess[6],
            },
            offset: u.guess[7],
        },
        outputs: u.outputs,
        iterations: usize::try_from(u.iterations).map_err(|e| e.to_string())?,
        trials: u32::try_from(u.trials).map_err(|e| e.to_string())?,
        factorizations: 0,
        residuals: 0,
    };
    check_muscle_outputs(&mt, p)?;
    check_unit_outputs(&mt)?;
    Ok(mt)
}

/// The stored FE outputs are those of the restored positions: the
/// kinematic ones recomputed (to 1e-9 relative; they do not depend on the
/// law's parameters, which may have been set since the commit), the stress
/// the force over the area and the level the committed one, bit for bit.
fn check_muscle_outputs(mt: &MusculotendonFE, p: &Params) -> Result<(), String> {
    let (last, d) = (&mt.muscle.last, &mt.muscle.muscle.disc);
    let o = |q: Quantity| mt.muscle_outputs[q as usize];
    check_output("stress", o(Quantity::Stress), o(Quantity::Force) / d.area)?;
    check_unit_interval("committed activation level", last.activation).map_err(|e| e.0)?;
    check_output(
        "activation_level",
        o(Quantity::ActivationLevel),
        last.activation,
    )?;
    let (recomputed, _) = recompute(p, &mt.muscle)?;
    for q in [
        Quantity::FibreStretch,
        Quantity::VolumeRatioMin,
        Quantity::VolumeRatioMax,
    ] {
        let (stored, value) = (o(q), recomputed[q as usize]);
        if (stored - value).abs() > 1e-9 * value.abs().max(1.0) {
            return Err(format!(
                "output {q:?} = {stored} is not that of the restored positions ({value})"
            ));
        }
    }
    Ok(())
}

/// The unit's stored outputs consistent with the muscle's (MODEL_NOTES
/// "Musculotendon unit": outputs): the stress the muscle's and the fibre
/// length the muscle's length, bit for bit; the pennation in [0, α_max]; a
/// slack tendon (ε < 0) carrying nothing and a stretched one pulling.
fn check_unit_outputs(mt: &MusculotendonFE) -> Result<(), String> {
    let out = |o: UnitOutput| mt.outputs[o as usize];
    let stress = mt.muscle_outputs[Quantity::Stress as usize];
    check_output("stress", out(UnitOutput::Stress), stress)?;
    check_output(
        "fibre_length",
        out(UnitOutput::FibreLength),
        mt.muscle.muscle.length,
    )?;
    check_tendon_outputs(
        out(UnitOutput::PennationAngle),
        out(UnitOutput::Force),
        out(UnitOutput::TendonStrain),
        stress,
    )?;
    check_range("L0 of the muscle", mt.muscle.muscle.disc.l0, L0_RANGE).map_err(|e| e.0)?;
    check_range("area of the muscle", mt.muscle.muscle.disc.area, AREA_RANGE).map_err(|e| e.0)?;
    Ok(())
}

/// [`Model::check_stepping_outputs`] of the FE unit: a stepping instance's
/// parameters are those of its last commit, so the muscle's force and active
/// stress must be those of the restored positions with its parameters (as
/// `HillMuscleFE`'s, to 1e-9 relative), and the unit's force, tendon strain
/// and pennation those of the committed path at the muscle's length (the
/// expressions the step evaluated, to rounding).
pub(super) fn check_stepping<S: Scene>(m: &MusculotendonFEModel<S>) -> Result<(), String> {
    let Some(mt) = &m.state else {
        return Ok(());
    };
    check_law_quantities(&m.params, &mt.muscle, &mt.muscle_outputs)?;
    let mu = &mt.muscle.muscle;
    let unit = m.tendon_unit();
    let pen = unit.pennation.at(mu.length);
    let f_m = mt.muscle_outputs[Quantity::Force as usize];
    let (force, strain) = if unit.compliant {
        let lt = mt.path - pen.projection;
        (unit.tendon.force(lt).0, unit.tendon.strain(lt))
    } else {
        (f_m * pen.cos, 0.0)
    };
    let f0 = unit.tendon.f0;
    let out = |o: UnitOutput| mt.outputs[o as usize];
    for (name, stored, value, scale) in [
        ("force", out(UnitOutput::Force), force, f0),
        ("tendon_strain", out(UnitOutput::TendonStrain), strain, 1.0),
        ("pennation", out(UnitOutput::PennationAngle), pen.angle, 1.0),
    ] {
        if (stored - value).abs() > 1e-12 * scale.max(value.abs()) || !stored.is_finite() {
            return Err(format!(
                "output {name} = {stored} is not the unit's at the committed path and fibre length ({value})"
            ));
        }
    }
    Ok(())
}
