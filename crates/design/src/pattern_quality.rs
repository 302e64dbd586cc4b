//! Pattern element quality and the remesh trigger.
//!
//! As the optimizer moves the pattern boundary, the bi-harmonic interior follows, but triangles can become
//! skinny and boundary edges uneven. This module measures that and decides when the pattern should be
//! remeshed:
//!
//! - the shape quality of a triangle with area `A` and edge lengths `a, b, c` is
//!   `q = 4√3·A / (a² + b² + c²)`, dimensionless, 1 for an equilateral triangle, 0 for a degenerate one and
//!   negative for an inverted (clockwise) one;
//! - the boundary edge ratio is the largest of `ℓ / ℓ₀` and `ℓ₀ / ℓ` over the panel boundary edges of
//!   length `ℓ` (m), `ℓ₀` (m) being the garment's target edge length (≥ 1; 1 when every boundary edge has
//!   the target length).
//!
//! [`PatternQualityParams::needs_remesh`] fires when the smallest triangle quality falls below
//! `min_quality` or the boundary edge ratio exceeds `max_edge_ratio`.

use crate::design_mesh::DesignMesh;
use crate::math::{Real, Vec2};

/// When a pattern is remeshed.
#[derive(Clone, Debug, PartialEq)]
pub struct PatternQualityParams {
    /// Remesh when the smallest triangle shape quality `4√3·A / Σ edge²` falls below this (in `[0, 1)`;
    /// 0 disables the quality trigger).
    pub min_quality: Real,
    /// Remesh when a boundary edge is longer or shorter than the target edge length by more than this factor
    /// (> 1; infinity disables the edge trigger).
    pub max_edge_ratio: Real,
    /// At most this many remeshes per run.
    pub max_remeshes: usize,
}

impl Default for PatternQualityParams {
    fn default() -> Self {
        Self {
            min_quality: 0.2,
            max_edge_ratio: 3.0,
            max_remeshes: 4,
        }
    }
}

/// Quality of a pattern at given positions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatternQuality {
    /// Smallest triangle shape quality (dimensionless, ≤ 1; negative when a triangle is inverted).
    pub min_quality: Real,
    /// Triangle with the smallest quality.
    pub worst_triangle: usize,
    /// Largest of `ℓ/ℓ₀`, `ℓ₀/ℓ` over the boundary edges (≥ 1; infinity for a zero-length edge).
    pub max_edge_ratio: Real,
}

pub use skintight_garment::sliver_flip::triangle_quality;

impl PatternQualityParams {
    /// A one-line message when the parameters are out of range.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.min_quality.is_finite() && (0.0..1.0).contains(&self.min_quality)) {
            return Err(format!(
                "min_quality must be in [0, 1), got {}",
                self.min_quality
            ));
        }
        if self.max_edge_ratio.is_nan() || self.max_edge_ratio <= 1.0 {
            return Err(format!(
                "max_edge_ratio must be > 1, got {}",
                self.max_edge_ratio
            ));
        }
        Ok(())
    }

    /// Whether a pattern of quality `quality` should be remeshed (ignores `max_remeshes`).
    pub fn needs_remesh(&self, quality: &PatternQuality) -> bool {
        quality.min_quality < self.min_quality || quality.max_edge_ratio > self.max_edge_ratio
    }
}

/// Quality of `mesh`'s pattern at the `#Vp` positions `pattern` (m), boundary edges compared with the target
/// edge length `edge_length` (m, > 0).
pub fn pattern_quality(mesh: &DesignMesh, pattern: &[Vec2], edge_length: Real) -> PatternQuality {
    let mut min_quality = Real::INFINITY;
    let mut worst_triangle = 0;
    for (f, t) in mesh.pattern_triangles.iter().enumerate() {
        let q = triangle_quality(pattern[t[0]], pattern[t[1]], pattern[t[2]]);
        // NaN positions count as the worst possible triangle.
        let q = if q.is_nan() { Real::NEG_INFINITY } else { q };
        if q < min_quality {
            min_quality = q;
            worst_triangle = f;
        }
    }
    let mut max_edge_ratio: Real = 1.0;
    for panel in &mesh.panels {
        let n = panel.boundary.len();
        for i in 0..n {
            let l = (pattern[panel.boundary[(i + 1) % n]] - pattern[panel.boundary[i]]).norm();
            let ratio = if l > 0.0 {
                (l / edge_length).max(edge_length / l)
            } else {
                Real::INFINITY
            };
            let ratio = if ratio.is_nan() {
                Real::INFINITY
            } else {
                ratio
            };
            max_edge_ratio = max_edge_ratio.max(ratio);
        }
    }
    if mesh.pattern_triangles.is_empty() {
        min_quality = 1.0;
    }
    PatternQuality {
        min_quality,
        worst_triangle,
        max_edge_ratio,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design_mesh::DesignPanel;

    /// An `n × n` grid of squares of side `h` split into triangles, one panel, no seams.
    fn grid(n: usize, h: Real) -> (DesignMesh, Vec<Vec2>) {
        let id = |i: usize, j: usize| j * (n + 1) + i;
        let mut pattern = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                pattern.push(Vec2::new(i as Real * h, j as Real * h));
            }
        }
        let mut tris = Vec::new();
        for j in 0..n {
            for i in 0..n {
                tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        let mut boundary = Vec::new();
        boundary.extend((0..n).map(|i| id(i, 0)));
        boundary.extend((0..n).map(|j| id(n, j)));
        boundary.extend((1..=n).rev().map(|i| id(i, n)));
        boundary.extend((1..=n).rev().map(|j| id(0, j)));
        let nv = pattern.len();
        let mesh = DesignMesh {
            cloth_triangles: tris.clone(),
            pattern_triangles: tris,
            pattern_cloth_vertex: (0..nv).collect(),
            pattern_panel: vec![0; nv],
            panels: vec![DesignPanel {
                name: "p".into(),
                first_vertex: 0,
                num_vertices: nv,
                boundary_borders: vec![None; boundary.len()],
                boundary,
            }],
            seams: vec![],
            num_cloth_vertices: nv,
        };
        (mesh, pattern)
    }

    #[test]
    fn triangle_quality_is_one_for_equilateral_and_signed() {
        let a = Vec2::new(0.0, 0.0);
        let b = Vec2::new(0.01, 0.0);
        let c = Vec2::new(0.005, 0.005 * (3.0 as Real).sqrt());
        assert!((triangle_quality(a, b, c) - 1.0).abs() < 1e-12);
        assert!((triangle_quality(a, c, b) + 1.0).abs() < 1e-12);
        assert_eq!(triangle_quality(a, a, a), 0.0);
        // Right isosceles: 4√3·(1/2) / 4 = √3/2.
        let q = triangle_quality(a, Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0));
        assert!((q - (3.0 as Real).sqrt() / 2.0).abs() < 1e-12);
        // Scale invariant.
        let s = triangle_quality(a * 1e-3, Vec2::new(1e-3, 0.0), Vec2::new(0.0, 1e-3));
        assert!((q - s).abs() < 1e-12);
    }

    #[test]
    fn grid_quality_and_trigger_at_several_sizes() {
        let params = PatternQualityParams::default();
        params.validate().unwrap();
        for (n, h) in [(2, 0.01), (5, 0.004), (12, 0.001)] {
            let (mesh, mut pattern) = grid(n, h);
            let q = pattern_quality(&mesh, &pattern, h);
            assert!((q.min_quality - (3.0 as Real).sqrt() / 2.0).abs() < 1e-12);
            assert!((q.max_edge_ratio - 1.0).abs() < 1e-12);
            assert!(!params.needs_remesh(&q));
            // Squash an interior-adjacent vertex towards its neighbour: a skinny triangle.
            let v = n + 2; // vertex (1, 1)
            pattern[v] = Vec2::new(0.95 * h, 0.05 * h);
            let q = pattern_quality(&mesh, &pattern, h);
            assert!(q.min_quality < params.min_quality, "n {n}: {q:?}");
            assert!(params.needs_remesh(&q));
            let t = mesh.pattern_triangles[q.worst_triangle];
            assert!(t.contains(&v));
        }
    }

    #[test]
    fn boundary_edge_ratio_trigger() {
        let params = PatternQualityParams {
            min_quality: 0.0,
            ..Default::default()
        };
        let (mesh, mut pattern) = grid(4, 0.01);
        // Stretch the whole pattern along x by 4: boundary edges along x are 4× the target.
        for p in &mut pattern {
            p.x *= 4.0;
        }
        let q = pattern_quality(&mesh, &pattern, 0.01);
        assert!((q.max_edge_ratio - 4.0).abs() < 1e-9);
        assert!(params.needs_remesh(&q));
        // Same pattern with a matching target: only the y edges are off, by 1.
        let q = pattern_quality(&mesh, &pattern, 0.04);
        assert!((q.max_edge_ratio - 4.0).abs() < 1e-9);
        let q = pattern_quality(&mesh, &pattern, 0.02);
        assert!((q.max_edge_ratio - 2.0).abs() < 1e-9);
        assert!(!params.needs_remesh(&q));
    }

    #[test]
    fn bad_input_is_reported_not_panicking() {
        let (mesh, mut pattern) = grid(2, 0.01);
        pattern[4] = Vec2::new(Real::NAN, 0.0);
        let q = pattern_quality(&mesh, &pattern, 0.01);
        assert!(q.min_quality == Real::NEG_INFINITY || q.min_quality < 0.2);
        assert!(PatternQualityParams::default().needs_remesh(&q));
        let bad = PatternQualityParams {
            min_quality: 1.5,
            ..Default::default()
        };
        assert!(bad.validate().unwrap_err().contains("min_quality"));
        let bad = PatternQualityParams {
            max_edge_ratio: 0.5,
            ..Default::default()
        };
        assert!(bad.validate().unwrap_err().contains("max_edge_ratio"));
    }
}
