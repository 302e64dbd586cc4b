//! The voxels around the rest-pose yarn centrelines (the knitwear paper, Sec. 4): a uniform grid of cubes of
//! edge `h` (m), and every yarn segment walked through it voxel by voxel.
//!
//! **The walk.** The paper names the 3D Bresenham algorithm; this file walks each segment with the exact
//! grid traversal of Amanatides and Woo ("A fast voxel traversal algorithm for ray tracing", Eurographics
//! 1987) instead. Bresenham takes one voxel per step along the dominant axis and so skips the voxels a
//! segment only clips at a corner; those clipped pieces of yarn would then lie outside the mesh, with no
//! tetrahedron to embed them in and no nodes to take their mass (Eq. 2). The exact traversal visits every
//! voxel that holds a non-zero piece of the segment — what the paper asks of its grid ("each voxel
//! encapsulates a non-zero portion of a yarn thread") — and nothing else. In grid coordinates
//! `u = (x − o) / h` the segment `u(t) = u₀ + t (u₁ − u₀)`, `t ∈ [0, 1]`, crosses the plane `u_i = n` at
//! `t = (n − u₀ᵢ) / (u₁ᵢ − u₀ᵢ)`; the walk steps across whichever of the three next planes comes first.
//!
//! **Corner voxels (6-connectivity).** The walk moves one axis at a time, also when two or three crossings
//! coincide (the segment passes exactly through a voxel edge or corner): it then steps the axes one after the
//! other, lowest axis first, which adds the voxel the paper adds "in rare cases where the thread passes
//! through a voxel corner". Every two consecutive voxels of a walk therefore share a face, and a segment
//! from cell `c₀ = ⌊u₀⌋` to `c₁ = ⌊u₁⌋` takes exactly `‖c₁ − c₀‖₁` steps, so the walk always ends in `c₁`
//! and terminates whatever the round-off. Consecutive segments share their vertex and thus their end and
//! start voxels, so the voxels of one yarn are one face-connected chain and the tetrahedra built on them one
//! connected solid.
//!
//! **Dilation** (optional, `layers ≥ 1`): every voxel's `(2·layers + 1)³` neighbourhood is added, so the mesh
//! encloses the yarn tubes and not only their centrelines. The paper does not dilate; the default is none.
//!
//! **Counting before building** ([`walk_bound`]): a yarn's walk visits `1 + Σ ‖c₁ − c₀‖₁` voxels over its
//! segments, revisits included, so that sum is an upper bound on its distinct voxels, computable in one
//! pass without storing any voxel. No derivatives: this is a discrete construction.

use serde::{Deserialize, Serialize};

/// A uniform grid: voxel `c = [i, j, k]` is the cube `o + h·([i, i+1] × [j, j+1] × [k, k+1])`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct VoxelGrid {
    /// The grid's origin `o` (m): the corner of voxel `[0, 0, 0]`.
    pub origin: [f64; 3],
    /// The voxel edge length `h` (m).
    pub voxel_m: f64,
}

impl VoxelGrid {
    /// Grid coordinates `u = (x − o) / h` (dimensionless) of a point `x` (m).
    pub fn coordinates(&self, x: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|i| (x[i] - self.origin[i]) / self.voxel_m)
    }

    /// The voxel `⌊u⌋` holding grid coordinates `u` (a point on a voxel face belongs to the upper voxel).
    pub fn cell(u: [f64; 3]) -> [i64; 3] {
        std::array::from_fn(|i| u[i].floor() as i64)
    }

    /// The position (m) of grid point `c` (a voxel corner, a mesh node).
    pub fn point(&self, c: [i64; 3]) -> [f64; 3] {
        std::array::from_fn(|i| self.origin[i] + self.voxel_m * c[i] as f64)
    }
}

/// Appends to `out` the voxels the segment from grid coordinates `a` to `b` passes through, in order, from
/// `⌊a⌋` to `⌊b⌋`, every two consecutive ones sharing a face (`‖⌊b⌋ − ⌊a⌋‖₁ + 1` voxels).
pub fn walk(a: [f64; 3], b: [f64; 3], out: &mut Vec<[i64; 3]>) {
    let (c0, c1) = (VoxelGrid::cell(a), VoxelGrid::cell(b));
    let mut c = c0;
    out.push(c);
    let d: [f64; 3] = std::array::from_fn(|i| b[i] - a[i]);
    let step: [i64; 3] = std::array::from_fn(|i| (c1[i] - c0[i]).signum());
    let mut remaining: [u64; 3] = std::array::from_fn(|i| c1[i].abs_diff(c0[i]));
    // Parameter of the next plane crossing along each axis (recomputed from `a` after each step, so no error
    // accumulates along long segments).
    let next = |i: usize, ci: i64| -> f64 {
        let plane = if step[i] > 0 { ci + 1 } else { ci } as f64;
        (plane - a[i]) / d[i]
    };
    let mut t_next: [f64; 3] = std::array::from_fn(|i| {
        if remaining[i] > 0 {
            next(i, c[i])
        } else {
            f64::INFINITY
        }
    });
    while remaining.iter().any(|&r| r > 0) {
        let mut axis = 3;
        for i in 0..3 {
            if remaining[i] > 0 && (axis == 3 || t_next[i] < t_next[axis]) {
                axis = i;
            }
        }
        c[axis] += step[axis];
        remaining[axis] -= 1;
        t_next[axis] = if remaining[axis] > 0 {
            next(axis, c[axis])
        } else {
            f64::INFINITY
        };
        out.push(c);
    }
}

/// The distinct voxels (sorted) holding the polylines, each given as its grid coordinates and whether its
/// last vertex joins its first; with `layers` of dilation.
pub fn voxelize(polylines: &[(&[[f64; 3]], bool)], layers: usize) -> Vec<[i64; 3]> {
    let mut cells = Vec::new();
    for &(u, closed) in polylines {
        match u.len() {
            0 => {}
            1 => cells.push(VoxelGrid::cell(u[0])),
            n => {
                let edges = if closed { n } else { n - 1 };
                for k in 0..edges {
                    walk(u[k], u[(k + 1) % n], &mut cells);
                }
            }
        }
    }
    cells.sort_unstable();
    cells.dedup();
    if layers == 0 {
        return cells;
    }
    // The cube neighbourhood is the product of three 1D ones: dilate along x, then y, then z, deduplicating
    // after each, so no intermediate list exceeds (2·layers + 1) times the final one.
    let l = layers as i64;
    for axis in 0..3 {
        let mut dilated = Vec::with_capacity(cells.len() * (2 * layers + 1));
        for c in &cells {
            for d in -l..=l {
                let mut n = *c;
                n[axis] += d;
                dilated.push(n);
            }
        }
        dilated.sort_unstable();
        dilated.dedup();
        cells = dilated;
    }
    cells
}

/// Upper bounds on what [`voxelize`] and the six-tetrahedra split make of the same polylines, computed without
/// storing a voxel: `(voxels, nodes)`. Per polyline, the walk's `s = Σ ‖c₁ − c₀‖₁` steps give at most `1 + s`
/// voxels and, each step adding at most one face's 4 new grid points, at most `8 + 4 s` nodes; with `ℓ` layers
/// of dilation the first voxel brings `(2ℓ + 1)³` voxels and `(2ℓ + 2)³` nodes and each step at most
/// `(2ℓ + 1)²` and `(2ℓ + 2)²` more. Both are also capped by the grid box around all the polylines. In `f64`
/// so that absurd inputs cannot overflow.
pub fn walk_bound(polylines: &[(&[[f64; 3]], bool)], layers: usize) -> (f64, f64) {
    let l = layers as f64;
    let (v_first, v_step) = ((2.0 * l + 1.0).powi(3), (2.0 * l + 1.0).powi(2));
    let (n_first, n_step) = ((2.0 * l + 2.0).powi(3), (2.0 * l + 2.0).powi(2));
    let (mut voxels, mut nodes) = (0.0, 0.0);
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for &(u, closed) in polylines {
        if u.is_empty() {
            continue;
        }
        for p in u {
            for i in 0..3 {
                lo[i] = lo[i].min(p[i].floor());
                hi[i] = hi[i].max(p[i].floor());
            }
        }
        let n = u.len();
        let edges = match n {
            1 => 0,
            _ if closed => n,
            _ => n - 1,
        };
        let mut steps = 0.0;
        for k in 0..edges {
            let (a, b) = (u[k], u[(k + 1) % n]);
            steps += (0..3)
                .map(|i| (b[i].floor() - a[i].floor()).abs())
                .sum::<f64>();
        }
        voxels += v_first + v_step * steps;
        nodes += n_first + n_step * steps;
    }
    if voxels == 0.0 {
        return (0.0, 0.0);
    }
    let extent: [f64; 3] = std::array::from_fn(|i| hi[i] - lo[i] + 1.0 + 2.0 * l);
    let box_voxels = extent[0] * extent[1] * extent[2];
    let box_nodes = (extent[0] + 1.0) * (extent[1] + 1.0) * (extent[2] + 1.0);
    (voxels.min(box_voxels), nodes.min(box_nodes))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn face_adjacent(a: [i64; 3], b: [i64; 3]) -> bool {
        (0..3).map(|i| a[i].abs_diff(b[i])).sum::<u64>() == 1
    }

    #[test]
    fn a_walk_is_face_connected_ends_where_it_should_and_covers_the_segment() {
        let mut rng = ChaCha8Rng::seed_from_u64(43);
        for _ in 0..500 {
            let a: [f64; 3] = std::array::from_fn(|_| rng.random_range(-5.0..5.0));
            let b: [f64; 3] = std::array::from_fn(|_| rng.random_range(-5.0..5.0));
            let mut out = Vec::new();
            walk(a, b, &mut out);
            let (c0, c1) = (VoxelGrid::cell(a), VoxelGrid::cell(b));
            assert_eq!(out[0], c0);
            assert_eq!(*out.last().unwrap(), c1);
            let l1: u64 = (0..3).map(|i| c0[i].abs_diff(c1[i])).sum();
            assert_eq!(out.len() as u64, l1 + 1);
            assert!(out.windows(2).all(|w| face_adjacent(w[0], w[1])));
            // The segment's piece inside each visited voxel (slab intersection, in t) is non-empty, and the
            // pieces follow each other without gaps from t = 0 to t = 1: every point of the segment lies in
            // a visited voxel, and every visited voxel holds a piece of positive length.
            let pieces: Vec<(f64, f64)> = out.iter().map(|&c| piece(a, b, c)).collect();
            assert!(pieces[0].0 <= 0.0 && pieces.last().unwrap().1 >= 1.0);
            for (k, &(t0, t1)) in pieces.iter().enumerate() {
                assert!(
                    t1 - t0 > 1e-12,
                    "voxel {:?} holds no piece: {t0}..{t1}",
                    out[k]
                );
            }
            for w in pieces.windows(2) {
                assert!((w[0].1 - w[1].0).abs() < 1e-12, "gap {w:?}");
            }
        }
    }

    /// The parameter interval of the segment `a → b` inside the closed voxel `c`, clipped to `[0, 1]`.
    fn piece(a: [f64; 3], b: [f64; 3], c: [i64; 3]) -> (f64, f64) {
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for i in 0..3 {
            let d = b[i] - a[i];
            let (lo, hi) = (c[i] as f64, c[i] as f64 + 1.0);
            if d == 0.0 {
                if a[i] < lo || a[i] > hi {
                    return (1.0, 0.0);
                }
                continue;
            }
            let (s0, s1) = ((lo - a[i]) / d, (hi - a[i]) / d);
            t0 = t0.max(s0.min(s1));
            t1 = t1.min(s0.max(s1));
        }
        (t0, t1)
    }

    #[test]
    fn a_segment_through_a_voxel_edge_or_corner_adds_the_connecting_voxels() {
        // Through the edge x = y = 1 (z inside a voxel): the diagonal step is split into x then y.
        let mut out = Vec::new();
        walk([0.5, 0.5, 0.5], [1.5, 1.5, 0.5], &mut out);
        assert_eq!(out, vec![[0, 0, 0], [1, 0, 0], [1, 1, 0]]);
        // Through the corner (1, 1, 1): three face steps.
        out.clear();
        walk([0.5, 0.5, 0.5], [1.5, 1.5, 1.5], &mut out);
        assert_eq!(out, vec![[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 1]]);
        // Backwards, through the same corner.
        out.clear();
        walk([1.5, 1.5, 1.5], [0.5, 0.5, 0.5], &mut out);
        assert_eq!(out, vec![[1, 1, 1], [0, 1, 1], [0, 0, 1], [0, 0, 0]]);
    }

    #[test]
    fn voxelize_dedupes_and_dilates() {
        let line = [[0.5, 0.5, 0.5], [3.5, 0.5, 0.5]];
        let v = voxelize(&[(&line, false)], 0);
        assert_eq!(v, vec![[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]);
        // The same line twice (closed: there and back) gives the same voxels once.
        assert_eq!(voxelize(&[(&line, true)], 0), v);
        // One layer: a 6 × 3 × 3 box.
        let d = voxelize(&[(&line, false)], 1);
        assert_eq!(d.len(), 6 * 3 * 3);
        assert_eq!(d[0], [-1, -1, -1]);
        assert_eq!(*d.last().unwrap(), [4, 1, 1]);
    }

    #[test]
    fn walk_bound_bounds_the_voxels_and_is_exact_on_a_simple_chain() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for layers in 0..3 {
            for _ in 0..50 {
                let n = rng.random_range(2..30);
                let u: Vec<[f64; 3]> = (0..n)
                    .map(|_| std::array::from_fn(|_| rng.random_range(-4.0..4.0)))
                    .collect();
                let closed = rng.random_bool(0.5);
                let voxels = voxelize(&[(&u, closed)], layers);
                let (bv, _) = walk_bound(&[(&u, closed)], layers);
                assert!(voxels.len() as f64 <= bv, "{} > {bv}", voxels.len());
            }
        }
        let line = [[0.5, 0.5, 0.5], [3.5, 0.5, 0.5]];
        assert_eq!(walk_bound(&[(&line, false)], 0), (4.0, 8.0 + 4.0 * 3.0));
    }
}
