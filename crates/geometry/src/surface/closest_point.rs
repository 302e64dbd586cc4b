//! Closest-point projection of a 3D point onto a limit surface (the idea of thesis Eq. 143 carried to curved
//! surfaces): damped Newton on the face coordinates `s` minimizing `½ |x(s) − p|²`, moving between faces by
//! [`surface_walk`].

use crate::math::{Mat2, Real, Vec2, Vec3};
use crate::surface::walk::{WalkError, WalkParams, surface_walk};
use crate::surface::{LimitSurface, Stencil, SurfaceCoord, SurfaceError};

/// Settings of [`closest_point`] and [`closest_point_from`].
#[derive(Clone, Copy, Debug)]
pub struct ClosestPointParams {
    /// Most Newton iterations.
    pub max_iterations: usize,
    /// Converged when the gradient `|Jᵀ (x − p)|` falls below `tolerance · |J| · (|x − p| + scale)`, with
    /// `scale` the control mesh size (m), or the step below `1e−14` in `s`.
    pub tolerance: Real,
    /// Largest step in face coordinates per iteration (dimensionless).
    pub max_step: Real,
    /// Number of best face-centroid candidates [`closest_point`] starts from.
    pub candidates: usize,
    /// Settings of the walks between faces.
    pub walk: WalkParams,
}

impl Default for ClosestPointParams {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            tolerance: 1e-12,
            max_step: 0.5,
            candidates: 4,
            walk: WalkParams::default(),
        }
    }
}

/// A projection result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projection {
    /// Location of the closest point found.
    pub coord: SurfaceCoord,
    /// Its position (m).
    pub position: Vec3,
    /// Distance from the query point (m).
    pub distance: Real,
    /// Newton iterations used.
    pub iterations: usize,
}

/// Why a projection failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ProjectionError {
    /// A surface query failed.
    #[error(transparent)]
    Surface(#[from] SurfaceError),
    /// A walk between faces failed.
    #[error(transparent)]
    Walk(#[from] WalkError),
    /// The query point is not finite.
    #[error("the point to project ({0}, {1}, {2}) is not finite")]
    NonFinitePoint(Real, Real, Real),
    /// The surface has no faces.
    #[error("the surface has no faces")]
    Empty,
}

/// Projects `target` (m) onto the surface with control positions `control`: starts from the
/// `params.candidates` faces whose centroids are nearest (one evaluation per face) and keeps the best
/// [`closest_point_from`] result. A local search: on strongly folded surfaces a farther sheet may win.
pub fn closest_point<S: LimitSurface + ?Sized>(
    surface: &S,
    control: &[Vec3],
    target: Vec3,
    params: &ClosestPointParams,
) -> Result<Projection, ProjectionError> {
    check_point(target)?;
    if surface.num_faces() == 0 {
        return Err(ProjectionError::Empty);
    }
    let centre = Vec2::new(1.0 / 3.0, 1.0 / 3.0);
    let mut scratch = Stencil::with_capacity(64);
    let mut best: Vec<(Real, usize)> = Vec::with_capacity(params.candidates + 1);
    for f in 0..surface.num_faces() {
        let p = surface.point_with(control, f, centre, &mut scratch)?;
        let d = (p.position - target).norm_squared();
        if best.len() < params.candidates.max(1) || d < best.last().map_or(Real::INFINITY, |b| b.0)
        {
            let at = best.partition_point(|b| b.0 <= d);
            best.insert(at, (d, f));
            best.truncate(params.candidates.max(1));
        }
    }
    let mut result: Option<Projection> = None;
    for &(_, f) in &best {
        let r = closest_point_from(
            surface,
            control,
            target,
            SurfaceCoord { face: f, s: centre },
            params,
        )?;
        if result.is_none_or(|b| r.distance < b.distance) {
            result = Some(r);
        }
    }
    result.ok_or(ProjectionError::Empty)
}

/// Projects `target` (m) onto the surface starting from `start` (a nearby location, e.g. the previous
/// projection): damped Newton with the full Hessian `JᵀJ + Σ (x − p)·∂²x/∂s²` (Gauss–Newton `JᵀJ` where that
/// is not positive definite), a step cap and backtracking on the distance.
pub fn closest_point_from<S: LimitSurface + ?Sized>(
    surface: &S,
    control: &[Vec3],
    target: Vec3,
    start: SurfaceCoord,
    params: &ClosestPointParams,
) -> Result<Projection, ProjectionError> {
    check_point(target)?;
    let mut scratch = Stencil::with_capacity(64);
    let mut coord = start;
    let mut p = surface.point_with(control, coord.face, coord.s, &mut scratch)?;
    let scale = control
        .iter()
        .fold(0.0_f64, |m, y| m.max(y.amax()))
        .max(Real::MIN_POSITIVE);
    let mut iterations = 0;
    while iterations < params.max_iterations {
        iterations += 1;
        let r = p.position - target;
        let j = p.tangents;
        let g = j.transpose() * r;
        let jn = j.norm();
        if g.norm() <= params.tolerance * jn * (r.norm() + scale) {
            break;
        }
        let gn = j.transpose() * j;
        let curv = Mat2::new(
            r.dot(&p.second[0]),
            r.dot(&p.second[1]),
            r.dot(&p.second[1]),
            r.dot(&p.second[2]),
        );
        let full = gn + curv;
        let mut step = solve(&full, &g)
            .or_else(|| solve(&(gn + Mat2::identity() * (1e-12 * gn.trace())), &g))
            .map(|x| -x)
            .unwrap_or_else(|| -g / (gn.trace().max(Real::MIN_POSITIVE)));
        let len = step.norm();
        if len > params.max_step {
            step *= params.max_step / len;
        }
        // Backtrack until the distance decreases.
        let d0 = r.norm_squared();
        let mut accepted = false;
        for _ in 0..40 {
            if step.norm() < 1e-15 {
                break;
            }
            let end = surface_walk(surface, control, coord, step, &params.walk, None)?;
            let q = surface.point_with(control, end.coord.face, end.coord.s, &mut scratch)?;
            if (q.position - target).norm_squared() < d0 {
                coord = end.coord;
                p = q;
                accepted = true;
                break;
            }
            step *= 0.5;
        }
        if !accepted {
            break;
        }
    }
    Ok(Projection {
        coord,
        position: p.position,
        distance: (p.position - target).norm(),
        iterations,
    })
}

fn check_point(p: Vec3) -> Result<(), ProjectionError> {
    if p.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(ProjectionError::NonFinitePoint(p.x, p.y, p.z))
    }
}

/// Solves a 2 × 2 system whose matrix should be positive definite; `None` otherwise.
fn solve(m: &Mat2, rhs: &Vec2) -> Option<Vec2> {
    let det = m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)];
    let positive_definite = m[(0, 0)] > 0.0 && det > 1e-14 * m[(0, 0)] * m[(1, 1)];
    if !positive_definite || !det.is_finite() {
        return None;
    }
    Some(Vec2::new(
        (m[(1, 1)] * rhs.x - m[(0, 1)] * rhs.y) / det,
        (m[(0, 0)] * rhs.y - m[(1, 0)] * rhs.x) / det,
    ))
}
