//! Walking a surface location by a step in surface coordinates, across faces (thesis Eq. 147–154).
//!
//! The step `Δs` is given in the coordinates of the starting face. Within a face the location moves on the
//! straight line `s + t Δs`; when a barycentric coordinate would become negative, the location stops on the
//! first edge crossed (Eq. 148–151), is re-expressed in the neighbouring face by the same edge parameter
//! (exact: both faces parametrize the shared edge identically), and the remaining step `(1 − t) Δs` is
//! converted by least squares, `(dx/ds_new) Δs_m = (dx/ds_old) Δs_n` (Eq. 153–154), which keeps the 3D
//! tangent vector of the remaining step. This repeats until the step is used up.
//!
//! Steps that hit a vertex exactly cross at a point nudged `vertex_nudge` along the edge away from the
//! vertex (then circle the vertex face by face if needed); a remaining step that would immediately leave the
//! new face through the shared edge again (tangent to the edge up to round-off) is projected onto the edge.
//! An iteration cap turns any pathological case into an error instead of a loop.

use crate::math::{FaceId, Mat2, Real, Vec2, Vec3};
use crate::surface::{LimitSurface, Stencil, SurfaceCoord, SurfaceError};

/// Settings of [`surface_walk`].
#[derive(Clone, Copy, Debug)]
pub struct WalkParams {
    /// Most edge crossings before giving up with [`WalkError::TooManyCrossings`].
    pub max_crossings: usize,
    /// Distance (in edge parameter, dimensionless) by which a crossing exactly at a vertex is moved along the
    /// edge.
    pub vertex_nudge: Real,
}

impl Default for WalkParams {
    fn default() -> Self {
        Self {
            max_crossings: 10_000,
            vertex_nudge: 1e-9,
        }
    }
}

/// One straight piece of a walk inside one face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkSegment {
    /// The face.
    pub face: FaceId,
    /// Start coordinates in the face.
    pub from: Vec2,
    /// End coordinates in the face.
    pub to: Vec2,
}

/// Where a walk ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkEnd {
    /// Final location.
    pub coord: SurfaceCoord,
    /// Number of edges crossed.
    pub crossings: usize,
}

/// Why a walk failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WalkError {
    /// The surface rejected a query (bad face, bad coordinates, wrong control count).
    #[error(transparent)]
    Surface(#[from] SurfaceError),
    /// The step is not finite.
    #[error("the step ({0}, {1}) is not finite")]
    NonFiniteStep(Real, Real),
    /// The walk reached a boundary edge.
    #[error("the walk left the surface through boundary edge {edge} of face {face}")]
    Boundary { face: FaceId, edge: usize },
    /// The surface derivative of a face is rank-deficient where the step must be transferred.
    #[error(
        "the surface derivative of face {face} is degenerate at ({s1}, {s2}); cannot transfer the step"
    )]
    DegenerateTangents { face: FaceId, s1: Real, s2: Real },
    /// The crossing cap was reached.
    #[error(
        "the walk crossed {crossings} edges without using up the step (stopped in face {face})"
    )]
    TooManyCrossings { face: FaceId, crossings: usize },
}

/// Moves `start` by `step` (in the start face's coordinates) over `surface` with control positions `control`
/// (`#V × 3`, m). Appends the straight pieces to `trace` when given. See the module docs.
pub fn surface_walk<S: LimitSurface + ?Sized>(
    surface: &S,
    control: &[Vec3],
    start: SurfaceCoord,
    step: Vec2,
    params: &WalkParams,
    mut trace: Option<&mut Vec<WalkSegment>>,
) -> Result<WalkEnd, WalkError> {
    if !(step.x.is_finite() && step.y.is_finite()) {
        return Err(WalkError::NonFiniteStep(step.x, step.y));
    }
    let mut scratch = Stencil::with_capacity(64);
    // Validates face, coordinates and control count.
    surface.point_with(control, start.face, start.s, &mut scratch)?;
    let mut face = start.face;
    let mut s = clamp_into_triangle(start.s);
    let mut ds = step;
    let topology = surface.topology();
    for crossings in 0..=params.max_crossings {
        let b = [s.x, s.y, 1.0 - s.x - s.y];
        let db = [ds.x, ds.y, -ds.x - ds.y];
        // First coordinate to reach zero along the step (Eq. 148–150); ties keep the lower index.
        let mut t_hit = 1.0;
        let mut hit = None;
        for k in 0..3 {
            if db[k] < 0.0 {
                let t = (-b[k] / db[k]).max(0.0);
                if t < t_hit {
                    t_hit = t;
                    hit = Some(k);
                }
            }
        }
        let Some(k) = hit else {
            let end = clamp_into_triangle(s + ds);
            if let Some(tr) = trace.as_deref_mut() {
                tr.push(WalkSegment {
                    face,
                    from: s,
                    to: end,
                });
            }
            return Ok(WalkEnd {
                coord: SurfaceCoord { face, s: end },
                crossings,
            });
        };
        // Move to the edge opposite corner k (Eq. 151): local edge e = (k + 1) % 3 from f[e] to f[e + 1].
        let e = (k + 1) % 3;
        let mut be = [
            b[0] + t_hit * db[0],
            b[1] + t_hit * db[1],
            b[2] + t_hit * db[2],
        ];
        be[k] = 0.0;
        let along = be[(e + 1) % 3].max(0.0) + be[e].max(0.0);
        let mut lambda = if along > 0.0 {
            be[(e + 1) % 3].max(0.0) / along
        } else {
            0.5
        };
        lambda = lambda.clamp(params.vertex_nudge, 1.0 - params.vertex_nudge);
        let mut at = [0.0; 3];
        at[e] = 1.0 - lambda;
        at[(e + 1) % 3] = lambda;
        let s_edge = Vec2::new(at[0], at[1]);
        if let Some(tr) = trace.as_deref_mut() {
            tr.push(WalkSegment {
                face,
                from: s,
                to: s_edge,
            });
        }
        let remaining = (1.0 - t_hit) * ds; // Eq. 152
        let twin = topology
            .twin(face, e)
            .ok_or(WalkError::Boundary { face, edge: e })?;
        // Same edge parameter in the neighbour: its edge runs f[e + 1] → f[e].
        let mut bn = [0.0; 3];
        bn[twin.edge] = lambda;
        bn[(twin.edge + 1) % 3] = 1.0 - lambda;
        let s_new = Vec2::new(bn[0], bn[1]);
        // Transfer the remaining step (Eq. 153–154) by the normal equations of the 3 × 2 system.
        let j_old = surface
            .point_with(control, face, s_edge, &mut scratch)?
            .tangents;
        let j_new = surface
            .point_with(control, twin.face, s_new, &mut scratch)?
            .tangents;
        let normal = j_new.transpose() * j_new;
        let rhs = j_new.transpose() * (j_old * remaining);
        let mut dm = solve_spd(&normal, &rhs).ok_or(WalkError::DegenerateTangents {
            face: twin.face,
            s1: s_new.x,
            s2: s_new.y,
        })?;
        // The coordinate of the corner opposite the shared edge must not decrease, or the next iteration
        // would bounce straight back: project such a (tangent-to-edge) step onto the edge.
        let opp = (twin.edge + 2) % 3;
        let d_opp = [dm.x, dm.y, -dm.x - dm.y][opp];
        if d_opp < 0.0 {
            dm = remove_component(dm, opp, d_opp);
        }
        face = twin.face;
        s = s_new;
        ds = dm;
    }
    Err(WalkError::TooManyCrossings {
        face,
        crossings: params.max_crossings,
    })
}

/// Changes `dm` so that barycentric coordinate `k` does not change, keeping the other two changes'
/// difference (a step along the edge opposite corner `k`).
fn remove_component(dm: Vec2, k: usize, d_k: Real) -> Vec2 {
    // Spread −d_k equally over the other two coordinates' changes.
    let mut d = [dm.x, dm.y, -dm.x - dm.y];
    d[k] = 0.0;
    d[(k + 1) % 3] += 0.5 * d_k;
    d[(k + 2) % 3] += 0.5 * d_k;
    Vec2::new(d[0], d[1])
}

/// Solves the 2 × 2 symmetric positive definite system, or `None` when it is (nearly) singular.
fn solve_spd(m: &Mat2, rhs: &Vec2) -> Option<Vec2> {
    let det = m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)];
    let scale = m[(0, 0)] * m[(1, 1)];
    let well_conditioned = det > 1e-14 * scale;
    if !well_conditioned || !det.is_finite() {
        return None;
    }
    let x = (m[(1, 1)] * rhs.x - m[(0, 1)] * rhs.y) / det;
    let y = (m[(0, 0)] * rhs.y - m[(1, 0)] * rhs.x) / det;
    Some(Vec2::new(x, y))
}

/// Clamps coordinates into the closed triangle (removing round-off outside it).
pub(crate) fn clamp_into_triangle(s: Vec2) -> Vec2 {
    let (mut s1, mut s2) = (s.x.max(0.0), s.y.max(0.0));
    let sum = s1 + s2;
    if sum > 1.0 {
        s1 /= sum;
        s2 /= sum;
    }
    Vec2::new(s1, s2)
}
