//! The 3D finite-element muscle: so far the procedural tetrahedral mesh of the paper's fusiform specimen.

pub mod mesh;
