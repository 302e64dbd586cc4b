//! The weighted average of rotations through the matrix logarithm (the knitwear paper, Sec. 5, the
//! rotation factor of Eq. 5; Grassia 1998).
//!
//! A rotation is `R = exp(Ω)` with `Ω = [ω]ₓ` skew-symmetric, `ω` the rotation vector (axis times angle,
//! rad). The paper averages the rotation vectors of a tetrahedron's yarn segments with weights `wⱼ` (their
//! lengths in the element, normalized to sum to 1):
//!
//! ```text
//! R̄₀ = exp(Σⱼ wⱼ log Rⱼ)                                   (Eq. 5, rotation factor)
//! ```
//!
//! That is the average of axes and angles about the identity: exact for rotations about one axis and
//! invariant under a common conjugation `Rⱼ → Q Rⱼ Qᵀ`, but not under `Rⱼ → Q Rⱼ` (a rigidly rotated
//! frame does not get a rotated average), and it breaks down when the rotations straddle an angle of π
//! (rotation vectors near `π a` and `−π a` describe nearly the same rotation but average to the identity).
//! [`rotation_average`] therefore takes `R̄₀` as the start of the fixed-point iteration of the weighted
//! Karcher (geodesic) mean `R̄ ← R̄ exp(Σⱼ wⱼ log(R̄ᵀ Rⱼ))`, which converges when the rotations lie in a ball
//! of radius π/2 and whose fixed point is bi-invariant: the average of `Q Rⱼ P` is `Q R̄ P`. With
//! `iterations = 0` it is the paper's formula verbatim. For rotations near the identity (a knit's
//! segments relative to rest, frame by frame) the two differ at third order in the angles.
//!
//! [`rotation_log`] is robust up to an angle of π (where the axis is read from `R + Rᵀ`); [`rotation_exp`]
//! is Rodrigues' formula with its series near 0. Angles in rad; the matrices are dimensionless.

use nalgebra::{Matrix3, Vector3};

/// `[ω]ₓ`, the skew-symmetric matrix with `[ω]ₓ v = ω × v`.
pub fn skew(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

/// `exp([ω]ₓ)`: the rotation by `|ω|` rad about `ω/|ω|` (Rodrigues' formula).
pub fn rotation_exp(w: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = w.norm_squared();
    let theta = theta2.sqrt();
    // sin θ / θ and (1 − cos θ) / θ², by their series below 1e-4 rad (error below 1e-17).
    let (a, b) = if theta < 1e-4 {
        (1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0)
    } else {
        (theta.sin() / theta, (1.0 - theta.cos()) / theta2)
    };
    let k = skew(w);
    Matrix3::identity() + k * a + k * k * b
}

/// The rotation vector `ω` (rad) of the rotation `r` with `|ω| ∈ [0, π]`: `exp([ω]ₓ) = r`. At an angle of
/// exactly π both `±ω` are logarithms; the sign follows the rounding of `r − rᵀ`.
pub fn rotation_log(r: &Matrix3<f64>) -> Vector3<f64> {
    // r − rᵀ = 2 sin θ [a]ₓ, tr r = 1 + 2 cos θ.
    let v = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    ) * 0.5;
    let s = v.norm();
    let c = ((r.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
    let theta = s.atan2(c);
    if theta < 1e-4 {
        // θ / sin θ = 1 + θ²/6 + O(θ⁴).
        return v * (1.0 + theta * theta / 6.0);
    }
    if theta < std::f64::consts::PI - 1e-3 {
        return v * (theta / s);
    }
    // Near π, sin θ carries no precision: (r + rᵀ)/2 − cos θ I = (1 − cos θ) a aᵀ.
    let b = (r + r.transpose()) * 0.5 - Matrix3::identity() * c;
    let k = (0..3)
        .max_by(|&i, &j| b[(i, i)].total_cmp(&b[(j, j)]))
        .unwrap_or(0);
    let mut a: Vector3<f64> = b.column(k).into_owned() / (b[(k, k)] * (1.0 - c)).max(0.0).sqrt();
    a /= a.norm();
    if a.dot(&v) < 0.0 {
        a = -a;
    }
    a * theta
}

/// The weighted average of `rotations` with the non-negative `weights` (any positive sum; normalized
/// here): the paper's `exp(Σ w log R)` refined by up to `iterations` Karcher-mean steps (stopping when a
/// step is below 1e-14 rad). `None` when the inputs are empty, of different lengths, or the weights are
/// not finite, negative or sum to zero.
pub fn rotation_average(
    weights: &[f64],
    rotations: &[Matrix3<f64>],
    iterations: usize,
) -> Option<Matrix3<f64>> {
    if weights.len() != rotations.len() || weights.is_empty() {
        return None;
    }
    if weights.iter().any(|w| !w.is_finite() || *w < 0.0) {
        return None;
    }
    let total: f64 = weights.iter().sum();
    if !total.is_finite() || total <= 0.0 {
        return None;
    }
    let mean_log = |base: &Matrix3<f64>| -> Vector3<f64> {
        weights
            .iter()
            .zip(rotations)
            .map(|(w, r)| rotation_log(&(base.transpose() * r)) * (w / total))
            .sum()
    };
    let mut mean = rotation_exp(&mean_log(&Matrix3::identity()));
    for _ in 0..iterations {
        let step = mean_log(&mean);
        mean *= rotation_exp(&step);
        if step.norm() < 1e-14 {
            break;
        }
    }
    Some(mean)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_vector(rng: &mut ChaCha8Rng, max_angle: f64) -> Vector3<f64> {
        let w = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        w.normalize() * rng.random_range(0.0..max_angle)
    }

    #[test]
    fn exp_and_log_are_inverse_over_all_angles() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for k in 0..400 {
            // Angles from 1e-9 rad up to just below π, including the series regimes of both functions.
            let max = [1e-8, 1e-4, 2e-4, 1.0, 3.0, std::f64::consts::PI - 1e-6][k % 6];
            let w = random_vector(&mut rng, max);
            let r = rotation_exp(&w);
            assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-14);
            assert!((r.determinant() - 1.0).abs() < 1e-14);
            let back = rotation_log(&r);
            assert!((back - w).norm() < 1e-9 * (1.0 + w.norm()), "{w} -> {back}");
        }
        // Exactly π: either sign is a logarithm; exp of it gives r back.
        let r = rotation_exp(&(Vector3::new(0.0, 0.6, 0.8) * std::f64::consts::PI));
        let w = rotation_log(&r);
        assert!((w.norm() - std::f64::consts::PI).abs() < 1e-12);
        assert!((rotation_exp(&w) - r).norm() < 1e-12);
    }

    #[test]
    fn exp_matches_its_derivative_definition() {
        // d/dt exp(t [ω]ₓ) at t = 0 is [ω]ₓ (central difference).
        let w = Vector3::new(0.3, -0.2, 0.5);
        let h = 1e-6;
        let d = (rotation_exp(&(w * h)) - rotation_exp(&(w * -h))) / (2.0 * h);
        assert!((d - skew(&w)).norm() < 1e-9);
    }

    #[test]
    fn identical_rotations_average_to_themselves() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for iterations in [0, 16] {
            for _ in 0..20 {
                let r = rotation_exp(&random_vector(&mut rng, 3.0));
                let avg = rotation_average(&[0.2, 1.3, 0.5], &[r, r, r], iterations).unwrap();
                assert!((avg - r).norm() < 1e-12);
            }
        }
    }

    #[test]
    fn symmetric_pairs_average_to_the_midpoint() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..20 {
            // R and Rᵀ average to the identity, with or without the Karcher steps.
            let r = rotation_exp(&random_vector(&mut rng, 1.4));
            for iterations in [0, 16] {
                let avg = rotation_average(&[1.0, 1.0], &[r, r.transpose()], iterations).unwrap();
                assert!((avg - Matrix3::identity()).norm() < 1e-12);
            }
            // Any pair: the geodesic midpoint R₁ exp(½ log(R₁ᵀ R₂)) (Karcher mean).
            let r1 = rotation_exp(&random_vector(&mut rng, 1.0));
            let r2 = r1 * rotation_exp(&random_vector(&mut rng, 1.4));
            let mid = r1 * rotation_exp(&(rotation_log(&(r1.transpose() * r2)) * 0.5));
            let avg = rotation_average(&[2.0, 2.0], &[r1, r2], 32).unwrap();
            assert!((avg - mid).norm() < 1e-12);
            // Unequal weights: the point at fraction w₂/(w₁+w₂) along the geodesic.
            let third = r1 * rotation_exp(&(rotation_log(&(r1.transpose() * r2)) / 3.0));
            let avg = rotation_average(&[2.0, 1.0], &[r1, r2], 32).unwrap();
            assert!((avg - third).norm() < 1e-12);
        }
    }

    #[test]
    fn karcher_mean_is_bi_invariant_and_the_paper_average_conjugation_invariant() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for _ in 0..20 {
            let center = rotation_exp(&random_vector(&mut rng, 3.0));
            let rs: Vec<Matrix3<f64>> = (0..5)
                .map(|_| center * rotation_exp(&random_vector(&mut rng, 0.6)))
                .collect();
            let ws: Vec<f64> = (0..5).map(|_| rng.random_range(0.1..2.0)).collect();
            let q = rotation_exp(&random_vector(&mut rng, 3.0));
            let p = rotation_exp(&random_vector(&mut rng, 3.0));
            let avg = rotation_average(&ws, &rs, 64).unwrap();
            let moved: Vec<Matrix3<f64>> = rs.iter().map(|r| q * r * p).collect();
            let avg_moved = rotation_average(&ws, &moved, 64).unwrap();
            assert!((avg_moved - q * avg * p).norm() < 1e-10);
            // Stationarity: Σ w log(R̄ᵀ Rⱼ) = 0.
            let residual: Vector3<f64> = ws
                .iter()
                .zip(&rs)
                .map(|(w, r)| rotation_log(&(avg.transpose() * r)) * *w)
                .sum();
            assert!(residual.norm() < 1e-12);
            // The paper's one-step average: invariant under a common conjugation only.
            let near: Vec<Matrix3<f64>> = (0..5)
                .map(|_| rotation_exp(&random_vector(&mut rng, 1.0)))
                .collect();
            let a0 = rotation_average(&ws, &near, 0).unwrap();
            let conj: Vec<Matrix3<f64>> = near.iter().map(|r| q * r * q.transpose()).collect();
            let a0c = rotation_average(&ws, &conj, 0).unwrap();
            assert!((a0c - q * a0 * q.transpose()).norm() < 1e-12);
            let logs: Vector3<f64> = ws
                .iter()
                .zip(&near)
                .map(|(w, r)| rotation_log(r) * *w)
                .sum::<Vector3<f64>>()
                / ws.iter().sum::<f64>();
            assert!((a0 - rotation_exp(&logs)).norm() < 1e-14);
        }
    }

    #[test]
    fn bad_weights_give_none() {
        let r = Matrix3::identity();
        assert!(rotation_average(&[], &[], 4).is_none());
        assert!(rotation_average(&[1.0], &[r, r], 4).is_none());
        assert!(rotation_average(&[0.0, 0.0], &[r, r], 4).is_none());
        assert!(rotation_average(&[-1.0, 2.0], &[r, r], 4).is_none());
        assert!(rotation_average(&[f64::NAN, 2.0], &[r, r], 4).is_none());
    }
}
