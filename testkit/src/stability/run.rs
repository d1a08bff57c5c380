//! Running a cell and many cells (with a watchdog), and the acceptance criteria.

use super::*;

// ---------------------------------------------------------------------------
// Running a cell
// ---------------------------------------------------------------------------

/// What the watchdog sees of one worker thread: its signs of life on the
/// worker's own CPU-time clock, so that a loaded machine (or a stopped
/// process) does not pass for a hang.
pub struct Slot {
    /// The CPU-time clock of the thread running the cell (set when its
    /// [`Watch`] is made, on that thread).
    clock: Mutex<Option<libc::clockid_t>>,
    /// That thread's CPU time in milliseconds at its last sign of life.
    heartbeat: AtomicU64,
    busy: AtomicBool,
    key: Mutex<String>,
}

impl Slot {
    pub fn new() -> Arc<Slot> {
        Arc::new(Slot {
            clock: Mutex::new(None),
            heartbeat: AtomicU64::new(0),
            busy: AtomicBool::new(false),
            key: Mutex::new(String::new()),
        })
    }

    /// A sign of life; on the thread running the cell.
    fn beat(&self) {
        self.heartbeat
            .store(thread_cpu_time().as_millis() as u64, Ordering::Relaxed);
    }

    /// The calling thread runs the cell from now on.
    fn attach(&self) {
        let mut id: libc::clockid_t = 0;
        // SAFETY: `id` is a valid, writable clockid_t; pthread_self() is
        // the calling thread, alive for the call.
        let rc = unsafe { libc::pthread_getcpuclockid(libc::pthread_self(), &mut id) };
        *self.clock.lock().unwrap() = (rc == 0).then_some(id);
        self.beat();
    }

    /// The CPU time the worker has used since its last sign of life, if it
    /// is in a cell.
    fn silent_for(&self) -> Option<Duration> {
        if !self.busy.load(Ordering::Relaxed) {
            return None;
        }
        let now = cpu_time_of((*self.clock.lock().unwrap())?)?;
        let last = Duration::from_millis(self.heartbeat.load(Ordering::Relaxed));
        Some(now.saturating_sub(last))
    }
}

/// The time bound of one cell: [`CELL_TIME_LIMIT`] of CPU time of the
/// thread that creates the watch and runs the cell (so a cell's outcome does
/// not depend on what else the machine runs).
pub struct Watch {
    /// The thread's CPU time at which the cell runs out.
    deadline: std::cell::Cell<Duration>,
    limit: Duration,
    slot: Arc<Slot>,
}

impl Watch {
    /// The bound [`CELL_TIME_LIMIT`] from now, on the calling thread.
    pub fn new(slot: Arc<Slot>) -> Watch {
        Watch::with_limit(slot, CELL_TIME_LIMIT)
    }

    /// A bound of `limit` of the calling thread's CPU time from now.
    pub fn with_limit(slot: Arc<Slot>, limit: Duration) -> Watch {
        slot.attach();
        Watch {
            deadline: std::cell::Cell::new(thread_cpu_time() + limit),
            limit,
            slot,
        }
    }

    /// The bound counted again from now: what the harness spent preparing
    /// the cell (a unit's program) is not the model's.
    pub fn restart(&self) {
        self.deadline.set(thread_cpu_time() + self.limit);
        self.beat();
    }

    /// Whether the calling thread has used up the cell's CPU time.
    pub fn expired(&self) -> bool {
        thread_cpu_time() > self.deadline.get()
    }

    fn beat(&self) {
        self.slot.beat();
    }
}

/// The CPU time the calling thread has used (CLOCK_THREAD_CPUTIME_ID).
pub fn thread_cpu_time() -> Duration {
    cpu_time_of(libc::CLOCK_THREAD_CPUTIME_ID)
        .expect("clock_gettime(CLOCK_THREAD_CPUTIME_ID) failed")
}

/// The time of CPU-time clock `clock`; `None` when it cannot be read (a
/// thread that has ended).
fn cpu_time_of(clock: libc::clockid_t) -> Option<Duration> {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; an invalid clock id is
    // reported by the return code.
    let rc = unsafe { libc::clock_gettime(clock, &mut ts) };
    (rc == 0).then(|| Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32))
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Every step completed (some perhaps after a master retry).
    Completed,
    /// A step was discarded and no retry with up to [`MAX_RETRY_PIECES`]
    /// pieces completed it: the run ends at `t`.
    Discarded { t: f64, message: String },
    /// A call returned fmi2Error or fmi2Fatal (or the setup failed).
    Error { message: String },
    /// The cell's time bound (CPU time, [`Watch`]) passed.
    Timeout { t: f64 },
}

/// A discard the master met, and how it went on.
#[derive(Clone, Debug, PartialEq)]
pub struct Discard {
    pub t: f64,
    pub message: String,
    /// The retry that completed the step: the step cut into this many pieces.
    pub recovered_with: Option<usize>,
}

/// One run of a cell's program at one step size.
#[derive(Clone, Debug, Default)]
pub struct Run {
    pub outcome: Option<Outcome>,
    /// The model's Real outputs.
    pub names: Vec<&'static str>,
    pub steps: usize,
    pub discards: Vec<Discard>,
    /// The two compared outputs ([`Hooks::compared`]) at the cell's
    /// communication points 0..=n (recorded only for a comparison with a
    /// reference run).
    pub samples: Vec<[f64; 2]>,
    /// The scales of the compared outputs' deviations: sigma0 for a stress,
    /// F0 = sigma0 · area (the FMU's `area`) for `force`.
    pub scales: [f64; 2],
    pub nonfinite: Vec<String>,
    pub violations: Vec<String>,
    /// Steps with a bound violated / an output not finite.
    pub n_violations: usize,
    pub n_nonfinite: usize,
    /// Sum and maximum over the steps of the solver counts.
    pub iterations: Counts,
    pub ce_iterations: Counts,
    pub substeps: Counts,
    /// Largest active_stress / (fv_max sigma0 activation_level) met.
    pub max_active_ratio: f64,
    /// The run's wall time (its time bound counts CPU time, [`Watch`]).
    pub seconds: f64,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counts {
    pub sum: u64,
    pub max: u32,
    pub n: u64,
}

impl Counts {
    fn add(&mut self, x: Option<u32>) {
        if let Some(x) = x {
            self.sum += u64::from(x);
            self.max = self.max.max(x);
            self.n += 1;
        }
    }

    pub fn mean(&self) -> Option<f64> {
        (self.n > 0).then(|| self.sum as f64 / self.n as f64)
    }
}

/// Agreement of the coarse run with the run at h / [`FINE_FACTOR`] at the
/// coarse communication points both reached: the largest
/// |x − x_ref| / max(scale, |x_ref|) for the two compared outputs
/// ([`Hooks::compared`]: stress and active_stress of a muscle, force and
/// stress of a unit; the scale sigma0 for a stress, F0 = sigma0 · area for
/// a force), and the time it occurs. The fields are named after the
/// muscle's outputs: `stress` is the first compared output, `active` the
/// second.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Agreement {
    pub stress: f64,
    pub stress_t: f64,
    pub active: f64,
    pub active_t: f64,
    pub points: usize,
}

impl Agreement {
    pub fn worst(&self) -> f64 {
        self.stress.max(self.active)
    }

    pub fn within(&self) -> bool {
        self.worst() <= AGREEMENT_TOL
    }
}

/// The result of one cell.
#[derive(Clone, Debug)]
pub struct CellResult {
    pub model: &'static str,
    pub cell: Cell,
    pub max_input_rate: f64,
    pub coarse: Run,
    pub fine: Option<Run>,
    /// Why there is no reference run.
    pub fine_skipped: Option<String>,
    pub agreement: Option<Agreement>,
}

/// What a run needs besides its program: the hooks, the law of the
/// samples' checks, and a unit's path at each breakpoint of the program
/// (`None` for a muscle; `Err` when the harness cannot map it).
pub(crate) struct Checker<'a, M> {
    hooks: &'a Hooks<M>,
    params: Params,
    unit_paths: Result<Option<Vec<f64>>, String>,
}

/// Runs the program with `m` steps per communication step.
pub(crate) fn execute<M: Model>(
    cell: &Cell,
    prog: &Program,
    m: usize,
    checker: &Checker<M>,
    watch: &Watch,
    record: bool,
) -> Run {
    let started = Instant::now();
    let mut run = Run::default();
    let outcome = execute_inner(cell, prog, m, checker, watch, record, &mut run);
    run.outcome = Some(match outcome {
        Ok(o) => o,
        Err(message) => Outcome::Error { message },
    });
    run.seconds = started.elapsed().as_secs_f64();
    run
}

pub(crate) fn execute_inner<M: Model>(
    cell: &Cell,
    prog: &Program,
    m: usize,
    checker: &Checker<M>,
    watch: &Watch,
    record: bool,
    run: &mut Run,
) -> Result<Outcome, String> {
    let l0 = L0;
    let mut fmu = cell_fmu::<M>(cell, checker.hooks)?;
    // A unit's length input is its path: the path at each breakpoint of
    // the program, by the fibres' share (`unit`).
    let unit_paths = checker.unit_paths.clone()?;
    fmu.set_real("initial_activation", prog.initial_activation)?;
    let length0 = match &unit_paths {
        Some(paths) => paths[0],
        None => prog.stretch0 * l0,
    };
    fmu.set_inputs(prog.command0, length0)?;
    fmu.initialize()?;
    run.names = fmu.out_names.clone();
    let idx = |name: &str| {
        fmu.out_names
            .iter()
            .position(|n| *n == name)
            .ok_or_else(|| format!("the model has no output {name}"))
    };
    let [first, second] = checker.hooks.compared;
    let (i_stress, i_active) = (idx(first)?, idx(second)?);
    let sigma0 = checker.params.sigma0;
    for (scale, name) in run.scales.iter_mut().zip([first, second]) {
        *scale = if name == "force" {
            sigma0 * fmu.get_real("area")?
        } else {
            sigma0
        };
    }
    let mut out = Vec::new();
    fmu.outputs(&mut out)?;
    check_sample(&fmu, checker, &out, prog.stretch0, run, 0.0);
    if record {
        run.samples.push([out[i_stress], out[i_active]]);
    }
    let h = cell.h / m as f64;
    let n_total = prog.steps.len() * m;
    // The signal at fine step i (0-based), `frac` of the way through it:
    // the command, the stretch and the length (a muscle's stretch · L0; a
    // unit's path interpolated linearly between the program's breakpoints).
    let signal = |i: usize, frac: f64| -> (f64, f64, f64) {
        let n = i / m;
        let s = prog.steps[n];
        let from = if n == 0 {
            prog.stretch0
        } else {
            prog.steps[n - 1].stretch
        };
        let x = ((i % m) as f64 + frac) / m as f64;
        let stretch = if x >= 1.0 {
            s.stretch
        } else {
            from + (s.stretch - from) * x
        };
        let length = match &unit_paths {
            None => stretch * l0,
            Some(paths) if x >= 1.0 => paths[n + 1],
            Some(paths) => paths[n] + (paths[n + 1] - paths[n]) * x,
        };
        (s.command, stretch, length)
    };
    for i in 0..n_total {
        watch.beat();
        if i % 256 == 0 && watch.expired() {
            return Ok(Outcome::Timeout { t: i as f64 * h });
        }
        let t = i as f64 * h;
        let (u, stretch, length) = signal(i, 1.0);
        fmu.save()?;
        fmu.set_inputs(u, length)?;
        let (st, msg) = fmu.step(t, h);
        match st {
            fmi2OK => {}
            fmi2Discard => {
                let last = fmu.last_successful_time()?;
                if last != t {
                    return Err(format!(
                        "after a discard at t = {t}: fmi2LastSuccessfulTime = {last}"
                    ));
                }
                let mut recovered = None;
                let mut pieces = 2;
                while pieces <= MAX_RETRY_PIECES {
                    fmu.restore()?;
                    let mut ok = true;
                    for k in 0..pieces {
                        // Every FMI call is a sign of life, and the cell's
                        // time bound holds inside a retry too.
                        watch.beat();
                        if watch.expired() {
                            return Ok(Outcome::Timeout { t });
                        }
                        let (u, _, length) = signal(i, (k + 1) as f64 / pieces as f64);
                        fmu.set_inputs(u, length)?;
                        let hp = h / pieces as f64;
                        let (st, _) = fmu.step(t + k as f64 * hp, hp);
                        if st != fmi2OK {
                            ok = false;
                            break;
                        }
                    }
                    if ok {
                        recovered = Some(pieces);
                        break;
                    }
                    pieces *= 2;
                }
                run.discards.push(Discard {
                    t,
                    message: msg.clone(),
                    recovered_with: recovered,
                });
                if recovered.is_none() {
                    fmu.restore()?;
                    return Ok(Outcome::Discarded { t, message: msg });
                }
            }
            other => {
                return Ok(Outcome::Error {
                    message: format!("fmi2DoStep at t = {t}: {}: {msg}", status_name(other)),
                })
            }
        }
        run.steps += 1;
        let s = fmu.stats(checker.hooks.stats);
        run.iterations.add(s.iterations);
        run.ce_iterations.add(s.ce_iterations);
        run.substeps.add(s.substeps);
        fmu.outputs(&mut out)?;
        check_sample(&fmu, checker, &out, stretch, run, t + h);
        if record && (i + 1) % m == 0 {
            run.samples.push([out[i_stress], out[i_active]]);
        }
    }
    Ok(Outcome::Completed)
}

/// An instance of `M` set up for `cell`, before initialization: the
/// hooks' Integer and Boolean parameters, the cell's law, L0 and, for a
/// unit, its tendon slack length.
pub(crate) fn cell_fmu<M: Model>(cell: &Cell, hooks: &Hooks<M>) -> Result<Fmu<M>, String> {
    let mut fmu = Fmu::<M>::new("stability")?;
    for (name, v) in hooks.integers {
        fmu.set_integer(name, *v)?;
    }
    for (name, v) in hooks.booleans {
        fmu.set_boolean(name, *v)?;
    }
    for (id, v) in cell.settings() {
        fmu.set_real(Params::info(id).name, v)?;
    }
    fmu.set_real("L0", L0)?;
    if let Some(lts) = hooks.tendon_slack_length {
        fmu.set_real("tendon_slack_length", lts)?;
    }
    Ok(fmu)
}

pub(crate) fn check_sample<M: Model>(
    fmu: &Fmu<M>,
    checker: &Checker<M>,
    out: &[f64],
    stretch: f64,
    run: &mut Run,
    t: f64,
) {
    let bad: Vec<String> = fmu
        .out_names
        .iter()
        .zip(out)
        .filter(|(_, v)| !v.is_finite())
        .map(|(n, v)| format!("{n} = {v}"))
        .collect();
    if !bad.is_empty() {
        run.n_nonfinite += 1;
        if run.nonfinite.len() < 3 {
            run.nonfinite.push(format!("t = {t:e}: {}", bad.join(", ")));
        }
        return;
    }
    let sample = Sample {
        names: &fmu.out_names,
        values: out,
        stretch,
        params: &checker.params,
    };
    if let Err(e) = (checker.hooks.bounds)(&sample) {
        run.n_violations += 1;
        if run.violations.len() < 3 {
            run.violations.push(format!("t = {t:e}: {e}"));
        }
    }
    if let (Some(a), Some(active)) = (sample.get("activation_level"), sample.get("active_stress")) {
        let max = checker.params.fv_max() * checker.params.sigma0 * a;
        if max > 0.0 {
            run.max_active_ratio = run.max_active_ratio.max(active / max);
        }
    }
}

/// Runs one cell: the program at h, and at h / [`FINE_FACTOR`] when affordable.
pub fn run_cell<M: Model>(cell: &Cell, watch: &Watch, hooks: &Hooks<M>) -> CellResult {
    run_cell_named(std::any::type_name::<M>(), cell, watch, hooks)
}

/// [`run_cell`] under another model name (one model type in two settings).
pub fn run_cell_named<M: Model>(
    name: &'static str,
    cell: &Cell,
    watch: &Watch,
    hooks: &Hooks<M>,
) -> CellResult {
    let prog = program_of(cell, hooks);
    let checker = Checker {
        hooks,
        params: cell.law(),
        unit_paths: unit_breakpoints(cell, hooks, &prog),
    };
    // The bound counts the model's runs: a unit's program and paths are the
    // harness's (for the FE unit, tens of initializations of its own).
    watch.restart();
    let fine_steps = prog.steps.len() * FINE_FACTOR;
    let affordable = fine_steps <= hooks.fine_budget;
    let mut coarse = execute::<M>(cell, &prog, 1, &checker, watch, affordable);
    let (mut fine, fine_skipped) = if !affordable {
        (
            None,
            Some(format!(
                "not affordable: {fine_steps} steps > {}",
                hooks.fine_budget
            )),
        )
    } else if matches!(coarse.outcome, Some(Outcome::Timeout { .. })) {
        (None, Some("the coarse run timed out".into()))
    } else {
        (
            Some(execute::<M>(
                cell,
                &prog,
                FINE_FACTOR,
                &checker,
                watch,
                true,
            )),
            None,
        )
    };
    // A reference run cut by the cell's time bound is not affordable
    // either: no comparison (its steps up to the cut are still checked).
    let (agreement, fine_skipped) = match fine.as_ref().and_then(|f| f.outcome.as_ref()) {
        Some(Outcome::Timeout { t }) => (
            None,
            Some(format!(
                "the reference run exceeded the cell's time bound at t = {t}"
            )),
        ),
        _ => (
            fine.as_ref().map(|f| agreement(&coarse, f, cell.h)),
            fine_skipped,
        ),
    };
    // The samples have served; a matrix keeps thousands of results
    // (`STABILITY_KEEP_SAMPLES` keeps them, for looking into one cell).
    if std::env::var_os("STABILITY_KEEP_SAMPLES").is_none() {
        coarse.samples = Vec::new();
        if let Some(f) = fine.as_mut() {
            f.samples = Vec::new();
        }
    }
    CellResult {
        model: short_name(name),
        cell: *cell,
        max_input_rate: prog.max_rate(cell.h),
        coarse,
        fine,
        fine_skipped,
        agreement,
    }
}

pub(crate) fn short_name(type_name: &'static str) -> &'static str {
    type_name.rsplit("::").next().unwrap_or(type_name)
}

pub(crate) fn agreement(coarse: &Run, fine: &Run, h: f64) -> Agreement {
    let mut a = Agreement {
        points: coarse.samples.len().min(fine.samples.len()),
        ..Agreement::default()
    };
    for (i, (c, f)) in coarse.samples.iter().zip(&fine.samples).enumerate() {
        let t = i as f64 * h;
        for (k, err, at) in [
            (0, &mut a.stress, &mut a.stress_t),
            (1, &mut a.active, &mut a.active_t),
        ] {
            let e = (c[k] - f[k]).abs() / coarse.scales[k].max(f[k].abs());
            // NaN counts as the worst (it cannot occur with finite outputs).
            if e > *err || e.is_nan() {
                *err = if e.is_nan() { f64::INFINITY } else { e };
                *at = t;
            }
        }
    }
    a
}

// ---------------------------------------------------------------------------
// Running many cells
// ---------------------------------------------------------------------------

/// Runs `jobs` (an index into `entries` and a cell) on `threads` worker
/// threads, results in job order. A watchdog thread ends the process (exit
/// code 3), naming the cell, when a worker shows no sign of life for
/// [`HANG_LIMIT`] of its CPU time: one FMI call that does not return. `progress` prints a
/// line every 5 % to stderr.
pub fn run_jobs(
    entries: &[ModelEntry],
    jobs: &[(usize, Cell)],
    threads: usize,
    progress: bool,
) -> Vec<CellResult> {
    let threads = threads.max(1);
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let finished = AtomicBool::new(false);
    let results: Mutex<Vec<Option<CellResult>>> = Mutex::new(vec![None; jobs.len()]);
    let slots: Vec<Arc<Slot>> = (0..threads).map(|_| Slot::new()).collect();
    let started = Instant::now();
    std::thread::scope(|scope| {
        scope.spawn(|| {
            while !finished.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(200));
                for slot in &slots {
                    if slot.silent_for().is_some_and(|d| d > HANG_LIMIT) {
                        eprintln!(
                            "stability: HANG: no progress for {HANG_LIMIT:?} in cell {}",
                            slot.key.lock().unwrap()
                        );
                        std::process::exit(3);
                    }
                }
            }
        });
        let workers: Vec<_> = slots
            .iter()
            .map(|slot| {
                let (next, done, results) = (&next, &done, &results);
                scope.spawn(move || loop {
                    let j = next.fetch_add(1, Ordering::Relaxed);
                    let Some((e, cell)) = jobs.get(j) else {
                        break;
                    };
                    let entry = &entries[*e];
                    *slot.key.lock().unwrap() = format!("{} {}", entry.name, cell.key());
                    let watch = Watch::new(slot.clone());
                    slot.busy.store(true, Ordering::Relaxed);
                    let mut r = (entry.run)(cell, &watch);
                    slot.busy.store(false, Ordering::Relaxed);
                    r.model = entry.name;
                    results.lock().unwrap()[j] = Some(r);
                    let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                    if progress && (n * 20 / jobs.len() != (n - 1) * 20 / jobs.len()) {
                        eprintln!(
                            "stability: {n}/{} cells, {:.0} s",
                            jobs.len(),
                            started.elapsed().as_secs_f64()
                        );
                    }
                })
            })
            .collect();
        for w in workers {
            if w.join().is_err() {
                finished.store(true, Ordering::Relaxed);
                panic!("a worker panicked (a panic escaped the FMI layer?)");
            }
        }
        finished.store(true, Ordering::Relaxed);
    });
    results
        .into_inner()
        .unwrap()
        .into_iter()
        .map(|r| r.expect("every job ran"))
        .collect()
}

/// Worker threads: `STABILITY_THREADS`, else the available parallelism.
pub fn threads() -> usize {
    std::env::var("STABILITY_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

// ---------------------------------------------------------------------------
// Acceptance
// ---------------------------------------------------------------------------

/// The explanation of a discard, from its message (the FMU's discard
/// messages name their cause); `None`: not explained. A model that joins the
/// matrix adds the causes its own messages name.
pub fn explain(message: &str) -> Option<&'static str> {
    const CAUSES: [(&str, &str); 7] = [
        (
            "past the tendon's rupture strain",
            "a musculotendon unit's path that needs its tendon past its rupture strain \
             (2.5 tendon_strain_at_F0, Butler et al. 1978): the unit refuses it with fmi2Discard, its state \
             unchanged; the capped programs stay short of it (`unit`)",
        ),
        (
            "the volume change",
            "the law's own limit with a soft volumetric term: with a large D (bulk modulus 2/D) against \
             the active and matrix stresses, the lateral equilibrium lets J run away until the matrix \
             term c exp(b (I1bar - 3)) overflows; a smaller D keeps J near 1",
        ),
        (
            "outside the range the law",
            "the input length lies outside the stretches at which the matrix term c exp(b (I1bar - 3)) \
             is finite",
        ),
        (
            "non-positive length",
            "the series kinematics would give the contractile element a non-positive length \
             ((1 + k) fibre_stretch - k see_stretch <= 0)",
        ),
        (
            "non-finite partial derivative",
            "a step so short that the partial derivatives of the step map overflow",
        ),
        (
            "length at the end of the step",
            "length + h dlength/dt is not a positive length",
        ),
        (
            "did not converge, even in",
            "the FE muscle's implicit quasi-static solve (Newton's method, continuation in the step's \
             inputs, up to 64 substeps, within its work budget) could not take the step's input change — \
             a length jump, the compression of the slender clamped specimen towards stretch 0.3, an \
             activation jump with S h >> 1 at the kink of f_v, mostly at D <= 1e-9 — and refused it \
             with fmi2Discard, its state unchanged (the discard contract of \
             docs/reference/bad-input.md); the message names the last \
             failure, and the master's retry in smaller pieces completes most such steps",
        ),
    ];
    CAUSES
        .iter()
        .find(|(pattern, _)| message.contains(pattern))
        .map(|(_, why)| *why)
}

/// The acceptance criteria of issue 4 §1 a cell fails (empty: it passes): no
/// error (a crash would end the process, a caught panic is fmi2Fatal, an
/// error), no timeout of the run at h, no non-finite output, no completed
/// step outside the model's bounds, every discard explained — in the run at
/// h and in the reference run (up to where the time bound cut it: a
/// reference run is made where affordable).
pub fn acceptance(r: &CellResult) -> Vec<String> {
    let mut fails = Vec::new();
    for (what, run, reference) in
        std::iter::once(("h", &r.coarse, false)).chain(r.fine.as_ref().map(|f| ("h/100", f, true)))
    {
        match &run.outcome {
            Some(Outcome::Error { message }) => fails.push(format!("{what}: error: {message}")),
            // The reference run is made where affordable; one the time bound
            // cuts is not (`CellResult::fine_skipped` says so), and the
            // bound itself holds.
            Some(Outcome::Timeout { .. }) if reference => {}
            Some(Outcome::Timeout { t }) => fails.push(format!("{what}: timeout at t = {t}")),
            None => fails.push(format!("{what}: no outcome")),
            _ => {}
        }
        if run.n_nonfinite > 0 {
            fails.push(format!("{what}: non-finite outputs: {:?}", run.nonfinite));
        }
        if run.n_violations > 0 {
            fails.push(format!("{what}: bounds: {:?}", run.violations));
        }
        for d in &run.discards {
            if explain(&d.message).is_none() {
                fails.push(format!(
                    "{what}: unexplained discard at t = {}: {}",
                    d.t, d.message
                ));
            }
        }
    }
    fails
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The watchdog measures a worker's silence in the worker's CPU time:
    /// a worker that sleeps (a loaded machine, a stopped process) is not
    /// silent, one that computes without a sign of life is. Read from
    /// another thread, as the watchdog does.
    #[test]
    fn the_watchdog_counts_the_workers_cpu_time() {
        let slot = Slot::new();
        let (attached, slept, spun) = (
            std::sync::Barrier::new(2),
            std::sync::Barrier::new(2),
            std::sync::Barrier::new(2),
        );
        std::thread::scope(|scope| {
            scope.spawn(|| {
                let _watch = Watch::new(slot.clone());
                slot.busy.store(true, Ordering::Relaxed);
                attached.wait();
                std::thread::sleep(Duration::from_millis(300));
                slept.wait();
                let start = thread_cpu_time();
                while thread_cpu_time() - start < Duration::from_millis(300) {
                    std::hint::black_box(start);
                }
                spun.wait();
                spun.wait();
            });
            attached.wait();
            slept.wait();
            let after_sleep = slot.silent_for().expect("busy");
            assert!(after_sleep < Duration::from_millis(100), "{after_sleep:?}");
            spun.wait();
            let after_spin = slot.silent_for().expect("busy");
            assert!(after_spin >= Duration::from_millis(250), "{after_spin:?}");
            spun.wait();
        });
    }
}
