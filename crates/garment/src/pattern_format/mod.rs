//! The files a cutting room reads, each written from the one [`Pattern`](crate::pattern::Pattern) model:
//!
//! - [`mod@json`]: `patterns.json`, the whole model, versioned (`schema_version`), in millimetres;
//! - [`mod@garmentcode`]: the same pieces and stitches in GarmentCode's JSON pattern specification;
//! - [`mod@svg`]: a true-scale SVG drawing with one layer per kind of line.
//!
//! Every writer draws the pieces side by side as [`sheet`](crate::pattern::sheet) lays them out.

pub mod garmentcode;
pub mod json;
pub mod svg;
