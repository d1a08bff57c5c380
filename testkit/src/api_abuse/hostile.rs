//! Hostile but well-formed calls: the classes of case an adversarial
//! importer found beyond the random sequences. Each is a property over a
//! strategy, its oracle the refusal the FMU documents
//! (docs/reference/bad-input.md), never a crash, an abort or a silent
//! `fmi2OK`:
//!
//! - a declared mesh whose estimated memory is over the FE muscle's budget
//!   (`hill_muscle::fe::memory`): `fmi2ExitInitializationMode` is
//!   `fmi2Error` naming the budget, at once, and the instance stays in
//!   initialization mode unchanged, where a small mesh then initializes;
//! - a serialized state whose stored copy of an output is forged (every
//!   occurrence of its value, checksum recomputed): refused with the
//!   instance unchanged;
//! - extreme activation input derivatives over a step: the step is
//!   `fmi2OK` or `fmi2Discard`, and `activation_level`, where the model has
//!   it, stays in [0, 1];
//! - a start time at which the step does not advance the time: `fmi2DoStep`
//!   is `fmi2Error` with the instance unchanged.

use super::*;

/// A new instance with [`Subject::SOLVER_INTEGERS`] (then `ints`), set up
/// from `t0`, in initialization mode.
fn entered(t0: f64, ints: &[(&'static str, i32)]) -> Fmu {
    let f = Fmu::new(false);
    unsafe {
        assert_eq!(
            (abi().setup_experiment)(f.c, fmi2False, 0.0, t0, fmi2False, 0.0),
            fmi2OK
        );
        assert_eq!((abi().enter_initialization_mode)(f.c), fmi2OK);
    }
    set_integers(f.c, profile().solver_integers).unwrap();
    for &(name, v) in ints {
        let vr = vr_named(name);
        assert_eq!(unsafe { (abi().set_integer)(f.c, &vr, 1, &v) }, fmi2OK);
    }
    f.book.clear();
    f
}

/// [`entered`], initialized, at activation `u`.
fn initialized(t0: f64, u: f64) -> Fmu {
    let f = entered(t0, &[]);
    unsafe {
        assert_eq!((abi().set_real)(f.c, &table().activation, 1, &u), fmi2OK);
        let st = (abi().exit_initialization_mode)(f.c);
        assert_eq!(st, fmi2OK, "{:?}", f.book.take());
    }
    f
}

fn messages(f: &Fmu) -> String {
    f.book
        .take()
        .iter()
        .map(|e| e.message.clone())
        .collect::<Vec<_>>()
        .join(" | ")
}

/// Meshes over the memory budget: every declared (n_axial, n_radial) whose
/// estimate exceeds it is refused at initialization, in under a second,
/// naming the budget; the instance is unchanged and a 1 × 1 mesh then
/// initializes. Models without a mesh pass trivially.
pub fn meshes_over_the_memory_budget_are_refused_at_once() {
    #[cfg(feature = "fe")]
    {
        use hill_muscle::fe::memory::{estimate, BUDGET};
        use hill_muscle::fe::mesh::Resolution;
        let has = |n: &str| table().vars.iter().any(|v| v.name == n);
        if !(has("n_axial") && has("n_radial")) {
            return;
        }
        let (ax, rad) = (
            int_range(vr_named("n_axial")),
            int_range(vr_named("n_radial")),
        );
        let over: Vec<(i32, i32)> = (ax.0..=ax.1)
            .flat_map(|a| (rad.0..=rad.1).map(move |r| (a, r)))
            .filter(|&(a, r)| {
                estimate(Resolution {
                    n_axial: a as usize,
                    n_radial: r as usize,
                }) > BUDGET
            })
            .collect();
        assert!(!over.is_empty(), "no declared mesh is over the budget");
        let strategy = prop::sample::select(over);
        properties::run_cases(cases(1, 4).max(8), &strategy, |(a, r)| {
            let f = entered(0.0, &[("n_axial", a), ("n_radial", r)]);
            let before = f.state_bytes().unwrap();
            let started = std::time::Instant::now();
            let st = unsafe { (abi().exit_initialization_mode)(f.c) };
            let log = messages(&f);
            prop_assert_eq!(st, fmi2Error, "{} x {}: {}", a, r, log);
            prop_assert!(log.contains("memory budget"), "{} x {}: {}", a, r, log);
            prop_assert!(started.elapsed().as_secs_f64() < 1.0, "{} x {}", a, r);
            prop_assert!(f.state_bytes().unwrap() == before, "{} x {}: changed", a, r);
            set_integers(f.c, &[("n_axial", 1), ("n_radial", 1)]).unwrap();
            let st = unsafe { (abi().exit_initialization_mode)(f.c) };
            prop_assert_eq!(st, fmi2OK, "then 1 x 1: {}", messages(&f));
            Ok(())
        });
    }
}

/// `bytes` with the one occurrence of `from` replaced by `to`, the checksum
/// recomputed; `None` when `from` does not occur exactly once (a value that
/// also sits in a state field is not only the stored output).
fn forged(bytes: &[u8], from: f64, to: f64) -> Option<Vec<u8>> {
    let (from, to) = (from.to_le_bytes(), to.to_le_bytes());
    let at: Vec<usize> = (0..bytes.len().saturating_sub(7))
        .filter(|&i| bytes[i..i + 8] == from)
        .collect();
    let [i] = at[..] else { return None };
    let mut out = bytes.to_vec();
    out[i..i + 8].copy_from_slice(&to);
    fix_checksum(&mut out);
    Some(out)
}

/// Whether `force` is the instance's `stress` times an area in the declared
/// range of `area`.
fn force_within_area_range(f: &Fmu, force: f64) -> bool {
    let (Some(stress), Some(area)) = (
        table().vars.iter().position(|v| v.name == "stress"),
        table().vars.iter().find(|v| v.name == "area"),
    ) else {
        return false;
    };
    let VarType::Real {
        min: Some(lo),
        max: Some(hi),
        ..
    } = area.ty
    else {
        return false;
    };
    let mut p = f64::NAN;
    let st = unsafe { (abi().get_real)(f.c, &(stress as u32), 1, &mut p) };
    st == fmi2OK && p != 0.0 && (lo..=hi).contains(&(force / p))
}

/// Deserialize and set `bytes` on `f`, which must succeed.
unsafe fn restore_bytes(f: &Fmu, bytes: &[u8]) {
    let mut s: fmi2FMUstate = null_mut();
    let p = bytes.as_ptr() as *const fmi2Byte;
    assert_eq!(
        (abi().deserialize_fmu_state)(f.c, p, bytes.len(), &mut s),
        fmi2OK
    );
    assert_eq!((abi().set_fmu_state)(f.c, s), fmi2OK);
    assert_eq!((abi().free_fmu_state)(f.c, &mut s), fmi2OK);
}

/// A stepped instance's state with one output's stored value forged (far
/// from the true one) is refused with the instance unchanged, or restores
/// the true value.
pub fn forged_stored_outputs_are_refused() {
    let f = initialized(0.0, 0.6);
    unsafe {
        let l = table().length0 + 0.02 * table().span;
        assert_eq!((abi().set_real)(f.c, &table().length, 1, &l), fmi2OK);
        assert_eq!((abi().do_step)(f.c, 0.0, 1e-3, fmi2True), fmi2OK);
    }
    let bytes = f.state_bytes().unwrap();
    let outputs = table().outputs.clone();
    let strategy = (
        prop::sample::select(outputs),
        prop::sample::select(vec![5.0, -0.5, -1.0, -3.0, 1e30, -1e30, 0.0, 2.0]),
    );
    properties::run_cases(cases(1, 4).max(16), &strategy, |(vr, value)| {
        let mut v = 0.0;
        prop_assert_eq!(unsafe { (abi().get_real)(f.c, &vr, 1, &mut v) }, fmi2OK);
        let name = var(vr).unwrap().name;
        let Some(forged) = forged(&bytes, v, value).filter(|_| v != value) else {
            return Ok(());
        };
        if v.abs() < 1e-12 || (value - v).abs() <= 1e-6 * v.abs().max(1.0) {
            return Ok(());
        }
        let mut s: fmi2FMUstate = null_mut();
        let st = unsafe {
            (abi().deserialize_fmu_state)(
                f.c,
                forged.as_ptr() as *const fmi2Byte,
                forged.len(),
                &mut s,
            )
        };
        if st != fmi2OK {
            let log = messages(&f);
            prop_assert_eq!(st, fmi2Error, "{} = {} (was {}): {}", name, value, v, log);
            prop_assert!(f.state_bytes().unwrap() == bytes, "{}: changed", name);
            return Ok(());
        }
        // Accepted: the restored instance must answer the true value.
        let mut after = f64::NAN;
        unsafe {
            prop_assert_eq!((abi().set_fmu_state)(f.c, s), fmi2OK);
            (abi().free_fmu_state)(f.c, &mut s);
            prop_assert_eq!((abi().get_real)(f.c, &vr, 1, &mut after), fmi2OK);
        }
        let within = name == "force" && force_within_area_range(&f, after);
        unsafe { restore_bytes(&f, &bytes) };
        // Documented exception (docs/reference/bad-input.md): a restored
        // force is checked as the stress times an area in the declared
        // range (the area may have been set since the step), not
        // recomputed, so a force forged within that range is taken.
        if within {
            return Ok(());
        }
        prop_assert!(
            after.to_bits() == v.to_bits(),
            "{} = {} restored from a forged state: {} (was {})",
            name,
            after,
            value,
            v
        );
        Ok(())
    });
}

/// Extreme activation input derivatives, positive and negative, over steps
/// of 1 and 10 ms from a command at either bound: `fmi2OK` or
/// `fmi2Discard`, and the activation level stays in [0, 1].
pub fn extreme_input_derivatives_keep_the_activation_level_in_range() {
    let level = table()
        .vars
        .iter()
        .position(|v| v.name == "activation_level")
        .map(|i| i as u32);
    let strategy = (
        prop::sample::select(vec![0.0, 1.0]),
        prop::sample::select(vec![1e3, -1e3, 1e6, -1e6, 1e300, -1e300, f64::MAX]),
        prop::sample::select(vec![1e-3, 1e-2]),
    );
    properties::run_cases(cases(1, 4).max(12), &strategy, |(u, du, h)| {
        let f = initialized(0.0, 0.5);
        let a = table().activation;
        let order: fmi2Integer = 1;
        unsafe {
            prop_assert_eq!((abi().set_real)(f.c, &a, 1, &u), fmi2OK);
            let st = (abi().set_real_input_derivatives)(f.c, &a, 1, &order, &du);
            prop_assert!(st == fmi2OK || st == fmi2Error, "{:?}", st);
            let st = (abi().do_step)(f.c, 0.0, h, fmi2True);
            let log = messages(&f);
            prop_assert!(
                st == fmi2OK || st == fmi2Warning || st == fmi2Discard,
                "u {} du/dt {} h {}: {:?} {}",
                u,
                du,
                h,
                st,
                log
            );
            if let Some(vr) = level {
                let mut x = f64::NAN;
                prop_assert_eq!((abi().get_real)(f.c, &vr, 1, &mut x), fmi2OK);
                prop_assert!((0.0..=1.0).contains(&x), "level {} (u {} du {})", x, u, du);
            }
        }
        Ok(())
    });
}

/// From start times at which a 1 ms step cannot advance the time (and a
/// huge one at which a step of 1 s cannot either): `fmi2DoStep` is
/// `fmi2Error` naming the step, the instance unchanged.
pub fn a_step_that_does_not_advance_the_time_is_refused() {
    let strategy =
        prop::sample::select(vec![(1e16, 1e-3), (1e17, 1e-3), (1e20, 1.0), (1e300, 1.0)]);
    properties::run_cases(4, &strategy, |(t0, h)| {
        let f = initialized(t0, 0.0);
        let before = f.state_bytes().unwrap();
        let st = unsafe { (abi().do_step)(f.c, t0, h, fmi2True) };
        let log = messages(&f);
        prop_assert_eq!(st, fmi2Error, "t0 {} h {}: {}", t0, h, log);
        prop_assert!(log.contains("fmi2DoStep"), "{}", log);
        prop_assert!(f.state_bytes().unwrap() == before, "t0 {}: changed", t0);
        Ok(())
    });
}
