//! Tetrahedral meshes of deformable bodies.
//!
//! # Orientation convention
//! A tetrahedron `[a, b, c, d]` is positively oriented when its signed volume
//! `V = (b − a) · ((c − a) × (d − a)) / 6` is positive: seen from `d`, the triangle `(a, b, c)` runs
//! counter-clockwise. Its four faces, oriented outward (counter-clockwise seen from outside), are then
//! `(b, c, d)`, `(a, d, c)`, `(a, b, d)` and `(a, c, b)` (see [`TET_FACES`]).
//!
//! # Shape quality
//! [`tet_quality`] is the *mean ratio* `q = 12 · (3|V|)^(2/3) / Σ ℓᵢⱼ²` over the six edge lengths `ℓᵢⱼ`,
//! carrying the sign of `V`. It is dimensionless, `q = 1` for the regular tetrahedron, `q → 0` for flat or
//! needle-like elements, and `q < 0` for an inverted element. A mesh of well-shaped tetrahedra has a minimum
//! quality above about 0.1; finite-element stiffness conditioning degrades roughly like `1/q`.

use crate::math::{Real, Vec3, VertexId};

/// The four outward-oriented faces of a positively oriented tetrahedron `[a, b, c, d]`, as local corner
/// indices: the face opposite corner `i` is `TET_FACES[i]`.
pub const TET_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// A tetrahedral mesh: `#V` vertex positions (m), `#T` tetrahedra of four vertex indices (positively
/// oriented, see the module notes) and a `#V` flag per vertex that marks it fixed (bone/core: its position is
/// prescribed, it is not an unknown of the simulation).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TetMesh {
    /// `#V` rest positions (m).
    pub positions: Vec<Vec3>,
    /// `#T` tetrahedra as vertex indices, signed volume > 0.
    pub tets: Vec<[VertexId; 4]>,
    /// `#V` flags: `true` for a fixed vertex.
    pub fixed: Vec<bool>,
}

/// Why a tetrahedral mesh cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TetMeshError {
    /// A tetrahedron names a vertex index that does not exist.
    #[error("tetrahedron {tet} names vertex {vertex}, but the mesh has {num_vertices} vertices")]
    BadIndex {
        tet: usize,
        vertex: usize,
        num_vertices: usize,
    },
    /// A tetrahedron uses the same vertex twice.
    #[error("tetrahedron {tet} repeats vertex {vertex}")]
    RepeatedVertex { tet: usize, vertex: VertexId },
    /// A vertex position is NaN or infinite.
    #[error("vertex {vertex} has a non-finite position ({x}, {y}, {z})")]
    NonFinite {
        vertex: VertexId,
        x: Real,
        y: Real,
        z: Real,
    },
    /// The fixed-vertex flags do not match the vertex count.
    #[error("the mesh has {num_vertices} vertices but {num_flags} fixed-vertex flags")]
    FixedLength {
        num_vertices: usize,
        num_flags: usize,
    },
    /// A tetrahedron has negative signed volume.
    #[error(
        "tetrahedron {tet} {vertices:?} is inverted: signed volume {volume:.3e} m³ (must be positive; swap two of its vertices if the whole mesh uses the opposite orientation)"
    )]
    Inverted {
        tet: usize,
        vertices: [VertexId; 4],
        volume: Real,
    },
    /// A tetrahedron is flat (zero volume up to round-off) or has quality below the accepted minimum.
    #[error(
        "tetrahedron {tet} {vertices:?} is degenerate: signed volume {volume:.3e} m³, mean-ratio quality {quality:.3e} (minimum {min_quality:.1e})"
    )]
    Degenerate {
        tet: usize,
        vertices: [VertexId; 4],
        volume: Real,
        quality: Real,
        min_quality: Real,
    },
}

/// Signed volume (m³) of the tetrahedron with corners `a, b, c, d`; positive when `d` sees `(a, b, c)`
/// counter-clockwise.
#[inline]
pub fn tet_signed_volume(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> Real {
    (b - a).dot(&(c - a).cross(&(d - a))) / 6.0
}

/// Signed mean-ratio quality of the tetrahedron `a, b, c, d`: `sign(V) · 12 (3|V|)^(2/3) / Σ ℓ²`, in
/// `[−1, 1]`, 1 for the regular tetrahedron, negative when inverted, 0 when degenerate (all corners equal
/// included).
pub fn tet_quality(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> Real {
    let v = tet_signed_volume(a, b, c, d);
    let sum_sq = (b - a).norm_squared()
        + (c - a).norm_squared()
        + (d - a).norm_squared()
        + (c - b).norm_squared()
        + (d - b).norm_squared()
        + (d - c).norm_squared();
    if sum_sq <= 0.0 || !sum_sq.is_finite() || !v.is_finite() {
        return 0.0;
    }
    v.signum() * 12.0 * (3.0 * v.abs()).powf(2.0 / 3.0) / sum_sq
}

/// Quality statistics of a tetrahedral mesh.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct QualityStats {
    /// Smallest signed mean-ratio quality (negative when some tetrahedron is inverted).
    pub min: Real,
    /// Mean quality.
    pub mean: Real,
    /// Number of tetrahedra with signed volume ≤ 0.
    pub inverted: usize,
}

impl TetMesh {
    /// A mesh with no fixed vertices.
    pub fn new(positions: Vec<Vec3>, tets: Vec<[VertexId; 4]>) -> Self {
        let fixed = vec![false; positions.len()];
        Self {
            positions,
            tets,
            fixed,
        }
    }

    /// Number of vertices `#V`.
    pub fn num_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of tetrahedra `#T`.
    pub fn num_tets(&self) -> usize {
        self.tets.len()
    }

    /// Number of fixed vertices.
    pub fn num_fixed(&self) -> usize {
        self.fixed.iter().filter(|&&f| f).count()
    }

    /// Indices of the fixed vertices, ascending.
    pub fn fixed_vertices(&self) -> Vec<VertexId> {
        (0..self.fixed.len()).filter(|&v| self.fixed[v]).collect()
    }

    /// The four corner positions of tetrahedron `t` (m).
    pub fn corners(&self, t: usize) -> [Vec3; 4] {
        let [a, b, c, d] = self.tets[t];
        [
            self.positions[a],
            self.positions[b],
            self.positions[c],
            self.positions[d],
        ]
    }

    /// Signed volume of tetrahedron `t` (m³).
    pub fn tet_volume(&self, t: usize) -> Real {
        let [a, b, c, d] = self.corners(t);
        tet_signed_volume(&a, &b, &c, &d)
    }

    /// Total signed volume (m³).
    pub fn volume(&self) -> Real {
        (0..self.num_tets()).map(|t| self.tet_volume(t)).sum()
    }

    /// Signed mean-ratio quality of tetrahedron `t` (see the module notes).
    pub fn quality(&self, t: usize) -> Real {
        let [a, b, c, d] = self.corners(t);
        tet_quality(&a, &b, &c, &d)
    }

    /// `#T` signed mean-ratio qualities.
    pub fn qualities(&self) -> Vec<Real> {
        (0..self.num_tets()).map(|t| self.quality(t)).collect()
    }

    /// Minimum and mean quality and the number of inverted (volume ≤ 0) tetrahedra. For an empty mesh the
    /// minimum and mean are 0.
    pub fn quality_stats(&self) -> QualityStats {
        let mut min = Real::INFINITY;
        let mut sum = 0.0;
        let mut inverted = 0;
        for t in 0..self.num_tets() {
            let [a, b, c, d] = self.corners(t);
            let q = tet_quality(&a, &b, &c, &d);
            if tet_signed_volume(&a, &b, &c, &d) <= 0.0 {
                inverted += 1;
            }
            min = min.min(q);
            sum += q;
        }
        if self.tets.is_empty() {
            return QualityStats {
                min: 0.0,
                mean: 0.0,
                inverted: 0,
            };
        }
        QualityStats {
            min,
            mean: sum / self.num_tets() as Real,
            inverted,
        }
    }

    /// Checks indices, finiteness, the fixed flags, and that every tetrahedron is positively oriented with
    /// quality at least `min_quality` (pass 0 to only reject inverted and exactly flat ones). Reports the first
    /// offending tetrahedron.
    pub fn validate(&self, min_quality: Real) -> Result<(), TetMeshError> {
        let nv = self.num_vertices();
        if self.fixed.len() != nv {
            return Err(TetMeshError::FixedLength {
                num_vertices: nv,
                num_flags: self.fixed.len(),
            });
        }
        for (v, p) in self.positions.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                return Err(TetMeshError::NonFinite {
                    vertex: v,
                    x: p.x,
                    y: p.y,
                    z: p.z,
                });
            }
        }
        for (t, tet) in self.tets.iter().enumerate() {
            for (i, &v) in tet.iter().enumerate() {
                if v >= nv {
                    return Err(TetMeshError::BadIndex {
                        tet: t,
                        vertex: v,
                        num_vertices: nv,
                    });
                }
                if tet[i + 1..].contains(&v) {
                    return Err(TetMeshError::RepeatedVertex { tet: t, vertex: v });
                }
            }
        }
        for t in 0..self.num_tets() {
            let [a, b, c, d] = self.corners(t);
            let volume = tet_signed_volume(&a, &b, &c, &d);
            let quality = tet_quality(&a, &b, &c, &d);
            if volume < 0.0 && quality < -1e-12 {
                return Err(TetMeshError::Inverted {
                    tet: t,
                    vertices: self.tets[t],
                    volume,
                });
            }
            // A flat element: zero volume, or a quality at round-off level (|q| ≤ 1e-12), or below the minimum.
            if volume <= 0.0 || quality <= 1e-12 || quality < min_quality {
                return Err(TetMeshError::Degenerate {
                    tet: t,
                    vertices: self.tets[t],
                    volume,
                    quality,
                    min_quality,
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn unit() -> TetMesh {
        TetMesh::new(
            vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
            vec![[0, 1, 2, 3]],
        )
    }

    fn regular(edge: Real) -> [Vec3; 4] {
        let s = edge / (2.0 * 2f64.sqrt());
        [
            Vec3::new(1.0, 1.0, 1.0) * s,
            Vec3::new(1.0, -1.0, -1.0) * s,
            Vec3::new(-1.0, 1.0, -1.0) * s,
            Vec3::new(-1.0, -1.0, 1.0) * s,
        ]
    }

    #[test]
    fn unit_corner_tet_is_positive_with_outward_faces() {
        let m = unit();
        assert!((m.volume() - 1.0 / 6.0).abs() < 1e-15);
        m.validate(0.0).unwrap();
        // Each outward face normal points away from the opposite corner.
        let p = m.corners(0);
        for (i, f) in TET_FACES.iter().enumerate() {
            let n = (p[f[1]] - p[f[0]]).cross(&(p[f[2]] - p[f[0]]));
            assert!(n.dot(&(p[f[0]] - p[i])) > 0.0, "face {i} points inward");
        }
    }

    #[test]
    fn regular_tet_has_quality_one_at_any_size_and_pose() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for &edge in &[1e-3, 0.1, 3.0] {
            let r = regular(edge);
            let v = tet_signed_volume(&r[0], &r[1], &r[2], &r[3]);
            assert!(v.abs() > 0.0);
            let (r0, r1) = if v > 0.0 { (r[0], r[1]) } else { (r[1], r[0]) };
            let shift = Vec3::new(rng.random(), rng.random(), rng.random());
            let q = tet_quality(
                &(r0 + shift),
                &(r1 + shift),
                &(r[2] + shift),
                &(r[3] + shift),
            );
            assert!((q - 1.0).abs() < 1e-9, "edge {edge}: q = {q}");
        }
    }

    #[test]
    fn quality_is_in_range_and_sign_follows_volume() {
        for seed in [1u64, 2, 3] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            for _ in 0..200 {
                let p: Vec<Vec3> = (0..4)
                    .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
                    .collect();
                let q = tet_quality(&p[0], &p[1], &p[2], &p[3]);
                let v = tet_signed_volume(&p[0], &p[1], &p[2], &p[3]);
                assert!(q.abs() <= 1.0 + 1e-12);
                assert_eq!(q > 0.0, v > 0.0);
                let swapped = tet_quality(&p[1], &p[0], &p[2], &p[3]);
                assert!((q + swapped).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn flattening_drives_quality_to_zero() {
        let q_of = |h: Real| {
            let p = [Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::new(0.3, 0.3, h)];
            tet_quality(&p[0], &p[1], &p[2], &p[3])
        };
        assert!(q_of(1e-6) < 1e-3);
        assert!(q_of(1e-6) < q_of(1e-3) && q_of(1e-3) < q_of(0.5));
    }

    #[test]
    fn validate_names_the_inverted_tet_and_its_volume() {
        let mut m = unit();
        m.positions.push(Vec3::new(1.0, 1.0, 1.0));
        m.fixed.push(false);
        m.tets.push([2, 1, 3, 4]); // (b − a)·((c − a)×(d − a)) = −2 for this ordering.
        let err = m.validate(0.0).unwrap_err();
        match &err {
            TetMeshError::Inverted { tet, volume, .. } => {
                assert_eq!(*tet, 1);
                assert!((volume + 1.0 / 3.0).abs() < 1e-12, "{volume}");
            }
            other => panic!("unexpected {other:?}"),
        }
        assert!(err.to_string().contains("tetrahedron 1"));
    }

    #[test]
    fn validate_rejects_flat_repeated_and_out_of_range() {
        let mut flat = unit();
        flat.positions[3] = Vec3::new(0.2, 0.2, 0.0);
        assert!(matches!(
            flat.validate(0.0),
            Err(TetMeshError::Degenerate { tet: 0, .. })
        ));
        let mut rep = unit();
        rep.tets[0] = [0, 1, 1, 3];
        assert!(matches!(
            rep.validate(0.0),
            Err(TetMeshError::RepeatedVertex { tet: 0, vertex: 1 })
        ));
        let mut bad = unit();
        bad.tets[0] = [0, 1, 2, 9];
        assert!(matches!(
            bad.validate(0.0),
            Err(TetMeshError::BadIndex { vertex: 9, .. })
        ));
        let mut nan = unit();
        nan.positions[2].y = Real::NAN;
        assert!(matches!(
            nan.validate(0.0),
            Err(TetMeshError::NonFinite { vertex: 2, .. })
        ));
        let mut poor = unit();
        poor.positions[3] = Vec3::new(0.3, 0.3, 0.01);
        assert!(poor.validate(0.0).is_ok());
        assert!(matches!(
            poor.validate(0.2),
            Err(TetMeshError::Degenerate { .. })
        ));
    }

    #[test]
    fn quality_stats_count_inverted() {
        let mut m = unit();
        m.tets.push([1, 0, 2, 3]);
        let s = m.quality_stats();
        assert_eq!(s.inverted, 1);
        assert!(s.min < 0.0);
        assert!(s.mean.abs() < 1e-12);
    }
}
