//! The FMUs: models with their variable tables.
pub mod codec;
pub mod common;
pub mod hill1d;
#[cfg(feature = "fe")]
pub mod hillfe;
pub mod musculotendon1d;
#[cfg(feature = "fe")]
pub mod musculotendonfe;
pub mod table;
