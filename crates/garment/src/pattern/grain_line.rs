//! The grain line: the direction on a flat piece that runs along the body's length when worn — the
//! fabric's wale (lengthwise) direction, which a knitted compression garment runs along the limb.
//!
//! For each pattern triangle with rest corners `u_0, u_1, u_2` (m, 2D) sewn onto cloth corners
//! `x_0, x_1, x_2` (m, 3D, on the body), the affine map from the cloth triangle to the pattern sends the
//! tangent part of the body's up axis `ŷ` (its projection `t = ŷ − (ŷ·n̂) n̂` onto the triangle's plane,
//! `t = α (x_1 − x_0) + β (x_2 − x_0)` by the 2 × 2 Gram system) to `α (u_1 − u_0) + β (u_2 − u_0)`.
//! The grain direction is the area-weighted mean of these images, normalized; a piece lying flat across
//! the up axis (no mean direction) takes the pattern's +y.
//!
//! The arrow is drawn through a point inside the piece (its area centroid when inside, else the interior
//! pattern vertex farthest from the outline), along the grain direction, over `GRAIN_FRACTION` of the
//! piece's chord through that point.

use crate::math::{Real, Vec2, Vec3};
use crate::pattern::GrainLine;
use crate::pattern::seam_allowance::{polygon_contains, segment_crossing};

/// Share of the chord through the anchor point that the grain arrow spans.
const GRAIN_FRACTION: Real = 0.7;

/// The area-weighted wale direction (unit, pattern plane) of a piece whose pattern triangles `faces` have
/// rest corners in `pattern` (m) and 3D corners in `cloth` (m, by pattern vertex), for the body axis `up`.
pub fn grain_direction(pattern: &[Vec2], cloth: &[Vec3], faces: &[[usize; 3]], up: Vec3) -> Vec2 {
    let mut sum = Vec2::zeros();
    for f in faces {
        let [u0, u1, u2] = f.map(|v| pattern[v]);
        let [x0, x1, x2] = f.map(|v| cloth[v]);
        let (e1, e2) = (x1 - x0, x2 - x0);
        let normal = e1.cross(&e2);
        let area2 = normal.norm();
        if !(area2 > 0.0) {
            continue;
        }
        let nh = normal / area2;
        let t = up - nh * up.dot(&nh);
        // Gram system [e1·e1 e1·e2; e1·e2 e2·e2] (α, β) = (e1·t, e2·t).
        let (g11, g12, g22) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
        let det = g11 * g22 - g12 * g12;
        if !(det > 0.0) {
            continue;
        }
        let (r1, r2) = (e1.dot(&t), e2.dot(&t));
        let alpha = (g22 * r1 - g12 * r2) / det;
        let beta = (g11 * r2 - g12 * r1) / det;
        let image = (u1 - u0) * alpha + (u2 - u0) * beta;
        // Weighted by the 3D area (the image of a unit tangent is O(1)).
        sum += image * (0.5 * area2);
    }
    let len = sum.norm();
    if len > 1e-12 && len.is_finite() {
        sum / len
    } else {
        Vec2::new(0.0, 1.0)
    }
}

/// Area centroid of the pattern triangles (m); `None` without positive area.
pub fn area_centroid(pattern: &[Vec2], faces: &[[usize; 3]]) -> Option<Vec2> {
    let mut area = 0.0;
    let mut c = Vec2::zeros();
    for f in faces {
        let [a, b, d] = f.map(|v| pattern[v]);
        let t = 0.5 * ((b - a).x * (d - a).y - (b - a).y * (d - a).x);
        area += t;
        c += (a + b + d) * (t / 3.0);
    }
    (area > 0.0).then(|| c / area)
}

/// Distance (m) from `p` to the closed polyline `outline`.
fn distance_to_outline(outline: &[Vec2], p: Vec2) -> Real {
    let n = outline.len();
    (0..n)
        .map(|i| {
            let (a, b) = (outline[i], outline[(i + 1) % n]);
            let e = b - a;
            let t = ((p - a).dot(&e) / e.norm_squared().max(1e-300)).clamp(0.0, 1.0);
            (a + e * t - p).norm()
        })
        .fold(Real::INFINITY, Real::min)
}

/// A point well inside the piece: the area centroid if the sewing line contains it, else the pattern
/// vertex farthest from the sewing line.
pub fn inner_point(pattern: &[Vec2], faces: &[[usize; 3]], sewing: &[Vec2]) -> Vec2 {
    if let Some(c) = area_centroid(pattern, faces)
        && polygon_contains(sewing, c)
    {
        return c;
    }
    pattern
        .iter()
        .copied()
        .max_by(|a, b| distance_to_outline(sewing, *a).total_cmp(&distance_to_outline(sewing, *b)))
        .unwrap_or_else(Vec2::zeros)
}

/// The grain arrow through `anchor` (inside `sewing`) along unit `direction`: `GRAIN_FRACTION` of the
/// chord of the sewing line through the anchor, centred on the chord's middle.
pub fn grain_line(sewing: &[Vec2], anchor: Vec2, direction: Vec2) -> GrainLine {
    // Nearest crossings of the line anchor + t·direction with the outline on each side.
    let (lo, hi) = bounds(sewing);
    let reach = (hi - lo).norm() * 2.0 + 1.0;
    let (a, b) = (anchor - direction * reach, anchor + direction * reach);
    let n = sewing.len();
    let (mut back, mut ahead) = (Real::NEG_INFINITY, Real::INFINITY);
    for i in 0..n {
        if let Some((t, _)) = segment_crossing(a, b, sewing[i], sewing[(i + 1) % n]) {
            let s = (t - 0.5) * 2.0 * reach;
            if s <= 0.0 {
                back = back.max(s);
            } else {
                ahead = ahead.min(s);
            }
        }
    }
    if !(back.is_finite() && ahead.is_finite()) {
        // The anchor is not inside: a short arrow at the anchor.
        let half = 0.25 * (hi - lo).min();
        return GrainLine {
            from: anchor - direction * half,
            to: anchor + direction * half,
        };
    }
    let mid = anchor + direction * (0.5 * (back + ahead));
    let half = 0.5 * GRAIN_FRACTION * (ahead - back);
    GrainLine {
        from: mid - direction * half,
        to: mid + direction * half,
    }
}

fn bounds(points: &[Vec2]) -> (Vec2, Vec2) {
    points.iter().fold(
        (
            Vec2::repeat(Real::INFINITY),
            Vec2::repeat(Real::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    )
}
