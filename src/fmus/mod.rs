//! The FMUs: models with their variable tables.
pub mod hill1d;
