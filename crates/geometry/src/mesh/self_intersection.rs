//! Pairs of triangles of one surface that cross each other, accelerated by a uniform grid.
//!
//! Pairs that share a vertex are skipped: they always touch there, and telling a fold at a shared vertex from
//! a legitimate contact needs tests this check does not make. Coplanar overlaps are not reported (see
//! [`crate::mesh::triangle_intersection`]).

use crate::math::{Real, Vec3};
use crate::mesh::triangle_grid::TriangleGrid;
use crate::mesh::triangle_intersection::triangles_intersect;

/// All pairs `(f, g)`, `f < g`, of faces that share no vertex and intersect, in ascending order. `cell_size`
/// (m) of the acceleration grid: about twice the mean edge length works well; pass 0 to choose that.
pub fn self_intersections(
    positions: &[Vec3],
    faces: &[[usize; 3]],
    cell_size: Real,
) -> Vec<(usize, usize)> {
    let cell = if cell_size > 0.0 {
        cell_size
    } else {
        2.0 * mean_edge_length(positions, faces)
    };
    let grid = TriangleGrid::new(positions, faces, cell);
    let bbox = |f: usize| {
        let [a, b, c] = faces[f].map(|v| positions[v]);
        (a.inf(&b).inf(&c), a.sup(&b).sup(&c))
    };
    let mut pairs = Vec::new();
    let dims = grid.dims();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let items = grid.cell(i, j, k);
                for (x, &f) in items.iter().enumerate() {
                    let f = f as usize;
                    let (flo, fhi) = bbox(f);
                    for &g in &items[x + 1..] {
                        let g = g as usize;
                        let (glo, ghi) = bbox(g);
                        // Boxes must overlap.
                        if (0..3).any(|d| flo[d] > ghi[d] || glo[d] > fhi[d]) {
                            continue;
                        }
                        // Test each pair once: in the first cell both boxes share.
                        let (first, _) = grid.cell_range(&flo.sup(&glo), &fhi.inf(&ghi));
                        if first != [i, j, k] {
                            continue;
                        }
                        if faces[f].iter().any(|v| faces[g].contains(v)) {
                            continue;
                        }
                        let tf = faces[f].map(|v| positions[v]);
                        let tg = faces[g].map(|v| positions[v]);
                        if triangles_intersect(&tf, &tg) {
                            pairs.push((f.min(g), f.max(g)));
                        }
                    }
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

/// Mean edge length (m) over the faces' edges (each interior edge counted twice); 0 without faces.
pub fn mean_edge_length(positions: &[Vec3], faces: &[[usize; 3]]) -> Real {
    if faces.is_empty() {
        return 0.0;
    }
    let sum: Real = faces
        .iter()
        .map(|f| {
            (0..3)
                .map(|e| (positions[f[(e + 1) % 3]] - positions[f[e]]).norm())
                .sum::<Real>()
        })
        .sum();
    sum / (3 * faces.len()) as Real
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Brute force over all pairs, for comparison.
    fn brute(p: &[Vec3], faces: &[[usize; 3]]) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for f in 0..faces.len() {
            for g in f + 1..faces.len() {
                if faces[f].iter().any(|v| faces[g].contains(v)) {
                    continue;
                }
                if triangles_intersect(&faces[f].map(|v| p[v]), &faces[g].map(|v| p[v])) {
                    out.push((f, g));
                }
            }
        }
        out
    }

    #[test]
    fn grid_finds_the_same_pairs_as_brute_force() {
        for (seed, n) in [(1u64, 40usize), (2, 80), (3, 150)] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut p = Vec::new();
            let mut faces = Vec::new();
            for t in 0..n {
                let c = Vec3::new(rng.random(), rng.random(), rng.random());
                for _ in 0..3 {
                    p.push(c + 0.3 * Vec3::new(rng.random(), rng.random(), rng.random()));
                }
                faces.push([3 * t, 3 * t + 1, 3 * t + 2]);
            }
            let expect = brute(&p, &faces);
            assert!(
                !expect.is_empty(),
                "seed {seed}: the fixture should intersect"
            );
            for cell in [0.0, 0.05, 0.3] {
                assert_eq!(
                    self_intersections(&p, &faces, cell),
                    expect,
                    "seed {seed} cell {cell}"
                );
            }
        }
    }
}
