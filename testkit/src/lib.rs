//! Test and benchmark code shared by hill-muscle's integration tests, benches
//! and examples: the C-ABI loader of a built FMU ([`cabi`]), the test logger
//! ([`logger`]), finite differences ([`fd`]), the stability matrix
//! ([`stability`]), the property-based FMI API-abuse harness
//! ([`api_abuse`]) and the header of generated results pages
//! ([`provenance`]).
//!
//! # Shape
//!
//! This crate depends on hill-muscle normally; hill-muscle's integration
//! tests, benches and examples dev-depend on it. Cargo links one hill-muscle
//! into each of those targets (the same library unit serves both), so types
//! made here and there are the same types. Only hill-muscle's own unit tests
//! (`#[cfg(test)]` in `src/`) would see a second copy — the library compiled
//! as a test harness — so they must not use this crate.

pub mod api_abuse;
pub mod cabi;
pub mod fd;
pub mod logger;
pub mod provenance;
pub mod stability;
