//! Wall time of the FE muscle's most expensive legal calls, in-process
//! through the functions the exported `fmi2Xxx` symbols forward to
//! (`hill_muscle::fmi2::api`): one step of `HillMuscleFE` on its default
//! mesh from rest into extreme legal inputs (activated length jumps at
//! several step sizes, with and without adaptive substeps), and one column
//! of `fmi2GetDirectionalDerivative` with respect to a parameter in
//! initialization mode. Prints each call's status and time; the figures
//! are in docs/reference/bad-input.md ("Work bounds").
//!
//!     cargo run --release --example fe_work_bounds

use std::ffi::CString;
use std::ptr::null;
use std::time::Instant;

use hill_muscle::fmi2::api;
use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::types::*;
use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hillfe::HillFE;

fn vr(name: &str) -> fmi2ValueReference {
    HillFE::variables()
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}")) as fmi2ValueReference
}

/// A new instance in initialization mode with the Real `reals` and
/// Boolean `bools` set.
fn entered(reals: &[(&str, f64)], bools: &[(&str, bool)]) -> fmi2Component {
    let name = CString::new("work").unwrap();
    let g = CString::new(guid::<HillFE>()).unwrap();
    unsafe {
        let c = api::instantiate::<HillFE>(
            name.as_ptr(),
            fmi2CoSimulation,
            g.as_ptr(),
            null(),
            null(),
            fmi2False,
            fmi2False,
        );
        assert!(!c.is_null());
        for &(n, v) in bools {
            let b = if v { fmi2True } else { fmi2False };
            assert_eq!(api::set_boolean::<HillFE>(c, &vr(n), 1, &b), fmi2OK);
        }
        for &(n, v) in reals {
            assert_eq!(api::set_real::<HillFE>(c, &vr(n), 1, &v), fmi2OK, "{n}");
        }
        assert_eq!(
            api::setup_experiment::<HillFE>(c, fmi2False, 0.0, 0.0, fmi2False, 0.0),
            fmi2OK
        );
        assert_eq!(api::enter_initialization_mode::<HillFE>(c), fmi2OK);
        c
    }
}

fn main() {
    let l0 = 0.05;
    println!("one step from rest on the default mesh (16 x 3), activation 1:");
    for adaptive in [false, true] {
        for (stretch, h) in [
            (5.0, 1e-3),
            (5.0, 0.1),
            (1.3, 1e-3),
            (1.3, 0.1),
            (1.3, 1.0),
            (0.3, 0.1),
        ] {
            let c = entered(&[("activation", 1.0)], &[("adaptive_substeps", adaptive)]);
            unsafe {
                assert_eq!(api::exit_initialization_mode::<HillFE>(c), fmi2OK);
                let length = stretch * l0;
                assert_eq!(
                    api::set_real::<HillFE>(c, &vr("length"), 1, &length),
                    fmi2OK
                );
                let started = Instant::now();
                let status = api::do_step::<HillFE>(c, 0.0, h, fmi2True);
                let wall = started.elapsed().as_secs_f64();
                let mut solves = 0;
                api::get_integer::<HillFE>(c, &vr("newton_iterations"), 1, &mut solves);
                println!(
                    "  adaptive {adaptive:5}  {stretch} L0, h = {h:e} s: {status:?} in {wall:.2} s ({solves} solves)"
                );
                api::free_instance::<HillFE>(c);
            }
        }
    }
    println!("d(force)/d(parameter) in initialization mode, default mesh, activation 1:");
    for param in ["sigma0", "L0"] {
        let c = entered(&[("activation", 1.0)], &[]);
        let (k, u) = (vr(param), vr("force"));
        let (dk, mut du) = (1.0, 0.0);
        unsafe {
            // The initial values first (not timed), then one column.
            api::get_real::<HillFE>(c, &u, 1, &mut du);
            let started = Instant::now();
            let status = api::get_directional_derivative::<HillFE>(c, &u, 1, &k, 1, &dk, &mut du);
            println!(
                "  {param}: {status:?} in {:.2} s",
                started.elapsed().as_secs_f64()
            );
            api::free_instance::<HillFE>(c);
        }
    }
}
