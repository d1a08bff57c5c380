//! The memory an FE muscle of a given mesh needs at its peak, estimated
//! from the mesh resolution alone, before anything is allocated, and the
//! budget a muscle must fit in.
//!
//! Entry points: [`estimate`] (bytes at the peak of a step) and [`check`]
//! (the estimate against [`BUDGET`], an error naming both when over).
//!
//! What dominates is the factorisation of the tangent
//! ([`crate::fe::assembly`]). Its fill depends on the mesh topology only
//! (the AMD ordering is topological; grading, geometry and fibre layout
//! move nodes, not connections), so it is a function of the resolution:
//! the LBLᵀ factor of the fusiform mesh holds F ≈ [`FILL_COEFFICIENT`] ·
//! n_axial · n_radial^[`FILL_EXPONENT`] values (a fit of faer's symbolic
//! `len_val` at 16 × 3, 24 × 4, 36 × 6, 48 × 8, 64 × 8, 96 × 8, 48 × 12,
//! 64 × 12 and 96 × 16, within ±10 % there; [`FILL_MARGIN`] covers it). On
//! meshes of 1 to 3 rings off those points the law underestimates the fill
//! by up to 1.56× (4 × 1; 1.28× at 12 × 3), where the factor is a few MB and
//! the assembly and mesh terms of the estimate cover the difference (a test
//! checks the estimate against the fill of the built meshes). When the LBLᵀ fails its backward-error test the tangent is factored
//! by sparse LU, whose factor and workspace take up to [`LU_RATIO`] times
//! the LBLᵀ values, and the reused tangent keeps the previous factor while
//! a new one is computed: the estimate is two LU factors, plus the assembly
//! arrays (a few copies of the tangent's nonzeros, at most
//! [`NONZEROS_PER_NODE`] per node), the mesh and the element results the
//! worker threads buffer ([`THREAD_BUFFER_BYTES_PER_ELEMENT`]). Invariant: the estimate is
//! at least the peak resident memory measured on every mesh it was checked
//! against (docs/reference/bad-input.md).

use crate::fe::mesh::Resolution;

/// Coefficient of the LBLᵀ fill law F = c · n_axial · n_radial^e.
pub const FILL_COEFFICIENT: f64 = 618.0;
/// Exponent e of the fill law's ring count.
pub const FILL_EXPONENT: f64 = 3.7;
/// Factor over the fitted fill (the fit is within ±10 %).
pub const FILL_MARGIN: f64 = 1.15;
/// Peak bytes of one sparse LU factorisation over the LBLᵀ values' bytes
/// (measured 6.5 to 7.3 from 16 × 3 to 48 × 8).
pub const LU_RATIO: f64 = 8.0;
/// Bound on the tangent's nonzeros per node (measured 409 at 16 × 3 to
/// 511 at 48 × 8; the average-nodal-pressure patches widen the stencil).
pub const NONZEROS_PER_NODE: f64 = 560.0;
/// Copies of the tangent's values alive at once during a step (element
/// assembly, the constrained copy, the reused tangent, the pattern's
/// indices), each 8 bytes per nonzero.
const TANGENT_COPIES: f64 = 6.0;
/// Bytes per tetrahedron of the mesh and its per-element state (positions,
/// gradients, histories, patches), a generous bound.
const BYTES_PER_ELEMENT: f64 = 2048.0;
/// Bytes per tetrahedron the element loops' worker threads buffer until the
/// scatter (the tangent's forces, state and 12 × 12 stiffness, 1,416 bytes):
/// counted for every element, as the thread count is tunable.
pub const THREAD_BUFFER_BYTES_PER_ELEMENT: f64 = 1536.0;

/// The memory budget of one FE muscle: 12 GiB, half the 24 GiB of the
/// project's reference machine, leaving the other half to the importer.
/// It admits every mesh of the convergence study ([`crate::fe::mesh::LEVELS`],
/// up to 48 × 8), every mesh of up to 7 rings, and n_axial up to 61 at 8
/// rings, 27 at 10, 14 at 12, 4 at 16.
pub const BUDGET: u64 = 12 << 30;

/// The values of the tangent's LBLᵀ factor the fill law predicts, with its
/// margin (module docs).
pub fn factor_values(r: Resolution) -> f64 {
    let (na, nr) = (r.n_axial as f64, r.n_radial.max(1) as f64);
    FILL_MARGIN * FILL_COEFFICIENT * na * nr.powf(FILL_EXPONENT)
}

/// Bytes at the peak of a step of a muscle meshed at `r` (module docs): two
/// LU factorisations, the assembly arrays, the mesh and the threads' buffers.
pub fn estimate(r: Resolution) -> u64 {
    let factor = 8.0 * factor_values(r) * LU_RATIO;
    let tangent = 8.0 * TANGENT_COPIES * NONZEROS_PER_NODE * r.nodes() as f64;
    let mesh = (BYTES_PER_ELEMENT + THREAD_BUFFER_BYTES_PER_ELEMENT) * r.tets() as f64;
    // Saturating: a resolution far out of any range gives u64::MAX.
    (2.0 * factor + tangent + mesh) as u64
}

/// `Ok` when the estimate for `r` is within `budget`, else an error naming
/// the mesh, the estimate and the budget.
pub fn check(r: Resolution, budget: u64) -> Result<(), String> {
    let bytes = estimate(r);
    if bytes <= budget {
        return Ok(());
    }
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    Err(format!(
        "a {} x {} mesh needs an estimated {:.1} GiB, over the FE muscle's memory budget of {:.1} GiB",
        r.n_axial,
        r.n_radial,
        gib(bytes),
        gib(budget)
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn res(n_axial: usize, n_radial: usize) -> Resolution {
        Resolution { n_axial, n_radial }
    }

    /// The fill law with its margin covers faer's symbolic fill measured on
    /// the meshes of the fit (values of `len_val`).
    #[test]
    fn the_fill_law_covers_the_measured_fill() {
        for (na, nr, measured) in [
            (16, 3, 0.63e6),
            (24, 4, 2.66e6),
            (36, 6, 16.5e6),
            (48, 8, 64.9e6),
            (64, 8, 89.4e6),
            (48, 12, 283e6),
            (64, 12, 396e6),
            (96, 8, 130e6),
            (96, 16, 1.71e9),
        ] {
            let f = factor_values(res(na, nr));
            assert!(
                f >= measured && f <= 1.35 * measured,
                "{na} x {nr}: {f} for {measured}"
            );
        }
    }

    /// The estimate covers two LU factors of the fill the code builds now
    /// (faer's symbolic analysis of the assembled pattern, not the figures
    /// of the fit) on meshes small enough to analyse in a test, graded and
    /// uniform: on 1 to 3 rings the fill law alone underestimates it (module
    /// docs), the assembly and mesh terms cover the difference.
    #[test]
    fn the_estimate_covers_the_fill_of_the_built_meshes() {
        use crate::fe::discretization::{Discretization, Ends};
        use crate::fe::mesh::{FibreLayout, Grading, LUMPED_GRADING};
        use crate::specimen::{LENGTH, MEAN_AREA};
        let uniform = Grading {
            axial: 0.0,
            radial: 0.0,
        };
        for (na, nr) in [
            (1, 1),
            (4, 1),
            (8, 1),
            (4, 2),
            (8, 2),
            (12, 2),
            (16, 2),
            (24, 2),
            (6, 3),
            (12, 3),
            (16, 3),
            (18, 3),
            (24, 3),
            (8, 4),
            (16, 4),
            (24, 4),
        ] {
            for grading in [LUMPED_GRADING, uniform] {
                let d = Discretization::fusiform_graded(
                    LENGTH,
                    MEAN_AREA,
                    res(na, nr),
                    grading,
                    FibreLayout::Axial,
                    Ends::Clamped,
                )
                .unwrap();
                let built = d.pattern.factor_values() as f64;
                let factors = 2.0 * 8.0 * LU_RATIO * built;
                assert!(
                    estimate(res(na, nr)) as f64 >= factors,
                    "{na} x {nr}: estimate {} below two LU factors of the built fill {built}",
                    estimate(res(na, nr))
                );
            }
        }
    }

    /// The default and the convergence study's meshes fit the budget; the
    /// largest declared one does not, and the message names both figures.
    #[test]
    fn the_budget_admits_the_study_meshes_and_refuses_the_largest() {
        for r in crate::fe::mesh::LEVELS {
            check(r, BUDGET).unwrap();
        }
        check(crate::fe::mesh::LUMPED, BUDGET).unwrap();
        let e = check(res(96, 16), BUDGET).unwrap_err();
        assert!(
            e.contains("96 x 16") && e.contains("GiB") && e.contains("12.0 GiB"),
            "{e}"
        );
        // The largest meshes served, as documented (module docs of BUDGET).
        for (na, nr) in [(96, 7), (61, 8), (27, 10), (14, 12), (4, 16)] {
            check(res(na, nr), BUDGET).unwrap();
            assert!(check(res(na + 1, nr), BUDGET).is_err() || na == 96);
        }
        // A test budget refuses what the real one admits.
        assert!(check(crate::fe::mesh::LUMPED, 1 << 20).is_err());
    }

    /// The estimate grows with either count and saturates far out of range.
    #[test]
    fn the_estimate_is_monotone_and_saturates() {
        assert!(estimate(res(16, 3)) < estimate(res(17, 3)));
        assert!(estimate(res(16, 3)) < estimate(res(16, 4)));
        assert_eq!(estimate(res(usize::MAX / 2, 1 << 20)), u64::MAX);
    }
}
