//! Regressions: the bugs this harness found, fixed.

use super::*;

/// A parameter's value in the parameter-bound test.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Value {
    Real(f64),
    Integer(i32),
}

/// A new instance with [`Subject::SOLVER_INTEGERS`] and one parameter set
/// to `value`, initialized: `Ok(instance)`, or, where the subject's
/// initialization may refuse in-range parameters
/// ([`Subject::INIT_MAY_FAIL`]), `Err(message)` after checking that the
/// refusal is an `fmi2Error` with a message that left the instance in
/// initialization mode, unchanged.
pub(crate) fn initialized_with(name: &str, value: Value) -> Result<Fmu, (Fmu, String)> {
    let f = Fmu::new(false);
    let vr = vr_named(name);
    unsafe {
        set_integers(f.c, profile().solver_integers).unwrap();
        let st = match value {
            Value::Real(x) => (abi().set_real)(f.c, &vr, 1, &x),
            Value::Integer(i) => (abi().set_integer)(f.c, &vr, 1, &i),
        };
        assert_eq!(st, fmi2OK, "{name} = {value:?}");
        assert_eq!((abi().enter_initialization_mode)(f.c), fmi2OK);
        let before = f.state_bytes().unwrap();
        f.book.clear();
        let st = (abi().exit_initialization_mode)(f.c);
        if st == fmi2OK {
            return Ok(f);
        }
        let log = f.book.take();
        if !profile().init_may_fail {
            panic!("{name} = {value:?}: initialization {st:?} {log:?}");
        }
        assert_eq!(st, fmi2Error, "{name} = {value:?}: {log:?}");
        let why = log
            .iter()
            .find(|e| {
                e.status == fmi2Error
                    && e.message
                        .starts_with("fmi2ExitInitializationMode: initialization failed: ")
            })
            .map(|e| e.message.clone());
        let Some(why) = why else {
            panic!("{name} = {value:?}: initialization refused without a message: {log:?}");
        };
        assert!(
            f.state_bytes().unwrap() == before,
            "{name} = {value:?}: the refused initialization changed the instance"
        );
        Err((f, why))
    }
}

/// `fmi2GetFMUstate` + `fmi2SerializeFMUstate` + `fmi2DeSerializeFMUstate`
/// of the instance's current state: the status, the log and the bytes.
pub fn round_trip_status(f: &Fmu) -> (fmi2Status, Vec<Entry>, Vec<u8>) {
    let mut s: fmi2FMUstate = null_mut();
    assert_eq!(unsafe { (abi().get_fmu_state)(f.c, &mut s) }, fmi2OK);
    let bytes = f.serialize_state(s).unwrap();
    let mut d: fmi2FMUstate = null_mut();
    let st = unsafe {
        (abi().deserialize_fmu_state)(f.c, bytes.as_ptr() as *const fmi2Byte, bytes.len(), &mut d)
    };
    (st, f.book.take(), bytes)
}

/// The declared `min`/`max` of every Real parameter.
pub(crate) fn parameter_bounds() -> Vec<(&'static str, f64, f64)> {
    table()
        .vars
        .iter()
        .filter(|v| v.causality == Causality::Parameter)
        .filter_map(|v| match v.ty {
            VarType::Real {
                min: Some(lo),
                max: Some(hi),
                ..
            } => Some((v.name, lo, hi)),
            _ => None,
        })
        .collect()
}

/// The declared `min`/`max` of every Integer parameter.
pub(crate) fn integer_parameter_bounds() -> Vec<(&'static str, i32, i32)> {
    table()
        .vars
        .iter()
        .filter(|v| v.causality == Causality::Parameter)
        .filter_map(|v| match v.ty {
            VarType::Integer {
                min: Some(lo),
                max: Some(hi),
                ..
            } => Some((v.name, lo, hi)),
            _ => None,
        })
        .collect()
}

/// Found by `random_call_sequences` (and by `corrupt_fmu_states`): a
/// parameter that was positive and finite, hence accepted, but so small
/// that a derived value overflowed — `alpha` or `beta` = `f64::MIN_POSITIVE`
/// (the SEE stiffness alpha·beta underflowed: ±inf/NaN in the Jacobian and
/// the predictor, a step completing with a CE stretch of -9.5e289),
/// `L0` = 5e-324 (the Jacobian's 1/L0 was inf) — so the FMU's own
/// serialized state was refused by its own `fmi2DeSerializeFMUstate`. Fixed
/// by giving every parameter a closed physical range (declared as min/max in
/// the modelDescription): such values are now refused when set, with a
/// message that names the parameter and the range. Integer parameters
/// (`HillMuscleFE`'s mesh and fibre layout) likewise.
pub fn out_of_range_parameters_are_refused_naming_the_range() {
    let bounds = parameter_bounds();
    assert!(bounds.len() >= 16, "{bounds:?}");
    for (name, lo, hi) in bounds {
        let vr = table().vars.iter().position(|v| v.name == name).unwrap() as u32;
        let below = if lo > 0.0 { lo * 0.5 } else { lo - 1.0 };
        let above = if hi > 0.0 { hi * 2.0 } else { hi * 0.5 };
        let f = Fmu::new(false);
        for bad in [below, above, f64::MIN_POSITIVE, 5e-324, -5e-324] {
            if (lo..=hi).contains(&bad) {
                continue;
            }
            let st = unsafe { (abi().set_real)(f.c, &vr, 1, &bad) };
            assert_eq!(st, fmi2Error, "{name} = {bad:e} accepted");
            let log = f.book.take();
            assert!(
                log.iter()
                    .any(|e| e.message.contains(name) && e.message.contains("in [")),
                "{name} = {bad:e}: {log:?}"
            );
        }
        assert_eq!(
            &f.state_bytes().unwrap(),
            fresh_bytes(),
            "{name}: refused values changed the instance"
        );
    }
    for (name, lo, hi) in integer_parameter_bounds() {
        let vr = vr_named(name);
        let f = Fmu::new(false);
        for bad in [
            lo.saturating_sub(1),
            hi.saturating_add(1),
            i32::MIN,
            i32::MAX,
        ] {
            if (lo..=hi).contains(&bad) {
                continue;
            }
            let st = unsafe { (abi().set_integer)(f.c, &vr, 1, &bad) };
            assert_eq!(st, fmi2Error, "{name} = {bad} accepted");
            let log = f.book.take();
            assert!(
                log.iter()
                    .any(|e| e.message.contains(name)
                        && e.message.contains(&format!("in [{lo}, {hi}]"))),
                "{name} = {bad}: {log:?}"
            );
        }
        assert_eq!(
            &f.state_bytes().unwrap(),
            fresh_bytes(),
            "{name}: refused values changed the instance"
        );
    }
}

/// Every parameter at either end of its declared range (the others at their
/// defaults, with [`Subject::SOLVER_INTEGERS`]; Integer parameters up to
/// [`Subject::LARGEST_INTEGER_TRIED`]): initialization succeeds (or, with
/// [`Subject::INIT_MAY_FAIL`], is refused with a message, the instance
/// unchanged); steps that stretch and shorten the muscle at full activation
/// either complete with finite outputs and physical stretches (CE and SEE
/// stretch > 0) and finite directional derivatives, or are discarded with a
/// message; the FMU's own serialized state always deserializes.
pub fn every_parameter_at_either_bound_steps_and_round_trips() {
    let t = table();
    let vr = |n: &str| t.vars.iter().position(|v| v.name == n).map(|i| i as u32);
    let vr_real = |c: fmi2Component, n: &str| {
        let mut x = f64::NAN;
        if let Some(r) = vr(n) {
            unsafe { (abi().get_real)(c, &r, 1, &mut x) };
        }
        x
    };
    // The CE and SEE stretches where the model outputs them (a
    // musculotendon unit outputs its fibre length instead).
    let stretches = vr("ce_stretch").zip(vr("see_stretch"));
    let mut failures = Vec::new();
    let mut refused = Vec::new();
    let mut cases: Vec<(&str, Value)> = Vec::new();
    for (name, lo, hi) in parameter_bounds() {
        cases.extend([(name, Value::Real(lo)), (name, Value::Real(hi))]);
    }
    for (name, lo, hi) in integer_parameter_bounds() {
        for v in [lo, hi] {
            if v <= profile().largest_integer_tried {
                cases.push((name, Value::Integer(v)));
            }
        }
    }
    for (name, value) in cases {
        let f = match initialized_with(name, value) {
            Ok(f) => {
                let l0 = vr_real(f.c, "L0");
                // A unit's length is its path: the tendon at its slack
                // length, then the fibres (at the pennation angle).
                let (lts, alpha) = match vr("tendon_slack_length") {
                    Some(_) => (
                        vr_real(f.c, "tendon_slack_length"),
                        vr_real(f.c, "pennation_angle"),
                    ),
                    None => (0.0, 0.0),
                };
                let mut time = 0.0;
                for (k, stretch) in [1.0, 1.1, 1.2, 0.9, 1.0].into_iter().enumerate() {
                    let length = lts + stretch * l0 * alpha.cos();
                    unsafe {
                        (abi().set_real)(f.c, &t.activation, 1, &1.0);
                        (abi().set_real)(f.c, &t.length, 1, &length);
                        let st = (abi().do_step)(f.c, time, 1e-3, 0);
                        if st == fmi2OK {
                            time += 1e-3;
                            let mut out = vec![f64::NAN; t.outputs.len()];
                            (abi().get_real)(f.c, t.outputs.as_ptr(), out.len(), out.as_mut_ptr());
                            let (c, s) = match stretches {
                                Some(_) => {
                                    (vr_real(f.c, "ce_stretch"), vr_real(f.c, "see_stretch"))
                                }
                                None => (1.0, 1.0),
                            };
                            let d = &t.differentiated;
                            let mut dv = vec![f64::NAN; d.len()];
                            let dd = (abi().get_directional_derivative)(
                                f.c,
                                d.as_ptr(),
                                d.len(),
                                &t.activation,
                                1,
                                &1.0,
                                dv.as_mut_ptr(),
                            );
                            if !(out.iter().all(|x| x.is_finite()) && c > 0.0 && s > 0.0) {
                                failures.push(format!("{name} = {value:?}, step {k}: {out:?}"));
                            }
                            if dd == fmi2OK && !dv.iter().all(|x| x.is_finite()) {
                                failures.push(format!("{name} = {value:?}, step {k}: d/da {dv:?}"));
                            }
                        } else {
                            assert_eq!(st, fmi2Discard, "{name} = {value:?}");
                            assert!(!f.book.take().is_empty(), "discard without a message");
                            break;
                        }
                    }
                }
                f
            }
            Err((f, why)) => {
                refused.push(format!("{name} = {value:?}: {why}"));
                f
            }
        };
        f.book.clear();
        let (st, log, _) = round_trip_status(&f);
        if st != fmi2OK {
            failures.push(format!("{name} = {value:?}: round trip {st:?} {log:?}"));
        }
    }
    if !refused.is_empty() {
        eprintln!("initializations refused: {refused:#?}");
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Found by `random_call_sequences` with `API_ABUSE_ROUND_TRIP=1`. A legal
/// communication step of `h = 5e-324` (finite and > 0) while the length
/// input changes completes with `fmi2OK`, but the step predictor's history
/// rate (a change divided by h) overflows to ±inf and is committed: the
/// FMU's own serialized state is then rejected by `fmi2DeSerializeFMUstate`
/// ("a non-finite value"). Inputs: defaults; length its start + 0.2 of its span (`Table::span`), `fmi2DoStep(0,
/// 0.01)`; length its start, `fmi2DoStep(0.01, 5e-324)` → `fmi2OK`; serialize →
/// deserialize. Expected: `fmi2OK` (or the step refused or discarded with
/// a message). Was: `fmi2Error` (fixed: a rate that overflows is not committed, and a step whose partial derivatives are not finite is discarded).
pub fn tiny_step_leaves_a_serializable_state() {
    let t = table();
    let f = Fmu::new(false);
    unsafe {
        assert_eq!((abi().enter_initialization_mode)(f.c), fmi2OK);
        set_integers(f.c, profile().cheap_integers).unwrap();
        assert_eq!((abi().exit_initialization_mode)(f.c), fmi2OK);
        assert_eq!(
            (abi().set_real)(f.c, &t.length, 1, &(t.length0 + 0.2 * t.span)),
            fmi2OK
        );
        assert_eq!((abi().do_step)(f.c, 0.0, 0.01, 0), fmi2OK);
        assert_eq!((abi().set_real)(f.c, &t.length, 1, &t.length0), fmi2OK);
        let s = (abi().do_step)(f.c, 0.01, 5e-324, 0);
        f.book.clear();
        if s != fmi2OK {
            return; // refused or discarded: fine
        }
    }
    let (st, logs, _) = round_trip_status(&f);
    assert_eq!(st, fmi2OK, "{logs:?}");
}

/// Found by reading `do_step` while writing this harness, confirmed here. A
/// serialized state whose FMU time is NaN (crafted: the checksum is
/// recomputed) is accepted by `fmi2DeSerializeFMUstate` and
/// `fmi2SetFMUstate` (`decode_state` checks no value of the layer's part),
/// and then `fmi2DoStep` accepts any `currentCommunicationPoint`:
/// `(tc - NaN).abs() > tol` is false, so the documented "does not match the
/// FMU time" check never fires. Inputs: the pool state after 20 steps (stop
/// time 1.0) with the time field set to NaN; `fmi2DoStep(0.5, 1e-3)`.
/// Expected: the state refused at `fmi2DeSerializeFMUstate` (non-finite
/// time), or the step refused. Was: both `fmi2OK`, time NaN → 0.501 (fixed: `decode_state` checks the layer's times).
pub fn deserialized_state_with_non_finite_time_is_refused() {
    let f = Fmu::new(false);
    let mut b = pool()[P_RUN].clone();
    let at = state_code_offset() + 1; // the time follows the state code
    b[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    fix_checksum(&mut b);
    let mut s: fmi2FMUstate = null_mut();
    unsafe {
        let d = (abi().deserialize_fmu_state)(f.c, b.as_ptr() as *const fmi2Byte, b.len(), &mut s);
        if d != fmi2OK {
            return; // refused: fine
        }
        assert_eq!((abi().set_fmu_state)(f.c, s), fmi2OK);
        let step = (abi().do_step)(f.c, 0.5, 1e-3, 0);
        assert_eq!(step, fmi2Error, "tc = 0.5 accepted with the FMU time NaN");
    }
}

/// Found by a review probe (a crafted state, checksum recomputed). A
/// serialized state whose last step status is `fmi2Pending` (or any code
/// `fmi2DoStep` never leaves) was accepted, and `fmi2GetStatus
/// (fmi2DoStepStatus)` then reported an asynchronous step this FMU never
/// runs. Inputs: the pool state after 20 steps with the status byte set to
/// each of fmi2Pending and fmi2Fatal. Expected: `fmi2DeSerializeFMUstate`
/// refuses it, naming the status; the unmodified state is accepted. Was:
/// `fmi2OK` (fixed: `decode_state` accepts OK, Warning, Discard, Error).
pub fn deserialized_state_with_an_impossible_step_status_is_refused() {
    let f = Fmu::new(false);
    // After the state code: time, start, stop flag, stop, tolerance flag,
    // tolerance, last successful time, dirty (1 + 8 + 8 + 1 + 8 + 1 + 8 + 8 + 1).
    let at = state_code_offset() + 44;
    let good = pool()[P_RUN].clone();
    assert_eq!(
        good[at], fmi2OK as u8,
        "the status byte is not where expected"
    );
    for code in [fmi2OK as u8, fmi2Pending as u8, fmi2Fatal as u8] {
        let mut b = good.clone();
        b[at] = code;
        fix_checksum(&mut b);
        let mut s: fmi2FMUstate = null_mut();
        let d = unsafe {
            (abi().deserialize_fmu_state)(f.c, b.as_ptr() as *const fmi2Byte, b.len(), &mut s)
        };
        if code == fmi2OK as u8 {
            assert_eq!(d, fmi2OK, "the unmodified state was refused");
            continue;
        }
        assert_eq!(d, fmi2Error, "last step status {code} accepted");
        assert!(s.is_null());
        let logs = f.book.take();
        assert!(
            logs.iter().any(|e| e
                .message
                .contains(&format!("invalid last step status {code}"))),
            "{logs:?}"
        );
    }
}

/// Found by the second long run (`API_ABUSE_CASES=1000000`, default seed,
/// after 2,882 s): `fmi2SetupExperiment(startTime = f64::MAX, stopTime =
/// f64::MAX)`, initialization, `fmi2DoStep(f64::MAX, 1e300)` completed with
/// `fmi2OK` and the FMU time +inf (the stop-time test `tc + h > stop + tol`
/// is false when both sides overflow), a state the FMU's own deserializer
/// refuses. Now a step whose end `tc + h` is not finite is `fmi2Error`
/// naming it, nothing changed; the largest finite step from there is not.
pub fn a_step_to_an_infinite_time_is_refused() {
    let f = Fmu::new(false);
    let t0 = f64::MAX / 2.0;
    unsafe {
        assert_eq!(
            (abi().setup_experiment)(f.c, fmi2False, 0.0, t0, fmi2True, f64::MAX),
            fmi2OK
        );
        assert_eq!((abi().enter_initialization_mode)(f.c), fmi2OK);
        set_integers(f.c, profile().cheap_integers).unwrap();
        assert_eq!((abi().exit_initialization_mode)(f.c), fmi2OK);
    }
    let before = f.state_bytes().unwrap();
    f.book.clear();
    let st = unsafe { (abi().do_step)(f.c, t0, f64::MAX, 0) };
    let log = f.book.take();
    assert_eq!(st, fmi2Error, "{log:?}");
    assert!(
        log.iter().any(|e| e.message.contains("not a finite time")),
        "{log:?}"
    );
    assert!(f.state_bytes().unwrap() == before);
    // A finite end (f64::MAX itself) is a legal step.
    let st = unsafe { (abi().do_step)(f.c, t0, f64::MAX - t0, 0) };
    assert!(st == fmi2OK || st == fmi2Discard, "{st:?}");
    let (rt, log, _) = round_trip_status(&f);
    assert_eq!(rt, fmi2OK, "{log:?}");
}

/// Found by the long run (`API_ABUSE_CASES=1000000`, seed 0x4d75_7363_6c65):
/// `fmi2SetupExperiment(toleranceDefined = fmi2True, tolerance = NaN)` was
/// accepted, and the NaN kept in the layer (a state the layer cannot
/// compare with itself). Now a defined tolerance that is not finite and at
/// least 0 is `fmi2Error` naming it, nothing changed, and a crafted state
/// holding one is refused; an undefined tolerance is ignored whatever its
/// value, and 0 is accepted.
pub fn setup_experiment_with_a_non_finite_tolerance_is_refused() {
    for tol in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -1e-6] {
        let f = Fmu::new(false);
        let before = f.state_bytes().unwrap();
        let st = unsafe { (abi().setup_experiment)(f.c, fmi2True, tol, 0.0, fmi2False, 0.0) };
        let log = f.book.take();
        assert_eq!(st, fmi2Error, "tolerance {tol}");
        assert!(
            log.iter().any(|e| e.message.contains("tolerance = ")),
            "{log:?}"
        );
        assert!(f.state_bytes().unwrap() == before, "tolerance {tol}");
        // The same value in a serialized state (checksum recomputed).
        let mut b = before.clone();
        let at = state_code_offset() + 1 + 8 + 8 + 1 + 8; // time, start, stop flag, stop
        assert_eq!(b[at], 0, "the layout changed");
        b[at] = 1;
        b[at + 1..at + 9].copy_from_slice(&tol.to_le_bytes());
        fix_checksum(&mut b);
        let e = (installed().decode)(guid_str(), &b).err();
        assert!(
            e.is_some_and(|e| e.contains("tolerance")),
            "tolerance {tol} decodes"
        );
    }
    for (defined, tol) in [(fmi2False, f64::NAN), (fmi2True, 0.0), (fmi2True, 1e-6)] {
        let f = Fmu::new(false);
        let st = unsafe { (abi().setup_experiment)(f.c, defined, tol, 0.0, fmi2False, 0.0) };
        assert_eq!(st, fmi2OK, "toleranceDefined {defined}, tolerance {tol}");
        let (rt, log, _) = round_trip_status(&f);
        assert_eq!(rt, fmi2OK, "{log:?}");
    }
}
