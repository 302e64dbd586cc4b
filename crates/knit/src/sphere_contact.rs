//! Contact of yarn vertices with a rigid sphere (for draping): a smooth penalty on the penetration of the
//! yarn's surface into the sphere,
//!
//! `E_s = k ℓ δ³ / (3 r)`,  `δ = max(0, R + r − |x − c|)`
//!
//! - `x` the vertex position (m); `c`, `R` the sphere's centre (m) and radius (m); `r` the yarn radius (m), so
//!   `δ` (m) is how deep the yarn's surface reaches into the sphere;
//! - `ℓ` the vertex's Voronoi length (m): the penalty is a force per unit yarn length, `f = k δ²/r` (N/m),
//!   so refining the yarn does not stiffen the obstacle;
//! - `k` the obstacle stiffness (Pa = J/m³); `E_s` in J.
//!
//! The cubic makes the energy C² (energy, force and stiffness all vanish as contact switches on, so Newton
//! sees no jump), like the yarn–yarn barrier of [`crate::contact`]. The sphere is frictionless.
//!
//! Derivatives by hand, with `d = |x − c|`, `n = (x − c)/d`, `∂δ/∂x = −n`:
//! `∂E/∂x = −(k ℓ δ²/r) n` (N) and `∂²E/∂x² = (2 k ℓ δ/r) n nᵀ − (k ℓ δ²/(r d)) (I − n nᵀ)` (N/m); the
//! second term (the curvature of the sphere) is negative, so the Hessian is indefinite tangentially, which
//! the Newton solver's shift handles. Both are checked against central differences in the tests.

use serde::{Deserialize, Serialize};

/// A rigid sphere obstacle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SphereObstacle {
    /// Centre `c` (m).
    pub center: [f64; 3],
    /// Radius `R` (m).
    pub radius: f64,
    /// Penalty stiffness `k` (Pa).
    pub stiffness: f64,
}

impl SphereObstacle {
    /// Penetration `δ` (m) of a yarn of radius `yarn_radius` (m) centred at `x` (m); negative when apart.
    pub fn penetration(&self, x: [f64; 3], yarn_radius: f64) -> f64 {
        let d = [
            x[0] - self.center[0],
            x[1] - self.center[1],
            x[2] - self.center[2],
        ];
        self.radius + yarn_radius - (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    }

    /// Energy (J), gradient (N) and Hessian (N/m) of a vertex at `x` (m) with Voronoi length `length` (m) of a
    /// yarn of radius `yarn_radius` (m); `None` when the yarn does not touch the sphere.
    #[allow(clippy::type_complexity)]
    pub fn derivatives(
        &self,
        x: [f64; 3],
        yarn_radius: f64,
        length: f64,
    ) -> Option<(f64, [f64; 3], [[f64; 3]; 3])> {
        let v = [
            x[0] - self.center[0],
            x[1] - self.center[1],
            x[2] - self.center[2],
        ];
        let d = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let delta = self.radius + yarn_radius - d;
        if delta <= 0.0 || d <= 0.0 {
            return None;
        }
        let n = [v[0] / d, v[1] / d, v[2] / d];
        let c = self.stiffness * length / yarn_radius;
        let e = c * delta * delta * delta / 3.0;
        let f = c * delta * delta;
        let g = [-f * n[0], -f * n[1], -f * n[2]];
        let mut h = [[0.0; 3]; 3];
        for a in 0..3 {
            for b in 0..3 {
                let id = if a == b { 1.0 } else { 0.0 };
                h[a][b] = 2.0 * c * delta * n[a] * n[b] - f / d * (id - n[a] * n[b]);
            }
        }
        Some((e, g, h))
    }

    /// Checks the sphere's numbers; the message names the one out of range.
    pub fn validate(&self) -> Result<(), String> {
        if self.center.iter().any(|v| !v.is_finite()) {
            return Err(format!(
                "sphere center {:?} must be finite (m)",
                self.center
            ));
        }
        if !(self.radius.is_finite() && self.radius > 0.0) {
            return Err(format!("sphere radius {} must be > 0 (m)", self.radius));
        }
        if !(self.stiffness.is_finite() && self.stiffness > 0.0) {
            return Err(format!(
                "sphere stiffness {} must be > 0 (Pa)",
                self.stiffness
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{check_derivatives, random_point};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    const R: f64 = 1e-3;

    fn sphere() -> SphereObstacle {
        SphereObstacle {
            center: [0.01, -0.02, 0.003],
            radius: 0.05,
            stiffness: 1.0e7,
        }
    }

    fn at_depth(rng: &mut ChaCha8Rng, s: &SphereObstacle, depth: f64) -> [f64; 3] {
        let d = random_point(rng, 1.0);
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let dist = s.radius + R - depth;
        std::array::from_fn(|k| s.center[k] + d[k] / l * dist)
    }

    fn derivatives_or_zero(s: &SphereObstacle, q: &[f64; 3]) -> (f64, [f64; 3], [[f64; 3]; 3]) {
        s.derivatives(*q, R, 1.3e-3)
            .unwrap_or((0.0, [0.0; 3], [[0.0; 3]; 3]))
    }

    #[test]
    fn derivatives_match_central_differences_in_contact() {
        let s = sphere();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for depth in [1e-5, 1e-4, 5e-4, 1.5e-3] {
            for _ in 0..5 {
                let x = at_depth(&mut rng, &s, depth);
                assert!((s.penetration(x, R) - depth).abs() < 1e-12);
                let r = check_derivatives(&x, 1e-8, &|q: &[f64; 3]| derivatives_or_zero(&s, q));
                assert!(
                    r.gradient_error < 1e-6 && r.hessian_error < 1e-5,
                    "depth {depth}: {r:?}"
                );
            }
        }
    }

    #[test]
    fn no_energy_apart_and_a_smooth_switch_on() {
        let s = sphere();
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        for _ in 0..10 {
            let x = at_depth(&mut rng, &s, -1e-6);
            assert!(s.derivatives(x, R, 1e-3).is_none());
        }
        // Energy ∝ δ³, force ∝ δ², stiffness ∝ δ: all vanish at the surface.
        let x1 = at_depth(&mut rng, &s, 1e-6);
        let n: [f64; 3] = std::array::from_fn(|k| x1[k] - s.center[k]);
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let x2: [f64; 3] = std::array::from_fn(|k| s.center[k] + n[k] / l * (s.radius + R - 1e-7));
        let (e1, g1, _) = s.derivatives(x1, R, 1e-3).unwrap();
        let (e2, g2, _) = s.derivatives(x2, R, 1e-3).unwrap();
        assert!((e1 / e2 - 1000.0).abs() < 1e-3 * 1000.0);
        let norm = |g: [f64; 3]| (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        assert!((norm(g1) / norm(g2) - 100.0).abs() < 0.1);
        // The force pushes out of the sphere.
        assert!(g1.iter().zip(&n).map(|(a, b)| a * b).sum::<f64>() < 0.0);
        assert!(
            SphereObstacle {
                radius: -1.0,
                ..sphere()
            }
            .validate()
            .unwrap_err()
            .contains("sphere radius")
        );
    }
}
