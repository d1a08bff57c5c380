//! The FE muscle's opt-in element threads (`hill_muscle::fe::threads`):
//! every result the same bits at 1, 2 and 3 threads (3: uneven chunks) — a
//! residual and a tangent evaluation, one step, a run's forces — on the
//! default mesh, a small one and one large enough for the residual's loop
//! to be threaded; the `threads` parameter of the FE FMUs refused outside
//! [1, 64], tunable between steps, and not part of the serialized state (a
//! state saved at 2 threads continues at 1 to the same bits).

#![cfg(feature = "fe")]

use std::sync::Arc;

use hill_muscle::fe::discretization::Evaluation;
use hill_muscle::fe::mesh::{FibreLayout, Resolution, LUMPED, LUMPED_GRADING};
use hill_muscle::fe::muscle::{Discretization, Ends, Muscle};
use hill_muscle::fe::threads::{Threads, MAX_THREADS, RESIDUAL_ELEMENTS_PER_THREAD};
use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hillfe::{HillFE, Output, Var};
use hill_muscle::fmus::musculotendonfe::{MusculotendonFe, Var as MtVar};
use hill_muscle::law::{FibreHistory, FibreRate, Params};
use hill_muscle::specimen::{LENGTH as L0, MEAN_AREA};

const H: f64 = 1e-3;
const COUNTS: [usize; 3] = [1, 2, 3];

fn specimen(res: Resolution) -> Arc<Discretization> {
    Arc::new(
        Discretization::fusiform_graded(
            L0,
            MEAN_AREA,
            res,
            LUMPED_GRADING,
            FibreLayout::Meridian,
            Ends::Clamped,
        )
        .unwrap(),
    )
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Every number of an evaluation, as bits.
fn evaluation_bits(ev: &Evaluation) -> Vec<u64> {
    let mut b = bits(&ev.forces);
    b.extend(bits(&ev.d_activation));
    b.extend(bits(ev.tangent.as_deref().unwrap_or(&[])));
    for e in &ev.elements {
        b.extend(bits(&[
            e.lambda_f,
            e.j,
            e.j_assumed,
            e.history.lambda_s,
            e.history.lambda_m,
            e.sigma_see,
        ]));
    }
    b.extend(bits(&[ev.volume, ev.j_nodal_range.0, ev.j_nodal_range.1]));
    b
}

/// A perturbed, activated configuration of `d` with a start history off
/// the state's.
fn configuration(d: &Discretization) -> (Vec<f64>, Vec<FibreHistory>) {
    // Stretched 5 % along the axis, thinned to keep the volume, and
    // perturbed by 0.01 % (no element of the finest mesh inverted).
    let mut x = d.reference_positions();
    for (i, v) in x.iter_mut().enumerate() {
        let stretch = if i % 3 == 0 { 1.05 } else { 1.05f64.powf(-0.5) };
        *v *= stretch * (1.0 + 1e-4 * (((i * 7919) % 17) as f64 / 17.0 - 0.5));
    }
    let hist = (0..d.n_elements())
        .map(|e| FibreHistory {
            lambda_s: 1.0 + 0.001 * (e % 7) as f64,
            lambda_m: 0.99,
        })
        .collect();
    (x, hist)
}

/// Residual and tangent evaluations: the same bits at every thread count.
fn check_evaluations(res: Resolution) {
    let d = specimen(res);
    let p = Params::default();
    let (x, hist) = configuration(&d);
    let rate = FibreRate::Step { h: H };
    for tangent in [false, true] {
        let mut reference = None;
        for n in COUNTS {
            d.set_threads(Threads::new(n).unwrap());
            let ev = d.evaluate(&p, &x, 0.6, &hist, rate, tangent).unwrap();
            let b = evaluation_bits(&ev);
            match &reference {
                None => reference = Some(b),
                Some(r) => assert!(
                    *r == b,
                    "{res:?}, tangent {tangent}: {n} threads differ from 1"
                ),
            }
        }
    }
}

#[test]
fn evaluations_are_the_same_bits_at_every_thread_count() {
    check_evaluations(Resolution {
        n_axial: 4,
        n_radial: 1,
    });
    check_evaluations(LUMPED);
    // Large enough that the residual's loop is threaded at 2 and 3 threads.
    let large = Resolution {
        n_axial: 48,
        n_radial: 4,
    };
    assert!(specimen(large).n_elements() >= 3 * RESIDUAL_ELEMENTS_PER_THREAD);
    check_evaluations(large);
}

/// `steps` steps of the passive pull, activation ramped to 0.8, on `d`
/// at `n` threads: the end state's positions and histories and every
/// step's force, as bits.
fn run(d: &Arc<Discretization>, n: usize, steps: usize) -> (Vec<u64>, Vec<u64>) {
    let p = Params::default();
    d.set_threads(Threads::new(n).unwrap());
    let (mut m, _) = Muscle::isometric(d.clone(), &p, L0, 0.0).unwrap();
    let mut forces = Vec::new();
    for i in 0..steps {
        let a = (0.1 * (i + 1) as f64).min(0.8);
        let l = L0 * (1.0 + 0.002 * (i + 1) as f64);
        m = m.advance(&p, l, H, &move |_| a).unwrap().muscle;
        let ev = d
            .evaluate(&p, &m.x, a, &m.history, FibreRate::Step { h: H }, false)
            .unwrap();
        forces.push(d.reaction(&ev.forces).to_bits());
    }
    let mut state = bits(&m.x);
    for h in &m.history {
        state.extend(bits(&[h.lambda_s, h.lambda_m]));
    }
    (state, forces)
}

#[test]
fn steps_and_runs_are_the_same_bits_at_every_thread_count() {
    for (res, steps) in [
        (
            Resolution {
                n_axial: 4,
                n_radial: 1,
            },
            30,
        ),
        (LUMPED, 12),
    ] {
        let d = specimen(res);
        let one_step = run(&d, 1, 1);
        let reference = run(&d, 1, steps);
        for n in [2, 3] {
            assert!(
                run(&d, n, 1) == one_step,
                "{res:?}: one step at {n} threads"
            );
            assert!(
                run(&d, n, steps) == reference,
                "{res:?}: run at {n} threads"
            );
        }
    }
}

/// The mesh of [`small_fmu`]: the smallest whose tangent loop is split at
/// 2 threads (the test below asserts it).
const SMALL: Resolution = Resolution {
    n_axial: 8,
    n_radial: 2,
};

/// A small `HillMuscleFE` at 0.5 activation and 1.05 L0.
fn small_fmu() -> HillFE {
    let mut m = HillFE::new();
    m.set_integer(Var::NAxial, SMALL.n_axial as i32).unwrap();
    m.set_integer(Var::NRadial, SMALL.n_radial as i32).unwrap();
    m.set_real(Var::Activation, 0.5).unwrap();
    m.initialize().unwrap();
    m
}

fn steps(m: &mut HillFE, from: usize, n: usize) -> Vec<u64> {
    (from..from + n)
        .map(|i| {
            m.set_real(Var::Length, L0 * (1.0 + 0.003 * (i + 1) as f64))
                .unwrap();
            m.do_step(i as f64 * H, H).unwrap();
            m.get_real(Var::Out(Output::Force)).to_bits()
        })
        .collect()
}

#[test]
fn the_fmus_threads_parameter_is_refused_outside_its_range() {
    let mut m = small_fmu();
    for bad in [0, -1, MAX_THREADS as i32 + 1, i32::MAX, i32::MIN] {
        let e = m.set_integer(Var::Threads, bad).unwrap_err().0;
        assert!(
            e.contains("threads") && e.contains("out of range") && e.contains("[1, 64]"),
            "{bad}: {e}"
        );
    }
    assert_eq!(
        m.get_integer(Var::Threads),
        1,
        "a refused value is not kept"
    );
    let mut mt = MusculotendonFe::new();
    let e = mt.set_integer(MtVar::Threads, 0).unwrap_err().0;
    assert!(e.contains("threads") && e.contains("[1, 64]"), "{e}");
    mt.set_integer(MtVar::Threads, 2).unwrap();
    assert_eq!(mt.get_integer(MtVar::Threads), 2);
}

/// Set between steps (tunable), the count changes no force; a state saved
/// at 2 threads restores at 1 and continues to the same bits.
#[test]
fn the_fmus_threads_change_no_result_and_are_not_in_the_state() {
    // The FMU's mesh is large enough for its tangent to use 2 threads.
    let ne = specimen(SMALL).n_elements();
    assert!(
        ne >= 2 * hill_muscle::fe::threads::TANGENT_ELEMENTS_PER_THREAD,
        "{ne} elements: one thread"
    );
    let mut one = small_fmu();
    let mut two = small_fmu();
    two.set_integer(Var::Threads, 2).unwrap();
    let a = steps(&mut one, 0, 10);
    let b = steps(&mut two, 0, 10);
    assert_eq!(a, b);
    let mut bytes = Vec::new();
    two.serialize(&mut bytes);
    let mut restored = HillFE::deserialize(&mut bytes.as_slice()).unwrap();
    assert_eq!(restored.get_integer(Var::Threads), 1);
    let mut saved_at_one = Vec::new();
    one.serialize(&mut saved_at_one);
    assert_eq!(
        bytes, saved_at_one,
        "the state bytes do not depend on threads"
    );
    let continued = steps(&mut two, 10, 10);
    assert_eq!(steps(&mut restored, 10, 10), continued);
    restored.set_integer(Var::Threads, 3).unwrap();
    two.set_integer(Var::Threads, 1).unwrap();
    assert_eq!(steps(&mut restored, 20, 5), steps(&mut two, 20, 5));
}
