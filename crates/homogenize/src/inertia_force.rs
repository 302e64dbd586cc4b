//! The inertia forces of a yarn-level sequence on the mesh (the knitwear paper, Sec. 6.1, Eq. 12–14): with
//! the fitted mesh shapes `xᵢ = φʸ²ⱽ(xᵢʸ)` of consecutive frames (Y2V, [`crate::shape_fit`]) and the
//! lumped nodal masses `Mⱽ` (Eq. 2), the nodal accelerations and forces are
//!
//! ```text
//! aᵢ = (xᵢ − 2 xᵢ₋₁ + xᵢ₋₂) / Δt²   (m/s²),      fᵢ = Mⱽ aᵢ   (N)
//! ```
//!
//! so that the equilibrium of frame `i` (Eq. 14) reads `∂ΣEₑ/∂x + fᵢ − fᵢᵉˣᵗ = 0`: a quasi-static
//! problem in which the inertia force is a known load (its d'Alembert force `−fᵢ` acts with the external
//! forces). The paper writes `Mⱽ φʸ²ⱽ(xᵢʸ − 2xᵢ₋₁ʸ + xᵢ₋₂ʸ)`, Y2V of the second difference of the yarn
//! poses; Y2V is affine in the yarn positions only for fixed element targets (Eq. 5 is not linear in the
//! pose: polar decompositions and logarithms), and the second difference of three poses is not a pose, so
//! we difference the three fitted shapes instead, which is the same wherever Y2V is linear (translations,
//! and the position term). `Δt` is the time between the frames (s), the sequence's `frame_interval_s`.
//!
//! `fᵢ` is linear in the three shapes: `∂fᵢ/∂xᵢ = Mⱽ/Δt²`, `∂fᵢ/∂xᵢ₋₁ = −2Mⱽ/Δt²`, `∂fᵢ/∂xᵢ₋₂ = Mⱽ/Δt²`
//! (N/m, diagonal).

use crate::shape_fit_error::ShapeFitError;

fn check_shape(what: &'static str, x: &[[f64; 3]], n: usize) -> Result<(), ShapeFitError> {
    if x.len() != n {
        return Err(ShapeFitError::Count {
            what,
            got: x.len(),
            expected: n,
            per: "mesh node (its lumped mass)",
        });
    }
    for (index, p) in x.iter().enumerate() {
        if let Some(&value) = p.iter().find(|v| !v.is_finite()) {
            return Err(ShapeFitError::NotFinite { what, index, value });
        }
    }
    Ok(())
}

/// `Mⱽ (xᵢ − 2xᵢ₋₁ + xᵢ₋₂) / Δt²`, flattened `3#V` (node-major, N), from the lumped masses `node_mass`
/// (`#V`, kg), the fitted shapes of frames `i`, `i − 1`, `i − 2` (`#V × 3` each, m) and the time between
/// frames `dt_s` (s, > 0).
pub fn inertia_force(
    node_mass: &[f64],
    current: &[[f64; 3]],
    previous: &[[f64; 3]],
    before_previous: &[[f64; 3]],
    dt_s: f64,
) -> Result<Vec<f64>, ShapeFitError> {
    if !(dt_s > 0.0 && dt_s.is_finite()) {
        return Err(ShapeFitError::Param {
            name: "dt_s",
            value: dt_s,
            problem: "(the time between frames, s) must be positive and finite",
        });
    }
    let n = node_mass.len();
    for (index, &value) in node_mass.iter().enumerate() {
        if !(value.is_finite() && value >= 0.0) {
            return Err(ShapeFitError::NotFinite {
                what: "node mass (kg, finite and non-negative)",
                index,
                value,
            });
        }
    }
    check_shape("the fitted shape of frame i", current, n)?;
    check_shape("the fitted shape of frame i − 1", previous, n)?;
    check_shape("the fitted shape of frame i − 2", before_previous, n)?;
    let inv = 1.0 / (dt_s * dt_s);
    let mut f = Vec::with_capacity(3 * n);
    for v in 0..n {
        for c in 0..3 {
            let a = (current[v][c] - 2.0 * previous[v][c] + before_previous[v][c]) * inv;
            f.push(node_mass[v] * a);
        }
    }
    if let Some(index) = f.iter().position(|v| !v.is_finite()) {
        return Err(ShapeFitError::NotFinite {
            what: "inertia force (the shapes or masses are too large for this dt_s) entry",
            index,
            value: f[index],
        });
    }
    Ok(f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::{FdParams, check_jacobian};

    #[test]
    fn a_uniformly_accelerating_translation_gives_m_a_per_node() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let n = 30;
        let rest: Vec<[f64; 3]> = (0..n)
            .map(|_| std::array::from_fn(|_| rng.random_range(-0.01..0.01)))
            .collect();
        let mass: Vec<f64> = (0..n).map(|_| rng.random_range(1e-6..1e-5)).collect();
        let (v0, a) = ([0.02, -0.01, 0.0], [0.3, -9.81, 1.5]);
        let dt = 1.0 / 60.0;
        let at = |t: f64| -> Vec<[f64; 3]> {
            rest.iter()
                .map(|p| std::array::from_fn(|c| p[c] + v0[c] * t + 0.5 * a[c] * t * t))
                .collect()
        };
        let t = 0.37;
        let f = inertia_force(&mass, &at(t), &at(t - dt), &at(t - 2.0 * dt), dt).unwrap();
        let mut total = [0.0; 3];
        for v in 0..n {
            for c in 0..3 {
                assert!((f[3 * v + c] - mass[v] * a[c]).abs() < 1e-9 * mass[v] * 10.0);
                total[c] += f[3 * v + c];
            }
        }
        let m: f64 = mass.iter().sum();
        for c in 0..3 {
            assert!((total[c] - m * a[c]).abs() < 1e-9 * m * 10.0);
        }
        // A uniform motion (no acceleration) gives no force.
        let still = |t: f64| -> Vec<[f64; 3]> {
            rest.iter()
                .map(|p| std::array::from_fn(|c| p[c] + v0[c] * t))
                .collect()
        };
        let f = inertia_force(&mass, &still(t), &still(t - dt), &still(t - 2.0 * dt), dt).unwrap();
        assert!(f.iter().all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn a_sequence_accelerating_rigidly_gives_m_a_through_y2v() {
        // Yarn frames of the straight-yarn block translated by v t + a t²/2, fitted by Y2V frame by frame
        // (the transport carried along): the inertia forces are mᵢ a and sum to the total mass times a.
        use crate::shape_fit::{ShapeFit, ShapeFitParams};
        use crate::straight_yarn_block::straight_yarn_block;
        let b = straight_yarn_block([3, 2, 2], 2e-3, 1e-3);
        let fit = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let mut transport = fit.transport();
        let (v0, a) = ([0.05, 0.0, -0.02], [0.0, -9.81, 2.0]);
        let dt = 1.0 / 120.0;
        let shapes: Vec<Vec<[f64; 3]>> = (0..4)
            .map(|i| {
                let t = i as f64 * dt;
                let rows: Vec<[f64; 4]> = b
                    .rest
                    .iter()
                    .map(|r| {
                        let d: [f64; 3] = std::array::from_fn(|c| v0[c] * t + 0.5 * a[c] * t * t);
                        [r[0] + d[0], r[1] + d[1], r[2] + d[2], r[3]]
                    })
                    .collect();
                fit.fit(&transport.pose(&rows).unwrap()).unwrap()
            })
            .collect();
        let m = &b.mesh.node_mass;
        let total: f64 = m.iter().sum();
        for i in 2..4 {
            let f = inertia_force(m, &shapes[i], &shapes[i - 1], &shapes[i - 2], dt).unwrap();
            let mut sum = [0.0; 3];
            for v in 0..m.len() {
                for c in 0..3 {
                    // Positions ~1e-2 m differenced over dt² ~ 7e-5 s²: round-off ~1e-18/7e-5 m/s².
                    assert!(
                        (f[3 * v + c] - m[v] * a[c]).abs() < 1e-9 * m[v] + 1e-15,
                        "{v} {c}"
                    );
                    sum[c] += f[3 * v + c];
                }
            }
            for c in 0..3 {
                assert!((sum[c] - total * a[c]).abs() < 1e-9 * total);
            }
        }
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let n = 4;
        let mass: Vec<f64> = (0..n).map(|_| rng.random_range(0.1..1.0)).collect();
        let x: Vec<f64> = (0..9 * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let dt = 0.1;
        let split = |x: &[f64]| -> [Vec<[f64; 3]>; 3] {
            std::array::from_fn(|f| {
                (0..n)
                    .map(|v| std::array::from_fn(|c| x[f * 3 * n + 3 * v + c]))
                    .collect()
            })
        };
        let g = |x: &[f64]| {
            let [a, b, c] = split(x);
            inertia_force(&mass, &a, &b, &c, dt).unwrap()
        };
        let mut jac = vec![0.0; 3 * n * 9 * n];
        for v in 0..n {
            for c in 0..3 {
                let row = 3 * v + c;
                for (f, coef) in [1.0, -2.0, 1.0].iter().enumerate() {
                    jac[row * 9 * n + f * 3 * n + 3 * v + c] = coef * mass[v] / (dt * dt);
                }
            }
        }
        check_jacobian(g, &x, &jac, &FdParams::default()).unwrap();
    }

    #[test]
    fn bad_input_is_named() {
        let m = [1.0, 2.0];
        let x = [[0.0; 3]; 2];
        for dt in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = inertia_force(&m, &x, &x, &x, dt).unwrap_err().to_string();
            assert!(e.contains("dt_s"), "{e}");
        }
        let e = inertia_force(&m, &x[..1], &x, &x, 0.1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("frame i has 1 entries, expected 2"), "{e}");
        let mut nan = x;
        nan[1][2] = f64::NAN;
        let e = inertia_force(&m, &x, &x, &nan, 0.1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("frame i − 2 1 is not finite"), "{e}");
        let e = inertia_force(&[1.0, -1.0], &x, &x, &x, 0.1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("node mass"), "{e}");
    }
}
