//! Exact-predicate-free intersection tests between segments and triangles, and between two triangles.
//!
//! The tests use the Möller–Trumbore parametrisation with a small relative tolerance; touching contacts at
//! round-off level may go either way. Coplanar triangle pairs are reported as not intersecting (a measure-zero
//! configuration that offset surfaces of real bodies do not produce).

use crate::math::{Real, Vec3};

/// Where the segment `p + t (q − p)`, `t ∈ [0, 1]`, crosses triangle `(a, b, c)`: the parameter `t`, or
/// `None` when it misses (or runs parallel to the triangle's plane).
#[inline]
pub fn segment_triangle(p: &Vec3, q: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Option<Real> {
    let dir = q - p;
    let e1 = b - a;
    let e2 = c - a;
    let h = dir.cross(&e2);
    let det = e1.dot(&h);
    let scale = e1.norm() * e2.norm() * dir.norm();
    if scale <= 0.0 || det.abs() <= 1e-12 * scale {
        return None;
    }
    let inv = 1.0 / det;
    let s = p - a;
    let u = s.dot(&h) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = s.cross(&e1);
    let v = dir.dot(&qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(&qv) * inv;
    if (0.0..=1.0).contains(&t) {
        Some(t)
    } else {
        None
    }
}

/// Whether two triangles intersect: some edge of one crosses the other. Meant for triangles that share no
/// vertex (pairs sharing a vertex or an edge always touch there).
pub fn triangles_intersect(t: &[Vec3; 3], u: &[Vec3; 3]) -> bool {
    for (x, y) in [(t, u), (u, t)] {
        for e in 0..3 {
            if segment_triangle(&x[e], &x[(e + 1) % 3], &y[0], &y[1], &y[2]).is_some() {
                return true;
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_through_triangle_reports_parameter() {
        let (a, b, c) = (Vec3::zeros(), Vec3::x(), Vec3::y());
        let t = segment_triangle(
            &Vec3::new(0.2, 0.2, 1.0),
            &Vec3::new(0.2, 0.2, -3.0),
            &a,
            &b,
            &c,
        )
        .unwrap();
        assert!((t - 0.25).abs() < 1e-14);
        assert!(
            segment_triangle(
                &Vec3::new(0.8, 0.8, 1.0),
                &Vec3::new(0.8, 0.8, -1.0),
                &a,
                &b,
                &c
            )
            .is_none()
        );
        assert!(
            segment_triangle(
                &Vec3::new(0.2, 0.2, 1.0),
                &Vec3::new(0.2, 0.2, 0.5),
                &a,
                &b,
                &c
            )
            .is_none()
        );
    }

    #[test]
    fn crossing_and_separate_triangles() {
        let t = [Vec3::zeros(), Vec3::x(), Vec3::y()];
        let crossing = [
            Vec3::new(0.2, 0.2, -1.0),
            Vec3::new(0.2, 0.2, 1.0),
            Vec3::new(0.3, -1.0, 0.0),
        ];
        assert!(triangles_intersect(&t, &crossing));
        let above = crossing.map(|p| p + Vec3::new(0.0, 0.0, 2.5));
        assert!(!triangles_intersect(&t, &above));
        // One triangle pierces the other's interior without any of the other's edges crossing it.
        let big = [
            Vec3::new(-5.0, -5.0, 0.0),
            Vec3::new(5.0, -5.0, 0.0),
            Vec3::new(0.0, 5.0, 0.0),
        ];
        let small = [
            Vec3::new(0.0, 0.0, -0.1),
            Vec3::new(0.1, 0.0, 0.1),
            Vec3::new(0.0, 0.1, 0.1),
        ];
        assert!(triangles_intersect(&big, &small));
    }
}
