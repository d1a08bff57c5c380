//! Loading an FMU's binary from `dist/<id>.fmu` (at the repository's top
//! level) with dlopen and calling its FMI 2.0 C functions, for the
//! benchmarks. The C types are declared here independently of the crate's
//! own FMI layer, as an importer would. Entry points: [`load`], then
//! [`Instance`] for an initialized instance freed on drop.

use std::ffi::{c_char, c_int, c_uint, c_void, CStr, CString};
use std::io::Read;
use std::path::PathBuf;

/// fmi2CallbackFunctions (FMI 2.0, fmi2FunctionTypes.h). Null members are
/// allowed by these FMUs (they never allocate through the importer and log
/// only when a logger is given).
#[repr(C)]
pub struct Callbacks {
    pub logger: *const c_void,
    pub allocate: *const c_void,
    pub free: *const c_void,
    pub step_finished: *const c_void,
    pub env: *mut c_void,
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
type SetBoolean = unsafe extern "C" fn(*mut c_void, *const c_uint, usize, *const c_int) -> c_int;
type SetInteger = unsafe extern "C" fn(*mut c_void, *const c_uint, usize, *const c_int) -> c_int;
type GetInteger = unsafe extern "C" fn(*mut c_void, *const c_uint, usize, *mut c_int) -> c_int;
type DoStep = unsafe extern "C" fn(*mut c_void, f64, f64, c_int) -> c_int;
type SetRealInputDerivatives =
    unsafe extern "C" fn(*mut c_void, *const c_uint, usize, *const c_int, *const f64) -> c_int;
type GetDirectionalDerivative = unsafe extern "C" fn(
    *mut c_void,
    *const c_uint,
    usize,
    *const c_uint,
    usize,
    *const f64,
    *mut f64,
) -> c_int;

/// The functions a co-simulation loop calls.
pub struct Api {
    _lib: *mut c_void,
    /// The GUID of the FMU's modelDescription.xml, as an importer passes it
    /// (an older build under `HM_DIST` has its own).
    pub guid: String,
    pub instantiate: Instantiate,
    pub setup: Setup,
    pub enter_init: Comp,
    pub exit_init: Comp,
    pub free: Free,
    pub set_real: SetReal,
    pub get_real: GetReal,
    pub set_boolean: SetBoolean,
    pub set_integer: SetInteger,
    pub get_integer: GetInteger,
    pub do_step: DoStep,
    pub set_real_input_derivatives: SetRealInputDerivatives,
    pub get_directional_derivative: GetDirectionalDerivative,
}

unsafe fn sym<T: Copy>(lib: *mut c_void, name: &str) -> T {
    let c = CString::new(name).unwrap();
    let p = libc::dlsym(lib, c.as_ptr());
    assert!(!p.is_null(), "symbol {name} missing from the FMU binary");
    std::mem::transmute_copy(&p)
}

/// The binary of `<id>.fmu` extracted to a temporary file, and the FMU's GUID.
fn extract_binary(id: &str) -> (PathBuf, String) {
    // This crate sits one level below the repository's top level.
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("testkit/ has a parent directory")
        .to_path_buf();
    // HM_DIST names another dist/ (an older build, for side-by-side runs).
    let dist = std::env::var_os("HM_DIST").map_or(root.join("dist"), PathBuf::from);
    let fmu = dist.join(format!("{id}.fmu"));
    let file = std::fs::File::open(&fmu)
        .unwrap_or_else(|e| panic!("{}: {e} (run scripts/build_fmus.sh first)", fmu.display()));
    let mut zip = zip::ZipArchive::new(file).expect("FMU is a zip archive");
    let mut xml = String::new();
    zip.by_name("modelDescription.xml")
        .expect("modelDescription.xml in the FMU")
        .read_to_string(&mut xml)
        .unwrap();
    let guid = xml
        .split("guid=\"")
        .nth(1)
        .and_then(|rest| rest.split('"').next())
        .expect("a guid attribute in modelDescription.xml")
        .to_string();
    let mut entry = zip
        .by_name(&format!("binaries/linux64/{id}.so"))
        .expect("linux64 binary in the FMU");
    let mut bytes = Vec::new();
    entry.read_to_end(&mut bytes).unwrap();
    let out = std::env::temp_dir().join(format!("{id}-bench-{}.so", std::process::id()));
    std::fs::write(&out, bytes).unwrap();
    (out, guid)
}

/// dlopen the binary of `dist/<id>.fmu` (or `$HM_DIST/<id>.fmu`).
pub fn load(id: &str) -> Api {
    let (path, guid) = extract_binary(id);
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
            guid,
            instantiate: sym(lib, "fmi2Instantiate"),
            setup: sym(lib, "fmi2SetupExperiment"),
            enter_init: sym(lib, "fmi2EnterInitializationMode"),
            exit_init: sym(lib, "fmi2ExitInitializationMode"),
            free: sym(lib, "fmi2FreeInstance"),
            set_real: sym(lib, "fmi2SetReal"),
            get_real: sym(lib, "fmi2GetReal"),
            set_boolean: sym(lib, "fmi2SetBoolean"),
            set_integer: sym(lib, "fmi2SetInteger"),
            get_integer: sym(lib, "fmi2GetInteger"),
            do_step: sym(lib, "fmi2DoStep"),
            set_real_input_derivatives: sym(lib, "fmi2SetRealInputDerivatives"),
            get_directional_derivative: sym(lib, "fmi2GetDirectionalDerivative"),
        }
    }
}

/// An initialized instance (default parameters), freed on drop.
pub struct Instance<'a> {
    pub api: &'a Api,
    pub c: *mut c_void,
}

impl<'a> Instance<'a> {
    /// Instantiate (co-simulation, no logger), set up from t = 0 without a
    /// stop time, initialize.
    pub fn new(api: &'a Api, guid: &str) -> Instance<'a> {
        Self::with_parameters(api, guid, &[])
    }

    /// [`Instance::new`] with the Real parameters `(value reference, value)`
    /// set after instantiation.
    pub fn with_parameters(api: &'a Api, guid: &str, parameters: &[(c_uint, f64)]) -> Instance<'a> {
        Self::with_settings(api, guid, parameters, &[], &[])
    }

    /// [`Instance::with_parameters`] with also the Integer and Boolean
    /// parameters `(value reference, value)` set after instantiation.
    pub fn with_settings(
        api: &'a Api,
        guid: &str,
        parameters: &[(c_uint, f64)],
        integers: &[(c_uint, i32)],
        booleans: &[(c_uint, bool)],
    ) -> Instance<'a> {
        let name = CString::new("bench").unwrap();
        let guid = CString::new(guid).unwrap();
        let cb = Callbacks {
            logger: std::ptr::null(),
            allocate: std::ptr::null(),
            free: std::ptr::null(),
            step_finished: std::ptr::null(),
            env: std::ptr::null_mut(),
        };
        unsafe {
            let c = (api.instantiate)(name.as_ptr(), 1, guid.as_ptr(), std::ptr::null(), &cb, 0, 0);
            assert!(
                !c.is_null(),
                "fmi2Instantiate failed (stale dist/*.fmu? rebuild it)"
            );
            for &(vr, value) in parameters {
                assert_eq!(
                    (api.set_real)(c, &vr, 1, &value),
                    0,
                    "parameter {vr} = {value}"
                );
            }
            for &(vr, value) in integers {
                assert_eq!(
                    (api.set_integer)(c, &vr, 1, &value),
                    0,
                    "parameter {vr} = {value}"
                );
            }
            for &(vr, value) in booleans {
                let v = c_int::from(value);
                assert_eq!(
                    (api.set_boolean)(c, &vr, 1, &v),
                    0,
                    "parameter {vr} = {value}"
                );
            }
            assert_eq!((api.setup)(c, 0, 0.0, 0.0, 0, 0.0), 0);
            assert_eq!((api.enter_init)(c), 0);
            assert_eq!((api.exit_init)(c), 0);
            Instance { api, c }
        }
    }

    /// fmi2SetReal + fmi2DoStep + fmi2GetReal; panics on any non-OK status
    /// (a failed step must not pass as a fast one).
    pub fn step(
        &self,
        inputs: &[c_uint],
        values: &[f64],
        t: f64,
        h: f64,
        outputs: &[c_uint],
        out: &mut [f64],
    ) {
        unsafe {
            let s1 = (self.api.set_real)(self.c, inputs.as_ptr(), inputs.len(), values.as_ptr());
            let s2 = (self.api.do_step)(self.c, t, h, 1);
            let s3 = (self.api.get_real)(self.c, outputs.as_ptr(), outputs.len(), out.as_mut_ptr());
            assert!(
                s1 == 0 && s2 == 0 && s3 == 0,
                "t = {t}: statuses {s1} {s2} {s3}"
            );
        }
    }
}

impl Instance<'_> {
    /// fmi2GetInteger of one variable; panics on a non-OK status.
    pub fn integer(&self, vr: c_uint) -> i32 {
        let mut v: c_int = 0;
        let s = unsafe { (self.api.get_integer)(self.c, &vr, 1, &mut v) };
        assert_eq!(s, 0, "fmi2GetInteger({vr})");
        v
    }
}

impl Drop for Instance<'_> {
    fn drop(&mut self) {
        unsafe { (self.api.free)(self.c) }
    }
}

/// The median of `v`.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}
