//! Refusals of states and setups no call sequence can serve, through the
//! C-ABI functions (`hill_muscle::fmi2::api::*::<M>`, what the exported
//! `fmi2Xxx` symbols forward to): a restored state whose stored outputs are
//! not those of its muscle, one that changes a scene's compiled-in
//! constant, one that claims a mesh over the FE muscle's memory budget, and
//! a setup of such a mesh. Each is `fmi2Error` with a message naming the
//! offending field, the instance unchanged; none allocates the mesh
//! (docs/reference/bad-input.md). The last test repeats the setup refusal
//! in a child process under an address-space limit: `fmi2Error`, no abort.

use std::ffi::CString;
use std::ptr::null_mut;

use hill_muscle::fmi2::api;
use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::types::*;
use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hill1d::{Hill1D, Hill1DModel};
#[cfg(feature = "fe")]
use hill_muscle::fmus::hillfe::HillFE;
use hill_muscle::scene::shipped::HillActuator1D;
use testkit::api_abuse::fix_checksum;
use testkit::logger::{callbacks, LogBook};

/// The value reference of variable `name` of `M`.
fn vr<M: Model>(name: &str) -> fmi2ValueReference {
    M::variables()
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}")) as fmi2ValueReference
}

/// An instance of `M` with a logger, freed on drop.
struct Inst<M: Model> {
    c: fmi2Component,
    book: Box<LogBook>,
    _m: std::marker::PhantomData<M>,
}

impl<M: Model> Inst<M> {
    fn new() -> Self {
        let book = Box::new(LogBook::default());
        let cb = callbacks(&book);
        let name = CString::new("refusals").unwrap();
        let g = CString::new(guid::<M>()).unwrap();
        let c = unsafe {
            api::instantiate::<M>(
                name.as_ptr(),
                fmi2CoSimulation,
                g.as_ptr(),
                c"file:///tmp/".as_ptr(),
                &cb,
                fmi2False,
                fmi2False,
            )
        };
        assert!(!c.is_null(), "instantiate: {:?}", book.take());
        Inst {
            c,
            book,
            _m: std::marker::PhantomData,
        }
    }

    /// Set the Integer parameters, set up from t = 0 and enter
    /// initialization mode.
    fn enter(&self, ints: &[(&str, i32)]) {
        unsafe {
            for &(n, v) in ints {
                assert_eq!(api::set_integer::<M>(self.c, &vr::<M>(n), 1, &v), fmi2OK);
            }
            assert_eq!(
                api::setup_experiment::<M>(self.c, fmi2False, 0.0, 0.0, fmi2False, 0.0),
                fmi2OK
            );
            assert_eq!(api::enter_initialization_mode::<M>(self.c), fmi2OK);
        }
    }

    /// Initialized with `ints`, a 1 ms step at activation 0.6 and 1.02 L0.
    fn stepped(ints: &[(&str, i32)]) -> Self {
        let f = Self::new();
        f.enter(ints);
        unsafe {
            assert_eq!(api::exit_initialization_mode::<M>(f.c), fmi2OK);
            let l0 = 0.05;
            for (n, v) in [("activation", 0.6), ("length", 1.02 * l0)] {
                if M::variables().iter().any(|x| x.name == n) {
                    assert_eq!(api::set_real::<M>(f.c, &vr::<M>(n), 1, &v), fmi2OK);
                }
            }
            assert_eq!(api::do_step::<M>(f.c, 0.0, 1e-3, fmi2True), fmi2OK);
        }
        f
    }

    fn real(&self, name: &str) -> f64 {
        let mut v = 0.0;
        let s = unsafe { api::get_real::<M>(self.c, &vr::<M>(name), 1, &mut v) };
        assert_eq!(s, fmi2OK);
        v
    }

    /// The serialized state of the instance.
    fn state_bytes(&self) -> Vec<u8> {
        unsafe {
            let mut s: fmi2FMUstate = null_mut();
            assert_eq!(api::get_fmu_state::<M>(self.c, &mut s), fmi2OK);
            let mut n = 0usize;
            assert_eq!(
                api::serialized_fmu_state_size::<M>(self.c, s, &mut n),
                fmi2OK
            );
            let mut buf = vec![0 as fmi2Byte; n];
            assert_eq!(
                api::serialize_fmu_state::<M>(self.c, s, buf.as_mut_ptr(), n),
                fmi2OK
            );
            assert_eq!(api::free_fmu_state::<M>(self.c, &mut s), fmi2OK);
            buf.into_iter().map(|b| b as u8).collect()
        }
    }

    /// Deserialize `bytes` and set the state: the first non-OK status and
    /// the messages logged.
    fn restore(&self, bytes: &[u8]) -> (fmi2Status, String) {
        self.book.clear();
        let status = unsafe {
            let mut s: fmi2FMUstate = null_mut();
            let st = api::deserialize_fmu_state::<M>(
                self.c,
                bytes.as_ptr() as *const fmi2Byte,
                bytes.len(),
                &mut s,
            );
            if st == fmi2OK {
                let set = api::set_fmu_state::<M>(self.c, s);
                api::free_fmu_state::<M>(self.c, &mut s);
                set
            } else {
                st
            }
        };
        let log = self.book.take();
        let text = log.iter().map(|e| e.message.clone()).collect::<Vec<_>>();
        (status, text.join(" | "))
    }
}

impl<M: Model> Drop for Inst<M> {
    fn drop(&mut self) {
        unsafe { api::free_instance::<M>(self.c) }
    }
}

/// `bytes` with every occurrence of `from` replaced by `to`, the checksum
/// recomputed; panics when `from` does not occur.
fn replaced(bytes: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
    assert_eq!(from.len(), to.len());
    let mut out = bytes.to_vec();
    let mut found = 0;
    let mut i = 0;
    while i + from.len() <= out.len() {
        if &out[i..i + from.len()] == from {
            out[i..i + from.len()].copy_from_slice(to);
            found += 1;
            i += from.len();
        } else {
            i += 1;
        }
    }
    assert!(found > 0, "pattern not in the state");
    fix_checksum(&mut out);
    out
}

/// A state whose stored copy of an output is changed (every occurrence of
/// its value, checksum recomputed) is refused naming the first offending
/// field; the instance keeps its state.
fn tampered_outputs_are_refused<M: Model>(ints: &[(&str, i32)], outputs: &[(&str, f64)]) {
    let f = Inst::<M>::stepped(ints);
    let bytes = f.state_bytes();
    assert_eq!(f.restore(&bytes).0, fmi2OK, "an unmodified state");
    for &(name, forged) in outputs {
        let value = f.real(name);
        let forged_bytes = replaced(&bytes, &value.to_le_bytes(), &forged.to_le_bytes());
        let (status, log) = f.restore(&forged_bytes);
        assert_eq!(status, fmi2Error, "{name} = {forged}: {log}");
        // Named: the stored output, or the model field its value also sits
        // in (activation level, a CE stretch), or the output it contradicts.
        assert!(
            log.contains("malformed model state: HillMuscle"),
            "{name} = {forged}: {log}"
        );
        assert_eq!(f.real(name), value, "{name}: the instance changed");
        assert_eq!(f.state_bytes(), bytes, "{name}: the instance changed");
    }
}

#[test]
fn restored_outputs_must_be_those_of_the_1d_muscle() {
    tampered_outputs_are_refused::<Hill1D>(
        &[],
        &[
            ("activation_level", 5.0),
            ("force", 1e30),
            ("ce_stretch", -1.0),
        ],
    );
}

#[cfg(feature = "fe")]
#[test]
#[cfg_attr(debug_assertions, ignore = "unoptimized FE: cargo test --release")]
fn restored_outputs_must_be_those_of_the_fe_muscle() {
    tampered_outputs_are_refused::<HillFE>(
        &[("n_axial", 6), ("n_radial", 1)],
        &[
            ("activation_level", -0.5),
            ("volume_ratio_min", -3.0),
            ("force", 1e30),
        ],
    );
}

/// The outputs to forge (name, value) from an instance and a forged force.
type Forge<M> = fn(&Inst<M>, f64) -> Vec<(&'static str, f64)>;

/// In a stepping state no parameter can have changed since the outputs
/// were committed: a force 1.5 times the committed one, with the outputs
/// `forge` gives from it so that they agree with each other and with some
/// area in its range (checksum recomputed), is refused as not that of the
/// muscle with its parameters; the instance keeps its state.
fn forged_force_of_a_stepping_state_is_refused<M: Model>(ints: &[(&str, i32)], forge: Forge<M>) {
    let f = Inst::<M>::stepped(ints);
    let bytes = f.state_bytes();
    let mut forged = bytes.clone();
    for (name, value) in forge(&f, 1.5 * f.real("force")) {
        forged = replaced(&forged, &f.real(name).to_le_bytes(), &value.to_le_bytes());
    }
    let (status, log) = f.restore(&forged);
    assert_eq!(status, fmi2Error, "{log}");
    assert!(log.contains("output force"), "{log}");
    assert_eq!(f.state_bytes(), bytes, "the instance changed");
}

#[test]
fn a_stepping_1d_state_has_the_force_of_its_area() {
    forged_force_of_a_stepping_state_is_refused::<Hill1D>(&[], |_, force| vec![("force", force)]);
}

#[cfg(feature = "fe")]
#[test]
#[cfg_attr(debug_assertions, ignore = "unoptimized FE: cargo test --release")]
fn a_stepping_fe_state_has_the_force_of_its_muscle() {
    forged_force_of_a_stepping_state_is_refused::<HillFE>(
        &[("n_axial", 6), ("n_radial", 1)],
        |f, force| {
            let stress = force / f.real("area");
            let cauchy = 1.5 * f.real("cauchy_stress");
            let passive = stress - f.real("active_stress");
            vec![
                ("force", force),
                ("stress", stress),
                ("cauchy_stress", cauchy),
                ("passive_stress", passive),
            ]
        },
    );
}

/// `HillActuator1D` compiles b = 23.46 in: a state with b = 30 (checksum
/// recomputed) is refused naming the constant.
#[test]
fn a_scene_constant_cannot_be_changed_through_a_state() {
    type Actuator = Hill1DModel<HillActuator1D>;
    let f = Inst::<Actuator>::stepped(&[]);
    let bytes = f.state_bytes();
    let forged = replaced(&bytes, &23.46f64.to_le_bytes(), &30.0f64.to_le_bytes());
    let (status, log) = f.restore(&forged);
    assert_eq!(status, fmi2Error, "{log}");
    assert!(log.contains("b = 30"), "{log}");
    assert_eq!(f.state_bytes(), bytes, "the instance changed");
}

/// The committed muscle of a 6 × 1 FE state made to claim 96 × 16 (the
/// geometry's L0, area and mesh counts are contiguous there only) is
/// refused before any mesh is built, naming the memory estimate.
#[cfg(feature = "fe")]
#[test]
#[cfg_attr(debug_assertions, ignore = "unoptimized FE: cargo test --release")]
fn a_state_claiming_a_mesh_over_the_budget_is_refused_before_it_is_built() {
    let f = Inst::<HillFE>::stepped(&[("n_axial", 6), ("n_radial", 1)]);
    let bytes = f.state_bytes();
    let (l0, area) = (f.real("L0"), f.real("area"));
    let claim = |na: i32, nr: i32| {
        [
            l0.to_le_bytes().as_slice(),
            &area.to_le_bytes(),
            &na.to_le_bytes(),
            &nr.to_le_bytes(),
        ]
        .concat()
    };
    let forged = replaced(&bytes, &claim(6, 1), &claim(96, 16));
    let started = std::time::Instant::now();
    let (status, log) = f.restore(&forged);
    assert_eq!(status, fmi2Error, "{log}");
    assert!(
        log.contains("96 x 16 mesh needs an estimated") && log.contains("budget"),
        "{log}"
    );
    assert!(
        started.elapsed().as_secs_f64() < 0.5,
        "{:?}",
        started.elapsed()
    );
    assert_eq!(f.state_bytes(), bytes, "the instance changed");
}

/// The setup of a declared mesh over the budget: `fmi2ExitInitializationMode`
/// is `fmi2Error` naming the estimate and the budget, at once. Returns the
/// log.
#[cfg(feature = "fe")]
fn refuse_the_largest_mesh() -> String {
    let f = Inst::<HillFE>::new();
    f.enter(&[("n_axial", 96), ("n_radial", 16)]);
    f.book.clear();
    let started = std::time::Instant::now();
    let status = unsafe { api::exit_initialization_mode::<HillFE>(f.c) };
    let log = f
        .book
        .take()
        .iter()
        .map(|e| e.message.clone())
        .collect::<Vec<_>>()
        .join(" | ");
    assert_eq!(status, fmi2Error, "{log}");
    assert!(
        log.contains("96 x 16 mesh needs an estimated") && log.contains("GiB"),
        "{log}"
    );
    assert!(
        started.elapsed().as_secs_f64() < 0.5,
        "{:?}",
        started.elapsed()
    );
    log
}

#[cfg(feature = "fe")]
#[test]
#[cfg_attr(debug_assertions, ignore = "unoptimized FE: cargo test --release")]
fn a_mesh_over_the_memory_budget_is_refused_at_initialization() {
    refuse_the_largest_mesh();
}

/// The variable that makes this test binary a child running
/// [`refuse_the_largest_mesh`] (under the address-space limit its parent's
/// shell set).
#[cfg(feature = "fe")]
const CHILD: &str = "HILL_RLIMIT_CHILD";

/// In a child process limited to 1 GiB of address space (`ulimit -v`), the
/// 96 × 16 setup is `fmi2Error` and the child exits normally (an
/// allocation of the mesh's factor would abort it with SIGABRT).
#[cfg(feature = "fe")]
#[test]
#[cfg_attr(debug_assertions, ignore = "unoptimized FE: cargo test --release")]
fn under_an_address_space_limit_the_refusal_is_an_error_not_an_abort() {
    let name = "under_an_address_space_limit_the_refusal_is_an_error_not_an_abort";
    if std::env::var_os(CHILD).is_some() {
        refuse_the_largest_mesh();
        return;
    }
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(r#"ulimit -v 1048576 && exec "$0" --exact "$1" --test-threads=1 --include-ignored"#)
        .arg(std::env::current_exe().unwrap())
        .arg(name)
        .env(CHILD, "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("1 passed"),
        "child: {:?}\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
}
