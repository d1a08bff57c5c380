//! Per-step cost of each shipped scene's FMU against the full FMU on the same
//! inputs, through the C ABI (issue 6).
//!
//! Loads `dist/<id>.fmu` (build them first with `scripts/build_fmus.sh`) with
//! dlopen. Per scene: its workload (the inputs it has; the full FMU gets the
//! same values, its other inputs left at their start values), per step
//! fmi2SetReal(the scene's inputs) + fmi2DoStep + fmi2GetReal(the scene's
//! outputs) on both FMUs, runs interleaved (scene, full, scene, …) so that
//! both see the same machine load; median of `REPEATS`. Also: the binary's
//! size and the modelDescription's variable count. Both FMUs' outputs are
//! checked to agree (to 1e-12 relative) on every run.
//!
//! `cargo bench --bench scene_step` — prints a Markdown table and one JSON
//! line per scene. `SCENE_BENCH_QUICK=1` runs 20x fewer steps;
//! `SCENE_BENCH_ONLY=<id>` only that scene's row;
//! `SCENE_BENCH_PROFILE_MODEL=<id>` only that scene's model, in-process,
//! for perf.

use std::ffi::c_uint;
use std::io::Read;
use std::time::Instant;

use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hill1d::{Hill1DModel, DEFAULT_L0};
use hill_muscle::scene::shipped::*;
use hill_muscle::scene::Scene;

use cabi::{load, median, Api, Instance};
use testkit::cabi;

const REPEATS: usize = 7;
const H: f64 = 1e-4;

/// One FMU of the comparison: its binary, GUID, and value references.
struct Side {
    api: Api,
    guid: String,
    inputs: Vec<c_uint>,
    outputs: Vec<c_uint>,
}

fn vr<M: Model>(name: &str) -> c_uint {
    M::variables()
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}")) as c_uint
}

fn side<M: Model>(id: &str, inputs: &[&str], outputs: &[&str]) -> Side {
    Side {
        api: load(id),
        guid: guid::<M>(),
        inputs: inputs.iter().map(|n| vr::<M>(n)).collect(),
        outputs: outputs.iter().map(|n| vr::<M>(n)).collect(),
    }
}

/// ns per step and the outputs' sum over the run.
fn time(s: &Side, steps: usize, inputs: &dyn Fn(f64, &mut [f64])) -> (f64, Vec<f64>) {
    let instance = Instance::new(&s.api, &s.guid);
    let mut out = vec![0.0; s.outputs.len()];
    let mut sum = vec![0.0; s.outputs.len()];
    let mut values = vec![0.0; s.inputs.len()];
    let start = Instant::now();
    for i in 0..steps {
        inputs((i + 1) as f64 * H, &mut values);
        instance.step(&s.inputs, &values, i as f64 * H, H, &s.outputs, &mut out);
        for (a, b) in sum.iter_mut().zip(&out) {
            *a += b;
        }
    }
    (start.elapsed().as_nanos() as f64 / steps as f64, sum)
}

/// ns per step of model `M` alone, in-process (the law and the model's
/// bookkeeping: no FMI layer, no dynamic call), on the same loop.
fn time_model<M: Model>(
    inputs_names: &[&str],
    outputs: &[&str],
    steps: usize,
    inputs: &dyn Fn(f64, &mut [f64]),
) -> f64 {
    let vars = M::variables();
    let id = |n: &str| vars.iter().find(|v| v.name == n).unwrap().id;
    let ins: Vec<M::Var> = inputs_names.iter().map(|n| id(n)).collect();
    let outs: Vec<M::Var> = outputs.iter().map(|n| id(n)).collect();
    let mut m = M::new();
    m.initialize().unwrap();
    let mut values = vec![0.0; ins.len()];
    let mut sum = 0.0;
    let start = Instant::now();
    for i in 0..steps {
        inputs((i + 1) as f64 * H, &mut values);
        for (&v, &x) in ins.iter().zip(&values) {
            m.set_real(v, x).unwrap();
        }
        m.do_step(i as f64 * H, H).unwrap();
        for &o in &outs {
            sum += m.get_real(o);
        }
    }
    std::hint::black_box(sum);
    start.elapsed().as_nanos() as f64 / steps as f64
}

/// Size of the binary inside `dist/<id>.fmu`.
fn binary_size(id: &str) -> u64 {
    let f = std::fs::File::open(format!("{}/dist/{id}.fmu", env!("CARGO_MANIFEST_DIR"))).unwrap();
    let mut zip = zip::ZipArchive::new(f).unwrap();
    let mut e = zip.by_name(&format!("binaries/linux64/{id}.so")).unwrap();
    let mut v = Vec::new();
    e.read_to_end(&mut v).unwrap();
    v.len() as u64
}

struct Row {
    id: &'static str,
    workload: &'static str,
    size: u64,
    n_vars: usize,
    scene_ns: f64,
    full_ns: f64,
    full_id: &'static str,
    ratios: Vec<f64>,
    /// The models alone (median ns/step of scene and full, median ratio).
    model: (f64, f64, f64),
}

fn compare<S: Scene, F: Model>(
    full_id: &'static str,
    workload: &'static str,
    steps: usize,
    inputs: &dyn Fn(f64, &mut [f64]),
) -> Row
where
    Hill1DModel<S>: Model,
{
    compare_models::<Hill1DModel<S>, F>(
        S::SPEC.model_identifier,
        S::SPEC.inputs_names(),
        S::SPEC.outputs,
        full_id,
        workload,
        steps,
        inputs,
    )
}

trait InputNames {
    fn inputs_names(&self) -> &'static [&'static str];
}

impl InputNames for hill_muscle::scene::SceneSpec {
    fn inputs_names(&self) -> &'static [&'static str] {
        match (self.inputs.activation, self.inputs.length) {
            (true, true) => &["activation", "length"],
            (true, false) => &["activation"],
            (false, true) => &["length"],
            (false, false) => &[],
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn compare_models<M: Model, F: Model>(
    id: &'static str,
    inputs_names: &[&str],
    outputs: &[&str],
    full_id: &'static str,
    workload: &'static str,
    steps: usize,
    inputs: &dyn Fn(f64, &mut [f64]),
) -> Row {
    // The full FMU has no `stiffness` output: it reads force in its place
    // (the same number of values through fmi2GetReal).
    // fmi2GetReal reads the Real outputs (not newton_iterations).
    let vars = M::variables();
    let outputs: Vec<&str> = outputs
        .iter()
        .copied()
        .filter(|o| {
            vars.iter()
                .any(|v| v.name == *o && matches!(v.ty, hill_muscle::fmi2::VarType::Real { .. }))
        })
        .collect();
    let outputs = outputs.as_slice();
    let full_outputs: Vec<&str> = outputs
        .iter()
        .map(|&o| if o == "stiffness" { "force" } else { o })
        .collect();
    let only = std::env::var("SCENE_BENCH_ONLY").ok();
    // Profiling one scene's model in-process (perf): only that.
    if std::env::var("SCENE_BENCH_PROFILE_MODEL").ok().as_deref() == Some(id) {
        for _ in 0..20 {
            std::hint::black_box(time_model::<M>(inputs_names, outputs, steps, inputs));
        }
        std::process::exit(0);
    }
    if only.as_deref().is_some_and(|o| o != id) {
        return Row {
            id,
            workload,
            size: 0,
            n_vars: 0,
            scene_ns: f64::NAN,
            full_ns: f64::NAN,
            full_id,
            ratios: vec![f64::NAN],
            model: (f64::NAN, f64::NAN, f64::NAN),
        };
    }
    let scene = side::<M>(id, inputs_names, outputs);
    let full = side::<F>(full_id, inputs_names, &full_outputs);
    let (mut a, mut b, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
    let (mut ma, mut mb, mut mr) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..REPEATS {
        {
            let x = time_model::<M>(inputs_names, outputs, steps, inputs);
            let y = time_model::<F>(inputs_names, &full_outputs, steps, inputs);
            ma.push(x);
            mb.push(y);
            mr.push(y / x);
        }
        let (ts, ss) = time(&scene, steps, inputs);
        let (tf, sf) = time(&full, steps, inputs);
        for ((x, y), name) in ss.iter().zip(&sf).zip(outputs) {
            if *name != "stiffness" {
                assert!(
                    (x - y).abs() <= 1e-12 * y.abs().max(1e-300),
                    "{id}: {name} sums {x} vs full {y}"
                );
            }
        }
        a.push(ts);
        b.push(tf);
        ratios.push(tf / ts);
    }
    Row {
        id,
        workload,
        size: binary_size(id),
        n_vars: M::variables().len(),
        scene_ns: median(a),
        full_ns: median(b),
        full_id,
        ratios,
        model: (median(ma), median(mb), median(mr)),
    }
}

fn main() {
    let quick = std::env::var_os("SCENE_BENCH_QUICK").is_some();
    let n = if quick { 10_000 } else { 200_000 };
    let l0 = DEFAULT_L0;
    let cycle = |t: f64| l0 * (1.0 + 0.1 * (2.0 * std::f64::consts::PI * 2.0 * t).sin());
    let mut rows = Vec::new();
    type Full1D = Hill1DModel<HillMuscle1D>;
    rows.push(compare::<HillMuscle1D, Full1D>(
        "HillMuscle1D",
        "u = 1, length ±10 % at 2 Hz",
        n,
        &|t, v| v.copy_from_slice(&[1.0, cycle(t)]),
    ));
    rows.push(compare::<HillPassive1D, Full1D>(
        "HillMuscle1D",
        "passive (u = 0), length ±10 % at 2 Hz",
        n,
        &|t, v| v[0] = cycle(t),
    ));
    rows.push(compare::<HillActivated1D, Full1D>(
        "HillMuscle1D",
        "u = 1, length ±10 % at 2 Hz",
        n,
        &|t, v| v.copy_from_slice(&[1.0, cycle(t)]),
    ));
    rows.push(compare::<HillIsometric1D, Full1D>(
        "HillMuscle1D",
        "u = 1 at L0",
        n,
        &|_, v| v[0] = 1.0,
    ));
    rows.push(compare::<HillActuator1D, Full1D>(
        "HillMuscle1D",
        "u = 1, length ±10 % at 2 Hz",
        n,
        &|t, v| v.copy_from_slice(&[1.0, cycle(t)]),
    ));
    #[cfg(feature = "fe")]
    {
        use hill_muscle::fmus::hillfe::HillFEModel;
        type FullFE = HillFEModel<HillMuscleFE>;
        // h = 1e-4 on the FE muscle: a few hundred steps per run.
        let m = if quick { 10 } else { 60 };
        let fe_in = |t: f64| l0 * (1.0 + 0.1 * (2.0 * std::f64::consts::PI * 2.0 * t).sin());
        rows.push(compare_models::<HillFEModel<HillPassiveFE>, FullFE>(
            "HillPassiveFE",
            HillPassiveFE::SPEC.inputs_names(),
            HillPassiveFE::SPEC.outputs,
            "HillMuscleFE",
            "passive, length ±10 % at 2 Hz",
            m,
            &|t, v| v[0] = fe_in(t),
        ));
        rows.push(compare_models::<HillFEModel<HillActivatedFE>, FullFE>(
            "HillActivatedFE",
            HillActivatedFE::SPEC.inputs_names(),
            HillActivatedFE::SPEC.outputs,
            "HillMuscleFE",
            "u = 1, length ±10 % at 2 Hz",
            m,
            &|t, v| v.copy_from_slice(&[1.0, fe_in(t)]),
        ));
    }
    println!(
        "h = {H} s, {n} steps per run (FE: see the rows), median of {REPEATS} interleaved runs"
    );
    println!();
    println!("| scene | workload | binary (bytes) | variables | C ABI: scene ns/step | full ns/step | full / scene (median; range) | model alone: scene / full ns, ratio |");
    println!("|---|---|---|---|---|---|---|---|");
    for r in &rows {
        let mut rs = r.ratios.clone();
        rs.sort_by(|a, b| a.partial_cmp(b).unwrap());
        println!(
            "| {} | {} | {} | {} | {:.1} | {:.1} ({}) | {:.2} ({:.2}–{:.2}) | {:.1} / {:.1}, {:.2} |",
            r.id,
            r.workload,
            r.size,
            r.n_vars,
            r.scene_ns,
            r.full_ns,
            r.full_id,
            median(r.ratios.clone()),
            rs[0],
            rs[rs.len() - 1],
            r.model.0,
            r.model.1,
            r.model.2
        );
    }
    for r in &rows {
        println!(
            "{{\"bench\":\"scene_step\",\"scene\":\"{}\",\"binary_bytes\":{},\"variables\":{},\"scene_ns\":{:.1},\"full_ns\":{:.1},\"ratio\":{:.3},\"model_ratio\":{:.3}}}",
            r.id, r.size, r.n_vars, r.scene_ns, r.full_ns, median(r.ratios.clone()), r.model.2
        );
    }
}
