//! The yarn vertices embedded in the mesh, and the mesh-to-yarn map V2Y (the knitwear paper, Eq. 4):
//! `x^Y = N x^V`, with `N` (`3#Y × 3#V`, dimensionless) holding for each yarn vertex the four barycentric
//! weights of its tetrahedron's nodes, once per coordinate.
//!
//! **Locating a point** takes no search over the tetrahedra: the point's grid coordinates `u` give its voxel
//! `c = ⌊u⌋` (found among the sorted voxels by binary search) and its local coordinates `f = u − c ∈ [0, 1]³`;
//! ordering them, `f_π₀ ≥ f_π₁ ≥ f_π₂`, names the Kuhn tetrahedron `π` holding it ([`super::tet_split`]),
//! and its barycentric weights of the corners `[0, e_π₀, e_π₀ + e_π₁, 1]` are
//! `[1 − f_π₀, f_π₀ − f_π₁, f_π₁ − f_π₂, f_π₂]` — non-negative, summing to 1 exactly in exact arithmetic,
//! and reproducing the point: `Σ_a w_a X_a = c + f` (the weights are the affine coordinates of the
//! tetrahedron, so linear interpolation is exact for every affine map). A point within round-off of its
//! voxel's face whose `⌊u⌋` falls in a voxel outside the mesh is given the neighbouring mesh voxel it lies
//! on, with weights then off zero by round-off only.
//!
//! **V2Y and its transpose** are applied as sums over the embedding (`#Y × 4` terms each), or assembled once as
//! a faer sparse matrix with the coordinates interleaved (row `3i + d`, column `3a + d`). The map is linear,
//! so its derivative is `N` itself and the adjoint (for the fit's gradients) is `Nᵀ`.

use faer::sparse::{SparseColMat, Triplet};

use super::error::VolumetricMeshError;
use super::tet_split::{KUHN, odd};
use super::voxelize::VoxelGrid;
use super::{Embedded, VolumetricMesh};

/// How far (in voxels) a point may lie outside the mesh voxel it is given to: round-off only.
const FACE_TOLERANCE: f64 = 1e-9;

/// Finds the tetrahedron holding a point: the grid and its sorted voxels (voxel `v` holds tetrahedra
/// `6v .. 6v + 6`).
#[derive(Clone, Copy, Debug)]
pub struct TetLocator<'a> {
    /// The grid.
    pub grid: VoxelGrid,
    /// The mesh's voxels, sorted and distinct.
    pub voxels: &'a [[i64; 3]],
}

impl TetLocator<'_> {
    /// The tetrahedron holding the point with grid coordinates `u` and its barycentric weights, or `None` when
    /// the point lies outside the mesh's voxels (by more than round-off).
    pub fn locate(&self, u: [f64; 3]) -> Option<Embedded> {
        let c = VoxelGrid::cell(u);
        if let Ok(v) = self.voxels.binary_search(&c) {
            return Some(weights(v, std::array::from_fn(|i| u[i] - c[i] as f64)));
        }
        // On a face (edge, corner) shared with a mesh voxel, up to round-off.
        let mut best: Option<(f64, usize, [f64; 3])> = None;
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let n = [c[0] + dx, c[1] + dy, c[2] + dz];
                    let Ok(v) = self.voxels.binary_search(&n) else {
                        continue;
                    };
                    let f: [f64; 3] = std::array::from_fn(|i| u[i] - n[i] as f64);
                    let out = f
                        .iter()
                        .map(|&x| (-x).max(x - 1.0).max(0.0))
                        .fold(0.0, f64::max);
                    if out <= FACE_TOLERANCE && best.is_none_or(|b| out < b.0) {
                        best = Some((out, v, f));
                    }
                }
            }
        }
        best.map(|(_, v, f)| weights(v, f))
    }
}

/// The Kuhn tetrahedron of voxel `v` holding local coordinates `f` and its barycentric weights (in the
/// order of [`super::tet_split::kuhn_corners`]).
fn weights(v: usize, f: [f64; 3]) -> Embedded {
    let mut order = [0usize, 1, 2];
    // Descending, ties by axis: the sort is stable.
    order.sort_by(|&a, &b| f[b].total_cmp(&f[a]));
    let k = KUHN
        .iter()
        .position(|p| *p == order)
        .expect("every permutation of three axes is a Kuhn tetrahedron");
    let [a, b, c] = order;
    let mut w = [1.0 - f[a], f[a] - f[b], f[b] - f[c], f[c]];
    if odd(k) {
        w.swap(1, 2);
    }
    Embedded {
        tet: 6 * v + k,
        weights: w,
    }
}

impl VolumetricMesh {
    /// Checks that the arrays fit together: masses and positions one per node, finite; tetrahedra naming
    /// nodes; embeddings naming tetrahedra, with finite weights. A mesh from [`VolumetricMesh::build`] always
    /// passes; one read from a file should be checked before use.
    pub fn validate(&self) -> Result<(), VolumetricMeshError> {
        let bad = |problem: String| Err(VolumetricMeshError::Inconsistent { problem });
        let nodes = self.rest.len();
        if self.node_mass.len() != nodes {
            return bad(format!(
                "{} nodal masses for {nodes} nodes",
                self.node_mass.len()
            ));
        }
        if let Some(i) = self
            .rest
            .iter()
            .position(|p| !p.iter().all(|x| x.is_finite()))
        {
            return bad(format!("node {i} has a non-finite rest position"));
        }
        if let Some(i) = self
            .node_mass
            .iter()
            .position(|m| !(m.is_finite() && *m >= 0.0))
        {
            return bad(format!("node {i} has mass {}", self.node_mass[i]));
        }
        if let Some(t) = self.tets.iter().position(|t| t.iter().any(|&n| n >= nodes)) {
            return bad(format!(
                "tetrahedron {t} names a node beyond the {nodes} nodes"
            ));
        }
        self.embedding_checked().map(|_| ())
    }

    /// The embedding's tetrahedra, checked against the mesh (no panic on a damaged mesh).
    fn embedding_checked(&self) -> Result<Vec<[usize; 4]>, VolumetricMeshError> {
        let nodes = self.rest.len();
        self.embedding
            .iter()
            .enumerate()
            .map(|(i, e)| match self.tets.get(e.tet) {
                Some(t)
                    if t.iter().all(|&n| n < nodes) && e.weights.iter().all(|w| w.is_finite()) =>
                {
                    Ok(*t)
                }
                _ => Err(VolumetricMeshError::Inconsistent {
                    problem: format!(
                        "yarn vertex {i} is embedded in tetrahedron {} (of {}) with weights {:?}",
                        e.tet,
                        self.tets.len(),
                        e.weights
                    ),
                }),
            })
            .collect()
    }

    /// V2Y (Eq. 4): the yarn vertices `N x^V`, `#Y × 3` (m), of the node positions `x_nodes`, `#V × 3` (m).
    pub fn v2y(&self, x_nodes: &[[f64; 3]]) -> Result<Vec<[f64; 3]>, VolumetricMeshError> {
        if x_nodes.len() != self.rest.len() {
            return Err(VolumetricMeshError::Length {
                what: "node positions",
                len: x_nodes.len(),
                expected: self.rest.len(),
            });
        }
        let tets = self.embedding_checked()?;
        Ok(self
            .embedding
            .iter()
            .zip(&tets)
            .map(|(e, t)| {
                std::array::from_fn(|d| (0..4).map(|a| e.weights[a] * x_nodes[t[a]][d]).sum())
            })
            .collect())
    }

    /// The transpose of V2Y: `Nᵀ y`, `#V × 3`, of one 3-vector per yarn vertex `y`, `#Y × 3` (any unit; e.g.
    /// the gradient of a loss with respect to the yarn positions becomes its gradient with respect to the
    /// nodes).
    pub fn v2y_transpose(&self, y: &[[f64; 3]]) -> Result<Vec<[f64; 3]>, VolumetricMeshError> {
        if y.len() != self.embedding.len() {
            return Err(VolumetricMeshError::Length {
                what: "yarn-vertex values",
                len: y.len(),
                expected: self.embedding.len(),
            });
        }
        let tets = self.embedding_checked()?;
        let mut out = vec![[0.0; 3]; self.rest.len()];
        for ((e, t), yi) in self.embedding.iter().zip(&tets).zip(y) {
            for a in 0..4 {
                for d in 0..3 {
                    out[t[a]][d] += e.weights[a] * yi[d];
                }
            }
        }
        Ok(out)
    }

    /// V2Y as the sparse matrix `N`, `3#Y × 3#V`, coordinates interleaved (row `3i + d`, column `3a + d`).
    pub fn v2y_matrix(&self) -> Result<SparseColMat<usize, f64>, VolumetricMeshError> {
        let tets = self.embedding_checked()?;
        let mut triplets = Vec::with_capacity(12 * self.embedding.len());
        for (i, (e, t)) in self.embedding.iter().zip(&tets).enumerate() {
            for a in 0..4 {
                for d in 0..3 {
                    triplets.push(Triplet::new(3 * i + d, 3 * t[a] + d, e.weights[a]));
                }
            }
        }
        SparseColMat::try_new_from_triplets(
            3 * self.embedding.len(),
            3 * self.rest.len(),
            &triplets,
        )
        .map_err(|e| VolumetricMeshError::Inconsistent {
            problem: format!("N cannot be assembled: {e:?}"),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::tet_split::tet_split;
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A 3 × 2 × 2 block of voxels of 1.5 mm at an offset origin, with random points inside.
    fn block(rng: &mut ChaCha8Rng) -> (VoxelGrid, Vec<[i64; 3]>, Vec<[f64; 3]>) {
        let grid = VoxelGrid {
            origin: [0.01, -0.02, 0.003],
            voxel_m: 1.5e-3,
        };
        let mut voxels = Vec::new();
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..3 {
                    voxels.push([x, y, z]);
                }
            }
        }
        voxels.sort_unstable();
        let points = (0..200)
            .map(|_| {
                let u = [
                    rng.random_range(0.0..3.0),
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                ];
                std::array::from_fn(|i| grid.origin[i] + grid.voxel_m * u[i])
            })
            .collect();
        (grid, voxels, points)
    }

    #[test]
    fn located_weights_are_barycentric_and_reproduce_the_point() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let (grid, voxels, points) = block(&mut rng);
        let (nodes, tets) = tet_split(&voxels);
        let locator = TetLocator {
            grid,
            voxels: &voxels,
        };
        for p in &points {
            let e = locator.locate(grid.coordinates(*p)).expect("inside");
            assert!(
                e.weights
                    .iter()
                    .all(|&w| (-1e-12..=1.0 + 1e-12).contains(&w))
            );
            assert!((e.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let t = tets[e.tet];
            for d in 0..3 {
                let x: f64 = (0..4)
                    .map(|a| e.weights[a] * grid.point(nodes[t[a]])[d])
                    .sum();
                assert!((x - p[d]).abs() < 1e-15, "{x} vs {}", p[d]);
            }
        }
        // Outside the block by more than round-off: not located.
        assert!(locator.locate([3.1, 0.5, 0.5]).is_none());
        // On the block's upper face (⌊u⌋ = 3 is outside): given to the voxel below.
        let e = locator.locate([3.0, 0.5, 0.5]).expect("on the face");
        assert_eq!(e.tet / 6, voxels.binary_search(&[2, 0, 0]).unwrap());
    }

    #[test]
    fn v2y_derivatives_match_central_differences() {
        use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let (grid, voxels, points) = block(&mut rng);
        let voxels = &voxels[..2];
        let points: Vec<[f64; 3]> = points
            .into_iter()
            .filter(|p| {
                let c = VoxelGrid::cell(grid.coordinates(*p));
                voxels.contains(&c)
            })
            .take(6)
            .collect();
        let (nodes, tets) = tet_split(voxels);
        let locator = TetLocator { grid, voxels };
        let mesh = VolumetricMesh {
            rest: nodes.iter().map(|&g| grid.point(g)).collect(),
            tets,
            node_mass: vec![0.0; nodes.len()],
            embedding: points
                .iter()
                .map(|p| locator.locate(grid.coordinates(*p)).unwrap())
                .collect(),
        };
        assert!(points.len() >= 3);
        // A random deformed state of the nodes (m).
        let x: Vec<f64> = mesh
            .rest
            .iter()
            .flatten()
            .map(|v| v + rng.random_range(-1e-4..1e-4))
            .collect();
        let unflat = |x: &[f64]| -> Vec<[f64; 3]> {
            x.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
        };
        let g = |x: &[f64]| -> Vec<f64> {
            mesh.v2y(&unflat(x))
                .unwrap()
                .into_iter()
                .flatten()
                .collect()
        };
        let n = mesh.v2y_matrix().unwrap().to_dense();
        let (rows, cols) = (n.nrows(), n.ncols());
        let jac: Vec<f64> = (0..rows * cols).map(|k| n[(k / cols, k % cols)]).collect();
        let fd = FdParams::default();
        check_jacobian(g, &x, &jac, &fd).unwrap();
        // The check can fail: a wrong weight is caught.
        let mut wrong = jac.clone();
        let k = wrong.iter().position(|&v| v > 0.1).unwrap();
        wrong[k] += 0.01;
        assert!(check_jacobian(g, &x, &wrong, &fd).is_err());
        // Nᵀ y is the gradient of ⟨y, N x⟩ with respect to the nodes.
        let y: Vec<[f64; 3]> = (0..points.len())
            .map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)))
            .collect();
        let phi = |x: &[f64]| -> f64 {
            mesh.v2y(&unflat(x))
                .unwrap()
                .iter()
                .zip(&y)
                .map(|(a, b)| (0..3).map(|d| a[d] * b[d]).sum::<f64>())
                .sum()
        };
        let grad: Vec<f64> = mesh
            .v2y_transpose(&y)
            .unwrap()
            .into_iter()
            .flatten()
            .collect();
        check_gradient(phi, &x, &grad, &fd).unwrap();
    }

    #[test]
    fn v2y_is_exact_for_affine_maps_and_matches_its_matrix_and_transpose() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (grid, voxels, points) = block(&mut rng);
        let (nodes, tets) = tet_split(&voxels);
        let locator = TetLocator {
            grid,
            voxels: &voxels,
        };
        let mesh = VolumetricMesh {
            rest: nodes.iter().map(|&g| grid.point(g)).collect(),
            tets,
            node_mass: vec![0.0; nodes.len()],
            embedding: points
                .iter()
                .map(|p| locator.locate(grid.coordinates(*p)).unwrap())
                .collect(),
        };
        // At rest V2Y gives back the points.
        let at_rest = mesh.v2y(&mesh.rest).unwrap();
        for (y, p) in at_rest.iter().zip(&points) {
            assert!((0..3).all(|d| (y[d] - p[d]).abs() < 1e-15));
        }
        // An affine map of the nodes moves the points by the same map.
        let a: [[f64; 3]; 3] =
            std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-2.0..2.0)));
        let b: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.1..0.1));
        let affine = |p: &[f64; 3]| -> [f64; 3] {
            std::array::from_fn(|i| b[i] + (0..3).map(|j| a[i][j] * p[j]).sum::<f64>())
        };
        let x: Vec<[f64; 3]> = mesh.rest.iter().map(affine).collect();
        let y = mesh.v2y(&x).unwrap();
        for (yi, p) in y.iter().zip(&points) {
            let want = affine(p);
            assert!(
                (0..3).all(|d| (yi[d] - want[d]).abs() < 1e-14),
                "{yi:?} vs {want:?}"
            );
        }
        // A non-affine map is not reproduced (so the test above can fail): bend the nodes.
        let bent: Vec<[f64; 3]> = mesh
            .rest
            .iter()
            .map(|p| [p[0], p[1], p[2] + 50.0 * (p[0] - 0.01).powi(2)])
            .collect();
        let yb = mesh.v2y(&bent).unwrap();
        let worst = yb
            .iter()
            .zip(&points)
            .map(|(yi, p)| (yi[2] - (p[2] + 50.0 * (p[0] - 0.01).powi(2))).abs())
            .fold(0.0, f64::max);
        assert!(worst > 1e-6, "{worst}");
        // The matrix gives the same, and the transpose is its adjoint: ⟨N x, y⟩ = ⟨x, Nᵀ y⟩.
        let n = mesh.v2y_matrix().unwrap();
        assert_eq!(
            (n.nrows(), n.ncols()),
            (3 * points.len(), 3 * mesh.rest.len())
        );
        let flat: Vec<f64> = x.iter().flatten().copied().collect();
        let col = faer::Mat::<f64>::from_fn(flat.len(), 1, |i, _| flat[i]);
        let nx = &n * &col;
        for (i, yi) in y.iter().enumerate() {
            assert!((0..3).all(|d| (nx[(3 * i + d, 0)] - yi[d]).abs() < 1e-14));
        }
        let w: Vec<[f64; 3]> = (0..points.len())
            .map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)))
            .collect();
        let ntw = mesh.v2y_transpose(&w).unwrap();
        let lhs: f64 = y
            .iter()
            .zip(&w)
            .map(|(a, b)| (0..3).map(|d| a[d] * b[d]).sum::<f64>())
            .sum();
        let rhs: f64 = x
            .iter()
            .zip(&ntw)
            .map(|(a, b)| (0..3).map(|d| a[d] * b[d]).sum::<f64>())
            .sum();
        assert!((lhs - rhs).abs() < 1e-12 * lhs.abs().max(1.0));
        // Wrong lengths are errors, not panics.
        assert!(
            mesh.v2y(&x[1..])
                .unwrap_err()
                .to_string()
                .contains("node positions")
        );
        assert!(mesh.v2y_transpose(&w[1..]).is_err());
        // A damaged mesh is an error naming what is wrong, not a panic.
        assert!(mesh.validate().is_ok());
        let mut damaged = mesh.clone();
        damaged.embedding[3].tet = damaged.tets.len();
        let e = damaged.v2y(&x).unwrap_err().to_string();
        assert!(
            e.contains("yarn vertex 3 is embedded in tetrahedron"),
            "{e}"
        );
        assert!(damaged.v2y_transpose(&w).is_err() && damaged.v2y_matrix().is_err());
        assert!(damaged.validate().is_err());
        let mut damaged = mesh.clone();
        damaged.tets[0][2] = damaged.rest.len();
        assert!(
            damaged
                .validate()
                .unwrap_err()
                .to_string()
                .contains("tetrahedron 0")
        );
        assert!(damaged.v2y(&x).is_err());
        let mut damaged = mesh.clone();
        damaged.node_mass.pop();
        assert!(
            damaged
                .validate()
                .unwrap_err()
                .to_string()
                .contains("nodal masses")
        );
    }
}
