//! The proptest strategies of every argument and operation.

use super::*;

pub(crate) fn special() -> impl Strategy<Value = f64> + Clone {
    prop::sample::select(vec![
        f64::NAN,
        -f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        0.0,
        -0.0,
        -1.0,
        1.0,
        0.5,
        2.0,
        -1e-3,
        f64::MIN_POSITIVE,
        5e-324,
        1e-300,
        1e300,
        f64::MAX,
        -f64::MAX,
    ])
}

pub(crate) fn arb_comp() -> impl Strategy<Value = Comp> + Clone {
    prop_oneof![
        40 => Just(Comp::Valid),
        1 => Just(Comp::Null),
        1 => Just(Comp::Foreign),
    ]
}

pub(crate) fn arb_ptr() -> impl Strategy<Value = Ptr> + Clone {
    prop_oneof![25 => Just(Ptr::Ok), 1 => Just(Ptr::Null)]
}

pub(crate) fn arb_len() -> impl Strategy<Value = Len> + Clone {
    prop_oneof![40 => Just(Len::Exact), 1 => Just(Len::Impossible)]
}

pub(crate) fn arb_vr() -> impl Strategy<Value = u32> + Clone {
    let n = n_vars();
    let t = table();
    prop_oneof![
        8 => 0..n,
        6 => prop::sample::select(vec![t.activation, t.length]),
        1 => n..n + 4,
        1 => Just(u32::MAX),
        1 => any::<u32>(),
    ]
}

/// A value for a Real variable: near its start value, in [0, 1], special, or
/// any bit pattern.
pub(crate) fn real_for(vr: u32) -> BoxedStrategy<f64> {
    let start = start_of(vr);
    prop_oneof![
        4 => (0.5f64..1.5).prop_map(move |f| start * f),
        2 => Just(start),
        2 => 0.0f64..=1.0,
        3 => special(),
        1 => any::<f64>(),
    ]
    .boxed()
}

pub(crate) fn vr_real() -> impl Strategy<Value = (u32, f64)> + Clone {
    arb_vr().prop_flat_map(|vr| (Just(vr), real_for(vr)))
}

/// Short arrays mostly; sometimes long ones (up to 120, with repeats).
pub(crate) fn items<T: Strategy + Clone>(s: T) -> impl Strategy<Value = Vec<T::Value>> + Clone
where
    T::Value: Clone,
{
    prop_oneof![
        12 => prop::collection::vec(s.clone(), 0..4),
        1 => prop::collection::vec(s, 20..120),
    ]
}

pub(crate) fn arb_state_in() -> impl Strategy<Value = StateIn> + Clone {
    prop_oneof![
        12 => (0..N_SLOTS).prop_map(StateIn::Slot),
        1 => Just(StateIn::Null),
        1 => Just(StateIn::Bogus),
        1 => Just(StateIn::Other),
    ]
}

pub(crate) fn arb_state_out() -> impl Strategy<Value = StateOut> + Clone {
    prop_oneof![
        12 => (0..N_SLOTS).prop_map(StateOut::Slot),
        1 => Just(StateOut::NullPtr),
        1 => Just(StateOut::HoldsBogus),
        1 => Just(StateOut::HoldsOther),
    ]
}

pub(crate) fn arb_tc() -> impl Strategy<Value = Tc> + Clone {
    prop_oneof![
        6 => Just(Tc::Exact),
        6 => Just(Tc::Accumulated),
        4 => Just(Tc::Multiplied),
        2 => (-1000i32..=1000).prop_map(Tc::Ulps),
        2 => (-1e-11f64..1e-11).prop_map(Tc::Rel),
        2 => prop_oneof![3.0f64..1e6, -1e6f64..-3.0].prop_map(Tc::Jump),
        1 => any::<bool>().prop_map(Tc::JumpH),
        1 => prop_oneof![
            Just(f64::NAN),
            Just(f64::INFINITY),
            Just(f64::NEG_INFINITY),
            Just(0.0),
            any::<f64>()
        ]
        .prop_map(Tc::Lit),
    ]
}

pub(crate) fn step_size() -> impl Strategy<Value = f64> + Clone {
    prop_oneof![
        6 => prop::sample::select(vec![1e-6, 1e-4, 1e-3, 1e-2, 0.1, 0.5]),
        3 => 1e-7f64..0.2,
        1 => prop::sample::select(vec![
            0.0,
            -0.0,
            -1e-3,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            5e-324,
            1e300,
        ]),
    ]
}

pub(crate) fn arb_h() -> impl Strategy<Value = H> + Clone {
    prop_oneof![
        8 => step_size().prop_map(H::Lit),
        1 => Just(H::ToStop),
        1 => prop::sample::select(vec![1e-9, 1e-3, 1.0]).prop_map(H::PastStop),
    ]
}

pub(crate) fn start_time() -> impl Strategy<Value = f64> + Clone {
    prop_oneof![
        6 => prop::sample::select(vec![0.0, 1.0, -3.5, 1e6, 1e-300, -1e9]),
        2 => -1e3f64..1e3,
        1 => special(),
    ]
}

/// `(start, stop_defined, stop)`.
pub(crate) fn experiment() -> impl Strategy<Value = (f64, i32, f64)> + Clone {
    (
        start_time(),
        prop_oneof![3 => Just(1), 2 => Just(0), 1 => Just(7)],
        prop_oneof![
            6 => prop::sample::select(vec![0.0, 1e-3, 0.05, 1.0, 10.0]).prop_map(Some),
            1 => Just(None),
        ],
        special(),
    )
        .prop_map(|(start, def, rel, sp)| (start, def, rel.map_or(sp, |r| start + r)))
}

pub(crate) fn arb_cat() -> impl Strategy<Value = Cat> + Clone {
    prop_oneof![
        10 => (0..6usize).prop_map(Cat::Known),
        1 => Just(Cat::Unknown),
        1 => Just(Cat::Empty),
        1 => Just(Cat::Null),
        1 => Just(Cat::NonUtf8),
    ]
}

pub(crate) fn arb_mutation() -> impl Strategy<Value = Mutation> + Clone {
    prop_oneof![
        3 => Just(Mutation::None),
        2 => any::<Index>().prop_map(Mutation::Truncate),
        3 => (any::<Index>(), 0u8..8, any::<bool>())
            .prop_map(|(at, bit, fix)| Mutation::Flip { at, bit, fix }),
        3 => (any::<Index>(), special(), prop_oneof![3 => Just(true), 1 => Just(false)])
            .prop_map(|(at, value, fix)| Mutation::Overwrite { at, value, fix }),
        1 => prop::collection::vec(any::<u8>(), 1..32).prop_map(Mutation::Append),
        1 => Just(Mutation::ForeignGuid),
        1 => Just(Mutation::Zero),
    ]
}

pub(crate) fn arb_src() -> impl Strategy<Value = Src> + Clone {
    prop_oneof![
        4 => Just(Src::Current),
        4 => (0..POOL_LEN).prop_map(Src::Pool),
        2 => (0..N_SLOTS).prop_map(Src::Slot),
        1 => prop::collection::vec(any::<u8>(), 0..400).prop_map(Src::Random),
        1 => Just(Src::Empty),
    ]
}

pub(crate) fn deserialize_op() -> impl Strategy<Value = Op> + Clone {
    (
        arb_comp(),
        arb_src(),
        arb_mutation(),
        prop_oneof![
            8 => Just(Size::Exact),
            2 => any::<Index>().prop_map(Size::Less),
            1 => Just(Size::Zero),
            1 => Just(Size::Impossible),
        ],
        arb_ptr(),
        arb_state_out(),
    )
        .prop_map(|(comp, src, mutation, size, ptr, out)| Op::Deserialize {
            comp,
            src,
            mutation,
            size,
            ptr,
            out,
        })
}

pub(crate) fn init_op() -> impl Strategy<Value = Op> + Clone {
    let t = table();
    let inputs = prop_oneof![
        2 => Just(vec![]),
        3 => (0.0f64..=1.0, 0.8f64..1.2)
            .prop_map(move |(a, l)| vec![(t.activation, a), (t.length, t.length0 * l)]),
        1 => prop::collection::vec(vr_real(), 1..3),
    ];
    (
        prop::sample::select(vec![0.0, 0.0, 1.0, 1e6, -2.0]),
        prop_oneof![
            2 => Just(None),
            3 => prop::sample::select(vec![1e-3, 0.05, 0.2, 10.0]).prop_map(Some),
        ],
        inputs,
        init_integers(),
    )
        .prop_map(|(start, stop, inputs, integers)| Op::Init {
            start,
            stop: stop.map(|d: f64| start + d),
            integers,
            inputs,
        })
}

/// The Integer parameters of an `Init` ([`Subject::INIT_INTEGERS`]; draws
/// nothing when there are none).
pub(crate) fn init_integers() -> BoxedStrategy<Vec<(u32, i32)>> {
    match profile().init_integers {
        [] => Just(Vec::new()).boxed(),
        choices => Union::new_weighted(
            choices
                .iter()
                .map(|&(w, ints)| (w, Just(integer_refs(ints)).boxed()))
                .collect(),
        )
        .boxed(),
    }
}

/// A value reference and an Integer value for it: any `i32`, or with
/// [`Subject::INTEGER_SPAN`] mostly in-range (cheap) values of an Integer
/// variable and values just outside its range.
pub(crate) fn vr_int() -> BoxedStrategy<(u32, i32)> {
    let Some(span) = profile().integer_span else {
        return (arb_vr(), any::<i32>()).boxed();
    };
    arb_vr()
        .prop_flat_map(move |vr| {
            let values = if is_int(vr) {
                let (lo, hi) = int_range(vr);
                prop_oneof![
                    4 => lo..=hi.min(lo.saturating_add(span)),
                    1 => prop::sample::select(vec![
                        lo.saturating_sub(1),
                        hi.saturating_add(1),
                        0,
                        -1,
                        i32::MIN,
                        i32::MAX,
                    ]),
                    1 => any::<i32>(),
                ]
                .boxed()
            } else {
                any::<i32>().boxed()
            };
            (Just(vr), values)
        })
        .boxed()
}

pub(crate) fn run_op() -> impl Strategy<Value = Op> + Clone {
    (
        prop_oneof![3 => 1usize..20, 1 => 20usize..profile().long_run],
        prop_oneof![
            4 => prop::sample::select(vec![1e-4, 1e-3, 1e-2]),
            1 => prop::sample::select(vec![1e-6, 0.1, 0.5]),
            1 => 1e-5f64..0.05,
        ],
        prop_oneof![
            Just(Tc::Accumulated),
            Just(Tc::Multiplied),
            Just(Tc::Exact),
            (-3i32..=3).prop_map(Tc::Ulps),
        ],
        prop::sample::select(vec![0.0, 0.05, 0.3, 1.5]),
        prop::sample::select(vec![0.0, 0.5, 1.0, 1.5]),
    )
        .prop_map(|(n, h, tc, amp, act)| Op::Run { n, h, tc, amp, act })
}

pub(crate) fn op() -> BoxedStrategy<Op> {
    let c = |s: BoxedStrategy<Call>| s.prop_map(Op::Call).boxed();
    let setup = (arb_comp(), any::<bool>(), special(), experiment()).prop_map(
        |(comp, td, tol, (start, stop_def, stop))| Call::Setup {
            comp,
            tol_def: i32::from(td),
            tol,
            start,
            stop_def,
            stop,
        },
    );
    let simple = (arb_comp(), 0..6u8).prop_map(|(comp, k)| match k {
        0 => Call::Enter(comp),
        1 => Call::Exit(comp),
        2 | 3 => Call::Terminate(comp),
        4 => Call::Reset(comp),
        _ => Call::Cancel(comp),
    });
    let logging = (
        arb_comp(),
        prop::sample::select(vec![0, 1, 2, -1]),
        prop::collection::vec(arb_cat(), 0..4),
        arb_ptr(),
        arb_len(),
    )
        .prop_map(|(comp, on, cats, ptr, len)| Call::Logging {
            comp,
            on,
            cats,
            ptr,
            len,
        });
    let set_r = (
        arb_comp(),
        items(vr_real()),
        arb_ptr(),
        arb_ptr(),
        arb_len(),
    )
        .prop_map(|(comp, items, p0, p1, len)| {
            let (vrs, vals) = items.into_iter().unzip();
            Call::SetReal {
                comp,
                vrs,
                vals,
                ptrs: [p0, p1],
                len,
            }
        });
    let set_other = (
        arb_comp(),
        items(vr_int()),
        arb_ptr(),
        arb_ptr(),
        arb_len(),
        0..3u8,
    )
        .prop_map(|(comp, items, p0, p1, len, k)| {
            let (vrs, vals): (Vec<u32>, Vec<i32>) = items.into_iter().unzip();
            let ptrs = [p0, p1];
            match k {
                0 => Call::SetInteger {
                    comp,
                    vrs,
                    vals,
                    ptrs,
                    len,
                },
                1 => Call::SetBoolean {
                    comp,
                    vrs,
                    vals,
                    ptrs,
                    len,
                },
                _ => {
                    let vals = vals
                        .iter()
                        .map(|v| match v.rem_euclid(3) {
                            0 => Str::Null,
                            1 => Str::Text("a string"),
                            _ => Str::NonUtf8,
                        })
                        .collect();
                    Call::SetString {
                        comp,
                        vrs,
                        vals,
                        ptrs,
                        len,
                    }
                }
            }
        });
    let outputs = table().outputs.clone();
    let get = (
        arb_comp(),
        prop_oneof![
            6 => Just(Ty::Real),
            1 => Just(Ty::Integer),
            2 => Just(Ty::Boolean),
            1 => Just(Ty::String),
        ],
        prop_oneof![
            2 => Just(outputs),
            3 => items(arb_vr()),
        ],
        arb_ptr(),
        arb_ptr(),
        arb_len(),
    )
        .prop_map(|(comp, ty, vrs, p0, p1, len)| Call::Get {
            comp,
            ty,
            vrs,
            ptrs: [p0, p1],
            len,
        });
    let get_state =
        (arb_comp(), arb_state_out()).prop_map(|(comp, out)| Call::GetState { comp, out });
    let set_state = (arb_comp(), arb_state_in()).prop_map(|(comp, st)| Call::SetState { comp, st });
    let free_state =
        (arb_comp(), arb_state_out()).prop_map(|(comp, out)| Call::FreeState { comp, out });
    let size = (
        arb_comp(),
        arb_state_in(),
        prop_oneof![8 => Just(false), 1 => Just(true)],
    )
        .prop_map(|(comp, st, null)| Call::StateSize { comp, st, null });
    let serialize = (
        arb_comp(),
        arb_state_in(),
        prop_oneof![
            6 => Just(Buf::Exact),
            2 => any::<Index>().prop_map(Buf::Short),
            1 => Just(Buf::Zero),
            1 => (1usize..64).prop_map(Buf::Long),
            1 => Just(Buf::Null),
            1 => Just(Buf::Impossible),
        ],
    )
        .prop_map(|(comp, st, buf)| Op::Serialize { comp, st, buf });
    let dir = (
        arb_comp(),
        items(arb_vr()),
        prop::collection::vec(vr_real(), 0..3),
        [arb_ptr(), arb_ptr(), arb_ptr(), arb_ptr()],
        arb_len(),
    )
        .prop_map(|(comp, unknowns, knowns, ptrs, len)| {
            let (knowns, dv) = knowns.into_iter().unzip();
            Call::DirDeriv {
                comp,
                unknowns,
                knowns,
                dv,
                ptrs,
                len,
            }
        });
    let order = prop_oneof![6 => Just(1), 1 => Just(0), 1 => Just(2), 1 => any::<i32>()];
    let set_der = (
        arb_comp(),
        items((vr_real(), order.clone())),
        [arb_ptr(), arb_ptr(), arb_ptr()],
        arb_len(),
    )
        .prop_map(|(comp, items, ptrs, len)| {
            let mut vrs = Vec::new();
            let mut orders = Vec::new();
            let mut vals = Vec::new();
            for ((vr, v), o) in items {
                vrs.push(vr);
                orders.push(o);
                vals.push(v);
            }
            Call::SetInputDer {
                comp,
                vrs,
                orders,
                vals,
                ptrs,
                len,
            }
        });
    let get_der = (
        arb_comp(),
        items((arb_vr(), order)),
        [arb_ptr(), arb_ptr(), arb_ptr()],
        arb_len(),
    )
        .prop_map(|(comp, items, ptrs, len)| {
            let (vrs, orders) = items.into_iter().unzip();
            Call::GetOutputDer {
                comp,
                vrs,
                orders,
                ptrs,
                len,
            }
        });
    let step = (
        arb_comp(),
        arb_tc(),
        arb_h(),
        prop::sample::select(vec![0, 1, 2]),
    )
        .prop_map(|(comp, tc, h, flag)| Op::Step { comp, tc, h, flag });
    let status = (
        arb_comp(),
        prop::sample::select(vec![
            StatusFn::Status,
            StatusFn::Real,
            StatusFn::Integer,
            StatusFn::Boolean,
            StatusFn::String,
        ]),
        prop_oneof![8 => 0..4i32, 1 => Just(-1), 1 => Just(4), 1 => any::<i32>()],
        prop_oneof![8 => Just(false), 1 => Just(true)],
    )
        .prop_map(|(comp, func, kind, null)| Call::Status {
            comp,
            func,
            kind,
            null,
        });
    Union::new_weighted(vec![
        (10, init_op().boxed()),
        (8, run_op().boxed()),
        (10, step.boxed()),
        (3, (0..POOL_LEN).prop_map(Op::Restore).boxed()),
        (
            3,
            prop::sample::select(profile().discard_factors.to_vec())
                .prop_map(Op::DiscardRecover)
                .boxed(),
        ),
        (3, c(setup.boxed())),
        (10, c(simple.boxed())),
        (2, c(logging.boxed())),
        (8, c(set_r.boxed())),
        (3, c(set_other.boxed())),
        (8, c(get.boxed())),
        (5, c(get_state.boxed())),
        (5, c(set_state.boxed())),
        (3, c(free_state.boxed())),
        (2, c(size.boxed())),
        (3, serialize.boxed()),
        (4, deserialize_op().boxed()),
        (2, c(dir.boxed())),
        (3, c(set_der.boxed())),
        (1, c(get_der.boxed())),
        (3, c(status.boxed())),
    ])
    .boxed()
}
