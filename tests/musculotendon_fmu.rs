//! `HillMusculotendon1D` through its FMI 2.0 C functions (`fmi2::api`, the
//! functions its binary exports): the equilibrium of tendon and muscle after
//! every step, read from the outputs; a rigid tendon without pennation is
//! `HillMuscle1D` at length ℓ − L_TS; directional derivatives against finite
//! differences of the step map; state save/restore and serialization; bad
//! values of the unit's parameters; a slack tendon; a path jump; the largest
//! pennation angle (MODEL_NOTES "Musculotendon unit"). The last tests run
//! `HillMusculotendonFE` (on a 6 × 1 mesh) the same way.

use std::ffi::CString;
use std::marker::PhantomData;

use hill_muscle::fmi2::api;
use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::types::*;
use hill_muscle::fmi2::{Causality, Model, VarType};
use hill_muscle::fmus::hill1d::Hill1D;
use hill_muscle::fmus::musculotendon1d::Musculotendon;
use hill_muscle::law::tendon::Tendon;
use testkit::logger::{callbacks, LogBook};

/// An instance of model `M` driven through the C functions.
struct Fmu<M: Model> {
    c: fmi2Component,
    book: Box<LogBook>,
    _m: PhantomData<M>,
}

impl<M: Model> Drop for Fmu<M> {
    fn drop(&mut self) {
        unsafe { api::free_instance::<M>(self.c) }
    }
}

fn vr<M: Model>(name: &str) -> u32 {
    M::variables()
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}")) as u32
}

impl<M: Model> Fmu<M> {
    /// Instantiated, the Real parameters `params` and Booleans `flags` set,
    /// the inputs set, initialized.
    fn new(params: &[(&str, f64)], flags: &[(&str, bool)], u: f64, path: f64) -> Self {
        Self::new_with(params, &[], flags, u, path)
    }

    /// [`Self::new`] with the Integer parameters `ints` set too.
    fn new_with(
        params: &[(&str, f64)],
        ints: &[(&str, i32)],
        flags: &[(&str, bool)],
        u: f64,
        path: f64,
    ) -> Self {
        let f = Self::instantiated();
        for &(name, v) in ints {
            let r = vr::<M>(name);
            f.ok(unsafe { api::set_integer::<M>(f.c, &r, 1, &v) });
        }
        for &(name, v) in params {
            assert_eq!(
                f.set(name, v),
                fmi2OK,
                "{name} = {v}: {:?}",
                f.book.entries()
            );
        }
        for &(name, b) in flags {
            let v = fmi2Boolean::from(b);
            let r = vr::<M>(name);
            f.ok(unsafe { api::set_boolean::<M>(f.c, &r, 1, &v) });
        }
        f.ok(unsafe { api::setup_experiment::<M>(f.c, fmi2False, 0.0, 0.0, fmi2False, 0.0) });
        f.ok(unsafe { api::enter_initialization_mode::<M>(f.c) });
        f.ok(f.set("activation", u));
        f.ok(f.set("length", path));
        f.ok(unsafe { api::exit_initialization_mode::<M>(f.c) });
        f
    }

    fn instantiated() -> Self {
        let book = Box::new(LogBook::default());
        let cb = callbacks(&book);
        let name = CString::new("mt").unwrap();
        let g = CString::new(guid::<M>()).unwrap();
        let c = unsafe {
            api::instantiate::<M>(
                name.as_ptr(),
                fmi2CoSimulation,
                g.as_ptr(),
                c"file:///nowhere".as_ptr(),
                &cb,
                fmi2False,
                fmi2False,
            )
        };
        assert!(!c.is_null());
        Fmu {
            c,
            book,
            _m: PhantomData,
        }
    }

    fn ok(&self, s: fmi2Status) {
        assert_eq!(s, fmi2OK, "log: {:#?}", self.book.entries());
    }

    fn set(&self, name: &str, v: f64) -> fmi2Status {
        let r = vr::<M>(name);
        unsafe { api::set_real::<M>(self.c, &r, 1, &v) }
    }

    fn get(&self, name: &str) -> f64 {
        let r = vr::<M>(name);
        let mut v = f64::NAN;
        self.ok(unsafe { api::get_real::<M>(self.c, &r, 1, &mut v) });
        v
    }

    fn gets(&self, names: &[&str]) -> Vec<f64> {
        names.iter().map(|n| self.get(n)).collect()
    }

    /// Every Real output, in the order of the variable table.
    fn outputs(&self) -> Vec<f64> {
        self.gets(&output_names::<M>())
    }

    /// Force, muscle stress, fibre length, tendon strain and pennation.
    fn unit_outputs(&self) -> [f64; 5] {
        [
            "force",
            "stress",
            "fibre_length",
            "tendon_strain",
            "pennation",
        ]
        .map(|n| self.get(n))
    }

    /// Set the inputs and step from `t` by `h`; the status.
    fn step(&self, t: f64, h: f64, u: f64, path: f64) -> fmi2Status {
        self.ok(self.set("activation", u));
        self.ok(self.set("length", path));
        unsafe { api::do_step::<M>(self.c, t, h, fmi2True) }
    }

    fn derivative(&self, unknown: &str, known: &str) -> f64 {
        let (u, k, seed) = (vr::<M>(unknown), vr::<M>(known), 1.0);
        let mut d = f64::NAN;
        self.ok(unsafe {
            api::get_directional_derivative::<M>(self.c, &u, 1, &k, 1, &seed, &mut d)
        });
        d
    }

    fn save(&self) -> fmi2FMUstate {
        let mut s: fmi2FMUstate = std::ptr::null_mut();
        self.ok(unsafe { api::get_fmu_state::<M>(self.c, &mut s) });
        s
    }

    fn restore(&self, s: fmi2FMUstate) {
        self.ok(unsafe { api::set_fmu_state::<M>(self.c, s) });
    }

    fn free_state(&self, mut s: fmi2FMUstate) {
        self.ok(unsafe { api::free_fmu_state::<M>(self.c, &mut s) });
    }

    fn serialize(&self, s: fmi2FMUstate) -> Vec<u8> {
        let mut n = 0usize;
        self.ok(unsafe { api::serialized_fmu_state_size::<M>(self.c, s, &mut n) });
        let mut buf = vec![0 as fmi2Byte; n];
        self.ok(unsafe { api::serialize_fmu_state::<M>(self.c, s, buf.as_mut_ptr(), n) });
        buf.into_iter().map(|b| b as u8).collect()
    }

    fn deserialize(&self, bytes: &[u8]) -> fmi2FMUstate {
        let mut s: fmi2FMUstate = std::ptr::null_mut();
        self.ok(unsafe {
            api::deserialize_fmu_state::<M>(
                self.c,
                bytes.as_ptr() as *const fmi2Byte,
                bytes.len(),
                &mut s,
            )
        });
        s
    }

    fn state_bytes(&self) -> Vec<u8> {
        let s = self.save();
        let b = self.serialize(s);
        self.free_state(s);
        b
    }
}

type Mt = Fmu<Musculotendon>;

const H: f64 = 1e-3;

/// The Real outputs of model `M`, from its variable table.
fn output_names<M: Model>() -> Vec<&'static str> {
    M::variables()
        .into_iter()
        .filter(|v| v.causality == Causality::Output && matches!(v.ty, VarType::Real { .. }))
        .map(|v| v.name)
        .collect()
}

/// The scene's start value of `name` (its modelDescription's).
fn start(name: &str) -> f64 {
    match Musculotendon::variables()
        .into_iter()
        .find(|v| v.name == name)
        .unwrap()
        .ty
    {
        hill_muscle::fmi2::VarType::Real { start, .. } => start.unwrap(),
        _ => panic!("{name} is not Real"),
    }
}

/// The rest path of the scene (the `length` input's start).
fn rest_path() -> f64 {
    start("length")
}

/// F0 = sigma0 · area of instance `f`.
fn f0(f: &Mt) -> f64 {
    f.get("sigma0") * f.get("area")
}

/// The tendon of instance `f` (MODEL_NOTES "Musculotendon unit").
fn tendon(f: &Mt) -> Tendon {
    Tendon {
        slack_length: f.get("tendon_slack_length"),
        strain_at_f0: f.get("tendon_strain_at_F0"),
        f0: f0(f),
    }
}

/// A protocol with every phase: activation rising, a stretch, a hold, a
/// path jump, release to slack with activation on, then off.
fn protocol(i: usize, rest: f64) -> (f64, f64) {
    let t = (i + 1) as f64 * H;
    let u = if i < 300 {
        (t * 5.0).min(1.0)
    } else if i < 400 {
        1.0
    } else {
        0.0
    };
    let path = match i {
        0..=99 => rest,
        100..=199 => rest + 0.02 * (t - 0.1),
        200..=249 => rest + 0.002,
        250..=299 => rest + 0.012,
        _ => rest - 0.03,
    };
    (u, path)
}

/// After every step the outputs satisfy the equilibrium: force is the
/// tendon curve at tendon_strain, and force = F_M cos(pennation) with
/// F_M = stress · area, below 1e-10 F0 (the solver's tolerance, and a few
/// ulp of the force). Default (no pennation) and pennated (0.4 rad) units,
/// through a protocol with a path jump and a slack phase.
#[test]
fn the_equilibrium_holds_after_every_step() {
    let rest = rest_path();
    for alpha0 in [0.0, 0.4] {
        let f = Mt::new(&[("pennation_angle", alpha0)], &[], 0.0, rest);
        let (tendon, area, f0) = (tendon(&f), f.get("area"), f0(&f));
        let mut worst: f64 = 0.0;
        let mut slack_steps = 0;
        for i in 0..500 {
            let (u, path) = protocol(i, rest);
            f.ok(f.step(i as f64 * H, H, u, path));
            let [force, stress, l_m, strain, alpha] = f.unit_outputs();
            let lt = tendon.slack_length * (1.0 + strain);
            let curve = tendon.force(lt).0;
            assert!(
                (force - curve).abs() <= 1e-12 * f0,
                "step {i}: force {force} vs the tendon curve {curve}"
            );
            let residual = stress * area * alpha.cos() - force;
            worst = worst.max(residual.abs() / f0);
            assert!(
                residual.abs() <= 1e-10 * f0,
                "step {i}: residual {residual:e} N"
            );
            // The path is tendon plus the fibres' projection.
            assert!(
                (lt + l_m * alpha.cos() - path).abs() <= 1e-12 * path,
                "step {i}"
            );
            if strain < 0.0 {
                slack_steps += 1;
                assert_eq!(force, 0.0);
            }
        }
        assert!(slack_steps > 50, "{slack_steps}");
        eprintln!("pennation_angle {alpha0}: worst residual {worst:e} F0");
    }
}

/// A rigid tendon without pennation is `HillMuscle1D` at length
/// ℓ − L_TS, bit for bit (force, stress, activation level, stiffness).
#[test]
fn a_rigid_tendon_without_pennation_is_the_plain_muscle() {
    let rest = rest_path();
    let mt = Mt::new(&[], &[("compliant_tendon", false)], 0.0, rest);
    let (l0, area, lts) = (mt.get("L0"), mt.get("area"), mt.get("tendon_slack_length"));
    let plain = Fmu::<Hill1D>::new(&[("L0", l0), ("area", area)], &[], 0.0, rest - lts);
    for i in 0..300 {
        let (u, path) = protocol(i, rest);
        let path = path.max(rest - 0.01);
        mt.ok(mt.step(i as f64 * H, H, u, path));
        plain.ok(plain.step(i as f64 * H, H, u, path - lts));
        for name in ["force", "stress", "activation_level"] {
            assert_eq!(
                mt.get(name).to_bits(),
                plain.get(name).to_bits(),
                "step {i}: {name}"
            );
        }
        let l_m = mt.get("fibre_length");
        assert!(
            (l_m - (path - lts)).abs() <= 4.0 * f64::EPSILON * l_m,
            "{l_m}"
        );
        assert_eq!(mt.get("tendon_strain"), 0.0);
        assert_eq!(
            mt.get("stiffness").to_bits(),
            plain.derivative("force", "length").to_bits()
        );
    }
}

/// fmi2GetDirectionalDerivative of every output (but `stiffness`) with
/// respect to both inputs against central differences of the step map
/// (each side from the state saved before the step); `stiffness` is the
/// derivative of force by length. Compliant and rigid tendons, with and
/// without pennation, activated and not.
#[test]
fn directional_derivatives_match_finite_differences_of_the_step_map() {
    let rest = rest_path();
    // All but `stiffness`, itself d force / d length.
    let names: Vec<&str> = output_names::<Musculotendon>()
        .into_iter()
        .filter(|n| *n != "stiffness")
        .collect();
    let names = &names[..];
    let mut worst: f64 = 0.0;
    for (alpha0, compliant) in [(0.0, true), (0.4, true), (0.4, false)] {
        let f = Mt::new(
            &[("pennation_angle", alpha0)],
            &[("compliant_tendon", compliant)],
            0.3,
            rest + 0.005,
        );
        for i in 0..60 {
            let (u, path) = (
                if i < 40 { 0.3 + 0.01 * i as f64 } else { 0.05 },
                rest + 0.005 + 1e-4 * i as f64,
            );
            let t = i as f64 * H;
            if i % 10 != 9 {
                f.ok(f.step(t, H, u, path));
                continue;
            }
            let before = f.save();
            let at = |du: f64, dl: f64| -> Vec<f64> {
                f.restore(before);
                f.ok(f.step(t, H, u + du, path + dl));
                f.gets(names)
            };
            let (dl, du) = (1e-6, 1e-5);
            let (lp, lm) = (at(0.0, dl), at(0.0, -dl));
            let (up, um) = (at(du, 0.0), at(-du, 0.0));
            f.restore(before);
            f.free_state(before);
            f.ok(f.step(t, H, u, path));
            let values = f.gets(names);
            for (k, name) in names.iter().enumerate() {
                for (input, plus, minus, d) in
                    [("length", &lp, &lm, dl), ("activation", &up, &um, du)]
                {
                    let fd = (plus[k] - minus[k]) / (2.0 * d);
                    let dd = f.derivative(name, input);
                    let scale = fd.abs().max(dd.abs());
                    // The equilibrium's tolerance (1e-10 F0) shows in the
                    // differences: a floor of 1e-9 of the value over d.
                    let err = (fd - dd).abs();
                    assert!(
                        err <= 1e-4 * scale + 1e-9 * values[k].abs() / d,
                        "α0 {alpha0} compliant {compliant} step {i}: d {name} / d {input}: {dd} vs fd {fd}"
                    );
                    if scale > 1e-6 {
                        worst = worst.max(err / scale);
                    }
                }
            }
            assert_eq!(f.get("stiffness"), f.derivative("force", "length"));
        }
    }
    eprintln!("worst relative error of the directional derivatives: {worst:e}");
}

/// A state saved, serialized and deserialized continues exactly as the
/// instance it came from, bit for bit, and serializes to the same bytes.
#[test]
fn state_save_restore_and_serialization_are_bit_identical() {
    let rest = rest_path();
    let f = Mt::new(&[("pennation_angle", 0.3)], &[], 0.0, rest);
    for i in 0..150 {
        let (u, path) = protocol(i, rest);
        f.ok(f.step(i as f64 * H, H, u, path));
    }
    let saved = f.save();
    let bytes = f.serialize(saved);
    let run = || -> Vec<u64> {
        let mut out = Vec::new();
        for i in 150..350 {
            let (u, path) = protocol(i, rest);
            f.ok(f.step(i as f64 * H, H, u, path));
            out.extend(f.outputs().iter().map(|x| x.to_bits()));
        }
        out
    };
    let first = run();
    f.restore(saved);
    assert_eq!(f.state_bytes(), bytes);
    let second = run();
    assert_eq!(first, second);
    let restored = f.deserialize(&bytes);
    f.restore(restored);
    assert_eq!(f.state_bytes(), bytes);
    let third = run();
    assert_eq!(first, third);
    f.free_state(saved);
    f.free_state(restored);
}

/// Each of the unit's parameters refuses a value outside its range with the
/// standard message (naming it and its range), the value not taken, and
/// the instance then runs exactly as a twin that never saw the call.
#[test]
fn bad_values_of_the_unit_parameters_are_refused() {
    let rest = rest_path();
    let cases: [(&str, &[f64], &str); 3] = [
        (
            "tendon_slack_length",
            &[0.0, -0.1, 20.0, f64::NAN, f64::INFINITY],
            "[1e-4, 10]",
        ),
        (
            "tendon_strain_at_F0",
            &[0.0, -0.04, 2.0, f64::NAN],
            "[1e-6, 1]",
        ),
        ("pennation_angle", &[-0.1, 1.2, f64::NAN], "[0, 1]"),
    ];
    let twin = Mt::new(&[], &[], 0.5, rest);
    for (name, values, range) in cases {
        let f = Mt::instantiated();
        let before = start(name);
        for &v in values {
            f.book.clear();
            assert_eq!(f.set(name, v), fmi2Error, "{name} = {v}");
            let msg = f
                .book
                .entries()
                .into_iter()
                .map(|e| e.message)
                .collect::<Vec<_>>()
                .join(" | ");
            assert!(
                msg.contains(&format!("parameter {name} = "))
                    && msg.contains(&format!("is out of range: must be finite and in {range}")),
                "{name} = {v}: {msg}"
            );
        }
        f.ok(unsafe {
            api::setup_experiment::<Musculotendon>(f.c, fmi2False, 0.0, 0.0, fmi2False, 0.0)
        });
        f.ok(unsafe { api::enter_initialization_mode::<Musculotendon>(f.c) });
        assert_eq!(f.get(name).to_bits(), before.to_bits(), "{name}");
        f.ok(f.set("activation", 0.5));
        f.ok(f.set("length", rest));
        f.ok(unsafe { api::exit_initialization_mode::<Musculotendon>(f.c) });
        assert_eq!(f.state_bytes(), twin.state_bytes(), "{name}");
    }
}

/// A slack tendon (path shorter than L_TS plus the fibres at zero force):
/// no force, a negative strain, and the muscle shortened until it carries
/// nothing, with activation on and off; from initialization and after a
/// release in one step.
#[test]
fn a_slack_tendon_carries_nothing() {
    let rest = rest_path();
    for u in [0.0, 1.0] {
        let f = Mt::new(&[("initial_activation", u)], &[], u, rest - 0.04);
        let f0 = f0(&f);
        let check = |f: &Mt, when: &str| {
            assert_eq!(f.get("force"), 0.0, "{when}");
            assert!(f.get("tendon_strain") < 0.0, "{when}");
            let fm = f.get("stress") * f.get("area");
            assert!(fm.abs() <= 1e-10 * f0, "{when}: F_M = {fm:e}");
            assert_eq!(f.get("stiffness"), 0.0, "{when}");
        };
        check(&f, "initialization");
        for i in 0..50 {
            f.ok(f.step(i as f64 * H, H, u, rest - 0.04));
            check(&f, &format!("u {u} step {i}"));
        }
        // Taut again, then released in one step.
        f.ok(f.step(0.05, H, u, rest + 0.01));
        assert!(f.get("force") > 0.0 || u == 0.0);
        f.ok(f.step(0.051, H, u, rest - 0.04));
        check(&f, "after the release");
    }
}

/// A path jump of 2 cm (with activation 1 about 3 % strain of the tendon)
/// in one step is solved: the equilibrium holds and the force follows the
/// tendon; jumping back is solved too.
#[test]
fn a_path_jump_in_one_step_is_solved() {
    let rest = rest_path();
    let f = Mt::new(&[("initial_activation", 1.0)], &[], 1.0, rest);
    let (f0, area) = (f0(&f), f.get("area"));
    let mut forces = vec![f.get("force")];
    for (i, path) in [rest + 0.02, rest + 0.02, rest, rest - 0.02]
        .into_iter()
        .enumerate()
    {
        f.ok(f.step(i as f64 * H, H, 1.0, path));
        let residual = f.get("stress") * area * f.get("pennation").cos() - f.get("force");
        assert!(residual.abs() <= 1e-10 * f0, "{residual:e}");
        forces.push(f.get("force"));
    }
    // The jump stretches the tendon (the force rises), the return and the
    // shortening release it.
    assert!(forces[1] > forces[0] && forces[3] < forces[2], "{forces:?}");
    assert!(forces[4] < forces[3], "{forces:?}");
}

/// The largest pennation angle: a rigid tendon on a path too short for the
/// fibres' smallest projection is a discard, logged naming the largest
/// angle, that leaves the outputs as they were.
#[test]
fn past_the_largest_angle_a_step_is_discarded_and_changes_nothing() {
    let f = Mt::new(
        &[("pennation_angle", 1.0)],
        &[("compliant_tendon", false)],
        0.0,
        rest_path(),
    );
    let lts = f.get("tendon_slack_length");
    let before = f.outputs();
    f.book.clear();
    assert_eq!(f.step(0.0, H, 0.0, lts + 0.001), fmi2Discard);
    assert!(
        f.book
            .entries()
            .iter()
            .any(|e| e.message.contains("largest pennation angle")),
        "{:?}",
        f.book.entries()
    );
    assert_eq!(f.outputs(), before);
}

/// `HillMusculotendonFE` on a 6 × 1 mesh (its tests stay fast), with the
/// Real parameters `params` and Booleans `flags`.
#[cfg(feature = "fe")]
fn fe_unit(
    params: &[(&str, f64)],
    flags: &[(&str, bool)],
    u: f64,
    path: f64,
) -> Fmu<hill_muscle::fmus::musculotendonfe::MusculotendonFe> {
    Fmu::new_with(params, &[("n_axial", 6), ("n_radial", 1)], flags, u, path)
}

/// The FE unit: after every step the outputs satisfy the equilibrium
/// (force = F_M cos(pennation), F_M = stress · area, below 1e-9 F0, the
/// FE unit's tolerance) and the path is tendon plus projection; through an
/// activation rise, a stretch, a path jump and a slack phase.
#[cfg(feature = "fe")]
#[test]
fn fe_the_equilibrium_holds_after_every_step() {
    let rest = rest_path();
    for alpha0 in [0.0, 0.4] {
        let f = fe_unit(&[("pennation_angle", alpha0)], &[], 0.0, rest);
        let (area, f0) = (f.get("area"), f.get("sigma0") * f.get("area"));
        let lts = f.get("tendon_slack_length");
        let mut slack_steps = 0;
        for (k, i) in (0..500).step_by(10).enumerate() {
            let (u, path) = protocol(i, rest);
            f.ok(f.step(k as f64 * H, H, u, path));
            let [force, stress, l_m, strain, alpha] = f.unit_outputs();
            let residual = stress * area * alpha.cos() - force;
            assert!(
                residual.abs() <= 1e-9 * f0,
                "step {i}: residual {residual:e} N"
            );
            let lt = lts * (1.0 + strain);
            assert!((lt + l_m * alpha.cos() - path).abs() <= 1e-12 * path);
            if strain < 0.0 {
                slack_steps += 1;
                assert_eq!(force, 0.0);
            }
        }
        assert!(slack_steps > 0);
    }
}

/// The FE unit with a rigid tendon without pennation is `HillMuscleFE` at
/// length ℓ − L_TS, bit for bit (force, stress, activation level, and
/// stiffness = its d force / d length).
#[cfg(feature = "fe")]
#[test]
fn fe_a_rigid_tendon_without_pennation_is_the_plain_muscle() {
    use hill_muscle::fmus::hillfe::HillFE;
    let rest = rest_path();
    let mt = fe_unit(&[], &[("compliant_tendon", false)], 0.0, rest);
    let (l0, area, lts) = (mt.get("L0"), mt.get("area"), mt.get("tendon_slack_length"));
    let plain = Fmu::<HillFE>::new_with(
        &[("L0", l0), ("area", area)],
        &[("n_axial", 6), ("n_radial", 1)],
        &[],
        0.0,
        rest - lts,
    );
    for (k, i) in (0..300).step_by(10).enumerate() {
        let (u, path) = protocol(i, rest);
        let path = path.max(rest - 0.01);
        mt.ok(mt.step(k as f64 * H, H, u, path));
        plain.ok(plain.step(k as f64 * H, H, u, path - lts));
        for name in ["force", "stress", "activation_level"] {
            assert_eq!(
                mt.get(name).to_bits(),
                plain.get(name).to_bits(),
                "step {i}: {name}"
            );
        }
        assert_eq!(mt.get("fibre_length"), path - lts);
        assert_eq!(
            mt.get("stiffness").to_bits(),
            plain.derivative("force", "length").to_bits()
        );
    }
}

/// The FE unit's directional derivatives of force and fibre_length with
/// respect to both inputs against central differences of the step map
/// (each side from the state saved before the step); stiffness is d force /
/// d length.
#[cfg(feature = "fe")]
#[test]
fn fe_directional_derivatives_match_finite_differences_of_the_step_map() {
    let rest = rest_path();
    for (alpha0, compliant) in [(0.0, true), (0.4, true), (0.4, false)] {
        let f = fe_unit(
            &[("pennation_angle", alpha0)],
            &[("compliant_tendon", compliant)],
            0.3,
            rest + 0.005,
        );
        for i in 0..3 {
            f.ok(f.step(i as f64 * H, H, 0.4, rest + 0.005 + 1e-4 * i as f64));
        }
        let (t, u, path) = (3.0 * H, 0.6, rest + 0.0054);
        let before = f.save();
        let at = |u: f64, path: f64| -> Vec<f64> {
            f.restore(before);
            f.ok(f.step(t, H, u, path));
            f.gets(&["force", "fibre_length"])
        };
        let (dl, du) = (1e-6, 1e-4);
        let (lp, lm, up, um) = (
            at(u, path + dl),
            at(u, path - dl),
            at(u + du, path),
            at(u - du, path),
        );
        at(u, path);
        let f0 = f.get("sigma0") * f.get("area");
        for (k, name, scale) in [(0, "force", f0), (1, "fibre_length", 0.1)] {
            for (known, fd, step) in [
                ("length", (lp[k] - lm[k]) / (2.0 * dl), dl),
                ("activation", (up[k] - um[k]) / (2.0 * du), du),
            ] {
                let d = f.derivative(name, known);
                // Each side solved to ~1e-9 of the output's scale.
                let tol = 2e-3 * d.abs() + 1e-8 * scale / step;
                assert!(
                    (d - fd).abs() <= tol,
                    "α0 {alpha0} compliant {compliant}: d {name}/d {known} {d} vs fd {fd}"
                );
            }
        }
        assert_eq!(f.get("stiffness"), f.derivative("force", "length"));
        f.free_state(before);
    }
}

/// The FE unit's state saved, restored and serialized: bit-identical
/// bytes, and the restored instance steps on as the original.
#[cfg(feature = "fe")]
#[test]
fn fe_state_save_restore_and_serialization_are_bit_identical() {
    let rest = rest_path();
    let f = fe_unit(&[("pennation_angle", 0.3)], &[], 0.5, rest);
    for i in 0..3 {
        f.ok(f.step(i as f64 * H, H, 0.7, rest + 2e-4 * i as f64));
    }
    let s = f.save();
    let bytes = f.serialize(s);
    f.ok(f.step(3.0 * H, H, 0.9, rest + 1e-3));
    let after = f.state_bytes();
    let back = f.deserialize(&bytes);
    f.restore(back);
    assert!(
        f.state_bytes() == bytes,
        "the restored state's bytes differ"
    );
    f.ok(f.step(3.0 * H, H, 0.9, rest + 1e-3));
    assert!(
        f.state_bytes() == after,
        "the restored unit steps on differently"
    );
    f.free_state(s);
    f.free_state(back);
}

/// The FE unit past the largest pennation angle: a discard that changes
/// nothing.
#[cfg(feature = "fe")]
#[test]
fn fe_past_the_largest_angle_a_step_is_discarded_and_changes_nothing() {
    let f = fe_unit(
        &[("pennation_angle", 1.0)],
        &[("compliant_tendon", false)],
        0.0,
        rest_path(),
    );
    let lts = f.get("tendon_slack_length");
    let before = f.outputs();
    assert_eq!(f.step(0.0, H, 0.0, lts + 0.001), fmi2Discard);
    assert!(
        f.book
            .entries()
            .iter()
            .any(|e| e.message.contains("largest pennation angle")),
        "{:?}",
        f.book.entries()
    );
    assert_eq!(f.outputs(), before);
}
