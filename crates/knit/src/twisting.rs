//! Twisting energy at one rod vertex with rest twist (Bergou et al. 2008 Eq. 10; 2010 §4; HYLC, Sperl et al.
//! 2020 §4):
//!
//! `E_t = k_t / (2 D) · (m − m̄)²`,  `m = θ¹ − θ⁰ + m_ref`
//!
//! - `θ⁰, θ¹`: the material angles of the incoming and outgoing edge (rad), `m_ref` the reference twist of
//!   the time-parallel transported reference frames ([`crate::frames::vertex_strains`]), `m̄` the rest twist
//!   (`*RT`, rad);
//! - `D = (L̄⁰ + L̄¹)/2` (m); `k_t = G π r⁴/2` the twisting stiffness (N·m², `G = E / (2(1 + ν))`);
//! - `E_t` in J.
//!
//! Unknowns `q = (x₀, x₁, x₂, θ⁰, θ¹)`. Gradient and Hessian by second-order forward automatic
//! differentiation of the closed form ([`crate::jet`]), exact to rounding; the position derivatives come from
//! the reference twist's dependence on the tangents (DER's `∂m/∂e = κb/(2|e|)` at a freshly transported
//! frame, plus the transport terms away from it), all captured by the differentiation and checked against
//! central differences in the tests.

use crate::bending::split_stencil;
use crate::frames::{EdgeFrame, vertex_strains};
use crate::jet::Scalar;
use crate::stencil_energy::{STENCIL_DOFS, StencilEnergy};

/// The twisting energy of one vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwistingVertex {
    /// Reference frames of the incoming and outgoing edge.
    pub frames: [EdgeFrame; 2],
    /// Rest twist `m̄` (rad).
    pub rest_twist: f64,
    /// Reference twist of the last evaluation (rad): selects the 2π-branch.
    pub reference_twist_hint: f64,
    /// Voronoi length `D` (m).
    pub voronoi_length: f64,
    /// Twisting stiffness `k_t` (N·m²).
    pub stiffness: f64,
}

impl StencilEnergy for TwistingVertex {
    /// The energy (J) over any [`Scalar`].
    fn energy_of<S: Scalar>(&self, q: &[S; STENCIL_DOFS]) -> S {
        let (x, theta) = split_stencil(q);
        let s = vertex_strains(
            x,
            theta,
            [&self.frames[0], &self.frames[1]],
            self.reference_twist_hint,
        );
        let d = s.twist - self.rest_twist;
        d * d * (0.5 * self.stiffness / self.voronoi_length)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bending::tests::{random_stencil, stencil_steps};
    use crate::test_support::check_derivatives_steps;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn derivatives_match_central_differences_straight_to_strongly_bent() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for (case, angle) in [
            ("nearly straight", 1e-3),
            ("moderate", 0.6),
            ("strongly bent", 2.6),
        ] {
            for _ in 0..4 {
                let (q, frames) = random_stencil(&mut rng, angle);
                let vertex = TwistingVertex {
                    frames,
                    rest_twist: rng.random_range(-0.5..0.5),
                    reference_twist_hint: 0.0,
                    voronoi_length: 9e-4,
                    stiffness: 6.0e-7,
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
            }
        }
    }

    #[test]
    fn twist_depends_on_angle_difference_only() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let (q, frames) = random_stencil(&mut rng, 0.4);
        let vertex = TwistingVertex {
            frames,
            rest_twist: 0.1,
            reference_twist_hint: 0.0,
            voronoi_length: 1e-3,
            stiffness: 1e-6,
        };
        let mut shifted = q;
        shifted[9] += 0.37;
        shifted[10] += 0.37;
        assert!(
            (vertex.energy(&q) - vertex.energy(&shifted)).abs()
                < 1e-12 * vertex.energy(&q).max(1e-30)
        );
        let (_, g, _) = vertex.derivatives(&q);
        assert!((g[9] + g[10]).abs() < 1e-9 * g[10].abs().max(1e-30));
    }
}
