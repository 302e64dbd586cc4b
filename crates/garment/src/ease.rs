//! Ease: the uniform scaling of a flat pattern that makes the garment looser or tighter than the body.
//!
//! Pattern positions are scaled by `1 + ease` about the panel's area centroid: `x ← c + (1 + ease)(x − c)`.
//! `ease = −0.1` makes every length 10 % shorter (areas 19 % smaller), so a pattern flattened from the body and
//! then eased is stretched everywhere when sewn on: no element starts slack (thesis Sec. 7.2, "Performance and
//! Statistics": the initial guess scales down the geometrically flattened patterns). `ease = 0` leaves the
//! pattern unchanged; positive values make it looser.

use crate::lscm::area_moments;
use crate::math::{Real, Vec2};

/// Why the ease could not be applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EaseError {
    /// The ease is not finite or would shrink the pattern to nothing or mirror it.
    #[error(
        "ease {ease} is invalid: it must be a finite number greater than -1 (e.g. -0.1 for 10 % smaller)"
    )]
    OutOfRange { ease: Real },
    /// A face names a vertex that does not exist.
    #[error(
        "pattern face {face} names vertex {vertex}, but the pattern has {num_vertices} vertices"
    )]
    BadIndex {
        face: usize,
        vertex: usize,
        num_vertices: usize,
    },
    /// The pattern has no area, so it has no centroid.
    #[error(
        "the pattern has no area (total signed area {area:.3e} m²), so it has no centroid to scale about"
    )]
    NoArea { area: Real },
}

/// Scales the pattern `positions` (`#V`, m) of a panel with triangles `faces` by `1 + ease` about its area
/// centroid, in place. Returns the centroid (m).
pub fn ease(positions: &mut [Vec2], faces: &[[usize; 3]], ease: Real) -> Result<Vec2, EaseError> {
    if !(ease.is_finite() && ease > -1.0) {
        return Err(EaseError::OutOfRange { ease });
    }
    for (f, face) in faces.iter().enumerate() {
        if let Some(&v) = face.iter().find(|&&v| v >= positions.len()) {
            return Err(EaseError::BadIndex {
                face: f,
                vertex: v,
                num_vertices: positions.len(),
            });
        }
    }
    let (area, centroid, _) = area_moments(faces, positions);
    if !(area.abs() > 0.0 && area.is_finite()) {
        return Err(EaseError::NoArea { area });
    }
    let s = 1.0 + ease;
    for p in positions.iter_mut() {
        *p = centroid + (*p - centroid) * s;
    }
    Ok(centroid)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lscm::signed_area;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_fan(seed: u64, n: usize) -> (Vec<Vec2>, Vec<[usize; 3]>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let c = Vec2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        let mut pos = vec![c];
        for k in 0..n {
            let a = std::f64::consts::TAU * k as Real / n as Real;
            let r = rng.random_range(0.1..0.5);
            pos.push(c + Vec2::new(a.cos(), a.sin()) * r);
        }
        let faces = (0..n).map(|k| [0, 1 + k, 1 + (k + 1) % n]).collect();
        (pos, faces)
    }

    fn area(p: &[Vec2], faces: &[[usize; 3]]) -> Real {
        faces
            .iter()
            .map(|f| signed_area(p[f[0]], p[f[1]], p[f[2]]))
            .sum()
    }

    #[test]
    fn scales_lengths_and_areas_about_the_centroid() {
        for (seed, n) in [(1, 5), (2, 12), (3, 40)] {
            for e in [-0.1, 0.0, 0.05, -0.5] {
                let (mut p, faces) = random_fan(seed, n);
                let before = p.clone();
                let a0 = area(&p, &faces);
                let c = ease(&mut p, &faces, e).unwrap();
                let a1 = area(&p, &faces);
                assert!((a1 - a0 * (1.0 + e) * (1.0 + e)).abs() < 1e-12 * a0);
                let (_, c1, _) = area_moments(&faces, &p);
                assert!((c1 - c).norm() < 1e-12);
                for (q0, q1) in before.iter().zip(&p) {
                    assert!(((q1 - c) - (q0 - c) * (1.0 + e)).norm() < 1e-12);
                }
                // Ten percent smaller means every edge 10 % shorter.
                let l0 = (before[1] - before[2]).norm();
                let l1 = (p[1] - p[2]).norm();
                assert!((l1 - (1.0 + e) * l0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn invalid_ease_is_rejected() {
        let (mut p, faces) = random_fan(7, 6);
        for e in [-1.0, -2.0, Real::NAN, Real::INFINITY] {
            assert!(matches!(
                ease(&mut p, &faces, e),
                Err(EaseError::OutOfRange { .. })
            ));
        }
        assert!(matches!(
            ease(&mut p, &[[0, 1, 99]], 0.1),
            Err(EaseError::BadIndex { vertex: 99, .. })
        ));
        let mut line = vec![Vec2::zeros(), Vec2::x(), Vec2::x() * 2.0];
        assert!(matches!(
            ease(&mut line, &[[0, 1, 2]], 0.1),
            Err(EaseError::NoArea { .. })
        ));
    }
}
