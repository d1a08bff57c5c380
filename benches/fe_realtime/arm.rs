//! The coupled arm's workload of `fe_realtime`: the calls
//! `examples/arm_mujoco.py --model fe --scheme implicit` (H = 10 ms, the
//! flex-and-hold controller, 1 s) makes of `HillMuscleFE`, recorded once with
//! its `--trace` option into `benches/data/arm_fe_implicit.csv` and replayed
//! open loop: per communication step fmi2SetReal (length, activation),
//! fmi2SetRealInputDerivatives (length, order 1), fmi2DoStep, fmi2GetReal
//! (force), fmi2GetDirectionalDerivative (force; length) and fmi2GetReal
//! (force, activation level, fibre stretch), all timed ([`cabi`]); and the
//! same step map in-process ([`in_process`]), with the work of each step and
//! of its derivative counted, and the factorisations attempted by kind.

use std::ffi::{c_int, c_uint};
use std::time::Instant;

use hill_muscle::fe::assembly::Attempts;
use hill_muscle::fe::mesh::{FibreLayout, Resolution, LUMPED_GRADING};
use hill_muscle::fe::step_map::{
    discretization, end_length, rate_step, Committed, LastStep, Quantity, StepLevel, Substepped,
};
use hill_muscle::law::activation::Decay;
use hill_muscle::law::Params;
use testkit::cabi::{Api, Instance};

use crate::vr_of;

/// The committed trace, relative to the repository's top level.
const TRACE: &str = "benches/data/arm_fe_implicit.csv";

/// One communication step of the trace: what the master set and got.
#[derive(Clone, Copy, Debug)]
pub struct Row {
    pub t: f64,
    pub length: f64,
    pub der_length: f64,
    pub activation: f64,
    pub force: f64,
    pub dforce_dlength: f64,
}

/// The recorded run: H, the initial inputs, the Real parameters set before
/// initialization, the steps.
pub struct Trace {
    pub h: f64,
    pub length0: f64,
    pub params: Vec<(String, f64)>,
    pub rows: Vec<Row>,
}

/// Read the committed trace (its format: `write_trace` of
/// examples/arm_mujoco.py).
pub fn load() -> Trace {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join(TRACE))
        .unwrap_or_else(|e| panic!("{TRACE}: {e} (examples/arm_mujoco.py --trace writes it)"));
    let (mut h, mut length0, mut params, mut rows) = (f64::NAN, f64::NAN, Vec::new(), Vec::new());
    let number = |s: &str| -> f64 { s.trim().parse().expect("a number in the trace") };
    for line in text.lines() {
        if let Some(comment) = line.strip_prefix("# ") {
            if let Some(v) = comment.strip_prefix("H = ") {
                h = number(v);
            } else if let Some(v) = comment.strip_prefix("initial length = ") {
                length0 = number(v);
            } else if let Some(v) = comment.strip_prefix("parameter ") {
                let (name, value) = v.split_once(" = ").expect("parameter NAME = VALUE");
                params.push((name.to_string(), number(value)));
            } else {
                assert!(
                    !comment.starts_with("integer "),
                    "the replay sets Real parameters only"
                );
            }
        } else if !line.starts_with('t') && !line.is_empty() {
            let v: Vec<f64> = line.split(',').map(number).collect();
            rows.push(Row {
                t: v[0],
                length: v[1],
                der_length: v[2],
                activation: v[3],
                force: v[4],
                dforce_dlength: v[5],
            });
        }
    }
    assert!(
        h > 0.0 && length0 > 0.0 && !rows.is_empty(),
        "{TRACE}: incomplete"
    );
    Trace {
        h,
        length0,
        params,
        rows,
    }
}

/// One replay through the C ABI.
pub struct Replayed {
    /// Wall time of each communication step's calls [s].
    pub times: Vec<f64>,
    /// Of which fmi2GetDirectionalDerivative [s].
    pub derivative: Vec<f64>,
    /// `newton_iterations` after each step (read outside the timed calls).
    pub solves: Vec<i32>,
    /// The force and d force / d length at the end.
    pub force: f64,
    pub stiffness: f64,
    /// Largest |force − recorded force| over the steps [N].
    pub force_deviation: f64,
    /// Largest |K − recorded K| / |recorded K| of d force / d length.
    pub stiffness_deviation: f64,
}

/// Replay `trace` through the C ABI of `api` on the mesh settings `mesh`
/// (empty: the default mesh; panics on a non-OK status).
pub fn cabi(api: &Api, mesh: &[(c_uint, i32)], trace: &Trace) -> Replayed {
    let mut settings: Vec<(c_uint, f64)> =
        trace.params.iter().map(|(n, v)| (vr_of(n), *v)).collect();
    settings.push((vr_of("length"), trace.length0));
    settings.push((vr_of("activation"), 0.0));
    let instance = Instance::with_settings(api, &api.guid, &settings, mesh, &[]);
    let c = instance.c;
    let (length, activation, force) = (vr_of("length"), vr_of("activation"), vr_of("force"));
    let outs = [force, vr_of("activation_level"), vr_of("fibre_stretch")];
    let solves_vr = vr_of("newton_iterations");
    let n = trace.rows.len();
    let mut out = Replayed {
        times: Vec::with_capacity(n),
        derivative: Vec::with_capacity(n),
        solves: Vec::with_capacity(n),
        force: f64::NAN,
        stiffness: f64::NAN,
        force_deviation: 0.0,
        stiffness_deviation: 0.0,
    };
    let ins = [length, activation];
    let order: c_int = 1;
    let one = 1.0;
    for r in &trace.rows {
        let (mut f, mut k, mut o) = (0.0, 0.0, [0.0; 3]);
        let t0 = Instant::now();
        let (s, td) = unsafe {
            let s1 = (api.set_real)(c, ins.as_ptr(), 2, [r.length, r.activation].as_ptr());
            let s2 = (api.set_real_input_derivatives)(c, &length, 1, &order, &r.der_length);
            let s3 = (api.do_step)(c, r.t, trace.h, 1);
            let s4 = (api.get_real)(c, &force, 1, &mut f);
            let td = Instant::now();
            let s5 = (api.get_directional_derivative)(c, &force, 1, &length, 1, &one, &mut k);
            let td = td.elapsed().as_secs_f64();
            let s6 = (api.get_real)(c, outs.as_ptr(), 3, o.as_mut_ptr());
            ([s1, s2, s3, s4, s5, s6], td)
        };
        out.times.push(t0.elapsed().as_secs_f64());
        assert!(s.iter().all(|&s| s == 0), "t = {}: statuses {s:?}", r.t);
        out.derivative.push(td);
        out.solves.push(instance.integer(solves_vr));
        out.force_deviation = out.force_deviation.max((f - r.force).abs());
        let dk = (k - r.dforce_dlength).abs() / r.dforce_dlength.abs();
        out.stiffness_deviation = out.stiffness_deviation.max(dk);
        (out.force, out.stiffness) = (f, k);
    }
    out
}

/// One step of the in-process replay: wall time of the step and of its
/// derivative [s], the step's linear solves, residual evaluations and
/// factorisations (every attempt: the discretization's ledger), its
/// substeps, and the solves and factorisations of the attempts that
/// converged (what the step reports).
#[derive(Clone, Copy, Debug)]
pub struct Work {
    pub step: f64,
    pub derivative: f64,
    pub solves: usize,
    pub residuals: usize,
    pub factorizations: usize,
    pub substeps: usize,
    pub converged: (usize, usize),
}

/// The FMU's step map on the trace in-process (its defaults: activation
/// dynamics on, no substep control; the parameters `L0`, `area`,
/// `initial_activation` of the trace): each step's [`Work`], the force and
/// d force / d length at the end, and the factorisations the steps and
/// their derivatives attempted (the initialization's not included).
pub fn in_process(trace: &Trace, mesh: Resolution) -> (Vec<Work>, f64, f64, Attempts) {
    let p = Params::default();
    let param = |name: &str, default: f64| {
        trace
            .params
            .iter()
            .find(|(n, _)| n == name)
            .map_or(default, |(_, v)| *v)
    };
    for (name, _) in &trace.params {
        assert!(
            ["L0", "area", "initial_activation"].contains(&name.as_str()),
            "in-process replay: parameter {name} not supported"
        );
    }
    let (l0, area) = (param("L0", f64::NAN), param("area", f64::NAN));
    let a_init = param("initial_activation", 0.0);
    let d =
        discretization(None, l0, area, mesh, LUMPED_GRADING, FibreLayout::Axial).expect("the mesh");
    let mut state = Committed::initialize(d, &p, area, trace.length0, a_init, 0.0)
        .expect("the arm's initial equilibrium")
        .state;
    let initialization = state.muscle.disc.pattern.attempts();
    let decay = Decay::new(p.s, trace.h).value;
    let mut a = a_init;
    let (mut work, mut force, mut stiffness) = (Vec::new(), f64::NAN, f64::NAN);
    for r in &trace.rows {
        let level = StepLevel::new(true, p.s, a, r.activation, 0.0, trace.h, decay);
        let end = end_length(r.length, r.der_length, trace.h, &p, l0).expect("an end length");
        // Committed::step without substep control, its counts kept.
        let before = state.muscle.disc.work.work();
        let t0 = Instant::now();
        let adv = state
            .muscle
            .advance(&p, end, trace.h, &|tau| level.at(tau))
            .expect("the arm's step");
        let all = adv.muscle.disc.work.work() - before;
        let substepped = (adv.substeps > 1).then(|| Substepped {
            before: state.muscle.clone(),
            level,
            end_length: end,
            pieces: adv.pieces.clone(),
        });
        let last = LastStep {
            start: adv.start.clone(),
            h: rate_step(adv.rate),
            activation: level.end,
            da_du: level.d_end_du,
        };
        force = adv.muscle.disc.reaction(&adv.solution.evaluation.forces);
        let next = Committed::new(adv.muscle, last, substepped);
        let step = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        stiffness = next
            .partial(Quantity::Force, true, &p, l0, area)
            .expect("d force / d length");
        let derivative = t1.elapsed().as_secs_f64();
        work.push(Work {
            step,
            derivative,
            solves: all.solves,
            residuals: all.residuals,
            factorizations: all.factorizations,
            substeps: adv.substeps,
            converged: (adv.iterations, adv.factorizations),
        });
        a = level.end;
        state = next;
    }
    let a = state.muscle.disc.pattern.attempts();
    let attempts = Attempts {
        single: a.single - initialization.single,
        cholesky: a.cholesky - initialization.cholesky,
        cholesky_skipped: a.cholesky_skipped - initialization.cholesky_skipped,
        lblt: a.lblt - initialization.lblt,
        lblt_unused: a.lblt_unused - initialization.lblt_unused,
        lu: a.lu - initialization.lu,
    };
    (work, force, stiffness, attempts)
}
