//! Golden FMU states: the serialized model state of every shipped scene after
//! one fixed run is pinned by its length and FNV-1a hash.
//!
//! A refactoring that changes no behaviour leaves these bytes as they are: the
//! state format, the order of its fields and every number the models compute
//! along the run (outputs, fibre histories, predictors, Jacobians). A change
//! that is meant to alter them must update the pins and say why.

use hill_muscle::fmi2::bytes::{fnv1a64, FNV64_OFFSET};
use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hill1d::Hill1DModel;
use hill_muscle::scene::shipped::*;

/// The variable of `M` named `name`, if the scene exposes it.
fn var<M: Model>(name: &str) -> Option<M::Var> {
    M::variables()
        .into_iter()
        .find(|v| v.name == name)
        .map(|v| v.id)
}

/// The fixed run: start at 1.02 × the start length with activation 0.3,
/// then `n` steps of 1 ms of a stretch, a rising activation, a length jump
/// and input derivatives on every fifth step. Returns the serialized state
/// (which must also restore to itself).
fn run<M: Model>(n: usize) -> Vec<u8> {
    let mut m = M::new();
    let activation = var::<M>("activation");
    let length = var::<M>("length");
    // The length input starts at L0.
    let l0 = length.map_or(0.0, |l| m.get_real(l));
    if let Some(a) = activation {
        m.set_real(a, 0.3).unwrap();
    }
    if let Some(l) = length {
        m.set_real(l, 1.02 * l0).unwrap();
    }
    m.initialize().unwrap();
    for i in 0..n {
        let t = i as f64 * 1e-3;
        if let Some(a) = activation {
            m.set_real(a, (0.3 + 20.0 * t).min(1.0)).unwrap();
            if i % 5 == 0 {
                m.set_real_input_derivative(a, 1, 2.0).unwrap();
            }
        }
        if let Some(l) = length {
            let jump = if i >= n / 2 { 0.03 * l0 } else { 0.0 };
            m.set_real(l, l0 * (1.02 + 0.5 * t) + jump).unwrap();
            if i % 5 == 0 {
                m.set_real_input_derivative(l, 1, 0.2 * l0).unwrap();
            }
        }
        m.do_step(t, 1e-3).unwrap();
    }
    let mut bytes = Vec::new();
    m.serialize(&mut bytes);
    let back = M::deserialize(&mut bytes.as_slice()).expect("the state restores");
    let mut again = Vec::new();
    back.serialize(&mut again);
    assert_eq!(
        again, bytes,
        "a restored state serializes to the same bytes"
    );
    bytes
}

/// (model identifier, state length, FNV-1a 64 of the state) after [`run`].
fn golden<M: Model>(n: usize) -> (&'static str, usize, u64) {
    let bytes = run::<M>(n);
    (
        M::info().model_identifier,
        bytes.len(),
        fnv1a64(FNV64_OFFSET, &bytes),
    )
}

/// Every run's (identifier, length, hash) equals the pinned one; on a
/// mismatch the message lists all of them, ready to paste.
fn check(got: &[(&'static str, usize, u64)], want: &[(&str, usize, u64)]) {
    let listing: String = got
        .iter()
        .map(|(id, n, h)| format!("(\"{id}\", {n}, {h:#018x}),\n"))
        .collect();
    assert_eq!(
        got, want,
        "the serialized states after the fixed run changed; now:\n{listing}"
    );
}

#[test]
fn one_d_scene_states_are_unchanged() {
    check(
        &[
            golden::<Hill1DModel<HillMuscle1D>>(40),
            golden::<Hill1DModel<HillPassive1D>>(40),
            golden::<Hill1DModel<HillActivated1D>>(40),
            golden::<Hill1DModel<HillIsometric1D>>(40),
            golden::<Hill1DModel<HillActuator1D>>(40),
        ],
        &[
            ("HillMuscle1D", 578, 0x61ad5fd7e977d9ac),
            ("HillPassive1D", 570, 0x88facbe782e17a86),
            ("HillActivated1D", 578, 0x61ad5fd7e977d9ac),
            ("HillIsometric1D", 570, 0xe8dbb8dc7147a29f),
            ("HillActuator1D", 578, 0x61ad5fd7e977d9ac),
        ],
    );
}

#[cfg(feature = "fe")]
#[test]
fn fe_scene_states_are_unchanged() {
    use hill_muscle::fmus::hillfe::HillFEModel;
    check(
        &[
            golden::<HillFEModel<HillMuscleFE>>(12),
            golden::<HillFEModel<HillPassiveFE>>(12),
            golden::<HillFEModel<HillActivatedFE>>(12),
        ],
        &[
            ("HillMuscleFE", 205546, 0xb14535418eef8b0f),
            ("HillPassiveFE", 205546, 0xf246e54f693e2e0d),
            ("HillActivatedFE", 205546, 0xb14535418eef8b0f),
        ],
    );
}

/// `HillMusculotendon1D` after the same fixed run (its `length` input the
/// path, starting at the rest path).
#[test]
fn musculotendon_scene_state_is_unchanged() {
    use hill_muscle::fmus::musculotendon1d::MusculotendonModel;
    check(
        &[golden::<MusculotendonModel<HillMusculotendon1D>>(40)],
        &[("HillMusculotendon1D", 771, 0x8a5e19b817a3179f)],
    );
}

/// `HillMusculotendonFE` after the same fixed run (12 steps, as the FE
/// scenes; its `length` input the path, starting at the rest path).
#[cfg(feature = "fe")]
#[test]
fn fe_musculotendon_scene_state_is_unchanged() {
    use hill_muscle::fmus::musculotendonfe::MusculotendonFEModel;
    check(
        &[golden::<MusculotendonFEModel<HillMusculotendonFE>>(12)],
        &[("HillMusculotendonFE", 205727, 0x2f2e2a92d133b597)],
    );
}
