//! The target surfaces of the shape objective that are given by numbers rather than a file.

use skintight_geometry::math::{Real, Vec3};
use skintight_geometry::mesh::TriMesh;

/// A surface of revolution about y through the profile `[y, r]` (linear between points), open at both
/// ends, outward normals (counter-clockwise seen from outside). Rows are spaced about as far apart as the
/// `segments` vertices around, so the triangles are well shaped (the IMLS radius follows the edge length).
pub fn revolution_target(profile: &[[Real; 2]], segments: usize) -> TriMesh {
    // Heights: each profile interval split into pieces no longer than the spacing around.
    let mut rows: Vec<[Real; 2]> = vec![profile[0]];
    for w in profile.windows(2) {
        let ([y0, r0], [y1, r1]) = (w[0], w[1]);
        let around = 2.0 * std::f64::consts::PI * r0.max(r1) / segments as Real;
        let pieces = (((y1 - y0).hypot(r1 - r0) / around).ceil() as usize).max(1);
        for k in 1..=pieces {
            let t = k as Real / pieces as Real;
            rows.push([y0 + t * (y1 - y0), r0 + t * (r1 - r0)]);
        }
    }
    let mut positions = Vec::with_capacity(rows.len() * segments);
    for &[y, r] in &rows {
        for k in 0..segments {
            let a = 2.0 * std::f64::consts::PI * k as Real / segments as Real;
            positions.push(Vec3::new(r * a.cos(), y, -r * a.sin()));
        }
    }
    let mut faces = Vec::with_capacity(2 * (rows.len() - 1) * segments);
    for j in 0..rows.len() - 1 {
        for k in 0..segments {
            let (a, b) = (j * segments + k, j * segments + (k + 1) % segments);
            let (c, d) = (a + segments, b + segments);
            faces.push([a, b, d]);
            faces.push([a, d, c]);
        }
    }
    TriMesh {
        positions,
        faces,
        ..Default::default()
    }
}
