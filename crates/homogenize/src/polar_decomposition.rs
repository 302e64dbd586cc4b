//! The polar decomposition `F = R S` of a 3 × 3 deformation gradient, with `R` a proper rotation
//! (`det R = +1`) and `S` symmetric, through the rotation-variant singular value decomposition
//! `F = U Σ Wᵀ` with `U`, `W` proper rotations (Irving et al. 2004): when `det F < 0` the smallest
//! singular value carries the sign, so `R = U Wᵀ` is the closest rotation to `F` in the Frobenius norm
//! even for an inverted element, and `S = W Σ Wᵀ` then has one negative eigenvalue.
//!
//! The closest rotation is what the knitwear paper needs twice: the rotation part of the per-segment
//! deformation gradients it averages (Sec. 5, Eq. 5) and the target `R(F)` of the shape term of its
//! material (Eq. 7, the projective-dynamics local step of Sec. 7.1). Dimensionless.

use nalgebra::{Matrix3, Vector3};

/// `F = U diag(σ) Wᵀ = R S` with `U`, `W`, `R` proper rotations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Polar {
    /// The closest rotation `R = U Wᵀ`.
    pub rotation: Matrix3<f64>,
    /// The symmetric factor `S = W Σ Wᵀ`.
    pub stretch: Matrix3<f64>,
    /// `U`, a proper rotation.
    pub u: Matrix3<f64>,
    /// The signed singular values `σ₁ ≥ σ₂ ≥ |σ₃|`; `σ₃ < 0` exactly when `det F < 0`.
    pub sigma: Vector3<f64>,
    /// `W`, a proper rotation.
    pub w: Matrix3<f64>,
}

/// The polar decomposition of `f` (any finite 3 × 3 matrix, degenerate or inverted included).
pub fn polar_decomposition(f: &Matrix3<f64>) -> Polar {
    let svd = f.svd(true, true);
    let mut u = svd.u.expect("svd computed with u");
    let mut w = svd.v_t.expect("svd computed with v_t").transpose();
    let mut sigma = svd.singular_values;
    // Sort descending (nalgebra does not promise an order for 3 × 3).
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| sigma[b].total_cmp(&sigma[a]));
    let (u0, w0, s0) = (u, w, sigma);
    for (k, &j) in order.iter().enumerate() {
        u.set_column(k, &u0.column(j));
        w.set_column(k, &w0.column(j));
        sigma[k] = s0[j];
    }
    if u.determinant() < 0.0 {
        u.set_column(2, &(-u.column(2)));
        sigma[2] = -sigma[2];
    }
    if w.determinant() < 0.0 {
        w.set_column(2, &(-w.column(2)));
        sigma[2] = -sigma[2];
    }
    let rotation = u * w.transpose();
    let stretch = w * Matrix3::from_diagonal(&sigma) * w.transpose();
    Polar {
        rotation,
        stretch,
        u,
        sigma,
        w,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_matrix(rng: &mut ChaCha8Rng) -> Matrix3<f64> {
        Matrix3::from_fn(|_, _| rng.random_range(-1.5..1.5))
    }

    #[test]
    fn reconstructs_and_rotation_is_proper() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..200 {
            let f = random_matrix(&mut rng);
            let p = polar_decomposition(&f);
            assert!((p.rotation * p.stretch - f).norm() < 1e-12 * (1.0 + f.norm()));
            assert!((p.rotation.determinant() - 1.0).abs() < 1e-12);
            assert!((p.rotation.transpose() * p.rotation - Matrix3::identity()).norm() < 1e-12);
            assert!((p.stretch - p.stretch.transpose()).norm() < 1e-12 * (1.0 + f.norm()));
            assert!(p.sigma[0] >= p.sigma[1] && p.sigma[1] >= p.sigma[2].abs() - 1e-15);
            assert_eq!(p.sigma[2] < 0.0, f.determinant() < 0.0);
        }
    }

    #[test]
    fn rotation_is_the_closest_one() {
        // No random rotation is closer to F than R (Frobenius norm): the defining property.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for _ in 0..50 {
            let f = random_matrix(&mut rng);
            let best = (f - polar_decomposition(&f).rotation).norm();
            for _ in 0..200 {
                let axis = Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let q = nalgebra::Rotation3::new(axis * rng.random_range(0.0..3.0));
                assert!((f - q.matrix()).norm() >= best - 1e-12);
            }
        }
    }

    #[test]
    fn rotation_of_a_rotated_stretch_is_that_rotation() {
        let r = *nalgebra::Rotation3::new(Vector3::new(0.3, -0.2, 0.9)).matrix();
        let s = Matrix3::new(1.3, 0.1, 0.0, 0.1, 0.8, 0.05, 0.0, 0.05, 1.1);
        let p = polar_decomposition(&(r * s));
        assert!((p.rotation - r).norm() < 1e-12);
        assert!((p.stretch - s).norm() < 1e-12);
    }

    #[test]
    fn degenerate_matrices_stay_finite() {
        for f in [
            Matrix3::zeros(),
            Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0),
        ] {
            let p = polar_decomposition(&f);
            assert!(p.rotation.iter().all(|v| v.is_finite()));
            assert!((p.rotation.determinant() - 1.0).abs() < 1e-12);
        }
    }
}
