//! The muscle law of Lu et al. (2011), as fixed by MODEL_NOTES.md. No FMI here.
//!
//! One module per thing it computes: the parameters, the fibre curves
//! (force-length, force-velocity, series and parallel elements), activation
//! dynamics, the CE–SEE step solve of the Hill fibre, the isotropic matrix and
//! volumetric energies, the 3D stress and tangent, the 1D uniaxial
//! reduction, and the musculotendon unit around a muscle (tendon curve,
//! pennation, their equilibrium with the muscle's force).

pub mod activation;
pub mod components;
pub mod force_length;
pub mod force_velocity;
pub mod hill_fibre;
pub mod isotropic_matrix;
pub mod musculotendon;
pub mod parallel_element;
pub mod params;
pub mod pennation;
pub mod root_finding;
pub mod series_element;
pub mod stress;
pub mod tendon;
pub mod uniaxial;
pub mod volumetric;

pub use components::{Components, FullLaw};
pub use hill_fibre::{fibre_response, FibreHistory, FibreRate, FibreResponse};
pub use params::{ParamError, ParamId, Params, PARAMETERS};
pub use stress::LawPoint;
pub use uniaxial::{solve_uniaxial, solve_uniaxial_with, Uniaxial};
