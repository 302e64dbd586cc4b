//! Frames of the discrete elastic rod (Bergou et al. 2008 "Discrete Elastic Rods", §4–5; Bergou et al. 2010
//! "Discrete Viscous Threads", §4): parallel transport, the time-parallel-transported reference frame of an
//! edge, the curvature binormal and material curvatures at a vertex, and the reference twist.
//!
//! Conventions (those of the `.pyp` data, checked in `pyp` tests: the stored reference twists are reproduced
//! to float precision):
//! - edge `e = x₁ − x₀`, tangent `t = e/|e|`;
//! - reference frame `(u, v = t × u)`; the material frame at angle `θ`:
//!   `m₁ = cos θ u + sin θ v`, `m₂ = −sin θ u + cos θ v`;
//! - a vertex between edge `e⁰` (incoming) and `e¹` (outgoing) has the curvature binormal
//!   `κb = 2 e⁰ × e¹ / (|e⁰||e¹| + e⁰·e¹)` (|κb| = 2 tan(φ/2), φ the turning angle) and the material
//!   curvature `κ = (κb · (m₂⁰ + m₂¹)/2, −κb · (m₁⁰ + m₁¹)/2)` (Discrete Viscous Threads, Eq. 1 averaged over
//!   the two edges);
//! - the reference twist at the vertex is the signed angle, about `t¹`, from the space-parallel transport
//!   `P_{t⁰→t¹} u⁰` to `u¹`; the twist is `m = θ¹ − θ⁰ + reference twist`.
//!
//! **Time-parallel transport** (DER §5): an edge's reference director is stored as `ū` together with the
//! tangent `a` it was last transported to; at any configuration `u = P_{a→t} ū`. This makes every energy an
//! explicit function of positions and angles, so its derivatives are exact (they are computed with
//! [`crate::jet`]). When a tangent turns far from `a` the frame is re-based (`ū ← u`, `a ← t`), which
//! leaves `u` — and the energy — unchanged at that configuration.

use crate::jet::Scalar;

/// A 3-vector over a [`Scalar`].
pub type V3<S> = [S; 3];

/// `a + b`.
pub fn add<S: Scalar>(a: V3<S>, b: V3<S>) -> V3<S> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`.
pub fn sub<S: Scalar>(a: V3<S>, b: V3<S>) -> V3<S> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `s a`.
pub fn scale<S: Scalar>(a: V3<S>, s: S) -> V3<S> {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// `a · b`.
pub fn dot<S: Scalar>(a: V3<S>, b: V3<S>) -> S {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a × b`.
pub fn cross<S: Scalar>(a: V3<S>, b: V3<S>) -> V3<S> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `|a|`.
pub fn norm<S: Scalar>(a: V3<S>) -> S {
    dot(a, a).sqrt()
}

/// A constant vector lifted to `S`.
pub fn lift<S: Scalar>(a: [f64; 3]) -> V3<S> {
    [S::cst(a[0]), S::cst(a[1]), S::cst(a[2])]
}

/// The parallel transport of `u` from unit tangent `t0` to unit tangent `t1`: the rotation about
/// `b = t0 × t1` taking `t0` to `t1`, `P u = (t0·t1) u + b × u + (b·u) b / (1 + t0·t1)` (Rodrigues with
/// `|b| = sin φ`). Undefined for opposite tangents (`t0·t1 = −1`).
pub fn parallel_transport<S: Scalar>(u: V3<S>, t0: V3<S>, t1: V3<S>) -> V3<S> {
    let b = cross(t0, t1);
    let c = dot(t0, t1);
    let bu = dot(b, u);
    add(add(scale(u, c), cross(b, u)), scale(b, bu / (c + 1.0)))
}

/// The signed angle (rad) from `a` to `b` about the axis `n` (both perpendicular to the unit `n`).
pub fn signed_angle<S: Scalar>(a: V3<S>, b: V3<S>, n: V3<S>) -> S {
    dot(cross(a, b), n).atan2(dot(a, b))
}

/// The reference frame of one edge under time-parallel transport: the stored director `ū` (unit, ⊥ `a`)
/// and the unit tangent `a` it belongs to.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EdgeFrame {
    /// Stored reference director `ū` (unit).
    pub director: [f64; 3],
    /// Unit tangent `a` the director was last transported to.
    pub tangent: [f64; 3],
}

impl EdgeFrame {
    /// The reference director `u = P_{a→t} ū` at the unit tangent `t`.
    pub fn director_at<S: Scalar>(&self, t: V3<S>) -> V3<S> {
        parallel_transport(lift(self.director), lift(self.tangent), t)
    }

    /// Re-bases the frame on the unit tangent `t` (`ū ← P_{a→t} ū`, `a ← t`).
    pub fn rebase(&mut self, t: [f64; 3]) {
        let u = self.director_at(t);
        // Remove rounding drift: keep u unit and ⊥ t.
        let u = sub(u, scale(t, dot(u, t)));
        let l = norm(u);
        self.director = scale(u, 1.0 / l);
        self.tangent = t;
    }
}

/// The bending and twisting quantities at one vertex, from the three vertex positions `x0, x1, x2` (edges
/// `e⁰ = x1 − x0`, `e¹ = x2 − x1`) and the two edge angles `θ⁰, θ¹`.
#[derive(Clone, Copy, Debug)]
pub struct VertexStrains<S> {
    /// Material curvature `(κ₁, κ₂)` (dimensionless, integrated).
    pub curvature: [S; 2],
    /// Twist `m = θ¹ − θ⁰ + reference twist` (rad).
    pub twist: S,
    /// Reference twist (rad), on the 2π-branch nearest the hint.
    pub reference_twist: S,
}

/// Evaluates [`VertexStrains`] at one vertex. `frames` are the time-parallel reference frames of `e⁰` and
/// `e¹`; `twist_hint` (rad) picks the 2π-branch of the reference twist (the stored value of the rest state
/// or the previous iterate).
pub fn vertex_strains<S: Scalar>(
    x: [V3<S>; 3],
    theta: [S; 2],
    frames: [&EdgeFrame; 2],
    twist_hint: f64,
) -> VertexStrains<S> {
    vertex_strains_of_edges(
        [sub(x[1], x[0]), sub(x[2], x[1])],
        theta,
        frames,
        twist_hint,
    )
}

/// [`vertex_strains`] from the two edge vectors `e⁰, e¹` (m) instead of the three positions: the strains
/// depend on the positions only through them, so differentiating over `(e⁰, e¹, θ⁰, θ¹)` — 8 variables
/// instead of 11 — and mapping back is the cheaper way to the stencil's derivatives
/// ([`crate::rod_vertex::RodVertex::derivatives`]).
pub fn vertex_strains_of_edges<S: Scalar>(
    e: [V3<S>; 2],
    theta: [S; 2],
    frames: [&EdgeFrame; 2],
    twist_hint: f64,
) -> VertexStrains<S> {
    let [e0, e1] = e;
    let l0 = norm(e0);
    let l1 = norm(e1);
    let t0 = scale(e0, S::cst(1.0) / l0);
    let t1 = scale(e1, S::cst(1.0) / l1);
    let kb = scale(cross(e0, e1), S::cst(2.0) / (l0 * l1 + dot(e0, e1)));
    let u0 = frames[0].director_at(t0);
    let u1 = frames[1].director_at(t1);
    let material = |u: V3<S>, t: V3<S>, th: S| {
        let v = cross(t, u);
        let (c, s) = cos_sin(th);
        let m1 = add(scale(u, c), scale(v, s));
        let m2 = sub(scale(v, c), scale(u, s));
        (m1, m2)
    };
    let (m1a, m2a) = material(u0, t0, theta[0]);
    let (m1b, m2b) = material(u1, t1, theta[1]);
    let curvature = [
        dot(kb, add(m2a, m2b)) * 0.5,
        -(dot(kb, add(m1a, m1b)) * 0.5),
    ];
    let transported = parallel_transport(u0, t0, t1);
    let mut reference_twist = signed_angle(transported, u1, t1);
    let turns = ((twist_hint - reference_twist.value()) / std::f64::consts::TAU).round();
    reference_twist = reference_twist + turns * std::f64::consts::TAU;
    VertexStrains {
        curvature,
        twist: theta[1] - theta[0] + reference_twist,
        reference_twist,
    }
}

/// `(cos θ, sin θ)` for a [`Scalar`], through `atan2`-free identities: evaluated on the value and
/// differentiated with `d cos = −sin dθ`, `d sin = cos dθ`.
pub fn cos_sin<S: Scalar>(theta: S) -> (S, S) {
    let v = theta.value();
    let (s, c) = v.sin_cos();
    // cos θ ≈ c − s δ − c δ²/2, sin θ ≈ s + c δ − s δ²/2 with δ = θ − v (exact to second order).
    let d = theta - v;
    let d2 = d * d * 0.5;
    (S::cst(c) - d * s - d2 * c, S::cst(s) + d * c - d2 * s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parallel_transport_maps_tangent_and_preserves_angles() {
        let t0 = [1.0, 0.0, 0.0];
        let t1 = {
            let v = [0.6, 0.7, -0.2];
            let l = norm(v);
            scale(v, 1.0 / l)
        };
        let p = parallel_transport(t0, t0, t1);
        for k in 0..3 {
            assert!((p[k] - t1[k]).abs() < 1e-14);
        }
        let u = [0.0, 0.6, 0.8];
        let pu = parallel_transport(u, t0, t1);
        assert!((norm(pu) - 1.0).abs() < 1e-14);
        assert!(dot(pu, t1).abs() < 1e-14);
        // The binormal is fixed.
        let b = cross(t0, t1);
        let pb = parallel_transport(b, t0, t1);
        for k in 0..3 {
            assert!((pb[k] - b[k]).abs() < 1e-14);
        }
    }

    #[test]
    fn cos_sin_is_exact_to_second_order() {
        use crate::jet::{Jet, value_gradient_hessian};
        let (v, g, h) = value_gradient_hessian(&[0.8], |t: &[Jet<1>; 1]| cos_sin(t[0]).0);
        assert!((v - 0.8f64.cos()).abs() < 1e-15);
        assert!((g[0] + 0.8f64.sin()).abs() < 1e-15);
        assert!((h[0][0] + 0.8f64.cos()).abs() < 1e-15);
    }
}
