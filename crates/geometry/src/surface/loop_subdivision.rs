//! One explicit Loop subdivision step of a closed triangle mesh, as a sparse linear map on the vertices plus
//! the refined faces (Loop 1987; thesis appendix A).
//!
//! New vertices: first the `#V` vertex points (vertex `v` keeps its id), then one edge point per undirected
//! edge. Vertex rule: `(1 − N β_N) v + β_N Σ ring`, with Loop's `β_N = (5/8 − (3/8 + cos(2π/N)/4)²) / N`.
//! Edge rule: `3/8 (a + b) + 1/8 (c + d)` for edge `(a, b)` with opposite vertices `c`, `d`.
//! Face `f = [a, b, c]` with edge points `ab`, `bc`, `ca` becomes the four children (ids `4f + k`)
//! `[a, ab, ca]`, `[ab, b, bc]`, `[ca, bc, c]`, `[ab, bc, ca]`, which keep the orientation.

use crate::math::{FaceId, Real, Vec2, Vec3, VertexId};
use crate::mesh::topology::Topology;
use crate::surface::SurfaceError;

/// A sparse `rows × cols` matrix in compressed sparse row form.
#[derive(Clone, Debug, PartialEq)]
pub struct SparseMatrix {
    rows: usize,
    cols: usize,
    /// `rows + 1` offsets into `col_indices` / `values`.
    row_offsets: Vec<usize>,
    col_indices: Vec<usize>,
    values: Vec<Real>,
}

impl SparseMatrix {
    /// Builds a CSR matrix from rows given as `(column, value)` lists (duplicates are kept as given).
    pub fn from_rows(cols: usize, rows: &[Vec<(usize, Real)>]) -> Self {
        let mut row_offsets = Vec::with_capacity(rows.len() + 1);
        let mut col_indices = Vec::new();
        let mut values = Vec::new();
        row_offsets.push(0);
        for r in rows {
            for &(c, v) in r {
                debug_assert!(c < cols);
                col_indices.push(c);
                values.push(v);
            }
            row_offsets.push(col_indices.len());
        }
        Self {
            rows: rows.len(),
            cols,
            row_offsets,
            col_indices,
            values,
        }
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.values.len()
    }

    /// Row `i` as `(column, value)` pairs.
    #[inline]
    pub fn row(&self, i: usize) -> impl Iterator<Item = (usize, Real)> + '_ {
        let (a, b) = (self.row_offsets[i], self.row_offsets[i + 1]);
        self.col_indices[a..b]
            .iter()
            .copied()
            .zip(self.values[a..b].iter().copied())
    }

    /// All entries as `(row, column, value)` triplets.
    pub fn triplets(&self) -> Vec<(usize, usize, Real)> {
        (0..self.rows)
            .flat_map(|r| self.row(r).map(move |(c, v)| (r, c, v)))
            .collect()
    }

    /// `self · x` for `x` of length `cols` (one 3-vector per column).
    ///
    /// # Panics
    /// If `x.len() != cols`.
    pub fn apply(&self, x: &[Vec3]) -> Vec<Vec3> {
        assert_eq!(x.len(), self.cols, "vector length must match the columns");
        (0..self.rows)
            .map(|r| self.row(r).map(|(c, v)| v * x[c]).sum())
            .collect()
    }
}

/// Loop's vertex weight `β_N` for a vertex of valence `n`.
pub fn loop_beta(n: usize) -> Real {
    let n_r = n as Real;
    let c = 0.375 + 0.25 * (2.0 * std::f64::consts::PI / n_r).cos();
    (0.625 - c * c) / n_r
}

/// The result of one Loop subdivision step.
#[derive(Clone, Debug)]
pub struct LoopRefinement {
    /// The subdivision map `S` (`#V' × #V`): refined positions are `S · y`.
    pub subdivision: SparseMatrix,
    /// The refined faces (`4 #F`); children of face `f` are `4f .. 4f + 4`.
    pub faces: Vec<[VertexId; 3]>,
    /// `#V'` = `#V + #E`.
    pub num_vertices: usize,
}

impl LoopRefinement {
    /// The original face a refined face came from.
    pub fn parent_face(&self, refined: FaceId) -> FaceId {
        refined / 4
    }

    /// Maps coordinates `s` in original face `f` to the refined face containing the point and its
    /// coordinates there (the refined faces split the parameter triangle at the edge midpoints).
    pub fn child_coords(&self, f: FaceId, s: Vec2) -> (FaceId, Vec2) {
        child_coords(f, s)
    }
}

pub(crate) fn child_coords(f: FaceId, s: Vec2) -> (FaceId, Vec2) {
    let (s1, s2) = (s.x, s.y);
    let s3 = 1.0 - s1 - s2;
    if s1 >= 0.5 {
        (4 * f, Vec2::new(2.0 * s1 - 1.0, 2.0 * s2))
    } else if s2 >= 0.5 {
        (4 * f + 1, Vec2::new(2.0 * s1, 2.0 * s2 - 1.0))
    } else if s3 >= 0.5 {
        (4 * f + 2, Vec2::new(2.0 * s1, 2.0 * s2))
    } else {
        (4 * f + 3, Vec2::new(1.0 - 2.0 * s3, 1.0 - 2.0 * s1))
    }
}

/// One Loop subdivision step of a closed mesh.
pub fn loop_subdivision(topology: &Topology) -> Result<LoopRefinement, SurfaceError> {
    if let Some(&(a, b)) = topology.boundary_edges().first() {
        return Err(SurfaceError::Boundary { a, b });
    }
    let nv = topology.num_vertices();
    let faces = topology.faces();
    let mut rows: Vec<Vec<(usize, Real)>> = Vec::with_capacity(nv + faces.len() * 3 / 2);
    for v in 0..nv {
        let ring = topology.one_ring(v);
        let n = ring.len();
        if n == 0 {
            // An isolated vertex is carried over unchanged.
            rows.push(vec![(v, 1.0)]);
            continue;
        }
        let beta = loop_beta(n);
        let mut row = Vec::with_capacity(n + 1);
        row.push((v, 1.0 - n as Real * beta));
        row.extend(ring.iter().map(|&u| (u, beta)));
        rows.push(row);
    }
    // Edge points, numbered by first visit (face order, then local edge order).
    let mut edge_id = vec![[usize::MAX; 3]; faces.len()];
    for (f, face) in faces.iter().enumerate() {
        for e in 0..3 {
            if edge_id[f][e] != usize::MAX {
                continue;
            }
            let t = topology
                .twin(f, e)
                .expect("closed mesh: every edge has a twin");
            let id = rows.len();
            edge_id[f][e] = id;
            edge_id[t.face][t.edge] = id;
            let (a, b, c) = (face[e], face[(e + 1) % 3], face[(e + 2) % 3]);
            let d = faces[t.face][(t.edge + 2) % 3];
            rows.push(vec![(a, 0.375), (b, 0.375), (c, 0.125), (d, 0.125)]);
        }
    }
    let mut refined = Vec::with_capacity(faces.len() * 4);
    for (f, &[a, b, c]) in faces.iter().enumerate() {
        let [ab, bc, ca] = edge_id[f];
        refined.push([a, ab, ca]);
        refined.push([ab, b, bc]);
        refined.push([ca, bc, c]);
        refined.push([ab, bc, ca]);
    }
    Ok(LoopRefinement {
        num_vertices: rows.len(),
        subdivision: SparseMatrix::from_rows(nv, &rows),
        faces: refined,
    })
}
