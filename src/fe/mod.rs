//! The 3D finite-element muscle: the procedural tetrahedral mesh of the
//! paper's fusiform specimen and the locking-free tetrahedron (isochoric
//! element response plus an average-nodal-pressure volumetric term).

pub mod assembly;
pub mod discretization;
pub mod element;
pub mod mesh;
pub mod muscle;
pub mod newton;
pub mod tangent;
