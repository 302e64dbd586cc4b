//! Garments for skintight: everything that turns a region of the body surface into sewn 2D sewing
//! patterns and back.
//!
//! - [`plane_cut`]: the body surface cut exactly along planes into panels, with their seams;
//! - [`lscm`]: each panel flattened by the least squares conformal map;
//! - [`pattern_remesh`]: the flat panels remeshed together at the cloth edge length, seam sides sampled alike;
//! - [`mod@ease`]: a pattern scaled about its area centroid by the requested ease;
//! - [`mod@garment`]: the pipeline (cut, flatten, remesh, ease) and [`sew`]: pattern vertices merged into 3D
//!   cloth vertices shared along the seams;
//! - [`mod@garment_remesh`]: a designed garment's patterns resampled and triangulated afresh, located on the
//!   previous cloth;
//! - [`pattern`]: the cut-ready pattern model (pieces, named edges, cut line, notches, grain, labels) that
//!   every pattern file is written from;
//! - [`sliver_flip`]: slivers of a re-flattened pattern repaired by edge flips;
//! - [`seam_truing`]: the two sides of every seam made equally long with the least change to the patterns;
//! - [`pattern_format`]: the pattern files (JSON, GarmentCode JSON, SVG, …), each written from the model.
//!
//! Units: 3D positions in metres (m); pattern (2D) positions in metres; pattern files in their own units
//! (millimetres for JSON, SVG and DXF), each documented.

pub use skintight_geometry::math;

pub mod ease;
pub mod garment;
pub mod garment_remesh;
pub mod lscm;
pub mod marker;
pub mod pattern;
pub mod pattern_format;
pub mod pattern_remesh;
pub mod plane_cut;
pub mod seam_truing;
pub mod sliver_flip;

pub use garment::{Garment, GarmentError, GarmentParams, garment, sew};
pub use garment_remesh::garment_remesh;
