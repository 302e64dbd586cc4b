//! A uniform grid of triangles for proximity queries: each triangle is listed in every cell its bounding box
//! overlaps. Used for ray casts against a surface and for self-intersection tests.

use crate::math::{Real, Vec3};

/// Most cells a grid may have; a finer requested cell size is coarsened to stay below it.
const MAX_CELLS: usize = 1 << 22;

/// Uniform grid over the bounding box of a triangle set.
#[derive(Clone, Debug)]
pub struct TriangleGrid {
    origin: Vec3,
    cell: Real,
    dims: [usize; 3],
    /// CSR offsets per cell (`#cells + 1`).
    offsets: Vec<usize>,
    /// Triangle indices, grouped by cell.
    items: Vec<u32>,
}

impl TriangleGrid {
    /// Builds the grid with cubic cells of edge about `cell_size` (m). Positions must be finite.
    pub fn new(positions: &[Vec3], faces: &[[usize; 3]], cell_size: Real) -> Self {
        let mut lo = Vec3::repeat(Real::INFINITY);
        let mut hi = Vec3::repeat(Real::NEG_INFINITY);
        for f in faces {
            for &v in f {
                lo = lo.inf(&positions[v]);
                hi = hi.sup(&positions[v]);
            }
        }
        if faces.is_empty() {
            lo = Vec3::zeros();
            hi = Vec3::zeros();
        }
        let extent = (hi - lo).max().max(1e-12);
        let mut cell = if cell_size.is_finite() && cell_size > 0.0 {
            cell_size
        } else {
            extent
        };
        let dims_for = |cell: Real| {
            let d = (hi - lo) / cell;
            [0, 1, 2].map(|i| (d[i].floor().min(MAX_CELLS as Real) as usize + 1).max(1))
        };
        let mut dims = dims_for(cell);
        while dims[0].saturating_mul(dims[1]).saturating_mul(dims[2]) > MAX_CELLS {
            cell *= 1.5;
            dims = dims_for(cell);
        }
        let mut grid = Self {
            origin: lo,
            cell,
            dims,
            offsets: Vec::new(),
            items: Vec::new(),
        };
        let ncells = dims[0] * dims[1] * dims[2];
        let mut counts = vec![0usize; ncells + 1];
        for f in faces {
            let (a, b) = grid.face_range(positions, f);
            grid.for_cells(a, b, |c| counts[c + 1] += 1);
        }
        for i in 0..ncells {
            counts[i + 1] += counts[i];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; counts[ncells]];
        for (fi, f) in faces.iter().enumerate() {
            let (a, b) = grid.face_range(positions, f);
            grid.for_cells(a, b, |c| {
                items[fill[c]] = fi as u32;
                fill[c] += 1;
            });
        }
        grid.offsets = counts;
        grid.items = items;
        grid
    }

    /// Cell edge length (m).
    pub fn cell_size(&self) -> Real {
        self.cell
    }

    /// Number of cells along x, y, z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The inclusive cell-coordinate range covering the box `[lo, hi]`, clamped to the grid.
    pub fn cell_range(&self, lo: &Vec3, hi: &Vec3) -> ([usize; 3], [usize; 3]) {
        let to = |p: &Vec3, i: usize| {
            let x = ((p[i] - self.origin[i]) / self.cell).floor();
            if x.is_nan() || x < 0.0 {
                0
            } else {
                (x as usize).min(self.dims[i] - 1)
            }
        };
        ([0, 1, 2].map(|i| to(lo, i)), [0, 1, 2].map(|i| to(hi, i)))
    }

    fn face_range(&self, positions: &[Vec3], f: &[usize; 3]) -> ([usize; 3], [usize; 3]) {
        let (a, b, c) = (positions[f[0]], positions[f[1]], positions[f[2]]);
        self.cell_range(&a.inf(&b).inf(&c), &a.sup(&b).sup(&c))
    }

    fn for_cells(&self, a: [usize; 3], b: [usize; 3], mut f: impl FnMut(usize)) {
        for k in a[2]..=b[2] {
            for j in a[1]..=b[1] {
                for i in a[0]..=b[0] {
                    f(i + self.dims[0] * (j + self.dims[1] * k));
                }
            }
        }
    }

    /// The triangles listed in cell `(i, j, k)`.
    pub fn cell(&self, i: usize, j: usize, k: usize) -> &[u32] {
        let c = i + self.dims[0] * (j + self.dims[1] * k);
        &self.items[self.offsets[c]..self.offsets[c + 1]]
    }

    /// Calls `f` once for every triangle whose cells overlap the box `[lo, hi]`. `seen` is scratch space
    /// (resized to the triangle count on demand) that removes duplicates; `stamp` must differ on each call
    /// (pass an increasing counter starting at 1).
    pub fn for_each_in_box(
        &self,
        lo: &Vec3,
        hi: &Vec3,
        seen: &mut Vec<u32>,
        stamp: u32,
        mut f: impl FnMut(usize),
    ) {
        let (a, b) = self.cell_range(lo, hi);
        self.for_cells(a, b, |c| {
            for &t in &self.items[self.offsets[c]..self.offsets[c + 1]] {
                let t = t as usize;
                if seen.len() <= t {
                    seen.resize(t + 1, 0);
                }
                if seen[t] != stamp {
                    seen[t] = stamp;
                    f(t);
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_query_finds_nearby_triangles_once() {
        let p = vec![
            Vec3::zeros(),
            Vec3::x(),
            Vec3::y(),
            Vec3::new(5.0, 5.0, 5.0),
            Vec3::new(5.1, 5.0, 5.0),
            Vec3::new(5.0, 5.1, 5.0),
        ];
        let faces = vec![[0, 1, 2], [3, 4, 5]];
        let grid = TriangleGrid::new(&p, &faces, 0.25);
        let mut seen = Vec::new();
        let mut found = Vec::new();
        grid.for_each_in_box(
            &Vec3::new(-0.1, -0.1, -0.1),
            &Vec3::new(0.6, 0.6, 0.1),
            &mut seen,
            1,
            |t| found.push(t),
        );
        assert_eq!(found, vec![0]);
        found.clear();
        grid.for_each_in_box(
            &Vec3::new(-1.0, -1.0, -1.0),
            &Vec3::new(9.0, 9.0, 9.0),
            &mut seen,
            2,
            |t| found.push(t),
        );
        found.sort();
        assert_eq!(found, vec![0, 1]);
    }

    #[test]
    fn tiny_cells_are_coarsened() {
        let p = vec![Vec3::zeros(), Vec3::x(), Vec3::new(0.0, 100.0, 100.0)];
        let grid = TriangleGrid::new(&p, &[[0, 1, 2]], 1e-6);
        let d = grid.dims();
        assert!(d[0] * d[1] * d[2] <= MAX_CELLS);
    }
}
