//! The files a cutting room reads, each written from the one [`Pattern`](crate::pattern::Pattern) model:
//!
//! - [`mod@json`]: `patterns.json`, the whole model, versioned (`schema_version`), in millimetres;
//! - [`mod@garmentcode`]: the same pieces and stitches in GarmentCode's JSON pattern specification;
//! - [`mod@svg`]: a true-scale SVG drawing with one layer per kind of line;
//! - [`mod@dxf`]: `patterns.dxf` (DXF-AAMA) and `patterns-astm.dxf` (DXF-ASTM), one block per piece on the
//!   AAMA/ASTM layers;
//! - [`mod@pdf`]: `patterns.pdf` (one wide page at 1:1) and `patterns-a4.pdf` (tiled onto A4, Letter or A3);
//! - [`mod@hpgl`]: `patterns.plt`, HP-GL/2 for plotters and cutters.
//!
//! Every writer draws the pieces side by side as [`sheet`](crate::pattern::sheet) lays them out.

pub mod dxf;
pub mod garmentcode;
pub mod hpgl;
pub mod json;
pub mod pdf;
pub mod svg;

#[cfg(test)]
pub(crate) mod test_pattern;
#[cfg(test)]
pub(crate) mod test_tools;
