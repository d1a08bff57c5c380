//! Tests of `HillMusculotendonFE`'s FMI mapping on a 6 × 1 mesh: a rigid
//! tendon without pennation against `HillMuscleFE`, the stiffness output
//! against the directional derivative, and the restore checks.

use super::*;
use crate::fmus::common::{assert_restore_refuses, restored};
use crate::fmus::hillfe::{HillFE, Output as FeQuantity, Var as FeVar};

/// A 6 × 1 unit at its rest path under command `u` (no dynamics).
fn small(flags: &[(Var, bool)], path: Option<f64>, u: f64) -> MusculotendonFe {
    let mut m = MusculotendonFe::new();
    m.set_integer(Var::NAxial, 6).unwrap();
    m.set_integer(Var::NRadial, 1).unwrap();
    m.set_boolean(Var::ActivationDynamics, false).unwrap();
    for &(v, b) in flags {
        m.set_boolean(v, b).unwrap();
    }
    if let Some(p) = path {
        m.set_real(Var::Length, p).unwrap();
    }
    m.set_real(Var::Activation, u).unwrap();
    m.initialize().unwrap();
    m
}

fn out(m: &MusculotendonFe, o: UnitOutput) -> f64 {
    m.get_real(Var::Out(MtOutput::Unit(o)))
}

/// A rigid tendon without pennation is `HillMuscleFE` at length ℓ − L_TS,
/// bit for bit, with the scene's geometry.
#[test]
fn a_rigid_tendon_without_pennation_is_hill_muscle_fe() {
    let mut mt = small(&[(Var::CompliantTendon, false)], None, 0.5);
    let slack = mt.unit.tendon_slack_length;
    let mut fe = HillFE::new();
    fe.set_real(FeVar::L0, mt.l0).unwrap();
    fe.set_real(FeVar::Area, mt.area).unwrap();
    fe.set_integer(FeVar::NAxial, 6).unwrap();
    fe.set_integer(FeVar::NRadial, 1).unwrap();
    fe.set_boolean(FeVar::ActivationDynamics, false).unwrap();
    fe.set_real(FeVar::Activation, 0.5).unwrap();
    fe.set_real(FeVar::Length, mt.path() - slack).unwrap();
    fe.initialize().unwrap();
    let path0 = mt.path();
    for k in 0..4 {
        let f = fe.get_real(FeVar::Out(FeQuantity::Force));
        assert_eq!(out(&mt, UnitOutput::Force), f, "step {k}");
        assert_eq!(
            out(&mt, UnitOutput::Stress),
            fe.get_real(FeVar::Out(FeQuantity::Stress))
        );
        let path = path0 + 1e-4 * (k + 1) as f64;
        mt.set_real(Var::Length, path).unwrap();
        mt.set_real(Var::Activation, 0.8).unwrap();
        fe.set_real(FeVar::Length, path - slack).unwrap();
        fe.set_real(FeVar::Activation, 0.8).unwrap();
        mt.do_step(0.0, 1e-3).unwrap();
        fe.do_step(0.0, 1e-3).unwrap();
    }
    let d = mt.partial_derivative(Var::Out(MtOutput::Unit(UnitOutput::Force)), Var::Length);
    let e = fe.partial_derivative(FeVar::Out(FeQuantity::Force), FeVar::Length);
    assert_eq!(d.unwrap(), e.unwrap());
}

/// The stiffness output is the directional derivative d force / d length.
#[test]
fn the_stiffness_is_the_force_derivative() {
    let mut m = small(&[], None, 0.3);
    let path = m.path();
    m.set_real(Var::Length, path + 1e-4).unwrap();
    m.do_step(0.0, 1e-3).unwrap();
    let d = m
        .partial_derivative(Var::Out(MtOutput::Unit(UnitOutput::Force)), Var::Length)
        .unwrap();
    assert_eq!(out(&m, UnitOutput::Stiffness), d);
    assert!(d > 0.0 && d.is_finite());
}

/// The unmodified state round-trips bit for bit and steps on as the
/// original; crafted values are refused naming them.
#[test]
fn a_restored_state_is_checked() {
    let mut m = small(&[], None, 0.6);
    let path = m.path();
    for k in 1..=3 {
        m.set_real(Var::Length, path + 1e-4 * k as f64).unwrap();
        m.do_step(0.0, 1e-3).unwrap();
    }
    let mut back = restored(&m).expect("an unmodified state");
    let (mut a, mut b) = (Vec::new(), Vec::new());
    m.serialize(&mut a);
    back.serialize(&mut b);
    assert_eq!(a, b);
    for x in [&mut m, &mut back] {
        x.set_real(Var::Length, path + 5e-4).unwrap();
        x.do_step(0.0, 1e-3).unwrap();
    }
    let (mut a, mut b) = (Vec::new(), Vec::new());
    m.serialize(&mut a);
    back.serialize(&mut b);
    assert_eq!(a, b, "the restored unit steps on as the original");
    assert_restore_refuses(
        &m,
        |f| f.unit.tendon_strain_at_f0 = 0.0,
        "parameter tendon_strain_at_F0 = 0",
    );
    assert_restore_refuses(&m, |f| f.path = Some(1e3), "length = 1000");
    let set = |o: FeOutput, v: f64| {
        move |f: &mut MusculotendonFe| f.state.as_mut().unwrap().outputs[o as usize] = v
    };
    assert_restore_refuses(&m, set(FeOutput::Stress, 1.0), "output stress");
    assert_restore_refuses(&m, set(FeOutput::FibreLength, 1.0), "output fibre_length");
    assert_restore_refuses(&m, set(FeOutput::PennationAngle, 1.5), "output pennation");
    assert_restore_refuses(&m, set(FeOutput::Force, -1.0), "output force = -1");
    assert_restore_refuses(
        &m,
        |f| f.state.as_mut().unwrap().guess.slope = f64::NAN,
        "a non-finite value",
    );
}

/// A stepping unit's stored outputs are recomputed from its state: those of
/// every step pass (compliant, pennated and rigid; through a pull and a
/// slack phase), and a stored force, tendon strain, pennation or muscle
/// force changed by 1e-6 of itself (plus 1e-9, or 1 mN for the muscle's
/// force, which is ~0 on a slack path) is refused.
#[test]
fn a_stepping_state_has_the_outputs_of_its_committed_state() {
    for (flags, alpha) in [
        (vec![], 0.0),
        (vec![], 0.3),
        (vec![(Var::CompliantTendon, false)], 0.0),
    ] {
        let mut m = MusculotendonFe::new();
        m.set_integer(Var::NAxial, 6).unwrap();
        m.set_integer(Var::NRadial, 1).unwrap();
        m.set_real(Var::Tendon(TendonParamId::PennationAngle), alpha)
            .unwrap();
        for &(v, b) in &flags {
            m.set_boolean(v, b).unwrap();
        }
        let rest = m.get_real(Var::Length);
        m.set_real(Var::Activation, 0.5).unwrap();
        m.initialize().unwrap();
        m.check_stepping_outputs().unwrap();
        for k in 0..6 {
            let path = if k < 4 {
                rest * (1.0 + 0.01 * k as f64)
            } else {
                0.97 * rest
            };
            m.set_real(Var::Length, path).unwrap();
            if m.do_step(k as f64 * 1e-3, 1e-3).is_ok() {
                m.check_stepping_outputs().unwrap();
            }
        }
        let forge = |f: &dyn Fn(&mut MusculotendonFE)| {
            let mut c = m.clone();
            f(c.state.as_mut().unwrap());
            assert!(c.check_stepping_outputs().is_err());
        };
        for o in [
            FeOutput::Force,
            FeOutput::TendonStrain,
            FeOutput::PennationAngle,
        ] {
            forge(&|s| s.outputs[o as usize] = s.outputs[o as usize] * (1.0 + 1e-6) + 1e-9);
        }
        forge(&|s| {
            let f = &mut s.muscle_outputs[FeQuantity::Force as usize];
            *f = *f * (1.0 + 1e-6) + 1e-3;
        });
    }
}
