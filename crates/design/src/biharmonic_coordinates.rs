//! Bi-harmonic coordinates of a planar triangle mesh with respect to a set of boundary vertices (thesis
//! ch. 6, "Pattern Parameterization": `x̄ = W p`).
//!
//! The weights `W` (`#interior × #boundary`) give every other ("interior") vertex's value as a linear
//! combination of the values at the boundary vertices: the interpolant of given boundary values is the
//! minimizer of the discrete squared-Laplacian energy
//!
//! `E(x) = xᵀ L̃ᵀ M⁻¹ L̃ x`   with `x_B` fixed,
//!
//! i.e. `A_II x_I = −A_IB x_B` with `A = L̃ᵀ M⁻¹ L̃`, so `W = −A_II⁻¹ A_IB`. Here
//!
//! - `M` (`#V × #V`, diagonal, m²) is the lumped (barycentric) mass: a third of the area of every incident
//!   triangle;
//! - `L̃` (`#V × #V`, dimensionless) is the cotangent Laplacian `L_ab = Σ_T A_T ∇φ_a · ∇φ_b` **with the
//!   discrete normal flux subtracted in the rows of mesh-boundary vertices**: for every mesh-boundary edge
//!   `e` of triangle `T` with outward normal `n_e`, rows `a` and `b` of `e` get
//!   `−(‖e‖/2) n_e · ∇x|_T`. For a linear function `f`, `(L f)_a` is exactly that boundary flux, so `L̃`
//!   annihilates every linear function (in the interior rows this is the cotangent Laplacian's linear
//!   precision on planar meshes).
//!
//! Why the correction: with the plain `L M⁻¹ L` (the usual natural boundary conditions) the boundary rows
//! of `L f` do not vanish for a linear `f`, and the minimizer bends linear boundary data (on a jittered
//! 6 × 5 grid, interior errors of about 5 % of the data's range). With `L̃`, a linear function has zero
//! energy, so it *is* the minimizer: **`W` reproduces constants and linear functions exactly** (rows sum to 1,
//! `W f(X̄_B) = f(X̄_I)` for affine `f`). Away from the boundary (vertices whose one-ring does not touch a
//! boundary vertex) the optimality condition is the plain discrete bi-Laplace equation
//! `(L M⁻¹ L x)_i = 0`. `A_II` is symmetric positive semi-definite, and definite whenever `L̃ x = 0, x_B = 0`
//! forces `x = 0`: always when the mesh is connected and every mesh-boundary vertex is in the boundary set
//! (the interior rows of `L̃` are then the Dirichlet Laplacian); vertices of inner loops (holes) may be
//! unknowns as well (tested), but a singular system is then possible and reported as
//! [`BiharmonicError::Solver`]. `A_II` is factored once by a sparse Cholesky factorization (faer) and
//! solved for all boundary columns at once.
//!
//! `W` is stored **dense**, row-major (`#interior × #boundary` reals): every boundary vertex influences every
//! interior vertex. Interior vertices are all vertices not listed in `boundary`, in increasing id order.
//!
//! Requirements (errors otherwise): a non-empty boundary of distinct, in-range vertex ids; finite positions
//! (m); triangles counter-clockwise with area above `1e-14 ×` the squared bounding-box diagonal; every edge
//! shared by at most two triangles; every interior vertex in some triangle.

use std::collections::HashMap;

use faer::prelude::Solve;
use faer::sparse::{SparseColMat, Triplet};

use crate::math::{Real, Vec2};

/// Why bi-harmonic coordinates could not be computed or applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BiharmonicError {
    /// The boundary set is empty.
    #[error("the boundary vertex set is empty")]
    NoBoundary,
    /// A vertex id is not below the number of positions.
    #[error("vertex id {vertex} is out of range ({num_vertices} vertices)")]
    VertexOutOfRange {
        /// The offending id.
        vertex: usize,
        /// Number of positions.
        num_vertices: usize,
    },
    /// A boundary vertex is listed twice.
    #[error("boundary vertex {vertex} is listed twice")]
    DuplicateBoundaryVertex {
        /// The vertex.
        vertex: usize,
    },
    /// A position is NaN or infinite.
    #[error("vertex {vertex} has a non-finite position")]
    NonFinitePosition {
        /// The vertex.
        vertex: usize,
    },
    /// A triangle is clockwise or (nearly) degenerate.
    #[error("triangle {triangle} is clockwise or degenerate (signed area {area:.3e} m²)")]
    DegenerateTriangle {
        /// The triangle.
        triangle: usize,
        /// Its signed area (m²).
        area: Real,
    },
    /// An edge is shared by more than two triangles.
    #[error("edge ({0}, {1}) is shared by more than two triangles")]
    NonManifoldEdge(usize, usize),
    /// An interior vertex belongs to no triangle, so nothing determines its value.
    #[error("interior vertex {vertex} belongs to no triangle")]
    UnusedVertex {
        /// The vertex.
        vertex: usize,
    },
    /// The linear system could not be factored or gave non-finite weights.
    #[error("the bi-Laplacian system could not be solved: {0}")]
    Solver(String),
    /// Values of the wrong count were passed to [`BiharmonicCoordinates::interpolate`] or its transpose.
    #[error("expected {expected} values, got {got}")]
    ValueCount {
        /// Expected count.
        expected: usize,
        /// Given count.
        got: usize,
    },
}

/// Bi-harmonic coordinates: the interior vertices' values as linear combinations of the boundary
/// vertices' values (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct BiharmonicCoordinates {
    interior: Vec<usize>,
    boundary: Vec<usize>,
    /// `#interior × #boundary`, row-major (dimensionless).
    weights: Vec<Real>,
}

impl BiharmonicCoordinates {
    /// The interior vertex ids (rows of `W`), increasing.
    pub fn interior(&self) -> &[usize] {
        &self.interior
    }

    /// The boundary vertex ids (columns of `W`), in the order given.
    pub fn boundary(&self) -> &[usize] {
        &self.boundary
    }

    /// Number of interior vertices (rows of `W`).
    pub fn num_interior(&self) -> usize {
        self.interior.len()
    }

    /// Number of boundary vertices (columns of `W`).
    pub fn num_boundary(&self) -> usize {
        self.boundary.len()
    }

    /// `W`: `#interior × #boundary` dimensionless weights, row-major (`weights()[i · #boundary + b]`).
    pub fn weights(&self) -> &[Real] {
        &self.weights
    }

    /// Row `i` of `W` (the weights of interior vertex `interior()[i]`, `#boundary` entries); `None` when
    /// `i ≥ #interior`.
    pub fn row(&self, i: usize) -> Option<&[Real]> {
        let nb = self.boundary.len();
        self.weights.get(i * nb..(i + 1) * nb)
    }

    /// `W v`: the interior values (`#interior`) of the boundary values `values` (`#boundary`, any unit,
    /// e.g. positions in m).
    pub fn interpolate(&self, values: &[Vec2]) -> Result<Vec<Vec2>, BiharmonicError> {
        let nb = self.boundary.len();
        if values.len() != nb {
            return Err(BiharmonicError::ValueCount {
                expected: nb,
                got: values.len(),
            });
        }
        Ok((0..self.interior.len())
            .map(|i| {
                let row = &self.weights[i * nb..(i + 1) * nb];
                row.iter().zip(values).map(|(w, v)| *w * v).sum()
            })
            .collect())
    }

    /// `Wᵀ g`: pulls values at the interior vertices (`#interior`) back to the boundary vertices
    /// (`#boundary`), e.g. a gradient with respect to interior positions.
    pub fn interpolate_transpose(&self, values: &[Vec2]) -> Result<Vec<Vec2>, BiharmonicError> {
        let nb = self.boundary.len();
        if values.len() != self.interior.len() {
            return Err(BiharmonicError::ValueCount {
                expected: self.interior.len(),
                got: values.len(),
            });
        }
        let mut out = vec![Vec2::zeros(); nb];
        for (i, g) in values.iter().enumerate() {
            let row = &self.weights[i * nb..(i + 1) * nb];
            for (o, w) in out.iter_mut().zip(row) {
                *o += *w * g;
            }
        }
        Ok(out)
    }
}

/// Validated per-triangle data: signed area (m²) and hat-function gradients (1/m).
struct TriangleGeometry {
    area: Real,
    grad: [Vec2; 3],
}

fn triangle_geometry(
    positions: &[Vec2],
    triangles: &[[usize; 3]],
) -> Result<Vec<TriangleGeometry>, BiharmonicError> {
    let n = positions.len();
    let (lo, hi) = positions.iter().fold(
        (
            Vec2::repeat(Real::INFINITY),
            Vec2::repeat(Real::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    let scale2 = if n > 0 { (hi - lo).norm_squared() } else { 0.0 };
    triangles
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            if let Some(&v) = tri.iter().find(|&&v| v >= n) {
                return Err(BiharmonicError::VertexOutOfRange {
                    vertex: v,
                    num_vertices: n,
                });
            }
            let p = tri.map(|v| positions[v]);
            let area = 0.5 * (p[1] - p[0]).perp(&(p[2] - p[0]));
            if area.is_nan() || area <= 1e-14 * scale2 {
                return Err(BiharmonicError::DegenerateTriangle { triangle: t, area });
            }
            // ∇φ_k = J (p_{k+2} − p_{k+1}) / 2A with J the rotation by +90°.
            let grad = [0, 1, 2].map(|k| {
                let d = p[(k + 2) % 3] - p[(k + 1) % 3];
                Vec2::new(-d.y, d.x) / (2.0 * area)
            });
            Ok(TriangleGeometry { area, grad })
        })
        .collect()
}

/// Rows of a sparse matrix: `(column, value)` pairs, one `Vec` per row.
type SparseRows = Vec<Vec<(usize, Real)>>;

/// The rows of `L̃` (merged, one `Vec` of `(column, value)` per vertex) and the lumped masses.
fn corrected_laplacian(
    positions: &[Vec2],
    triangles: &[[usize; 3]],
    geometry: &[TriangleGeometry],
) -> Result<(SparseRows, Vec<Real>), BiharmonicError> {
    let n = positions.len();
    let mut rows: Vec<HashMap<usize, Real>> = vec![HashMap::new(); n];
    let mut mass = vec![0.0; n];
    let mut edge_count: HashMap<(usize, usize), usize> = HashMap::new();
    for tri in triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            *edge_count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    if let Some((&(a, b), _)) = edge_count.iter().find(|(_, c)| **c > 2) {
        return Err(BiharmonicError::NonManifoldEdge(a, b));
    }
    for (tri, g) in triangles.iter().zip(geometry) {
        for a in 0..3 {
            mass[tri[a]] += g.area / 3.0;
            for b in 0..3 {
                *rows[tri[a]].entry(tri[b]).or_insert(0.0) += g.area * g.grad[a].dot(&g.grad[b]);
            }
        }
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if edge_count[&(a.min(b), a.max(b))] != 1 {
                continue;
            }
            // Outward normal scaled by the edge length: the edge a → b rotated by −90°.
            let e = positions[b] - positions[a];
            let normal = Vec2::new(e.y, -e.x);
            for v in [a, b] {
                for (&vc, grad) in tri.iter().zip(&g.grad) {
                    *rows[v].entry(vc).or_insert(0.0) -= 0.5 * normal.dot(grad);
                }
            }
        }
    }
    let rows = rows
        .into_iter()
        .map(|r| {
            let mut r: Vec<(usize, Real)> = r.into_iter().collect();
            r.sort_unstable_by_key(|e| e.0);
            r
        })
        .collect();
    Ok((rows, mass))
}

/// The bi-harmonic coordinates of the vertices of the planar triangle mesh (`positions`, `#V`, m;
/// counter-clockwise `triangles`) not in `boundary`, with respect to the vertices in `boundary` (any
/// order; it fixes the column order of `W`). See the module documentation for the system solved and the
/// requirements.
pub fn biharmonic_coordinates(
    positions: &[Vec2],
    triangles: &[[usize; 3]],
    boundary: &[usize],
) -> Result<BiharmonicCoordinates, BiharmonicError> {
    let n = positions.len();
    if boundary.is_empty() {
        return Err(BiharmonicError::NoBoundary);
    }
    const NONE: usize = usize::MAX;
    let mut boundary_index = vec![NONE; n];
    for (b, &v) in boundary.iter().enumerate() {
        if v >= n {
            return Err(BiharmonicError::VertexOutOfRange {
                vertex: v,
                num_vertices: n,
            });
        }
        if boundary_index[v] != NONE {
            return Err(BiharmonicError::DuplicateBoundaryVertex { vertex: v });
        }
        boundary_index[v] = b;
    }
    if let Some(v) = positions
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return Err(BiharmonicError::NonFinitePosition { vertex: v });
    }
    let geometry = triangle_geometry(positions, triangles)?;
    let mut used = vec![false; n];
    triangles.iter().flatten().for_each(|&v| used[v] = true);
    let interior: Vec<usize> = (0..n).filter(|&v| boundary_index[v] == NONE).collect();
    if let Some(&v) = interior.iter().find(|&&v| !used[v]) {
        return Err(BiharmonicError::UnusedVertex { vertex: v });
    }
    let nb = boundary.len();
    let ni = interior.len();
    if ni == 0 {
        return Ok(BiharmonicCoordinates {
            interior,
            boundary: boundary.to_vec(),
            weights: Vec::new(),
        });
    }
    let mut interior_index = vec![NONE; n];
    for (i, &v) in interior.iter().enumerate() {
        interior_index[v] = i;
    }

    // A = L̃ᵀ M⁻¹ L̃, split into A_II (sparse) and the right-hand sides −A_IB (dense).
    let (rows, mass) = corrected_laplacian(positions, triangles, &geometry)?;
    let mut triplets = Vec::new();
    let mut rhs = faer::Mat::<Real>::zeros(ni, nb);
    for (row, &m) in rows.iter().zip(&mass) {
        if m <= 0.0 {
            continue; // a vertex in no triangle has an empty row
        }
        for &(c1, v1) in row {
            let i = interior_index[c1];
            if i == NONE {
                continue;
            }
            for &(c2, v2) in row {
                let a = v1 * v2 / m;
                match interior_index[c2] {
                    NONE => rhs[(i, boundary_index[c2])] -= a,
                    j => triplets.push(Triplet::new(i, j, a)),
                }
            }
        }
    }
    let a_ii = SparseColMat::<usize, Real>::try_new_from_triplets(ni, ni, &triplets)
        .map_err(|e| BiharmonicError::Solver(format!("{e:?}")))?;
    let llt = a_ii
        .sp_cholesky(faer::Side::Lower)
        .map_err(|e| BiharmonicError::Solver(format!("{e:?}")))?;
    let x = llt.solve(&rhs);
    let mut weights = vec![0.0; ni * nb];
    for i in 0..ni {
        for b in 0..nb {
            weights[i * nb + b] = x[(i, b)];
        }
    }
    if weights.iter().any(|w| !w.is_finite()) {
        return Err(BiharmonicError::Solver(
            "the weights are not finite".to_string(),
        ));
    }
    Ok(BiharmonicCoordinates {
        interior,
        boundary: boundary.to_vec(),
        weights,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{grid_panel, rng};
    use rand::Rng;

    /// An L-shaped panel: a grid with the top-right quarter removed (non-convex), and its boundary loop.
    fn l_shape() -> (Vec<Vec2>, Vec<[usize; 3]>, Vec<usize>) {
        let (pos, tri, _) = grid_panel(6, 6, 0.6, 0.6, 0.2, 9);
        let id = |i: usize, j: usize| j * 7 + i;
        // Triangles 2c and 2c + 1 are cell c = (c % 6, c / 6); drop the cells with i ≥ 3 and j ≥ 3.
        let tri: Vec<[usize; 3]> = tri
            .into_iter()
            .enumerate()
            .filter(|(t, _)| !((t / 2) % 6 >= 3 && (t / 2) / 6 >= 3))
            .map(|(_, t)| t)
            .collect();
        let mut used = [false; 49];
        tri.iter().flatten().for_each(|&v| used[v] = true);
        // Renumber the used vertices.
        let mut new_id = [usize::MAX; 49];
        let mut positions = Vec::new();
        for v in 0..49 {
            if used[v] {
                new_id[v] = positions.len();
                positions.push(pos[v]);
            }
        }
        let tri = tri.iter().map(|t| t.map(|v| new_id[v])).collect();
        let mut boundary = Vec::new();
        boundary.extend((0..6).map(|i| id(i, 0)));
        boundary.extend((0..3).map(|j| id(6, j)));
        boundary.extend((4..=6).rev().map(|i| id(i, 3)));
        boundary.extend((3..6).map(|j| id(3, j)));
        boundary.extend((1..=3).rev().map(|i| id(i, 6)));
        boundary.extend((1..=6).rev().map(|j| id(0, j)));
        let boundary = boundary.iter().map(|&v| new_id[v]).collect();
        (positions, tri, boundary)
    }

    fn check_linear_precision(positions: &[Vec2], triangles: &[[usize; 3]], boundary: &[usize]) {
        let w = biharmonic_coordinates(positions, triangles, boundary).unwrap();
        assert_eq!(w.num_boundary(), boundary.len());
        assert_eq!(w.num_interior() + boundary.len(), positions.len());
        for i in 0..w.num_interior() {
            let s: Real = w.row(i).unwrap().iter().sum();
            assert!((s - 1.0).abs() < 1e-12, "row {i} sums to {s}");
        }
        let affine = |p: &Vec2| Vec2::new(2.0 * p.x - 3.0 * p.y + 0.5, -p.x + 0.25 * p.y - 1.0);
        let values: Vec<Vec2> = boundary.iter().map(|&v| affine(&positions[v])).collect();
        let inside = w.interpolate(&values).unwrap();
        for (i, &v) in w.interior().iter().enumerate() {
            let err = (inside[i] - affine(&positions[v])).norm();
            assert!(err < 1e-12, "vertex {v}: error {err:.3e}");
        }
        // The identity reproduces the interior positions.
        let bpos: Vec<Vec2> = boundary.iter().map(|&v| positions[v]).collect();
        let inside = w.interpolate(&bpos).unwrap();
        for (i, &v) in w.interior().iter().enumerate() {
            assert!((inside[i] - positions[v]).norm() < 1e-12);
        }
    }

    #[test]
    fn reproduces_constants_and_linear_functions_on_a_jittered_grid() {
        for seed in 0..3 {
            let (pos, tri, boundary) = grid_panel(7, 5, 0.7, 0.4, 0.3, seed);
            check_linear_precision(&pos, &tri, &boundary);
        }
    }

    #[test]
    fn reproduces_linear_functions_on_a_non_convex_panel() {
        let (pos, tri, boundary) = l_shape();
        check_linear_precision(&pos, &tri, &boundary);
    }

    #[test]
    fn reproduces_linear_functions_around_a_hole() {
        // A 6 × 6 grid without its central 2 × 2 cells: the hole's vertices are unknowns like the
        // interior (only the outer loop is the boundary set).
        let (pos, tri, boundary) = grid_panel(6, 6, 0.6, 0.6, 0.2, 4);
        let tri: Vec<[usize; 3]> = tri
            .into_iter()
            .enumerate()
            .filter(|(t, _)| {
                let (i, j) = ((t / 2) % 6, (t / 2) / 6);
                !((2..4).contains(&i) && (2..4).contains(&j))
            })
            .map(|(_, t)| t)
            .collect();
        // The centre vertex (3, 3) is now in no triangle: drop it by making it the last and cutting it.
        let centre = 3 * 7 + 3;
        let mut pos = pos;
        let last = pos.len() - 1;
        pos.swap(centre, last);
        let rename = |v: usize| if v == last { centre } else { v };
        let tri: Vec<[usize; 3]> = tri.iter().map(|t| t.map(rename)).collect();
        let boundary: Vec<usize> = boundary.iter().map(|&v| rename(v)).collect();
        pos.pop();
        check_linear_precision(&pos, &tri, &boundary);
    }

    #[test]
    fn boundary_order_only_permutes_columns() {
        let (pos, tri, boundary) = grid_panel(4, 4, 0.4, 0.4, 0.2, 5);
        let w = biharmonic_coordinates(&pos, &tri, &boundary).unwrap();
        let mut reversed = boundary.clone();
        reversed.reverse();
        let wr = biharmonic_coordinates(&pos, &tri, &reversed).unwrap();
        let nb = boundary.len();
        for i in 0..w.num_interior() {
            for b in 0..nb {
                let d = w.row(i).unwrap()[b] - wr.row(i).unwrap()[nb - 1 - b];
                assert!(d.abs() < 1e-12);
            }
        }
    }

    /// The plain cotangent Laplacian `L` (from cotangents, independently of the module) and the lumped
    /// masses.
    fn cotangent_laplacian(pos: &[Vec2], tri: &[[usize; 3]]) -> (Vec<Vec<Real>>, Vec<Real>) {
        let n = pos.len();
        let mut l = vec![vec![0.0; n]; n];
        let mut m = vec![0.0; n];
        for t in tri {
            let p = t.map(|v| pos[v]);
            let area = 0.5 * (p[1] - p[0]).perp(&(p[2] - p[0]));
            for k in 0..3 {
                m[t[k]] += area / 3.0;
                let (u, v) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                let cot = u.dot(&v) / u.perp(&v);
                let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
                l[a][b] -= 0.5 * cot;
                l[b][a] -= 0.5 * cot;
                l[a][a] += 0.5 * cot;
                l[b][b] += 0.5 * cot;
            }
        }
        (l, m)
    }

    #[test]
    fn interpolant_is_discretely_biharmonic_away_from_the_boundary() {
        let (pos, tri, boundary) = grid_panel(8, 8, 0.5, 0.5, 0.3, 2);
        let w = biharmonic_coordinates(&pos, &tri, &boundary).unwrap();
        let mut r = rng(7);
        let values: Vec<Vec2> = boundary
            .iter()
            .map(|_| Vec2::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0)))
            .collect();
        let inside = w.interpolate(&values).unwrap();
        let n = pos.len();
        let mut x = vec![0.0; n];
        for (b, &v) in boundary.iter().enumerate() {
            x[v] = values[b].x;
        }
        for (i, &v) in w.interior().iter().enumerate() {
            x[v] = inside[i].x;
        }
        let (l, m) = cotangent_laplacian(&pos, &tri);
        let lx: Vec<Real> = (0..n)
            .map(|i| (0..n).map(|j| l[i][j] * x[j]).sum::<Real>() / m[i])
            .collect();
        let is_boundary = |v: usize| boundary.contains(&v);
        let mut checked = 0;
        for &v in w.interior() {
            let touches = (0..n).any(|j| l[v][j] != 0.0 && is_boundary(j));
            if touches {
                continue;
            }
            let bilaplacian: Real = (0..n).map(|j| l[v][j] * lx[j]).sum();
            let scale: Real = (0..n).map(|j| (l[v][j] * lx[j]).abs()).sum();
            assert!(
                bilaplacian.abs() < 1e-9 * scale,
                "vertex {v}: {bilaplacian} (scale {scale})"
            );
            checked += 1;
        }
        assert!(checked >= 16);
        // It is not merely harmonic: the Laplacian itself does not vanish there.
        assert!(w.interior().iter().any(|&v| lx[v].abs() > 1e-3));
    }

    #[test]
    fn transpose_is_consistent() {
        let (pos, tri, boundary) = grid_panel(5, 4, 0.5, 0.4, 0.2, 3);
        let w = biharmonic_coordinates(&pos, &tri, &boundary).unwrap();
        let mut r = rng(11);
        let mut random = |k: usize| -> Vec<Vec2> {
            (0..k)
                .map(|_| Vec2::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0)))
                .collect()
        };
        let u = random(w.num_boundary());
        let g = random(w.num_interior());
        let wu = w.interpolate(&u).unwrap();
        let wtg = w.interpolate_transpose(&g).unwrap();
        let lhs: Real = wu.iter().zip(&g).map(|(a, b)| a.dot(b)).sum();
        let rhs: Real = u.iter().zip(&wtg).map(|(a, b)| a.dot(b)).sum();
        assert!((lhs - rhs).abs() < 1e-12 * lhs.abs().max(1.0));
        assert!(w.interpolate(&g).is_err());
        assert!(w.interpolate_transpose(&u).is_err());
        assert!(w.row(w.num_interior()).is_none());
    }

    #[test]
    fn no_interior_vertices() {
        let pos = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
        ];
        let w = biharmonic_coordinates(&pos, &[[0, 1, 2]], &[0, 1, 2]).unwrap();
        assert_eq!(w.num_interior(), 0);
        assert!(w.weights().is_empty());
        assert!(w.interpolate(&[Vec2::zeros(); 3]).unwrap().is_empty());
    }

    #[test]
    fn invalid_inputs_are_errors() {
        let (pos, tri, boundary) = grid_panel(3, 3, 0.3, 0.3, 0.0, 0);
        assert_eq!(
            biharmonic_coordinates(&pos, &tri, &[]),
            Err(BiharmonicError::NoBoundary)
        );
        assert!(matches!(
            biharmonic_coordinates(&pos, &tri, &[0, 99]),
            Err(BiharmonicError::VertexOutOfRange { vertex: 99, .. })
        ));
        assert!(matches!(
            biharmonic_coordinates(&pos, &tri, &[0, 1, 0]),
            Err(BiharmonicError::DuplicateBoundaryVertex { vertex: 0 })
        ));
        let mut nan = pos.clone();
        nan[5].y = Real::NAN;
        assert!(matches!(
            biharmonic_coordinates(&nan, &tri, &boundary),
            Err(BiharmonicError::NonFinitePosition { vertex: 5 })
        ));
        let mut flipped = tri.clone();
        flipped[3].swap(0, 1);
        assert!(matches!(
            biharmonic_coordinates(&pos, &flipped, &boundary),
            Err(BiharmonicError::DegenerateTriangle { triangle: 3, .. })
        ));
        let mut collapsed = pos.clone();
        collapsed[5] = collapsed[4];
        assert!(matches!(
            biharmonic_coordinates(&collapsed, &tri, &boundary),
            Err(BiharmonicError::DegenerateTriangle { .. })
        ));
        let mut extra = pos.clone();
        extra.push(Vec2::new(5.0, 5.0));
        assert!(matches!(
            biharmonic_coordinates(&extra, &tri, &boundary),
            Err(BiharmonicError::UnusedVertex { vertex: 16 })
        ));
        let mut bad = tri.clone();
        bad.push([0, 1, 99]);
        assert!(matches!(
            biharmonic_coordinates(&pos, &bad, &boundary),
            Err(BiharmonicError::VertexOutOfRange { vertex: 99, .. })
        ));
        let mut triple = tri.clone();
        triple.push(tri[0]);
        triple.push(tri[0]);
        assert!(matches!(
            biharmonic_coordinates(&pos, &triple, &boundary),
            Err(BiharmonicError::NonManifoldEdge(..))
        ));
    }
}
