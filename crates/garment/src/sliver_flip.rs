//! Sliver repair of a flat pattern triangulation by edge flips: an interior edge of a badly shaped
//! triangle is flipped to the other diagonal of its quadrilateral when that makes both triangles better.
//!
//! **Why.** A pattern is triangulated (refined to a minimum angle) on its first flattening, from the flat-faced
//! body mesh; the simulation then flattens each panel again from the cloth as it lies on the smooth limit
//! surface (`simulate::reflatten`). Where the cut line had a kink on the flat-faced mesh that the limit
//! surface smooths away — at the crotch of leggings on a finely graded scan — three consecutive boundary
//! samples a few millimetres apart come out nearly collinear, and the "ear" triangle they span degenerates
//! (pattern quality 0.05 was measured). Its long edge is interior: flipping it to the quadrilateral's other
//! diagonal replaces the sliver by two well-shaped triangles without touching the boundary, the seams or any
//! vertex.
//!
//! **Rule.** The quality of a triangle with corners `a, b, c` (m) is `q = 4√3·A / (|ab|² + |bc|² + |ca|²)`
//! (dimensionless: 1 equilateral, 0 degenerate, negative inverted; the measure the admissibility check
//! uses). An interior edge shared by triangles `t₁, t₂` with `min(q₁, q₂) < params.below` is flipped when
//! both new triangles are counter-clockwise and `min(q₁', q₂') > min(q₁, q₂)`. Each flip strictly raises
//! the smallest quality of the pair it replaces, so no state repeats; the passes stop when no edge
//! qualifies, or after `params.max_passes` passes over the edges. Triangles all above `below` are never
//! touched: a well-shaped pattern comes back unchanged, bit for bit.
//!
//! The triangles keep their indices (`faces[t]` is rewritten in place), so maps from pattern triangles to
//! cloth triangles stay valid; only the vertex triples of flipped triangles change.

use std::collections::HashMap;

use crate::math::{Real, Vec2};

/// Settings of [`sliver_flip`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliverFlipParams {
    /// Edges of triangles with quality below this are candidates (dimensionless, in (0, 1]). The default
    /// 0.3 lies well below what the pattern remesher produces (≥ 0.56 at its 28° angle bound) and above the
    /// admissibility limit (0.1).
    pub below: Real,
    /// Most passes over the interior edges.
    pub max_passes: usize,
}

impl Default for SliverFlipParams {
    fn default() -> Self {
        Self {
            below: 0.3,
            max_passes: 20,
        }
    }
}

/// Shape quality `4√3·A / (a² + b² + c²)` of the triangle `p0 p1 p2` (m), signed by orientation; 0 when all
/// edges have zero length (or a length is not finite). The one definition the admissibility check, the
/// design's remeshing trigger and this repair share.
pub fn triangle_quality(p0: Vec2, p1: Vec2, p2: Vec2) -> Real {
    let (e0, e1, e2) = (p1 - p0, p2 - p1, p0 - p2);
    let area = 0.5 * (e0.x * (-e2.y) - e0.y * (-e2.x));
    let sum = e0.norm_squared() + e1.norm_squared() + e2.norm_squared();
    if sum > 0.0 && sum.is_finite() {
        4.0 * (3.0 as Real).sqrt() * area / sum
    } else {
        0.0
    }
}

/// Flips interior edges of slivers in the triangulation `faces` (`#F`, counter-clockwise, indices into
/// `positions`, `#V × 2`, m) as the module documentation says. Returns the number of flips.
pub fn sliver_flip(
    positions: &[Vec2],
    faces: &mut [[usize; 3]],
    params: &SliverFlipParams,
) -> usize {
    let q = |f: [usize; 3]| triangle_quality(positions[f[0]], positions[f[1]], positions[f[2]]);
    let mut flips = 0;
    for _ in 0..params.max_passes {
        if !faces.iter().any(|&f| q(f) < params.below) {
            break;
        }
        // Directed edge (a, b) → (triangle, corner opposite the edge); an interior edge has both directions.
        let mut half: HashMap<(usize, usize), (usize, usize)> = HashMap::new();
        for (t, f) in faces.iter().enumerate() {
            for k in 0..3 {
                half.insert((f[k], f[(k + 1) % 3]), (t, (k + 2) % 3));
            }
        }
        let mut flipped_now = 0;
        let mut touched = vec![false; faces.len()];
        for t in 0..faces.len() {
            if touched[t] || q(faces[t]) >= params.below {
                continue;
            }
            // The best flip among this triangle's interior edges.
            let mut best: Option<(Real, usize, [usize; 3], [usize; 3])> = None;
            for k in 0..3 {
                let f = faces[t];
                let (a, b, c) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
                let Some(&(u, corner)) = half.get(&(b, a)) else {
                    continue; // a boundary edge
                };
                if touched[u] || faces[u][corner] == c {
                    continue;
                }
                let d = faces[u][corner];
                let old = q(f).min(q(faces[u]));
                // Edge a–b becomes c–d: triangles (c, a, d) and (d, b, c), counter-clockwise when the
                // quadrilateral a d b c is convex.
                let (n1, n2) = ([c, a, d], [d, b, c]);
                let new = q(n1).min(q(n2));
                if new > old && best.as_ref().is_none_or(|x| new > x.0) {
                    best = Some((new, u, n1, n2));
                }
            }
            if let Some((_, u, n1, n2)) = best {
                faces[t] = n1;
                faces[u] = n2;
                touched[t] = true;
                touched[u] = true;
                flipped_now += 1;
            }
        }
        flips += flipped_now;
        if flipped_now == 0 {
            break;
        }
    }
    flips
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: Real, y: Real) -> Vec2 {
        Vec2::new(x, y)
    }

    fn q3(p: &[Vec2], f: [usize; 3]) -> Real {
        triangle_quality(p[f[0]], p[f[1]], p[f[2]])
    }

    /// A fan of triangles around an ear whose middle vertex is nearly on the chord: the sliver
    /// (quality ≈ 0.03) is flipped away and every triangle ends above the threshold.
    #[test]
    fn an_ear_sliver_is_flipped_into_two_good_triangles() {
        // Boundary a(0,0) – m(1, 0.03) – b(2,0); interior apex x(1,-1.2); the ear a m b sits above chord a b.
        let p = vec![v(0.0, 0.0), v(1.0, 0.03), v(2.0, 0.0), v(1.0, -1.2)];
        let mut faces = vec![[0, 2, 1], [0, 3, 2]];
        // Orientation: (0, 2, 1) is counter-clockwise (the ear above the chord, seen from +z).
        assert!(q3(&p, faces[0]) > 0.0);
        assert!(q3(&p, faces[0]) < 0.05);
        let before = faces.clone();
        let n = sliver_flip(&p, &mut faces, &SliverFlipParams::default());
        assert_eq!(n, 1);
        assert_ne!(faces, before);
        for f in &faces {
            let qf = q3(&p, *f);
            assert!(qf > 0.3, "{f:?}: {qf}");
        }
        // Same vertex set, area preserved.
        let area = |fs: &[[usize; 3]]| -> Real {
            fs.iter()
                .map(|f| {
                    let [a, b, c] = f.map(|i| p[i]);
                    let (e1, e2) = (b - a, c - a);
                    0.5 * (e1.x * e2.y - e1.y * e2.x)
                })
                .sum()
        };
        assert!((area(&faces) - area(&before)).abs() < 1e-12);
    }

    /// Good triangulations are left bit for bit; a sliver whose flip would fold (non-convex quadrilateral)
    /// is left too — the checker can say no.
    #[test]
    fn good_meshes_and_impossible_flips_are_left_alone() {
        let p = vec![v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0), v(1.0, 1.0)];
        let mut faces = vec![[0, 1, 2], [1, 3, 2]];
        let before = faces.clone();
        assert_eq!(sliver_flip(&p, &mut faces, &SliverFlipParams::default()), 0);
        assert_eq!(faces, before);
        // A sliver (0, 1, 2) whose neighbour across 0–1 is a sliver too, reaching past vertex 1: the
        // quadrilateral 0 3 1 2 is reflex at 1, and the other diagonal would fold a triangle over.
        let p = vec![v(0.0, 0.0), v(2.0, 0.0), v(1.0, 0.02), v(3.0, -0.001)];
        let mut faces = vec![[0, 1, 2], [0, 3, 1]];
        let before = faces.clone();
        assert!(q3(&p, faces[1]) > 0.0);
        assert_eq!(sliver_flip(&p, &mut faces, &SliverFlipParams::default()), 0);
        assert_eq!(faces, before);
    }
}
