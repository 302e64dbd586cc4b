//! Stretching energy of one rod edge (Bergou et al. 2008, §4.1 / 2010 §4: `E_s = ½ k_s (|e|/L̄ − 1)² L̄`).
//!
//! - `e = x₁ − x₀` the edge (m), `L̄` its rest length (m), `ε = |e|/L̄ − 1` the axial strain;
//! - `k_s = E A` the axial stiffness (N; Young's modulus `E` in Pa times the cross-section `A = π r²`);
//! - `E_s = ½ k_s L̄ ε²` (J).
//!
//! Derivatives, by hand (closed form): with `t = e/|e|`, `∂ε/∂e = t/L̄`, so `∂E/∂e = k_s ε t` (N) and
//! `∂²E/∂e² = (k_s/L̄) t tᵀ + (k_s ε/|e|)(I − t tᵀ)` (N/m); `∂/∂x₁ = ∂/∂e = −∂/∂x₀`. The Hessian is
//! indefinite under compression (`ε < 0`, the second term); [`StretchingEdge::derivatives`] returns it
//! exactly, and the Newton solver deals with indefiniteness.

/// One edge's stretching energy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StretchingEdge {
    /// Rest length `L̄` (m).
    pub rest_length: f64,
    /// Axial stiffness `k_s = E π r²` (N).
    pub stiffness: f64,
}

impl StretchingEdge {
    /// The energy (J) at end positions `x0, x1` (m).
    pub fn energy(&self, x0: [f64; 3], x1: [f64; 3]) -> f64 {
        let l = dist(x0, x1);
        let strain = l / self.rest_length - 1.0;
        0.5 * self.stiffness * self.rest_length * strain * strain
    }

    /// Energy (J), gradient over `(x0, x1)` (N) and Hessian (N/m, 6 × 6 row-major blocks).
    pub fn derivatives(&self, x0: [f64; 3], x1: [f64; 3]) -> (f64, [f64; 6], [[f64; 6]; 6]) {
        let e = [x1[0] - x0[0], x1[1] - x0[1], x1[2] - x0[2]];
        let l = dist(x0, x1);
        let t = [e[0] / l, e[1] / l, e[2] / l];
        let strain = l / self.rest_length - 1.0;
        let k = self.stiffness;
        let energy = 0.5 * k * self.rest_length * strain * strain;
        let mut g = [0.0; 6];
        for a in 0..3 {
            g[a] = -k * strain * t[a];
            g[3 + a] = k * strain * t[a];
        }
        let mut h = [[0.0; 6]; 6];
        for a in 0..3 {
            for b in 0..3 {
                let id = if a == b { 1.0 } else { 0.0 };
                let block =
                    k / self.rest_length * t[a] * t[b] + k * strain / l * (id - t[a] * t[b]);
                h[a][b] = block;
                h[3 + a][3 + b] = block;
                h[a][3 + b] = -block;
                h[3 + a][b] = -block;
            }
        }
        (energy, g, h)
    }
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{check_derivatives, random_point};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn derivatives_match_central_differences_stretched_and_compressed() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for (case, stretch) in [
            ("stretched", 1.3),
            ("compressed", 0.6),
            ("near rest", 1.0 + 1e-4),
        ] {
            for _ in 0..5 {
                let x0 = random_point(&mut rng, 1e-3);
                let dir = random_point(&mut rng, 1.0);
                let l = dist([0.0; 3], dir);
                let rest = 1.2e-3;
                let x1 = [
                    x0[0] + dir[0] / l * rest * stretch,
                    x0[1] + dir[1] / l * rest * stretch,
                    x0[2] + dir[2] / l * rest * stretch,
                ];
                let edge = StretchingEdge {
                    rest_length: rest,
                    stiffness: 31.4,
                };
                let q: [f64; 6] = [x0[0], x0[1], x0[2], x1[0], x1[1], x1[2]];
                let f = |q: &[f64; 6]| edge.derivatives([q[0], q[1], q[2]], [q[3], q[4], q[5]]);
                let report = check_derivatives(&q, 1e-9, &f);
                eprintln!("FD {case}: {report:?}");
                assert!(
                    report.gradient_error < 1e-6 && report.hessian_error < 1e-5,
                    "{case}: {report:?}"
                );
                let (e, _, _) = f(&q);
                assert!((e - edge.energy(x0, x1)).abs() <= 1e-15 * (1.0 + e));
            }
        }
    }
}
