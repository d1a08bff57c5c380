//! Tests of the generic FMI 2.0 Co-Simulation layer (`hill_muscle::fmi2`)
//! through its C signatures, with a small dummy model: a first-order lag
//! `tau y' = x - y`, `x = gain * u + w`, stepped with implicit Euler.
//!
//! The test logger is `testkit::logger` (FMI's variadic logger received by a
//! non-variadic function; its module docs say why that is sound on Linux).

use std::ffi::{CStr, CString};
use std::marker::PhantomData;

use hill_muscle::fmi2::api;
use hill_muscle::fmi2::bytes::{ByteReader, ByteWriter};
use hill_muscle::fmi2::model_description::{
    documentation_html, guid, model_description, validate, validate_table,
};
use hill_muscle::fmi2::types::*;
use hill_muscle::fmi2::{
    Causality, Initial, Model, ModelError, ModelInfo, ScalarVariable, SetOutcome, StepError, Unit,
    VarType, Variability,
};
use testkit::logger::{callbacks, Entry, LogBook};

// ---------------------------------------------------------------------------
// The dummy model
// ---------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum V {
    U,
    W,
    Tau,
    Gain,
    HMax,
    Clamp,
    Mode,
    Y,
    Z,
    Steps,
    High,
    TauMs,
    Answer,
    Internal,
}

// Value references (= index in the table).
const U: u32 = 0;
const W: u32 = 1;
const TAU: u32 = 2;
const GAIN: u32 = 3;
const HMAX: u32 = 4;
const CLAMP: u32 = 5;
const MODE: u32 = 6;
const Y: u32 = 7;
const Z: u32 = 8;
const STEPS: u32 = 9;
const HIGH: u32 = 10;
const TAU_MS: u32 = 11;
const ANSWER: u32 = 12;
const INTERNAL: u32 = 13;
const N_VARS: u32 = 14;

/// `K = 0`: the model; `K = 1`: the same with another start value of `tau`
/// (a different interface, hence a different GUID).
#[derive(Clone, Debug, PartialEq)]
struct LagM<const K: u8> {
    u: f64,
    du: f64,
    w: f64,
    tau: f64,
    gain: f64,
    h_max: f64,
    clamp: bool,
    mode: i32,
    y: f64,
    steps: i32,
    tau_ms: f64,
    internal: f64,
    last_a: Option<f64>,
}

type Lag = LagM<0>;
type Lag2 = LagM<1>;

fn real(
    unit: Option<&'static str>,
    start: Option<f64>,
    min: Option<f64>,
    max: Option<f64>,
) -> VarType {
    VarType::Real {
        unit,
        start,
        min,
        max,
    }
}

fn sv(
    name: &'static str,
    causality: Causality,
    variability: Variability,
    ty: VarType,
    depends_on: &[&'static str],
    id: V,
) -> ScalarVariable<V> {
    ScalarVariable {
        name,
        description: "a test variable",
        causality,
        variability,
        initial: None,
        ty,
        depends_on: depends_on.to_vec(),
        id,
    }
}

fn finite(name: &str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(format!("{name} = {v} is not finite; valid range (-inf, inf)").into())
    }
}

impl<const K: u8> Model for LagM<K> {
    type Var = V;

    fn info() -> ModelInfo {
        ModelInfo {
            model_identifier: "Lag",
            description: "First-order lag <test> & \"quotes\"",
            version: "1.0",
            units: vec![
                Unit {
                    name: "s",
                    s: 1,
                    ..Default::default()
                },
                Unit {
                    name: "N",
                    kg: 1,
                    m: 1,
                    s: -2,
                },
            ],
            default_experiment: (0.0, 10.0, 1e-2),
            max_input_derivative_order: 1,
            // The lag changes y only in fmi2DoStep, but this test model declares
            // feedthrough so that the generator's dependency branch stays tested.
            direct_feedthrough: true,
        }
    }

    fn variables() -> Vec<ScalarVariable<V>> {
        use Causality::*;
        use Variability::*;
        let tau_start = if K == 0 { 1.0 } else { 2.0 };
        let deps: &[&str] = &["u", "w", "gain"];
        vec![
            sv(
                "u",
                Input,
                Continuous,
                real(None, Some(0.0), None, None),
                &[],
                V::U,
            ),
            sv(
                "w",
                Input,
                Continuous,
                real(None, Some(0.0), None, None),
                &[],
                V::W,
            ),
            sv(
                "tau",
                Parameter,
                Fixed,
                real(Some("s"), Some(tau_start), Some(1e-9), None),
                &[],
                V::Tau,
            ),
            sv(
                "gain",
                Parameter,
                Tunable,
                real(None, Some(2.0), None, None),
                &[],
                V::Gain,
            ),
            sv(
                "h_max",
                Parameter,
                Fixed,
                real(Some("s"), Some(0.5), Some(1e-300), None),
                &[],
                V::HMax,
            ),
            sv(
                "clamp",
                Parameter,
                Tunable,
                VarType::Boolean { start: Some(false) },
                &[],
                V::Clamp,
            ),
            sv(
                "mode",
                Parameter,
                Tunable,
                VarType::Integer {
                    start: Some(1),
                    min: Some(1),
                    max: Some(3),
                },
                &[],
                V::Mode,
            ),
            sv(
                "y",
                Output,
                Continuous,
                real(Some("N"), None, None, None),
                deps,
                V::Y,
            ),
            sv(
                "z",
                Output,
                Continuous,
                real(Some("N"), None, None, None),
                deps,
                V::Z,
            ),
            sv(
                "steps",
                Output,
                Discrete,
                VarType::Integer {
                    start: None,
                    min: None,
                    max: None,
                },
                &[],
                V::Steps,
            ),
            sv(
                "high",
                Output,
                Discrete,
                VarType::Boolean { start: None },
                deps,
                V::High,
            ),
            sv(
                "tau_ms",
                CalculatedParameter,
                Fixed,
                real(None, None, None, None),
                &["tau"],
                V::TauMs,
            ),
            ScalarVariable {
                initial: Some(Initial::Exact),
                ..sv(
                    "answer",
                    Local,
                    Constant,
                    VarType::Integer {
                        start: Some(42),
                        min: None,
                        max: None,
                    },
                    &[],
                    V::Answer,
                )
            },
            sv(
                "internal",
                Local,
                Continuous,
                real(None, None, None, None),
                &[],
                V::Internal,
            ),
        ]
    }

    fn new() -> Self {
        LagM {
            u: 0.0,
            du: 0.0,
            w: 0.0,
            tau: if K == 0 { 1.0 } else { 2.0 },
            gain: 2.0,
            h_max: 0.5,
            clamp: false,
            mode: 1,
            y: 0.0,
            steps: 0,
            tau_ms: 0.0,
            internal: 0.0,
            last_a: None,
        }
    }

    fn get_real(&self, var: V) -> f64 {
        match var {
            V::U => self.u,
            V::W => self.w,
            V::Tau => self.tau,
            V::Gain => self.gain,
            V::HMax => self.h_max,
            V::Y => self.y,
            V::Z => 3.0 * self.y,
            V::TauMs => self.tau_ms,
            V::Internal => self.internal,
            other => panic!("get_real({other:?})"),
        }
    }

    fn get_integer(&self, var: V) -> i32 {
        match var {
            V::Mode => self.mode,
            V::Steps => self.steps,
            V::Answer => 42,
            other => panic!("get_integer({other:?})"),
        }
    }

    fn get_boolean(&self, var: V) -> bool {
        match var {
            V::Clamp => self.clamp,
            V::High => self.y >= 1.0,
            other => panic!("get_boolean({other:?})"),
        }
    }

    fn set_real(&mut self, var: V, v: f64) -> Result<SetOutcome, ModelError> {
        match var {
            V::U => {
                finite("u", v)?;
                self.du = 0.0;
                if self.clamp && v.abs() > 1.0 {
                    self.u = v.clamp(-1.0, 1.0);
                    return Ok(SetOutcome::Warning {
                        message: format!(
                            "u = {v} clamped to {} (range [-1, 1] when clamp)",
                            self.u
                        ),
                        log_once: true,
                    });
                }
                self.u = v;
            }
            V::W => {
                finite("w", v)?;
                self.w = v;
            }
            V::Tau => {
                if !(v.is_finite() && v > 0.0) {
                    return Err(format!("tau = {v} is out of the valid range (0, inf)").into());
                }
                self.tau = v;
            }
            V::Gain => {
                finite("gain", v)?;
                self.gain = v;
            }
            V::HMax => {
                if !(v.is_finite() && v > 0.0) {
                    return Err(format!("h_max = {v} is out of the valid range (0, inf)").into());
                }
                self.h_max = v;
            }
            other => panic!("set_real({other:?})"),
        }
        Ok(SetOutcome::Ok)
    }

    fn set_integer(&mut self, var: V, v: i32) -> Result<SetOutcome, ModelError> {
        match var {
            V::Mode if (1..=3).contains(&v) => {
                self.mode = v;
                Ok(SetOutcome::Ok)
            }
            V::Mode => Err(format!("mode #{v} is not in the valid range [1, 3]").into()),
            other => panic!("set_integer({other:?})"),
        }
    }

    fn set_boolean(&mut self, var: V, v: bool) -> Result<SetOutcome, ModelError> {
        match var {
            V::Clamp => {
                self.clamp = v;
                Ok(SetOutcome::Ok)
            }
            other => panic!("set_boolean({other:?})"),
        }
    }

    fn set_real_input_derivative(&mut self, var: V, order: i32, v: f64) -> Result<(), ModelError> {
        assert_eq!(order, 1, "the layer checks the order");
        match var {
            V::U => {
                finite("du/dt", v)?;
                self.du = v;
                Ok(())
            }
            _ => Err("no derivative for this input".into()),
        }
    }

    fn initialize(&mut self) -> Result<(), ModelError> {
        if self.w < -100.0 {
            return Err(format!("w = {} < -100: no equilibrium", self.w).into());
        }
        self.y = self.gain * self.u + self.w;
        self.tau_ms = self.tau * 1000.0;
        self.steps = 0;
        self.last_a = None;
        Ok(())
    }

    fn do_step(&mut self, t: f64, h: f64) -> Result<(), StepError> {
        if self.w == 12345.0 {
            panic!("test panic #7");
        }
        if h > self.h_max {
            return Err(StepError::Discard(format!(
                "h = {h} > h_max = {}",
                self.h_max
            )));
        }
        if self.w > 1e6 {
            return Err(StepError::Error(format!("w = {} is too large", self.w)));
        }
        let a = h / self.tau;
        let x = self.gain * (self.u + self.du * h) + self.w;
        self.y = (self.y + a * x) / (1.0 + a);
        self.steps += 1;
        self.internal = t + h;
        self.last_a = Some(a);
        Ok(())
    }

    fn partial_derivative(&self, unknown: V, known: V) -> Result<f64, ModelError> {
        let k = self.last_a.map_or(1.0, |a| a / (1.0 + a));
        match (unknown, known) {
            (V::Y, V::U) => Ok(self.gain * k),
            (V::Y, V::W) => Ok(k),
            (V::Z, V::U) => Ok(3.0 * self.gain * k),
            // A refusal the layer must pass on without changing anything
            // (`a_refused_directional_derivative_in_initialization_changes_nothing`).
            (V::Z, V::W) if self.gain < 0.0 => {
                Err("dz/dw is not provided for a negative gain".into())
            }
            (V::Z, V::W) => Ok(3.0 * k),
            _ => Err("no such partial derivative".into()),
        }
    }

    fn serialize(&self, out: &mut Vec<u8>) {
        let mut w = ByteWriter::new(out);
        w.f64(self.u)
            .f64(self.du)
            .f64(self.w)
            .f64(self.tau)
            .f64(self.gain)
            .f64(self.h_max)
            .bool(self.clamp)
            .i32(self.mode)
            .f64(self.y)
            .i32(self.steps)
            .f64(self.tau_ms)
            .f64(self.internal)
            .bool(self.last_a.is_some())
            .f64(self.last_a.unwrap_or(0.0));
    }

    fn deserialize(input: &mut &[u8]) -> Result<Self, ModelError> {
        let mut r = ByteReader::new(input);
        let m = LagM {
            u: r.f64()?,
            du: r.f64()?,
            w: r.f64()?,
            tau: r.f64()?,
            gain: r.f64()?,
            h_max: r.f64()?,
            clamp: r.bool()?,
            mode: r.i32()?,
            y: r.f64()?,
            steps: r.i32()?,
            tau_ms: r.f64()?,
            internal: r.f64()?,
            last_a: {
                let some = r.bool()?;
                let a = r.f64()?;
                some.then_some(a)
            },
        };
        if m.tau.is_nan() || m.tau <= 0.0 {
            return Err("tau must be > 0".into());
        }
        Ok(m)
    }
}

// ---------------------------------------------------------------------------
// Test logger and instance wrapper
// ---------------------------------------------------------------------------

struct Fmu<M: Model> {
    c: fmi2Component,
    book: Box<LogBook>,
    _m: PhantomData<M>,
}

// FMI 2.0 allows an instance to be used from another thread between calls;
// the log book is behind a mutex.
unsafe impl<M: Model> Send for Fmu<M> {}

fn try_instantiate<M: Model>(
    name: Option<&str>,
    fmu_type: fmi2Type,
    guid_str: Option<&str>,
    logging_on: bool,
) -> (fmi2Component, Box<LogBook>) {
    let book = Box::new(LogBook::default());
    let cb = callbacks(&book);
    let name = name.map(|n| CString::new(n).unwrap());
    let g = guid_str.map(|g| CString::new(g).unwrap());
    let c = unsafe {
        api::instantiate::<M>(
            name.as_ref().map_or(std::ptr::null(), |n| n.as_ptr()),
            fmu_type,
            g.as_ref().map_or(std::ptr::null(), |g| g.as_ptr()),
            c"file:///nowhere".as_ptr(),
            &cb,
            fmi2False,
            if logging_on { fmi2True } else { fmi2False },
        )
    };
    (c, book)
}

impl<M: Model> Fmu<M> {
    fn new() -> Self {
        Self::named("inst #1", false)
    }

    fn named(name: &str, logging_on: bool) -> Self {
        let (c, book) =
            try_instantiate::<M>(Some(name), fmi2CoSimulation, Some(&guid::<M>()), logging_on);
        assert!(!c.is_null(), "instantiate failed: {:?}", book.entries());
        Fmu {
            c,
            book,
            _m: PhantomData,
        }
    }

    /// Instantiated, experiment from 0 (stop 10), initialized.
    fn running() -> Self {
        let f = Self::new();
        f.ok(unsafe { api::setup_experiment::<M>(f.c, fmi2False, 0.0, 0.0, fmi2True, 10.0) });
        f.ok(unsafe { api::enter_initialization_mode::<M>(f.c) });
        f.ok(unsafe { api::exit_initialization_mode::<M>(f.c) });
        f
    }

    fn ok(&self, s: fmi2Status) {
        assert_eq!(s, fmi2OK, "log: {:#?}", self.logs());
    }

    fn logs(&self) -> Vec<Entry> {
        self.book.entries()
    }

    fn clear_logs(&self) {
        self.book.clear();
    }

    fn has_log(&self, status: fmi2Status, needle: &str) -> bool {
        self.logs()
            .iter()
            .any(|e| e.status == status && e.message.contains(needle))
    }

    fn set_real(&self, vrs: &[u32], vals: &[f64]) -> fmi2Status {
        assert_eq!(vrs.len(), vals.len());
        unsafe { api::set_real::<M>(self.c, vrs.as_ptr(), vrs.len(), vals.as_ptr()) }
    }

    fn set_integer(&self, vrs: &[u32], vals: &[i32]) -> fmi2Status {
        unsafe { api::set_integer::<M>(self.c, vrs.as_ptr(), vrs.len(), vals.as_ptr()) }
    }

    fn set_boolean(&self, vrs: &[u32], vals: &[bool]) -> fmi2Status {
        let v: Vec<fmi2Boolean> = vals.iter().map(|&b| b as fmi2Boolean).collect();
        unsafe { api::set_boolean::<M>(self.c, vrs.as_ptr(), vrs.len(), v.as_ptr()) }
    }

    fn get_real(&self, vrs: &[u32]) -> (fmi2Status, Vec<f64>) {
        let mut out = vec![f64::NAN; vrs.len()];
        let s = unsafe { api::get_real::<M>(self.c, vrs.as_ptr(), vrs.len(), out.as_mut_ptr()) };
        (s, out)
    }

    fn real(&self, vr: u32) -> f64 {
        let (s, v) = self.get_real(&[vr]);
        self.ok(s);
        v[0]
    }

    fn get_integer(&self, vrs: &[u32]) -> (fmi2Status, Vec<i32>) {
        let mut out = vec![-999; vrs.len()];
        let s = unsafe { api::get_integer::<M>(self.c, vrs.as_ptr(), vrs.len(), out.as_mut_ptr()) };
        (s, out)
    }

    fn get_boolean(&self, vrs: &[u32]) -> (fmi2Status, Vec<fmi2Boolean>) {
        let mut out = vec![-1; vrs.len()];
        let s = unsafe { api::get_boolean::<M>(self.c, vrs.as_ptr(), vrs.len(), out.as_mut_ptr()) };
        (s, out)
    }

    fn step(&self, tc: f64, h: f64) -> fmi2Status {
        unsafe { api::do_step::<M>(self.c, tc, h, fmi2True) }
    }

    fn save(&self) -> fmi2FMUstate {
        let mut s: fmi2FMUstate = std::ptr::null_mut();
        self.ok(unsafe { api::get_fmu_state::<M>(self.c, &mut s) });
        assert!(!s.is_null());
        s
    }

    fn restore(&self, s: fmi2FMUstate) -> fmi2Status {
        unsafe { api::set_fmu_state::<M>(self.c, s) }
    }

    fn free_state(&self, mut s: fmi2FMUstate) {
        self.ok(unsafe { api::free_fmu_state::<M>(self.c, &mut s) });
        assert!(s.is_null());
    }

    fn serialize(&self, s: fmi2FMUstate) -> Vec<u8> {
        let mut n = 0usize;
        self.ok(unsafe { api::serialized_fmu_state_size::<M>(self.c, s, &mut n) });
        let mut buf = vec![0 as fmi2Byte; n];
        self.ok(unsafe { api::serialize_fmu_state::<M>(self.c, s, buf.as_mut_ptr(), n) });
        buf.into_iter().map(|b| b as u8).collect()
    }

    fn deserialize(&self, bytes: &[u8]) -> (fmi2Status, fmi2FMUstate) {
        let mut s: fmi2FMUstate = std::ptr::null_mut();
        let st = unsafe {
            api::deserialize_fmu_state::<M>(
                self.c,
                bytes.as_ptr() as *const fmi2Byte,
                bytes.len(),
                &mut s,
            )
        };
        (st, s)
    }

    /// The complete dynamic state of the instance, as bytes.
    fn state_bytes(&self) -> Vec<u8> {
        let s = self.save();
        let b = self.serialize(s);
        self.free_state(s);
        b
    }

    fn last_successful_time(&self) -> (fmi2Status, f64) {
        let mut t = f64::NAN;
        let s = unsafe { api::get_real_status::<M>(self.c, fmi2LastSuccessfulTime, &mut t) };
        (s, t)
    }
}

impl<M: Model> Drop for Fmu<M> {
    fn drop(&mut self) {
        unsafe { api::free_instance::<M>(self.c) };
    }
}

// ---------------------------------------------------------------------------
// Lifecycle
// ---------------------------------------------------------------------------

/// Implicit Euler of the lag, as the model computes it.
fn lag_step(y: f64, x: f64, h: f64, tau: f64) -> f64 {
    let a = h / tau;
    (y + a * x) / (1.0 + a)
}

#[test]
fn full_lifecycle() {
    assert_eq!(
        unsafe { CStr::from_ptr(api::get_types_platform()) }.to_str(),
        Ok("default")
    );
    assert_eq!(
        unsafe { CStr::from_ptr(api::get_version()) }.to_str(),
        Ok("2.0")
    );

    let f = Fmu::<Lag>::new();
    let c = f.c;
    f.ok(unsafe { api::setup_experiment::<Lag>(c, fmi2True, 1e-6, 1.0, fmi2True, 3.0) });
    // Parameters before initialization mode.
    f.ok(f.set_real(&[TAU, GAIN], &[0.5, 3.0]));
    f.ok(f.set_integer(&[MODE], &[2]));
    f.ok(f.set_boolean(&[CLAMP], &[false]));
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(c) });
    f.ok(f.set_real(&[U, W], &[0.2, 0.1]));
    // Outputs in initialization mode are consistent with what was set.
    assert_eq!(f.real(Y), 3.0 * 0.2 + 0.1);
    assert_eq!(f.real(TAU_MS), 500.0);
    f.ok(f.set_real(&[U], &[0.3]));
    assert_eq!(f.real(Z), 3.0 * (3.0 * 0.3 + 0.1));
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(c) });

    let (s, t0) = f.last_successful_time();
    f.ok(s);
    assert_eq!(t0, 1.0);

    let mut y = 3.0 * 0.3 + 0.1;
    let mut t = 1.0;
    let h = 0.1;
    for i in 0..10 {
        let u = 0.3 + 0.1 * i as f64;
        f.ok(f.set_real(&[U], &[u]));
        f.ok(f.step(t, h));
        y = lag_step(y, 3.0 * u + 0.1, h, 0.5);
        t += h;
        assert_eq!(f.real(Y), y);
        assert_eq!(f.real(INTERNAL), t);
    }
    let (s, ints) = f.get_integer(&[STEPS, MODE, ANSWER]);
    f.ok(s);
    assert_eq!(ints, vec![10, 2, 42]);
    let (s, b) = f.get_boolean(&[HIGH, CLAMP]);
    f.ok(s);
    assert_eq!(b, vec![(y >= 1.0) as fmi2Boolean, fmi2False]);
    // Tunable parameter after initialization.
    f.ok(f.set_real(&[GAIN], &[1.0]));

    let mut st = fmi2Error;
    f.ok(unsafe { api::get_status::<Lag>(c, fmi2DoStepStatus, &mut st) });
    assert_eq!(st, fmi2OK);
    let mut term = fmi2True;
    f.ok(unsafe { api::get_boolean_status::<Lag>(c, fmi2Terminated, &mut term) });
    assert_eq!(term, fmi2False);

    f.ok(unsafe { api::terminate::<Lag>(c) });
    // Values can still be read after termination.
    assert_eq!(f.real(Y), y);
    // No errors or warnings were logged.
    assert!(
        f.logs().iter().all(|e| e.status == fmi2OK),
        "{:#?}",
        f.logs()
    );
}

// ---------------------------------------------------------------------------
// State machine: every call in every reachable state
// ---------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum St {
    Instantiated,
    InitializationMode,
    StepComplete,
    StepFailed,
    Terminated,
    Error,
}

impl St {
    fn name(self) -> &'static str {
        match self {
            St::Instantiated => "instantiated",
            St::InitializationMode => "initializationMode",
            St::StepComplete => "stepComplete",
            St::StepFailed => "stepFailed",
            St::Terminated => "terminated",
            St::Error => "error",
        }
    }
}

fn lag_in(state: St) -> Fmu<Lag> {
    let f = Fmu::<Lag>::new();
    let c = f.c;
    if state == St::Instantiated {
        return f;
    }
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(c) });
    if state == St::InitializationMode {
        return f;
    }
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(c) });
    match state {
        St::StepComplete => {}
        St::StepFailed => assert_eq!(f.step(0.0, 1.0), fmi2Discard),
        St::Terminated => f.ok(unsafe { api::terminate::<Lag>(c) }),
        St::Error => {
            f.ok(f.set_real(&[W], &[2e6]));
            assert_eq!(f.step(0.0, 0.1), fmi2Error);
        }
        _ => unreachable!(),
    }
    f.clear_logs();
    f
}

type Call = fn(fmi2Component) -> fmi2Status;

/// Every function with valid arguments, and the states the FMI 2.0 table
/// allows it in.
fn catalogue() -> Vec<(&'static str, Call, &'static [St])> {
    use St::*;
    const ALL: &[St] = &[
        Instantiated,
        InitializationMode,
        StepComplete,
        StepFailed,
        Terminated,
        Error,
    ];
    const GET: &[St] = &[
        InitializationMode,
        StepComplete,
        StepFailed,
        Terminated,
        Error,
    ];
    const SET: &[St] = &[Instantiated, InitializationMode, StepComplete];
    const STATUS: &[St] = &[StepComplete, StepFailed, Terminated];
    vec![
        (
            "fmi2SetDebugLogging",
            |c| unsafe { api::set_debug_logging::<Lag>(c, fmi2False, 0, std::ptr::null()) },
            ALL,
        ),
        (
            "fmi2SetupExperiment",
            |c| unsafe { api::setup_experiment::<Lag>(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) },
            &[Instantiated],
        ),
        (
            "fmi2EnterInitializationMode",
            |c| unsafe { api::enter_initialization_mode::<Lag>(c) },
            &[Instantiated],
        ),
        (
            "fmi2ExitInitializationMode",
            |c| unsafe { api::exit_initialization_mode::<Lag>(c) },
            &[InitializationMode],
        ),
        (
            "fmi2Terminate",
            |c| unsafe { api::terminate::<Lag>(c) },
            &[StepComplete, StepFailed],
        ),
        ("fmi2Reset", |c| unsafe { api::reset::<Lag>(c) }, ALL),
        (
            "fmi2GetReal",
            |c| unsafe {
                let mut v = 0.0;
                api::get_real::<Lag>(c, &Y, 1, &mut v)
            },
            GET,
        ),
        (
            "fmi2GetInteger",
            |c| unsafe {
                let mut v = 0;
                api::get_integer::<Lag>(c, &STEPS, 1, &mut v)
            },
            GET,
        ),
        (
            "fmi2GetBoolean",
            |c| unsafe {
                let mut v = 0;
                api::get_boolean::<Lag>(c, &HIGH, 1, &mut v)
            },
            GET,
        ),
        (
            "fmi2GetString",
            |c| unsafe { api::get_string::<Lag>(c, std::ptr::null(), 0, std::ptr::null_mut()) },
            GET,
        ),
        (
            "fmi2SetReal",
            |c| unsafe { api::set_real::<Lag>(c, &U, 1, &0.5) },
            SET,
        ),
        (
            "fmi2SetInteger",
            |c| unsafe { api::set_integer::<Lag>(c, &MODE, 1, &2) },
            SET,
        ),
        (
            "fmi2SetBoolean",
            |c| unsafe { api::set_boolean::<Lag>(c, &CLAMP, 1, &fmi2True) },
            SET,
        ),
        (
            "fmi2SetString",
            |c| unsafe { api::set_string::<Lag>(c, std::ptr::null(), 0, std::ptr::null()) },
            SET,
        ),
        (
            "fmi2GetFMUstate",
            |c| unsafe {
                let mut s: fmi2FMUstate = std::ptr::null_mut();
                let st = api::get_fmu_state::<Lag>(c, &mut s);
                if !s.is_null() {
                    api::free_fmu_state::<Lag>(c, &mut s);
                }
                st
            },
            ALL,
        ),
        (
            "fmi2GetDirectionalDerivative",
            |c| unsafe {
                let mut dv = 0.0;
                api::get_directional_derivative::<Lag>(c, &Y, 1, &U, 1, &1.0, &mut dv)
            },
            GET,
        ),
        (
            "fmi2SetRealInputDerivatives",
            |c| unsafe { api::set_real_input_derivatives::<Lag>(c, &U, 1, &1, &0.5) },
            SET,
        ),
        (
            "fmi2GetRealOutputDerivatives",
            |c| unsafe {
                api::get_real_output_derivatives::<Lag>(
                    c,
                    std::ptr::null(),
                    0,
                    std::ptr::null(),
                    std::ptr::null_mut(),
                )
            },
            &[StepComplete, StepFailed, Terminated, Error],
        ),
        (
            "fmi2DoStep",
            |c| unsafe { api::do_step::<Lag>(c, 0.0, 0.1, fmi2True) },
            &[StepComplete],
        ),
        (
            "fmi2CancelStep",
            |c| unsafe { api::cancel_step::<Lag>(c) },
            &[],
        ),
        (
            "fmi2GetStatus",
            |c| unsafe {
                let mut v = fmi2Error;
                api::get_status::<Lag>(c, fmi2DoStepStatus, &mut v)
            },
            STATUS,
        ),
        (
            "fmi2GetRealStatus",
            |c| unsafe {
                let mut v = 0.0;
                api::get_real_status::<Lag>(c, fmi2LastSuccessfulTime, &mut v)
            },
            STATUS,
        ),
        (
            "fmi2GetIntegerStatus",
            |c| unsafe {
                let mut v = 0;
                api::get_integer_status::<Lag>(c, fmi2DoStepStatus, &mut v)
            },
            STATUS,
        ),
        (
            "fmi2GetBooleanStatus",
            |c| unsafe {
                let mut v = 0;
                api::get_boolean_status::<Lag>(c, fmi2Terminated, &mut v)
            },
            STATUS,
        ),
        (
            "fmi2GetStringStatus",
            |c| unsafe {
                let mut v: fmi2String = std::ptr::null();
                api::get_string_status::<Lag>(c, fmi2PendingStatus, &mut v)
            },
            STATUS,
        ),
    ]
}

#[test]
fn every_call_in_every_state_follows_the_table() {
    use St::*;
    for state in [
        Instantiated,
        InitializationMode,
        StepComplete,
        StepFailed,
        Terminated,
        Error,
    ] {
        for (name, call, allowed) in catalogue() {
            let f = lag_in(state);
            let before = f.state_bytes();
            f.clear_logs();
            let status = call(f.c);
            let rejected_by_state = f
                .logs()
                .iter()
                .any(|e| e.message.contains("not allowed in state"));
            if allowed.contains(&state) {
                assert!(
                    !rejected_by_state,
                    "{name} must be allowed in {}: {:#?}",
                    state.name(),
                    f.logs()
                );
            } else {
                assert_eq!(status, fmi2Error, "{name} in {}", state.name());
                let expected = format!("{name}: not allowed in state {}", state.name());
                assert!(
                    f.has_log(fmi2Error, &expected),
                    "missing '{expected}': {:#?}",
                    f.logs()
                );
                assert_eq!(
                    f.state_bytes(),
                    before,
                    "rejected {name} changed the instance in {}",
                    state.name()
                );
            }
        }
    }
}

#[test]
fn rejected_call_changes_nothing_and_next_call_is_unaffected() {
    // Two identical instances; one gets rejected calls in between.
    let a = Fmu::<Lag>::running();
    let b = Fmu::<Lag>::running();
    for f in [&a, &b] {
        f.ok(f.set_real(&[U], &[1.0]));
        f.ok(f.step(0.0, 0.1));
    }
    assert_eq!(a.set_real(&[U, TAU], &[5.0, 2.0]), fmi2Error); // tau fixed
    assert_eq!(a.set_real(&[U, W], &[5.0, f64::NAN]), fmi2Error); // w refused
    assert_eq!(a.step(0.0, 0.1), fmi2Error); // wrong time
    assert_eq!(
        unsafe { api::exit_initialization_mode::<Lag>(a.c) },
        fmi2Error
    );
    assert_eq!(a.state_bytes(), b.state_bytes());
    for f in [&a, &b] {
        f.ok(f.step(0.1, 0.1));
    }
    assert_eq!(a.real(Y).to_bits(), b.real(Y).to_bits());
    assert_eq!(a.real(U), 1.0);
}

#[test]
fn exit_initialization_failure_stays_in_initialization_mode() {
    let f = Fmu::<Lag>::new();
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(f.set_real(&[W], &[-1000.0]));
    let (s, _) = f.get_real(&[Y]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(fmi2Error, "no equilibrium"));
    let before = f.state_bytes();
    assert_eq!(
        unsafe { api::exit_initialization_mode::<Lag>(f.c) },
        fmi2Error
    );
    assert!(f.has_log(
        fmi2Error,
        "fmi2ExitInitializationMode: initialization failed"
    ));
    assert_eq!(f.state_bytes(), before);
    // Still in initialization mode: fix the input and exit.
    f.ok(f.set_real(&[W], &[0.5]));
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    assert_eq!(f.real(Y), 0.5);
    f.ok(f.step(0.0, 0.1));
}

// ---------------------------------------------------------------------------
// Value references, types, settability
// ---------------------------------------------------------------------------

#[test]
fn unknown_value_reference_and_type_mismatch() {
    let f = Fmu::<Lag>::running();
    let before = f.state_bytes();
    let (s, _) = f.get_real(&[Y, 99]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(fmi2Error, "fmi2GetReal: unknown value reference 99"));
    assert_eq!(f.set_real(&[N_VARS], &[1.0]), fmi2Error);
    assert!(f.has_log(fmi2Error, &format!("unknown value reference {N_VARS}")));
    let (s, _) = f.get_integer(&[u32::MAX]);
    assert_eq!(s, fmi2Error);

    // Type mismatches name the variable.
    let (s, _) = f.get_real(&[HIGH]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(
        fmi2Error,
        "variable 'high' (value reference 10) is of type Boolean, not Real"
    ));
    let (s, _) = f.get_boolean(&[Y]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(fmi2Error, "'y'"));
    assert_eq!(f.set_integer(&[U], &[1]), fmi2Error);
    assert!(f.has_log(
        fmi2Error,
        "variable 'u' (value reference 0) is of type Real, not Integer"
    ));
    let mut sv: fmi2String = std::ptr::null();
    assert_eq!(
        unsafe { api::get_string::<Lag>(f.c, &Y, 1, &mut sv) },
        fmi2Error
    );
    assert!(f.has_log(fmi2Error, "is of type Real, not String"));
    let cs = c"x";
    assert_eq!(
        unsafe { api::set_string::<Lag>(f.c, &U, 1, &cs.as_ptr()) },
        fmi2Error
    );
    assert_eq!(f.state_bytes(), before);
}

#[test]
fn only_settable_variables_can_be_set() {
    // Instantiated: parameters (fixed and tunable) and inputs.
    let f = Fmu::<Lag>::new();
    f.ok(f.set_real(&[TAU, HMAX, GAIN, U, W], &[2.0, 0.4, 1.5, 0.1, 0.2]));
    for (vr, name) in [(Y, "y"), (TAU_MS, "tau_ms"), (INTERNAL, "internal")] {
        assert_eq!(f.set_real(&[vr], &[1.0]), fmi2Error);
        assert!(
            f.has_log(fmi2Error, &format!("variable '{name}' (causality = ")),
            "{name}: {:#?}",
            f.logs()
        );
    }
    assert_eq!(f.set_integer(&[ANSWER], &[1]), fmi2Error);
    assert!(f.has_log(
        fmi2Error,
        "fmi2SetInteger: variable 'answer' (causality = local, variability = constant) cannot be set in state instantiated"
    ));
    assert_eq!(f.set_integer(&[STEPS], &[1]), fmi2Error);
    assert_eq!(f.set_boolean(&[HIGH], &[true]), fmi2Error);

    // stepComplete: inputs and tunable parameters only.
    let f = Fmu::<Lag>::running();
    f.ok(f.set_real(&[U, W, GAIN], &[0.1, 0.2, 3.0]));
    f.ok(f.set_integer(&[MODE], &[3]));
    f.ok(f.set_boolean(&[CLAMP], &[true]));
    for (vr, name) in [(TAU, "tau"), (HMAX, "h_max"), (Y, "y"), (Z, "z")] {
        let before = f.state_bytes();
        assert_eq!(f.set_real(&[vr], &[1.0]), fmi2Error);
        assert!(f.has_log(
            fmi2Error,
            &format!("fmi2SetReal: variable '{name}' (causality = ")
        ));
        assert!(f.has_log(fmi2Error, "cannot be set in state stepComplete"));
        assert_eq!(f.state_bytes(), before);
    }
}

#[test]
fn refused_value_names_variable_value_and_range_and_vector_set_is_atomic() {
    let f = Fmu::<Lag>::new();
    f.ok(f.set_real(&[U], &[0.7]));
    let before = f.state_bytes();
    // The second element is refused: the first must not stick.
    assert_eq!(f.set_real(&[U, TAU, GAIN], &[0.1, -1.0, 5.0]), fmi2Error);
    assert!(
        f.has_log(
            fmi2Error,
            "fmi2SetReal: cannot set 'tau' = -1.0: tau = -1 is out of the valid range (0, inf)"
        ),
        "{:#?}",
        f.logs()
    );
    assert_eq!(f.state_bytes(), before);
    assert_eq!(f.set_real(&[W], &[f64::INFINITY]), fmi2Error);
    assert!(f.has_log(fmi2Error, "cannot set 'w' = inf"));
    assert_eq!(f.set_integer(&[MODE, MODE], &[2, 7]), fmi2Error);
    assert_eq!(f.state_bytes(), before);
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    assert_eq!(f.real(Y), 2.0 * 0.7);
}

#[test]
fn nvr_zero_with_null_arrays_is_fine() {
    let f = Fmu::<Lag>::running();
    unsafe {
        f.ok(api::get_real::<Lag>(f.c, cn(), 0, nm()));
        f.ok(api::get_integer::<Lag>(f.c, cn(), 0, nm()));
        f.ok(api::get_boolean::<Lag>(f.c, cn(), 0, nm()));
        f.ok(api::get_string::<Lag>(f.c, cn(), 0, nm()));
        f.ok(api::set_real::<Lag>(f.c, cn(), 0, cn()));
        f.ok(api::set_integer::<Lag>(f.c, cn(), 0, cn()));
        f.ok(api::set_boolean::<Lag>(f.c, cn(), 0, cn()));
        f.ok(api::set_string::<Lag>(f.c, cn(), 0, cn()));
        f.ok(api::get_directional_derivative::<Lag>(
            f.c,
            cn(),
            0,
            cn(),
            0,
            cn(),
            nm(),
        ));
        f.ok(api::set_real_input_derivatives::<Lag>(
            f.c,
            cn(),
            0,
            cn(),
            cn(),
        ));
        f.ok(api::get_real_output_derivatives::<Lag>(
            f.c,
            cn(),
            0,
            cn(),
            nm(),
        ));
    }
    // dvUnknown for one unknown and zero knowns is zero.
    let mut dv = f64::NAN;
    f.ok(unsafe { api::get_directional_derivative::<Lag>(f.c, &Y, 1, cn(), 0, cn(), &mut dv) });
    assert_eq!(dv, 0.0);
}

#[test]
fn null_pointers_everywhere() {
    let nc: fmi2Component = std::ptr::null_mut();
    unsafe {
        // NULL component: fmi2Error (nothing to log to), no crash.
        assert_eq!(api::set_debug_logging::<Lag>(nc, 1, 0, cn()), fmi2Error);
        assert_eq!(
            api::setup_experiment::<Lag>(nc, 0, 0.0, 0.0, 0, 0.0),
            fmi2Error
        );
        assert_eq!(api::enter_initialization_mode::<Lag>(nc), fmi2Error);
        assert_eq!(api::exit_initialization_mode::<Lag>(nc), fmi2Error);
        assert_eq!(api::terminate::<Lag>(nc), fmi2Error);
        assert_eq!(api::reset::<Lag>(nc), fmi2Error);
        assert_eq!(api::get_real::<Lag>(nc, &Y, 1, &mut 0.0), fmi2Error);
        assert_eq!(api::set_real::<Lag>(nc, &U, 1, &0.0), fmi2Error);
        assert_eq!(
            api::get_fmu_state::<Lag>(nc, &mut std::ptr::null_mut()),
            fmi2Error
        );
        assert_eq!(api::set_fmu_state::<Lag>(nc, nm()), fmi2Error);
        assert_eq!(
            api::free_fmu_state::<Lag>(nc, &mut std::ptr::null_mut()),
            fmi2Error
        );
        assert_eq!(
            api::serialized_fmu_state_size::<Lag>(nc, nm(), &mut 0),
            fmi2Error
        );
        assert_eq!(
            api::serialize_fmu_state::<Lag>(nc, nm(), nm::<fmi2Byte>(), 0),
            fmi2Error
        );
        assert_eq!(
            api::deserialize_fmu_state::<Lag>(nc, cn(), 0, &mut std::ptr::null_mut()),
            fmi2Error
        );
        assert_eq!(api::do_step::<Lag>(nc, 0.0, 0.1, 0), fmi2Error);
        assert_eq!(api::cancel_step::<Lag>(nc), fmi2Error);
        assert_eq!(
            api::get_status::<Lag>(nc, fmi2DoStepStatus, &mut fmi2OK),
            fmi2Error
        );
        assert_eq!(
            api::get_real_status::<Lag>(nc, fmi2LastSuccessfulTime, &mut 0.0),
            fmi2Error
        );
        api::free_instance::<Lag>(nc);
    }

    let f = Fmu::<Lag>::running();
    let c = f.c;
    let before = f.state_bytes();
    let checks: Vec<(fmi2Status, &str)> = unsafe {
        vec![
            (
                api::get_real::<Lag>(c, cn(), 1, &mut 0.0),
                "fmi2GetReal: vr is NULL",
            ),
            (
                api::get_real::<Lag>(c, &Y, 1, nm()),
                "fmi2GetReal: value is NULL",
            ),
            (
                api::get_integer::<Lag>(c, &STEPS, 1, nm()),
                "fmi2GetInteger: value is NULL",
            ),
            (
                api::get_boolean::<Lag>(c, cn(), 2, nm()),
                "fmi2GetBoolean: vr is NULL",
            ),
            (
                api::get_string::<Lag>(c, cn(), 1, nm()),
                "fmi2GetString: vr is NULL",
            ),
            (
                api::set_real::<Lag>(c, &U, 1, cn()),
                "fmi2SetReal: value is NULL",
            ),
            (
                api::set_integer::<Lag>(c, cn(), 1, &1),
                "fmi2SetInteger: vr is NULL",
            ),
            (
                api::set_boolean::<Lag>(c, &CLAMP, 1, cn()),
                "fmi2SetBoolean: value is NULL",
            ),
            (
                api::set_string::<Lag>(c, cn(), 1, cn()),
                "fmi2SetString: vr is NULL",
            ),
            (
                api::set_debug_logging::<Lag>(c, 1, 2, cn()),
                "fmi2SetDebugLogging: categories is NULL",
            ),
            (
                api::set_debug_logging::<Lag>(c, 1, 1, &std::ptr::null()),
                "categories[0] is NULL",
            ),
            (
                api::get_fmu_state::<Lag>(c, nm::<fmi2FMUstate>()),
                "fmi2GetFMUstate: FMUstate is NULL",
            ),
            (
                api::set_fmu_state::<Lag>(c, nm()),
                "fmi2SetFMUstate: FMUstate is NULL",
            ),
            (
                api::serialized_fmu_state_size::<Lag>(c, nm(), &mut 0),
                "FMUstate is NULL",
            ),
            (
                api::serialize_fmu_state::<Lag>(c, nm(), nm::<fmi2Byte>(), 10),
                "FMUstate is NULL",
            ),
            (
                api::deserialize_fmu_state::<Lag>(c, cn(), 10, &mut std::ptr::null_mut()),
                "fmi2DeSerializeFMUstate: serializedState is NULL",
            ),
            (
                api::deserialize_fmu_state::<Lag>(
                    c,
                    [0 as fmi2Byte].as_ptr(),
                    1,
                    nm::<fmi2FMUstate>(),
                ),
                "fmi2DeSerializeFMUstate: FMUstate is NULL",
            ),
            (
                api::get_directional_derivative::<Lag>(c, &Y, 1, &U, 1, cn(), &mut 0.0),
                "dvKnown is NULL",
            ),
            (
                api::get_directional_derivative::<Lag>(c, &Y, 1, &U, 1, &1.0, nm()),
                "dvUnknown is NULL",
            ),
            (
                api::set_real_input_derivatives::<Lag>(c, &U, 1, cn(), &1.0),
                "order is NULL",
            ),
            (
                api::get_real_output_derivatives::<Lag>(c, &Y, 1, &1, nm()),
                "value is NULL",
            ),
            (
                api::get_status::<Lag>(c, fmi2DoStepStatus, nm::<fmi2Status>()),
                "fmi2GetStatus: value is NULL",
            ),
            (
                api::get_real_status::<Lag>(c, fmi2LastSuccessfulTime, nm()),
                "value is NULL",
            ),
            (
                api::get_integer_status::<Lag>(c, fmi2DoStepStatus, nm()),
                "value is NULL",
            ),
            (
                api::get_boolean_status::<Lag>(c, fmi2Terminated, nm()),
                "value is NULL",
            ),
            (
                api::get_string_status::<Lag>(c, fmi2PendingStatus, nm()),
                "value is NULL",
            ),
        ]
    };
    for (i, (status, needle)) in checks.iter().enumerate() {
        assert_eq!(*status, fmi2Error, "check {i}: {needle}");
        assert!(
            f.has_log(fmi2Error, needle),
            "check {i}: '{needle}': {:#?}",
            f.logs()
        );
    }
    // FreeFMUstate with NULL is a no-op.
    f.ok(unsafe { api::free_fmu_state::<Lag>(c, nm::<fmi2FMUstate>()) });
    f.ok(unsafe { api::free_fmu_state::<Lag>(c, &mut std::ptr::null_mut()) });
    assert_eq!(f.state_bytes(), before);
}

#[test]
fn instantiate_rejects_bad_arguments() {
    let g = guid::<Lag>();
    for (name, ty, gd, needle) in [
        (
            None,
            fmi2CoSimulation,
            Some(g.as_str()),
            "instanceName is NULL",
        ),
        (
            Some("  "),
            fmi2CoSimulation,
            Some(g.as_str()),
            "instanceName is empty",
        ),
        (
            Some("a"),
            fmi2ModelExchange,
            Some(g.as_str()),
            "fmuType is fmi2ModelExchange",
        ),
        (Some("a"), 7, Some(g.as_str()), "unknown fmi2Type"),
        (Some("a"), fmi2CoSimulation, None, "fmuGUID is NULL"),
        (
            Some("a"),
            fmi2CoSimulation,
            Some("{00000000-0000-0000-0000-000000000000}"),
            "does not match this binary",
        ),
        (
            Some("a"),
            fmi2CoSimulation,
            Some(&guid::<Lag2>()),
            "does not match",
        ),
    ] {
        let (c, book) = try_instantiate::<Lag>(name, ty, gd, false);
        assert!(c.is_null(), "{needle}");
        let logs = book.entries();
        assert!(
            logs.iter()
                .any(|e| e.status == fmi2Error && e.message.contains(needle)),
            "{needle}: {logs:#?}"
        );
    }
    // NULL callbacks and NULL resource location are fine.
    let name = c"quiet";
    let gc = CString::new(g).unwrap();
    let c = unsafe {
        api::instantiate::<Lag>(
            name.as_ptr(),
            fmi2CoSimulation,
            gc.as_ptr(),
            std::ptr::null(),
            std::ptr::null(),
            fmi2False,
            fmi2True,
        )
    };
    assert!(!c.is_null());
    // Errors without a logger are just not logged.
    assert_eq!(unsafe { api::do_step::<Lag>(c, 0.0, 0.1, 0) }, fmi2Error);
    let cb = fmi2CallbackFunctions {
        logger: None,
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: std::ptr::null_mut(),
    };
    let c2 = unsafe {
        api::instantiate::<Lag>(
            name.as_ptr(),
            fmi2CoSimulation,
            gc.as_ptr(),
            cn(),
            &cb,
            0,
            1,
        )
    };
    assert!(!c2.is_null());
    unsafe {
        api::free_instance::<Lag>(c);
        api::free_instance::<Lag>(c2);
    }
}

fn cn<T>() -> *const T {
    std::ptr::null()
}

fn nm<T>() -> *mut T {
    std::ptr::null_mut()
}

#[test]
fn instance_of_another_model_type_is_rejected() {
    let f = Fmu::<Lag>::running();
    // Handing a Lag instance to Lag2's functions is caught, not misread.
    assert_eq!(unsafe { api::do_step::<Lag2>(f.c, 0.0, 0.1, 0) }, fmi2Error);
    unsafe { api::free_instance::<Lag2>(f.c) }; // ignored
    f.ok(f.step(0.0, 0.1));
}

// ---------------------------------------------------------------------------
// fmi2DoStep
// ---------------------------------------------------------------------------

#[test]
fn do_step_rejects_bad_steps_without_changing_anything() {
    let f = Fmu::<Lag>::running(); // stop time 10
    f.ok(f.set_real(&[U], &[1.0]));
    f.ok(f.step(0.0, 0.25));
    let before = f.state_bytes();
    for (tc, h, needle) in [
        (
            0.25,
            0.0,
            "communicationStepSize = 0.0 must be finite and > 0",
        ),
        (0.25, -0.1, "must be finite and > 0"),
        (0.25, f64::NAN, "communicationStepSize = NaN"),
        (0.25, f64::INFINITY, "must be finite"),
        (
            f64::NAN,
            0.1,
            "currentCommunicationPoint = NaN does not match the FMU time 0.25",
        ),
        (0.0, 0.1, "currentCommunicationPoint = 0.0 does not match"),
        (0.26, 0.1, "does not match"),
        (0.25 + 1e-6, 0.1, "does not match"),
        (0.25, 9.76, "goes past stopTime = 10.0"),
    ] {
        f.clear_logs();
        assert_eq!(f.step(tc, h), fmi2Error, "tc = {tc}, h = {h}");
        assert!(f.has_log(fmi2Error, needle), "{needle}: {:#?}", f.logs());
        assert!(f.has_log(fmi2Error, "fmi2DoStep: "));
        assert_eq!(f.state_bytes(), before);
    }
    // Within the tolerance: accepted.
    f.ok(f.step(0.25 + 1e-12, 0.1));
    // Exactly to the stop time (with accumulated rounding) is fine.
    let mut t: f64 = 0.35 + 1e-12;
    while t < 10.0 - 1e-9 {
        let h = (10.0 - t).min(0.5);
        f.ok(f.step(t, h));
        t += h;
    }
    assert_eq!(f.step(t, 1e-3), fmi2Error);
}

/// Time that would not advance is not reported as advanced: from a start
/// time of 1e16 a step of 1 ms leaves t + h == t (and at 1e13 it would
/// advance by twice h): refused with fmi2Error naming the step, the
/// instance unchanged. The communication-point check is absolute beyond
/// |t| = 5e8 h: at t = 1e13 a point 1e4 s off (within the old relative
/// 1e-9 |t|) is refused, and the tolerance never exceeds 0.500001 h.
#[test]
fn a_step_the_time_cannot_resolve_is_refused() {
    for (start, h) in [(1e16, 1e-3), (1e13, 1e-3), (1.0, 1e-17)] {
        let f = Fmu::<Lag>::new();
        // h_max raised to let the resolved step below through.
        let resolved = 1e3 * start * f64::EPSILON;
        f.ok(f.set_real(&[HMAX], &[resolved]));
        f.ok(unsafe { api::setup_experiment::<Lag>(f.c, 0, 0.0, start, 0, 0.0) });
        f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
        f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
        let before = f.state_bytes();
        f.clear_logs();
        assert_eq!(f.step(start, h), fmi2Error, "start {start}, h {h}");
        assert!(f.has_log(fmi2Error, "cannot represent the time after this step"));
        assert_eq!(f.state_bytes(), before);
        // A step the time resolves goes through.
        f.ok(f.step(start, resolved));
    }
    let f = Fmu::<Lag>::new();
    f.ok(unsafe { api::setup_experiment::<Lag>(f.c, 0, 0.0, 1e13, 0, 0.0) });
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    assert_eq!(f.step(1e13 + 1e4, 0.1), fmi2Error);
    assert!(f.has_log(fmi2Error, "does not match the FMU time"));
    assert_eq!(f.step(1e13 + 0.06, 0.1), fmi2Error);
    f.ok(f.step(1e13 + 0.04, 0.1));
    for (t, h) in [(1e13, 1e-3), (0.0, 1.0), (1e300, 1e290), (3.0, 1e-12)] {
        assert!(api::time_tolerance(t, h) <= 0.500001 * h * (1.0 + 1e-15));
    }
}

#[test]
fn accumulated_time_drift_over_a_million_tiny_steps_is_accepted() {
    let f = Fmu::<Lag>::new();
    f.ok(unsafe { api::setup_experiment::<Lag>(f.c, 0, 0.0, 0.0, fmi2True, 0.1) });
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    f.ok(f.set_real(&[U], &[1.0]));
    let h = 1e-7;
    let n = 1_000_000;
    // Half with t += h (as most importers), half with t = t0 + i*h.
    let mut t = 0.0;
    for _ in 0..n / 2 {
        let s = f.step(t, h);
        if s != fmi2OK {
            panic!("t = {t}: {:#?}", f.logs());
        }
        t += h;
    }
    let t0 = t;
    for i in 0..n / 2 {
        let tc = t0 + i as f64 * h;
        let s = f.step(tc, h);
        if s != fmi2OK {
            panic!("tc = {tc}: {:#?}", f.logs());
        }
    }
    let (s, ints) = f.get_integer(&[STEPS]);
    f.ok(s);
    assert_eq!(ints[0], n);
    let (s, last) = f.last_successful_time();
    f.ok(s);
    assert!((last - 0.1).abs() < 1e-9, "{last}");
}

#[test]
fn discard_rollback_and_continue() {
    let f = Fmu::<Lag>::running();
    f.ok(f.set_real(&[U], &[1.0]));
    f.ok(f.step(0.0, 0.5));
    let saved = f.save();
    let before = f.state_bytes();
    f.clear_logs();
    // h > h_max: the model discards.
    assert_eq!(f.step(0.5, 0.8), fmi2Discard);
    let discard: Vec<Entry> = f
        .logs()
        .into_iter()
        .filter(|e| e.status == fmi2Discard)
        .collect();
    assert_eq!(discard.len(), 1, "{:#?}", f.logs());
    assert_eq!(discard[0].category, "logStatusDiscard");
    assert!(discard[0].message.contains("h = 0.8 > h_max = 0.5"));

    let (s, t) = f.last_successful_time();
    f.ok(s);
    assert_eq!(t, 0.5);
    let mut st = fmi2OK;
    f.ok(unsafe { api::get_status::<Lag>(f.c, fmi2DoStepStatus, &mut st) });
    assert_eq!(st, fmi2Discard);
    let mut term = fmi2True;
    f.ok(unsafe { api::get_boolean_status::<Lag>(f.c, fmi2Terminated, &mut term) });
    assert_eq!(term, fmi2False);
    let mut s_str: fmi2String = std::ptr::null();
    assert_eq!(
        unsafe { api::get_string_status::<Lag>(f.c, fmi2PendingStatus, &mut s_str) },
        fmi2Discard
    );
    let mut i = 0;
    assert_eq!(
        unsafe { api::get_integer_status::<Lag>(f.c, fmi2LastSuccessfulTime, &mut i) },
        fmi2Discard
    );
    assert_eq!(
        unsafe { api::get_real_status::<Lag>(f.c, 99, &mut 0.0) },
        fmi2Error
    );
    // The model is unchanged; outputs can be read.
    assert_eq!(f.real(Y), lag_step(0.0, 2.0, 0.5, 1.0));
    // In stepFailed, DoStep is not allowed.
    assert_eq!(f.step(0.5, 0.1), fmi2Error);
    assert!(f.has_log(fmi2Error, "fmi2DoStep: not allowed in state stepFailed"));

    // Roll back and continue with a smaller step.
    f.ok(f.restore(saved));
    assert_eq!(f.state_bytes(), before);
    f.ok(f.step(0.5, 0.4));
    f.ok(f.step(0.9, 0.4));
    let (s, t) = f.last_successful_time();
    f.ok(s);
    assert!((t - 1.3).abs() < 1e-12);
    f.free_state(saved);
}

#[test]
fn model_error_enters_error_state_and_fmu_state_recovers() {
    let f = Fmu::<Lag>::running();
    let saved = f.save();
    f.ok(f.set_real(&[W], &[2e6]));
    assert_eq!(f.step(0.0, 0.1), fmi2Error);
    assert!(f.has_log(fmi2Error, "w = 2000000 is too large"));
    assert_eq!(f.step(0.0, 0.1), fmi2Error);
    assert!(f.has_log(fmi2Error, "not allowed in state error"));
    // Values are readable in state error, and an FMU state brings it back.
    assert_eq!(f.real(W), 2e6);
    f.ok(f.restore(saved));
    f.ok(f.step(0.0, 0.1));
}

#[test]
fn panic_becomes_fatal() {
    let f = Fmu::<Lag>::running();
    f.ok(f.set_real(&[W], &[12345.0]));
    assert_eq!(f.step(0.0, 0.1), fmi2Fatal);
    let fatal: Vec<Entry> = f
        .logs()
        .into_iter()
        .filter(|e| e.status == fmi2Fatal)
        .collect();
    assert_eq!(fatal.len(), 1);
    assert_eq!(fatal[0].category, "logStatusFatal");
    assert!(fatal[0]
        .message
        .contains("fmi2DoStep: internal error (panic): test panic No.7"));
    // Nothing is allowed in fatal.
    let (s, _) = f.get_real(&[Y]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(fmi2Error, "fmi2GetReal: not allowed in state fatal"));
    assert_eq!(unsafe { api::reset::<Lag>(f.c) }, fmi2Error);
    let mut s = std::ptr::null_mut();
    assert_eq!(unsafe { api::get_fmu_state::<Lag>(f.c, &mut s) }, fmi2Error);
    // FreeInstance (in Drop) still releases it.
}

// ---------------------------------------------------------------------------
// FMU states
// ---------------------------------------------------------------------------

fn trajectory(f: &Fmu<Lag>, t0: f64, n: usize) -> Vec<u64> {
    let mut out = Vec::new();
    let mut t = t0;
    for i in 0..n {
        f.ok(f.set_real(&[U], &[(i as f64 * 0.7).sin()]));
        f.ok(f.step(t, 0.05));
        t += 0.05;
        out.push(f.real(Y).to_bits());
        out.push(f.real(Z).to_bits());
    }
    out
}

#[test]
fn get_set_fmu_state_continues_bit_for_bit() {
    let f = Fmu::<Lag>::running();
    let _ = trajectory(&f, 0.0, 7);
    let t1 = 7.0 * 0.05;
    let (s, t_check) = f.last_successful_time();
    f.ok(s);
    let s1 = f.save();
    let first = trajectory(&f, t_check, 20);
    f.ok(f.restore(s1));
    let second = trajectory(&f, t_check, 20);
    assert_eq!(first, second);
    assert!((t_check - t1).abs() < 1e-12);

    // Overwrite in place: same pointer, new content.
    let mut p = s1;
    f.ok(unsafe { api::get_fmu_state::<Lag>(f.c, &mut p) });
    assert_eq!(p, s1);
    let third = trajectory(&f, t_check + 20.0 * 0.05, 3);
    f.ok(f.restore(s1));
    assert_eq!(trajectory(&f, t_check + 20.0 * 0.05, 3), third);

    // Unknown or freed pointers are rejected.
    let mut bogus = 0x1234usize as fmi2FMUstate;
    assert_eq!(
        unsafe { api::get_fmu_state::<Lag>(f.c, &mut bogus) },
        fmi2Error
    );
    assert!(f.has_log(fmi2Error, "is not an FMU state of this instance"));
    assert_eq!(f.restore(bogus), fmi2Error);
    f.free_state(s1);
    assert_eq!(f.restore(s1), fmi2Error);
    let mut again = s1;
    assert_eq!(
        unsafe { api::free_fmu_state::<Lag>(f.c, &mut again) },
        fmi2Error
    );

    // A state of another instance is rejected (use (de)serialization).
    let g = Fmu::<Lag>::running();
    let sg = g.save();
    assert_eq!(f.restore(sg), fmi2Error);
    // States still owned at FreeInstance are freed with the instance.
    let _leftover = f.save();
}

#[test]
fn fmu_state_restores_fmi_state_and_time() {
    let f = Fmu::<Lag>::new();
    let s_inst = f.save();
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    f.ok(f.step(0.0, 0.1));
    f.ok(unsafe { api::terminate::<Lag>(f.c) });
    f.ok(f.restore(s_inst));
    // Back in instantiated: SetupExperiment is allowed again.
    f.ok(unsafe { api::setup_experiment::<Lag>(f.c, 0, 0.0, 5.0, 0, 0.0) });
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    f.ok(f.step(5.0, 0.1));
}

#[test]
fn serialize_deserialize_round_trip() {
    let f = Fmu::<Lag>::running();
    let _ = trajectory(&f, 0.0, 5);
    let (_, t) = f.last_successful_time();
    let s = f.save();
    let bytes = f.serialize(s);
    // Values only: the same state serializes to the same bytes.
    assert_eq!(f.serialize(s), bytes);
    assert_eq!(&bytes[..8], b"HMFMI2ST");

    let (st, d) = f.deserialize(&bytes);
    f.ok(st);
    assert!(!d.is_null() && d != s);
    assert_eq!(f.serialize(d), bytes);

    // Another instance (as another process would) continues identically.
    let g = Fmu::<Lag>::named("other", false);
    let (st, gd) = g.deserialize(&bytes);
    g.ok(st);
    g.ok(g.restore(gd));
    assert_eq!(g.state_bytes(), bytes);
    let expected = trajectory(&f, t, 10);
    assert_eq!(trajectory(&g, t, 10), expected);

    // A larger buffer is fine for both directions.
    let mut big = vec![0 as fmi2Byte; bytes.len() + 16];
    f.ok(unsafe { api::serialize_fmu_state::<Lag>(f.c, s, big.as_mut_ptr(), big.len()) });
    let big_u8: Vec<u8> = big.iter().map(|&b| b as u8).collect();
    assert_eq!(&big_u8[..bytes.len()], &bytes[..]);
    let (st, d2) = f.deserialize(&big_u8);
    f.ok(st);
    assert_eq!(f.serialize(d2), bytes);
    // Too small a buffer is an error.
    let mut small = vec![0 as fmi2Byte; bytes.len() - 1];
    assert_eq!(
        unsafe { api::serialize_fmu_state::<Lag>(f.c, s, small.as_mut_ptr(), small.len()) },
        fmi2Error
    );
    assert!(f.has_log(fmi2Error, "is too small"));
}

#[test]
fn corrupt_truncated_or_foreign_states_are_rejected() {
    let f = Fmu::<Lag>::running();
    f.ok(f.step(0.0, 0.1));
    let s = f.save();
    let bytes = f.serialize(s);
    let before = f.state_bytes();

    // Every truncation.
    for n in 0..bytes.len() {
        let (st, d) = f.deserialize(&bytes[..n]);
        assert_eq!(st, fmi2Error, "truncated to {n}");
        assert!(d.is_null());
    }
    assert!(f.has_log(fmi2Error, "truncated"));
    // Every single-bit corruption.
    for i in 0..bytes.len() {
        for bit in [0, 3, 7] {
            let mut b = bytes.clone();
            b[i] ^= 1 << bit;
            let (st, d) = f.deserialize(&b);
            assert_eq!(st, fmi2Error, "byte {i} bit {bit}");
            assert!(d.is_null());
        }
    }
    assert!(f.has_log(fmi2Error, "checksum mismatch"));
    assert!(f.has_log(fmi2Error, "bad magic bytes"));
    // Garbage.
    let (st, _) = f.deserialize(&[7u8; 100]);
    assert_eq!(st, fmi2Error);

    // A state of another interface version (different GUID).
    let g = Fmu::<Lag2>::running();
    let gs = g.save();
    let foreign = g.serialize(gs);
    let (st, d) = f.deserialize(&foreign);
    assert_eq!(st, fmi2Error);
    assert!(d.is_null());
    assert!(
        f.has_log(fmi2Error, "belongs to another model or interface version"),
        "{:#?}",
        f.logs()
    );
    // None of this changed the instance or allocated a state.
    assert_eq!(f.state_bytes(), before);
}

#[test]
fn reset_gives_a_fresh_instance() {
    let fresh = Fmu::<Lag>::new();
    let f = Fmu::<Lag>::running();
    f.ok(f.set_real(&[U, GAIN], &[0.9, 4.0]));
    f.ok(f.set_boolean(&[CLAMP], &[true]));
    assert_eq!(f.set_real(&[U], &[3.0]), fmi2Warning); // a log-once warning
    f.ok(f.step(0.0, 0.1));
    let kept = f.save();
    f.ok(unsafe { api::reset::<Lag>(f.c) });
    assert_eq!(f.state_bytes(), fresh.state_bytes());
    // Like a new instance: whole lifecycle again, warnings logged again.
    f.ok(unsafe { api::setup_experiment::<Lag>(f.c, 0, 0.0, 2.0, 0, 0.0) });
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    assert_eq!(f.real(Y), 0.0);
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    f.ok(f.set_boolean(&[CLAMP], &[true]));
    f.clear_logs();
    assert_eq!(f.set_real(&[U], &[3.0]), fmi2Warning);
    assert!(f.has_log(fmi2Warning, "clamped"));
    f.ok(f.step(2.0, 0.1));
    // FMU states survive a reset.
    f.ok(f.restore(kept));
    f.ok(f.step(0.1, 0.1));
}

// ---------------------------------------------------------------------------
// Logging
// ---------------------------------------------------------------------------

#[test]
fn logger_gets_percent_s_text_without_hash_and_the_instance_name() {
    let f = Fmu::<Lag>::named("muscle #3 (left)", false);
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    assert_eq!(f.set_integer(&[MODE], &[9]), fmi2Error);
    let logs = f.logs();
    assert!(!logs.is_empty());
    for e in &logs {
        assert_eq!(e.format, "%s");
        assert_eq!(e.instance, b"muscle #3 (left)");
        assert!(!e.message.contains('#'), "{}", e.message);
    }
    let e = logs.iter().find(|e| e.status == fmi2Error).unwrap();
    assert_eq!(e.category, "logStatusError");
    assert_eq!(
        e.message,
        "fmi2SetInteger: cannot set 'mode' = 9: mode No.9 is not in the valid range [1, 3]"
    );
    // A message with printf directives is passed through as data.
    assert_eq!(f.set_real(&[U], &[f64::NAN]), fmi2Error);
    assert!(f.has_log(fmi2Error, "u = NaN is not finite"));
}

#[test]
fn debug_logging_categories() {
    // loggingOn = false: no debug messages.
    let f = Fmu::<Lag>::named("dbg", false);
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(f.set_real(&[U], &[0.5]));
    assert!(f.logs().is_empty(), "{:#?}", f.logs());

    // All categories.
    f.ok(unsafe { api::set_debug_logging::<Lag>(f.c, fmi2True, 0, std::ptr::null()) });
    f.clear_logs();
    f.ok(f.set_real(&[U], &[0.25]));
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    let logs = f.logs();
    assert!(logs.iter().any(|e| e.status == fmi2OK
        && e.category == "logAll"
        && e.message == "fmi2SetReal: u = 0.25"));
    assert!(logs.iter().any(|e| e.status == fmi2OK
        && e.category == "logEvents"
        && e.message.contains("stepComplete")));

    // Only logEvents: straight from "all on", the list replaces the
    // selection (no `(false, 0)` first).
    let cats = [c"logEvents".as_ptr()];
    f.ok(unsafe { api::set_debug_logging::<Lag>(f.c, fmi2True, 1, cats.as_ptr()) });
    f.clear_logs();
    f.ok(f.set_real(&[U], &[0.3]));
    f.ok(f.step(0.0, 0.1));
    let s = f.save();
    let logs = f.logs();
    assert!(logs.iter().all(|e| e.category == "logEvents"), "{logs:#?}");
    assert!(logs.iter().any(|e| e.message.contains("fmi2GetFMUstate")));
    f.free_state(s);

    // Unknown category: error, settings unchanged.
    let bad = [c"logEvents".as_ptr(), c"logNonsense".as_ptr()];
    f.clear_logs();
    assert_eq!(
        unsafe { api::set_debug_logging::<Lag>(f.c, fmi2False, 2, bad.as_ptr()) },
        fmi2Error
    );
    assert!(f.has_log(fmi2Error, "unknown log category 'logNonsense'"));
    f.clear_logs();
    f.ok(unsafe { api::terminate::<Lag>(f.c) });
    assert!(f
        .logs()
        .iter()
        .any(|e| e.category == "logEvents" && e.message.contains("terminated")));

    // Warnings and errors are logged even with debug logging off.
    let g = Fmu::<Lag>::named("quiet", false);
    assert_eq!(g.step(0.0, 0.1), fmi2Error);
    assert!(g.has_log(fmi2Error, "not allowed in state instantiated"));
}

/// `fmi2SetDebugLogging(c, loggingOn, categories)` through the C signature.
fn set_logging(f: &Fmu<Lag>, on: bool, cats: &[&CStr]) -> fmi2Status {
    let ptrs: Vec<fmi2String> = cats.iter().map(|c| c.as_ptr()).collect();
    let on = if on { fmi2True } else { fmi2False };
    unsafe { api::set_debug_logging::<Lag>(f.c, on, ptrs.len(), ptrs.as_ptr()) }
}

/// Calls that log debug messages of both categories (from an instantiated
/// instance): initialization and the step (`logEvents` on state changes,
/// `logAll` for every call), a set, an FMU state saved and freed; then a
/// rejected set (an error). Returns the categories of the debug messages
/// (status `fmi2OK`) logged, and whether the error was logged.
fn exercise(f: &Fmu<Lag>) -> (Vec<String>, bool) {
    f.clear_logs();
    f.ok(unsafe { api::setup_experiment::<Lag>(f.c, fmi2False, 0.0, 0.0, fmi2False, 0.0) });
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(f.set_real(&[U], &[0.25]));
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    f.ok(f.step(0.0, 0.1));
    let s = f.save();
    f.free_state(s);
    assert_eq!(f.set_integer(&[MODE], &[9]), fmi2Error);
    let logs = f.logs();
    let mut cats: Vec<String> = logs
        .iter()
        .filter(|e| e.status == fmi2OK)
        .map(|e| e.category.clone())
        .collect();
    cats.sort();
    cats.dedup();
    let error = logs
        .iter()
        .any(|e| e.status == fmi2Error && e.category == "logStatusError");
    (cats, error)
}

#[test]
fn debug_logging_with_categories_logs_only_those_categories() {
    // FMI 2.0 section 2.1.5: "If loggingOn=fmi2True and nCategories > 0,
    // then only debug messages according to the categories argument shall
    // be output." From a fresh instance, whether it was instantiated with
    // loggingOn true (all on) or false (all off).
    for instantiated_on in [true, false] {
        let f = Fmu::<Lag>::named("dbg", instantiated_on);
        f.ok(set_logging(&f, true, &[c"logEvents"]));
        let (cats, error) = exercise(&f);
        assert_eq!(
            cats,
            ["logEvents"],
            "loggingOn at instantiation {instantiated_on}"
        );
        assert!(error);
        // The state changes were among them.
        assert!(f.logs().iter().any(|e| e.status == fmi2OK
            && e.category == "logEvents"
            && e.message.contains("stepComplete")));
    }

    // logAll selects every debug message.
    let f = Fmu::<Lag>::named("dbg", false);
    f.ok(set_logging(&f, true, &[c"logAll"]));
    assert_eq!(exercise(&f).0, ["logAll", "logEvents"]);

    // A later list replaces the earlier selection instead of adding to it.
    let f = Fmu::<Lag>::named("dbg", false);
    f.ok(set_logging(&f, true, &[c"logAll"]));
    f.ok(set_logging(&f, true, &[c"logEvents"]));
    assert_eq!(exercise(&f).0, ["logEvents"]);

    // A status category only: no debug message at all; errors still logged.
    let f = Fmu::<Lag>::named("dbg", true);
    f.ok(set_logging(&f, true, &[c"logStatusError"]));
    let (cats, error) = exercise(&f);
    assert!(cats.is_empty(), "{cats:?}");
    assert!(error);

    // nCategories = 0 turns all of them on again.
    let f = Fmu::<Lag>::named("dbg", false);
    f.ok(set_logging(&f, true, &[c"logEvents"]));
    f.ok(set_logging(&f, true, &[]));
    assert_eq!(exercise(&f).0, ["logAll", "logEvents"]);
}

#[test]
fn debug_logging_off_switches_all_debug_logging_off() {
    // FMI 2.0 section 2.1.5: "If loggingOn = fmi2True, debug logging is
    // enabled, otherwise it is switched off." The categories do not narrow
    // loggingOn = fmi2False: (false, [logAll]) silences logEvents as well.
    for cats in [&[][..], &[c"logAll"][..], &[c"logEvents"][..]] {
        let f = Fmu::<Lag>::named("dbg", true);
        f.ok(set_logging(&f, true, &[c"logAll", c"logEvents"]));
        f.ok(set_logging(&f, false, cats));
        let (seen, error) = exercise(&f);
        assert!(seen.is_empty(), "after (false, {cats:?}): {seen:?}");
        // Errors are always logged (src/fmi2/mod.rs, "Logging").
        assert!(error);
    }
}

#[test]
fn unknown_debug_log_category_is_rejected_and_changes_nothing() {
    let f = Fmu::<Lag>::named("dbg", false);
    f.ok(set_logging(&f, true, &[c"logEvents"]));
    for on in [true, false] {
        f.clear_logs();
        assert_eq!(
            set_logging(&f, on, &[c"logAll", c"logBogus", c"logEvents"]),
            fmi2Error
        );
        let logs = f.logs();
        let e = logs
            .iter()
            .find(|e| e.status == fmi2Error)
            .expect("an error message");
        assert_eq!(e.category, "logStatusError");
        assert!(e.message.contains("'logBogus'"), "{}", e.message);
        for valid in [
            "logStatusWarning",
            "logStatusDiscard",
            "logStatusError",
            "logStatusFatal",
            "logAll",
            "logEvents",
        ] {
            assert!(e.message.contains(valid), "{valid} in {}", e.message);
        }
    }
    // Still exactly logEvents: neither the valid names before and after the
    // bad one nor loggingOn took effect.
    assert_eq!(exercise(&f).0, ["logEvents"]);
}

#[test]
fn warning_is_logged_once_per_instance_when_asked() {
    let f = Fmu::<Lag>::running();
    f.ok(f.set_boolean(&[CLAMP], &[true]));
    f.clear_logs();
    assert_eq!(f.set_real(&[U], &[5.0]), fmi2Warning);
    assert_eq!(f.real(U), 1.0);
    assert_eq!(f.set_real(&[U], &[-7.0]), fmi2Warning);
    assert_eq!(f.real(U), -1.0);
    assert_eq!(f.set_real(&[U, W], &[9.0, 0.5]), fmi2Warning);
    f.ok(f.set_real(&[U], &[0.5]));
    let warnings: Vec<Entry> = f
        .logs()
        .into_iter()
        .filter(|e| e.status == fmi2Warning)
        .collect();
    assert_eq!(warnings.len(), 1, "{warnings:#?}");
    assert_eq!(warnings[0].category, "logStatusWarning");
    assert_eq!(
        warnings[0].message,
        "fmi2SetReal: 'u': u = 5 clamped to 1 (range [-1, 1] when clamp)"
    );
    // Another instance logs its own first warning.
    let g = Fmu::<Lag>::running();
    g.ok(g.set_boolean(&[CLAMP], &[true]));
    assert_eq!(g.set_real(&[U], &[5.0]), fmi2Warning);
    assert!(g.has_log(fmi2Warning, "clamped"));
    // A warned-about element of a rejected vector set is not logged.
    let h = Fmu::<Lag>::running();
    h.ok(h.set_boolean(&[CLAMP], &[true]));
    assert_eq!(h.set_real(&[U, W], &[5.0, f64::NAN]), fmi2Error);
    assert!(!h.has_log(fmi2Warning, "clamped"));
    assert_eq!(h.real(U), 0.0);
}

// ---------------------------------------------------------------------------
// Derivatives
// ---------------------------------------------------------------------------

fn dir_deriv(
    f: &Fmu<Lag>,
    unknowns: &[u32],
    knowns: &[u32],
    seed: &[f64],
) -> (fmi2Status, Vec<f64>) {
    let mut out = vec![f64::NAN; unknowns.len()];
    let s = unsafe {
        api::get_directional_derivative::<Lag>(
            f.c,
            unknowns.as_ptr(),
            unknowns.len(),
            knowns.as_ptr(),
            knowns.len(),
            seed.as_ptr(),
            out.as_mut_ptr(),
        )
    };
    (s, out)
}

/// In initialization mode with inputs set since the initial values were
/// last computed, `fmi2GetDirectionalDerivative` computes them first, on a
/// copy: a call the model refuses (here dz/dw at a negative gain) is
/// `fmi2Error`, writes nothing to `dvUnknown` and changes nothing (the
/// instance's state, initial values not yet computed included), and the
/// same call for a derivative it provides then commits them.
#[test]
fn a_refused_directional_derivative_in_initialization_changes_nothing() {
    let f = Fmu::<Lag>::new();
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(f.set_real(&[GAIN, U], &[-2.0, 0.5]));
    let before = f.state_bytes();
    let (s, d) = dir_deriv(&f, &[Y, Z], &[U, W], &[1.0, 1.0]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(fmi2Error, "negative gain"));
    assert!(d.iter().all(|x| x.is_nan()), "dvUnknown written: {d:?}");
    assert!(
        f.state_bytes() == before,
        "the refused call changed the instance"
    );
    let (s, d) = dir_deriv(&f, &[Y], &[U, W], &[1.0, 1.0]);
    f.ok(s);
    assert_eq!(d, vec![-2.0 + 1.0]);
    assert!(
        f.state_bytes() != before,
        "the initial values were not committed"
    );
}

/// FMI 2.0 section 2.1.9 with 2.2.8: in initialization mode the knowns
/// include the parameters (`initial = "exact"`); the layer differentiates
/// the model's initialization with respect to a Real one.
#[test]
fn in_initialization_mode_real_parameters_are_knowns() {
    let f = Fmu::<Lag>::new();
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(f.set_real(&[GAIN, U, W], &[3.0, 0.5, 0.25]));
    // Initial equilibrium y = gain u + w, z = 3 y: d/d gain = (u, 3 u);
    // y and z do not depend on tau (not in their depends_on): 0.
    let (s, d) = dir_deriv(&f, &[Y, Z], &[GAIN, TAU, U], &[1.0, 7.0, 2.0]);
    f.ok(s);
    approx::assert_relative_eq!(d[0], 0.5 + 2.0 * 3.0, max_relative = 1e-12);
    approx::assert_relative_eq!(d[1], 3.0 * (0.5 + 2.0 * 3.0), max_relative = 1e-12);
    assert_eq!(f.real(GAIN), 3.0, "the instance's parameter moved");
    assert_eq!(f.real(Y), 3.0 * 0.5 + 0.25);
    // Only Real parameters: an Integer one is refused, naming the rule.
    let (s, _) = dir_deriv(&f, &[Y], &[MODE], &[1.0]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(
        fmi2Error,
        "'mode' (value reference 6, Integer parameter) cannot be a known: knowns must be Real inputs or Real parameters"
    ));
    // A difference step the model refuses: an error naming the unknowns,
    // the parameter and the model's reason, and nothing changes.
    f.ok(f.set_real(&[GAIN], &[f64::MAX]));
    let before = f.state_bytes();
    let (s, d) = dir_deriv(&f, &[Y, Z], &[GAIN], &[1.0]);
    assert_eq!(s, fmi2Error);
    assert!(d.iter().all(|x| x.is_nan()), "dvUnknown written: {d:?}");
    assert!(f.has_log(
        fmi2Error,
        "d(y, z)/d(gain) in initialization mode: the difference step to inf was refused: gain = inf is not finite"
    ));
    assert!(
        f.state_bytes() == before,
        "the refused call changed the instance"
    );
    // After initialization the knowns are the inputs only (section 2.2.8:
    // the knowns at a communication point).
    f.ok(f.set_real(&[GAIN], &[3.0]));
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    let (s, _) = dir_deriv(&f, &[Y], &[GAIN], &[1.0]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(
        fmi2Error,
        "'gain' (value reference 3, Real parameter) cannot be a known: knowns must be Real inputs (Real parameters only in initialization mode)"
    ));
}

#[test]
fn directional_derivative_is_the_linear_combination() {
    let f = Fmu::<Lag>::new();
    f.ok(unsafe { api::enter_initialization_mode::<Lag>(f.c) });
    f.ok(f.set_real(&[GAIN], &[3.0]));
    // Initial equilibrium: y = gain u + w.
    let (s, d) = dir_deriv(&f, &[Y, Z], &[U, W], &[0.5, -2.0]);
    f.ok(s);
    assert_eq!(d, vec![3.0 * 0.5 - 2.0, 3.0 * (3.0 * 0.5 - 2.0)]);
    f.ok(unsafe { api::exit_initialization_mode::<Lag>(f.c) });
    f.ok(f.step(0.0, 0.25));
    let k = 0.25 / 1.25;
    let (s, d) = dir_deriv(&f, &[Z, Y], &[W, U], &[1.0, 1.0]);
    f.ok(s);
    approx::assert_relative_eq!(d[0], 3.0 * (k + 3.0 * k), max_relative = 1e-15);
    approx::assert_relative_eq!(d[1], k + 3.0 * k, max_relative = 1e-15);
    // Finite-difference check of dy/du through the C API.
    let g = Fmu::<Lag>::running();
    g.ok(g.set_real(&[GAIN], &[3.0]));
    let saved = g.save();
    g.ok(g.step(0.0, 0.25));
    let y0 = g.real(Y);
    g.ok(g.restore(saved));
    g.ok(g.set_real(&[U], &[1e-6]));
    g.ok(g.step(0.0, 0.25));
    approx::assert_relative_eq!((g.real(Y) - y0) / 1e-6, 3.0 * k, max_relative = 1e-6);

    // Roles are checked and named.
    let (s, _) = dir_deriv(&f, &[U], &[W], &[1.0]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(
        fmi2Error,
        "'u' (value reference 0, Real input) cannot be an unknown"
    ));
    let (s, _) = dir_deriv(&f, &[Y], &[GAIN], &[1.0]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(
        fmi2Error,
        "'gain' (value reference 3, Real parameter) cannot be a known"
    ));
    let (s, _) = dir_deriv(&f, &[HIGH], &[U], &[1.0]);
    assert_eq!(s, fmi2Error);
    let (s, _) = dir_deriv(&f, &[Y], &[77], &[1.0]);
    assert_eq!(s, fmi2Error);
    assert!(f.has_log(fmi2Error, "unknown value reference 77"));
}

/// A seed `dvKnown` that is NaN or infinite is refused with `fmi2Error`
/// naming its index and value; nothing is written to `dvUnknown`, the
/// instance is unchanged, and a finite seed then gives the derivative.
#[test]
fn non_finite_seeds_are_refused() {
    let f = Fmu::<Lag>::running();
    f.ok(f.step(0.0, 0.25));
    let before = f.state_bytes();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let (s, d) = dir_deriv(&f, &[Y, Z], &[U, W], &[1.0, bad]);
        assert_eq!(s, fmi2Error, "seed {bad} accepted");
        assert!(d.iter().all(|x| x.is_nan()), "dvUnknown written: {d:?}");
        assert!(f.has_log(
            fmi2Error,
            &format!("fmi2GetDirectionalDerivative: dvKnown[1] = {bad:?} must be finite")
        ));
        assert!(
            f.state_bytes() == before,
            "the refused call changed the instance"
        );
    }
    let (s, d) = dir_deriv(&f, &[Y], &[U, W], &[1.0, 0.0]);
    f.ok(s);
    assert!(d[0].is_finite() && d[0] != 0.0, "{d:?}");
}

#[test]
fn input_and_output_derivatives() {
    let f = Fmu::<Lag>::running();
    f.ok(f.set_real(&[U], &[1.0]));
    f.ok(unsafe { api::set_real_input_derivatives::<Lag>(f.c, &U, 1, &1, &2.0) });
    f.ok(f.step(0.0, 0.5));
    // x = gain * (u + du * h) + w = 2 * (1 + 1) = 4.
    assert_eq!(f.real(Y), lag_step(0.0, 4.0, 0.5, 1.0));
    let before = f.state_bytes();
    assert_eq!(
        unsafe { api::set_real_input_derivatives::<Lag>(f.c, &U, 1, &2, &2.0) },
        fmi2Error
    );
    assert!(f.has_log(fmi2Error, "order 2 for 'u' is not supported"));
    assert_eq!(
        unsafe { api::set_real_input_derivatives::<Lag>(f.c, &GAIN, 1, &1, &2.0) },
        fmi2Error
    );
    assert!(f.has_log(fmi2Error, "'gain' (value reference 3) is not a Real input"));
    let vrs = [U, W];
    assert_eq!(
        unsafe {
            api::set_real_input_derivatives::<Lag>(
                f.c,
                vrs.as_ptr(),
                2,
                [1, 1].as_ptr(),
                [3.0, 1.0].as_ptr(),
            )
        },
        fmi2Error
    );
    assert!(f.has_log(fmi2Error, "no derivative for this input"));
    assert_eq!(f.state_bytes(), before);

    let mut v = 0.0;
    assert_eq!(
        unsafe { api::get_real_output_derivatives::<Lag>(f.c, &Y, 1, &1, &mut v) },
        fmi2Error
    );
    assert!(f.has_log(
        fmi2Error,
        "output derivatives are not provided (maxOutputDerivativeOrder = 0); requested order 1 of 'y'"
    ));
    assert_eq!(unsafe { api::cancel_step::<Lag>(f.c) }, fmi2Error);
    assert!(f.has_log(
        fmi2Error,
        "fmi2CancelStep: not allowed in state stepComplete"
    ));
}

// ---------------------------------------------------------------------------
// GUID, modelDescription.xml, documentation
// ---------------------------------------------------------------------------

#[test]
fn guid_is_stable_well_formed_and_tracks_the_table() {
    let g = guid::<Lag>();
    assert_eq!(g, guid::<Lag>());
    assert_eq!(g.len(), 38);
    assert!(g.starts_with('{') && g.ends_with('}'));
    let parts: Vec<&str> = g[1..37].split('-').collect();
    assert_eq!(
        parts.iter().map(|p| p.len()).collect::<Vec<_>>(),
        vec![8, 4, 4, 4, 12]
    );
    assert!(parts.iter().all(|p| p
        .chars()
        .all(|c| c.is_ascii_hexdigit() && !c.is_ascii_uppercase())));
    assert_ne!(g, guid::<Lag2>());
    // Any change of the interface changes the GUID.
    let info = Lag::info();
    let base = hill_muscle::fmi2::model_description::guid_for(&info, &Lag::variables());
    assert_eq!(base, g);
    let mut vars = Lag::variables();
    vars[GAIN as usize].variability = Variability::Fixed;
    assert_ne!(
        hill_muscle::fmi2::model_description::guid_for(&info, &vars),
        g
    );
    let mut vars = Lag::variables();
    vars[Y as usize].depends_on.pop();
    assert_ne!(
        hill_muscle::fmi2::model_description::guid_for(&info, &vars),
        g
    );
    let mut info2 = Lag::info();
    info2.max_input_derivative_order = 0;
    assert_ne!(
        hill_muscle::fmi2::model_description::guid_for(&info2, &Lag::variables()),
        g
    );
}

/// Attributes of an element as (name, value) pairs.
fn attrs(e: &quick_xml::events::BytesStart) -> Vec<(String, String)> {
    e.attributes()
        .map(|a| {
            let a = a.expect("well-formed attribute");
            (
                a.key.as_ref().to_string(),
                a.normalized_value(quick_xml::XmlVersion::Explicit1_0)
                    .unwrap()
                    .into_owned(),
            )
        })
        .collect()
}

fn attr<'a>(a: &'a [(String, String)], k: &str) -> Option<&'a str> {
    a.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str())
}

#[test]
fn model_description_is_well_formed_and_its_structure_is_right() {
    use quick_xml::events::Event;
    assert_eq!(validate_table::<Lag>(), Ok(()));
    let xml = model_description::<Lag>();
    assert!(xml.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<fmiModelDescription"));
    assert!(xml.contains("\n  <CoSimulation"), "2-space indent");

    let mut r = quick_xml::Reader::from_str(&xml);
    let mut path: Vec<String> = Vec::new();
    let mut root = Vec::new();
    let mut cosim = Vec::new();
    let mut vrs = Vec::new();
    let mut names = Vec::new();
    let mut reals = Vec::new();
    let mut outputs = Vec::new();
    let mut initial_unknowns = Vec::new();
    let mut categories = Vec::new();
    let mut units = Vec::new();
    let mut experiment = Vec::new();
    loop {
        let ev = r.read_event().expect("well-formed XML");
        let (e, empty) = match &ev {
            Event::Start(e) => (e.clone(), false),
            Event::Empty(e) => (e.clone(), true),
            Event::End(_) => {
                path.pop();
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        let name = e.name().as_ref().to_string();
        let a = attrs(&e);
        let parent = path.last().cloned().unwrap_or_default();
        match name.as_str() {
            "fmiModelDescription" => root = a,
            "CoSimulation" => cosim = a,
            "ScalarVariable" => {
                vrs.push(attr(&a, "valueReference").unwrap().parse::<u32>().unwrap());
                names.push(attr(&a, "name").unwrap().to_string());
            }
            "Real" => reals.push((names.last().unwrap().clone(), a)),
            "Unknown" if parent == "Outputs" => outputs.push(a),
            "Unknown" if parent == "InitialUnknowns" => initial_unknowns.push(a),
            "Category" => categories.push(attr(&a, "name").unwrap().to_string()),
            "BaseUnit" => units.push(a),
            "DefaultExperiment" => experiment = a,
            _ => {}
        }
        if !empty {
            path.push(name);
        }
    }
    assert!(path.is_empty());
    assert_eq!(attr(&root, "fmiVersion"), Some("2.0"));
    assert_eq!(attr(&root, "modelName"), Some("Lag"));
    assert_eq!(attr(&root, "guid"), Some(guid::<Lag>().as_str()));
    assert_eq!(
        attr(&root, "description"),
        Some("First-order lag <test> & \"quotes\"")
    );
    assert_eq!(attr(&root, "variableNamingConvention"), Some("flat"));
    assert_eq!(attr(&root, "numberOfEventIndicators"), Some("0"));
    assert!(attr(&root, "generationTool")
        .unwrap()
        .starts_with("hill-muscle fmu_build "));
    assert_eq!(attr(&cosim, "modelIdentifier"), Some("Lag"));
    for (k, v) in [
        ("canHandleVariableCommunicationStepSize", "true"),
        ("canInterpolateInputs", "true"),
        ("maxOutputDerivativeOrder", "0"),
        ("canGetAndSetFMUstate", "true"),
        ("canSerializeFMUstate", "true"),
        ("providesDirectionalDerivative", "true"),
        ("canNotUseMemoryManagementFunctions", "true"),
        ("canRunAsynchronuously", "false"),
        ("canBeInstantiatedOnlyOncePerProcess", "false"),
        ("needsExecutionTool", "false"),
    ] {
        assert_eq!(attr(&cosim, k), Some(v), "{k}");
    }
    assert_eq!(vrs, (0..N_VARS).collect::<Vec<_>>());
    assert_eq!(names[Y as usize], "y");
    let (_, tau) = reals.iter().find(|(n, _)| n == "tau").unwrap();
    assert_eq!(attr(tau, "unit"), Some("s"));
    assert_eq!(attr(tau, "start"), Some("1.0"));
    assert_eq!(attr(tau, "min").unwrap().parse::<f64>().unwrap(), 1e-9);
    let (_, hmax) = reals.iter().find(|(n, _)| n == "h_max").unwrap();
    assert_eq!(attr(hmax, "min").unwrap().parse::<f64>().unwrap(), 1e-300);
    assert_eq!(categories.len(), 6);
    assert!(categories.contains(&"logEvents".to_string()));
    assert_eq!(units.len(), 2);
    assert_eq!(attr(&units[1], "kg"), Some("1"));
    assert_eq!(attr(&units[1], "s"), Some("-2"));
    assert_eq!(attr(&experiment, "stepSize"), Some("0.01"));

    let deps = |list: &[Vec<(String, String)>]| -> Vec<(String, String)> {
        list.iter()
            .map(|a| {
                (
                    attr(a, "index").unwrap().to_string(),
                    attr(a, "dependencies").unwrap().to_string(),
                )
            })
            .collect()
    };
    let s = |a: &str, b: &str| (a.to_string(), b.to_string());
    // 1-based: u=1, w=2, tau=3, gain=4, y=8, z=9, steps=10, high=11, tau_ms=12.
    assert_eq!(
        deps(&outputs),
        vec![s("8", "1 2"), s("9", "1 2"), s("10", ""), s("11", "1 2")]
    );
    assert_eq!(
        deps(&initial_unknowns),
        vec![
            s("8", "1 2 4"),
            s("9", "1 2 4"),
            s("10", ""),
            s("11", "1 2 4"),
            s("12", "3")
        ]
    );
    assert!(!xml.contains("dependenciesKind"));
}

#[test]
fn validate_reports_table_errors() {
    let info = Lag::info();
    let mut vars = Lag::variables();
    vars[Y as usize].depends_on.push("nope");
    vars[Z as usize].depends_on.push("internal");
    vars[U as usize].variability = Variability::Fixed;
    vars[W as usize].ty = real(None, None, None, None);
    vars[TAU as usize].ty = real(Some("lightyear"), Some(-1.0), Some(0.0), None);
    vars[STEPS as usize].name = "y";
    let errs = validate(&info, &vars).unwrap_err();
    let all = errs.join("\n");
    for needle in [
        "'y': depends_on 'nope' is not a variable",
        "'z': depends_on 'internal' is neither an input nor a variable with initial = exact",
        "'u': causality input with variability fixed is not allowed",
        "'w': a start value is required",
        "'tau': start -1 outside [min, max]",
        "unit 'lightyear' is not declared",
        "variable 9 'y': duplicate name",
    ] {
        assert!(all.contains(needle), "missing '{needle}' in:\n{all}");
    }
}

#[test]
#[should_panic(expected = "depends on 'nope', which is not in the variable table")]
fn model_description_panics_on_unknown_dependency() {
    let mut vars = Lag::variables();
    vars[Y as usize].depends_on.push("nope");
    let _ = hill_muscle::fmi2::model_description::model_description_for(&Lag::info(), &vars);
}

#[test]
fn documentation_lists_variables_and_the_law() {
    let html = documentation_html::<Lag>("<h3>The law</h3><p>tau y' = x - y</p>");
    assert!(html.starts_with("<!DOCTYPE html>"));
    for needle in [
        "<code>tau_ms</code>",
        "calculatedParameter",
        "<td>[1e-9, inf]</td>",
        "<h3>The law</h3><p>tau y' = x - y</p>",
        "First-order lag &lt;test&gt; &amp; &quot;quotes&quot;",
        &guid::<Lag>(),
    ] {
        assert!(html.contains(needle), "missing {needle}");
    }
}

// ---------------------------------------------------------------------------
// Threads
// ---------------------------------------------------------------------------

#[test]
fn instances_move_between_threads_and_run_in_parallel() {
    let f = Fmu::<Lag>::running();
    f.ok(f.set_real(&[U], &[1.0]));
    f.ok(f.step(0.0, 0.1));
    // Step the same instance on another thread, then continue here.
    let f = std::thread::spawn(move || {
        f.ok(f.step(0.1, 0.1));
        f
    })
    .join()
    .unwrap();
    f.ok(f.step(0.2, 0.1));
    let (s, ints) = f.get_integer(&[STEPS]);
    f.ok(s);
    assert_eq!(ints[0], 3);

    // Independent instances in parallel give identical results.
    let results: Vec<Vec<u64>> = (0..4)
        .map(|_| {
            std::thread::spawn(|| {
                let g = Fmu::<Lag>::running();
                trajectory(&g, 0.0, 200)
            })
        })
        .collect::<Vec<_>>()
        .into_iter()
        .map(|h| h.join().unwrap())
        .collect();
    assert!(results.windows(2).all(|w| w[0] == w[1]));
}

// ---------------------------------------------------------------------------
// The export macro
// ---------------------------------------------------------------------------

// Defines the `fmi2Xxx` C symbols for `Lag` in this test binary (skipped if
// the library itself exports an FMU, which would clash).
#[cfg(not(feature = "export-scene"))]
hill_muscle::export_fmi2!(Lag);

#[cfg(not(feature = "export-scene"))]
#[test]
fn exported_symbols_work() {
    use __fmi2_exports::*;
    assert_eq!(
        unsafe { CStr::from_ptr(fmi2GetVersion()) }.to_str(),
        Ok("2.0")
    );
    assert_eq!(
        unsafe { CStr::from_ptr(fmi2GetTypesPlatform()) }.to_str(),
        Ok("default")
    );
    let book = LogBook::default();
    let cb = callbacks(&book);
    let g = CString::new(guid::<Lag>()).unwrap();
    unsafe {
        let c = fmi2Instantiate(c"x".as_ptr(), fmi2CoSimulation, g.as_ptr(), cn(), &cb, 0, 0);
        assert!(!c.is_null());
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), fmi2OK);
        assert_eq!(fmi2EnterInitializationMode(c), fmi2OK);
        assert_eq!(fmi2SetReal(c, &U, 1, &1.0), fmi2OK);
        assert_eq!(fmi2ExitInitializationMode(c), fmi2OK);
        assert_eq!(fmi2DoStep(c, 0.0, 0.1, 1), fmi2OK);
        let mut y = 0.0;
        assert_eq!(fmi2GetReal(c, &Y, 1, &mut y), fmi2OK);
        assert_eq!(y, 2.0);
        let mut s: fmi2FMUstate = std::ptr::null_mut();
        assert_eq!(fmi2GetFMUstate(c, &mut s), fmi2OK);
        let mut n = 0;
        assert_eq!(fmi2SerializedFMUstateSize(c, s, &mut n), fmi2OK);
        assert!(n > 0);
        assert_eq!(fmi2FreeFMUstate(c, &mut s), fmi2OK);
        assert_eq!(fmi2CancelStep(c), fmi2Error);
        assert_eq!(fmi2Terminate(c), fmi2OK);
        fmi2FreeInstance(c);
    }
}
