//! One FMI call with its arguments (NULL, foreign, bogus and short
//! pointers included) and its executor.

use super::*;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Comp {
    Valid,
    Null,
    /// Readable memory that is not an instance.
    Foreign,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ptr {
    Ok,
    Null,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Len {
    /// The array's length.
    Exact,
    /// `usize::MAX` with a valid pointer: must be refused before any read.
    Impossible,
}

/// A `fmi2FMUstate` argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum StateIn {
    Slot(usize),
    Null,
    Bogus,
    /// A state of another instance.
    Other,
}

/// A `fmi2FMUstate*` argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum StateOut {
    Slot(usize),
    NullPtr,
    /// Points to a variable holding a bogus state pointer.
    HoldsBogus,
    /// Points to a variable holding another instance's state.
    HoldsOther,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ty {
    Real,
    Integer,
    Boolean,
    String,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum StatusFn {
    Status,
    Real,
    Integer,
    Boolean,
    String,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Str {
    Null,
    Text(&'static str),
    NonUtf8,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Cat {
    Known(usize),
    Unknown,
    Empty,
    Null,
    NonUtf8,
}

pub(crate) const CATEGORIES: [&CStr; 6] = [
    c"logStatusWarning",
    c"logStatusDiscard",
    c"logStatusError",
    c"logStatusFatal",
    c"logAll",
    c"logEvents",
];

/// Bytes of a deserialization, printed short.
#[derive(Clone, PartialEq, Eq)]
pub(crate) struct Bytes(pub(crate) Vec<u8>);

impl fmt::Debug for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "<{} bytes, fnv {:016x}>",
            self.0.len(),
            fnv1a64(FNV64_OFFSET, &self.0)
        )
    }
}

/// One FMI call with concrete arguments, replayable on any instance (slots
/// are indices into that instance's own slots).
#[derive(Clone, Debug)]
pub(crate) enum Call {
    Setup {
        comp: Comp,
        tol_def: i32,
        tol: f64,
        start: f64,
        stop_def: i32,
        stop: f64,
    },
    Enter(Comp),
    Exit(Comp),
    Terminate(Comp),
    Reset(Comp),
    Cancel(Comp),
    Logging {
        comp: Comp,
        on: i32,
        cats: Vec<Cat>,
        ptr: Ptr,
        len: Len,
    },
    SetReal {
        comp: Comp,
        vrs: Vec<u32>,
        vals: Vec<f64>,
        ptrs: [Ptr; 2],
        len: Len,
    },
    SetInteger {
        comp: Comp,
        vrs: Vec<u32>,
        vals: Vec<i32>,
        ptrs: [Ptr; 2],
        len: Len,
    },
    SetBoolean {
        comp: Comp,
        vrs: Vec<u32>,
        vals: Vec<i32>,
        ptrs: [Ptr; 2],
        len: Len,
    },
    SetString {
        comp: Comp,
        vrs: Vec<u32>,
        vals: Vec<Str>,
        ptrs: [Ptr; 2],
        len: Len,
    },
    Get {
        comp: Comp,
        ty: Ty,
        vrs: Vec<u32>,
        ptrs: [Ptr; 2],
        len: Len,
    },
    GetState {
        comp: Comp,
        out: StateOut,
    },
    SetState {
        comp: Comp,
        st: StateIn,
    },
    FreeState {
        comp: Comp,
        out: StateOut,
    },
    StateSize {
        comp: Comp,
        st: StateIn,
        null: bool,
    },
    Serialize {
        comp: Comp,
        st: StateIn,
        size: usize,
        ptr: Ptr,
        impossible: bool,
    },
    Deserialize {
        comp: Comp,
        bytes: Bytes,
        size: usize,
        ptr: Ptr,
        impossible: bool,
        out: StateOut,
    },
    DirDeriv {
        comp: Comp,
        unknowns: Vec<u32>,
        knowns: Vec<u32>,
        dv: Vec<f64>,
        ptrs: [Ptr; 4],
        len: Len,
    },
    SetInputDer {
        comp: Comp,
        vrs: Vec<u32>,
        orders: Vec<i32>,
        vals: Vec<f64>,
        ptrs: [Ptr; 3],
        len: Len,
    },
    GetOutputDer {
        comp: Comp,
        vrs: Vec<u32>,
        orders: Vec<i32>,
        ptrs: [Ptr; 3],
        len: Len,
    },
    Step {
        comp: Comp,
        tc: f64,
        h: f64,
        flag: i32,
    },
    Status {
        comp: Comp,
        func: StatusFn,
        kind: i32,
        null: bool,
    },
}

impl Call {
    pub(crate) fn comp(&self) -> Comp {
        use Call::*;
        match self {
            Enter(c) | Exit(c) | Terminate(c) | Reset(c) | Cancel(c) => *c,
            Setup { comp, .. }
            | Logging { comp, .. }
            | SetReal { comp, .. }
            | SetInteger { comp, .. }
            | SetBoolean { comp, .. }
            | SetString { comp, .. }
            | Get { comp, .. }
            | GetState { comp, .. }
            | SetState { comp, .. }
            | FreeState { comp, .. }
            | StateSize { comp, .. }
            | Serialize { comp, .. }
            | Deserialize { comp, .. }
            | DirDeriv { comp, .. }
            | SetInputDer { comp, .. }
            | GetOutputDer { comp, .. }
            | Step { comp, .. }
            | Status { comp, .. } => *comp,
        }
    }

    /// The function's name and the states the table allows it in.
    pub(crate) fn meta(&self) -> (&'static str, StateSet) {
        use Call::*;
        match self {
            Setup { .. } => ("fmi2SetupExperiment", st::SETUP_EXPERIMENT),
            Enter(_) => ("fmi2EnterInitializationMode", st::ENTER_INITIALIZATION_MODE),
            Exit(_) => ("fmi2ExitInitializationMode", st::EXIT_INITIALIZATION_MODE),
            Terminate(_) => ("fmi2Terminate", st::TERMINATE),
            Reset(_) => ("fmi2Reset", st::RESET),
            Cancel(_) => ("fmi2CancelStep", st::CANCEL_STEP),
            Logging { .. } => ("fmi2SetDebugLogging", st::SET_DEBUG_LOGGING),
            SetReal { .. } => ("fmi2SetReal", st::SET_VALUES),
            SetInteger { .. } => ("fmi2SetInteger", st::SET_VALUES),
            SetBoolean { .. } => ("fmi2SetBoolean", st::SET_VALUES),
            SetString { .. } => ("fmi2SetString", st::SET_VALUES),
            Get { ty, .. } => (
                match ty {
                    Ty::Real => "fmi2GetReal",
                    Ty::Integer => "fmi2GetInteger",
                    Ty::Boolean => "fmi2GetBoolean",
                    Ty::String => "fmi2GetString",
                },
                st::GET_VALUES,
            ),
            GetState { .. } => ("fmi2GetFMUstate", st::FMU_STATE),
            SetState { .. } => ("fmi2SetFMUstate", st::FMU_STATE),
            FreeState { .. } => ("fmi2FreeFMUstate", st::FMU_STATE),
            StateSize { .. } => ("fmi2SerializedFMUstateSize", st::FMU_STATE),
            Serialize { .. } => ("fmi2SerializeFMUstate", st::FMU_STATE),
            Deserialize { .. } => ("fmi2DeSerializeFMUstate", st::FMU_STATE),
            DirDeriv { .. } => (
                "fmi2GetDirectionalDerivative",
                st::GET_DIRECTIONAL_DERIVATIVE,
            ),
            SetInputDer { .. } => (
                "fmi2SetRealInputDerivatives",
                st::SET_REAL_INPUT_DERIVATIVES,
            ),
            GetOutputDer { .. } => (
                "fmi2GetRealOutputDerivatives",
                st::GET_REAL_OUTPUT_DERIVATIVES,
            ),
            Step { .. } => ("fmi2DoStep", st::DO_STEP),
            Status { func, .. } => (
                match func {
                    StatusFn::Status => "fmi2GetStatus",
                    StatusFn::Real => "fmi2GetRealStatus",
                    StatusFn::Integer => "fmi2GetIntegerStatus",
                    StatusFn::Boolean => "fmi2GetBooleanStatus",
                    StatusFn::String => "fmi2GetStringStatus",
                },
                st::GET_STATUS,
            ),
        }
    }

    /// FMU state slots the call refers to.
    pub(crate) fn slots(&self) -> Vec<usize> {
        let mut v = Vec::new();
        match self {
            Call::GetState { out, .. }
            | Call::FreeState { out, .. }
            | Call::Deserialize { out, .. } => {
                if let StateOut::Slot(k) = out {
                    v.push(*k);
                }
            }
            Call::SetState { st, .. } | Call::StateSize { st, .. } | Call::Serialize { st, .. } => {
                if let StateIn::Slot(k) = st {
                    v.push(*k);
                }
            }
            _ => {}
        }
        v
    }

    /// Calls that must leave the serialized state unchanged whatever they
    /// return (module docs, property 4).
    pub(crate) fn is_pure(&self, pre: FmiState) -> bool {
        use Call::*;
        match self {
            Get { ty: Ty::Real, .. } | DirDeriv { .. } => pre != FmiState::InitializationMode,
            Get {
                ty: Ty::Integer,
                vrs,
                ..
            } => pre != FmiState::InitializationMode || !vrs.iter().any(|&vr| computed(vr)),
            Get { .. }
            | Logging { .. }
            | Status { .. }
            | Cancel(_)
            | GetOutputDer { .. }
            | GetState { .. }
            | FreeState { .. }
            | StateSize { .. }
            | Serialize { .. }
            | Deserialize { .. } => true,
            _ => false,
        }
    }
}

/// What a call returned and wrote.
pub(crate) struct Outcome {
    pub(crate) status: fmi2Status,
    /// Everything written to out-arguments on success (bit patterns), for
    /// comparing instances.
    pub(crate) reads: Vec<u64>,
    /// No out-argument was written (checked after `fmi2Error`).
    pub(crate) untouched: bool,
}

pub(crate) const SENT_F64: f64 = -7.777e77;
pub(crate) const SENT_I32: i32 = -777_777;
pub(crate) const SENT_BYTE: u8 = 0xA5;
pub(crate) static SENT_STR: &CStr = c"sentinel";

pub(crate) fn in_ptr<T>(v: &[T], p: Ptr) -> *const T {
    match p {
        Ptr::Ok => v.as_ptr(),
        Ptr::Null => null(),
    }
}

pub(crate) fn out_ptr<T>(v: &mut [T], p: Ptr) -> *mut T {
    match p {
        Ptr::Ok => v.as_mut_ptr(),
        Ptr::Null => null_mut(),
    }
}

pub(crate) fn n_of(n: usize, len: Len) -> usize {
    match len {
        Len::Exact => n,
        Len::Impossible => usize::MAX,
    }
}

pub(crate) fn bits_f64(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

pub(crate) fn bits_i32(v: &[i32]) -> Vec<u64> {
    v.iter().map(|&x| x as u32 as u64).collect()
}

/// Runs `call` on `f`.
pub(crate) fn exec(f: &mut Fmu, env: &Env, call: &Call) -> Outcome {
    let c = match call.comp() {
        Comp::Valid => f.c,
        Comp::Null => null_mut(),
        Comp::Foreign => env.foreign(),
    };
    let mut reads = Vec::new();
    let mut untouched = true;
    let status = unsafe {
        match call {
            Call::Setup {
                tol_def,
                tol,
                start,
                stop_def,
                stop,
                ..
            } => (abi().setup_experiment)(c, *tol_def, *tol, *start, *stop_def, *stop),
            Call::Enter(_) => (abi().enter_initialization_mode)(c),
            Call::Exit(_) => (abi().exit_initialization_mode)(c),
            Call::Terminate(_) => (abi().terminate)(c),
            Call::Reset(_) => (abi().reset)(c),
            Call::Cancel(_) => (abi().cancel_step)(c),
            Call::Logging {
                on, cats, ptr, len, ..
            } => {
                let owned: Vec<Option<CString>> = cats
                    .iter()
                    .map(|cat| match cat {
                        Cat::Known(i) => Some(CATEGORIES[*i].to_owned()),
                        Cat::Unknown => Some(c"logNothing".to_owned()),
                        Cat::Empty => Some(c"".to_owned()),
                        Cat::NonUtf8 => Some(CString::new(vec![0xff, 0xfe, b'l']).unwrap()),
                        Cat::Null => None,
                    })
                    .collect();
                let ptrs: Vec<fmi2String> = owned
                    .iter()
                    .map(|o| o.as_ref().map_or(null(), |s| s.as_ptr()))
                    .collect();
                (abi().set_debug_logging)(c, *on, n_of(ptrs.len(), *len), in_ptr(&ptrs, *ptr))
            }
            Call::SetReal {
                vrs,
                vals,
                ptrs,
                len,
                ..
            } => (abi().set_real)(
                c,
                in_ptr(vrs, ptrs[0]),
                n_of(vrs.len(), *len),
                in_ptr(vals, ptrs[1]),
            ),
            Call::SetInteger {
                vrs,
                vals,
                ptrs,
                len,
                ..
            } => (abi().set_integer)(
                c,
                in_ptr(vrs, ptrs[0]),
                n_of(vrs.len(), *len),
                in_ptr(vals, ptrs[1]),
            ),
            Call::SetBoolean {
                vrs,
                vals,
                ptrs,
                len,
                ..
            } => (abi().set_boolean)(
                c,
                in_ptr(vrs, ptrs[0]),
                n_of(vrs.len(), *len),
                in_ptr(vals, ptrs[1]),
            ),
            Call::SetString {
                vrs,
                vals,
                ptrs,
                len,
                ..
            } => {
                let owned: Vec<Option<CString>> = vals
                    .iter()
                    .map(|s| match s {
                        Str::Null => None,
                        Str::Text(t) => Some(CString::new(*t).unwrap()),
                        Str::NonUtf8 => Some(CString::new(vec![0xc3, 0x28]).unwrap()),
                    })
                    .collect();
                let sp: Vec<fmi2String> = owned
                    .iter()
                    .map(|o| o.as_ref().map_or(null(), |s| s.as_ptr()))
                    .collect();
                (abi().set_string)(
                    c,
                    in_ptr(vrs, ptrs[0]),
                    n_of(vrs.len(), *len),
                    in_ptr(&sp, ptrs[1]),
                )
            }
            Call::Get {
                ty, vrs, ptrs, len, ..
            } => {
                let (vp, n) = (in_ptr(vrs, ptrs[0]), n_of(vrs.len(), *len));
                match ty {
                    Ty::Real => {
                        let mut out = vec![SENT_F64; vrs.len()];
                        let s = (abi().get_real)(c, vp, n, out_ptr(&mut out, ptrs[1]));
                        untouched = out.iter().all(|x| x.to_bits() == SENT_F64.to_bits());
                        reads = bits_f64(&out);
                        s
                    }
                    Ty::Integer => {
                        let mut out = vec![SENT_I32; vrs.len()];
                        let s = (abi().get_integer)(c, vp, n, out_ptr(&mut out, ptrs[1]));
                        untouched = out.iter().all(|&x| x == SENT_I32);
                        reads = bits_i32(&out);
                        s
                    }
                    Ty::Boolean => {
                        let mut out = vec![SENT_I32; vrs.len()];
                        let s = (abi().get_boolean)(c, vp, n, out_ptr(&mut out, ptrs[1]));
                        untouched = out.iter().all(|&x| x == SENT_I32);
                        reads = bits_i32(&out);
                        s
                    }
                    Ty::String => {
                        let mut out: Vec<fmi2String> = vec![SENT_STR.as_ptr(); vrs.len()];
                        let s = (abi().get_string)(c, vp, n, out_ptr(&mut out, ptrs[1]));
                        untouched = out.iter().all(|&x| x == SENT_STR.as_ptr());
                        reads = out.iter().map(|&p| c_bytes(p).len() as u64).collect();
                        s
                    }
                }
            }
            Call::GetState { out, .. } | Call::FreeState { out, .. } => {
                let mut holder = match out {
                    StateOut::HoldsBogus => env.bogus(),
                    StateOut::HoldsOther => env.other_state(),
                    _ => null_mut(),
                };
                let p: *mut fmi2FMUstate = match out {
                    StateOut::Slot(k) => &mut f.slots[*k],
                    StateOut::NullPtr => null_mut(),
                    _ => &mut holder,
                };
                let before = if p.is_null() { null_mut() } else { *p };
                let s = if matches!(call, Call::GetState { .. }) {
                    (abi().get_fmu_state)(c, p)
                } else {
                    (abi().free_fmu_state)(c, p)
                };
                untouched = p.is_null() || *p == before;
                if !p.is_null() {
                    reads.push(u64::from((*p).is_null()));
                }
                s
            }
            Call::SetState { st, .. } => (abi().set_fmu_state)(c, state_in(f, env, *st)),
            Call::StateSize { st, null, .. } => {
                let mut n = usize::MAX - 1;
                let p: *mut usize = if *null { null_mut() } else { &mut n };
                let s = (abi().serialized_fmu_state_size)(c, state_in(f, env, *st), p);
                untouched = n == usize::MAX - 1;
                reads.push(n as u64);
                s
            }
            Call::Serialize {
                st,
                size,
                ptr,
                impossible,
                ..
            } => {
                let mut buf = vec![SENT_BYTE as fmi2Byte; if *impossible { 16 } else { *size }];
                let n = if *impossible { usize::MAX } else { *size };
                let s = (abi().serialize_fmu_state)(
                    c,
                    state_in(f, env, *st),
                    out_ptr(&mut buf, *ptr),
                    n,
                );
                untouched = buf.iter().all(|&b| b as u8 == SENT_BYTE);
                reads = buf.iter().map(|&b| u64::from(b as u8)).collect();
                s
            }
            Call::Deserialize {
                bytes,
                size,
                ptr,
                impossible,
                out,
                ..
            } => {
                let mut holder = match out {
                    StateOut::HoldsBogus => env.bogus(),
                    StateOut::HoldsOther => env.other_state(),
                    _ => null_mut(),
                };
                let p: *mut fmi2FMUstate = match out {
                    StateOut::Slot(k) => &mut f.slots[*k],
                    StateOut::NullPtr => null_mut(),
                    _ => &mut holder,
                };
                let before = if p.is_null() { null_mut() } else { *p };
                let n = if *impossible { usize::MAX } else { *size };
                let s = (abi().deserialize_fmu_state)(
                    c,
                    in_ptr(&bytes.0, *ptr) as *const fmi2Byte,
                    n,
                    p,
                );
                untouched = p.is_null() || *p == before;
                s
            }
            Call::DirDeriv {
                unknowns,
                knowns,
                dv,
                ptrs,
                len,
                ..
            } => {
                let mut out = vec![SENT_F64; unknowns.len()];
                let s = (abi().get_directional_derivative)(
                    c,
                    in_ptr(unknowns, ptrs[0]),
                    n_of(unknowns.len(), *len),
                    in_ptr(knowns, ptrs[1]),
                    knowns.len(),
                    in_ptr(dv, ptrs[2]),
                    out_ptr(&mut out, ptrs[3]),
                );
                untouched = out.iter().all(|x| x.to_bits() == SENT_F64.to_bits());
                reads = bits_f64(&out);
                s
            }
            Call::SetInputDer {
                vrs,
                orders,
                vals,
                ptrs,
                len,
                ..
            } => (abi().set_real_input_derivatives)(
                c,
                in_ptr(vrs, ptrs[0]),
                n_of(vrs.len(), *len),
                in_ptr(orders, ptrs[1]),
                in_ptr(vals, ptrs[2]),
            ),
            Call::GetOutputDer {
                vrs,
                orders,
                ptrs,
                len,
                ..
            } => {
                let mut out = vec![SENT_F64; vrs.len()];
                let s = (abi().get_real_output_derivatives)(
                    c,
                    in_ptr(vrs, ptrs[0]),
                    n_of(vrs.len(), *len),
                    in_ptr(orders, ptrs[1]),
                    out_ptr(&mut out, ptrs[2]),
                );
                untouched = out.iter().all(|x| x.to_bits() == SENT_F64.to_bits());
                reads = bits_f64(&out);
                s
            }
            Call::Step { tc, h, flag, .. } => (abi().do_step)(c, *tc, *h, *flag),
            Call::Status {
                func, kind, null, ..
            } => match func {
                StatusFn::Status => {
                    let mut v = fmi2Pending;
                    let p: *mut fmi2Status = if *null { null_mut() } else { &mut v };
                    let s = (abi().get_status)(c, *kind, p);
                    untouched = v == fmi2Pending;
                    reads.push(v as u64);
                    s
                }
                StatusFn::Real => {
                    let mut v = SENT_F64;
                    let p: *mut f64 = if *null { null_mut() } else { &mut v };
                    let s = (abi().get_real_status)(c, *kind, p);
                    untouched = v.to_bits() == SENT_F64.to_bits();
                    reads.push(v.to_bits());
                    s
                }
                StatusFn::Integer | StatusFn::Boolean => {
                    let mut v = SENT_I32;
                    let p: *mut i32 = if *null { null_mut() } else { &mut v };
                    let s = if *func == StatusFn::Integer {
                        (abi().get_integer_status)(c, *kind, p)
                    } else {
                        (abi().get_boolean_status)(c, *kind, p)
                    };
                    untouched = v == SENT_I32;
                    reads.push(v as u32 as u64);
                    s
                }
                StatusFn::String => {
                    let mut v: fmi2String = SENT_STR.as_ptr();
                    let p: *mut fmi2String = if *null { null_mut() } else { &mut v };
                    let s = (abi().get_string_status)(c, *kind, p);
                    untouched = v == SENT_STR.as_ptr();
                    s
                }
            },
        }
    };
    Outcome {
        status,
        reads,
        untouched,
    }
}

pub(crate) fn state_in(f: &Fmu, env: &Env, s: StateIn) -> fmi2FMUstate {
    match s {
        StateIn::Slot(k) => f.slots[k],
        StateIn::Null => null_mut(),
        StateIn::Bogus => env.bogus(),
        StateIn::Other => env.other_state(),
    }
}
