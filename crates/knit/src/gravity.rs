//! Gravity on yarn vertices: the potential energy of lumped vertex masses in a uniform field,
//!
//! `E_g = −Σ_i m_i g·x_i`
//!
//! - `x_i` the vertex position (m); `g` the gravitational acceleration (m/s², e.g. `(0, −9.81, 0)`: skintight
//!   is +y up);
//! - `m_i = μ ℓ_i` the lumped mass (kg): the yarn's linear density `μ` (kg/m,
//!   [`crate::yarn_params::YarnParams::linear_density`]) times the vertex's Voronoi length `ℓ_i` (m, half the
//!   rest lengths of the one or two edges meeting there);
//! - `E_g` in J.
//!
//! Derivatives by hand: the energy is linear, `∂E_g/∂x_i = −m_i g` (N) and the Hessian is zero.

/// The gravitational acceleration of the Earth's surface (m/s², standard gravity).
pub const STANDARD_GRAVITY: f64 = 9.806_65;

/// Gravity on one lumped vertex mass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GravityVertex {
    /// Lumped mass `m_i` (kg).
    pub mass: f64,
    /// Gravitational acceleration `g` (m/s²).
    pub acceleration: [f64; 3],
}

impl GravityVertex {
    /// Energy (J) at position `x` (m) and its gradient (N); the Hessian is zero.
    pub fn derivatives(&self, x: [f64; 3]) -> (f64, [f64; 3]) {
        let g = self.acceleration;
        let e = -self.mass * (g[0] * x[0] + g[1] * x[1] + g[2] * x[2]);
        (e, [-self.mass * g[0], -self.mass * g[1], -self.mass * g[2]])
    }
}

/// The lumped vertex masses (kg) of one yarn: `μ` times half the rest lengths of the edges at each vertex.
/// `rest_length[k]` is the rest length (m) of edge `k` joining vertex `k` to `k + 1` (mod the vertex count
/// when `closed`); `linear_density` in kg/m.
pub fn lumped_masses(
    rest_length: &[f64],
    vertices: usize,
    closed: bool,
    linear_density: f64,
) -> Vec<f64> {
    let mut m = vec![0.0; vertices];
    for (k, &l) in rest_length.iter().enumerate() {
        let (a, b) = (k, (k + 1) % vertices.max(1));
        if !closed && k + 1 >= vertices {
            break;
        }
        m[a] += 0.5 * l * linear_density;
        m[b] += 0.5 * l * linear_density;
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::random_point;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn gradient_matches_central_differences_and_energy_falls_along_g() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..10 {
            let v = GravityVertex {
                mass: 2.1e-6,
                acceleration: random_point(&mut rng, 10.0),
            };
            let x = random_point(&mut rng, 0.1);
            let (e, g) = v.derivatives(x);
            let h = 1e-6;
            for k in 0..3 {
                let (mut xp, mut xm) = (x, x);
                xp[k] += h;
                xm[k] -= h;
                let fd = (v.derivatives(xp).0 - v.derivatives(xm).0) / (2.0 * h);
                assert!(
                    (fd - g[k]).abs() <= 1e-9 * (1.0 + g[k].abs()),
                    "{fd} vs {}",
                    g[k]
                );
            }
            // Moving along g lowers the energy by m |g|² per unit of time².
            let a = v.acceleration;
            let moved = [x[0] + a[0], x[1] + a[1], x[2] + a[2]];
            let drop = e - v.derivatives(moved).0;
            let expect = v.mass * (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
            assert!((drop - expect).abs() <= 1e-12 * expect.max(1e-30) + 1e-18);
        }
    }

    #[test]
    fn lumped_masses_sum_to_the_yarn_mass() {
        let rest = [1.0e-3, 2.0e-3, 3.0e-3];
        let open = lumped_masses(&rest, 4, false, 2.0);
        assert_eq!(open, vec![1.0e-3, 3.0e-3, 5.0e-3, 3.0e-3]);
        let closed = lumped_masses(&rest, 3, true, 2.0);
        assert!((closed.iter().sum::<f64>() - 12.0e-3).abs() < 1e-15);
        assert!((closed[0] - 4.0e-3).abs() < 1e-15);
    }
}
