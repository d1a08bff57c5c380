//! Instances of the subject, their serialized states, and the pool of
//! restorable states the generated sequences draw from.

use super::*;

/// The instance name: `#` and `%` check that the name reaches the logger
/// unchanged and that messages are passed as `"%s"` + text.
pub(crate) const NAME: &CStr = c"abuse #1 %s";
pub(crate) const N_SLOTS: usize = 4;

/// One instance with its log book and its FMU state slots (the importer's
/// `fmi2FMUstate` variables).
pub struct Fmu {
    pub c: fmi2Component,
    pub book: Box<LogBook>,
    pub slots: [fmi2FMUstate; N_SLOTS],
}

impl Fmu {
    pub fn new(logging_on: bool) -> Fmu {
        let book = Box::new(LogBook::default());
        let cb = callbacks(&book);
        let c = unsafe {
            (abi().instantiate)(
                NAME.as_ptr(),
                fmi2CoSimulation,
                table().guid.as_ptr(),
                c"file:///tmp/".as_ptr(),
                &cb,
                fmi2False,
                if logging_on { fmi2True } else { fmi2False },
            )
        };
        assert!(!c.is_null(), "instantiate: {:?}", book.take());
        book.clear();
        Fmu {
            c,
            book,
            slots: [null_mut(); N_SLOTS],
        }
    }

    pub(crate) fn serialize_state(&self, s: fmi2FMUstate) -> Result<Vec<u8>, String> {
        let mut n = 0usize;
        let st = unsafe { (abi().serialized_fmu_state_size)(self.c, s, &mut n) };
        if st != fmi2OK {
            return Err(format!("fmi2SerializedFMUstateSize = {st:?}"));
        }
        let mut buf = vec![0 as fmi2Byte; n];
        let st = unsafe { (abi().serialize_fmu_state)(self.c, s, buf.as_mut_ptr(), n) };
        if st != fmi2OK {
            return Err(format!("fmi2SerializeFMUstate = {st:?}"));
        }
        Ok(buf.into_iter().map(|b| b as u8).collect())
    }

    /// The complete dynamic state of the instance, through a fresh FMU state.
    /// Logs nothing into the book (its debug messages are dropped).
    pub fn state_bytes(&self) -> Result<Vec<u8>, String> {
        let mut s: fmi2FMUstate = null_mut();
        let st = unsafe { (abi().get_fmu_state)(self.c, &mut s) };
        if st != fmi2OK || s.is_null() {
            return Err(format!(
                "snapshot: fmi2GetFMUstate = {st:?}: {:?}",
                self.book.take()
            ));
        }
        let bytes = self.serialize_state(s);
        let st = unsafe { (abi().free_fmu_state)(self.c, &mut s) };
        let logs = self.book.take();
        let bytes = bytes.map_err(|e| format!("snapshot: {e}: {logs:?}"))?;
        if st != fmi2OK || !s.is_null() {
            return Err(format!("snapshot: fmi2FreeFMUstate = {st:?}: {logs:?}"));
        }
        Ok(bytes)
    }

    pub(crate) fn slot_bytes(&self, k: usize) -> Result<Vec<u8>, String> {
        let r = self.serialize_state(self.slots[k]);
        self.book.clear();
        r
    }
}

impl Drop for Fmu {
    fn drop(&mut self) {
        // Exactly once per instance, in whatever state it is, with the FMU
        // states it still owns.
        unsafe { (abi().free_instance)(self.c) };
    }
}

/// The layer's part of a serialized state (the format documented at
/// `hill_muscle::fmi2::instance::encode_state`) and the model's bytes, read
/// without the model's deserializer so that a model state that does not
/// deserialize does not hide everything else.
pub fn split_state(bytes: &[u8]) -> Result<(LayerState, &[u8]), String> {
    let bad = |e: ByteError| format!("a snapshot does not parse: {e}");
    let mut input = bytes;
    let mut r = ByteReader::new(&mut input);
    r.take(8).map_err(bad)?;
    r.u32().map_err(bad)?;
    r.u64().map_err(bad)?;
    r.str().map_err(bad)?;
    let code = r.u8().map_err(bad)?;
    let fmi_state = FmiState::from_u8(code).ok_or(format!("bad state code {code}"))?;
    let time = r.f64().map_err(bad)?;
    let start_time = r.f64().map_err(bad)?;
    let stop_def = r.bool().map_err(bad)?;
    let stop = r.f64().map_err(bad)?;
    let tol_def = r.bool().map_err(bad)?;
    let tol = r.f64().map_err(bad)?;
    let last_successful_time = r.f64().map_err(bad)?;
    let dirty = r.bool().map_err(bad)?;
    let status = r.u8().map_err(bad)?;
    let last_step_status = fmi2Status::from_u8(status).ok_or(format!("bad status {status}"))?;
    let model_terminated = r.bool().map_err(bad)?;
    let model = r.bytes().map_err(bad)?;
    let layer = LayerState {
        fmi_state,
        time,
        start_time,
        stop_time: stop_def.then_some(stop),
        tolerance: tol_def.then_some(tol),
        last_successful_time,
        dirty,
        last_step_status,
        model_terminated,
    };
    Ok((layer, model))
}

/// The layer's part of a snapshot ([`split_state`]). Unless
/// `API_ABUSE_ROUND_TRIP=0`, every snapshot must also pass the layer's full
/// `decode_state` (what `fmi2DeSerializeFMUstate` runs; module docs,
/// property 7).
pub(crate) fn layer_of(bytes: &[u8]) -> Result<LayerState, String> {
    let (layer, _) = split_state(bytes)?;
    if round_trip() {
        round_trip_verdict(bytes)?;
    }
    Ok(layer)
}

/// `API_ABUSE_ROUND_TRIP=0` turns property 7 off: then not every
/// serialized state the FMU produces has to deserialize.
pub(crate) fn round_trip() -> bool {
    static R: OnceLock<bool> = OnceLock::new();
    *R.get_or_init(|| std::env::var("API_ABUSE_ROUND_TRIP").map_or(true, |v| v != "0"))
}

pub(crate) fn guid_str() -> &'static str {
    table().guid.to_str().unwrap()
}

thread_local! {
    /// The serialized states this thread has decoded (key: the state's own
    /// checksum, its last 8 bytes, and its length).
    static DECODED: RefCell<HashSet<(u64, usize)>> = RefCell::new(HashSet::new());
}

/// `Err` when bytes the FMU serialized itself do not decode.
pub(crate) fn round_trip_verdict(bytes: &[u8]) -> Result<(), String> {
    let key = (
        bytes
            .len()
            .checked_sub(8)
            .map_or(0, |n| u64::from_le_bytes(bytes[n..].try_into().unwrap())),
        bytes.len(),
    );
    if DECODED.with(|d| d.borrow().contains(&key)) {
        return Ok(());
    }
    if let Err(e) = (installed().decode)(guid_str(), bytes) {
        return Err(format!(
            "the instance's serialized state does not deserialize: {e}"
        ));
    }
    DECODED.with(|d| {
        let mut d = d.borrow_mut();
        if d.len() >= 100_000 {
            d.clear();
        }
        d.insert(key);
    });
    Ok(())
}

/// Whether `fmi2DeSerializeFMUstate` must accept these bytes of a state the
/// FMU serialized itself: always with property 7 on (the snapshot checks
/// it); with it off, when they decode.
pub(crate) fn decodes(bytes: &[u8]) -> bool {
    round_trip() || (installed().decode)(guid_str(), bytes).is_ok()
}

/// Recomputes the checksum of a serialized state after the header's body
/// length (so corruptions reach the body parsers).
pub fn fix_checksum(b: &mut [u8]) {
    if b.len() < 20 {
        return;
    }
    let body = u64::from_le_bytes(b[12..20].try_into().unwrap());
    let Some(needed) = usize::try_from(body)
        .ok()
        .and_then(|n| n.checked_add(28))
        .filter(|&n| n <= b.len())
    else {
        return;
    };
    let sum = fnv1a64(FNV64_OFFSET, &b[..needed - 8]);
    b[needed - 8..needed].copy_from_slice(&sum.to_le_bytes());
}

/// Offset of the FMI state code in a serialized state: header (20), GUID
/// length (8), GUID.
pub(crate) fn state_code_offset() -> usize {
    28 + guid_str().len()
}

// The pool of serialized states (valid, of this GUID) that `Restore` and
// deserialization draw from.
pub(crate) const P_FRESH: usize = 0;
pub(crate) const P_IM: usize = 1;
pub(crate) const P_SC: usize = 2;
pub(crate) const P_RUN: usize = 3;
pub(crate) const P_SF: usize = 4;
pub(crate) const P_T: usize = 5;
pub(crate) const P_E: usize = 6;
pub(crate) const P_SCA: usize = 7;
pub(crate) const P_LATE: usize = 8;
pub(crate) const POOL_LEN: usize = 9;

pub(crate) fn pool() -> &'static Vec<Vec<u8>> {
    static P: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    P.get_or_init(|| {
        let t = table();
        let ok = |s: fmi2Status| assert!(s == fmi2OK || s == fmi2Warning, "pool: {s:?}");
        let f = Fmu::new(false);
        let c = f.c;
        let mut pool = vec![Vec::new(); POOL_LEN];
        pool[P_FRESH] = f.state_bytes().unwrap();
        unsafe {
            ok((abi().setup_experiment)(c, 0, 0.0, 0.0, 1, 1.0));
            ok((abi().enter_initialization_mode)(c));
            if !profile().solver_integers.is_empty() {
                set_integers(c, profile().solver_integers).unwrap();
                // Reading an output computes the initial values, on the new
                // mesh: a state in initialization mode that deserializes
                // (tests/api_abuse_fe.rs, the mesh bug).
                let mut out = 0.0;
                ok((abi().get_real)(c, &t.outputs[0], 1, &mut out));
            }
            let vrs = [t.activation, t.length];
            ok((abi().set_real)(
                c,
                vrs.as_ptr(),
                2,
                [0.3, t.length0 + 0.1 * t.span].as_ptr(),
            ));
            pool[P_IM] = f.state_bytes().unwrap();
            ok((abi().exit_initialization_mode)(c));
            pool[P_SC] = f.state_bytes().unwrap();
            ok((abi().set_real)(
                c,
                vrs.as_ptr(),
                2,
                [1.0, t.length0 + 0.04 * t.span].as_ptr(),
            ));
            let mut tc = 0.0;
            for _ in 0..20 {
                ok((abi().do_step)(c, tc, 1e-3, 1));
                tc += 1e-3;
            }
            pool[P_RUN] = f.state_bytes().unwrap();
            let mut e = pool[P_RUN].clone();
            e[state_code_offset()] = FmiState::Error.to_u8();
            fix_checksum(&mut e);
            pool[P_E] = e;
            let mut sca = pool[P_RUN].clone();
            sca[state_code_offset()] = FmiState::StepCanceled.to_u8();
            fix_checksum(&mut sca);
            pool[P_SCA] = sca;
            // The longest length the input takes (100 m): beyond what the
            // law can evaluate (a muscle), or the fibres can span (a unit).
            ok((abi().set_real)(c, &t.length, 1, &100.0));
            let s = (abi().do_step)(c, tc, 1e-3, 1);
            assert_eq!(s, fmi2Discard, "{:?}", f.book.take());
            pool[P_SF] = f.state_bytes().unwrap();
            ok((abi().terminate)(c));
            pool[P_T] = f.state_bytes().unwrap();
            ok((abi().reset)(c));
            ok((abi().setup_experiment)(c, 1, 1e-6, 1e6, 1, 1e6 + 0.5));
            ok((abi().enter_initialization_mode)(c));
            set_integers(c, profile().solver_integers).unwrap();
            ok((abi().exit_initialization_mode)(c));
            ok((abi().do_step)(c, 1e6, 0.01, 0));
            pool[P_LATE] = f.state_bytes().unwrap();
        }
        // Every pool state restores (`Restore` reaches its state).
        for (i, b) in pool.iter().enumerate() {
            if let Err(e) = (installed().decode)(guid_str(), b) {
                panic!("pool state {i} does not decode: {e}");
            }
        }
        pool
    })
}

/// The serialized state of a new instance.
pub(crate) fn fresh_bytes() -> &'static Vec<u8> {
    pool().get(P_FRESH).unwrap()
}

/// Pointers that are not this instance's: a zeroed buffer (not an
/// instance: its first 8 bytes are not the magic) used as a foreign
/// `fmi2Component` and as a bogus `fmi2FMUstate`, and another instance
/// holding an FMU state. Nothing the harness does changes it (the calls
/// that receive its pointers must refuse them), so each test thread makes
/// one ([`with_env`]).
pub(crate) struct Env {
    pub(crate) foreign: Box<[u64; 8]>,
    pub(crate) bogus: Box<[u64; 8]>,
    pub(crate) other: Fmu,
}

impl Env {
    pub(crate) fn new() -> Env {
        let mut other = Fmu::new(false);
        let s = unsafe { (abi().get_fmu_state)(other.c, &mut other.slots[0]) };
        assert_eq!(s, fmi2OK);
        Env {
            foreign: Box::new([0; 8]),
            bogus: Box::new([0; 8]),
            other,
        }
    }

    pub(crate) fn foreign(&self) -> fmi2Component {
        &*self.foreign as *const [u64; 8] as *mut c_void
    }

    pub(crate) fn bogus(&self) -> fmi2FMUstate {
        &*self.bogus as *const [u64; 8] as *mut c_void
    }

    pub(crate) fn other_state(&self) -> fmi2FMUstate {
        self.other.slots[0]
    }
}

thread_local! {
    static ENV: Env = Env::new();
}

/// This thread's [`Env`].
pub(crate) fn with_env<R>(f: impl FnOnce(&Env) -> R) -> R {
    ENV.with(f)
}
