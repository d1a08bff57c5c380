//! A host that traps floating-point exceptions (overflow, division by zero,
//! invalid) gets no SIGFPE from the FMUs on legal inputs: every entry point
//! computes in the default environment and gives the caller's back
//! (`fmi2::fp_env`). Driven in-process through the C-ABI functions with the
//! traps unmasked around every call: without the guard the steps below kill
//! the test process.
#![cfg(target_arch = "x86_64")]

use std::ffi::CString;
use std::ptr::null;

use hill_muscle::fmi2::api;
use hill_muscle::fmi2::fp_env::with_traps;
use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::types::*;
use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hill1d::Hill1D;

/// The value reference of variable `name` (its index in the table).
fn vr<M: Model>(name: &str) -> fmi2ValueReference {
    M::variables()
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}")) as fmi2ValueReference
}

/// `f` with traps on; panics if the call did not give the trapping
/// environment back.
fn trapped<T>(f: impl FnOnce() -> T) -> T {
    let (out, restored) = with_traps(f);
    assert!(
        restored,
        "the entry point did not restore the caller's FP environment"
    );
    out
}

/// An instance of `M` initialized at activation 1 with the Integer
/// parameters `ints`, then steps of 1 ms to each length of `lengths` (in
/// units of L0 = 0.05 m); every call made with traps on. Returns the
/// statuses of the steps.
fn run<M: Model>(ints: &[(&str, i32)], lengths: &[f64]) -> Vec<fmi2Status> {
    let name = CString::new("trapped").unwrap();
    let g = CString::new(guid::<M>()).unwrap();
    let c = trapped(|| unsafe {
        api::instantiate::<M>(
            name.as_ptr(),
            fmi2CoSimulation,
            g.as_ptr(),
            null(),
            null(),
            fmi2False,
            fmi2False,
        )
    });
    assert!(!c.is_null());
    let mut statuses = Vec::new();
    unsafe {
        for &(n, v) in ints {
            let s = trapped(|| api::set_integer::<M>(c, &vr::<M>(n), 1, &v));
            assert_eq!(s, fmi2OK, "{n}");
        }
        let s = trapped(|| api::setup_experiment::<M>(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
        assert_eq!(s, fmi2OK);
        assert_eq!(trapped(|| api::enter_initialization_mode::<M>(c)), fmi2OK);
        let one = 1.0;
        let s = trapped(|| api::set_real::<M>(c, &vr::<M>("activation"), 1, &one));
        assert_eq!(s, fmi2OK);
        assert_eq!(trapped(|| api::exit_initialization_mode::<M>(c)), fmi2OK);
        let mut t = 0.0;
        for &x in lengths {
            let l = 0.05 * x;
            let s = trapped(|| api::set_real::<M>(c, &vr::<M>("length"), 1, &l));
            assert_eq!(s, fmi2OK);
            let s = trapped(|| api::do_step::<M>(c, t, 1e-3, fmi2True));
            statuses.push(s);
            if s == fmi2OK {
                t += 1e-3;
            } else {
                // Back to the last good state for the next jump.
                break;
            }
            let mut force = 0.0;
            let s = trapped(|| api::get_real::<M>(c, &vr::<M>("force"), 1, &mut force));
            assert_eq!(s, fmi2OK);
            assert!(force.is_finite());
        }
        trapped(|| api::free_instance::<M>(c));
    }
    statuses
}

/// Length jumps the law cannot follow in one step end in fmi2Discard (or
/// fmi2OK), never in a trap: 5 L0 and 0.5 L0 activated, the 1D muscle.
#[test]
fn the_1d_fmu_raises_no_trap_on_extreme_length_jumps() {
    for jump in [5.0, 0.5, 1e-3, 100.0 / 0.05] {
        let statuses = run::<Hill1D>(&[], &[1.0, jump]);
        assert_eq!(statuses[0], fmi2OK);
        assert!(
            matches!(statuses[1], s if s == fmi2OK || s == fmi2Discard),
            "jump to {jump} L0: {statuses:?}"
        );
    }
}

/// The FE muscle (a small 4 x 1 mesh: the same element code) on an
/// activated 1.3 L0 jump and the extreme ones.
#[cfg(feature = "fe")]
#[test]
fn the_fe_fmu_raises_no_trap_on_extreme_length_jumps() {
    use hill_muscle::fmus::hillfe::HillFE;
    for jump in [1.3, 5.0, 0.5] {
        let statuses = run::<HillFE>(&[("n_axial", 4), ("n_radial", 1)], &[1.0, jump]);
        assert_eq!(statuses[0], fmi2OK);
        assert!(
            matches!(statuses[1], s if s == fmi2OK || s == fmi2Discard),
            "jump to {jump} L0: {statuses:?}"
        );
    }
}
