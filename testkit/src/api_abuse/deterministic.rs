//! Deterministic tests: every special value, every function and the
//! drifting clocks in every state; terminate/reset; the NULL environment and
//! NULL FMU state; parameter bounds.

use super::*;

pub fn free_instance_of_null_or_foreign_pointer_is_harmless() {
    unsafe {
        (abi().free_instance)(null_mut());
        let foreign = Box::new([0u64; 8]);
        (abi().free_instance)(&*foreign as *const [u64; 8] as *mut c_void);
        assert_eq!(*foreign, [0; 8]);
    }
    // And every function refuses them without touching anything.
    with_env(refused_without_an_instance);
}

pub(crate) fn refused_without_an_instance(env: &Env) {
    let mut f = Fmu::new(true);
    for comp in [Comp::Null, Comp::Foreign] {
        for call in [
            Call::Enter(comp),
            Call::Reset(comp),
            Call::Terminate(comp),
            Call::Step {
                comp,
                tc: 0.0,
                h: 1e-3,
                flag: 0,
            },
            Call::GetState {
                comp,
                out: StateOut::Slot(0),
            },
        ] {
            let o = exec(&mut f, env, &call);
            assert_eq!(o.status, fmi2Error, "{call:?}");
            assert!(o.untouched);
            assert!(f.book.take().is_empty());
        }
    }
    assert_eq!(&f.state_bytes().unwrap(), fresh_bytes());
}

/// The subject's cheap Integer parameters ([`Subject::CHEAP_INTEGERS`]), for
/// the `Init` of deterministic tests.
pub(crate) fn cheap() -> Vec<(u32, i32)> {
    integer_refs(profile().cheap_integers)
}

/// Prefixes that reach each state.
pub(crate) fn reach(state: FmiState) -> Vec<Op> {
    let t = table();
    let init = Op::Init {
        start: 0.0,
        stop: Some(10.0),
        integers: cheap(),
        inputs: vec![(t.activation, 0.5)],
    };
    let mut v = match state {
        FmiState::Instantiated => vec![],
        FmiState::InitializationMode => vec![
            Op::Call(Call::Setup {
                comp: Comp::Valid,
                tol_def: 0,
                tol: 0.0,
                start: 0.0,
                stop_def: 0,
                stop: 0.0,
            }),
            Op::Call(Call::Enter(Comp::Valid)),
        ],
        FmiState::StepComplete => vec![init],
        FmiState::StepFailed => {
            let mut v = vec![
                init,
                // The longest length the input takes (100 m): beyond what
                // the law can evaluate.
                Op::Call(set_real(vec![t.length], vec![100.0])),
            ];
            let rate = profile().failing_length_rate;
            if rate != 0.0 {
                v.push(Op::Call(Call::SetInputDer {
                    comp: Comp::Valid,
                    vrs: vec![t.length],
                    orders: vec![1],
                    vals: vec![rate],
                    ptrs: [Ptr::Ok; 3],
                    len: Len::Exact,
                }));
            }
            v.push(Op::Step {
                comp: Comp::Valid,
                tc: Tc::Exact,
                h: H::Lit(1e-3),
                flag: 0,
            });
            v
        }
        FmiState::Terminated => vec![init, Op::Call(Call::Terminate(Comp::Valid))],
        FmiState::Error => vec![Op::Restore(P_E)],
        FmiState::StepCanceled => vec![Op::Restore(P_SCA)],
        FmiState::Fatal => unreachable!(),
    };
    v.push(Op::ExpectState(state));
    v
}

/// Every state an instance can be driven into (all but `fatal`, the last).
pub(crate) const ALL_STATES: [FmiState; 7] = {
    let a = FmiState::ALL;
    [a[0], a[1], a[2], a[3], a[4], a[5], a[6]]
};

/// A variable of the special-value test.
#[derive(Clone, Copy)]
pub(crate) enum Target {
    Real(u32),
    Integer(u32),
}

/// Values of an Integer variable for the special-value test: the extremes,
/// 0, ±1, 2 and the values at and just outside either end of the declared
/// range, without in-range values above [`Subject::LARGEST_INTEGER_TRIED`].
pub(crate) fn special_integers(vr: u32) -> Vec<i32> {
    let (lo, hi) = int_range(vr);
    let mut v: Vec<i32> = [
        i32::MIN,
        -1,
        0,
        1,
        2,
        lo.saturating_sub(1),
        lo,
        lo.saturating_add(1),
        hi,
        hi.saturating_add(1),
        i32::MAX,
    ]
    .into_iter()
    .filter(|x| !(lo..=hi).contains(x) || *x <= profile().largest_integer_tried)
    .collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// Every Real variable × NaN, ±∞, ±0, negative, tiny, huge and ordinary
/// values, and every Integer variable × [`special_integers`], set alone and
/// together with an input, then the outputs read, a step and the variable
/// read, each value from the same saved state, in every state; then a reset
/// and a run. [`Subject::SPECIAL_VALUE_VARS_PER_SEQUENCE`] variables share
/// a sequence.
pub fn every_real_variable_with_every_special_value_in_every_state() {
    let t = table();
    let values = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        -1.0,
        -1e-300,
        -0.0,
        0.0,
        5e-324,
        1e-300,
        1e300,
        f64::MAX,
        0.5,
        1.0,
    ];
    let targets: Vec<Target> = t
        .reals
        .iter()
        .map(|&vr| Target::Real(vr))
        .chain(t.integers.iter().map(|&vr| Target::Integer(vr)))
        .collect();
    let step = Op::Step {
        comp: Comp::Valid,
        tc: Tc::Accumulated,
        h: H::Lit(1e-3),
        flag: 0,
    };
    for (k, state) in ALL_STATES.into_iter().enumerate() {
        let logging: &[bool] = match (profile().special_value_both_logging, k % 2) {
            (true, _) => &[false, true],
            (false, 0) => &[false],
            (false, _) => &[true],
        };
        for group in targets.chunks(profile().special_value_vars_per_sequence) {
            for &logging_on in logging {
                // Each value from the same saved state.
                let mut ops = reach(state);
                ops.push(Op::Call(Call::GetState {
                    comp: Comp::Valid,
                    out: StateOut::Slot(1),
                }));
                let restore = [
                    Op::Call(Call::SetState {
                        comp: Comp::Valid,
                        st: StateIn::Slot(1),
                    }),
                    Op::ExpectState(state),
                ];
                for &target in group {
                    match target {
                        Target::Real(vr) => {
                            for v in values {
                                ops.extend(restore.clone());
                                ops.push(Op::Call(set_real(vec![vr], vec![v])));
                                ops.push(Op::Call(set_real(vec![t.activation, vr], vec![0.5, v])));
                                ops.push(Op::Call(get(Ty::Real, t.outputs.clone())));
                                ops.push(step.clone());
                                ops.push(Op::Call(get(Ty::Real, vec![vr])));
                                if state == FmiState::InitializationMode {
                                    ops.push(Op::Call(Call::Exit(Comp::Valid)));
                                }
                            }
                        }
                        Target::Integer(vr) => {
                            for v in special_integers(vr) {
                                ops.extend(restore.clone());
                                ops.push(Op::Call(set_integer(vec![vr], vec![v])));
                                ops.push(Op::Call(get(Ty::Integer, vec![vr])));
                                ops.push(Op::Call(get(Ty::Real, t.outputs.clone())));
                                ops.push(step.clone());
                                ops.push(Op::Call(get(Ty::Integer, t.integers.clone())));
                                if state == FmiState::InitializationMode {
                                    ops.push(Op::Call(Call::Exit(Comp::Valid)));
                                }
                            }
                        }
                    }
                }
                ops.push(Op::Call(Call::Reset(Comp::Valid)));
                ops.push(Op::Init {
                    start: 0.0,
                    stop: None,
                    integers: cheap(),
                    inputs: vec![],
                });
                ops.push(Op::Run {
                    n: 3,
                    h: 1e-3,
                    tc: Tc::Accumulated,
                    amp: 0.05,
                    act: 1.0,
                });
                if let Err(e) = run_sequence(logging_on, &ops) {
                    let names: Vec<String> = group
                        .iter()
                        .map(|&g| match g {
                            Target::Real(vr) | Target::Integer(vr) => {
                                format!("{} (vr {vr})", t.vars[vr as usize].name)
                            }
                        })
                        .collect();
                    panic!(
                        "state {state:?}, variable {}, logging {logging_on}: {e}",
                        names.join(", ")
                    );
                }
            }
        }
    }
}

pub fn every_function_in_every_state_with_legal_and_illegal_arguments() {
    // Calls of every function, each run after reaching every state; the
    // harness checks the state table, the log messages and that rejected
    // calls change nothing.
    let t = table();
    let calls: Vec<Op> = vec![
        Op::Call(Call::Setup {
            comp: Comp::Valid,
            tol_def: 1,
            tol: 1e-6,
            start: 0.0,
            stop_def: 1,
            stop: 1.0,
        }),
        Op::Call(Call::Enter(Comp::Valid)),
        Op::Call(Call::Exit(Comp::Valid)),
        Op::Call(Call::Cancel(Comp::Valid)),
        Op::Call(Call::Logging {
            comp: Comp::Valid,
            on: 1,
            cats: vec![Cat::Known(4)],
            ptr: Ptr::Ok,
            len: Len::Exact,
        }),
        Op::Call(set_real(vec![t.activation], vec![0.25])),
        Op::Call(set_real(vec![0], vec![30.0])),
        Op::Call(get(Ty::Real, t.outputs.clone())),
        Op::Call(get(Ty::Boolean, vec![0])),
        Op::Call(Call::SetBoolean {
            comp: Comp::Valid,
            vrs: vec![],
            vals: vec![],
            ptrs: [Ptr::Null; 2],
            len: Len::Exact,
        }),
        Op::Call(Call::GetState {
            comp: Comp::Valid,
            out: StateOut::Slot(0),
        }),
        Op::Call(Call::StateSize {
            comp: Comp::Valid,
            st: StateIn::Slot(0),
            null: false,
        }),
        Op::Serialize {
            comp: Comp::Valid,
            st: StateIn::Slot(0),
            buf: Buf::Exact,
        },
        Op::Deserialize {
            comp: Comp::Valid,
            src: Src::Current,
            mutation: Mutation::None,
            size: Size::Exact,
            ptr: Ptr::Ok,
            out: StateOut::Slot(1),
        },
        Op::Call(Call::SetState {
            comp: Comp::Valid,
            st: StateIn::Slot(1),
        }),
        Op::Call(Call::FreeState {
            comp: Comp::Valid,
            out: StateOut::Slot(1),
        }),
        Op::Call(Call::DirDeriv {
            comp: Comp::Valid,
            unknowns: t.outputs.clone(),
            knowns: vec![t.length],
            dv: vec![1.0],
            ptrs: [Ptr::Ok; 4],
            len: Len::Exact,
        }),
        Op::Call(Call::SetInputDer {
            comp: Comp::Valid,
            vrs: vec![t.length],
            orders: vec![1],
            vals: vec![0.01],
            ptrs: [Ptr::Ok; 3],
            len: Len::Exact,
        }),
        Op::Call(Call::GetOutputDer {
            comp: Comp::Valid,
            vrs: vec![],
            orders: vec![],
            ptrs: [Ptr::Ok; 3],
            len: Len::Exact,
        }),
        Op::Step {
            comp: Comp::Valid,
            tc: Tc::Exact,
            h: H::Lit(1e-3),
            flag: 0,
        },
        Op::Call(Call::Status {
            comp: Comp::Valid,
            func: StatusFn::Status,
            kind: fmi2DoStepStatus,
            null: false,
        }),
        Op::Call(Call::Status {
            comp: Comp::Valid,
            func: StatusFn::String,
            kind: fmi2PendingStatus,
            null: false,
        }),
        Op::Call(Call::Terminate(Comp::Valid)),
        Op::Call(Call::Terminate(Comp::Valid)),
        Op::Call(Call::Reset(Comp::Valid)),
        Op::Call(Call::Reset(Comp::Valid)),
    ];
    // Integer variables and a subset of differentiated outputs, where the
    // model has them.
    let mut calls = calls;
    if !t.integers.is_empty() {
        let (vrs, vals): (Vec<u32>, Vec<i32>) = cheap().into_iter().unzip();
        calls.push(Op::Call(set_integer(vrs, vals)));
        calls.push(Op::Call(get(Ty::Integer, t.integers.clone())));
    }
    if t.differentiated != t.outputs {
        calls.push(Op::Call(Call::DirDeriv {
            comp: Comp::Valid,
            unknowns: t.differentiated.clone(),
            knowns: vec![t.length, t.activation],
            dv: vec![1.0, 0.5],
            ptrs: [Ptr::Ok; 4],
            len: Len::Exact,
        }));
    }
    let after = [
        Op::Init {
            start: 0.0,
            stop: None,
            integers: cheap(),
            inputs: vec![],
        },
        Op::Run {
            n: 2,
            h: 1e-3,
            tc: Tc::Accumulated,
            amp: 0.0,
            act: 1.0,
        },
    ];
    for state in ALL_STATES {
        if profile().functions_per_sequence == 1 {
            for call in &calls {
                let mut ops = reach(state);
                ops.push(call.clone());
                ops.extend(after.clone());
                if let Err(e) = run_sequence(false, &ops) {
                    panic!("state {state:?}, {call:?}: {e}");
                }
            }
            continue;
        }
        // Several calls per sequence, each from the same saved state (slot
        // 2, which no call uses).
        for group in calls.chunks(profile().functions_per_sequence) {
            let mut ops = reach(state);
            ops.push(Op::Call(Call::GetState {
                comp: Comp::Valid,
                out: StateOut::Slot(2),
            }));
            for call in group {
                ops.push(Op::Call(Call::SetState {
                    comp: Comp::Valid,
                    st: StateIn::Slot(2),
                }));
                ops.push(Op::ExpectState(state));
                ops.push(call.clone());
                ops.extend(after.clone());
            }
            if let Err(e) = run_sequence(false, &ops) {
                panic!("state {state:?}, one of {group:?}: {e}");
            }
        }
    }
}

/// A master that keeps `t += h` and one that computes `t0 + i * h`,
/// alternating, over [`Subject::DRIFT_STEPS`] steps per case: every step
/// must be accepted.
/// Then jumps and steps past the stop time are rejected and change nothing.
pub fn drifting_communication_points_are_accepted_and_jumps_rejected() {
    let t = table();
    for (t0, h) in [
        (0.0, 1e-4),
        (1e3, 1e-3),
        (-50.0, 1.0 / 3.0 * 1e-2),
        (1e6, 1e-3),
    ] {
        let n = profile().drift_steps;
        let stop = t0 + n as f64 * h;
        let f = Fmu::new(false);
        let c = f.c;
        unsafe {
            assert_eq!((abi().setup_experiment)(c, 0, 0.0, t0, 1, stop), fmi2OK);
            assert_eq!((abi().enter_initialization_mode)(c), fmi2OK);
            set_integers(c, profile().cheap_integers).unwrap();
            assert_eq!((abi().exit_initialization_mode)(c), fmi2OK);
            assert_eq!((abi().set_real)(c, &t.activation, 1, &1.0), fmi2OK);
        }
        let mut acc = t0;
        let mut max_drift = 0.0f64;
        for i in 0..n {
            let mult = t0 + i as f64 * h;
            max_drift = max_drift.max((mult - acc).abs());
            let tc = if i % 2 == 0 { acc } else { mult };
            // The last step ends at the stop time up to the drift.
            let hh = if i + 1 == n { stop - tc } else { h };
            let s = unsafe { (abi().do_step)(c, tc, hh, 1) };
            assert_eq!(
                s,
                fmi2OK,
                "t0 = {t0}, h = {h}, step {i}, tc = {tc}: {:?}",
                f.book.take()
            );
            acc += h;
        }
        let before = f.state_bytes().unwrap();
        let layer = layer_of(&before).unwrap();
        let tn = layer.time;
        assert!(
            (tn - stop).abs() <= 1e-9 * stop.abs().max(1.0),
            "{tn} vs {stop}"
        );
        let tol = api::time_tolerance(tn, h);
        for (tc, hh) in [
            (tn, 1.0 + 10.0 * tol), // past the stop time
            (tn - 1.0, h),          // a jump back
            (tn + 3.0 * tol, 1e-9), // a jump forward
            (tn, -h),
            (tn, 0.0),
            (f64::NAN, h),
        ] {
            f.book.clear();
            let s = unsafe { (abi().do_step)(c, tc, hh, 1) };
            assert_eq!(s, fmi2Error, "tc = {tc}, h = {hh}");
            let logs = f.book.take();
            assert!(
                logs.iter()
                    .any(|e| e.status == fmi2Error && e.message.starts_with("fmi2DoStep: ")),
                "{logs:?}"
            );
            assert_eq!(f.state_bytes().unwrap(), before, "tc = {tc}, h = {hh}");
        }
        // Max drift seen (both clocks within the tolerance all along).
        assert!(max_drift <= 1e-9 * stop.abs().max(1.0), "{max_drift}");
    }
}

pub fn repeated_terminate_and_reset_and_reset_in_every_state() {
    for state in ALL_STATES {
        let mut ops = reach(state);
        for _ in 0..3 {
            ops.push(Op::Call(Call::Terminate(Comp::Valid)));
        }
        for _ in 0..3 {
            ops.push(Op::Call(Call::Reset(Comp::Valid)));
        }
        ops.push(Op::ExpectState(FmiState::Instantiated));
        ops.push(Op::Init {
            start: 0.5,
            stop: Some(1.0),
            integers: cheap(),
            inputs: vec![],
        });
        ops.push(Op::Run {
            n: 10,
            h: 1e-2,
            tc: Tc::Multiplied,
            amp: 0.1,
            act: 1.0,
        });
        ops.push(Op::Call(Call::Terminate(Comp::Valid)));
        ops.push(Op::Call(Call::Terminate(Comp::Valid)));
        ops.push(Op::Call(Call::Reset(Comp::Valid)));
        ops.push(Op::Init {
            start: 0.5,
            stop: Some(1.0),
            integers: cheap(),
            inputs: vec![],
        });
        ops.push(Op::Run {
            n: 50,
            h: 1e-2,
            tc: Tc::Accumulated,
            amp: 0.1,
            act: 1.0,
        });
        ops.push(Op::Step {
            comp: Comp::Valid,
            tc: Tc::Exact,
            h: H::PastStop(1e-3),
            flag: 0,
        });
        if let Err(e) = run_sequence(true, &ops) {
            panic!("from {state:?}: {e}");
        }
    }
}

/// What [`null_env_logger`] received, call by call: (componentEnvironment
/// as an address, instance name, status, category, format, message).
pub(crate) type NullEnvEntry = (usize, Vec<u8>, fmi2Status, String, String, String);

pub(crate) static NULL_ENV_LOG: Mutex<Vec<NullEnvEntry>> = Mutex::new(Vec::new());

/// Like [`test_logger`], but it records every call whatever the environment
/// pointer (the book cannot be reached through it: it is NULL). Used only by
/// [`null_component_environment_is_passed_to_the_logger`].
pub(crate) unsafe extern "C" fn null_env_logger(
    env: fmi2ComponentEnvironment,
    instance_name: fmi2String,
    status: fmi2Status,
    category: fmi2String,
    message: fmi2String,
    arg: *const c_char,
) {
    let e = (
        env as usize,
        c_bytes(instance_name),
        status,
        c_text(category),
        c_text(message),
        c_text(arg),
    );
    if let Ok(mut g) = NULL_ENV_LOG.lock() {
        g.push(e);
    }
}

/// FMI 2.0 §2.1.5: componentEnvironment is the importer's pointer, passed back
/// unchanged as the logger's first argument; NULL is a legal value. With a
/// live logger and a NULL environment, `fmi2Instantiate` must work, and every
/// message (the refusal of a wrong GUID, the debug message at creation, the
/// error of an illegal call, ...) must reach the logger with that NULL
/// environment and the given instance name, without a crash.
pub fn null_component_environment_is_passed_to_the_logger() {
    let t = table();
    let take = || std::mem::take(&mut *NULL_ENV_LOG.lock().unwrap());
    let name = c"null env #2 %s";
    let check_all = |logs: &[NullEnvEntry]| {
        assert!(!logs.is_empty(), "the logger was not called");
        for e in logs {
            assert_eq!(e.0, 0, "componentEnvironment not passed through: {e:?}");
            assert_eq!(e.1, name.to_bytes(), "instance name: {e:?}");
            assert_eq!(e.4, "%s", "format: {e:?}");
        }
    };
    let cb = callbacks_with(null_env_logger, null_mut());
    assert!(cb.componentEnvironment.is_null() && cb.logger.is_some());
    take();

    // Refused: the reason still reaches the logger.
    let c = unsafe {
        (abi().instantiate)(
            name.as_ptr(),
            fmi2CoSimulation,
            c"{00000000-0000-0000-0000-000000000000}".as_ptr(),
            null(),
            &cb,
            fmi2False,
            fmi2True,
        )
    };
    assert!(c.is_null());
    let logs = take();
    check_all(&logs);
    assert!(
        logs.iter().any(|e| e.2 == fmi2Error
            && e.3 == "logStatusError"
            && e.5.starts_with("fmi2Instantiate: ")
            && e.5.contains("does not match")),
        "{logs:?}"
    );

    // Accepted, logging on: a life with one illegal call in it.
    let c = unsafe {
        (abi().instantiate)(
            name.as_ptr(),
            fmi2CoSimulation,
            t.guid.as_ptr(),
            null(),
            &cb,
            fmi2False,
            fmi2True,
        )
    };
    assert!(!c.is_null(), "{:?}", take());
    let mut out = vec![f64::NAN; t.outputs.len()];
    unsafe {
        assert_eq!((abi().do_step)(c, 0.0, 1e-3, fmi2True), fmi2Error);
        assert_eq!(
            (abi().setup_experiment)(c, fmi2False, 0.0, 0.0, fmi2True, 1.0),
            fmi2OK
        );
        assert_eq!((abi().enter_initialization_mode)(c), fmi2OK);
        set_integers(c, profile().cheap_integers).unwrap();
        assert_eq!((abi().exit_initialization_mode)(c), fmi2OK);
        let (vrs, vals) = ([t.activation, t.length], [1.0, t.length0 + 0.05 * t.span]);
        assert_eq!((abi().set_real)(c, vrs.as_ptr(), 2, vals.as_ptr()), fmi2OK);
        assert_eq!((abi().do_step)(c, 0.0, 1e-3, fmi2True), fmi2OK);
        assert_eq!(
            (abi().get_real)(c, t.outputs.as_ptr(), t.outputs.len(), out.as_mut_ptr()),
            fmi2OK
        );
        (abi().free_instance)(c);
    }
    assert!(out.iter().all(|v| v.is_finite()), "{out:?}");
    let logs = take();
    check_all(&logs);
    assert!(
        logs.iter()
            .any(|e| e.2 == fmi2OK && e.5.contains("fmi2Instantiate: instance created")),
        "the debug message at creation: {logs:?}"
    );
    assert!(
        logs.iter().any(|e| e.2 == fmi2Error
            && e.5.starts_with("fmi2DoStep: ")
            && e.5.contains("not allowed in state")),
        "the illegal step's error: {logs:?}"
    );
}

/// `fmi2SetFMUstate(c, NULL)`: `fmi2Error` naming the NULL argument, and the
/// instance is unchanged — its serialized state and outputs are as before,
/// its FMI state is kept (it steps on), and it continues bit for bit like a
/// twin that never saw the call. Then the same through the harness from
/// every FMI state (which checks properties 2, 4 and 5 of the module docs).
pub fn set_fmu_state_with_null_pointer_is_an_error_and_changes_nothing() {
    let t = table();
    let outputs = |f: &Fmu| {
        let mut v = vec![f64::NAN; t.outputs.len()];
        let s =
            unsafe { (abi().get_real)(f.c, t.outputs.as_ptr(), t.outputs.len(), v.as_mut_ptr()) };
        assert_eq!(s, fmi2OK);
        bits_f64(&v)
    };
    let step = |f: &Fmu, i: usize| unsafe {
        let h = 1e-3;
        let vrs = [t.activation, t.length];
        let vals = [1.0, t.length0 + 0.01 * i as f64 * t.span];
        assert_eq!(
            (abi().set_real)(f.c, vrs.as_ptr(), 2, vals.as_ptr()),
            fmi2OK
        );
        assert_eq!((abi().do_step)(f.c, i as f64 * h, h, fmi2True), fmi2OK);
    };
    let drive = |bad_call: bool| {
        let mut f = Fmu::new(true);
        unsafe {
            assert_eq!((abi().enter_initialization_mode)(f.c), fmi2OK);
            set_integers(f.c, profile().cheap_integers).unwrap();
            assert_eq!((abi().exit_initialization_mode)(f.c), fmi2OK);
            // A saved state exists (slot 0): "unchanged" must not mean "restored".
            assert_eq!((abi().get_fmu_state)(f.c, &mut f.slots[0]), fmi2OK);
        }
        (0..10).for_each(|i| step(&f, i));
        if bad_call {
            let before = f.state_bytes().unwrap();
            let out_before = outputs(&f);
            f.book.clear();
            assert_eq!(unsafe { (abi().set_fmu_state)(f.c, null_mut()) }, fmi2Error);
            let logs = f.book.take();
            assert!(
                logs.iter().any(|e| e.status == fmi2Error
                    && e.category == "logStatusError"
                    && e.message.starts_with("fmi2SetFMUstate: FMUstate is NULL")),
                "{logs:?}"
            );
            assert_eq!(f.state_bytes().unwrap(), before, "the instance changed");
            assert_eq!(outputs(&f), out_before);
        }
        (10..20).for_each(|i| step(&f, i));
        (outputs(&f), f.state_bytes().unwrap())
    };
    let (with, without) = (drive(true), drive(false));
    assert!(with == without, "the instance diverged from its twin");

    for state in ALL_STATES {
        for logging_on in [false, true] {
            let mut ops = reach(state);
            ops.push(Op::Call(Call::GetState {
                comp: Comp::Valid,
                out: StateOut::Slot(1),
            }));
            ops.push(Op::Call(Call::SetState {
                comp: Comp::Valid,
                st: StateIn::Null,
            }));
            ops.push(Op::ExpectState(state));
            ops.push(Op::Run {
                n: 3,
                h: 1e-3,
                tc: Tc::Accumulated,
                amp: 0.05,
                act: 1.0,
            });
            if let Err(e) = run_sequence(logging_on, &ops) {
                panic!("from {state:?}, logging {logging_on}: {e}");
            }
        }
    }
}
