//! Harmonic bases of a tetrahedral mesh's elements (the knitwear paper, Sec. 6.5, Eq. 23–24): the `r`
//! smoothest per-element fields, through which the elasticity fit first looks for a material
//! `γ = diag(H, H) q` with `q ∈ ℝ^{2r}` before it frees every element (`r = 1, 10, 30`, then all).
//!
//! **The operator.** The fields live on elements (one `γ` per tetrahedron), so the Laplacian is the
//! finite-volume one of the element graph: two tetrahedra `a`, `b` that share a face `f` are joined with
//! the weight `w_ab = A_f / |c_a − c_b|` (the face's area over the distance of the centroids, m), and
//!
//! ```text
//! L = Σ_faces w_ab (e_a − e_b)(e_a − e_b)ᵀ   (m),      M = diag(V_e)   (m³),
//! L h = λ M h                                         (λ in 1/m²),
//! ```
//!
//! the generalized eigenproblem of a Laplacian with the element volumes as its mass, so that on a
//! refined mesh the fields approximate the Neumann eigenfunctions of the solid, whatever the element sizes
//! (Vallet and Lévy 2008 use the same mass-weighted form on surfaces). `L` is positive semi-definite with
//! the constant fields of each connected part as its kernel, so `h₁` is constant and `λ₁ = 0`.
//!
//! **The solve.** Subspace iteration with shift-and-invert: a block `X` of `p = r + oversampling`
//! columns is mapped to `(L + σ M)⁻¹ M X` (one sparse Cholesky factorization, `p` solves an iteration),
//! made `M`-orthonormal by Gram-Schmidt, and rotated onto the Ritz vectors of `L` in its span (a dense
//! `p × p` eigenproblem). The shift `σ = 10⁻² / D²` (`D` the rest mesh's bounding-box diagonal) lies far
//! below the first non-zero eigenvalue (≈ π² / D² on a box), so the factor is positive definite while the
//! lowest eigenvalues converge at the rate `(λ_r + σ) / (λ_{p+1} + σ)` per iteration. The iteration stops
//! when each of the first `r` pairs has `‖L h − λ M h‖_{M⁻¹} ≤ tol · max(λ, σ) ‖h‖_M`.
//!
//! **Normalization.** Each basis vector is scaled to `hᵀ M h = Σ_e V_e` (a volume-weighted root mean
//! square of 1) and signed so that its largest-magnitude entry is positive, so the constant vector is
//! exactly all ones and `q` carries the units of `γ` (Pa). Eigenvectors of a repeated eigenvalue are an
//! arbitrary basis of their eigenspace; the fit needs the span, not the vectors.

use std::collections::HashMap;

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef, Triplet};
use nalgebra::{DMatrix, SymmetricEigen, Vector3};
use skintight_geometry::body::tet_mesh::tet_signed_volume;
use skintight_physics::newton::compressed_lower;

use crate::volumetric_mesh::tet_split::sorted_faces;
use skintight_physics::{SparseCholesky, SparseCholeskyParams};
use thiserror::Error;

/// Settings of [`harmonic_basis`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HarmonicBasisParams {
    /// Relative eigen-residual at which a pair counts as converged (dimensionless). Default `1e-6`: the
    /// fit needs the span of smooth fields, not eigenvectors to round-off.
    pub tolerance: f64,
    /// Most subspace iterations. Default 500.
    pub max_iterations: usize,
    /// Extra columns of the block beyond the rank; `None`: `max(4, r / 2)`.
    pub oversampling: Option<usize>,
}

impl Default for HarmonicBasisParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-6,
            max_iterations: 500,
            oversampling: None,
        }
    }
}

/// Why [`harmonic_basis`] could not build a basis.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum HarmonicBasisError {
    /// The rank is zero or above the number of elements.
    #[error(
        "a harmonic basis of rank {rank} was asked of a mesh of {elements} elements; ask for 1 ..= {elements}"
    )]
    Rank {
        /// The rank asked for.
        rank: usize,
        /// Elements of the mesh.
        elements: usize,
    },
    /// A node position is not finite or a tetrahedron names a node that does not exist.
    #[error(
        "tetrahedron {tet} names node {node}, which is missing or not at a finite position; pass the mesh as built"
    )]
    Node {
        /// The tetrahedron.
        tet: usize,
        /// Its node.
        node: usize,
    },
    /// A tetrahedron has no volume (or is inverted) at rest.
    #[error(
        "tetrahedron {tet} has rest volume {volume:e} m³; every element needs a positive volume"
    )]
    Degenerate {
        /// The tetrahedron.
        tet: usize,
        /// Its signed volume (m³).
        volume: f64,
    },
    /// A settings value is out of range.
    #[error("harmonic basis setting {name} = {value} is out of range: {why}")]
    Params {
        /// The setting.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        why: &'static str,
    },
    /// The factorization of `L + σ M` failed (only round-off on a valid mesh can cause it).
    #[error("the shifted element Laplacian could not be factored: {0}")]
    Factorization(String),
    /// The subspace iteration did not converge.
    #[error(
        "the harmonic basis did not converge in {iterations} iterations (worst residual {residual:e}); \
         raise max_iterations or the tolerance"
    )]
    NotConverged {
        /// Iterations made.
        iterations: usize,
        /// The worst relative residual of the first `r` pairs.
        residual: f64,
    },
}

/// `r` harmonic fields over a mesh's elements: the matrix `H` (`#T × r`) of Eq. 23.
#[derive(Clone, Debug, PartialEq)]
pub struct HarmonicBasis {
    elements: usize,
    /// Column-major `#T × r`.
    values: Vec<f64>,
    /// `λ₁ ≤ … ≤ λ_r` (1/m²).
    eigenvalues: Vec<f64>,
    iterations: usize,
}

impl HarmonicBasis {
    /// The rank `r`.
    pub fn rank(&self) -> usize {
        self.eigenvalues.len()
    }

    /// `#T`.
    pub fn elements(&self) -> usize {
        self.elements
    }

    /// Basis vector `k` (`#T`, dimensionless).
    pub fn column(&self, k: usize) -> &[f64] {
        &self.values[k * self.elements..(k + 1) * self.elements]
    }

    /// The eigenvalues `λ₁ ≤ … ≤ λ_r` (1/m²).
    pub fn eigenvalues(&self) -> &[f64] {
        &self.eigenvalues
    }

    /// Subspace iterations the basis took (0 for rank 1, which needs none).
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// The per-element field `H q` (`#T`) of coefficients `q` (`r`): Eq. 23 for one of `γˢ`, `γᵛ`.
    pub fn field(&self, q: &[f64]) -> Vec<f64> {
        assert_eq!(q.len(), self.rank(), "one coefficient per basis vector");
        let mut out = vec![0.0; self.elements];
        for (k, &c) in q.iter().enumerate() {
            for (o, h) in out.iter_mut().zip(self.column(k)) {
                *o += c * h;
            }
        }
        out
    }

    /// `Hᵀ g` (`r`) of a per-element derivative `g` (`#T`): the chain rule below Eq. 23.
    pub fn pull_back(&self, g: &[f64]) -> Vec<f64> {
        assert_eq!(g.len(), self.elements, "one entry per element");
        (0..self.rank())
            .map(|k| self.column(k).iter().zip(g).map(|(h, g)| h * g).sum())
            .collect()
    }

    /// The least-squares coefficients of a per-element field in the volume inner product,
    /// `q = (Hᵀ M H)⁻¹ Hᵀ M γ = Hᵀ M γ / Σ V` (the basis is `M`-orthogonal): how a fit at a lower rank
    /// hands its field to a higher one. `volumes` is `M`'s diagonal (m³).
    pub fn project(&self, field: &[f64], volumes: &[f64]) -> Vec<f64> {
        let total: f64 = volumes.iter().sum();
        let weighted: Vec<f64> = field.iter().zip(volumes).map(|(f, v)| f * v).collect();
        self.pull_back(&weighted)
            .into_iter()
            .map(|c| c / total)
            .collect()
    }
}

/// The element graph of a mesh: volumes `V_e` (m³) and, per face shared by two elements, the pair and the
/// weight `A_f / |c_a − c_b|` (m).
#[derive(Clone, Debug, PartialEq)]
pub struct ElementGraph {
    /// `V_e`, `#T` (m³).
    pub volumes: Vec<f64>,
    /// `(a, b, w_ab)` with `a > b`, one per interior face (m).
    pub edges: Vec<(usize, usize, f64)>,
}

/// The element graph of `tets` over `rest` (`#V × 3`, m), validated.
pub fn element_graph(
    rest: &[[f64; 3]],
    tets: &[[usize; 4]],
) -> Result<ElementGraph, HarmonicBasisError> {
    let mut volumes = Vec::with_capacity(tets.len());
    let mut centroids = Vec::with_capacity(tets.len());
    for (t, tet) in tets.iter().enumerate() {
        let mut p = [Vector3::zeros(); 4];
        for (c, &n) in tet.iter().enumerate() {
            let x = rest
                .get(n)
                .filter(|x| x.iter().all(|v| v.is_finite()))
                .ok_or(HarmonicBasisError::Node { tet: t, node: n })?;
            p[c] = Vector3::from(*x);
        }
        let volume = tet_signed_volume(&p[0], &p[1], &p[2], &p[3]);
        if volume.is_nan() || volume <= 0.0 {
            return Err(HarmonicBasisError::Degenerate { tet: t, volume });
        }
        volumes.push(volume);
        centroids.push((p[0] + p[1] + p[2] + p[3]) / 4.0);
    }
    let mut faces: HashMap<[usize; 3], usize> = HashMap::with_capacity(2 * tets.len());
    let mut edges = Vec::new();
    for (t, tet) in tets.iter().enumerate() {
        for face in sorted_faces(tet) {
            if let Some(other) = faces.remove(&face) {
                let corner = |n: usize| Vector3::from(rest[n]);
                let area = 0.5
                    * (corner(face[1]) - corner(face[0]))
                        .cross(&(corner(face[2]) - corner(face[0])))
                        .norm();
                let distance = (centroids[t] - centroids[other]).norm();
                edges.push((t.max(other), t.min(other), area / distance));
            } else {
                faces.insert(face, t);
            }
        }
    }
    Ok(ElementGraph { volumes, edges })
}

impl ElementGraph {
    /// `L x` (`#T`, m · units of `x`).
    fn laplacian(&self, x: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; x.len()];
        for &(a, b, w) in &self.edges {
            let d = w * (x[a] - x[b]);
            out[a] += d;
            out[b] -= d;
        }
        out
    }
}

/// The `rank` smoothest fields of the mesh's element graph (see the module documentation); `rest` is
/// `#V × 3` (m), `tets` `#T × 4`.
pub fn harmonic_basis(
    rest: &[[f64; 3]],
    tets: &[[usize; 4]],
    rank: usize,
    params: &HarmonicBasisParams,
) -> Result<HarmonicBasis, HarmonicBasisError> {
    let n = tets.len();
    if rank == 0 || rank > n {
        return Err(HarmonicBasisError::Rank { rank, elements: n });
    }
    if !(params.tolerance > 0.0 && params.tolerance < 1.0) {
        return Err(HarmonicBasisError::Params {
            name: "tolerance",
            value: params.tolerance,
            why: "a relative residual in (0, 1)",
        });
    }
    let graph = element_graph(rest, tets)?;
    if rank == 1 {
        return Ok(HarmonicBasis {
            elements: n,
            values: vec![1.0; n],
            eigenvalues: vec![0.0],
            iterations: 0,
        });
    }
    let volumes = &graph.volumes;
    let total: f64 = volumes.iter().sum();
    let p = (rank + params.oversampling.unwrap_or((rank / 2).max(4))).min(n);

    // The shift: far below the first non-zero eigenvalue, ≈ π² / D².
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for tet in tets {
        for &v in tet {
            for k in 0..3 {
                lo[k] = lo[k].min(rest[v][k]);
                hi[k] = hi[k].max(rest[v][k]);
            }
        }
    }
    let diagonal = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    let sigma = 1e-2 / (diagonal * diagonal);

    let mut triplets = Vec::with_capacity(n + 3 * graph.edges.len());
    for (e, &v) in volumes.iter().enumerate() {
        triplets.push(Triplet::new(e, e, sigma * v));
    }
    for &(a, b, w) in &graph.edges {
        triplets.push(Triplet::new(a, a, w));
        triplets.push(Triplet::new(b, b, w));
        triplets.push(Triplet::new(a, b, -w));
    }
    let lower = compressed_lower(n, &triplets);
    let symbolic = SymbolicSparseColMatRef::new_checked(n, n, &lower.col_ptr, None, &lower.row_idx);
    let matrix = SparseColMatRef::new(symbolic, &lower.values);
    let factor_error =
        |e: skintight_physics::CholeskyError| HarmonicBasisError::Factorization(e.to_string());
    let mut chol =
        SparseCholesky::analyze(matrix, &SparseCholeskyParams::default()).map_err(factor_error)?;
    chol.factorize(matrix).map_err(factor_error)?;

    // The start: the constant field and smooth coordinate monomials of the centroids, then a
    // deterministic pseudo-random fill (no zero column, no accidental symmetry).
    let mut block = vec![0.0; n * p];
    let centroid = |e: usize, k: usize| tets[e].iter().map(|&v| rest[v][k]).sum::<f64>() / 4.0;
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    for j in 0..p {
        for e in 0..n {
            block[j * n + e] = match j {
                0 => 1.0,
                1..=3 => centroid(e, j - 1) - lo[j - 1],
                _ => {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
                }
            };
        }
    }
    m_orthonormalize(&mut block, n, p, volumes);

    let mut eigenvalues = vec![0.0; p];
    let mut worst = f64::INFINITY;
    for iteration in 1..=params.max_iterations {
        // Y = (L + σ M)⁻¹ M X.
        for j in 0..p {
            for e in 0..n {
                block[j * n + e] *= volumes[e];
            }
        }
        chol.solve_columns_in_place(&mut block, p)
            .map_err(factor_error)?;
        m_orthonormalize(&mut block, n, p, volumes);
        // Rayleigh-Ritz: A = Yᵀ L Y (Y is M-orthonormal), X = Y Z.
        let ly: Vec<Vec<f64>> = (0..p)
            .map(|j| graph.laplacian(&block[j * n..(j + 1) * n]))
            .collect();
        let a = DMatrix::<f64>::from_fn(p, p, |i, j| {
            let yi = &block[i * n..(i + 1) * n];
            yi.iter().zip(&ly[j]).map(|(y, l)| y * l).sum::<f64>()
        });
        let a = (&a + a.transpose()) * 0.5;
        let eigen = SymmetricEigen::new(a);
        let mut order: Vec<usize> = (0..p).collect();
        order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
        let mut rotated = vec![0.0; n * p];
        let mut lx = vec![0.0; n * p];
        for (k, &i) in order.iter().enumerate() {
            eigenvalues[k] = eigen.eigenvalues[i].max(0.0);
            for j in 0..p {
                let z = eigen.eigenvectors[(j, i)];
                if z != 0.0 {
                    for e in 0..n {
                        rotated[k * n + e] += z * block[j * n + e];
                        lx[k * n + e] += z * ly[j][e];
                    }
                }
            }
        }
        block = rotated;
        // Residuals of the first `rank` pairs, ‖L h − λ M h‖_{M⁻¹} against max(λ, σ) ‖h‖_M (= 1).
        worst = (0..rank)
            .map(|k| {
                let lambda = eigenvalues[k];
                let r2: f64 = (0..n)
                    .map(|e| {
                        let r = lx[k * n + e] - lambda * volumes[e] * block[k * n + e];
                        r * r / volumes[e]
                    })
                    .sum();
                r2.sqrt() / lambda.max(sigma)
            })
            .fold(0.0, f64::max);
        if worst <= params.tolerance {
            let mut values = block[..rank * n].to_vec();
            for k in 0..rank {
                let column = &mut values[k * n..(k + 1) * n];
                let largest = column
                    .iter()
                    .copied()
                    .fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m });
                let scale = total.sqrt() * largest.signum();
                column.iter_mut().for_each(|v| *v *= scale);
            }
            eigenvalues.truncate(rank);
            return Ok(HarmonicBasis {
                elements: n,
                values,
                eigenvalues,
                iterations: iteration,
            });
        }
    }
    Err(HarmonicBasisError::NotConverged {
        iterations: params.max_iterations,
        residual: worst,
    })
}

/// Modified Gram-Schmidt, twice, in the inner product `⟨x, y⟩ = Σ V_e x_e y_e` on the column-major
/// `n × p` block; a column that vanishes is replaced by a fresh one orthogonal to the others.
fn m_orthonormalize(block: &mut [f64], n: usize, p: usize, volumes: &[f64]) {
    let dot = |x: &[f64], y: &[f64]| -> f64 {
        x.iter()
            .zip(y)
            .zip(volumes)
            .map(|((a, b), v)| a * b * v)
            .sum()
    };
    for j in 0..p {
        let before = dot(&block[j * n..(j + 1) * n], &block[j * n..(j + 1) * n]).sqrt();
        for _pass in 0..2 {
            for i in 0..j {
                let (head, tail) = block.split_at_mut(j * n);
                let xi = &head[i * n..(i + 1) * n];
                let xj = &mut tail[..n];
                let c = dot(xi, xj);
                xj.iter_mut().zip(xi).for_each(|(y, x)| *y -= c * x);
            }
        }
        let column = &mut block[j * n..(j + 1) * n];
        let mut norm = dot(column, column).sqrt();
        if norm.is_nan() || norm <= 1e-10 * before || norm == 0.0 {
            // Lost to round-off: restart it as an alternating field, then orthogonalize again.
            for (e, v) in column.iter_mut().enumerate() {
                *v = if (e * 7 + j) % 3 == 0 { 1.0 } else { -0.5 };
            }
            for i in 0..j {
                let (head, tail) = block.split_at_mut(j * n);
                let xi = &head[i * n..(i + 1) * n];
                let xj = &mut tail[..n];
                let c = dot(xi, xj);
                xj.iter_mut().zip(xi).for_each(|(y, x)| *y -= c * x);
            }
            norm = dot(&block[j * n..(j + 1) * n], &block[j * n..(j + 1) * n]).sqrt();
        }
        block[j * n..(j + 1) * n]
            .iter_mut()
            .for_each(|v| *v /= norm);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `k.0 × k.1 × k.2` grid of cubes of side `h`, six tetrahedra a cube.
    pub(super) fn grid(k: [usize; 3], h: f64) -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
        crate::volumetric_mesh::tet_split::voxel_block(k, h)
    }

    /// The generalized eigenvalues of (L, M) by a dense solve of `M^{-1/2} L M^{-1/2}`.
    fn dense_eigenvalues(graph: &ElementGraph) -> Vec<f64> {
        let n = graph.volumes.len();
        let mut l = DMatrix::<f64>::zeros(n, n);
        for &(a, b, w) in &graph.edges {
            l[(a, a)] += w;
            l[(b, b)] += w;
            l[(a, b)] -= w;
            l[(b, a)] -= w;
        }
        let s = DMatrix::from_fn(n, n, |i, j| {
            l[(i, j)] / (graph.volumes[i] * graph.volumes[j]).sqrt()
        });
        let mut values: Vec<f64> = SymmetricEigen::new(s).eigenvalues.iter().copied().collect();
        values.sort_by(f64::total_cmp);
        values
    }

    #[test]
    fn eigenvalues_match_a_dense_solve_and_vectors_are_m_orthonormal() {
        let (rest, tets) = grid([4, 3, 2], 0.002);
        let graph = element_graph(&rest, &tets).unwrap();
        let dense = dense_eigenvalues(&graph);
        let basis = harmonic_basis(
            &rest,
            &tets,
            12,
            &HarmonicBasisParams {
                tolerance: 1e-10,
                ..Default::default()
            },
        )
        .unwrap();
        for (k, (&ours, &theirs)) in basis.eigenvalues().iter().zip(&dense).enumerate() {
            assert!(
                (ours - theirs).abs() <= 1e-8 * dense[11],
                "eigenvalue {k}: {ours} vs dense {theirs}"
            );
        }
        let total: f64 = graph.volumes.iter().sum();
        for i in 0..basis.rank() {
            for j in 0..basis.rank() {
                let g: f64 = (0..tets.len())
                    .map(|e| basis.column(i)[e] * basis.column(j)[e] * graph.volumes[e])
                    .sum();
                let want = if i == j { total } else { 0.0 };
                assert!((g - want).abs() < 1e-8 * total, "⟨h{i}, h{j}⟩_M = {g}");
            }
        }
        // The first is exactly the constant field of ones; the second varies along the longest side.
        assert!(basis.column(0).iter().all(|&v| (v - 1.0).abs() < 1e-8));
        assert!(basis.eigenvalues()[0].abs() < 1e-8 * basis.eigenvalues()[1]);
    }

    #[test]
    fn fields_and_pull_back_are_transposes_and_project_inverts_field() {
        let (rest, tets) = grid([3, 3, 1], 0.01);
        let graph = element_graph(&rest, &tets).unwrap();
        let basis = harmonic_basis(&rest, &tets, 6, &HarmonicBasisParams::default()).unwrap();
        let q = [2.0, -1.0, 0.5, 0.25, 3.0, -0.75];
        let g: Vec<f64> = (0..tets.len())
            .map(|e| ((e * 13) % 7) as f64 - 3.0)
            .collect();
        let hq = basis.field(&q);
        let lhs: f64 = hq.iter().zip(&g).map(|(a, b)| a * b).sum();
        let rhs: f64 = basis.pull_back(&g).iter().zip(&q).map(|(a, b)| a * b).sum();
        assert!((lhs - rhs).abs() < 1e-10 * lhs.abs().max(1.0));
        let back = basis.project(&hq, &graph.volumes);
        for (a, b) in back.iter().zip(&q) {
            assert!((a - b).abs() < 1e-6, "{back:?} vs {q:?}");
        }
    }

    #[test]
    fn a_mesh_in_two_parts_has_two_constant_fields() {
        let (mut rest, mut tets) = grid([2, 2, 1], 0.01);
        let offset = rest.len();
        let (rest2, tets2) = grid([2, 1, 1], 0.01);
        rest.extend(rest2.iter().map(|p| [p[0] + 1.0, p[1], p[2]]));
        tets.extend(tets2.iter().map(|t| t.map(|v| v + offset)));
        let basis = harmonic_basis(&rest, &tets, 4, &HarmonicBasisParams::default()).unwrap();
        assert!(basis.eigenvalues()[0] < 1e-6 * basis.eigenvalues()[2]);
        assert!(basis.eigenvalues()[1] < 1e-6 * basis.eigenvalues()[2]);
    }

    #[test]
    fn bad_meshes_and_ranks_are_refused_by_name() {
        let (mut rest, mut tets) = grid([1, 1, 1], 0.01);
        assert!(matches!(
            harmonic_basis(&rest, &tets, 0, &HarmonicBasisParams::default()),
            Err(HarmonicBasisError::Rank {
                rank: 0,
                elements: 6
            })
        ));
        assert!(matches!(
            harmonic_basis(&rest, &tets, 7, &HarmonicBasisParams::default()),
            Err(HarmonicBasisError::Rank { rank: 7, .. })
        ));
        let bad = HarmonicBasisParams {
            tolerance: f64::NAN,
            ..Default::default()
        };
        assert!(matches!(
            harmonic_basis(&rest, &tets, 2, &bad),
            Err(HarmonicBasisError::Params { .. })
        ));
        tets[2].swap(0, 1);
        assert!(matches!(
            harmonic_basis(&rest, &tets, 2, &HarmonicBasisParams::default()),
            Err(HarmonicBasisError::Degenerate { tet: 2, .. })
        ));
        tets[2].swap(0, 1);
        rest[3][1] = f64::NAN;
        let err = harmonic_basis(&rest, &tets, 2, &HarmonicBasisParams::default()).unwrap_err();
        assert!(
            matches!(err, HarmonicBasisError::Node { node: 3, .. }),
            "{err}"
        );
        tets[0][0] = 99;
        assert!(matches!(
            harmonic_basis(&rest, &tets, 2, &HarmonicBasisParams::default()),
            Err(HarmonicBasisError::Node { tet: 0, node: 99 })
        ));
    }

    #[test]
    fn the_convergence_test_can_fail() {
        let (rest, tets) = grid([4, 4, 2], 0.01);
        let params = HarmonicBasisParams {
            tolerance: 1e-14,
            max_iterations: 2,
            oversampling: Some(1),
        };
        assert!(matches!(
            harmonic_basis(&rest, &tets, 10, &params),
            Err(HarmonicBasisError::NotConverged { iterations: 2, .. })
        ));
    }
}
