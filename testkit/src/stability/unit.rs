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
//! F_p(λ) the relaxed muscle's static force at fibre stretch λ (the 1D law in
//! uniaxial stress, `solve_uniaxial`, isometric at activation 0; the FE
//! specimen's differs a little at its clamped ends) and ε_T the tendon's
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
//! Entry points: [`program_of`] (the program a model runs in a cell),
//! [`UnitPath`] (a unit's path at a stretch, and at a program's
//! breakpoints), [`unit_cap`] and [`relaxed_force`].

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
        let mut last = (prog.stretch0, self.path(prog.stretch0));
        let mut out = Vec::with_capacity(prog.steps.len() + 1);
        out.push(last.1);
        for s in &prog.steps {
            if s.stretch != last.0 {
                last = (s.stretch, self.path(s.stretch));
            }
            out.push(last.1);
        }
        out
    }
}

/// The program a model runs in `cell`: the scenario's, and for a unit
/// ([`Hooks::tendon_slack_length`]) the same capped at [`unit_cap`].
pub fn program_of<M>(cell: &Cell, hooks: &Hooks<M>) -> Program {
    let prog = program(cell.scenario, cell.h);
    match hooks.tendon_slack_length {
        Some(_) => capped(&prog, unit_cap(&cell.law())),
        None => prog,
    }
}
