//! Tetrahedral mesh formats.

pub mod vtu;

pub use vtu::{VtuArray, VtuError, body_arrays, vtu_string, write_vtu};
