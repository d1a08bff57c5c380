//! Per-step cost of `HillMusculotendonFE` against `HillMuscleFE` through the
//! C ABI, on the default (lumped, 16 × 3) mesh:
//! `cargo bench --bench musculotendon_fe_step [-- --runs N] [--only NAME] [--in-process]`.
//!
//! Loads the binaries of `dist/HillMuscleFE.fmu` and
//! `dist/HillMusculotendonFE.fmu` (or `$HM_DIST/…`, an older build; build
//! them with `scripts/build_fmus.sh --fmu HillMuscleFE` and `--fmu
//! HillMusculotendonFE`) and times, per communication step,
//! fmi2SetReal(activation, length) + fmi2DoStep + fmi2GetReal(force), the
//! two models alternating run by run. Workloads (`benches/fe_realtime.rs`'s
//! and docs/work-precision.md's), each at h = 1 ms and 10 ms:
//!
//! - `passive`: activation 0, pulled from L0 at 5 mm/s for 2 s;
//! - `activated`: command 1, held at L0 for 0.5 s, then pulled at 5 mm/s
//!   (2.5 s);
//! - `stretch-release`: command 0, then 1 from t = 0.2 s; L0 → 1.1 L0 over
//!   the first second and back over the second.
//!
//! `HillMuscleFE` runs at its defaults with the workload's length as its
//! input. The unit gets the same muscle (L0 and area set to
//! `HillMuscleFE`'s, so the same mesh and law) and the tendon at the
//! parameter table's defaults (L_TS = 5 cm, ε0 = 0.04, no pennation), and
//! its path is chosen so that its fibres follow the same length history:
//! ℓ_k = L_k + L_TS (1 + ε(F_k)), F_k the force of `HillMuscleFE` at the end
//! of step k (run in-process first) and ε(F) the tendon's strain at that
//! force. Each trial of the unit's equilibrium is then the FE step the
//! muscle takes, and the root is that step's end length.
//!
//! Reported per workload and h: mean and median wall time per step of each
//! model (median over the runs), the ratio unit / muscle (median of the
//! per-run ratios, range in brackets), and, in-process on the same inputs,
//! the wall time of each model's fmi2DoStep per step (not deterministic: a
//! ratio of the same run), the FE Newton solves (linear solves), tangent
//! factorisations and residual evaluations per step of each (the muscle's
//! from its step map run beside it, [`Shadow`]), the unit's equilibrium
//! trials (FE step maps) per step, its distribution, and the force at the
//! end (the muscle's and the unit's tendon force: equal to the
//! equilibrium's tolerance). `--in-process` prints only the counts (no
//! FMU needed); `--only NAME` runs one workload; `--runs N` (default 3).

use std::ffi::c_uint;
use std::time::Instant;

use hill_muscle::fe::mesh::FibreLayout;
use hill_muscle::fe::step_map::{discretization, Committed, StepLevel};
use hill_muscle::fe::work::Work as WorkCount;
use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hillfe::{HillFE, DEFAULT_GRADING, DEFAULT_MESH};
use hill_muscle::fmus::musculotendonfe::MusculotendonFe;
use hill_muscle::law::activation::Decay;
use hill_muscle::law::params::{TendonParamId, TENDON_PARAMETERS};
use hill_muscle::law::tendon::Tendon;
use hill_muscle::specimen::{LENGTH as L0, MEAN_AREA};

use cabi::{load, median, Api, Instance};
use testkit::cabi;

/// The pulls' speed [m/s].
const SPEED: f64 = 0.005;

/// A workload's inputs at the end of a step ending at `t` (the step
/// starting at `t0`): the activation command and the muscle length.
type Inputs = fn(f64, f64) -> (f64, f64);

fn passive(_t0: f64, t: f64) -> (f64, f64) {
    (0.0, L0 + SPEED * t)
}

fn activated(_t0: f64, t: f64) -> (f64, f64) {
    (1.0, L0 + SPEED * (t - 0.5).max(0.0))
}

fn stretch_release(_t0: f64, t: f64) -> (f64, f64) {
    let u = if t >= 0.2 { 1.0 } else { 0.0 };
    let up = t.min(2.0 - t).clamp(0.0, 1.0);
    (u, L0 * (1.0 + 0.1 * up))
}

const WORKLOADS: [(&str, Inputs, f64); 3] = [
    ("passive", passive as Inputs, 2.0),
    ("activated", activated as Inputs, 2.5),
    ("stretch-release", stretch_release as Inputs, 2.0),
];

const STEPS: [f64; 2] = [1e-3, 1e-2];

fn vr<M: Model>(name: &str) -> c_uint {
    M::variables()
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}")) as c_uint
}

fn id<M: Model>(name: &str) -> M::Var {
    M::variables()
        .into_iter()
        .find(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}"))
        .id
}

/// The tendon parameters' defaults (the table's).
fn tendon_default(p: TendonParamId) -> f64 {
    TENDON_PARAMETERS[p as usize].default
}

/// The unit's Real parameters: `HillMuscleFE`'s muscle, the default tendon.
fn unit_parameters() -> Vec<(&'static str, f64)> {
    let mut v = vec![("L0", L0), ("area", MEAN_AREA)];
    v.extend(TENDON_PARAMETERS.iter().map(|i| (i.name, i.default)));
    v
}

/// FE work per step, averaged over a run: Newton solves (linear solves),
/// tangents factorised, residuals evaluated, every attempt counted (the
/// discretization's ledger, [`hill_muscle::fe::work`]).
#[derive(Clone, Copy, Default)]
struct Work {
    solves: f64,
    factorizations: f64,
    residuals: f64,
}

impl Work {
    fn add(&mut self, solves: usize, factorizations: usize, residuals: usize) {
        self.solves += solves as f64;
        self.factorizations += factorizations as f64;
        self.residuals += residuals as f64;
    }

    fn per(self, n: usize) -> Work {
        let n = n as f64;
        Work {
            solves: self.solves / n,
            factorizations: self.factorizations / n,
            residuals: self.residuals / n,
        }
    }
}

/// One workload's inputs at step size `h`: per step the command, the
/// muscle's length and the unit's path, with the muscle's in-process
/// work per step and its force at the end.
struct Drive {
    steps: Vec<(f64, f64, f64)>,
    work: Work,
    force: f64,
    /// In-process wall time of its fmi2DoStep calls, per step [s].
    time: f64,
}

/// `HillMuscleFE`'s step map outside the FMU, to count its factorisations
/// and residuals: [`Committed::step`] as its fmi2DoStep takes it (default
/// mesh and law, activation level from the command), checked against the
/// model's force bit for bit every step.
struct Shadow {
    state: Committed,
    params: hill_muscle::law::Params,
    dynamics: bool,
    decay: Option<Decay>,
}

impl Shadow {
    fn new(dynamics: bool) -> Shadow {
        let params = hill_muscle::law::Params::default();
        let disc = discretization(
            None,
            L0,
            MEAN_AREA,
            DEFAULT_MESH,
            DEFAULT_GRADING,
            FibreLayout::Axial,
        )
        .expect("the default mesh");
        let da_du = if dynamics { 0.0 } else { 1.0 };
        let st = Committed::initialize(disc, &params, MEAN_AREA, L0, 0.0, da_du)
            .expect("HillMuscleFE's initialization");
        Shadow {
            state: st.state,
            params,
            dynamics,
            decay: None,
        }
    }

    /// The step to length `l` under command `u`: its force, its linear
    /// solves as the step reports them (the FMU's `newton_iterations`), and
    /// its work, every attempt counted (the discretization's ledger).
    fn step(&mut self, u: f64, l: f64, h: f64) -> (f64, usize, WorkCount) {
        let p = &self.params;
        let decay = Decay::for_step(self.decay, p.s, h);
        let level = StepLevel::new(
            self.dynamics,
            p.s,
            self.state.last.activation,
            u,
            0.0,
            h,
            decay.value,
        );
        let before = self.state.muscle.disc.work.work();
        let st = self
            .state
            .step(p, MEAN_AREA, level, l, None)
            .expect("the workload's step");
        let all = st.state.muscle.disc.work.work() - before;
        self.decay = Some(decay);
        self.state = st.state;
        let force = st.outputs[hill_muscle::fe::step_map::Quantity::Force as usize];
        (force, st.iterations, all)
    }
}

/// `HillMuscleFE` in-process on `inputs`: the drive of both models.
fn drive(inputs: Inputs, h: f64, duration: f64) -> Drive {
    let sigma0 = hill_muscle::law::Params::default().sigma0;
    let tendon = Tendon {
        slack_length: tendon_default(TendonParamId::TendonSlackLength),
        strain_at_f0: tendon_default(TendonParamId::TendonStrainAtF0),
        f0: sigma0 * MEAN_AREA,
    };
    let mut m = HillFE::new();
    m.initialize().expect("HillMuscleFE initializes");
    let (activation, length) = (id::<HillFE>("activation"), id::<HillFE>("length"));
    let (force, solves) = (id::<HillFE>("force"), id::<HillFE>("newton_iterations"));
    let mut shadow = Shadow::new(m.get_boolean(id::<HillFE>("activation_dynamics")));
    let n = (duration / h).round() as usize;
    let (mut steps, mut work, mut f) = (Vec::with_capacity(n), Work::default(), 0.0);
    let mut time = 0.0;
    for i in 0..n {
        let (u, l) = inputs(i as f64 * h, (i + 1) as f64 * h);
        m.set_real(activation, u).unwrap();
        m.set_real(length, l).unwrap();
        let t = Instant::now();
        m.do_step(i as f64 * h, h).expect("the workload's step");
        time += t.elapsed().as_secs_f64();
        f = m.get_real(force);
        let (fs, reported, all) = shadow.step(u, l, h);
        assert_eq!(fs, f, "the shadow step map is HillMuscleFE's");
        assert_eq!(reported as i32, m.get_integer(solves));
        work.add(all.solves, all.factorizations, all.residuals);
        let lt = if f > 0.0 {
            tendon.slack_length * (1.0 + tendon.strain_at(f))
        } else {
            tendon.slack_length
        };
        steps.push((u, l, l + lt));
    }
    Drive {
        steps,
        work: work.per(n),
        force: f,
        time: time / n as f64,
    }
}

/// The unit in-process on the drive: FE work and trials per step, the
/// steps by their trials (1, 2, 3, more), the tendon force at the end and
/// the largest |fibre length − the muscle's length|, and the in-process
/// wall time of its fmi2DoStep calls per step [s].
fn unit_counts(d: &Drive, h: f64) -> (Work, f64, [usize; 4], f64, f64, f64) {
    let mut m = MusculotendonFe::new();
    for (name, v) in unit_parameters() {
        m.set_real(id::<MusculotendonFe>(name), v).unwrap();
    }
    m.initialize().expect("the unit initializes");
    let (activation, length) = (
        id::<MusculotendonFe>("activation"),
        id::<MusculotendonFe>("length"),
    );
    let (force, fibre) = (
        id::<MusculotendonFe>("force"),
        id::<MusculotendonFe>("fibre_length"),
    );
    let (mut work, mut trials, mut by, mut dev) = (Work::default(), 0u64, [0usize; 4], 0.0f64);
    let mut time = 0.0;
    for (i, &(u, l, path)) in d.steps.iter().enumerate() {
        m.set_real(activation, u).unwrap();
        m.set_real(length, path).unwrap();
        let ledger = |m: &MusculotendonFe| {
            m.unit()
                .expect("the unit is initialized")
                .muscle
                .muscle
                .disc
                .work
                .work()
        };
        let before = ledger(&m);
        let t = Instant::now();
        m.do_step(i as f64 * h, h).expect("the unit's step");
        time += t.elapsed().as_secs_f64();
        let (_, t) = m.last_step_work();
        let all = ledger(&m) - before;
        work.add(all.solves, all.factorizations, all.residuals);
        trials += u64::from(t);
        by[(t as usize).clamp(1, 4) - 1] += 1;
        dev = dev.max((m.get_real(fibre) - l).abs());
    }
    let n = d.steps.len();
    (
        work.per(n),
        trials as f64 / n as f64,
        by,
        m.get_real(force),
        dev,
        time / n as f64,
    )
}

/// One C ABI run: wall time per step [s] and the force at the end.
fn run(api: &Api, unit: bool, d: &Drive, h: f64) -> (Vec<f64>, f64) {
    let (instance, ins, outs) = if unit {
        let params: Vec<(c_uint, f64)> = unit_parameters()
            .into_iter()
            .map(|(n, v)| (vr::<MusculotendonFe>(n), v))
            .collect();
        (
            Instance::with_parameters(api, &guid::<MusculotendonFe>(), &params),
            [
                vr::<MusculotendonFe>("activation"),
                vr::<MusculotendonFe>("length"),
            ],
            [vr::<MusculotendonFe>("force")],
        )
    } else {
        (
            Instance::new(api, &guid::<HillFE>()),
            [vr::<HillFE>("activation"), vr::<HillFE>("length")],
            [vr::<HillFE>("force")],
        )
    };
    let mut times = Vec::with_capacity(d.steps.len());
    let mut out = [0.0];
    for (i, &(u, l, path)) in d.steps.iter().enumerate() {
        let x = if unit { path } else { l };
        let t = Instant::now();
        instance.step(&ins, &[u, x], i as f64 * h, h, &outs, &mut out);
        times.push(t.elapsed().as_secs_f64());
    }
    (times, out[0])
}

/// Mean and median of per-step times [s].
fn mean_median(times: &[f64]) -> (f64, f64) {
    (
        times.iter().sum::<f64>() / times.len() as f64,
        median(times.to_vec()),
    )
}

/// The median of `v`, with its range.
fn with_range(v: &[f64]) -> String {
    let lo = v.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = v.iter().cloned().fold(0.0, f64::max);
    format!("{:.2} ({lo:.2}–{hi:.2})", median(v.to_vec()))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let runs: usize = value("--runs").map_or(3, |v| v.parse().expect("--runs N"));
    let only = value("--only");
    let in_process = args.iter().any(|a| a == "--in-process");
    let apis = (!in_process).then(|| (load("HillMuscleFE"), load("HillMusculotendonFE")));
    if apis.is_some() {
        println!(
            "HillMusculotendonFE against HillMuscleFE through the C ABI, default mesh; \
             {runs} runs alternating the models; ms per step, median over the runs"
        );
        println!();
        println!("| workload | h (ms) | muscle mean | muscle median | unit mean | unit median | ratio of means (range) | ratio of medians (range) |");
        println!("|---|---|---|---|---|---|---|---|");
    }
    let mut counts = Vec::new();
    for (name, inputs, duration) in WORKLOADS {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        for h in STEPS {
            let d = drive(inputs, h, duration);
            let (w, trials, by, unit_force, dev, time) = unit_counts(&d, h);
            let solves = w.solves;
            counts.push(format!(
                "| {name} | {} | {:.3}; {:.3} ({:.2}×) | {:.3}; {solves:.3} ({:.2}×) | {:.3}; {:.3} ({:.2}×) | {:.2}; {:.2} ({:.2}×) | {trials:.3} | {}/{}/{}/{} | {:.9}; {unit_force:.9} | {dev:.1e} |",
                h * 1e3,
                d.time * 1e3,
                time * 1e3,
                time / d.time,
                d.work.solves,
                solves / d.work.solves,
                d.work.factorizations,
                w.factorizations,
                w.factorizations / d.work.factorizations,
                d.work.residuals,
                w.residuals,
                w.residuals / d.work.residuals,
                by[0],
                by[1],
                by[2],
                by[3],
                d.force,
            ));
            let Some((plain, unit)) = &apis else {
                continue;
            };
            let (mut pm, mut pd, mut um, mut ud) = (vec![], vec![], vec![], vec![]);
            let (mut rm, mut rd) = (vec![], vec![]);
            for _ in 0..runs {
                let (tp, fp) = run(plain, false, &d, h);
                let (tu, fu) = run(unit, true, &d, h);
                assert_eq!(fp, d.force, "{name}: C ABI and in-process muscle differ");
                assert_eq!(fu, unit_force, "{name}: C ABI and in-process unit differ");
                let ((a, b), (c, e)) = (mean_median(&tp), mean_median(&tu));
                pm.push(a);
                pd.push(b);
                um.push(c);
                ud.push(e);
                rm.push(c / a);
                rd.push(e / b);
            }
            println!(
                "| {name} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {} | {} |",
                h * 1e3,
                median(pm) * 1e3,
                median(pd) * 1e3,
                median(um) * 1e3,
                median(ud) * 1e3,
                with_range(&rm),
                with_range(&rd),
            );
            println!(
                "{{\"bench\":\"musculotendon_fe_step\",\"workload\":\"{name}\",\"h\":{h},\"ratio_mean\":{:.3},\"ratio_median\":{:.3},\"solves\":[{:.3},{solves:.3}],\"trials\":{trials:.3}}}",
                median(rm),
                median(rd),
                d.work.solves,
            );
        }
    }
    println!();
    println!("Work per step, in-process on the same inputs (deterministic but the times)");
    println!();
    println!("| workload | h (ms) | ms/step in-process, muscle; unit (ratio) | FE solves/step, muscle; unit (ratio) | factorisations/step, muscle; unit (ratio) | residuals/step, muscle; unit (ratio) | trials/step | steps by trials 1/2/3/more | force at the end, muscle; unit (N) | largest fibre length − muscle length (m) |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for row in counts {
        println!("{row}");
    }
}
