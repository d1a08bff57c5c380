//! The property tests: random call sequences, corrupt FMU states,
//! instantiation arguments.

use super::*;

/// Runs `test` on `cases` cases of `strategy` (what `proptest!` does, as a
/// function the test crates can call).
pub(crate) fn run_cases<T: Strategy>(
    cases: u32,
    strategy: &T,
    test: impl Fn(T::Value) -> Result<(), TestCaseError>,
) {
    let mut runner = TestRunner::new(config(cases));
    if let Err(e) = runner.run(strategy, test) {
        panic!("{e}\n{runner}");
    }
}

/// The main property: random call sequences with random arguments
/// (module docs, properties 1–6). The cases run in two halves on two
/// threads, so that the longest test of a crate does not hold one core
/// while the other idles: the first half is the first cases of the fixed
/// seed ([`config`]), the second the cases of the seed's successor.
pub fn random_call_sequences() {
    let n = cases(1, 1);
    let halves = [(n - n / 2, 0), (n / 2, 1)];
    let results: Vec<Result<(), String>> = std::thread::scope(|scope| {
        let runs: Vec<_> = halves
            .iter()
            .filter(|(cases, _)| *cases > 0)
            .map(|&(cases, k)| scope.spawn(move || random_call_sequences_with(cases, k)))
            .collect();
        runs.into_iter()
            .map(|r| r.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    print_stats("random_call_sequences");
    for r in results {
        if let Err(e) = r {
            panic!("{e}");
        }
    }
}

/// `cases` random call sequences from the fixed seed plus `k`.
fn random_call_sequences_with(cases: u32, k: u64) -> Result<(), String> {
    let mut cfg = config(cases);
    if let RngSeed::Fixed(seed) = cfg.rng_seed {
        cfg.rng_seed = RngSeed::Fixed(seed.wrapping_add(k));
    }
    let mut runner = TestRunner::new(cfg);
    let strategy = (
        prop_oneof![3 => Just(false), 1 => Just(true)],
        prop::collection::vec(op(), 1..48),
    );
    runner
        .run(&strategy, |(logging_on, ops)| {
            run_sequence(logging_on, &ops).map_err(TestCaseError::fail)
        })
        .map_err(|e| format!("{e} (seed + {k})"))
}

/// FMU states: random, corrupt, truncated and padded buffers with right
/// and wrong sizes, restored and stepped from, in random states.
pub fn corrupt_fmu_states() {
    let (num, den) = profile().corrupt_cases;
    let strategy = (
        prop::collection::vec(
            prop_oneof![init_op(), run_op(), (0..POOL_LEN).prop_map(Op::Restore)],
            0..3,
        ),
        prop::collection::vec(deserialize_op(), 1..4),
        prop::collection::vec(op(), 0..6),
    );
    run_cases(cases(num, den), &strategy, |(prefix, des, tail)| {
        let mut ops = prefix;
        for d in des {
            let out = match &d {
                Op::Deserialize { out, .. } => *out,
                _ => unreachable!(),
            };
            ops.push(d);
            if let StateOut::Slot(k) = out {
                ops.push(Op::Call(Call::SetState {
                    comp: Comp::Valid,
                    st: StateIn::Slot(k),
                }));
                ops.push(Op::Step {
                    comp: Comp::Valid,
                    tc: Tc::Exact,
                    h: H::Lit(1e-3),
                    flag: 0,
                });
                ops.push(Op::Call(get(Ty::Real, table().outputs.clone())));
            }
        }
        ops.extend(tail);
        run_sequence(false, &ops).map_err(TestCaseError::fail)
    });
}

/// `fmi2Instantiate`'s arguments.
#[derive(Clone, Debug)]
pub(crate) struct InstArgs {
    pub(crate) name: Option<Vec<u8>>,
    pub(crate) fmu_type: i32,
    pub(crate) guid: Option<Vec<u8>>,
    pub(crate) resource: Option<Vec<u8>>,
    /// 0: NULL callbacks, 1: no logger, 2: the test logger.
    pub(crate) callbacks: u8,
    pub(crate) visible: i32,
    pub(crate) logging_on: i32,
}

pub(crate) fn c_string_bytes() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(1u8..=255, 0..24)
}

pub(crate) fn inst_args() -> impl Strategy<Value = InstArgs> {
    let g = (installed().guid)().into_bytes();
    let name = prop_oneof![
        1 => Just(None),
        1 => prop::sample::select(vec![
            b"".to_vec(),
            b" \t ".to_vec(),
            b"muscle #3 (left) %d%s".to_vec(),
            vec![0xff, 0xfe, b'x'],
            vec![b'x'; 5000],
        ]).prop_map(Some),
        4 => Just(Some(b"abuse".to_vec())),
        1 => c_string_bytes().prop_map(Some),
    ];
    let guid = prop_oneof![
        4 => Just(Some(g.clone())),
        1 => Just(None),
        1 => prop::sample::select(vec![
            b"".to_vec(),
            b"{00000000-0000-0000-0000-000000000000}".to_vec(),
            [g.as_slice(), b" "].concat(),
            g.to_ascii_lowercase(),
            g[..g.len() - 1].to_vec(),
        ]).prop_map(Some),
        1 => c_string_bytes().prop_map(Some),
    ];
    let resource = prop_oneof![
        Just(None),
        prop::sample::select(vec![
            b"file:///".to_vec(),
            b"file:///tmp/muscle/resources".to_vec(),
            b"file:////srv/share/resources/".to_vec(),
            b"file:///C:/fmu%20dir/resources/".to_vec(),
            b"".to_vec(),
            b"http://example.invalid/".to_vec(),
        ])
        .prop_map(Some),
        c_string_bytes().prop_map(Some),
    ];
    (
        name,
        prop_oneof![6 => Just(fmi2CoSimulation), 1 => Just(fmi2ModelExchange), 1 => any::<i32>()],
        guid,
        resource,
        prop_oneof![1 => Just(0u8), 1 => Just(1u8), 4 => Just(2u8)],
        prop::sample::select(vec![0, 1, 2, -1]),
        prop::sample::select(vec![0, 1, 2, -1]),
    )
        .prop_map(
            move |(name, fmu_type, guid, resource, callbacks, visible, logging_on)| InstArgs {
                name,
                fmu_type,
                guid,
                resource,
                callbacks,
                visible,
                logging_on,
            },
        )
}

pub(crate) fn check_instantiate(a: &InstArgs) -> Result<(), String> {
    let cs = |b: &Option<Vec<u8>>| b.as_ref().map(|b| CString::new(b.clone()).unwrap());
    let (name, g, res) = (cs(&a.name), cs(&a.guid), cs(&a.resource));
    let p = |s: &Option<CString>| s.as_ref().map_or(null(), |s| s.as_ptr());
    let book = Box::new(LogBook::default());
    let mut cb = callbacks(&book);
    if a.callbacks == 1 {
        cb.logger = None;
    }
    let cbp: *const fmi2CallbackFunctions = if a.callbacks == 0 { null() } else { &cb };
    let c = unsafe {
        (abi().instantiate)(
            p(&name),
            a.fmu_type,
            p(&g),
            p(&res),
            cbp,
            a.visible,
            a.logging_on,
        )
    };
    let logs = book.take();
    let name_ok = a
        .name
        .as_ref()
        .is_some_and(|n| !String::from_utf8_lossy(n).trim().is_empty());
    let should = name_ok
        && a.fmu_type == fmi2CoSimulation
        && a.guid.as_deref() == Some((installed().guid)().as_bytes());
    let logger = a.callbacks == 2;
    let given_name = a.name.clone().unwrap_or_default();
    for e in &logs {
        ensure!(e.format == "%s", "format {:?}", e.format);
        ensure!(!e.message.contains('#'), "'#' in {:?}", e.message);
        ensure!(
            e.instance == given_name,
            "logged as {:?}, given {:?}",
            String::from_utf8_lossy(&e.instance),
            String::from_utf8_lossy(&given_name)
        );
    }
    if c.is_null() {
        ensure!(!should, "fmi2Instantiate refused valid arguments: {logs:?}");
        if logger {
            ensure!(
                logs.iter()
                    .any(|e| e.status == fmi2Error && e.message.starts_with("fmi2Instantiate: ")),
                "fmi2Instantiate returned NULL without an error message: {logs:?}"
            );
        }
        ensure!(logs.is_empty() || logger, "logged without a logger");
        return Ok(());
    }
    ensure!(should, "fmi2Instantiate accepted invalid arguments");
    ensure!(
        !logger || logs.iter().any(|e| e.status == fmi2OK) == (a.logging_on != 0),
        "loggingOn = {}: debug messages {logs:?}",
        a.logging_on
    );
    // A legal life.
    let r = (|| unsafe {
        let ok = |s: fmi2Status, what: &str| -> Result<(), String> {
            ensure!(s == fmi2OK, "{what}: {s:?}");
            Ok(())
        };
        ok((abi().setup_experiment)(c, 1, 1e-4, 0.0, 1, 1.0), "setup")?;
        ok((abi().enter_initialization_mode)(c), "enter")?;
        set_integers(c, profile().cheap_integers)?;
        ok((abi().exit_initialization_mode)(c), "exit")?;
        ok((abi().do_step)(c, 0.0, 1e-3, 1), "step")?;
        let o = table().outputs.clone();
        let mut v = vec![0.0; o.len()];
        ok(
            (abi().get_real)(c, o.as_ptr(), o.len(), v.as_mut_ptr()),
            "get",
        )?;
        ensure!(v.iter().all(|x| x.is_finite()), "outputs {v:?}");
        ok((abi().terminate)(c), "terminate")?;
        ok((abi().reset)(c), "reset")?;
        Ok(())
    })();
    let logs = book.take();
    unsafe { (abi().free_instance)(c) };
    r?;
    for e in &logs {
        ensure!(e.instance == given_name, "instance name in {e:?}");
    }
    Ok(())
}

/// `fmi2Instantiate` with random arguments: NULL exactly when an argument
/// is invalid, with an error message when there is a logger; otherwise a
/// working instance that logs under the given name.
pub fn instantiate_arguments() {
    let (num, den) = profile().instantiate_cases;
    run_cases(cases(num, den), &inst_args(), |a| {
        check_instantiate(&a).map_err(TestCaseError::fail)
    });
}
