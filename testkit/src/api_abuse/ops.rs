//! Operations (what is generated) and their resolution into calls;
//! mutations of serialized states.

use super::*;

/// How `fmi2DoStep`'s `currentCommunicationPoint` is chosen, relative to the
/// FMU's time `t` before the call.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Tc {
    /// `t` itself.
    Exact,
    /// The master's own `t += h` accumulation.
    Accumulated,
    /// The master's `t0 + i * h`.
    Multiplied,
    /// `t` moved by a few ulps.
    Ulps(i32),
    /// `t + r · max(1, |t|)`, |r| ≤ 1e-11.
    Rel(f64),
    /// `t ± factor · tolerance`, factor ≥ 3: a jump.
    Jump(f64),
    /// `t ± h`: a whole step off.
    JumpH(bool),
    Lit(f64),
}

#[derive(Clone, Copy, Debug)]
pub(crate) enum H {
    Lit(f64),
    /// Exactly to the stop time (1e-3 without one).
    ToStop,
    /// To the stop time plus this.
    PastStop(f64),
}

#[derive(Clone, Copy, Debug)]
pub(crate) enum Buf {
    Exact,
    Short(Index),
    Zero,
    Long(usize),
    Null,
    Impossible,
}

#[derive(Clone, Debug)]
pub(crate) enum Src {
    /// The instance's current state.
    Current,
    Pool(usize),
    Slot(usize),
    Random(Vec<u8>),
    Empty,
}

#[derive(Clone, Debug)]
pub(crate) enum Mutation {
    None,
    Truncate(Index),
    Flip { at: Index, bit: u8, fix: bool },
    Overwrite { at: Index, value: f64, fix: bool },
    Append(Vec<u8>),
    ForeignGuid,
    Zero,
}

#[derive(Clone, Copy, Debug)]
pub(crate) enum Size {
    Exact,
    Less(Index),
    Zero,
    Impossible,
}

#[derive(Clone, Debug)]
pub(crate) enum Op {
    Call(Call),
    Step {
        comp: Comp,
        tc: Tc,
        h: H,
        flag: i32,
    },
    Serialize {
        comp: Comp,
        st: StateIn,
        buf: Buf,
    },
    Deserialize {
        comp: Comp,
        src: Src,
        mutation: Mutation,
        size: Size,
        ptr: Ptr,
        out: StateOut,
    },
    /// Setup, enter, set Integer parameters (the subject's cost
    /// parameters, [`Subject::INIT_INTEGERS`]), set inputs, exit.
    Init {
        start: f64,
        stop: Option<f64>,
        integers: Vec<(u32, i32)>,
        inputs: Vec<(u32, f64)>,
    },
    /// `n` × (set activation and length, step).
    Run {
        n: usize,
        h: f64,
        tc: Tc,
        amp: f64,
        act: f64,
    },
    /// Deserialize a pool state into slot 3 and set it.
    Restore(usize),
    /// What a master does on a discard: save the state in slot 0, set the
    /// length to `factor` × its start (beyond what the law can evaluate for large
    /// factors), step (discarded), ask why, roll back, step again.
    DiscardRecover(f64),
    /// Deterministic tests only: the FMI state before the next call.
    ExpectState(FmiState),
}

pub(crate) fn set_real(vrs: Vec<u32>, vals: Vec<f64>) -> Call {
    Call::SetReal {
        comp: Comp::Valid,
        vrs,
        vals,
        ptrs: [Ptr::Ok; 2],
        len: Len::Exact,
    }
}

pub(crate) fn set_integer(vrs: Vec<u32>, vals: Vec<i32>) -> Call {
    Call::SetInteger {
        comp: Comp::Valid,
        vrs,
        vals,
        ptrs: [Ptr::Ok; 2],
        len: Len::Exact,
    }
}

pub(crate) fn get(ty: Ty, vrs: Vec<u32>) -> Call {
    Call::Get {
        comp: Comp::Valid,
        ty,
        vrs,
        ptrs: [Ptr::Ok; 2],
        len: Len::Exact,
    }
}

/// Macros into primitive operations.
pub(crate) fn expand(op: &Op) -> Vec<Op> {
    let t = table();
    match op {
        Op::Init {
            start,
            stop,
            integers,
            inputs,
        } => {
            let mut v = vec![
                Op::Call(Call::Setup {
                    comp: Comp::Valid,
                    tol_def: 0,
                    tol: 0.0,
                    start: *start,
                    stop_def: i32::from(stop.is_some()),
                    stop: stop.unwrap_or(f64::NAN),
                }),
                Op::Call(Call::Enter(Comp::Valid)),
            ];
            if !integers.is_empty() {
                let (vrs, vals) = integers.iter().copied().unzip();
                v.push(Op::Call(set_integer(vrs, vals)));
            }
            if !inputs.is_empty() {
                let (vrs, vals) = inputs.iter().copied().unzip();
                v.push(Op::Call(set_real(vrs, vals)));
            }
            v.push(Op::Call(Call::Exit(Comp::Valid)));
            v
        }
        Op::Run { n, h, tc, amp, act } => (0..*n)
            .flat_map(|i| {
                let phase = 2.0 * std::f64::consts::PI * i as f64 / 40.0;
                let length = t.length0 + amp * phase.sin() * t.span;
                [
                    Op::Call(set_real(vec![t.activation, t.length], vec![*act, length])),
                    Op::Step {
                        comp: Comp::Valid,
                        tc: *tc,
                        h: H::Lit(*h),
                        flag: 0,
                    },
                ]
            })
            .collect(),
        Op::Restore(i) => vec![
            Op::Deserialize {
                comp: Comp::Valid,
                src: Src::Pool(*i),
                mutation: Mutation::None,
                size: Size::Exact,
                ptr: Ptr::Ok,
                out: StateOut::Slot(N_SLOTS - 1),
            },
            Op::Call(Call::SetState {
                comp: Comp::Valid,
                st: StateIn::Slot(N_SLOTS - 1),
            }),
        ],
        Op::DiscardRecover(factor) => {
            let step = Op::Step {
                comp: Comp::Valid,
                tc: Tc::Exact,
                h: H::Lit(1e-3),
                flag: 0,
            };
            let status = |func, kind| {
                Op::Call(Call::Status {
                    comp: Comp::Valid,
                    func,
                    kind,
                    null: false,
                })
            };
            vec![
                Op::Call(Call::GetState {
                    comp: Comp::Valid,
                    out: StateOut::Slot(0),
                }),
                Op::Call(set_real(vec![t.length], vec![t.length0 * factor])),
                step.clone(),
                status(StatusFn::Status, fmi2DoStepStatus),
                status(StatusFn::Real, fmi2LastSuccessfulTime),
                status(StatusFn::Boolean, fmi2Terminated),
                Op::Call(Call::SetState {
                    comp: Comp::Valid,
                    st: StateIn::Slot(0),
                }),
                Op::Call(set_real(vec![t.length], vec![t.length0])),
                step,
            ]
        }
        // The subject's cost parameters after every entry into
        // initialization mode (nothing for an empty list).
        Op::Call(Call::Enter(Comp::Valid)) if !profile().cheap_integers.is_empty() => {
            let (vrs, vals) = integer_refs(profile().cheap_integers).into_iter().unzip();
            vec![op.clone(), Op::Call(set_integer(vrs, vals))]
        }
        other => vec![other.clone()],
    }
}

pub(crate) fn mutate(mut b: Vec<u8>, m: &Mutation) -> Vec<u8> {
    match m {
        Mutation::None => {}
        Mutation::Truncate(i) => {
            let n = i.index(b.len().max(1));
            b.truncate(n);
        }
        Mutation::Flip { at, bit, fix } => {
            if !b.is_empty() {
                let k = at.index(b.len());
                b[k] ^= 1 << (bit % 8);
                if *fix {
                    fix_checksum(&mut b);
                }
            }
        }
        Mutation::Overwrite { at, value, fix } => {
            if b.len() >= 8 {
                let k = at.index(b.len() - 7);
                b[k..k + 8].copy_from_slice(&value.to_le_bytes());
                if *fix {
                    fix_checksum(&mut b);
                }
            }
        }
        Mutation::Append(x) => b.extend_from_slice(x),
        Mutation::ForeignGuid => {
            let k = 28;
            if b.len() > k {
                b[k] = if b[k] == b'X' { b'Y' } else { b'X' };
                fix_checksum(&mut b);
            }
        }
        Mutation::Zero => b.iter_mut().for_each(|x| *x = 0),
    }
    b
}
