//! Anthropometry of a standing body surface: plane sections ([`plane_section`]), tape-measure girths
//! ([`girth`]), the segmentation into torso, legs and arms with the limb axes ([`body_segmentation`]), and
//! the landmarks and girths a compression-garment maker uses ([`landmarks`], ISO 8559-1 / RAL-GZ 387), and
//! the regions (torso, legs, arms) of the surface that follow from them ([`body_regions`]).
//!
//! Everything works on plane sections of the surface, not on its vertices, so the results do not depend
//! on the mesh resolution or vertex numbering. Units: metres.

pub mod body_regions;
pub mod body_segmentation;
pub mod girth;
pub mod landmarks;
pub mod plane_section;

pub use body_regions::{BodyRegion, body_regions};
pub use body_segmentation::{LimbAxis, LimbKind, MeasureError, Segmentation, Side, segment_body};
pub use landmarks::{Landmark, Measurements, measure_body};
