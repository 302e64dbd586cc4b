//! The mid-edge normal shape operator of a triangle mesh (thesis Eq. 175–176, after Grinspun, Gingold,
//! Reisman and Zorin, "Computing discrete shape operators on general meshes", 2006), with the per-edge
//! normal corrections `φ` chosen to minimise the curvature energy `ψ`, and the derivatives the adjoint of
//! the pressure objective needs (Eq. 180).
//!
//! # The operator
//!
//! For a cloth triangle `f` with corners `x0, x1, x2` (m, counter-clockwise seen from outside), edge `k`
//! runs from corner `k` to corner `k + 1`: `e_k = x_{k+1} − x_k`, length `l_k` (m). With the unit outward
//! normal `n` and the deformed area `A` (m²), `t_k = e_k × n` is the in-plane edge normal of length `l_k`
//! (pointing out of the triangle). The shape operator of the triangle (Eq. 175; 3 × 3, 1/m, acting on the
//! triangle's tangent plane) is
//!
//! ```text
//! Λ_f = Σ_k a_k / (A l_k) t_k t_kᵀ,       a_k = θ_k/2 + s_k φ_k,
//! ```
//!
//! where, for edge `k`:
//! - `θ_k` (rad) is the signed bending angle between the normals of the two triangles sharing the edge,
//!   `θ = atan2((n_f × n_g)·ê, n_f·n_g)` with `ê = e_k/l_k` oriented as in the edge's *first* triangle
//!   `f`, positive where the surface is convex seen from outside (a sphere has `θ > 0` everywhere). The
//!   same value results from either side, so `θ` belongs to the edge. `θ/2` is the angle from each face
//!   normal to the averaged mid-edge normal.
//! - `φ_k` (rad) is the edge's correction degree of freedom: the mid-edge normal is turned by `φ` towards
//!   one side, so the angle from the face normal to it is `θ/2 + φ` in the edge's first triangle and
//!   `θ/2 − φ` in its second: `s_k = +1` for the first half-edge, `−1` for the opposite one.
//!
//! For a sphere of radius `R` meshed with small equilateral triangles, `θ ≈ l/(√3 R)` on every edge and
//! `tr Λ = 2/R`; on a cylinder `Λ → t̂ t̂ᵀ/R` along the circumference (both tested, with convergence).
//!
//! # Boundary edges
//!
//! An edge with one triangle has no bending angle: `θ = 0` there. Its mid-edge normal is chosen by
//! [`BoundaryEdges`]. [`BoundaryEdges::Free`] (default) gives it a free correction `φ`, found by the same
//! minimisation of `ψ` as the interior ones (the natural boundary condition): the boundary triangle's
//! mid-edge normal is whatever is most consistent with its neighbours. [`BoundaryEdges::FaceNormal`] fixes it
//! to the face normal (`a_k = 0`, no DOF). Measured (tests): on an open cylinder with irregular vertices the
//! free treatment converges at second order everywhere (error 0.1% of `1/R` at 48 vertices around), while
//! fixing the normals is wrong at the ends (the face of an irregular end triangle is tilted about its end
//! edge) and the error spreads through `φ` into the interior (24% at the ends, 3% inside, not converging).
//! On regular meshes whose boundary runs along a direction of zero normal curvature both agree. Where the
//! boundary is curved (a spherical cap) neither is right on the boundary triangles — the mesh does not
//! determine the normal across a free edge; the error is O(1) of the curvature there and 2–4% on the
//! triangles without a boundary vertex, for both treatments — which is why the pressure objective leaves
//! the boundary ring out by default ([`crate::pressure`]).
//!
//! # The corrections (Eq. 176)
//!
//! `φ` minimises `ψ = Σ_f A_f tr(Λ_f²)` (dimensionless). With `tr(t_i t_iᵀ t_j t_jᵀ) = (t_i·t_j)² =
//! (e_i·e_j)²`,
//!
//! ```text
//! ψ_f = aᵀ K_f a,      (K_f)_ij = (e_i·e_j)² / (A l_i l_j)     (dimensionless, 3 × 3, SPD),
//! ```
//!
//! quadratic in `φ`. `K_f` is positive definite for a non-degenerate triangle (the three `t_i t_iᵀ` are
//! linearly independent), so the Hessian `H = ∂²ψ/∂φ²` is positive definite whenever every triangle is
//! non-degenerate: `φ* = −H⁻¹ ∂ψ/∂φ|_{φ=0}` is one sparse SPD solve (faer's sparse Cholesky with its
//! fill-reducing ordering; `H` has at most 5 entries per row, so a few thousand edges factor in
//! milliseconds). Near-degenerate meshes make `H` ill-conditioned, so what is minimised is
//! `ψ̃ = ψ + δ |φ|²` with the fixed Tikhonov constant `δ = ` [`TIKHONOV`] (dimensionless, about 1e-10 of a
//! typical diagonal entry `2 l²/A ≈ 4.6`): `φ*` moves by a relative 1e-10 at most, and because `δ` does
//! not depend on the positions every derivative below is exact for `ψ̃`.
//!
//! # Derivatives
//!
//! The per-triangle geometry (`θ`, `l`, `A`, `K`) is evaluated with forward-mode dual numbers over the
//! triangle's corners and the vertices across its edges, so the derivatives with respect to the positions
//! `x` are exact. [`MidEdgeSolution::mixed_entries`] gives `∂²ψ̃/∂φ∂x` (the matrix of Eq. 180) as sparse
//! entries and [`MidEdgeSolution::adjoint_solve`] applies `H̃⁻¹`, so that for any `T(x, φ*(x))`,
//!
//! ```text
//! dT/dx = ∂T/∂x − μᵀ ∂²ψ̃/∂φ∂x,      H̃ μ = ∂T/∂φ.
//! ```

use crate::dual::{DVec3, Dual, constant3, cross3, dot3, sub3, variable3};
use crate::math::{Mat3, Real, Vec3};
use faer::prelude::Solve;
use faer::sparse::{SparseColMat, Triplet};
use std::collections::HashMap;

/// Tikhonov constant `δ` of `ψ̃ = ψ + δ|φ|²` (dimensionless); see the module documentation.
pub const TIKHONOV: Real = 1e-10;

/// How the mid-edge normal of a boundary edge (one triangle) is chosen; see the module documentation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BoundaryEdges {
    /// A free correction `φ` (with `θ = 0`), minimising `ψ` like the interior edges. Default.
    #[default]
    Free,
    /// The face normal: `a = 0`, no correction DOF.
    FaceNormal,
}

/// Why the operator cannot be built or evaluated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MidEdgeError {
    /// Bad sizes or vertex ids, or non-finite positions.
    #[error("{0}")]
    Input(String),
    /// An edge with more than two triangles, or two triangles traversing it in the same direction.
    #[error(
        "edge ({0}, {1}) is shared by more than two triangles or its triangles are not consistently oriented"
    )]
    NonManifold(usize, usize),
    /// A cloth triangle with (nearly) zero area or a zero-length edge: its shape operator is undefined.
    #[error(
        "cloth triangle {0} is degenerate (zero area or edge), its shape operator is undefined"
    )]
    Degenerate(usize),
    /// The sparse factorization of `∂²ψ̃/∂φ²` failed.
    #[error("the curvature energy's Hessian in φ could not be factored: {0}")]
    Solve(String),
}

/// The edge structure of a triangle mesh and its correction DOFs.
#[derive(Clone, Debug, PartialEq)]
pub struct MidEdgeShapeOperator {
    /// `#F × 3` triangles (vertex ids), counter-clockwise from outside.
    triangles: Vec<[usize; 3]>,
    /// Number of vertices.
    num_vertices: usize,
    /// `#E` edges `[a, b]`, oriented as in their first triangle.
    edges: Vec<[usize; 2]>,
    /// `#F × 3`: the edge id of edge `k` (corner `k` → `k + 1`) of each triangle.
    face_edges: Vec<[usize; 3]>,
    /// `#F × 3`: `s_k` (+1 first triangle of the edge, −1 second).
    face_signs: Vec<[Real; 3]>,
    /// `#F × 3`: the vertex of the other triangle across edge `k`, `None` on the boundary.
    face_opposite: Vec<[Option<usize>; 3]>,
    /// `#E`: the correction DOF of each edge, `None` for a fixed boundary normal.
    edge_dof: Vec<Option<usize>>,
    /// Number of DOFs.
    num_dofs: usize,
    boundary: BoundaryEdges,
}

/// `θ`, `l` and `K` of one triangle as duals in caller-chosen variables.
pub(crate) struct FaceGeometry<const N: usize> {
    /// Bending angle of each edge (rad), 0 on the boundary.
    pub theta: [Dual<N>; 3],
    /// Edge lengths `l_k` (m).
    pub length: [Dual<N>; 3],
    /// `K_ij = (e_i·e_j)²/(A l_i l_j)` (dimensionless).
    pub k: [[Dual<N>; 3]; 3],
}

/// The geometry of the triangle with corners `x` and the vertices `y[k]` across its edges. The caller
/// has checked that it and its neighbours are not degenerate.
pub(crate) fn face_geometry<const N: usize>(
    x: &[DVec3<N>; 3],
    y: &[Option<DVec3<N>>; 3],
) -> FaceGeometry<N> {
    let e: [DVec3<N>; 3] = [0, 1, 2].map(|k| sub3(&x[(k + 1) % 3], &x[k]));
    let normal = cross3(&e[0], &sub3(&x[2], &x[0]));
    let area = dot3(&normal, &normal).sqrt() * 0.5;
    let length = e.map(|v| dot3(&v, &v).sqrt());
    let theta = [0, 1, 2].map(|k| match &y[k] {
        None => Dual::constant(0.0),
        Some(y) => {
            let (a, b) = (&x[k], &x[(k + 1) % 3]);
            let other = cross3(&sub3(a, b), &sub3(y, b));
            let sin = dot3(&cross3(&normal, &other), &e[k]);
            let cos = dot3(&normal, &other) * length[k];
            sin.atan2(cos)
        }
    });
    let k = [0, 1, 2].map(|i| {
        [0, 1, 2].map(|j| {
            let d = dot3(&e[i], &e[j]);
            d * d / (area * length[i] * length[j])
        })
    });
    FaceGeometry { theta, length, k }
}

/// Positions of triangle `f`'s corners and opposite vertices as the 18 dual variables
/// `[x0, x1, x2, y0, y1, y2]` (coordinates in order; absent opposite vertices take no variables' values
/// but keep their slots).
pub(crate) fn local_duals<const N: usize>(
    op: &MidEdgeShapeOperator,
    x: &[Vec3],
    f: usize,
) -> ([DVec3<N>; 3], [Option<DVec3<N>>; 3]) {
    let t = op.triangles[f];
    let corners = [0, 1, 2].map(|c| variable3(&x[t[c]], 3 * c));
    let opposite = [0, 1, 2].map(|k| op.face_opposite[f][k].map(|v| variable3(&x[v], 9 + 3 * k)));
    (corners, opposite)
}

/// [`local_duals`] without derivatives: the same positions as values only, for what needs only the
/// values of [`face_geometry`] (the same operations, so the same values to the bit, without the 18
/// derivatives each one carries).
pub(crate) fn local_values(
    op: &MidEdgeShapeOperator,
    x: &[Vec3],
    f: usize,
) -> ([DVec3<0>; 3], [Option<DVec3<0>>; 3]) {
    let t = op.triangles[f];
    let corners = [0, 1, 2].map(|c| constant3(&x[t[c]]));
    let opposite = [0, 1, 2].map(|k| op.face_opposite[f][k].map(|v| constant3(&x[v])));
    (corners, opposite)
}

impl MidEdgeShapeOperator {
    /// The edge structure of `triangles` (`#F × 3` vertex ids below `num_vertices`, consistently
    /// oriented); errors on bad ids, non-manifold or inconsistently oriented edges, or no triangles.
    pub fn new(
        triangles: &[[usize; 3]],
        num_vertices: usize,
        boundary: BoundaryEdges,
    ) -> Result<Self, MidEdgeError> {
        if triangles.is_empty() {
            return Err(MidEdgeError::Input("the mesh has no triangles".into()));
        }
        if let Some(f) = triangles.iter().position(|t| {
            t.iter().any(|&v| v >= num_vertices) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]
        }) {
            return Err(MidEdgeError::Input(format!(
                "triangle {f} has a vertex id out of range or repeated"
            )));
        }
        let mut directed: HashMap<(usize, usize), (usize, usize)> = HashMap::new();
        for (f, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if directed.insert((a, b), (f, k)).is_some() {
                    return Err(MidEdgeError::NonManifold(a, b));
                }
            }
        }
        let nf = triangles.len();
        let mut edges = Vec::new();
        let mut face_edges = vec![[usize::MAX; 3]; nf];
        let mut face_signs = vec![[1.0; 3]; nf];
        let mut face_opposite = vec![[None; 3]; nf];
        let mut edge_dof = Vec::new();
        let mut num_dofs = 0;
        for (f, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                if face_edges[f][k] != usize::MAX {
                    continue;
                }
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let id = edges.len();
                edges.push([a, b]);
                face_edges[f][k] = id;
                let twin = directed.get(&(b, a)).copied();
                if let Some((g, j)) = twin {
                    face_edges[g][j] = id;
                    face_signs[g][j] = -1.0;
                    face_opposite[f][k] = Some(triangles[g][(j + 2) % 3]);
                    face_opposite[g][j] = Some(t[(k + 2) % 3]);
                }
                if twin.is_some() || boundary == BoundaryEdges::Free {
                    edge_dof.push(Some(num_dofs));
                    num_dofs += 1;
                } else {
                    edge_dof.push(None);
                }
            }
        }
        Ok(Self {
            triangles: triangles.to_vec(),
            num_vertices,
            edges,
            face_edges,
            face_signs,
            face_opposite,
            edge_dof,
            num_dofs,
            boundary,
        })
    }

    /// Number of edges `#E`.
    pub fn num_edges(&self) -> usize {
        self.edges.len()
    }

    /// The `#E` edges `[a, b]` (vertex ids), oriented as in their first triangle.
    pub fn edges(&self) -> &[[usize; 2]] {
        &self.edges
    }

    /// Edge ids of the three edges (corner `k` → `k + 1`) of triangle `f`.
    pub fn face_edges(&self, f: usize) -> [usize; 3] {
        self.face_edges[f]
    }

    /// Signs `s_k` of triangle `f`'s half-edges (+1 first triangle of the edge, −1 second).
    pub fn face_signs(&self, f: usize) -> [Real; 3] {
        self.face_signs[f]
    }

    /// The vertex across each edge of triangle `f` (`None` on the boundary).
    pub fn face_opposite(&self, f: usize) -> [Option<usize>; 3] {
        self.face_opposite[f]
    }

    /// `#F` flags: whether each triangle has a vertex on the mesh boundary (an edge of one triangle).
    pub fn boundary_ring(&self) -> Vec<bool> {
        let mut on_boundary = vec![false; self.num_vertices];
        for (t, o) in self.triangles.iter().zip(&self.face_opposite) {
            for k in 0..3 {
                if o[k].is_none() {
                    on_boundary[t[k]] = true;
                    on_boundary[t[(k + 1) % 3]] = true;
                }
            }
        }
        self.triangles
            .iter()
            .map(|t| t.iter().any(|&v| on_boundary[v]))
            .collect()
    }

    /// Whether edge `e` carries a correction DOF `φ_e`.
    pub fn has_dof(&self, e: usize) -> bool {
        self.edge_dof[e].is_some()
    }

    /// The boundary treatment.
    pub fn boundary(&self) -> BoundaryEdges {
        self.boundary
    }

    /// Checks `x` (`#V` finite positions) and that no triangle is degenerate.
    fn check(&self, x: &[Vec3]) -> Result<(), MidEdgeError> {
        if x.len() != self.num_vertices {
            return Err(MidEdgeError::Input(format!(
                "{} positions for {} vertices",
                x.len(),
                self.num_vertices
            )));
        }
        if let Some(v) = x.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(MidEdgeError::Input(format!("vertex {v} is not finite")));
        }
        for (f, t) in self.triangles.iter().enumerate() {
            let [a, b, c] = t.map(|v| x[v]);
            let longest = (b - a)
                .norm_squared()
                .max((c - b).norm_squared())
                .max((a - c).norm_squared());
            let twice_area = (b - a).cross(&(c - a)).norm();
            if !(twice_area > 1e-12 * longest && longest > 0.0) {
                return Err(MidEdgeError::Degenerate(f));
            }
        }
        Ok(())
    }

    /// `θ` of every edge (rad) at positions `x`.
    fn bending_angles(&self, x: &[Vec3]) -> Vec<Real> {
        let mut theta = vec![0.0; self.edges.len()];
        for f in 0..self.triangles.len() {
            let (c, y) = local_values(self, x, f);
            let g = face_geometry(&c, &y);
            for k in 0..3 {
                if self.face_signs[f][k] > 0.0 {
                    theta[self.face_edges[f][k]] = g.theta[k].v;
                }
            }
        }
        theta
    }

    /// `a_k = θ_k/2 + s_k φ_k` of triangle `f` (rad) from the edge values `theta`, `phi` (`#E`).
    pub fn face_angles(&self, f: usize, theta: &[Real], phi: &[Real]) -> [Real; 3] {
        [0, 1, 2].map(|k| {
            let e = self.face_edges[f][k];
            0.5 * theta[e] + self.face_signs[f][k] * phi[e]
        })
    }

    /// `ψ̃ = Σ_f A_f tr(Λ_f²) + δ|φ|²` (dimensionless) and its gradient in `φ` (`#E`, zero on edges
    /// without DOF), at positions `x` and corrections `phi` (`#E`, rad).
    pub fn energy(&self, x: &[Vec3], phi: &[Real]) -> Result<(Real, Vec<Real>), MidEdgeError> {
        self.check(x)?;
        if phi.len() != self.edges.len() {
            return Err(MidEdgeError::Input(format!(
                "{} corrections for {} edges",
                phi.len(),
                self.edges.len()
            )));
        }
        let theta = self.bending_angles(x);
        let mut psi = 0.0;
        let mut grad = vec![0.0; self.edges.len()];
        for f in 0..self.triangles.len() {
            let (c, y) = local_values(self, x, f);
            let g = face_geometry(&c, &y);
            let a = self.face_angles(f, &theta, phi);
            for i in 0..3 {
                let ka: Real = (0..3).map(|j| g.k[i][j].v * a[j]).sum();
                psi += a[i] * ka;
                let e = self.face_edges[f][i];
                if self.edge_dof[e].is_some() {
                    grad[e] += 2.0 * self.face_signs[f][i] * ka;
                }
            }
        }
        for (e, p) in phi.iter().enumerate() {
            if self.edge_dof[e].is_some() {
                psi += TIKHONOV * p * p;
                grad[e] += 2.0 * TIKHONOV * p;
            }
        }
        Ok((psi, grad))
    }

    /// Solves for `φ*` at positions `x` (`#V × 3`, m): the minimiser of `ψ̃`.
    pub fn solve(&self, x: &[Vec3]) -> Result<MidEdgeSolution, MidEdgeError> {
        self.check(x)?;
        let theta = self.bending_angles(x);
        let n = self.num_dofs;
        let mut triplets = Vec::with_capacity(9 * self.triangles.len() + n);
        let mut rhs = faer::Mat::<Real>::zeros(n.max(1), 1);
        for f in 0..self.triangles.len() {
            let (c, y) = local_values(self, x, f);
            let g = face_geometry(&c, &y);
            let s = self.face_signs[f];
            for i in 0..3 {
                let Some(di) = self.edge_dof[self.face_edges[f][i]] else {
                    continue;
                };
                // ∂ψ_f/∂φ_i at φ = 0: 2 s_i Σ_j K_ij θ_j/2.
                let b: Real = (0..3)
                    .map(|j| g.k[i][j].v * 0.5 * theta[self.face_edges[f][j]])
                    .sum();
                rhs[(di, 0)] -= 2.0 * s[i] * b;
                for j in 0..3 {
                    if let Some(dj) = self.edge_dof[self.face_edges[f][j]] {
                        triplets.push(Triplet::new(di, dj, 2.0 * s[i] * s[j] * g.k[i][j].v));
                    }
                }
            }
        }
        let mut phi = vec![0.0; self.edges.len()];
        let factor = if n == 0 {
            None
        } else {
            for d in 0..n {
                triplets.push(Triplet::new(d, d, 2.0 * TIKHONOV));
            }
            let h = SparseColMat::<usize, Real>::try_new_from_triplets(n, n, &triplets)
                .map_err(|e| MidEdgeError::Solve(format!("{e:?}")))?;
            let llt = h
                .sp_cholesky(faer::Side::Lower)
                .map_err(|e| MidEdgeError::Solve(format!("{e:?}")))?;
            let sol = llt.solve(&rhs);
            for (e, d) in self.edge_dof.iter().enumerate() {
                if let Some(d) = d {
                    phi[e] = sol[(*d, 0)];
                }
            }
            if phi.iter().any(|p| !p.is_finite()) {
                return Err(MidEdgeError::Solve("the corrections are not finite".into()));
            }
            Some(llt)
        };
        Ok(MidEdgeSolution { theta, phi, factor })
    }
}

/// `φ*` at one set of positions, with the factored Hessian for adjoint solves.
pub struct MidEdgeSolution {
    /// `#E` bending angles `θ` (rad).
    pub theta: Vec<Real>,
    /// `#E` corrections `φ*` (rad), 0 on edges without a DOF.
    pub phi: Vec<Real>,
    factor: Option<faer::sparse::linalg::solvers::Llt<usize, Real>>,
}

impl std::fmt::Debug for MidEdgeSolution {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MidEdgeSolution")
            .field("theta", &self.theta)
            .field("phi", &self.phi)
            .finish_non_exhaustive()
    }
}

impl MidEdgeSolution {
    /// Solves `H̃ μ = rhs` in place (`#E` entries indexed by edge; entries of edges without a DOF are
    /// ignored on entry and zero on return), `H̃ = ∂²ψ̃/∂φ²` at the solved positions.
    pub fn adjoint_solve(&self, op: &MidEdgeShapeOperator, rhs: &mut [Real]) {
        self.adjoint_solve_many(op, rhs, 1);
    }

    /// [`Self::adjoint_solve`] for `count` right-hand sides stored one after the other (`count × #E`).
    pub fn adjoint_solve_many(&self, op: &MidEdgeShapeOperator, rhs: &mut [Real], count: usize) {
        let ne = op.edges.len();
        let Some(llt) = &self.factor else {
            rhs.fill(0.0);
            return;
        };
        let mut b = faer::Mat::<Real>::zeros(op.num_dofs, count);
        for c in 0..count {
            for (e, d) in op.edge_dof.iter().enumerate() {
                if let Some(d) = d {
                    b[(*d, c)] = rhs[c * ne + e];
                }
            }
        }
        let sol = llt.solve(&b);
        for c in 0..count {
            for (e, d) in op.edge_dof.iter().enumerate() {
                rhs[c * ne + e] = d.map_or(0.0, |d| sol[(d, c)]);
            }
        }
    }

    /// The nonzero entries `(edge e, vertex v, ∂²ψ̃/∂φ_e∂x_v)` (1/m) at positions `x`, for edges with a
    /// DOF; several entries for one pair add up.
    #[allow(clippy::needless_range_loop)] // parallel per-triangle arrays
    pub fn mixed_entries(
        &self,
        op: &MidEdgeShapeOperator,
        x: &[Vec3],
    ) -> Vec<(usize, usize, Vec3)> {
        let mut out = Vec::with_capacity(op.triangles.len() * 18);
        for f in 0..op.triangles.len() {
            let (c, y) = local_duals::<18>(op, x, f);
            let g = face_geometry(&c, &y);
            let s = op.face_signs[f];
            let a: [Dual<18>; 3] =
                [0, 1, 2].map(|k| g.theta[k] * 0.5 + s[k] * self.phi[op.face_edges[f][k]]);
            let verts: [Option<usize>; 6] = [
                Some(op.triangles[f][0]),
                Some(op.triangles[f][1]),
                Some(op.triangles[f][2]),
                op.face_opposite[f][0],
                op.face_opposite[f][1],
                op.face_opposite[f][2],
            ];
            for i in 0..3 {
                let e = op.face_edges[f][i];
                if op.edge_dof[e].is_none() {
                    continue;
                }
                // ∂ψ_f/∂φ_i = 2 s_i Σ_j K_ij a_j.
                let mut d = Dual::<18>::constant(0.0);
                for j in 0..3 {
                    d = d + g.k[i][j] * a[j];
                }
                let d = d * (2.0 * s[i]);
                for (slot, v) in verts.iter().enumerate() {
                    if let Some(v) = v {
                        let grad = Vec3::new(d.d[3 * slot], d.d[3 * slot + 1], d.d[3 * slot + 2]);
                        out.push((e, *v, grad));
                    }
                }
            }
        }
        out
    }

    /// Adds `−μᵀ ∂²ψ̃/∂φ∂x` (`μ` indexed by edge, `#E`) into `out` (`#V`): the correction's share of a
    /// total derivative, `(∂φ/∂x)ᵀ ∂T/∂φ` with `μ = H̃⁻¹ ∂T/∂φ`.
    pub fn add_adjoint_product(
        &self,
        op: &MidEdgeShapeOperator,
        x: &[Vec3],
        mu: &[Real],
        out: &mut [Vec3],
    ) {
        for (e, v, d) in self.mixed_entries(op, x) {
            out[v] -= d * mu[e];
        }
    }

    /// The shape operator `Λ_f` (3 × 3, 1/m) of triangle `f` at positions `x`.
    pub fn shape_operator(&self, op: &MidEdgeShapeOperator, x: &[Vec3], f: usize) -> Mat3 {
        let t = op.triangles[f];
        let [p0, p1, p2] = t.map(|v| x[v]);
        let normal = (p1 - p0).cross(&(p2 - p0));
        let area = 0.5 * normal.norm();
        let n = normal / (2.0 * area);
        let a = op.face_angles(f, &self.theta, &self.phi);
        let corners = [p0, p1, p2];
        let mut m = Mat3::zeros();
        for k in 0..3 {
            let e = corners[(k + 1) % 3] - corners[k];
            let tk = e.cross(&n);
            m += tk * tk.transpose() * (a[k] / (area * e.norm()));
        }
        m
    }
}

#[cfg(test)]
mod tests;
