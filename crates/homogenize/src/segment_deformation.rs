//! The deformation gradient of one yarn segment (the knitwear paper, Sec. 5, the equation before Eq. 5):
//!
//! ```text
//! Fʸ = [x₁ − x₀, n₁, n₂] [x̄₁ − x̄₀, n̄₁, n̄₂]⁻¹
//! ```
//!
//! with `x̄₀, x̄₁` and `x₀, x₁` the rest and deformed endpoints (m) and `n̄₁, n̄₂`, `n₁, n₂` two mutually
//! perpendicular material normals of the segment at rest and deformed (unit, dimensionless; the rod's
//! material frame `m₁, m₂`, see [`crate::material_frame`]). A 1-D segment alone defines only the image of
//! its own direction; the normals complete it to a 3 × 3 map. `Fʸ` maps the rest edge onto the deformed
//! edge exactly and each rest normal onto its deformed normal, so with orthonormal frames
//! `Fʸ = Q (I + (λ − 1) t̄ t̄ᵀ)`: the rotation `Q` taking the rest frame `(t̄, n̄₁, n̄₂)` to the deformed one,
//! after a stretch `λ = |x₁ − x₀| / |x̄₁ − x̄₀|` along the rest tangent `t̄`. The yarn's cross-section stays
//! rigid: a deformation of the surrounding volume across the yarn is not seen by its segments (only the
//! position term of Y2V, Eq. 6, sees it). Dimensionless.
//!
//! `Fʸ` is linear in the deformed edge and normals, so its derivative is the constant rest inverse; the
//! element average of Eq. 5 then goes through the polar decomposition and the matrix logarithm
//! ([`crate::rotation_average`]).

use nalgebra::{Matrix3, Vector3};

/// A yarn segment's edge and two material normals, at rest or in a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentFrame {
    /// The edge `x₁ − x₀` (m).
    pub edge: Vector3<f64>,
    /// The material normals `n₁, n₂`: unit, perpendicular to each other and to the edge (dimensionless).
    pub normals: [Vector3<f64>; 2],
}

impl SegmentFrame {
    /// The matrix `[edge, n₁, n₂]` (first column in m, the others dimensionless).
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::from_columns(&[self.edge, self.normals[0], self.normals[1]])
    }
}

/// `[x̄₁ − x̄₀, n̄₁, n̄₂]⁻¹` of a rest segment (rows: the first in 1/m, the others dimensionless), or `None`
/// when the rest frame is singular (zero edge, normals parallel to the edge or to each other) or not
/// finite: the reciprocal condition estimate `|det| / (|e| |n₁| |n₂|)` must exceed 1e-8.
pub fn rest_frame_inverse(rest: &SegmentFrame) -> Option<Matrix3<f64>> {
    let m = rest.matrix();
    if m.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let scale = rest.edge.norm() * rest.normals[0].norm() * rest.normals[1].norm();
    let det = m.determinant().abs();
    if det.is_nan() || det <= 1e-8 * scale {
        return None;
    }
    m.try_inverse()
}

/// `Fʸ = [x₁ − x₀, n₁, n₂] R̄⁻¹` with `rest_inverse = R̄⁻¹` from [`rest_frame_inverse`] (dimensionless).
pub fn segment_deformation(rest_inverse: &Matrix3<f64>, deformed: &SegmentFrame) -> Matrix3<f64> {
    deformed.matrix() * rest_inverse
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation_average::rotation_exp;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
        Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize()
    }

    fn frame_about(t: Vector3<f64>, seed: Vector3<f64>, length: f64) -> SegmentFrame {
        let n1 = (seed - t * seed.dot(&t)).normalize();
        SegmentFrame {
            edge: t * length,
            normals: [n1, t.cross(&n1)],
        }
    }

    #[test]
    fn maps_edge_and_normals_and_factors_as_rotation_after_axial_stretch() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for _ in 0..100 {
            let t = random_unit(&mut rng);
            let rest = frame_about(t, random_unit(&mut rng), rng.random_range(1e-4..1e-2));
            let q = rotation_exp(&(random_unit(&mut rng) * rng.random_range(0.0..3.0)));
            let lambda = rng.random_range(0.5..2.0);
            let deformed = SegmentFrame {
                edge: q * rest.edge * lambda,
                normals: [q * rest.normals[0], q * rest.normals[1]],
            };
            let f = segment_deformation(&rest_frame_inverse(&rest).unwrap(), &deformed);
            assert!((f * rest.edge - deformed.edge).norm() < 1e-12 * rest.edge.norm());
            for k in 0..2 {
                assert!((f * rest.normals[k] - deformed.normals[k]).norm() < 1e-12);
            }
            let closed = q * (Matrix3::identity() + t * t.transpose() * (lambda - 1.0));
            assert!((f - closed).norm() < 1e-12);
        }
    }

    #[test]
    fn an_affine_map_is_reproduced_along_the_segment() {
        // Under any affine map A the edge maps as A does; the normals only as far as they stay unit and
        // perpendicular: a stretch along the segment and any rotation give Fʸ = A exactly.
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let t = Vector3::new(1.0, 0.0, 0.0);
        let rest = frame_about(t, Vector3::new(0.3, 1.0, 0.2), 2e-3);
        let a = Matrix3::new(1.3, 0.2, -0.1, 0.4, 0.9, 0.3, -0.2, 0.1, 1.1);
        let deformed_edge = a * rest.edge;
        let td = deformed_edge.normalize();
        let deformed = frame_about(td, a * rest.normals[0], deformed_edge.norm());
        let f = segment_deformation(&rest_frame_inverse(&rest).unwrap(), &deformed);
        assert!((f * rest.edge - a * rest.edge).norm() < 1e-15);
        for _ in 0..10 {
            let q = rotation_exp(&(random_unit(&mut rng) * rng.random_range(0.0..3.0)));
            let a = q * Matrix3::from_diagonal(&Vector3::new(rng.random_range(0.5..2.0), 1.0, 1.0));
            let deformed = SegmentFrame {
                edge: a * rest.edge,
                normals: [a * rest.normals[0], a * rest.normals[1]],
            };
            let f = segment_deformation(&rest_frame_inverse(&rest).unwrap(), &deformed);
            assert!((f - a).norm() < 1e-12);
        }
    }

    #[test]
    fn degenerate_rest_frames_are_refused() {
        let t = Vector3::new(0.0, 0.0, 1.0);
        let ok = frame_about(t, Vector3::new(1.0, 0.0, 0.0), 1e-3);
        assert!(rest_frame_inverse(&ok).is_some());
        let mut zero = ok;
        zero.edge = Vector3::zeros();
        assert!(rest_frame_inverse(&zero).is_none());
        let mut parallel = ok;
        parallel.normals[0] = t;
        assert!(rest_frame_inverse(&parallel).is_none());
        let mut nan = ok;
        nan.edge.x = f64::NAN;
        assert!(rest_frame_inverse(&nan).is_none());
    }
}
