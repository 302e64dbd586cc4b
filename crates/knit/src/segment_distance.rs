//! Distance between two line segments, differentiable to second order within each case.
//!
//! The closest points `p(s) = p₀ + s(p₁ − p₀)`, `q(t) = q₀ + t(q₁ − q₀)`, `s, t ∈ [0, 1]`, minimise
//! `|p(s) − q(t)|²`. With `d₁ = p₁ − p₀`, `d₂ = q₁ − q₀`, `r = p₀ − q₀`, `a = d₁·d₁`, `b = d₁·d₂`,
//! `e = d₂·d₂`, `c = d₁·r`, `f = d₂·r`:
//!
//! - **interior–interior**: `s = (bf − ce)/(ae − b²)`, `t = (af − bc)/(ae − b²)`;
//! - **s on an end** (`s ∈ {0, 1}`), t interior: `t = (bs + f)/e`;
//! - **t on an end**, s interior: `s = (bt − c)/a`;
//! - **both on ends**: constants.
//!
//! [`closest_point_case`] picks the case on plain numbers (the interior stationary point if inside, else the
//! nearest of the four sides' clamped projections — exact for parallel segments too), and [`segment_distance`]
//! evaluates the case's closed form over any [`Scalar`], so jets give the exact gradient and Hessian of
//! the distance within the case (the distance is C¹ across cases: the closest points are stationary).

use crate::frames::{V3, dot, lift, norm, scale, sub};
use crate::jet::Scalar;

/// Where the closest points lie.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ClosestPointCase {
    /// Both closest points inside their segments.
    Interior,
    /// `s` at the end `0.0` or `1.0`, `t` inside.
    SEnd(f64),
    /// `t` at the end `0.0` or `1.0`, `s` inside.
    TEnd(f64),
    /// Both at ends `(s, t)`.
    Ends(f64, f64),
}

/// The case and parameters `(s, t)` of the closest points of segments `p0p1` and `q0q1`.
///
/// `|p(s) − q(t)|²` is a convex quadratic on the unit square: its minimum is the interior stationary point
/// when that lies inside, otherwise on one of the four sides, where it is a clamped projection of an end
/// point onto the other segment. All four sides are evaluated and the nearest taken, so the result is
/// right for parallel and near-parallel segments too (no threshold on `ae − b²` that could switch the
/// answer between two ends and make the distance jump).
pub fn closest_point_case(
    p0: [f64; 3],
    p1: [f64; 3],
    q0: [f64; 3],
    q1: [f64; 3],
) -> (ClosestPointCase, f64, f64) {
    let d1 = sub(p1, p0);
    let d2 = sub(q1, q0);
    let r = sub(p0, q0);
    let a = dot(d1, d1);
    let e = dot(d2, d2);
    let b = dot(d1, d2);
    let c = dot(d1, r);
    let f = dot(d2, r);
    let den = a * e - b * b;
    if den > 0.0 {
        let s = (b * f - c * e) / den;
        let t = (a * f - b * c) / den;
        if s > 0.0 && s < 1.0 && t > 0.0 && t < 1.0 {
            return (ClosestPointCase::Interior, s, t);
        }
    }
    let dist2 = |s: f64, t: f64| {
        let w: [f64; 3] = std::array::from_fn(|k| r[k] + s * d1[k] - t * d2[k]);
        dot(w, w)
    };
    let mut best = (f64::INFINITY, ClosestPointCase::Ends(0.0, 0.0), 0.0, 0.0);
    for side in 0..4 {
        let (s, t) = match side {
            0 => (0.0, (f / e).clamp(0.0, 1.0)),
            1 => (1.0, ((b + f) / e).clamp(0.0, 1.0)),
            2 => ((-c / a).clamp(0.0, 1.0), 0.0),
            _ => (((b - c) / a).clamp(0.0, 1.0), 1.0),
        };
        let d = dist2(s, t);
        if d < best.0 {
            let s_end = s == 0.0 || s == 1.0;
            let t_end = t == 0.0 || t == 1.0;
            let regime = match (s_end, t_end) {
                (true, true) => ClosestPointCase::Ends(s, t),
                (true, false) => ClosestPointCase::SEnd(s),
                (false, true) => ClosestPointCase::TEnd(t),
                (false, false) => ClosestPointCase::Interior,
            };
            best = (d, regime, s, t);
        }
    }
    (best.1, best.2, best.3)
}

/// The distance (m) between segments `p0p1` and `q0q1` in the given case, over any [`Scalar`].
pub fn segment_distance<S: Scalar>(
    p0: V3<S>,
    p1: V3<S>,
    q0: V3<S>,
    q1: V3<S>,
    regime: ClosestPointCase,
) -> S {
    let d1 = sub(p1, p0);
    let d2 = sub(q1, q0);
    let r = sub(p0, q0);
    let (s, t) = match regime {
        ClosestPointCase::Interior => {
            let a = dot(d1, d1);
            let e = dot(d2, d2);
            let b = dot(d1, d2);
            let c = dot(d1, r);
            let f = dot(d2, r);
            let den = a * e - b * b;
            ((b * f - c * e) / den, (a * f - b * c) / den)
        }
        ClosestPointCase::SEnd(s) => {
            let e = dot(d2, d2);
            let t = (dot(d1, d2) * s + dot(d2, r)) / e;
            (S::cst(s), t)
        }
        ClosestPointCase::TEnd(t) => {
            let a = dot(d1, d1);
            let s = (dot(d1, d2) * t - dot(d1, r)) / a;
            (s, S::cst(t))
        }
        ClosestPointCase::Ends(s, t) => (S::cst(s), S::cst(t)),
    };
    let w = sub(add_scaled(r, d1, s), scale(d2, t));
    norm(w)
}

fn add_scaled<S: Scalar>(a: V3<S>, b: V3<S>, s: S) -> V3<S> {
    [a[0] + b[0] * s, a[1] + b[1] * s, a[2] + b[2] * s]
}

/// The distance (m) between two segments given by plain points.
pub fn distance(p0: [f64; 3], p1: [f64; 3], q0: [f64; 3], q1: [f64; 3]) -> f64 {
    let (regime, _, _) = closest_point_case(p0, p1, q0, q1);
    segment_distance::<f64>(lift(p0), lift(p1), lift(q0), lift(q1), regime)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::random_point;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn matches_brute_force_minimum_over_a_fine_grid() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..200 {
            let (p0, p1, q0, q1) = (
                random_point(&mut rng, 1.0),
                random_point(&mut rng, 1.0),
                random_point(&mut rng, 1.0),
                random_point(&mut rng, 1.0),
            );
            let d = distance(p0, p1, q0, q1);
            let mut best = f64::INFINITY;
            let n = 400;
            for i in 0..=n {
                let s = i as f64 / n as f64;
                let p = [
                    p0[0] + s * (p1[0] - p0[0]),
                    p0[1] + s * (p1[1] - p0[1]),
                    p0[2] + s * (p1[2] - p0[2]),
                ];
                // For a fixed p the closest point on the other segment is a clamped projection.
                let d2 = sub(q1, q0);
                let t = (dot(sub(p, q0), d2) / dot(d2, d2)).clamp(0.0, 1.0);
                let q = [q0[0] + t * d2[0], q0[1] + t * d2[1], q0[2] + t * d2[2]];
                best = best.min(norm(sub(p, q)));
            }
            assert!(d <= best + 1e-12 && best - d < 1e-4, "{d} vs {best}");
        }
        // Parallel, overlapping segments at distance 0.5.
        let d = distance(
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.3, 0.5, 0.0],
            [1.7, 0.5, 0.0],
        );
        assert!((d - 0.5).abs() < 1e-15);
    }
}
