//! Bending and twisting of one rod vertex evaluated together: `E_b + E_t` ([`crate::bending`],
//! [`crate::twisting`]; J) on the 11-unknown vertex stencil (m, rad). Both energies are functions of the
//! same vertex strains ([`crate::frames::vertex_strains`]: the material curvature `κ` and the twist `m`),
//! so one second-order jet pass ([`crate::jet`]) computes the strains once and differentiates the sum —
//! half the jet work of differentiating the two energies apart, which is what the patch evaluation spends
//! most of its time on (issue 19's speed-up). The derivatives are those of the two modules (exact to
//! rounding); the tests check the sum against the two separate evaluations and central differences.
//!
//! The jets run over the 8 variables the strains depend on, `r = (e⁰, e¹, θ⁰, θ¹)` with `e⁰ = x₁ − x₀` and
//! `e¹ = x₂ − x₁` ([`crate::frames::vertex_strains_of_edges`]), not over the 11 stencil unknowns: a jet of
//! 8 carries 73 numbers against 133, and the chain rule back to the stencil is the constant linear map
//! `r = A q`: `∇_q E = Aᵀ ∇_r E`, `∇²_q E = Aᵀ ∇²_r E A` (`A` has entries ±1; [`expand`]).

use crate::bending::{BendingVertex, split_stencil};
use crate::frames::{V3, sub, vertex_strains_of_edges};
use crate::jet::{Jet, Scalar};
use crate::stencil_energy::STENCIL_DOFS;
use crate::twisting::TwistingVertex;

/// The bending and the twisting energy of one vertex (the same frames and Voronoi length in both).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RodVertex {
    /// The bending term.
    pub bending: BendingVertex,
    /// The twisting term (its frames are the ones used for the strains).
    pub twisting: TwistingVertex,
}

impl RodVertex {
    /// `[E_b, E_t]` (J) over any [`Scalar`], from one evaluation of the vertex strains.
    pub fn energies_of<S: Scalar>(&self, q: &[S; STENCIL_DOFS]) -> [S; 2] {
        let (x, theta) = split_stencil(q);
        self.energies_of_edges([sub(x[1], x[0]), sub(x[2], x[1])], theta)
    }

    /// `[E_b, E_t]` (J) from the edge vectors `e⁰, e¹` (m) and the edge angles (rad).
    fn energies_of_edges<S: Scalar>(&self, e: [V3<S>; 2], theta: [S; 2]) -> [S; 2] {
        let t = &self.twisting;
        let s = vertex_strains_of_edges(
            e,
            theta,
            [&t.frames[0], &t.frames[1]],
            t.reference_twist_hint,
        );
        let b = &self.bending;
        let d0 = s.curvature[0] - b.rest_curvature[0];
        let d1 = s.curvature[1] - b.rest_curvature[1];
        let bend = (d0 * d0 + d1 * d1) * (0.5 * b.stiffness / b.voronoi_length);
        let d = s.twist - t.rest_twist;
        let twist = d * d * (0.5 * t.stiffness / t.voronoi_length);
        [bend, twist]
    }

    /// `[E_b, E_t]` (J).
    pub fn energies(&self, q: &[f64; STENCIL_DOFS]) -> [f64; 2] {
        self.energies_of(q)
    }

    /// `[E_b, E_t]` (J) and the gradient and Hessian of their sum over the 11 stencil unknowns.
    #[allow(clippy::type_complexity)]
    pub fn derivatives(
        &self,
        q: &[f64; STENCIL_DOFS],
    ) -> (
        [f64; 2],
        [f64; STENCIL_DOFS],
        [[f64; STENCIL_DOFS]; STENCIL_DOFS],
    ) {
        // r = (e⁰, e¹, θ⁰, θ¹), each edge component computed as in `energies_of`.
        let r: [f64; EDGE_VARS] = std::array::from_fn(|a| match a {
            // e⁰ = x₁ − x₀, then e¹ = x₂ − x₁: both are q[a + 3] − q[a].
            0..6 => q[3 + a] - q[a],
            _ => q[a + 3],
        });
        let v: [Jet<EDGE_VARS>; EDGE_VARS] = std::array::from_fn(|a| Jet::var(r[a], a));
        let [b, t] = self.energies_of_edges([[v[0], v[1], v[2]], [v[3], v[4], v[5]]], [v[6], v[7]]);
        let values = [b.v, t.v];
        let (g, h) = expand(&(b + t));
        (values, g, h)
    }
}

/// The variables the strains depend on: `(e⁰, e¹, θ⁰, θ¹)`.
const EDGE_VARS: usize = 8;

/// The stencil unknowns' derivatives from those over `r = (e⁰, e¹, θ⁰, θ¹)`: `g = Aᵀ ∇_r`, `H = Aᵀ ∇²_r A`,
/// with row `q` of `Aᵀ` the `(r index, ±1)` pairs below (`x₀` enters `e⁰` with −1, `x₁` enters `e⁰` with +1
/// and `e¹` with −1, `x₂` enters `e¹` with +1, the angles themselves).
#[allow(clippy::type_complexity)]
fn expand(jet: &Jet<EDGE_VARS>) -> ([f64; STENCIL_DOFS], [[f64; STENCIL_DOFS]; STENCIL_DOFS]) {
    let column = |i: usize| -> [(usize, f64); 2] {
        match i {
            0..3 => [(i, -1.0), (i, 0.0)],
            3..6 => [(i - 3, 1.0), (i, -1.0)],
            // x₂ and the two angles: one entry each (the second is padding).
            _ => [(i - 3, 1.0), (i - 3, 0.0)],
        }
    };
    let mut g = [0.0; STENCIL_DOFS];
    let mut h = [[0.0; STENCIL_DOFS]; STENCIL_DOFS];
    for i in 0..STENCIL_DOFS {
        let ci = column(i);
        g[i] = ci.iter().map(|&(a, c)| c * jet.g[a]).sum();
        for j in 0..=i {
            let cj = column(j);
            let mut sum = 0.0;
            for &(a, c) in &ci {
                for &(b, d) in &cj {
                    sum += c * d * jet.h[a][b];
                }
            }
            h[i][j] = sum;
            h[j][i] = sum;
        }
    }
    (g, h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bending::tests::{random_stencil, stencil_steps};
    use crate::stencil_energy::StencilEnergy;
    use crate::test_support::check_derivatives_steps;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn the_joint_evaluation_equals_bending_plus_twisting() {
        let mut rng = ChaCha8Rng::seed_from_u64(31);
        for angle in [1e-3, 0.6, 2.6] {
            for _ in 0..4 {
                let (q, frames) = random_stencil(&mut rng, angle);
                let v = RodVertex {
                    bending: BendingVertex {
                        frames,
                        rest_curvature: [rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3)],
                        voronoi_length: 9e-4,
                        stiffness: 7.0e-7,
                    },
                    twisting: TwistingVertex {
                        frames,
                        rest_twist: rng.random_range(-0.5..0.5),
                        reference_twist_hint: 0.0,
                        voronoi_length: 9e-4,
                        stiffness: 5.0e-7,
                    },
                };
                let (eb, gb, hb) = v.bending.derivatives(&q);
                let (et, gt, ht) = v.twisting.derivatives(&q);
                let ([b, t], g, h) = v.derivatives(&q);
                assert_eq!(
                    v.energies(&q),
                    [v.bending.energy(&q), v.twisting.energy(&q)]
                );
                assert!((b - eb).abs() <= 1e-13 * eb.abs().max(1e-30), "{b} vs {eb}");
                assert!((t - et).abs() <= 1e-13 * et.abs().max(1e-30), "{t} vs {et}");
                let gmax = g.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                let hmax = h.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
                for i in 0..STENCIL_DOFS {
                    assert!((g[i] - gb[i] - gt[i]).abs() <= 1e-12 * gmax, "g[{i}]");
                    for j in 0..STENCIL_DOFS {
                        assert!(
                            (h[i][j] - hb[i][j] - ht[i][j]).abs() <= 1e-12 * hmax,
                            "h[{i}][{j}]"
                        );
                    }
                }
                let r =
                    check_derivatives_steps(&q, &stencil_steps(), &|q: &[f64; STENCIL_DOFS]| {
                        let ([b, t], g, h) = v.derivatives(q);
                        (b + t, g, h)
                    });
                assert!(r.gradient_error < 1e-6 && r.hessian_error < 1e-5, "{r:?}");
            }
        }
    }
}
