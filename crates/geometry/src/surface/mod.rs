//! The smooth body surface the garment slides on, behind one trait.
//!
//! A surface is defined over a triangle mesh of fixed topology whose control vertex positions `y` (m) change
//! as the body deforms. A surface point is **linear** in the control positions,
//! `x(s, y) = Σ_i w_i(s) y_i`, so the core output is a [`Stencil`]: for a face `f` and surface coordinates
//! `s = (s1, s2)`, the control vertex ids `i`, the weights `w_i(s)` and their first and second derivatives
//! with respect to `s`. Positions and derivatives of `x` are then `Σ stencil · y`.
//!
//! # Coordinate convention (Eq. 119)
//!
//! For a surface face `f = [v0, v1, v2]` (counter-clockwise seen from outside), `s1` is the barycentric weight
//! of corner `v0`, `s2` the weight of `v1` and `s3 = 1 − s1 − s2` the weight of `v2`:
//! on the linear surface `x = s1 y_{v0} + s2 y_{v1} + s3 y_{v2}` (thesis Eq. 119 with `y1 = v0`, `y2 = v1`,
//! `y3 = v2`). The Loop surface uses the same barycentric parametrization of each face (Stam 1998): the
//! corner `v0` is reached at `s = (1, 0)`, `v1` at `(0, 1)`, `v2` at `(0, 0)`, and the edge between two faces
//! is parametrized identically from both sides (same edge parameter ⇒ same point).
//!
//! Local edge `e` of a face runs `f[e] → f[(e + 1) % 3]` (see [`crate::mesh::topology`]); on edge 0 `s3 = 0`, on edge
//! 1 `s1 = 0`, on edge 2 `s2 = 0`.

//!
//! # Files
//!
//! - [`loop_surface`]: the Loop limit surface ([`LoopSurface`]), evaluated per face by
//!   [`loop_regular_patch`] (box-spline patches of regular faces) and [`loop_irregular_patch`] (Stam's
//!   eigen-decomposition near an extraordinary vertex), with the subdivision rules in [`loop_subdivision`];
//! - [`linear_surface`]: the flat-triangle surface ([`LinearSurface`], Eq. 119), for tests and simple bodies;
//! - [`walk`]: moving a surface point across faces along a step in `s` (Eq. 147–154);
//! - [`closest_point`]: the closest point of the surface to a point in space.

pub mod closest_point;
pub mod limit_mesh;
pub mod linear_surface;
pub mod loop_irregular_patch;
pub mod loop_regular_patch;
pub mod loop_subdivision;
pub mod loop_surface;
pub mod walk;

pub use linear_surface::LinearSurface;
pub use loop_surface::LoopSurface;

use crate::math::{FaceId, Mat3x2, Real, Vec2, Vec3, VertexId};
use crate::mesh::topology::Topology;

/// One control vertex's contribution to a surface point: `x += w y_i`, `∂x/∂s_a += dw[a] y_i`,
/// `∂²x/∂s_a∂s_b += ddw[·] y_i`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StencilEntry {
    /// Control vertex id (an index into the control positions).
    pub vertex: VertexId,
    /// Weight `w_i` (dimensionless).
    pub w: Real,
    /// `[∂w_i/∂s1, ∂w_i/∂s2]`.
    pub dw: [Real; 2],
    /// `[∂²w_i/∂s1², ∂²w_i/∂s1∂s2, ∂²w_i/∂s2²]`.
    pub ddw: [Real; 3],
}

/// The linear map from control positions to one surface point and its first and second derivatives.
///
/// Reuse one `Stencil` across evaluations: [`LimitSurface::stencil`] clears it and refills it without
/// allocating once its capacity suffices. Each control vertex appears at most once.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stencil {
    /// The contributing control vertices, each once.
    pub entries: Vec<StencilEntry>,
}

impl Stencil {
    /// An empty stencil with room for `capacity` control vertices.
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            entries: Vec::with_capacity(capacity),
        }
    }

    /// Removes all entries, keeping the allocation.
    pub fn clear(&mut self) {
        self.entries.clear();
    }

    /// Number of control vertices in the stencil.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether the stencil is empty.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Adds `scale ×` (weight and derivatives) for `vertex`, merging with an existing entry of the same vertex.
    #[inline]
    pub fn add(&mut self, vertex: VertexId, scale: Real, w: Real, dw: [Real; 2], ddw: [Real; 3]) {
        if let Some(e) = self.entries.iter_mut().find(|e| e.vertex == vertex) {
            e.w += scale * w;
            e.dw[0] += scale * dw[0];
            e.dw[1] += scale * dw[1];
            e.ddw[0] += scale * ddw[0];
            e.ddw[1] += scale * ddw[1];
            e.ddw[2] += scale * ddw[2];
        } else {
            self.entries.push(StencilEntry {
                vertex,
                w: scale * w,
                dw: [scale * dw[0], scale * dw[1]],
                ddw: [scale * ddw[0], scale * ddw[1], scale * ddw[2]],
            });
        }
    }

    /// Applies the stencil to control positions `control` (`#V × 3`, m).
    ///
    /// # Panics
    /// If a stencil vertex is not an index of `control` (the stencil came from a different surface).
    pub fn apply(&self, control: &[Vec3]) -> SurfacePoint {
        let mut p = SurfacePoint::default();
        for e in &self.entries {
            let y = control[e.vertex];
            p.position += e.w * y;
            for a in 0..2 {
                let mut col = p.tangents.column_mut(a);
                col += e.dw[a] * y;
            }
            for k in 0..3 {
                p.second[k] += e.ddw[k] * y;
            }
        }
        p
    }
}

/// A surface point and its derivatives with respect to the face coordinates `s`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SurfacePoint {
    /// Position `x` (m).
    pub position: Vec3,
    /// `∂x/∂s` (m): column 0 is `∂x/∂s1`, column 1 is `∂x/∂s2`.
    pub tangents: Mat3x2,
    /// `[∂²x/∂s1², ∂²x/∂s1∂s2, ∂²x/∂s2²]` (m).
    pub second: [Vec3; 3],
}

impl SurfacePoint {
    /// Unit normal `∂x/∂s1 × ∂x/∂s2 / |…|`, outward for a counter-clockwise oriented mesh; `None` where the
    /// tangents are degenerate (e.g. exactly at an extraordinary vertex of valence < 6).
    pub fn normal(&self) -> Option<Vec3> {
        let n = self.tangents.column(0).cross(&self.tangents.column(1));
        let len = n.norm();
        (len > 0.0 && len.is_finite()).then(|| n / len)
    }
}

/// A location on a surface: a face and coordinates `s = (s1, s2)` inside it (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceCoord {
    /// Surface face.
    pub face: FaceId,
    /// `(s1, s2)`, with `s1 ≥ 0`, `s2 ≥ 0`, `s1 + s2 ≤ 1` inside the face.
    pub s: Vec2,
}

impl SurfaceCoord {
    /// A location.
    pub fn new(face: FaceId, s1: Real, s2: Real) -> Self {
        Self {
            face,
            s: Vec2::new(s1, s2),
        }
    }

    /// The three barycentric coordinates `[s1, s2, s3 = 1 − s1 − s2]`.
    pub fn barycentric(&self) -> [Real; 3] {
        [self.s.x, self.s.y, 1.0 - self.s.x - self.s.y]
    }
}

/// Why a surface cannot be built or evaluated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SurfaceError {
    /// The control mesh is not an oriented 2-manifold.
    #[error("the control mesh is not an oriented manifold: {0}")]
    Topology(#[from] crate::mesh::topology::TopologyError),
    /// The control mesh has a boundary, but the surface needs a closed mesh.
    #[error(
        "the control mesh has a boundary (edge ({a}, {b}) has only one face); the Loop surface needs a closed mesh"
    )]
    Boundary { a: VertexId, b: VertexId },
    /// A vertex valence the Loop evaluator does not support.
    #[error("vertex {vertex} has valence {valence}; the Loop surface supports valences 3 to {max}")]
    Valence {
        vertex: VertexId,
        valence: usize,
        max: usize,
    },
    /// A face has more than one extraordinary vertex (valence ≠ 6), which Stam's evaluation cannot handle.
    #[error(
        "face {face} has {count} extraordinary vertices (valence ≠ 6); at most one is allowed — use \
         LoopSurface::with_preprocessing_subdivision to subdivide the mesh once"
    )]
    TooManyIrregular { face: FaceId, count: usize },
    /// A face id out of range.
    #[error("face {face} does not exist (the surface has {num_faces} faces)")]
    BadFace { face: FaceId, num_faces: usize },
    /// Surface coordinates that are not finite numbers.
    #[error("surface coordinates ({s1}, {s2}) in face {face} are not finite")]
    BadCoordinates { face: FaceId, s1: Real, s2: Real },
    /// Control positions whose count does not match the surface.
    #[error("{given} control positions given, but the surface has {expected} control vertices")]
    ControlCount { given: usize, expected: usize },
    /// Per-face flags whose count does not match the surface's faces.
    #[error("{given} face flags given, but the surface has {expected} faces")]
    FlagCount { given: usize, expected: usize },
    /// A control position is not finite.
    #[error("control position of vertex {vertex} is not finite")]
    NonFiniteControl { vertex: VertexId },
}

/// A surface over a fixed triangle topology whose points are linear in the control positions.
///
/// Faces are those of [`LimitSurface::topology`] (for a Loop surface built with preprocessing subdivision,
/// the refined faces); stencil ids index the control vertices (`num_control_vertices`), which may differ
/// from the topology's vertices.
pub trait LimitSurface {
    /// Number of surface faces.
    fn num_faces(&self) -> usize;

    /// Number of control vertices `#V` (length of the control position array).
    fn num_control_vertices(&self) -> usize;

    /// Connectivity of the surface faces (neighbours across edges, for walking).
    fn topology(&self) -> &Topology;

    /// Fills `out` (cleared first) with the stencil of the point at `s` in `face`. Coordinates slightly
    /// outside the triangle are clamped into it; a bad face id or non-finite `s` is an error.
    fn stencil(&self, face: FaceId, s: Vec2, out: &mut Stencil) -> Result<(), SurfaceError>;

    /// The surface point at `s` in `face` for control positions `control` (`#V × 3`, m), using `scratch` as
    /// the stencil buffer (no allocation once it is large enough).
    fn point_with(
        &self,
        control: &[Vec3],
        face: FaceId,
        s: Vec2,
        scratch: &mut Stencil,
    ) -> Result<SurfacePoint, SurfaceError> {
        if control.len() != self.num_control_vertices() {
            return Err(SurfaceError::ControlCount {
                given: control.len(),
                expected: self.num_control_vertices(),
            });
        }
        self.stencil(face, s, scratch)?;
        Ok(scratch.apply(control))
    }

    /// The surface point at `s` in `face` (allocates a stencil; use [`LimitSurface::point_with`] in loops).
    fn point(&self, control: &[Vec3], face: FaceId, s: Vec2) -> Result<SurfacePoint, SurfaceError> {
        let mut scratch = Stencil::with_capacity(32);
        self.point_with(control, face, s, &mut scratch)
    }
}

/// Validates a face id and coordinates and clamps `s` into the closed triangle.
pub(crate) fn checked_coords(
    face: FaceId,
    num_faces: usize,
    s: Vec2,
) -> Result<[Real; 2], SurfaceError> {
    if face >= num_faces {
        return Err(SurfaceError::BadFace { face, num_faces });
    }
    if !(s.x.is_finite() && s.y.is_finite()) {
        return Err(SurfaceError::BadCoordinates {
            face,
            s1: s.x,
            s2: s.y,
        });
    }
    let (mut s1, mut s2) = (s.x.max(0.0), s.y.max(0.0));
    let sum = s1 + s2;
    if sum > 1.0 {
        s1 /= sum;
        s2 /= sum;
    }
    Ok([s1, s2])
}
