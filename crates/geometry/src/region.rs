//! Regions of space bounded by planes: half-spaces `{x : n·x ≤ d}` and their intersections.
//!
//! The garment crate cuts the body surface exactly along such planes into panels; procedural bodies fix
//! the vertices inside a [`Region`]. Units: normals are dimensionless directions, offsets in metres.

use serde::{Deserialize, Serialize};

use crate::math::{Real, Vec3};

/// The closed half-space `{x : normal · x ≤ offset}`.
///
/// `normal` is a direction (dimensionless, should be unit length) and `offset` is in metres. A normal that
/// is not unit length is accepted: the half-space is rescaled to `n/|n|`, `d/|n|`, which describes the same
/// set of points. JSON form: `{"normal": [nx, ny, nz], "offset": d}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HalfSpace {
    /// Outward normal of the half-space (points away from the kept side).
    pub normal: Vec3,
    /// Signed distance of the plane from the origin along `normal` (m).
    pub offset: Real,
}

impl HalfSpace {
    /// The half-space `{x : normal · x ≤ offset}` (normal as `[x, y, z]`, offset in m).
    pub fn new(normal: [Real; 3], offset: Real) -> Self {
        Self {
            normal: Vec3::new(normal[0], normal[1], normal[2]),
            offset,
        }
    }
}

/// A labelled region of space: the intersection of its half-spaces (all points with `n·x ≤ d` for every
/// half-space). An empty list means all of space. Used to select body vertices (e.g. the fixed part of a
/// procedural body); a garment panel's region is a [`HalfSpace`] list in the garment crate's `PanelShape`.
///
/// JSON form: `{"label": "body.fixed", "half_spaces": [{"normal": [0, 0, -1], "offset": 0.0}, …]}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Region {
    /// What the region is (e.g. the scene key it came from), used in error messages.
    pub label: String,
    /// The half-spaces whose intersection is the region.
    pub half_spaces: Vec<HalfSpace>,
}
