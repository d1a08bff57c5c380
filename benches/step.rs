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

use std::ffi::{c_char, c_int, c_uint, c_void, CStr, CString};
use std::io::Read;
use std::path::PathBuf;
use std::time::Instant;

use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hill1d::{Hill1D, Var, DEFAULT_L0};

const STEPS: usize = 200_000;
const REPEATS: usize = 7;
const H: f64 = 1e-4;

/// fmi2CallbackFunctions (FMI 2.0, fmi2FunctionTypes.h), declared here
/// independently of the crate's own definition. Null members are allowed by
/// this FMU (it never allocates through the importer and logs only when a
/// logger is given).
#[repr(C)]
struct Callbacks {
    logger: *const c_void,
    allocate: *const c_void,
    free: *const c_void,
    step_finished: *const c_void,
    env: *mut c_void,
}

type Instantiate = unsafe extern "C" fn(
    *const c_char,
    c_int,
    *const c_char,
    *const c_char,
    *const Callbacks,
    c_int,
    c_int,
) -> *mut c_void;
type Setup = unsafe extern "C" fn(*mut c_void, c_int, f64, f64, c_int, f64) -> c_int;
type Comp = unsafe extern "C" fn(*mut c_void) -> c_int;
type Free = unsafe extern "C" fn(*mut c_void);
type SetReal = unsafe extern "C" fn(*mut c_void, *const c_uint, usize, *const f64) -> c_int;
type GetReal = unsafe extern "C" fn(*mut c_void, *const c_uint, usize, *mut f64) -> c_int;
type DoStep = unsafe extern "C" fn(*mut c_void, f64, f64, c_int) -> c_int;

struct Api {
    _lib: *mut c_void,
    instantiate: Instantiate,
    setup: Setup,
    enter_init: Comp,
    exit_init: Comp,
    free: Free,
    set_real: SetReal,
    get_real: GetReal,
    do_step: DoStep,
}

unsafe fn sym<T: Copy>(lib: *mut c_void, name: &str) -> T {
    let c = CString::new(name).unwrap();
    let p = libc::dlsym(lib, c.as_ptr());
    assert!(!p.is_null(), "symbol {name} missing from the FMU binary");
    std::mem::transmute_copy(&p)
}

fn extract_binary() -> PathBuf {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let fmu = root.join("dist/HillMuscle1D.fmu");
    let file = std::fs::File::open(&fmu)
        .unwrap_or_else(|e| panic!("{}: {e} (run scripts/build_fmus.sh first)", fmu.display()));
    let mut zip = zip::ZipArchive::new(file).expect("FMU is a zip archive");
    let mut entry = zip
        .by_name("binaries/linux64/HillMuscle1D.so")
        .expect("linux64 binary in the FMU");
    let mut bytes = Vec::new();
    entry.read_to_end(&mut bytes).unwrap();
    let out = std::env::temp_dir().join(format!("HillMuscle1D-bench-{}.so", std::process::id()));
    std::fs::write(&out, bytes).unwrap();
    out
}

fn load() -> Api {
    let path = extract_binary();
    let c = CString::new(path.to_str().unwrap()).unwrap();
    unsafe {
        let lib = libc::dlopen(c.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL);
        assert!(
            !lib.is_null(),
            "dlopen failed: {:?}",
            CStr::from_ptr(libc::dlerror())
        );
        if std::env::var_os("KEEP_BENCH_SO").is_none() {
            let _ = std::fs::remove_file(&path);
        }
        Api {
            _lib: lib,
            instantiate: sym(lib, "fmi2Instantiate"),
            setup: sym(lib, "fmi2SetupExperiment"),
            enter_init: sym(lib, "fmi2EnterInitializationMode"),
            exit_init: sym(lib, "fmi2ExitInitializationMode"),
            free: sym(lib, "fmi2FreeInstance"),
            set_real: sym(lib, "fmi2SetReal"),
            get_real: sym(lib, "fmi2GetReal"),
            do_step: sym(lib, "fmi2DoStep"),
        }
    }
}

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
    let name = CString::new("bench").unwrap();
    let guid = CString::new(guid::<Hill1D>()).unwrap();
    let cb = Callbacks {
        logger: std::ptr::null(),
        allocate: std::ptr::null(),
        free: std::ptr::null(),
        step_finished: std::ptr::null(),
        env: std::ptr::null_mut(),
    };
    let inputs_vr = [vr_of("activation"), vr_of("length")];
    let outputs_vr = [vr_of("force"), vr_of("stress")];
    unsafe {
        let c = (api.instantiate)(name.as_ptr(), 1, guid.as_ptr(), std::ptr::null(), &cb, 0, 0);
        assert!(
            !c.is_null(),
            "fmi2Instantiate failed (stale dist/HillMuscle1D.fmu? rebuild it)"
        );
        assert_eq!((api.setup)(c, 0, 0.0, 0.0, 0, 0.0), 0);
        assert_eq!((api.enter_init)(c), 0);
        assert_eq!((api.exit_init)(c), 0);
        let mut out = [0.0; 2];
        let mut checksum = 0.0;
        let start = Instant::now();
        for i in 0..STEPS {
            let (a, l) = inputs(i);
            let vals = [a, l];
            let s1 = (api.set_real)(c, inputs_vr.as_ptr(), 2, vals.as_ptr());
            let s2 = (api.do_step)(c, i as f64 * H, H, 1);
            let s3 = (api.get_real)(c, outputs_vr.as_ptr(), 2, out.as_mut_ptr());
            // Checked in the timed loop (a failed step must not pass as a fast one).
            assert!(
                s1 == 0 && s2 == 0 && s3 == 0,
                "step {i}: statuses {s1} {s2} {s3}"
            );
            checksum += out[0];
        }
        let ns = start.elapsed().as_nanos() as f64 / STEPS as f64;
        (api.free)(c);
        (ns, checksum)
    }
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

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn main() {
    // `cargo bench` passes --bench; `cargo test --benches` would pass nothing
    // useful; run the measurement either way.
    let api = load();
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
