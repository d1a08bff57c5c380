//! The 3D finite-element muscle, in layers that import only downward:
//! [`mesh`] and [`element`] (the specimen's tetrahedral mesh and the
//! locking-free tetrahedron: isochoric element response plus an
//! average-nodal-pressure volumetric term), [`assembly`] (the sparse tangent
//! and its factorisation), [`discretization`] (the spatial problem: forces
//! and tangent at given positions), [`tangent`] (the reused factorised
//! tangent and the predictor's record), [`newton`] (one (sub)step's
//! equilibrium), [`muscle`] (time stepping, initialization, error control)
//! and [`step_map`] (one communication step, its outputs and their
//! derivatives); [`memory`] estimates a mesh's peak memory before anything
//! is built; [`threads`] splits the element loops over opt-in scoped
//! threads; [`work`] counts the solves' work, failed attempts included.
//! Nothing here knows of FMI.

pub mod assembly;
pub mod discretization;
pub mod element;
pub mod memory;
pub mod mesh;
pub mod muscle;
pub mod musculotendon;
pub mod newton;
pub mod step_map;
pub mod tangent;
pub mod threads;
pub mod work;
