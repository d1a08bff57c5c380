//! Tests of `HillMuscleFE`'s FMI mapping: the output table, the step
//! map's derivatives, substeps and the restore checks.

use super::*;
use crate::fe::step_map::{outputs, Quantity, Substepped};
use crate::fmus::common::{assert_restore_refuses, restored};

/// The last step's map when it took substeps.
fn substepped(m: &HillFE) -> Option<&Substepped> {
    m.state.as_ref().and_then(|c| c.substepped.as_ref())
}

/// The output table lists the FE muscle's quantities in their order:
/// the serialized outputs are in that order.
#[test]
fn the_output_table_is_in_the_order_of_the_fe_quantities() {
    for (i, &(o, ..)) in OUTPUTS.iter().enumerate() {
        assert_eq!(o as usize, i, "{o:?}");
    }
}

/// A 6 × 1 muscle at `stretch` L0 and activation level `level`, with or
/// without `adaptive_substeps`.
fn muscle(stretch: f64, level: f64, adaptive: bool) -> HillFE {
    let mut m = HillFE::new();
    m.set_integer(Var::NAxial, 6).unwrap();
    m.set_integer(Var::NRadial, 1).unwrap();
    m.set_boolean(Var::AdaptiveSubsteps, adaptive).unwrap();
    m.set_real(Var::InitialActivation, level).unwrap();
    m.set_real(Var::Activation, level).unwrap();
    m.set_real(Var::Length, stretch * DEFAULT_L0).unwrap();
    m.initialize().unwrap();
    m
}

fn force(m: &HillFE) -> f64 {
    m.get_real(Var::Out(Output::Force))
}

/// `n` steps of `h` to length `l` under command `u`.
fn run(m: &HillFE, l: f64, u: f64, h: f64, n: usize) -> HillFE {
    let mut m = m.clone();
    m.set_real(Var::Length, l).unwrap();
    m.set_real(Var::Activation, u).unwrap();
    for _ in 0..n {
        m.do_step(0.0, h).unwrap();
    }
    m
}

/// (dF/dL, dF/du) through the FMU's partial derivatives.
fn derivatives(m: &HillFE) -> (f64, f64) {
    let d = |known| {
        m.partial_derivative(Var::Out(Output::Force), known)
            .unwrap()
    };
    (d(Var::Length), d(Var::Activation))
}

/// The outputs at the end of the step map of `start` in the fixed
/// pieces `pieces` (the map a substepped step's derivatives
/// differentiate).
fn map_outputs(start: &HillFE, pieces: &[(f64, usize)], l: f64, u: f64, h: f64) -> Outputs {
    let s = start.params.s;
    let a0 = start.activation_level;
    let level = StepLevel::new(true, s, a0, u, 0.0, h, Decay::new(s, h).value);
    let adv = start
        .state
        .as_ref()
        .unwrap()
        .muscle
        .advance_pieces(&start.params, l, h, &|t| level.at(t), pieces)
        .unwrap();
    let m = &adv.muscle;
    outputs(
        &m.disc,
        start.area,
        m.length,
        &adv.solution.evaluation,
        level.end,
    )
}

/// The force of [`map_outputs`].
fn map_force(start: &HillFE, pieces: &[(f64, usize)], l: f64, u: f64, h: f64) -> f64 {
    map_outputs(start, pieces, l, u, h)[Quantity::Force as usize]
}

/// A restored state is checked as strictly as the calls that produce
/// its values: an activation command or level outside [0, 1], or a
/// non-positive CE or SEE stretch in the history, is refused naming it
/// (a crafted state: the layer's checksum is not a signature), while the
/// unmodified state round-trips.
#[test]
fn a_restored_state_with_unphysical_values_is_refused() {
    let m = run(&muscle(1.05, 0.3, false), 1.06 * DEFAULT_L0, 0.6, 1e-3, 2);
    let back = restored(&m).expect("an unmodified state");
    assert_eq!(force(&back), force(&m));
    assert_restore_refuses(&m, |f| f.command = 5.0, "activation = 5");
    assert_restore_refuses(&m, |f| f.command = -3.0, "activation = -3");
    assert_restore_refuses(&m, |f| f.activation_level = 4.0, "activation level = 4");
    assert_restore_refuses(
        &m,
        |f| f.state.as_mut().unwrap().muscle.history[3].lambda_m = -1.0,
        "fibre history 3: CE stretch -1",
    );
    assert_restore_refuses(
        &m,
        |f| f.state.as_mut().unwrap().muscle.history[0].lambda_s = 0.0,
        "and SEE stretch 0 must be finite and > 0",
    );
    assert_restore_refuses(&m, |f| f.length = Some(1e3), "length = 1000");
}

/// After initialization the partial derivatives are those of the
/// isometric equilibrium (FibreRate::Isometric; activation dynamics off,
/// so the level is the command): dF/dL and dF/du against central
/// differences of re-initializing at L ± δ and u ± δ, passive-stretched
/// and active (measured agreement 5e-7 and better; held to 1e-5).
#[test]
fn initial_derivatives_match_finite_differences_of_the_initialization() {
    let init = |stretch: f64, u: f64| {
        let mut m = HillFE::new();
        m.set_integer(Var::NAxial, 6).unwrap();
        m.set_integer(Var::NRadial, 1).unwrap();
        m.set_boolean(Var::ActivationDynamics, false).unwrap();
        m.set_real(Var::Activation, u).unwrap();
        m.set_real(Var::Length, stretch * DEFAULT_L0).unwrap();
        m.initialize().unwrap();
        m
    };
    for (stretch, u) in [(1.1, 0.0), (1.05, 0.5)] {
        let m = init(stretch, u);
        let (d_l, d_u) = derivatives(&m);
        let (el, eu) = (1e-5, 1e-4);
        let fd_l = (force(&init(stretch + el, u)) - force(&init(stretch - el, u)))
            / (2.0 * el * DEFAULT_L0);
        let fd_u = if u > 0.0 {
            (force(&init(stretch, u + eu)) - force(&init(stretch, u - eu))) / (2.0 * eu)
        } else {
            let f = |u| force(&init(stretch, u));
            (-3.0 * f(0.0) + 4.0 * f(eu) - f(2.0 * eu)) / (2.0 * eu)
        };
        assert!(d_l > 0.0, "dF/dL {d_l}");
        assert!(
            ((d_l - fd_l) / fd_l).abs() < 1e-5,
            "L0 x {stretch}, u {u}: dF/dL {d_l} vs {fd_l}"
        );
        assert!(
            ((d_u - fd_u) / fd_u).abs() < 1e-5,
            "L0 x {stretch}, u {u}: dF/du {d_u} vs {fd_u}"
        );
    }
}

/// A step cut into pieces (level 0.3 -> command 0.6, 1.10 -> 1.12 L0,
/// 5 ms, adaptive): its directional derivatives are those of the whole
/// step's map (central differences of the same pieces from the same
/// start, steps 10x and 5x the model's, extrapolated), not those of the last piece's
/// tangent, which holds that piece's start history fixed and is
/// distinctly off here; a restored copy of the state gives the same
/// derivatives bit for bit; a step in one piece clears the record.
#[test]
fn a_substepped_step_has_the_derivatives_of_its_step_map() {
    let before = muscle(1.1, 0.3, true);
    let (l, u, h) = (1.12 * DEFAULT_L0, 0.6, 5e-3);
    let m = run(&before, l, u, h, 1);
    let pieces = substepped(&m).unwrap().pieces.clone();
    assert!(pieces.len() > 1, "{pieces:?}");
    // The map differentiated below is the step's own: replaying its
    // pieces gives the error-controlled step's force bit for bit.
    assert_eq!(map_force(&before, &pieces, l, u, h), force(&m));
    let (d_l, d_u) = derivatives(&m);
    // Central differences with steps 10x and 5x the model's, Richardson
    // extrapolated (their δ² terms cancel): this step's map is curved
    // enough that the 10x difference alone is 1.3e-5 off.
    let f = |l, u| map_force(&before, &pieces, l, u, h);
    let richardson = |d: &dyn Fn(f64) -> f64, e: f64| (4.0 * d(e / 2.0) - d(e)) / 3.0;
    let fd_l = richardson(
        &|e| (f(l + e, u) - f(l - e, u)) / (2.0 * e),
        1e-4 * DEFAULT_L0,
    );
    let fd_u = richardson(&|e| (f(l, u + e) - f(l, u - e)) / (2.0 * e), 1e-4);
    assert!(((d_l - fd_l) / fd_l).abs() < 1e-5, "dF/dL {d_l} vs {fd_l}");
    assert!(((d_u - fd_u) / fd_u).abs() < 1e-5, "dF/du {d_u} vs {fd_u}");

    // The last piece's tangent alone (what the derivatives were
    // before): off by more than 1 % in the command.
    let c = m.state.clone().unwrap();
    let last_only = Committed::new(c.muscle, c.last, None);
    let (_, d_u_last) = last_only
        .force_derivatives(&m.params, m.l0, m.area)
        .unwrap();
    assert!(
        ((d_u_last - fd_u) / fd_u).abs() > 1e-2,
        "the last piece's tangent {d_u_last} is as good as the map's {fd_u}: the test shows nothing"
    );

    let mut bytes = Vec::new();
    m.serialize(&mut bytes);
    let restored = HillFE::deserialize(&mut bytes.as_slice()).unwrap();
    assert!(substepped(&restored).is_some());
    let (r_l, r_u) = derivatives(&restored);
    assert_eq!(r_l.to_bits(), d_l.to_bits());
    assert_eq!(r_u.to_bits(), d_u.to_bits());
    let mut one_piece = m.clone();
    one_piece.set_boolean(Var::AdaptiveSubsteps, false).unwrap();
    assert!(substepped(&run(&one_piece, l, u, h, 1)).is_none());
}

/// A fast length ramp of the active muscle in one step (L0 → 2 L0 in
/// 0.1 s, alpha = 10, S = 50, D = 1e-6): the CE yields under the fast
/// lengthening (f_v near its plateau), where the error control needs
/// pieces of ~10 µs, hundreds in the step. Its active stress is within
/// 1e-3 sigma0 of the same ramp in 100 steps of 1 ms. Under the earlier
/// work bound (256 tries, pieces ≥ h/4096) the step took its rest in one
/// piece and was 8e-2 sigma0 off (docs/fe.md). `-- --nocapture` prints
/// the figures.
#[test]
fn adaptive_substeps_follow_a_yielding_ce_through_a_fast_ramp() {
    let start = || {
        let mut m = HillFE::new();
        m.set_integer(Var::NAxial, 6).unwrap();
        m.set_integer(Var::NRadial, 1).unwrap();
        m.set_boolean(Var::AdaptiveSubsteps, true).unwrap();
        for (id, v) in [
            (ParamId::Alpha, 10.0),
            (ParamId::S, 50.0),
            (ParamId::Dcomp, 1e-6),
        ] {
            m.set_real(Var::Param(id), v).unwrap();
        }
        m.set_real(Var::InitialActivation, 1.0).unwrap();
        m.set_real(Var::Activation, 1.0).unwrap();
        m.set_real(Var::Length, DEFAULT_L0).unwrap();
        m.initialize().unwrap();
        m
    };
    let h = 0.1;
    let mut reference = start();
    for k in 1..=100 {
        reference
            .set_real(Var::Length, DEFAULT_L0 * (1.0 + f64::from(k) / 100.0))
            .unwrap();
        reference.do_step(0.0, h / 100.0).unwrap();
    }
    let adaptive = run(&start(), 2.0 * DEFAULT_L0, 1.0, h, 1);
    let active = |m: &HillFE| m.get_real(Var::Out(Output::ActiveStress));
    let error = (active(&adaptive) - active(&reference)).abs() / adaptive.params.sigma0;
    let pieces = &substepped(&adaptive).unwrap().pieces;
    let shortest = pieces
        .iter()
        .scan(0.0, |t, &(end, _)| Some(end - std::mem::replace(t, end)))
        .fold(f64::INFINITY, f64::min);
    eprintln!(
        "{} pieces, the shortest {shortest:e} s; active stress error / sigma0 {error:e}",
        pieces.len()
    );
    assert!(error < 1e-3, "active stress error / sigma0 {error:e}");
}

/// An activation jump 0 → 1 in one step of 20 ms (S h = 1): with
/// `adaptive_substeps` the step is cut into pieces by the error estimate
/// and its force is within 1e-2 sigma0 A of the reference (the same step
/// in 200 steps of 0.1 ms), at least 5x closer than the one
/// backward-Euler step without it; its derivatives are those of its
/// step map, one-sided in the command at u = 1 (so first order in the
/// difference step). (Differences of whole adaptive steps are no check:
/// the pieces the control picks change with the inputs, by jumps of the
/// order of its tolerance — here as large as the force change of the
/// difference.) `-- --nocapture` prints the figures.
#[test]
fn adaptive_substeps_control_the_time_error_of_an_activation_jump() {
    let (l, h) = (1.05 * DEFAULT_L0, 0.02);
    let reference = force(&run(&muscle(1.05, 0.0, false), l, 1.0, h / 200.0, 200));
    let coarse = force(&run(&muscle(1.05, 0.0, false), l, 1.0, h, 1));
    let start = muscle(1.05, 0.0, true);
    let adaptive = run(&start, l, 1.0, h, 1);
    let scale = adaptive.params.sigma0 * adaptive.area;
    let (e_adaptive, e_coarse) = (
        (force(&adaptive) - reference).abs() / scale,
        (coarse - reference).abs() / scale,
    );
    let pieces = substepped(&adaptive).unwrap().pieces.clone();
    eprintln!(
        "{} pieces; force error / (sigma0 A): adaptive {e_adaptive:e}, one step {e_coarse:e}",
        pieces.len()
    );
    assert!(pieces.len() > 2, "{pieces:?}");
    assert!(
        e_adaptive < 1e-2 && e_adaptive < 0.2 * e_coarse,
        "adaptive {e_adaptive:e}, one step {e_coarse:e}"
    );

    let (d_l, d_u) = derivatives(&adaptive);
    let (el, eu) = (1e-4 * DEFAULT_L0, 1e-4);
    let f = |l, u| map_force(&start, &pieces, l, u, h);
    let fd_l = (f(l + el, 1.0) - f(l - el, 1.0)) / (2.0 * el);
    let fd_u = (f(l, 1.0) - f(l, 1.0 - eu)) / eu;
    assert!(((d_l - fd_l) / fd_l).abs() < 1e-5, "dF/dL {d_l} vs {fd_l}");
    assert!(((d_u - fd_u) / fd_u).abs() < 1e-3, "dF/du {d_u} vs {fd_u}");
}

/// Every output's directional derivatives (a step in one piece, and one
/// cut into pieces by the error control) against central differences of
/// the step map: the step taken again from the same start with the
/// inputs moved, in the same pieces ([`map_force`]; steps 1e-4 L0 and
/// 1e-4, Richardson extrapolated),
/// within 1e-4 of the larger of the two (or of the output's scale per
/// unit input, for derivatives that vanish). `-- --nocapture` prints
/// them.
#[test]
fn every_output_has_the_derivatives_of_its_step_map() {
    for adaptive in [false, true] {
        let before = muscle(1.1, 0.3, adaptive);
        let (l, u, h) = (1.12 * DEFAULT_L0, 0.6, 5e-3);
        let m = run(&before, l, u, h, 1);
        assert_eq!(substepped(&m).is_some(), adaptive);
        let richardson = |d: &dyn Fn(f64) -> f64, e: f64| (4.0 * d(e / 2.0) - d(e)) / 3.0;
        let pieces = substepped(&m).map(|s| s.pieces.clone());
        for &(o, Row { name, .. }) in OUTPUTS.iter() {
            let out = |l, u| match &pieces {
                None => run(&before, l, u, h, 1).get_real(Var::Out(o)),
                Some(pieces) => map_outputs(&before, pieces, l, u, h)[o as usize],
            };
            let d = |known| m.partial_derivative(Var::Out(o), known).unwrap();
            let (d_l, d_u) = (d(Var::Length), d(Var::Activation));
            let fd_l = richardson(
                &|e| (out(l + e, u) - out(l - e, u)) / (2.0 * e),
                1e-4 * DEFAULT_L0,
            );
            let fd_u = richardson(&|e| (out(l, u + e) - out(l, u - e)) / (2.0 * e), 1e-4);
            let value = m
                .get_real(Var::Out(o))
                .abs()
                .max(1e-3 * m.params.sigma0 * m.area);
            eprintln!(
                "{name} (adaptive {adaptive}): d/dL {d_l:e} vs {fd_l:e}, d/du {d_u:e} vs {fd_u:e}"
            );
            let close = |an: f64, fd: f64, scale: f64| {
                (an - fd).abs() <= 1e-4 * an.abs().max(fd.abs()).max(scale)
            };
            assert!(
                close(d_l, fd_l, value / DEFAULT_L0),
                "{name}: d/dL {d_l:e} vs {fd_l:e}"
            );
            assert!(close(d_u, fd_u, value), "{name}: d/du {d_u:e} vs {fd_u:e}");
        }
    }
}

/// Without activation dynamics the level is the command, held over the
/// step (MODEL_NOTES "Co-simulation conventions"), in every substep: a
/// command jump 0 → 1 in one 20 ms step cut into pieces by the error
/// control has the force of the same jump in 200 steps of 0.1 ms, to
/// 1e-2 sigma0 A (isometric at 1.05 L0). A level ramped across the
/// step's pieces instead (as the substeps did before) activates the
/// muscle late and is 0.15 sigma0 A low. `-- --nocapture` prints the
/// figures.
#[test]
fn without_dynamics_every_substep_sees_the_held_command() {
    let start = |adaptive| {
        let mut m = muscle(1.05, 0.0, adaptive);
        m.set_boolean(Var::ActivationDynamics, false).unwrap();
        m
    };
    let (l, h) = (1.05 * DEFAULT_L0, 0.02);
    let reference = force(&run(&start(false), l, 1.0, h / 200.0, 200));
    let adaptive = run(&start(true), l, 1.0, h, 1);
    let pieces = substepped(&adaptive).unwrap().pieces.len();
    let error = (force(&adaptive) - reference).abs() / (adaptive.params.sigma0 * adaptive.area);
    eprintln!("{pieces} pieces; force error / (sigma0 A) {error:e}");
    assert!(pieces > 1, "the step was not cut: the test shows nothing");
    assert!(error < 1e-2, "force error / (sigma0 A) {error:e}");
}
