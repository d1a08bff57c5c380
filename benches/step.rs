//! Per-step cost of `HillMuscle1D` through its C ABI, with a breakdown.
//!
//! Loads the binary of `dist/HillMuscle1D.fmu` (build it first with
//! `scripts/build_fmus.sh`) with dlopen and times, per communication step,
//! fmi2SetReal(activation, length) + fmi2DoStep + fmi2GetReal(force, stress)
//! over a stretch-and-release cycle with activation on. The same loop run on
//! the model directly (no FMI layer, no dynamic call) gives the law's share.
//!
//! `cargo bench --bench step` — prints a table and one JSON line. Median of
//! `REPEATS` runs; the machine is shared, so compare ratios within one run.

use std::ffi::c_uint;
use std::time::Instant;

use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hill1d::{Hill1D, Var, DEFAULT_L0};

use cabi::{load, median, Api, Instance};
use testkit::cabi;

const STEPS: usize = 200_000;
const REPEATS: usize = 7;
const H: f64 = 1e-4;

/// The driving signals: activation on from the start, a 2 Hz stretch-and-release
/// cycle of ±10 % around the rest length.
fn inputs(i: usize) -> (f64, f64) {
    let t = (i + 1) as f64 * H;
    (
        1.0,
        DEFAULT_L0 * (1.0 + 0.1 * (2.0 * std::f64::consts::PI * 2.0 * t).sin()),
    )
}

fn vr_of(name: &str) -> c_uint {
    Hill1D::variables()
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}")) as c_uint
}

/// ns per step through the C ABI.
fn time_fmi(api: &Api) -> (f64, f64) {
    let inputs_vr = [vr_of("activation"), vr_of("length")];
    let outputs_vr = [vr_of("force"), vr_of("stress")];
    let instance = Instance::new(api, &api.guid);
    let mut out = [0.0; 2];
    let mut checksum = 0.0;
    let start = Instant::now();
    for i in 0..STEPS {
        let (a, l) = inputs(i);
        instance.step(&inputs_vr, &[a, l], i as f64 * H, H, &outputs_vr, &mut out);
        checksum += out[0];
    }
    (start.elapsed().as_nanos() as f64 / STEPS as f64, checksum)
}

/// ns per step of the model alone (law + model bookkeeping, no FMI layer).
fn time_model() -> (f64, f64) {
    let mut m = Hill1D::new();
    m.initialize().unwrap();
    let mut checksum = 0.0;
    let start = Instant::now();
    for i in 0..STEPS {
        let (a, l) = inputs(i);
        m.set_real(Var::Activation, a).unwrap();
        m.set_real(Var::Length, l).unwrap();
        m.do_step(i as f64 * H, H).unwrap();
        checksum += m.get_real(Var::Out(hill_muscle::fmus::hill1d::Output::Force));
        std::hint::black_box(m.get_real(Var::Out(hill_muscle::fmus::hill1d::Output::Stress)));
    }
    (start.elapsed().as_nanos() as f64 / STEPS as f64, checksum)
}

fn main() {
    // `cargo bench` passes --bench; `cargo test --benches` would pass nothing
    // useful; run the measurement either way.
    let api = load("HillMuscle1D");
    let mut fmi = Vec::new();
    let mut law = Vec::new();
    for _ in 0..REPEATS {
        let (a, ca) = time_fmi(&api);
        let (b, cb) = time_model();
        assert!(
            (ca - cb).abs() <= 1e-9 * ca.abs(),
            "C ABI and direct model disagree: {ca} vs {cb}"
        );
        fmi.push(a);
        law.push(b);
    }
    let (f, l) = (median(fmi.clone()), median(law.clone()));
    println!("HillMuscle1D, {STEPS} steps of h = {H} s, stretch-and-release ±10 % at 2 Hz, activation 1; median of {REPEATS}");
    println!("  through the C ABI (SetReal + DoStep + GetReal): {f:8.1} ns/step   runs: {fmi:.0?}");
    println!("  model alone (law + bookkeeping):               {l:8.1} ns/step   runs: {law:.0?}");
    println!(
        "  FMI layer share:                                {:8.1} ns/step ({:.0} %)",
        f - l,
        100.0 * (f - l) / f
    );
    println!("{{\"bench\":\"hill1d_step\",\"fmi_ns\":{f:.1},\"model_ns\":{l:.1},\"steps\":{STEPS},\"repeats\":{REPEATS}}}");
}
