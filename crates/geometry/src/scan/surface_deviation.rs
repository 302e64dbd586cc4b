//! Distances between two triangle surfaces: the closest point of a triangle mesh to a query point, and the
//! mean and Hausdorff deviation of one surface from another.
//!
//! Units: positions and distances in the meshes' units (metres for skintight); the report of
//! [`crate::scan`] converts to millimetres.
//!
//! Method: the point–triangle closest point of Ericson, *Real-Time Collision Detection* (2005), §5.1.5
//! (Voronoi regions of the triangle), accelerated by the uniform [`TriangleGrid`] of the repository: a query
//! looks in a box of half-width `r` around the point and doubles `r` until the best distance found is at
//! most `r` (every triangle within `r` has a bounding box that meets the query box, so the answer is exact).
//! The deviation of surface A from surface B is sampled at A's vertices (one-sided), the mean weighted by
//! each vertex's share of the area; the symmetric
//! Hausdorff distance is the larger of the two one-sided maxima (Cignon, Rocchini & Scopigno 1998, "Metro:
//! measuring error on simplified surfaces", sample at vertices).

use crate::math::{Real, Vec3};
use crate::mesh::triangle_grid::TriangleGrid;

/// The closest point to `p` on triangle `(a, b, c)` (Ericson 2005, §5.1.5).
pub fn closest_point_on_triangle(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Vec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return a + ab * v;
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return a + ac * w;
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return b + (c - b) * w;
    }
    let denom = va + vb + vc;
    if denom.abs() < Real::MIN_POSITIVE {
        return *a;
    }
    let v = vb / denom;
    let w = vc / denom;
    a + ab * v + ac * w
}

/// A triangle mesh prepared for closest-point queries.
#[derive(Clone, Debug)]
pub struct ClosestPointGrid {
    positions: Vec<Vec3>,
    faces: Vec<[usize; 3]>,
    grid: TriangleGrid,
    diagonal: Real,
}

/// The answer to a closest-point query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Closest {
    /// The closest point on the surface.
    pub point: Vec3,
    /// Its face.
    pub face: usize,
    /// The distance to the query point.
    pub distance: Real,
}

impl ClosestPointGrid {
    /// Indexes the mesh with cells of about `cell_size` (pass the mean edge length or a small multiple).
    /// Positions must be finite.
    pub fn new(positions: &[Vec3], faces: &[[usize; 3]], cell_size: Real) -> Self {
        let grid = TriangleGrid::new(positions, faces, cell_size);
        let mut lo = Vec3::repeat(Real::INFINITY);
        let mut hi = Vec3::repeat(Real::NEG_INFINITY);
        for p in positions {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let diagonal = if faces.is_empty() {
            0.0
        } else {
            (hi - lo).norm()
        };
        Self {
            positions: positions.to_vec(),
            faces: faces.to_vec(),
            grid,
            diagonal,
        }
    }

    /// The faces indexed.
    pub fn faces(&self) -> &[[usize; 3]] {
        &self.faces
    }

    /// Area-weighted normal `(b − a) × (c − a)` of face `f`.
    pub fn face_normal(&self, f: usize) -> Vec3 {
        let [a, b, c] = self.faces[f].map(|v| self.positions[v]);
        (b - a).cross(&(c - a))
    }

    /// The closest point of the surface to `p`; `None` without faces or for a non-finite `p`. `seen` and
    /// `stamp` are scratch space as in [`TriangleGrid::for_each_in_box`] (`stamp` is advanced here).
    pub fn closest(&self, p: &Vec3, seen: &mut Vec<u32>, stamp: &mut u32) -> Option<Closest> {
        if self.faces.is_empty() || !p.iter().all(|x| x.is_finite()) {
            return None;
        }
        let mut r = self.grid.cell_size() * 0.5;
        loop {
            *stamp = stamp.wrapping_add(1);
            if *stamp == 0 {
                seen.iter_mut().for_each(|s| *s = 0);
                *stamp = 1;
            }
            let mut best: Option<Closest> = None;
            let lo = p - Vec3::repeat(r);
            let hi = p + Vec3::repeat(r);
            self.grid.for_each_in_box(&lo, &hi, seen, *stamp, |f| {
                let [a, b, c] = self.faces[f].map(|v| self.positions[v]);
                let q = closest_point_on_triangle(p, &a, &b, &c);
                let d = (q - p).norm();
                if best.is_none_or(|b| d < b.distance) {
                    best = Some(Closest {
                        point: q,
                        face: f,
                        distance: d,
                    });
                }
            });
            if best.is_some_and(|b| b.distance <= r) {
                return best;
            }
            // Past the whole box every triangle has been seen.
            if r > 2.0 * self.diagonal + (p - self.grid_center()).norm() {
                return best;
            }
            r *= 2.0;
        }
    }

    fn grid_center(&self) -> Vec3 {
        self.positions.first().copied().unwrap_or_else(Vec3::zeros)
    }
}

/// One-sided deviation of points from a surface.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Deviation {
    /// Mean distance.
    pub mean: Real,
    /// Largest distance.
    pub max: Real,
    /// Number of points measured.
    pub samples: usize,
}

/// The area each vertex stands for: a third of the area of its faces (the barycentric cell).
pub fn vertex_areas(positions: &[Vec3], faces: &[[usize; 3]]) -> Vec<Real> {
    let mut w = vec![0.0; positions.len()];
    for f in faces {
        let [a, b, c] = f.map(|v| positions[v]);
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        if area.is_finite() {
            for &v in f {
                w[v] += area / 3.0;
            }
        }
    }
    w
}

/// Distances from each of `points` to the surface, summarized: the mean weighted by `weight` (pass
/// [`vertex_areas`] for a mean over the area, so that densely sampled regions do not dominate) and the
/// largest. Points of weight 0 are skipped.
pub fn deviation_of_points(
    points: &[Vec3],
    weight: impl Fn(usize) -> Real,
    surface: &ClosestPointGrid,
) -> Deviation {
    let mut seen = Vec::new();
    let mut stamp = 0u32;
    let mut sum = 0.0;
    let mut wsum = 0.0;
    let mut max: Real = 0.0;
    let mut n = 0;
    for (i, p) in points.iter().enumerate() {
        let w = weight(i);
        if w <= 0.0 || !w.is_finite() {
            continue;
        }
        if let Some(c) = surface.closest(p, &mut seen, &mut stamp) {
            sum += w * c.distance;
            wsum += w;
            max = max.max(c.distance);
            n += 1;
        }
    }
    Deviation {
        mean: if wsum > 0.0 { sum / wsum } else { 0.0 },
        max,
        samples: n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::icosphere;

    #[test]
    fn closest_point_regions() {
        let a = Vec3::zeros();
        let b = Vec3::x();
        let c = Vec3::y();
        let q = |p: Vec3| closest_point_on_triangle(&p, &a, &b, &c);
        assert!((q(Vec3::new(0.2, 0.2, 1.0)) - Vec3::new(0.2, 0.2, 0.0)).norm() < 1e-15);
        assert_eq!(q(Vec3::new(-1.0, -1.0, 0.0)), a);
        assert_eq!(q(Vec3::new(2.0, -0.1, 0.0)), b);
        assert!((q(Vec3::new(0.5, -1.0, 0.0)) - Vec3::new(0.5, 0.0, 0.0)).norm() < 1e-15);
        assert!((q(Vec3::new(1.0, 1.0, 0.0)) - Vec3::new(0.5, 0.5, 0.0)).norm() < 1e-15);
    }

    #[test]
    fn grid_query_matches_brute_force_near_and_far() {
        let m = icosphere(3, 1.0);
        let grid = ClosestPointGrid::new(&m.positions, &m.faces, 0.1);
        let mut seen = Vec::new();
        let mut stamp = 0;
        for p in [
            Vec3::new(0.3, 0.2, 0.1),
            Vec3::new(1.5, -0.2, 0.7),
            Vec3::new(40.0, 3.0, -9.0),
        ] {
            let got = grid.closest(&p, &mut seen, &mut stamp).unwrap();
            let brute = m
                .faces
                .iter()
                .map(|f| {
                    let [a, b, c] = f.map(|v| m.positions[v]);
                    (closest_point_on_triangle(&p, &a, &b, &c) - p).norm()
                })
                .fold(Real::INFINITY, Real::min);
            assert!((got.distance - brute).abs() < 1e-12, "{p:?}");
        }
    }

    #[test]
    fn deviation_of_a_scaled_sphere() {
        let m = icosphere(3, 1.0);
        let grid = ClosestPointGrid::new(&m.positions, &m.faces, 0.1);
        let scaled: Vec<Vec3> = m.positions.iter().map(|p| p * 1.01).collect();
        let d = deviation_of_points(&scaled, |_| 1.0, &grid);
        assert!((d.mean - 0.01).abs() < 1e-9 && (d.max - 0.01).abs() < 1e-9);
        assert_eq!(d.samples, m.num_vertices());
    }
}
