//! Strain of one cloth triangle for the design terms that look at stretches and stresses
//! ([`crate::stretch_window`], [`crate::seam_traction`]), and the chain rule from a derivative with
//! respect to `C` back to the cloth and pattern corners.
//!
//! Conventions (those of `skintight_physics::membrane_element`):
//! - cloth corners `x0, x1, x2` (m), pattern corners `X̄0, X̄1, X̄2` (m);
//! - `Ds = [x1 − x0, x2 − x0]` (3 × 2, m), `Dm = [X̄1 − X̄0, X̄2 − X̄0]` (2 × 2, m);
//! - `F = Ds Dm⁻¹` (3 × 2), `C = FᵀF` (2 × 2, dimensionless), `A = det(Dm)/2` (m², the rest area of a
//!   counter-clockwise pattern triangle);
//! - `C = μ1 n1n1ᵀ + μ2 n2n2ᵀ` with `μ1 ≥ μ2 ≥ 0` (squared principal stretches) and unit `n1 ⊥ n2`.
//!
//! For a scalar `Q(C)` with symmetric `G = ∂Q/∂C` (so `δQ = G : δC`):
//!
//! ```text
//! δC = δFᵀF + FᵀδF            ⇒ ∂Q/∂F  = 2 F G,
//! δF = δDs Dm⁻¹               ⇒ ∂Q/∂Ds = 2 F G Dm⁻ᵀ,
//! δF = −F δDm Dm⁻¹            ⇒ ∂Q/∂Dm = −2 C G Dm⁻ᵀ,
//! δA = A tr(Dm⁻¹ δDm)         ⇒ ∂A/∂Dm = A Dm⁻ᵀ,
//! ```
//!
//! and `∂/∂Ds`, `∂/∂Dm` go to the corners as `(−col0 − col1, col0, col1)`.

use crate::math::{Mat2, Mat3x2, Real, Vec2, Vec3};
use crate::term::{Residuals, TermGradient};

/// Kinematics of one triangle; see the module documentation.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriangleStrain {
    /// `F` (3 × 2).
    pub f: Mat3x2,
    /// `C = FᵀF` (2 × 2).
    pub c: Mat2,
    /// `Dm⁻¹` (1/m).
    pub dm_inv: Mat2,
    /// Rest area `A` (m²), positive.
    pub area: Real,
    /// Eigenvalues of `C`, `μ1 ≥ μ2 ≥ 0` (squared principal stretches).
    pub mu: [Real; 2],
    /// Unit eigenvectors of `C` in the pattern plane, `n[i]` for `mu[i]`.
    pub n: [Vec2; 2],
}

impl TriangleStrain {
    /// The strain of the triangle with cloth corners `x` and pattern corners `rest`; `None` when the
    /// pattern triangle is degenerate or clockwise (signed area at most `1e-12` times its squared longest
    /// edge).
    pub fn new(x: &[Vec3; 3], rest: &[Vec2; 3]) -> Option<Self> {
        let e1 = rest[1] - rest[0];
        let e2 = rest[2] - rest[0];
        let det = e1.perp(&e2);
        let longest = e1
            .norm_squared()
            .max(e2.norm_squared())
            .max((rest[2] - rest[1]).norm_squared());
        if !(det > 2e-12 * longest && det.is_finite()) {
            return None;
        }
        let dm_inv = Mat2::new(e2.y, -e2.x, -e1.y, e1.x) / det;
        let ds = Mat3x2::from_columns(&[x[1] - x[0], x[2] - x[0]]);
        let f = ds * dm_inv;
        let c = f.transpose() * f;
        // Symmetrise exactly (rounding can leave c12 ≠ c21 by an ulp).
        let (p, q, r) = (c[(0, 0)], 0.5 * (c[(0, 1)] + c[(1, 0)]), c[(1, 1)]);
        let c = Mat2::new(p, q, q, r);
        let mean = 0.5 * (p + r);
        let half_gap = (0.5 * (p - r)).hypot(q);
        // The smaller eigenvalue from det C = |f0 × f1|² (columns of F), which stays accurate
        // when the cloth triangle is nearly collapsed (mean − half_gap would cancel).
        let mu1 = mean + half_gap;
        let det_c = f.column(0).cross(&f.column(1)).norm_squared();
        let mu2 = if mu1 > 0.0 {
            (det_c / mu1).min(mu1)
        } else {
            0.0
        };
        let mu = [mu1, mu2];
        // Eigenvector of the larger eigenvalue at angle θ = ½ atan2(2 C12, C11 − C22) (θ = 0 when C = sI).
        let theta = 0.5 * (2.0 * q).atan2(p - r);
        let (sin, cos) = theta.sin_cos();
        let n = [Vec2::new(cos, sin), Vec2::new(-sin, cos)];
        Some(Self {
            f,
            c,
            dm_inv,
            area: 0.5 * det,
            mu,
            n,
        })
    }

    /// `(∂Q/∂x, ∂Q/∂X̄)` per corner (units of Q per m) for a scalar `Q(C)` with `G = ∂Q/∂C` (symmetric).
    pub fn corner_gradients_from_c(&self, g: &Mat2) -> ([Vec3; 3], [Vec2; 3]) {
        let dm_inv_t = self.dm_inv.transpose();
        let d_ds = self.f * g * dm_inv_t * 2.0;
        let d_dm = self.c * g * dm_inv_t * (-2.0);
        (scatter3(&d_ds), scatter2(&d_dm))
    }

    /// `∂A/∂X̄` per corner (m).
    pub fn area_gradient(&self) -> [Vec2; 3] {
        scatter2(&(self.dm_inv.transpose() * self.area))
    }

    /// Adds the derivatives of `w A Φ(C)` — a penalty `Φ` (dimensionless, value `phi`, `G = ∂Φ/∂C`
    /// symmetric) weighted by the rest area — into `grad` at the triangle's cloth corners `cloth` and
    /// pattern corners `pattern`: `∂/∂x = w A ∂Φ/∂x`, `∂/∂X̄ = w (A ∂Φ/∂X̄ + Φ ∂A/∂X̄)`.
    pub fn add_area_weighted_gradient(
        &self,
        weight: Real,
        phi: Real,
        g: &Mat2,
        cloth: [usize; 3],
        pattern: [usize; 3],
        grad: &mut TermGradient,
    ) {
        let (dx, dr) = self.corner_gradients_from_c(g);
        let da = self.area_gradient();
        let scale = weight * self.area;
        for k in 0..3 {
            grad.cloth[cloth[k]] += dx[k] * scale;
            grad.pattern[pattern[k]] += dr[k] * scale + da[k] * (weight * phi);
        }
    }

    /// Appends the residual `r = √(w A) e` (`e` dimensionless, `G = ∂e/∂C` symmetric) with its Jacobian
    /// rows at the triangle's cloth corners `cloth` and pattern corners `pattern`:
    /// `∂r = √w (e/(2√A) ∂A + √A ∂e)`.
    pub fn push_area_weighted_residual(
        &self,
        weight: Real,
        e: Real,
        g: &Mat2,
        cloth: [usize; 3],
        pattern: [usize; 3],
        out: &mut Residuals,
    ) {
        let root = (weight * self.area).sqrt();
        let k = out.values.len();
        out.values.push(root * e);
        let (dx, dr) = self.corner_gradients_from_c(g);
        let da = self.area_gradient();
        let area_factor = weight.sqrt() * e * 0.5 / self.area.sqrt();
        for c in 0..3 {
            let dxc: Vec3 = dx[c] * root;
            let drc: Vec2 = dr[c] * root + da[c] * area_factor;
            out.cloth_jacobian.push((k, cloth[c], dxc));
            out.pattern_jacobian.push((k, pattern[c], drc));
        }
    }
}

/// Gathers a 3 × 2 `∂/∂Ds` into the three corners.
fn scatter3(g: &Mat3x2) -> [Vec3; 3] {
    let (c0, c1): (Vec3, Vec3) = (g.column(0).into(), g.column(1).into());
    [-c0 - c1, c0, c1]
}

/// Gathers a 2 × 2 `∂/∂Dm` into the three corners.
fn scatter2(g: &Mat2) -> [Vec2; 3] {
    let (c0, c1): (Vec2, Vec2) = (g.column(0).into(), g.column(1).into());
    [-c0 - c1, c0, c1]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Real;
    use skintight_geometry::finite_difference::{FdParams, check_gradient};

    fn corners(v: &[Real]) -> ([Vec3; 3], [Vec2; 3]) {
        let x = [0, 1, 2].map(|i| Vec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]));
        let r = [0, 1, 2].map(|i| Vec2::new(v[9 + 2 * i], v[10 + 2 * i]));
        (x, r)
    }

    #[test]
    fn chain_rule_matches_finite_differences() {
        // Q(C) = C : M with a fixed symmetric M, so G = M; and the rest area.
        let m = Mat2::new(0.7, -0.3, -0.3, 1.9);
        let v = [
            0.01, 0.02, -0.03, 1.2, 0.1, 0.2, 0.2, 0.9, -0.1, 0.05, -0.02, 0.95, 0.1, 0.15, 1.05,
        ];
        let q = |v: &[Real]| {
            let (x, r) = corners(v);
            let s = TriangleStrain::new(&x, &r).unwrap();
            s.c.component_mul(&m).sum()
        };
        let (x, r) = corners(&v);
        let s = TriangleStrain::new(&x, &r).unwrap();
        let (gx, gr) = s.corner_gradients_from_c(&m);
        let mut grad: Vec<Real> = gx.iter().flat_map(|g| g.iter().copied()).collect();
        grad.extend(gr.iter().flat_map(|g| g.iter().copied()));
        check_gradient(q, &v, &grad, &FdParams::default()).unwrap();
        let area = |v: &[Real]| {
            let (x, r) = corners(v);
            TriangleStrain::new(&x, &r).unwrap().area
        };
        let mut grad = vec![0.0; 9];
        grad.extend(s.area_gradient().iter().flat_map(|g| g.iter().copied()));
        check_gradient(area, &v, &grad, &FdParams::default()).unwrap();
        // Eigen-decomposition reproduces C.
        let back = s.n[0] * s.n[0].transpose() * s.mu[0] + s.n[1] * s.n[1].transpose() * s.mu[1];
        assert!((back - s.c).abs().max() < 1e-12);
        assert!(s.mu[0] >= s.mu[1]);
    }

    #[test]
    fn degenerate_or_clockwise_patterns_are_rejected() {
        let x = [Vec3::zeros(), Vec3::x(), Vec3::y()];
        let line = [Vec2::zeros(), Vec2::x(), Vec2::new(2.0, 0.0)];
        assert!(TriangleStrain::new(&x, &line).is_none());
        let cw = [Vec2::zeros(), Vec2::y(), Vec2::x()];
        assert!(TriangleStrain::new(&x, &cw).is_none());
        let ccw = [Vec2::zeros(), Vec2::x(), Vec2::y()];
        assert!(TriangleStrain::new(&x, &ccw).is_some());
    }
}
