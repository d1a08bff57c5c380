//! The input programs of a musculotendon unit: the program's stretch as the
//! stretch of the unit's fibres, mapped to the path length the unit's
//! `length` input takes, and capped inside the unit's physical range.
//!
//! A program (`program`) is written in stretch = fibre length / L0, up to
//! 2.0 and down to 0.3. A unit's input is the length of its whole path,
//! tendon and fibres (MODEL_NOTES "Musculotendon unit"), so the harness
//! chooses which path a stretch means. It is **the fibres' share**: the path
//! at which the relaxed unit (activation 0, at rest) holds its fibres at the
//! stretch, ℓ(λ) = L_TS (1 + ε_T(F_p(λ) cos α / F0)) + λ L0 cos α, with
//! F_p(λ) the relaxed muscle's static force at fibre stretch λ (for the 1D
//! unit the 1D law in uniaxial stress, `solve_uniaxial`, isometric at
//! activation 0; for the FE unit its own, see below) and ε_T the tendon's
//! strain at a force (`Tendon::strain_at`; 0 where the fibres carry
//! nothing, λ ≤ 1: there the path is L_TS + λ L0 cos α, the tendon at its
//! slack length). An active muscle then shortens its fibres against the
//! tendon, as in an isometric experiment on a unit.
//!
//! **The cap.** A tendon ruptures at 2.5 ε0 (`Tendon::max_strain`, where it
//! carries 3.567 F0) and the unit refuses such a path (fmi2Discard). The law's
//! relaxed fibres stiffen steeply past stretch 1.2 (its matrix term
//! c b e^(b (Ī1 − 3)), b = 23.46, on top of the PE): with D ≤ 1e-9 they
//! carry 3 to 17 F0 at 1.3 by parameter set, at 2.0 thousands to millions
//! of F0 (a softer volumetric term lets them thin instead). So no unit holds
//! its fibres near 2.0: the program's stretch is capped at [`unit_cap`],
//! where the relaxed fibres carry F0 ([`RELAXED_FORCE_CAP`]; 1.21 to 1.34
//! over the grid with D ≤ 1e-6, up to 2.0 with D = 1e-4), the end of the
//! passive range a musculoskeletal model is used in
//! (Thelen 2003's passive curve reaches F0 at its own end, 1.6 L0). The
//! fibres cannot pass the cap (longer, they would pull more than the
//! shorter tendon), and a fully active muscle adds at most f_v,max F0 ≤
//! 1.82 F0 (the eccentric asymptote at the paper's largest d), so the tendon
//! stays near 2.8 F0 at most, short of rupture, in every program
//! (`tests/stability_subset.rs` checks the margin). A capped program keeps
//! its timing: a ramp to 2.0 ramps at the same rate to the cap and holds
//! there until the plain program turns; a stretch below the cap is
//! unchanged. Rupture itself is tested by its own test
//! (`tests/stability_subset.rs`), not by the matrix.
//!
//! **Whose relaxed fibres** ([`Hooks::relaxed_fibres`]). The 1D unit's
//! map and cap use the 1D law's static force ([`relaxed_force`],
//! [`unit_cap`], [`UnitPath`]). The FE unit's use its own relaxed
//! equilibrium ([`RelaxedUnit`]: the unit initialized at activation 0
//! through its FMI functions, set up as in the cell, read at a path; the
//! path of a stretch and the cap are roots on the path). Its specimen,
//! clamped at its ends on the matrix's 6 × 1 mesh, carries more than the
//! law in uniaxial stress at the same stretch, most with a soft volumetric
//! term: with D = 1e-4 some 3.6 F0 at 2.0, where the law carries less than
//! F0, so the law's cap would ask its tendon past rupture. The FE unit's
//! caps over the parameter sets: 1.19–1.24 with D = 1e-9, 1.22–1.36 with
//! D = 1e-6, 1.55–1.82 with D = 1e-4 (`tests/stability_subset.rs` checks
//! the margin at each); with D = 1e-12, 1.226. A path the relaxed unit
//! refuses counts as too long, so a cap found there would be on the short
//! side.
//!
//! Entry points: [`program_of`] (the program a model runs in a cell),
//! [`unit_breakpoints`] (its path at the program's breakpoints),
//! [`UnitPath`] (the law's map from a stretch to a path), [`unit_cap`] and
//! [`relaxed_force`] (the law's cap and force), [`RelaxedUnit`] (a unit's
//! own relaxed equilibrium, cap and map).

use std::collections::BTreeMap;

use hill_muscle::law::pennation::Pennation;
use hill_muscle::law::tendon::Tendon;
use hill_muscle::law::{solve_uniaxial, FibreHistory, FibreRate};

use super::*;

/// The largest static force (in F0) of the relaxed fibres a unit's program
/// asks for: the cap of its stretch ([`unit_cap`]).
pub const RELAXED_FORCE_CAP: f64 = 1.0;

/// The relaxed muscle's static force at fibre stretch `stretch`, in F0 =
/// sigma0 · area: its nominal stress over sigma0 (the 1D law isometric at
/// activation 0, MODEL_NOTES "The 1D Hill reduction"); 0 for stretch ≤ 1
/// (the fibres carry no tension there), +inf where the law cannot be solved.
pub fn relaxed_force(params: &Params, stretch: f64) -> f64 {
    if stretch <= 1.0 {
        return 0.0;
    }
    solve_uniaxial(
        params,
        stretch,
        0.0,
        &FibreHistory::REST,
        FibreRate::Isometric,
        1.0,
    )
    .map_or(f64::INFINITY, |u| {
        (u.nominal_stress() / params.sigma0).max(0.0)
    })
}

/// The largest fibre stretch a unit's program takes for the law `params`:
/// where the relaxed fibres carry [`RELAXED_FORCE_CAP`] F0 (bisection between
/// 1 and 2.0, the programs' largest stretch; 2.0 if they carry less there).
pub fn unit_cap(params: &Params) -> f64 {
    let (mut lo, mut hi) = (1.0, 2.0);
    if relaxed_force(params, hi) <= RELAXED_FORCE_CAP {
        return hi;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if relaxed_force(params, mid) <= RELAXED_FORCE_CAP {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The program of a unit: `prog` with every stretch capped at `cap`.
pub fn capped(prog: &Program, cap: f64) -> Program {
    Program {
        stretch0: prog.stretch0.min(cap),
        steps: prog
            .steps
            .iter()
            .map(|s| ProgramStep {
                command: s.command,
                stretch: s.stretch.min(cap),
            })
            .collect(),
        ..prog.clone()
    }
}

/// A unit's map from fibre stretch to path length (the module's ℓ(λ)).
pub struct UnitPath {
    params: Params,
    l0: f64,
    tendon: Tendon,
    pennation: Pennation,
}

impl UnitPath {
    /// The map of a unit of the law `params`, rest fibre length `l0` (m),
    /// tendon slack length `lts` (m), tendon strain at F0 `eps0` and
    /// pennation angle `alpha0` (rad) at `l0`.
    pub fn new(params: &Params, l0: f64, lts: f64, eps0: f64, alpha0: f64) -> UnitPath {
        UnitPath {
            params: *params,
            l0,
            tendon: Tendon {
                slack_length: lts,
                strain_at_f0: eps0,
                f0: 1.0,
            },
            pennation: Pennation::new(l0, alpha0),
        }
    }

    /// The path at which the relaxed unit holds its fibres at `stretch`:
    /// L_TS (1 + ε_T(F_p cos α)) + λ L0 cos α (F in F0).
    pub fn path(&self, stretch: f64) -> f64 {
        let p = self.pennation.at(stretch * self.l0);
        let force = relaxed_force(&self.params, stretch) * p.cos;
        let strain = if force > 0.0 {
            self.tendon.strain_at(force)
        } else {
            0.0
        };
        self.tendon.slack_length * (1.0 + strain) + p.projection
    }

    /// The path at each breakpoint of `prog`: its start, then the end of
    /// each step (a held stretch is mapped once).
    pub fn breakpoints(&self, prog: &Program) -> Vec<f64> {
        breakpoints_by(prog, |s| Ok(self.path(s))).expect("the law's map is total")
    }
}

/// Whose relaxed fibres state a unit's program ([`Hooks::relaxed_fibres`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RelaxedFibres {
    /// The 1D law's static force: [`relaxed_force`], [`unit_cap`],
    /// [`UnitPath`].
    Law,
    /// The unit's own relaxed equilibrium, through its FMI functions
    /// ([`RelaxedUnit`]): the FE unit, whose clamped specimen carries more
    /// than the law at the same stretch.
    Own,
}

/// The program a model runs in `cell`: the scenario's, and for a unit
/// ([`Hooks::tendon_slack_length`]) the same capped at its cap ([`unit_cap`]
/// or [`RelaxedUnit::cap`], by [`Hooks::relaxed_fibres`]).
pub fn program_of<M: Model>(cell: &Cell, hooks: &Hooks<M>) -> Program {
    let prog = program(cell.scenario, cell.h);
    match (hooks.tendon_slack_length, hooks.relaxed_fibres) {
        (None, _) => prog,
        (Some(_), RelaxedFibres::Law) => capped(&prog, unit_cap(&cell.law())),
        (Some(_), RelaxedFibres::Own) => capped(&prog, RelaxedUnit::new(cell, hooks).cap()),
    }
}

/// A unit's path at each breakpoint of `prog` (the fibres' share, by
/// [`Hooks::relaxed_fibres`]); `None` for a muscle. The tendon's strain at
/// F0 and the pennation angle are the FMU's start values, which the
/// harness does not set.
pub fn unit_breakpoints<M: Model>(
    cell: &Cell,
    hooks: &Hooks<M>,
    prog: &Program,
) -> Result<Option<Vec<f64>>, String> {
    let Some(lts) = hooks.tendon_slack_length else {
        return Ok(None);
    };
    match hooks.relaxed_fibres {
        RelaxedFibres::Law => {
            let tendon = UnitParams::default();
            let map = UnitPath::new(
                &cell.law(),
                L0,
                lts,
                tendon.tendon_strain_at_f0,
                tendon.pennation_angle,
            );
            Ok(Some(map.breakpoints(prog)))
        }
        RelaxedFibres::Own => {
            let unit = RelaxedUnit::new(cell, hooks);
            breakpoints_by(prog, |s| unit.path(s)).map(Some)
        }
    }
}

/// The path at each breakpoint of `prog` by the map `path`: its start,
/// then the end of each step (a held stretch is mapped once).
fn breakpoints_by(
    prog: &Program,
    mut path: impl FnMut(f64) -> Result<f64, String>,
) -> Result<Vec<f64>, String> {
    let mut last = (prog.stretch0, path(prog.stretch0)?);
    let mut out = Vec::with_capacity(prog.steps.len() + 1);
    out.push(last.1);
    for s in &prog.steps {
        if s.stretch != last.0 {
            last = (s.stretch, path(s.stretch)?);
        }
        out.push(last.1);
    }
    Ok(out)
}

/// A unit's relaxed equilibrium at a path ([`RelaxedUnit::at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Relaxed {
    /// Fibre length / L0.
    pub stretch: f64,
    /// The fibres' force in F0: the unit's nominal `stress` over sigma0.
    pub force: f64,
    /// The tendon's strain (its output `tendon_strain`).
    pub tendon_strain: f64,
}

/// A unit's relaxed equilibrium (activation 0, at rest) as the unit itself
/// solves it, by initializing an instance of `M` set up as in `cell`
/// through its FMI functions: the program's cap and the fibres' share from
/// the model's own fibres (for the FE unit, its clamped FE specimen at the
/// matrix's mesh) instead of the 1D law's. The map is the module's ℓ(λ)
/// with F_p(λ) the unit's own relaxed force; the path is found as a root,
/// the relaxed fibre stretch and force rising with the path. Results are
/// kept per model, hooks, law and stretch (each costs some ten
/// initializations).
pub struct RelaxedUnit<'a, M> {
    cell: &'a Cell,
    hooks: &'a Hooks<M>,
    tendon: Tendon,
    pennation: Pennation,
    key: String,
}

impl<'a, M: Model> RelaxedUnit<'a, M> {
    /// The relaxed unit of `hooks` (a unit's: `tendon_slack_length` is
    /// `Some`) in `cell`.
    pub fn new(cell: &'a Cell, hooks: &'a Hooks<M>) -> RelaxedUnit<'a, M> {
        let lts = hooks
            .tendon_slack_length
            .expect("a unit's hooks name its tendon slack length");
        let unit = UnitParams::default();
        RelaxedUnit {
            cell,
            hooks,
            tendon: Tendon {
                slack_length: lts,
                strain_at_f0: unit.tendon_strain_at_f0,
                f0: 1.0,
            },
            pennation: Pennation::new(L0, unit.pennation_angle),
            key: format!(
                "{}|{lts}|{:?}|{:?}|{:?}",
                std::any::type_name::<M>(),
                hooks.integers,
                hooks.booleans,
                cell.law()
            ),
        }
    }

    /// The relaxed unit at path `path` (m). `Err`: the unit refuses the
    /// path (past the tendon's rupture, or no equilibrium found).
    pub fn at(&self, path: f64) -> Result<Relaxed, String> {
        let mut fmu = cell_fmu::<M>(self.cell, self.hooks)?;
        fmu.set_real("initial_activation", 0.0)?;
        fmu.set_inputs(0.0, path)?;
        fmu.initialize()?;
        Ok(Relaxed {
            stretch: fmu.get_real("fibre_length")? / L0,
            force: fmu.get_real("stress")? / self.cell.law().sigma0,
            tendon_strain: fmu.get_real("tendon_strain")?,
        })
    }

    /// The path at which the tendon at force `force` (F0) and the fibres
    /// at `stretch` lie: L_TS (1 + ε_T(F cos α)) + λ L0 cos α.
    fn path_with(&self, stretch: f64, force: f64) -> f64 {
        let p = self.pennation.at(stretch * L0);
        let f = force * p.cos;
        let strain = if f > 0.0 {
            self.tendon.strain_at(f)
        } else {
            0.0
        };
        self.tendon.slack_length * (1.0 + strain) + p.projection
    }

    fn memo(
        &self,
        what: &str,
        compute: impl FnOnce() -> Result<f64, String>,
    ) -> Result<f64, String> {
        static MEMO: Mutex<BTreeMap<String, f64>> = Mutex::new(BTreeMap::new());
        let key = format!("{}|{what}", self.key);
        if let Some(v) = MEMO.lock().unwrap().get(&key) {
            return Ok(*v);
        }
        let v = compute()?;
        MEMO.lock().unwrap().insert(key, v);
        Ok(v)
    }

    /// The largest fibre stretch of the unit's programs: where its relaxed
    /// fibres carry [`RELAXED_FORCE_CAP`] F0 (within 1e-9 F0, at or below),
    /// or 2.0, the programs' largest stretch, if they carry less there. A
    /// root on the path between the fibres at 1 (slack tendon) and the
    /// tendon at the cap's force with the fibres at 2.0.
    pub fn cap(&self) -> f64 {
        self.memo("cap", || {
            let excess = |path: f64| self.at(path).ok().map(|r| r.force - RELAXED_FORCE_CAP);
            let (lo, hi) = (
                self.path_with(1.0, 0.0),
                self.path_with(2.0, RELAXED_FORCE_CAP),
            );
            // There the tendon carries at most the cap's force: the fibres
            // are at 2.0 or longer. (A path the unit refuses is too long.)
            let at_hi = match excess(hi) {
                Some(e) if e <= 0.0 => return Ok(2.0),
                e => e.unwrap_or(RELAXED_FORCE_CAP),
            };
            let root = rising_root((lo, -RELAXED_FORCE_CAP), (hi, at_hi), 1e-9, excess);
            Ok(self.at(root)?.stretch.min(2.0))
        })
        .unwrap_or_else(|e| panic!("the relaxed unit at its cap: {e}"))
    }

    /// The path at which the relaxed unit holds its fibres at `stretch`
    /// (at most [`Self::cap`]; within [`PATH_STRETCH_TOL`], at or below): L_TS + λ L0 cos α
    /// for λ ≤ 1 (a slack tendon), else a root between the tendon slack
    /// and the tendon at the cap's force.
    pub fn path(&self, stretch: f64) -> Result<f64, String> {
        if stretch <= 1.0 {
            return Ok(self.path_with(stretch, 0.0));
        }
        self.memo(&format!("path {:x}", stretch.to_bits()), || {
            let excess = |path: f64| self.at(path).ok().map(|r| r.stretch - stretch);
            let (lo, hi) = (
                self.path_with(stretch, 0.0),
                self.path_with(stretch, RELAXED_FORCE_CAP),
            );
            let at_lo = self.at(lo)?.stretch - stretch;
            let at_hi = self.at(hi)?.stretch - stretch;
            // At the cap itself hi is the cap's path, where the fibres'
            // stretch is the cap's to the unit's equilibrium tolerance,
            // either side of it: within the tolerance below, hi is the path.
            if (-PATH_STRETCH_TOL..0.0).contains(&at_hi) {
                return Ok(hi);
            }
            if at_hi < 0.0 {
                return Err(format!(
                    "the relaxed unit does not reach fibre stretch {stretch} below its cap"
                ));
            }
            Ok(rising_root(
                (lo, at_lo.min(0.0)),
                (hi, at_hi),
                PATH_STRETCH_TOL,
                excess,
            ))
        })
    }
}

/// The tolerance of [`RelaxedUnit::path`] in fibre stretch.
pub const PATH_STRETCH_TOL: f64 = 1e-10;

/// The root of a rising function g on [a, b] with g(a) ≤ 0 ≤ g(b) (given as
/// `(a, g(a))`, `(b, g(b))`), by the Illinois method (regula falsi halving
/// the weight of an end kept twice), a bisection step after a point where
/// `g` is `None` (the unit refuses the path: counted as too long): the last
/// point with −tol ≤ g ≤ 0, or where the bracket is below 1e-13 m.
fn rising_root(
    (mut a, mut ga): (f64, f64),
    (mut b, mut gb): (f64, f64),
    tol: f64,
    g: impl Fn(f64) -> Option<f64>,
) -> f64 {
    let (mut true_ga, mut kept, mut bisect) = (ga, 0i8, false);
    for _ in 0..200 {
        if -true_ga <= tol || b - a <= 1e-13 {
            break;
        }
        let x = if bisect || gb <= ga {
            0.5 * (a + b)
        } else {
            a - ga * (b - a) / (gb - ga)
        };
        let x = if x > a && x < b { x } else { 0.5 * (a + b) };
        bisect = false;
        match g(x) {
            Some(v) if v <= 0.0 => {
                (a, ga, true_ga) = (x, v, v);
                if kept == -1 {
                    gb *= 0.5;
                }
                kept = -1;
            }
            Some(v) => {
                (b, gb) = (x, v);
                if kept == 1 {
                    ga *= 0.5;
                }
                kept = 1;
            }
            None => {
                b = x;
                (bisect, kept) = (true, 0);
            }
        }
    }
    a
}
