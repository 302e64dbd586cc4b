//! Bending energy at one rod vertex with rest curvature (Bergou et al. 2008 Eq. 9 with the vertex curvature of
//! Bergou et al. 2010 "Discrete Viscous Threads" §4; HYLC's yarn model, Sperl et al. 2020 §4):
//!
//! `E_b = k_b / (2 D) · |κ − κ̄|²`
//!
//! - `κ = (κb·(m₂⁰ + m₂¹)/2, −κb·(m₁⁰ + m₁¹)/2)`: the material curvature at the vertex (dimensionless,
//!   integrated; [`crate::frames::vertex_strains`]), `κ̄` the rest curvature (`*RK`);
//! - `D = (L̄⁰ + L̄¹)/2`: the vertex's Voronoi length (m, half the two rest lengths);
//! - `k_b = E π r⁴/4`: the bending stiffness (N·m², isotropic circular yarn);
//! - `E_b` in J.
//!
//! The stencil's 11 unknowns are `q = (x₀, x₁, x₂, θ⁰, θ¹)` (m, m, m, rad, rad). The reference frames are
//! time-parallel transported ([`crate::frames::EdgeFrame`]) so `E_b(q)` is an explicit function; its
//! gradient (N, N·m for the angles) and Hessian are derived by second-order forward automatic
//! differentiation of that closed form ([`crate::jet`]) — exact to rounding, including the dependence of
//! the transported frames on the tangents — and checked against central differences in the tests.

use crate::frames::{EdgeFrame, V3, vertex_strains};
use crate::jet::Scalar;
pub use crate::stencil_energy::{STENCIL_DOFS, StencilEnergy};

/// Positions and angles of a vertex stencil over a [`Scalar`].
pub(crate) fn split_stencil<S: Scalar>(q: &[S; STENCIL_DOFS]) -> ([V3<S>; 3], [S; 2]) {
    (
        [[q[0], q[1], q[2]], [q[3], q[4], q[5]], [q[6], q[7], q[8]]],
        [q[9], q[10]],
    )
}

/// The bending energy of one vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BendingVertex {
    /// Reference frames of the incoming and outgoing edge.
    pub frames: [EdgeFrame; 2],
    /// Rest material curvature `κ̄` (dimensionless).
    pub rest_curvature: [f64; 2],
    /// Voronoi length `D` (m).
    pub voronoi_length: f64,
    /// Bending stiffness `k_b` (N·m²).
    pub stiffness: f64,
}

impl StencilEnergy for BendingVertex {
    /// The energy (J) over any [`Scalar`].
    fn energy_of<S: Scalar>(&self, q: &[S; STENCIL_DOFS]) -> S {
        let (x, theta) = split_stencil(q);
        let s = vertex_strains(x, theta, [&self.frames[0], &self.frames[1]], 0.0);
        let d0 = s.curvature[0] - self.rest_curvature[0];
        let d1 = s.curvature[1] - self.rest_curvature[1];
        (d0 * d0 + d1 * d1) * (0.5 * self.stiffness / self.voronoi_length)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::frames::{cross, norm, scale};
    use crate::test_support::{check_derivatives_steps, random_point};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn unit(v: [f64; 3]) -> [f64; 3] {
        scale(v, 1.0 / norm(v))
    }

    /// A frame whose stored tangent is `t` turned by up to `tilt` rad (so the transport is exercised).
    pub(crate) fn tilted_frame(rng: &mut ChaCha8Rng, t: [f64; 3], tilt: f64) -> EdgeFrame {
        let a = unit([
            t[0] + rng.random_range(-tilt..tilt),
            t[1] + rng.random_range(-tilt..tilt),
            t[2] + rng.random_range(-tilt..tilt),
        ]);
        let d = unit(cross(a, random_point(rng, 1.0)));
        EdgeFrame {
            director: d,
            tangent: a,
        }
    }

    /// A vertex stencil turning by about `angle` rad, edges ~1 mm, random angles and tilted frames.
    pub(crate) fn random_stencil(
        rng: &mut ChaCha8Rng,
        angle: f64,
    ) -> ([f64; STENCIL_DOFS], [EdgeFrame; 2]) {
        let l = 1e-3;
        let x0 = random_point(rng, l);
        let t0 = unit(random_point(rng, 1.0));
        let x1 = [x0[0] + l * t0[0], x0[1] + l * t0[1], x0[2] + l * t0[2]];
        let axis = unit(cross(t0, random_point(rng, 1.0)));
        // Rotate t0 about axis by `angle` (Rodrigues; axis ⊥ t0).
        let c = angle.cos();
        let s = angle.sin();
        let bt = cross(axis, t0);
        let t1 = [
            c * t0[0] + s * bt[0],
            c * t0[1] + s * bt[1],
            c * t0[2] + s * bt[2],
        ];
        let l1 = 0.8 * l;
        let x2 = [x1[0] + l1 * t1[0], x1[1] + l1 * t1[1], x1[2] + l1 * t1[2]];
        let q = [
            x0[0],
            x0[1],
            x0[2],
            x1[0],
            x1[1],
            x1[2],
            x2[0],
            x2[1],
            x2[2],
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
        ];
        let frames = [tilted_frame(rng, t0, 0.3), tilted_frame(rng, t1, 0.3)];
        (q, frames)
    }

    pub(crate) fn stencil_steps() -> [f64; STENCIL_DOFS] {
        let mut steps = [1e-8; STENCIL_DOFS];
        steps[9] = 1e-5;
        steps[10] = 1e-5;
        steps
    }

    #[test]
    fn derivatives_match_central_differences_straight_to_strongly_bent() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for (case, angle) in [
            ("nearly straight", 1e-3),
            ("moderate", 0.6),
            ("strongly bent", 2.6),
        ] {
            for _ in 0..4 {
                let (q, frames) = random_stencil(&mut rng, angle);
                let vertex = BendingVertex {
                    frames,
                    rest_curvature: [rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5)],
                    voronoi_length: 9e-4,
                    stiffness: 7.85e-7,
                };
                let r =
                    check_derivatives_steps(&q, &stencil_steps(), &|q: &[f64; STENCIL_DOFS]| {
                        vertex.derivatives(q)
                    });
                eprintln!("FD {case}: {r:?}");
                assert!(
                    r.gradient_error < 1e-6 && r.hessian_error < 1e-5,
                    "{case}: {r:?}"
                );
                assert_eq!(vertex.energy(&q), vertex.derivatives(&q).0);
            }
        }
    }

    #[test]
    fn energy_vanishes_at_rest_curvature_and_is_rigid_invariant() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (q, frames) = random_stencil(&mut rng, 0.9);
        let (x, th) = split_stencil(&q);
        let s = vertex_strains(x, th, [&frames[0], &frames[1]], 0.0);
        let vertex = BendingVertex {
            frames,
            rest_curvature: s.curvature,
            voronoi_length: 1e-3,
            stiffness: 1e-6,
        };
        let (e, g, _) = vertex.derivatives(&q);
        assert!(e.abs() < 1e-25, "{e}");
        assert!(g.iter().all(|v| v.abs() < 1e-15));
        // Translation invariance: the gradient sums to zero over the three positions.
        let vertex = BendingVertex {
            rest_curvature: [0.0, 0.0],
            ..vertex
        };
        let (_, g, _) = vertex.derivatives(&q);
        for a in 0..3 {
            let sum = g[a] + g[3 + a] + g[6 + a];
            assert!(
                sum.abs() < 1e-9 * g.iter().fold(0.0f64, |m, v| m.max(v.abs())),
                "{sum}"
            );
        }
    }
}
