//! The driver: a sequence run on a primary, its twin and the snapshots,
//! with every property of the module docs checked after every call.

use super::*;

/// The master's clock: its own `t += h` accumulation and `t0 + i * h`,
/// resynchronized with the FMU's time only when that jumped (a reset, a
/// restored FMU state, a new experiment), never to absorb drift.
pub(crate) struct Master {
    pub(crate) t_acc: f64,
    pub(crate) t0: f64,
    pub(crate) i: u64,
    pub(crate) h: f64,
}

impl Master {
    pub(crate) fn new() -> Master {
        Master {
            t_acc: 0.0,
            t0: 0.0,
            i: 0,
            h: f64::NAN,
        }
    }

    pub(crate) fn tc(&mut self, kind: Tc, t: f64, h: f64) -> f64 {
        let near = (self.t_acc - t).abs() <= 1e-7 * t.abs().max(1.0);
        if !near {
            *self = Master {
                t_acc: t,
                t0: t,
                ..Master::new()
            };
        }
        if h.to_bits() != self.h.to_bits() {
            self.t0 = self.t_acc;
            self.i = 0;
            self.h = h;
        }
        let tol = api::time_tolerance(t, h);
        match kind {
            Tc::Exact => t,
            Tc::Accumulated => self.t_acc,
            Tc::Multiplied => self.t0 + self.i as f64 * h,
            Tc::Ulps(k) => t + f64::from(k) * f64::EPSILON * t.abs().max(f64::MIN_POSITIVE),
            Tc::Rel(r) => t + r * t.abs().max(1.0),
            Tc::Jump(x) => t + x * tol,
            Tc::JumpH(up) => {
                if up {
                    t + h
                } else {
                    t - h
                }
            }
            Tc::Lit(x) => x,
        }
    }

    pub(crate) fn stepped(&mut self, h: f64) {
        self.t_acc += h;
        self.i += 1;
    }
}

// ---------------------------------------------------------------------------
// The harness
// ---------------------------------------------------------------------------

/// `API_ABUSE_STATS=1`: counts of (function, state before, status) and of
/// the harness's comparisons, printed after the property tests.
pub(crate) fn stats() -> Option<&'static Mutex<std::collections::BTreeMap<String, u64>>> {
    static S: OnceLock<Option<Mutex<std::collections::BTreeMap<String, u64>>>> = OnceLock::new();
    S.get_or_init(|| {
        std::env::var("API_ABUSE_STATS")
            .is_ok_and(|v| v == "1")
            .then(Default::default)
    })
    .as_ref()
}

pub(crate) fn stat(key: impl FnOnce() -> String) {
    if let Some(s) = stats() {
        *s.lock().unwrap().entry(key()).or_default() += 1;
    }
}

pub(crate) fn print_stats(test: &str) {
    if let Some(s) = stats() {
        let s = s.lock().unwrap();
        eprintln!("-- {test}: calls by (function, state before, status), and comparisons");
        for (k, n) in s.iter() {
            eprintln!("{n:>10}  {k}");
        }
    }
}

/// Masks FMU state addresses (`0x...`) in log messages.
pub(crate) fn mask(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find("0x") {
        out.push_str(&rest[..i + 2]);
        out.push('?');
        rest = rest[i + 2..].trim_start_matches(|c: char| c.is_ascii_hexdigit());
    }
    out.push_str(rest);
    out
}

pub(crate) fn masked(logs: &[Entry]) -> Vec<(fmi2Status, String, String)> {
    logs.iter()
        .map(|e| (e.status, e.category.clone(), mask(&e.message)))
        .collect()
}

pub(crate) fn expected_category(s: fmi2Status) -> &'static [&'static str] {
    match s {
        fmi2OK => &["logAll", "logEvents"],
        fmi2Warning => &["logStatusWarning"],
        fmi2Discard => &["logStatusDiscard"],
        fmi2Error => &["logStatusError"],
        fmi2Fatal => &["logStatusFatal"],
        fmi2Pending => &[],
    }
}

/// After an accepted `fmi2SetDebugLogging`: whether any debug category is
/// on (a `logStatus*` name selects no debug message).
pub(crate) fn debug_after(call: &Call, s: fmi2Status) -> Option<bool> {
    match call {
        Call::Logging { on, cats, .. } if s == fmi2OK => Some(
            *on != 0
                && (cats.is_empty()
                    || cats
                        .iter()
                        .any(|c| matches!(c, Cat::Known(4) | Cat::Known(5)))),
        ),
        _ => None,
    }
}

pub(crate) struct Harness {
    pub(crate) logging_on: bool,
    pub(crate) p: Fmu,
    pub(crate) twin: Fmu,
    /// A fresh instance following the primary since its last accepted reset.
    pub(crate) shadow: Option<Fmu>,
    pub(crate) master: Master,
    /// The last accepted `fmi2SetDebugLogging` (replayed on a new shadow:
    /// a reset keeps the logging settings).
    pub(crate) last_logging: Option<Call>,
    /// Whether a debug message may be logged (instantiation's `loggingOn`,
    /// then the last accepted `fmi2SetDebugLogging`).
    pub(crate) debug_on: bool,
    pub(crate) trace: Vec<String>,
    pub(crate) calls: usize,
}

impl Harness {
    pub(crate) fn new(logging_on: bool) -> Harness {
        Harness {
            logging_on,
            p: Fmu::new(logging_on),
            twin: Fmu::new(logging_on),
            shadow: None,
            master: Master::new(),
            last_logging: None,
            debug_on: logging_on,
            trace: Vec::new(),
            calls: 0,
        }
    }

    pub(crate) fn fail(&self, e: String) -> String {
        let tail = self.trace.len().saturating_sub(25);
        format!(
            "{e}\n-- last calls (of {}):\n{}",
            self.calls,
            self.trace[tail..].join("\n")
        )
    }

    pub(crate) fn resolve(
        &mut self,
        op: &Op,
        pre: &LayerState,
        pre_bytes: &[u8],
    ) -> Result<(Call, Expect), String> {
        Ok(match op {
            Op::Call(c) => (c.clone(), Unknown),
            Op::Step { comp, tc, h, flag } => {
                let t = pre.time;
                let h = match *h {
                    H::Lit(x) => x,
                    H::ToStop => pre.stop_time.map_or(1e-3, |s| s - t),
                    H::PastStop(x) => pre.stop_time.map_or(x, |s| s - t + x),
                };
                let tc = self.master.tc(*tc, t, h);
                let call = Call::Step {
                    comp: *comp,
                    tc,
                    h,
                    flag: *flag,
                };
                (call, step_expect(tc, h, pre))
            }
            Op::Serialize { comp, st, buf } => {
                let need = match st {
                    StateIn::Slot(k) if !self.p.slots[*k].is_null() => {
                        Some(self.p.slot_bytes(*k)?.len())
                    }
                    _ => None,
                };
                let n = need.unwrap_or(256);
                let (size, ptr, impossible) = match buf {
                    Buf::Exact => (n, Ptr::Ok, false),
                    Buf::Short(i) => (i.index(n), Ptr::Ok, false),
                    Buf::Zero => (0, Ptr::Ok, false),
                    Buf::Long(k) => (n + k, Ptr::Ok, false),
                    Buf::Null => (n, Ptr::Null, false),
                    Buf::Impossible => (0, Ptr::Ok, true),
                };
                let e = if need.is_some() && matches!(buf, Buf::Exact | Buf::Long(_)) {
                    Accept
                } else {
                    Reject
                };
                let call = Call::Serialize {
                    comp: *comp,
                    st: *st,
                    size,
                    ptr,
                    impossible,
                };
                (call, e)
            }
            Op::Deserialize {
                comp,
                src,
                mutation,
                size,
                ptr,
                out,
            } => {
                let (bytes, valid) = match src {
                    Src::Current => (pre_bytes.to_vec(), true),
                    Src::Pool(i) => (pool()[*i].clone(), true),
                    Src::Slot(k) if !self.p.slots[*k].is_null() => (self.p.slot_bytes(*k)?, true),
                    Src::Slot(_) | Src::Empty => (Vec::new(), false),
                    Src::Random(b) => (b.clone(), false),
                };
                // Unless API_ABUSE_ROUND_TRIP=1: a state of the known bug is
                // not expected to deserialize.
                let intact = valid && decodes(&bytes);
                let full = bytes.len();
                let bytes = mutate(bytes, mutation);
                let (n, impossible) = match size {
                    Size::Exact => (bytes.len(), false),
                    Size::Less(i) => (i.index(bytes.len().max(1)), false),
                    Size::Zero => (0, false),
                    Size::Impossible => (0, true),
                };
                let e = if *ptr == Ptr::Null
                    || impossible
                    || *out == StateOut::NullPtr
                    || matches!(src, Src::Empty)
                    || (matches!(src, Src::Slot(_)) && !valid)
                {
                    Reject
                } else if !valid {
                    Unknown
                } else {
                    match mutation {
                        Mutation::None | Mutation::Append(_) if n >= full && intact => Accept,
                        Mutation::None | Mutation::Append(_) if n >= full => Unknown,
                        Mutation::None
                        | Mutation::Truncate(_)
                        | Mutation::Zero
                        | Mutation::ForeignGuid
                        | Mutation::Flip { fix: false, .. } => Reject,
                        _ => Unknown,
                    }
                };
                let call = Call::Deserialize {
                    comp: *comp,
                    bytes: Bytes(bytes),
                    size: n,
                    ptr: *ptr,
                    impossible,
                    out: *out,
                };
                (call, e)
            }
            Op::Init { .. }
            | Op::Run { .. }
            | Op::Restore(_)
            | Op::DiscardRecover(_)
            | Op::ExpectState(_) => {
                unreachable!("expanded before")
            }
        })
    }

    /// Runs one primitive operation on the primary with every check, then on
    /// the followers.
    pub(crate) fn one(&mut self, env: &Env, op: &Op) -> Result<fmi2Status, String> {
        let pre_bytes = self.p.state_bytes()?;
        let pre = layer_of(&pre_bytes)?;
        if let Op::ExpectState(s) = op {
            ensure!(
                pre.fmi_state == *s,
                "expected state {s:?}, in {:?}",
                pre.fmi_state
            );
            return Ok(fmi2OK);
        }
        let (call, resolved) = self.resolve(op, &pre, &pre_bytes)?;
        let mut want = expect(&call, &pre, &self.p);
        if want != Reject && resolved != Unknown {
            want = resolved;
        }
        let (fname, allowed) = call.meta();
        let state_ok = allowed.contains(pre.fmi_state);

        // The shadow cannot follow a call on an FMU state saved before its
        // reset: compare and stop following.
        if let Some(s) = &self.shadow {
            if call
                .slots()
                .iter()
                .any(|&k| s.slots[k].is_null() != self.p.slots[k].is_null())
            {
                let sb = s.state_bytes()?;
                ensure!(sb == pre_bytes, "reset shadow diverged before {call:?}");
                self.shadow = None;
            }
        }
        let set_from = match &call {
            Call::SetState {
                st: StateIn::Slot(k),
                ..
            } if !self.p.slots[*k].is_null() => Some(self.p.slot_bytes(*k)?),
            _ => None,
        };

        self.p.book.clear();
        let out = exec(&mut self.p, env, &call);
        let logs = self.p.book.take();
        let s = out.status;
        self.calls += 1;
        self.trace.push(format!(
            "[{}] {:?} -> {:?}: {:?}",
            pre.fmi_state.name(),
            call,
            s,
            logs.iter().map(|e| &e.message).collect::<Vec<_>>()
        ));

        stat(|| format!("{fname} [{}] -> {s:?}", pre.fmi_state.name()));
        stat(|| format!("~ oracle {want:?}"));
        // 1. A valid status, no caught panic, synchronous.
        ensure!(
            (0..=5).contains(&(s as i32)) && s != fmi2Fatal && s != fmi2Pending,
            "{fname} returned {s:?}"
        );
        // 3. The oracle.
        match want {
            Reject => ensure!(s == fmi2Error, "{fname} must be rejected, got {s:?}"),
            Accept => ensure!(s != fmi2Error, "{fname} must be accepted, got {s:?}"),
            Unknown => {}
        }
        // 2. Logging.
        for e in &logs {
            ensure!(
                e.instance == NAME.to_bytes(),
                "{fname}: logged with instance name {:?}",
                String::from_utf8_lossy(&e.instance)
            );
            ensure!(e.format == "%s", "{fname}: format {:?}", e.format);
            ensure!(!e.message.is_empty(), "{fname}: empty message");
            ensure!(!e.message.contains('#'), "{fname}: '#' in {:?}", e.message);
            ensure!(
                expected_category(e.status).contains(&e.category.as_str()),
                "{fname}: status {:?} in category {}",
                e.status,
                e.category
            );
            ensure!(
                e.status != fmi2OK || self.debug_on || debug_after(&call, s) == Some(true),
                "{fname}: debug message with debug logging off: {:?}",
                e.message
            );
        }
        if call.comp() != Comp::Valid {
            ensure!(
                s == fmi2Error,
                "{fname} on a {:?} component: {s:?}",
                call.comp()
            );
            ensure!(
                logs.is_empty(),
                "{fname} on a {:?} component logged {logs:?}",
                call.comp()
            );
        } else if s == fmi2Error || s == fmi2Discard {
            let prefix = format!("{fname}: ");
            ensure!(
                logs.iter()
                    .any(|e| e.status == s && e.message.starts_with(&prefix)),
                "{fname} returned {s:?} without a {s:?} message starting with {prefix:?}: {logs:?}"
            );
            if !state_ok {
                let why = format!("{fname}: not allowed in state {}", pre.fmi_state.name());
                ensure!(
                    logs.iter().any(|e| e.message == why),
                    "{fname} in state {}: no {why:?} in {logs:?}",
                    pre.fmi_state.name()
                );
            }
        }

        // 4. Rejected (and read-only) calls change nothing.
        let post_bytes = self.p.state_bytes()?;
        let is_step = matches!(call, Call::Step { .. });
        let keep = s == fmi2Error || (s == fmi2Discard && !is_step) || call.is_pure(pre.fmi_state);
        if keep && post_bytes != pre_bytes {
            let post = layer_of(&post_bytes)?;
            let at = pre_bytes
                .iter()
                .zip(&post_bytes)
                .position(|(a, b)| a != b)
                .unwrap_or(pre_bytes.len().min(post_bytes.len()));
            return Err(format!(
                "{fname} returned {s:?} but changed the instance: layer {pre:?} -> {post:?}; \
                 serialized state: {} -> {} bytes, first difference at byte {at}",
                pre_bytes.len(),
                post_bytes.len()
            ));
        }
        if s == fmi2Error {
            ensure!(
                out.untouched,
                "{fname} returned fmi2Error but wrote an out-argument"
            );
            return Ok(s);
        }
        // A discarded step: stepFailed at the step's start, the model as it was.
        if let (Call::Step { tc, .. }, fmi2Discard) = (&call, s) {
            let (post, post_model) = split_state(&post_bytes)?;
            let (_, pre_model) = split_state(&pre_bytes)?;
            let want = LayerState {
                fmi_state: FmiState::StepFailed,
                time: *tc,
                last_successful_time: *tc,
                last_step_status: fmi2Discard,
                ..pre
            };
            ensure!(
                post == want,
                "fmi2DoStep discarded, but the layer went from {pre:?} to {post:?}, not {want:?}"
            );
            ensure!(
                post_model == pre_model,
                "fmi2DoStep discarded, but the model changed ({} -> {} bytes)",
                pre_model.len(),
                post_model.len()
            );
            stat(|| {
                // The model's reason, without numbers.
                let why = logs
                    .iter()
                    .find_map(|e| e.message.split_once("discarded: ").map(|(_, w)| w))
                    .unwrap_or("?");
                let words: String = why
                    .split_whitespace()
                    .filter(|w| !w.contains(|c: char| c.is_ascii_digit()))
                    .take(8)
                    .collect::<Vec<_>>()
                    .join(" ");
                format!("~ discarded steps, model unchanged: {words}")
            });
        }
        match &call {
            Call::Reset(_) => ensure!(
                &post_bytes == fresh_bytes(),
                "fmi2Reset: the state differs from a new instance's"
            ),
            Call::SetState { .. } => ensure!(
                Some(&post_bytes) == set_from.as_ref(),
                "fmi2SetFMUstate: the state differs from the saved one"
            ),
            Call::GetState {
                out: StateOut::Slot(k),
                ..
            } => ensure!(
                self.p.slot_bytes(*k)? == pre_bytes,
                "fmi2GetFMUstate: the saved state differs from the instance's"
            ),
            _ => {}
        }

        // 5. and 6. The followers.
        let t = &mut self.twin;
        t.book.clear();
        let o = exec(t, env, &call);
        let tl = t.book.take();
        ensure!(
            o.status == s && o.reads == out.reads,
            "twin: {fname} gave {:?} (values {:?}), the primary {s:?} (values {:?})",
            o.status,
            o.reads,
            out.reads
        );
        ensure!(
            masked(&tl) == masked(&logs),
            "twin: {fname} logged {tl:?}, the primary {logs:?}"
        );
        stat(|| "~ twin: calls compared".into());
        if matches!(call, Call::Reset(_)) {
            if let Some(sh) = self.shadow.take() {
                ensure!(
                    sh.state_bytes()? == pre_bytes,
                    "reset shadow diverged before a reset"
                );
            }
            let sh = Fmu::new(self.logging_on);
            if let Some(l) = &self.last_logging {
                let mut sh = sh;
                let r = exec(&mut sh, env, l);
                ensure!(
                    r.status == fmi2OK,
                    "replaying logging settings: {:?}",
                    r.status
                );
                sh.book.clear();
                self.shadow = Some(sh);
            } else {
                self.shadow = Some(sh);
            }
            let sb = self.shadow.as_ref().unwrap().state_bytes()?;
            ensure!(sb == post_bytes, "fmi2Reset: differs from a new instance");
            stat(|| "~ reset shadows started".into());
        } else if let Some(sh) = &mut self.shadow {
            sh.book.clear();
            let o = exec(sh, env, &call);
            let sl = sh.book.take();
            ensure!(
                o.status == s && o.reads == out.reads,
                "reset shadow: {fname} gave {:?} (values {:?}), the reset instance {s:?} (values {:?})",
                o.status,
                o.reads,
                out.reads
            );
            ensure!(
                masked(&sl) == masked(&logs),
                "reset shadow: {fname} logged {sl:?}, the reset instance {logs:?}"
            );
            stat(|| "~ reset shadow: calls compared".into());
        }

        if let Call::Step { h, .. } = call {
            if s == fmi2OK {
                self.master.stepped(h);
            }
        }
        if let Some(on) = debug_after(&call, s) {
            self.debug_on = on;
            self.last_logging = Some(call);
        }
        Ok(s)
    }

    /// End of a sequence: the twin, the shadow and the primary agree.
    pub(crate) fn finish(&mut self, env: &Env) -> Result<(), String> {
        let pb = self.p.state_bytes()?;
        ensure!(
            self.twin.state_bytes()? == pb,
            "twin: the final serialized states differ"
        );
        if let Some(sh) = &self.shadow {
            ensure!(
                sh.state_bytes()? == pb,
                "reset shadow: the final serialized states differ"
            );
        }
        for k in 0..N_SLOTS {
            let (a, b) = (self.p.slots[k], self.twin.slots[k]);
            ensure!(a.is_null() == b.is_null(), "twin: slot {k} differs");
            if !a.is_null() {
                ensure!(
                    self.p.slot_bytes(k)? == self.twin.slot_bytes(k)?,
                    "twin: saved FMU state {k} differs"
                );
            }
        }
        let mut finals = vec![Call::Get {
            comp: Comp::Valid,
            ty: Ty::Real,
            vrs: table().outputs.clone(),
            ptrs: [Ptr::Ok; 2],
            len: Len::Exact,
        }];
        if !table().int_outputs.is_empty() {
            finals.push(get(Ty::Integer, table().int_outputs.clone()));
        }
        for (func, kind) in [
            (StatusFn::Status, fmi2DoStepStatus),
            (StatusFn::Real, fmi2LastSuccessfulTime),
            (StatusFn::Boolean, fmi2Terminated),
        ] {
            finals.push(Call::Status {
                comp: Comp::Valid,
                func,
                kind,
                null: false,
            });
        }
        for call in &finals {
            let a = exec(&mut self.p, env, call);
            let b = exec(&mut self.twin, env, call);
            ensure!(
                a.status == b.status && a.reads == b.reads,
                "twin: final {:?}: {:?} {:?} vs {:?} {:?}",
                call.meta().0,
                a.status,
                a.reads,
                b.status,
                b.reads
            );
            if let Some(sh) = &mut self.shadow {
                let c = exec(sh, env, call);
                ensure!(
                    a.status == c.status && a.reads == c.reads,
                    "reset shadow: final {:?} differs",
                    call.meta().0
                );
            }
        }
        Ok(())
    }
}

pub(crate) fn run_sequence(logging_on: bool, ops: &[Op]) -> Result<(), String> {
    with_env(|env| {
        let mut h = Harness::new(logging_on);
        for op in ops {
            let is_run = matches!(op, Op::Run { .. });
            for prim in expand(op) {
                let s = h.one(env, &prim).map_err(|e| h.fail(e))?;
                // A master stops a run at the first step that does not complete.
                if is_run && matches!(prim, Op::Step { .. }) && s != fmi2OK {
                    break;
                }
            }
        }
        h.finish(env).map_err(|e| h.fail(e))
    })
}
