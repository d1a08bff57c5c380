//! `HillMuscleFE`'s serialized state ([`HillFEState`] and its parts, their
//! byte order) and its restore: a decoded state becomes a model only if some
//! call sequence reaches it — every value in its declared range, the
//! scene's constants as compiled in, the mesh's size that of the state's own
//! arrays (checked before the mesh is built), and the stored outputs those
//! of the restored positions and histories ([`check_outputs`]).

use std::sync::Arc;

use super::{all_variables, check_mesh, HillFEModel, Var};
use crate::fe::mesh::{FibreLayout, Grading, Resolution};
use crate::fe::muscle::{Muscle, MAX_SUBSTEPS};
use crate::fe::newton::RESIDUAL_TOLERANCE;
use crate::fe::step_map::{
    discretization, outputs, rate_step, Committed, LastStep, Outputs, Quantity, StepLevel,
    Substepped, N_QUANTITIES,
};
use crate::fe::tangent::{
    Anchor, Contraction, Increment, TangentCache, Trend, CONTRACTION_STEPS, TREND_LENGTH,
};
use crate::fmi2::{Model, ModelError};
use crate::fmus::codec::{
    check_output, check_scene_constants, decode_from, encode_onto, wire_struct, MaybeF64,
};
use crate::fmus::common::{
    check_range, check_restored_drive, check_restored_history, check_unit_interval,
};
use crate::law::activation::Decay;
use crate::law::params::{AREA_RANGE, L0_RANGE};
use crate::law::{FibreHistory, FibreRate, Params, PARAMETERS};
use crate::scene::Scene;
use crate::step_control::MAX_CONTROLLED_TRIES;

wire_struct! {
    /// The state's fields in byte order (the format tests/golden_state.rs
    /// pins).
    pub(super) struct HillFEState {
        /// The law's parameters, in [`PARAMETERS`] order.
        params: Vec<f64>,
        l0: f64,
        area: f64,
        activation_dynamics: bool,
        initial_activation: f64,
        n_axial: i32,
        n_radial: i32,
        axial_grading: f64,
        radial_grading: f64,
        /// 0: axial, 1: meridian.
        fibre_layout: i32,
        adaptive_substeps: bool,
        substep_tolerance: f64,
        command: f64,
        length: MaybeF64,
        command_rate: f64,
        length_rate: f64,
        activation_level: f64,
        decay_step: MaybeF64,
        outputs: [f64; N_QUANTITIES],
        newton_iterations: i32,
        committed: Option<CommittedState>,
    }
}

wire_struct! {
    /// The committed muscle: the geometry and mesh it was built with (the
    /// parameters may have been set since), its state and the last step's.
    pub(crate) struct CommittedState {
        l0: f64,
        area: f64,
        n_axial: i32,
        n_radial: i32,
        axial_grading: f64,
        radial_grading: f64,
        fibre_layout: i32,
        /// Positions, 3 per node.
        x: Vec<f64>,
        /// (λs, λm) per element.
        history: Vec<f64>,
        length: f64,
        /// The last step's start histories, (λs, λm) per element.
        start: Vec<f64>,
        /// The last step's length (none: the initialization).
        h: MaybeF64,
        activation: f64,
        da_du: f64,
        solver: SolverState,
        substepped: Option<SubsteppedState>,
    }
}

wire_struct! {
    /// The solver's reused tangent (its anchor, from which a restored
    /// instance forms it again bit for bit) and the predictor's trend.
    pub(crate) struct SolverState {
        tangent: Option<AnchorState>,
        increments: Vec<IncrementState>,
        contraction: Option<ContractionState>,
    }
}

wire_struct! {
    pub(crate) struct AnchorState {
        x: Vec<f64>,
        activation: f64,
        start: Vec<f64>,
        rate_step: MaybeF64,
        /// Empty: the pressures of the volume ratios.
        pressure: Vec<f64>,
    }
}

wire_struct! {
    pub(crate) struct IncrementState {
        dx: Vec<f64>,
        dl: f64,
        da: f64,
        h: f64,
    }
}

wire_struct! {
    pub(crate) struct ContractionState {
        theta: f64,
        age: u64,
    }
}

wire_struct! {
    /// A substepped last step: the muscle before it and its inputs.
    pub(crate) struct SubsteppedState {
        x: Vec<f64>,
        history: Vec<f64>,
        length: f64,
        solver: SolverState,
        dynamics: bool,
        s: f64,
        a0: f64,
        u: f64,
        u_dot: f64,
        h: f64,
        end_length: f64,
        pieces: Vec<PieceState>,
    }
}

wire_struct! {
    #[derive(Copy)]
    pub(crate) struct PieceState {
        end: f64,
        n: u64,
    }
}

const MODEL: &str = "HillMuscleFE";

fn layout_code(l: FibreLayout) -> i32 {
    match l {
        FibreLayout::Axial => 0,
        FibreLayout::Meridian => 1,
    }
}

fn pairs_of(h: &[FibreHistory]) -> Vec<f64> {
    h.iter().flat_map(|x| [x.lambda_s, x.lambda_m]).collect()
}

fn solver_of(m: &Muscle) -> SolverState {
    SolverState {
        tangent: m.tangent.as_ref().map(|c| {
            let a = &c.anchor;
            AnchorState {
                x: a.x.clone(),
                activation: a.activation,
                start: pairs_of(&a.start),
                rate_step: MaybeF64(rate_step(a.rate)),
                pressure: a.pressure.clone().unwrap_or_default(),
            }
        }),
        increments: m
            .trend
            .increments
            .iter()
            .map(|i| IncrementState {
                dx: i.dx.clone(),
                dl: i.dl,
                da: i.da,
                h: i.h,
            })
            .collect(),
        contraction: m.trend.contraction.map(|c| ContractionState {
            theta: c.theta,
            age: c.age as u64,
        }),
    }
}

/// The wire form of a committed muscle (with the geometry and mesh it was
/// built with): `HillMuscleFE`'s, and the FE musculotendon unit's muscle.
pub(crate) fn committed_state(c: &Committed) -> CommittedState {
    let (mu, l, d) = (&c.muscle, &c.last, &c.muscle.disc);
    CommittedState {
        l0: d.l0,
        area: d.area,
        n_axial: d.mesh.resolution.n_axial as i32,
        n_radial: d.mesh.resolution.n_radial as i32,
        axial_grading: d.mesh.grading.axial,
        radial_grading: d.mesh.grading.radial,
        fibre_layout: layout_code(d.fibres),
        x: mu.x.clone(),
        history: pairs_of(&mu.history),
        length: mu.length,
        start: pairs_of(&l.start),
        h: MaybeF64(l.h),
        activation: l.activation,
        da_du: l.da_du,
        solver: solver_of(mu),
        substepped: c.substepped.as_ref().map(|st| SubsteppedState {
            x: st.before.x.clone(),
            history: pairs_of(&st.before.history),
            length: st.before.length,
            solver: solver_of(&st.before),
            dynamics: st.level.dynamics,
            s: st.level.s,
            a0: st.level.a0,
            u: st.level.u,
            u_dot: st.level.u_dot,
            h: st.level.h,
            end_length: st.end_length,
            pieces: st
                .pieces
                .iter()
                .map(|&(end, n)| PieceState { end, n: n as u64 })
                .collect(),
        }),
    }
}

/// [`Model::serialize`] of the FE model.
pub(super) fn encode<S: Scene>(m: &HillFEModel<S>, out: &mut Vec<u8>) {
    let committed = m.state.as_ref().map(committed_state);
    let state = HillFEState {
        params: PARAMETERS.iter().map(|i| m.params.get(i.id)).collect(),
        l0: m.l0,
        area: m.area,
        activation_dynamics: m.activation_dynamics,
        initial_activation: m.initial_activation,
        n_axial: m.n_axial,
        n_radial: m.n_radial,
        axial_grading: m.grading.axial,
        radial_grading: m.grading.radial,
        fibre_layout: m.fibre_layout,
        adaptive_substeps: m.adaptive_substeps,
        substep_tolerance: m.substep_tolerance,
        command: m.command,
        length: MaybeF64(m.length),
        command_rate: m.command_rate,
        length_rate: m.length_rate,
        activation_level: m.activation_level,
        decay_step: MaybeF64(m.decay.map(|d| d.h)),
        outputs: m.outputs,
        newton_iterations: m.newton_iterations,
        committed,
    };
    encode_onto(&state, out);
}

/// [`Model::deserialize`] of the FE model: decode, then [`restore`].
pub(super) fn decode<S: Scene>(input: &mut &[u8]) -> Result<HillFEModel<S>, ModelError> {
    let state: HillFEState = decode_from(MODEL, input)?;
    restore(state).map_err(|e| ModelError(format!("{MODEL} state: {e}")))
}

/// The model of a decoded state, if some call sequence reaches it.
fn restore<S: Scene>(s: HillFEState) -> Result<HillFEModel<S>, String> {
    let err = |e: ModelError| e.0;
    let mut m = HillFEModel::<S>::blank();
    if s.params.len() != PARAMETERS.len() {
        return Err(format!("{} parameters", s.params.len()));
    }
    for (info, &v) in PARAMETERS.iter().zip(&s.params) {
        m.params.set(info.id, v).map_err(|e| e.to_string())?;
    }
    m.l0 = s.l0;
    m.area = s.area;
    m.activation_dynamics = s.activation_dynamics;
    m.initial_activation = s.initial_activation;
    m.set_integer(Var::NAxial, s.n_axial).map_err(err)?;
    m.set_integer(Var::NRadial, s.n_radial).map_err(err)?;
    m.set_real(Var::AxialGrading, s.axial_grading)
        .map_err(err)?;
    m.set_real(Var::RadialGrading, s.radial_grading)
        .map_err(err)?;
    m.set_integer(Var::FibreLayout, s.fibre_layout)
        .map_err(err)?;
    m.adaptive_substeps = s.adaptive_substeps;
    m.set_real(Var::SubstepTolerance, s.substep_tolerance)
        .map_err(err)?;
    m.command = s.command;
    m.length = s.length.0;
    m.command_rate = s.command_rate;
    m.length_rate = s.length_rate;
    m.activation_level = s.activation_level;
    m.decay = match s.decay_step.0 {
        None => None,
        Some(h) if h.is_finite() && h > 0.0 => Some(Decay::new(m.params.s, h)),
        Some(h) => return Err(format!("bad activation decay step {h}")),
    };
    m.outputs = s.outputs;
    m.newton_iterations = s.newton_iterations;
    m.check_setup().map_err(err)?;
    let finite = [m.command, m.command_rate, m.length_rate, m.activation_level];
    if finite.iter().chain(&m.outputs).any(|x| !x.is_finite()) {
        return Err("a non-finite value".into());
    }
    if m.newton_iterations < 0 {
        return Err(format!("newton_iterations = {} < 0", m.newton_iterations));
    }
    check_restored_drive(m.command, m.activation_level).map_err(err)?;
    if let Some(c) = s.committed {
        let committed = restore_committed(c)?;
        check_outputs(&m, &committed)?;
        m.state = Some(committed);
    }
    check_scene_constants(&S::SPEC, &all_variables(), &m)?;
    Ok(m)
}

/// The mesh a committed state claims, its parameters checked as a setup's
/// ([`check_mesh`]: ranges, gradings, memory estimate) and its size that of
/// the state's positions and histories; nothing is built.
fn claimed_mesh(c: &CommittedState) -> Result<(Resolution, Grading, FibreLayout), String> {
    check_range("L0", c.l0, L0_RANGE).map_err(|e| e.0)?;
    check_range("area", c.area, AREA_RANGE).map_err(|e| e.0)?;
    let grading = Grading {
        axial: c.axial_grading,
        radial: c.radial_grading,
    };
    let (resolution, layout) =
        check_mesh(c.n_axial, c.n_radial, c.fibre_layout, grading).map_err(|e| e.0)?;
    // The fusiform mesh's node and element counts (crate::fe::mesh).
    let (nodes, elements) = (resolution.nodes(), resolution.tets());
    if c.x.len() != 3 * nodes {
        return Err(format!(
            "{} position values for a {} x {} mesh of {nodes} nodes",
            c.x.len(),
            c.n_axial,
            c.n_radial
        ));
    }
    for (name, v) in [("history", &c.history), ("start", &c.start)] {
        if v.len() != 2 * elements {
            return Err(format!(
                "{} {name} values for a {} x {} mesh of {elements} elements",
                v.len(),
                c.n_axial,
                c.n_radial
            ));
        }
    }
    Ok((resolution, grading, layout))
}

/// The committed muscle of `c`, its mesh built only after its size was
/// checked against the state's arrays ([`claimed_mesh`]).
pub(crate) fn restore_committed(c: CommittedState) -> Result<Committed, String> {
    let (resolution, grading, layout) = claimed_mesh(&c)?;
    let (n_nodes, n_elements) = (resolution.nodes(), resolution.tets());
    let n_dofs = 3 * n_nodes;
    let pairs = |v: Vec<f64>| -> Result<Vec<FibreHistory>, String> {
        if v.len() != 2 * n_elements || v.iter().any(|x| !x.is_finite()) {
            return Err(format!("{} history values", v.len()));
        }
        Ok(v.chunks(2)
            .map(|c| FibreHistory {
                lambda_s: c[0],
                lambda_m: c[1],
            })
            .collect())
    };
    let positions = |v: Vec<f64>| -> Result<Vec<f64>, String> {
        if v.len() != n_dofs || v.iter().any(|x| !x.is_finite()) {
            return Err(format!("{} position values", v.len()));
        }
        Ok(v)
    };
    let solver = |s: SolverState| -> Result<(Option<Arc<TangentCache>>, Trend), String> {
        let tangent = match s.tangent {
            None => None,
            Some(a) => {
                let rate = match a.rate_step.0 {
                    None => FibreRate::Isometric,
                    Some(h) if h.is_finite() && h > 0.0 => FibreRate::Step { h },
                    Some(h) => return Err(format!("bad anchor step {h}")),
                };
                if !a.activation.is_finite() {
                    return Err("a non-finite anchor activation".into());
                }
                let pressure = match a.pressure {
                    v if v.is_empty() => None,
                    v if v.len() == n_nodes && v.iter().all(|p| p.is_finite()) => Some(v),
                    v => return Err(format!("{} anchor pressure values", v.len())),
                };
                Some(Arc::new(TangentCache::new(Anchor {
                    x: positions(a.x)?,
                    activation: a.activation,
                    start: pairs(a.start)?,
                    rate,
                    pressure,
                })))
            }
        };
        if s.increments.len() > TREND_LENGTH {
            return Err(format!("{} predictor increments", s.increments.len()));
        }
        let mut trend = Trend::default();
        for i in s.increments {
            let dx = positions(i.dx)?;
            if !(i.dl.is_finite() && i.da.is_finite() && i.h.is_finite() && i.h > 0.0) {
                return Err("a bad predictor increment".into());
            }
            trend.increments.push(Increment {
                dx,
                dl: i.dl,
                da: i.da,
                h: i.h,
            });
        }
        if let Some(ContractionState { theta, age }) = s.contraction {
            if !(theta.is_finite() && theta >= 0.0 && age <= CONTRACTION_STEPS as u64) {
                return Err(format!("a bad contraction ({theta}, {age})"));
            }
            trend.contraction = Some(Contraction {
                theta,
                age: age as usize,
            });
        }
        Ok((tangent, trend))
    };
    let x = positions(c.x)?;
    let history = pairs(c.history)?;
    let start = pairs(c.start)?;
    let h = match c.h.0 {
        None => None,
        Some(h) if h.is_finite() && h > 0.0 => Some(h),
        Some(h) => return Err(format!("bad step {h}")),
    };
    let (length, activation, da_du) = (c.length, c.activation, c.da_du);
    if !(length.is_finite() && length > 0.0 && activation.is_finite() && da_du.is_finite()) {
        return Err("a non-finite value".into());
    }
    check_restored_history(&history)
        .and_then(|()| check_unit_interval("committed activation level", activation))
        .map_err(|e| e.0)?;
    let (tangent, trend) = solver(c.solver)?;
    let substepped = match c.substepped {
        None => None,
        Some(st) => {
            let x = positions(st.x)?;
            let history = pairs(st.history)?;
            let (tangent, trend) = solver(st.solver)?;
            let n_pieces = st.pieces.len() as u64;
            if !(1..=u64::from(MAX_CONTROLLED_TRIES)).contains(&n_pieces) {
                return Err(format!("{n_pieces} pieces of a substepped step"));
            }
            let mut pieces = Vec::with_capacity(st.pieces.len());
            for &PieceState { end, n } in &st.pieces {
                let previous = pieces.last().map_or(0.0, |&(t, _)| t);
                if !(end > previous && end <= st.h && (1..=MAX_SUBSTEPS as u64).contains(&n)) {
                    return Err(format!("a bad piece ({end}, {n})"));
                }
                pieces.push((end, n as usize));
            }
            let v = [st.s, st.a0, st.u, st.u_dot, st.h, st.end_length];
            let valid = st.length.is_finite()
                && st.length > 0.0
                && v.iter().all(|x| x.is_finite())
                && st.h > 0.0
                && st.end_length > 0.0
                && pieces.last().map(|&(t, _)| t) == Some(st.h);
            if !valid {
                return Err("a bad substepped step".into());
            }
            let level = StepLevel::new(
                st.dynamics,
                st.s,
                st.a0,
                st.u,
                st.u_dot,
                st.h,
                Decay::new(st.s, st.h).value,
            );
            Some((
                x,
                history,
                st.length,
                tangent,
                trend,
                level,
                st.end_length,
                pieces,
            ))
        }
    };
    // Only now, with every size checked, is the mesh built.
    let disc = discretization(None, c.l0, c.area, resolution, grading, layout)?;
    let substepped = substepped.map(
        |(x, history, length, tangent, trend, level, end_length, pieces)| Substepped {
            before: Muscle {
                disc: disc.clone(),
                x,
                history,
                length,
                tangent,
                trend,
                tolerance: RESIDUAL_TOLERANCE,
            },
            level,
            end_length,
            pieces,
        },
    );
    let muscle = Muscle {
        disc,
        x,
        history,
        length,
        tangent,
        trend,
        tolerance: RESIDUAL_TOLERANCE,
    };
    let last = LastStep {
        start,
        h,
        activation,
        da_du,
    };
    Ok(Committed::new(muscle, last, substepped))
}

/// The stored outputs those of the committed muscle `c`
/// ([`crate::fe::step_map::outputs`]): exactly, the level (also the
/// model's), stress = force / area, passive = stress − active and the
/// volume averages of the committed CE and SEE stretches; to round-off, the
/// geometric ones of the restored positions (fibre stretches, volume
/// ratios, and the Cauchy stress force · length / volume). The force and
/// the active stress depend on the law's parameters, which may have been
/// set since the state was committed: they are not recomputed.
fn check_outputs<S: Scene>(m: &HillFEModel<S>, c: &Committed) -> Result<(), String> {
    let o = |q: Quantity| m.outputs[q as usize];
    let (mu, d) = (&c.muscle, &c.muscle.disc);
    check_output(
        "activation_level",
        o(Quantity::ActivationLevel),
        c.last.activation,
    )?;
    check_output(
        "activation_level",
        o(Quantity::ActivationLevel),
        m.activation_level,
    )?;
    let stress = o(Quantity::Force) / d.area;
    check_output("stress", o(Quantity::Stress), stress)?;
    check_output(
        "passive_stress",
        o(Quantity::PassiveStress),
        stress - o(Quantity::ActiveStress),
    )?;
    let (mut v, mut lm, mut ls) = (0.0, 0.0, 0.0);
    for (h, ve) in mu.history.iter().zip(d.element_reference_volumes()) {
        v += ve;
        lm += ve * h.lambda_m;
        ls += ve * h.lambda_s;
    }
    check_output("ce_stretch", o(Quantity::CeStretch), lm / v)?;
    check_output("see_stretch", o(Quantity::SeeStretch), ls / v)?;
    let (recomputed, volume) = recompute(&m.params, c)?;
    let cauchy = o(Quantity::Force) * mu.length / volume;
    for (name, q, value) in [
        (
            "fibre_stretch",
            Quantity::FibreStretch,
            recomputed[Quantity::FibreStretch as usize],
        ),
        (
            "volume_ratio_min",
            Quantity::VolumeRatioMin,
            recomputed[Quantity::VolumeRatioMin as usize],
        ),
        (
            "volume_ratio_max",
            Quantity::VolumeRatioMax,
            recomputed[Quantity::VolumeRatioMax as usize],
        ),
        (
            "max_fibre_stretch",
            Quantity::MaxFibreStretch,
            recomputed[Quantity::MaxFibreStretch as usize],
        ),
        ("cauchy_stress", Quantity::CauchyStress, cauchy),
    ] {
        let stored = o(q);
        if (stored - value).abs() > 1e-9 * value.abs().max(1.0) || !stored.is_finite() {
            return Err(format!(
                "output {name} = {stored} is not that of the restored positions ({value})"
            ));
        }
    }
    Ok(())
}

/// The outputs of the restored muscle `c` with parameters `p` (the last
/// step's activation level, start histories and rate), and its volume.
/// Shared with the FE musculotendon unit.
pub(crate) fn recompute(p: &Params, c: &Committed) -> Result<(Outputs, f64), String> {
    let (mu, d) = (&c.muscle, &c.muscle.disc);
    let ev = d
        .evaluate(
            p,
            &mu.x,
            c.last.activation,
            &c.last.start,
            c.last.rate(),
            false,
        )
        .map_err(|e| format!("the restored positions: {e}"))?;
    let outputs = outputs(d, d.area, mu.length, &ev, c.last.activation);
    Ok((outputs, ev.volume))
}

/// The outputs that depend on the law's parameters — the force and its
/// stresses, the active stress — recomputed from the restored positions with
/// the current parameters (to the tolerance of [`check_outputs`]). Only for
/// a stepping instance: in instantiated or initialization mode a parameter
/// may have been set since the outputs were committed.
pub(super) fn check_law_outputs<S: Scene>(m: &HillFEModel<S>) -> Result<(), String> {
    match &m.state {
        Some(c) => check_law_quantities(&m.params, c, &m.outputs),
        None => Ok(()),
    }
}

/// `stored`'s force and active stress against those of the restored muscle
/// `c` with parameters `p` (1e-9 relative). Shared with the FE
/// musculotendon unit.
pub(crate) fn check_law_quantities(
    p: &Params,
    c: &Committed,
    stored: &Outputs,
) -> Result<(), String> {
    let (recomputed, _) = recompute(p, c)?;
    for (name, q) in [
        ("force", Quantity::Force),
        ("active_stress", Quantity::ActiveStress),
    ] {
        let (stored, value) = (stored[q as usize], recomputed[q as usize]);
        if (stored - value).abs() > 1e-9 * value.abs().max(1.0) || !stored.is_finite() {
            return Err(format!(
                "output {name} = {stored} is not that of the restored muscle with its parameters ({value})"
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::{HillFE, Output, DEFAULT_L0};
    use super::*;
    use crate::fmi2::bytes::ByteWriter;
    use crate::fmus::common::{assert_restore_refuses, restored};
    use crate::scene::shipped::HillActivatedFE;

    fn stepped() -> HillFE {
        let mut m = HillFE::new();
        m.set_integer(Var::NAxial, 6).unwrap();
        m.set_integer(Var::NRadial, 1).unwrap();
        m.set_real(Var::Activation, 0.6).unwrap();
        m.set_real(Var::Length, 1.05 * DEFAULT_L0).unwrap();
        m.initialize().unwrap();
        for _ in 0..2 {
            m.do_step(0.0, 1e-3).unwrap();
        }
        m
    }

    /// Stored outputs that are not those of the restored muscle (the
    /// layer's checksum recomputed) are refused naming the output.
    #[test]
    fn stored_outputs_must_be_those_of_the_restored_muscle() {
        let m = stepped();
        restored(&m).expect("an unmodified state");
        let set = |o: Output, v: f64| move |f: &mut HillFE| f.outputs[o as usize] = v;
        assert_restore_refuses(
            &m,
            set(Output::ActivationLevel, 5.0),
            "output activation_level = 5",
        );
        assert_restore_refuses(
            &m,
            set(Output::VolumeRatioMin, -3.0),
            "output volume_ratio_min = -3",
        );
        assert_restore_refuses(&m, set(Output::CeStretch, -1.0), "output ce_stretch = -1");
        assert_restore_refuses(&m, set(Output::Force, 1e30), "output stress");
        assert_restore_refuses(
            &m,
            |f| {
                let q = |o: Output| o as usize;
                let force = 1e30;
                f.outputs[q(Output::Force)] = force;
                f.outputs[q(Output::Stress)] = force / f.area;
                f.outputs[q(Output::PassiveStress)] =
                    force / f.area - f.outputs[q(Output::ActiveStress)];
            },
            "output cauchy_stress = ",
        );
    }

    /// A crafted state that claims a 96 × 16 mesh with a few kilobytes of
    /// positions is refused before the mesh is built (it would take seconds
    /// and 1.4 GB), naming the mesh's memory estimate and the budget; one
    /// that claims a mesh within the budget is refused naming the sizes; the
    /// message also names a count prefix larger than the bytes that follow.
    #[test]
    fn a_mesh_larger_than_its_state_is_refused_before_it_is_built() {
        let m = stepped();
        let mut bytes = Vec::new();
        m.serialize(&mut bytes);
        let claiming = |n_axial: i32, n_radial: i32| {
            let mut s: HillFEState = decode_from(MODEL, &mut bytes.as_slice()).unwrap();
            let c = s.committed.as_mut().unwrap();
            c.n_axial = n_axial;
            c.n_radial = n_radial;
            let mut crafted = Vec::new();
            encode_onto(&s, &mut crafted);
            crafted
        };
        let crafted = claiming(96, 16);
        let started = std::time::Instant::now();
        let e = HillFE::deserialize(&mut crafted.as_slice()).unwrap_err();
        assert!(
            e.0.contains("a 96 x 16 mesh needs an estimated") && e.0.contains("memory budget"),
            "{}",
            e.0
        );
        let e = HillFE::deserialize(&mut claiming(48, 8).as_slice()).unwrap_err();
        assert!(
            e.0.contains("position values for a 48 x 8 mesh of"),
            "{}",
            e.0
        );
        assert!(
            started.elapsed().as_secs_f64() < 0.5,
            "{:?}",
            started.elapsed()
        );
        // A count prefix of 2^40 positions in a short input.
        let cut = crafted.len() - 100;
        let mut short = crafted[..cut].to_vec();
        ByteWriter::new(&mut short).u64(1 << 40);
        let e = HillFE::deserialize(&mut short.as_slice()).unwrap_err();
        assert!(
            e.0.contains("cannot fit") || e.0.contains("truncated") || e.0.contains("exceeds"),
            "{}",
            e.0
        );
    }

    /// A restored FE scene's compiled-in constants cannot be changed.
    #[test]
    fn a_scene_constant_cannot_be_changed_through_a_state() {
        let m = HillFEModel::<HillActivatedFE>::new();
        restored(&m).expect("an unmodified state");
        let constant = HillActivatedFE::SPEC
            .parameters
            .iter()
            .find(|s| s.constant && s.name == "S")
            .expect("S is a constant of HillActivatedFE");
        assert!(constant.constant);
        assert_restore_refuses(
            &m,
            |f| f.params.set(crate::law::ParamId::S, 500.0).unwrap(),
            "S = 500.0, but scene HillActivatedFE compiles it in as the constant",
        );
    }
}
