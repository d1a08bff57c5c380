//! Skeletal muscle after Lu, Beldie, Walker, Richmond & Middleton (2011) as
//! FMI 2.0 Co-Simulation FMUs.
//!
//! - [`law`]: the muscle law (no FMI in it): parameters, fibre curves, the
//!   CE–SEE step solve, the 3D stress and tangent, the 1D uniaxial reduction.
//! - [`fmi2`]: a generic FMI 2.0 Co-Simulation layer over a [`fmi2::Model`]
//!   (knows nothing about muscles).
//! - [`fmus`]: the FMUs: models with their variable tables.
//! - `fe` (Cargo feature `fe`, on by default): the 3D finite-element muscle
//!   behind HillMuscleFE, with the sparse solver faer.
//!
//! The cdylib exports the C API of exactly one FMU, chosen by a Cargo feature
//! (`export-hill1d`, `export-hfe`); `fmu_build` builds it once per FMU with
//! `--no-default-features`, so HillMuscle1D's binary contains no FE code
//! (`export-hfe` turns `fe` on).

#[cfg(feature = "fe")]
pub mod fe;
pub mod fmi2;
pub mod fmus;
pub mod law;
pub mod specimen;

#[cfg(all(feature = "export-hill1d", feature = "export-hfe"))]
compile_error!("enable exactly one export-* feature: the cdylib exports one FMU");

#[cfg(feature = "export-hill1d")]
crate::export_fmi2!(crate::fmus::hill1d::Hill1D);

#[cfg(feature = "export-hfe")]
crate::export_fmi2!(crate::fmus::hillfe::HillFE);
