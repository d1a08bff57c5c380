//! Unit tests of the scene files (filled in below).
