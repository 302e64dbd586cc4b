//! Y2V: the mesh shape that best explains a yarn pose (the knitwear paper, Sec. 5, Eq. 6):
//!
//! ```text
//! φʸ²ⱽ(xʸ) = argmin_x  Σₑ Vₑ ‖𝒟(Bₑ x) − Fₑʸ²ⱽ(xʸ)‖²_F  +  α ‖N x − xʸ‖²_W
//! ```
//!
//! - `x`: mesh node positions, `#V × 3` (m); `xʸ`: yarn vertex positions, `#Y × 3` (m);
//! - `𝒟(Bₑ x) = Σₖ xₖ ∇Nₖᵀ`: the deformation gradient of the linear tetrahedron `e` (`∇Nₖ`, 1/m, the
//!   gradients of its barycentric coordinates at rest), `Vₑ` its rest volume (m³), `Fₑʸ²ⱽ` its target from
//!   the yarn segments inside it (Eq. 5, [`crate::element_deformation`]). This term is in m³;
//! - `N x`: the mesh-to-yarn map V2Y (Eq. 4), the barycentric interpolation at each embedded yarn vertex;
//! - `‖r‖²_W = Σⱼ βⱼ |rⱼ|²`, the mass-weighted position term. The paper writes `‖N Mⱽ x − Mʸ xʸ‖²` and
//!   calls it "a mass-weighted regularization penalty"; read literally it is not zero for the rest pose
//!   (the node masses interpolated to a yarn vertex are not that vertex's mass), so we take the weighted
//!   form, which any `x` with `N x = xʸ` zeroes. The weights are `βⱼ = (mⱼ / Σmʸ) · V / h²` (m): the yarn
//!   vertex masses `mⱼ` (uniform linear density, so `mⱼ ∝` the vertex's rest Voronoi length and the
//!   density cancels) as a share of the mesh volume `V`, over the squared element size
//!   `h = (6 V / #T)^{1/3}` (m; the voxel size of a six-tetrahedra-a-voxel mesh). The term is then in m³
//!   like the first, and `α` (dimensionless, 0.1 as in the paper) weighs a uniform position error of one
//!   voxel against a uniform deformation-gradient error of 1, whatever the unit of length.
//!
//! Both terms are quadratic in `x` and separate by coordinate, so the minimizer solves `K x_c = b_c` for
//! each coordinate `c` with one `#V × #V` matrix `K = Σₑ Vₑ Gₑᵀ Gₑ + α Nᵀ W N` (`Gₑ = [∇N₀ … ∇N₃]`) that
//! depends only on the mesh and the embedding: it is factored once in [`ShapeFit::new`] (sparse Cholesky)
//! and every frame costs the targets, the right-hand sides and two triangular solves with three columns.
//! `K` is positive definite when every node belongs to an element and every connected part holds an
//! embedded yarn vertex (barycentric rows sum to 1, so the position term fixes the rigid translation that
//! the deformation term leaves free).
//!
//! The same error measure is the loss of the elasticity fit (Eq. 10): [`ShapeFit::error`] evaluates it
//! for any `x` and [`ShapeFit::error_gradient`] gives `∂/∂x = 2 (K x − b)` (m²), derived from the residual
//! form term by term (`∂/∂xₖ Vₑ ‖F − Fₑ‖² = 2 Vₑ (F − Fₑ) ∇Nₖ`, `∂/∂xₖ βⱼ |N x − xⱼ|² = 2 βⱼ wₖ (N x − xⱼ)`)
//! and checked against central differences; the Hessian is the constant `2K`
//! ([`ShapeFit::error_hessian_product`]).

use faer::sparse::{SparseColMat, Triplet};
use nalgebra::{Matrix3, Vector3};
use skintight_knit::frame_sequence::YarnRange;
use skintight_physics::{SparseCholesky, SparseCholeskyParams};

use crate::element_deformation::ElementAverage;
use crate::material_frame::{DirectorTransport, YarnPose};
use crate::segment_clipping::segment_lengths_in_tets;
use crate::segment_deformation::{rest_frame_inverse, segment_deformation};
use crate::shape_fit_error::ShapeFitError;
use crate::volumetric_mesh::{Embedded, VolumetricMesh};

/// Settings of shape fitting.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct ShapeFitParams {
    /// `α` of Eq. 6: the weight of the position term against the deformation term (dimensionless; see
    /// the module documentation for the scaling that makes it so). Default 0.1 (the paper).
    pub alpha: f64,
    /// Karcher-mean steps after the paper's log-average of the rotations in Eq. 5 (0: the paper's formula
    /// verbatim). Default 16 (it stops earlier once a step is below 1e-14 rad).
    pub karcher_iterations: usize,
    /// The sparse Cholesky factorization's settings.
    pub cholesky: SparseCholeskyParams,
}

impl Default for ShapeFitParams {
    fn default() -> Self {
        Self {
            alpha: 0.1,
            karcher_iterations: 16,
            cholesky: SparseCholeskyParams::default(),
        }
    }
}

/// What Y2V fits for one yarn pose: the elements' target deformation gradients and the yarn positions.
#[derive(Clone, Debug, PartialEq)]
pub struct FitTarget {
    /// `Fₑʸ²ⱽ` per element (Eq. 5), `#T` (dimensionless).
    pub elements: Vec<Matrix3<f64>>,
    /// Yarn vertex positions `xʸ`, `#Y × 3` (m).
    pub yarn: Vec<[f64; 3]>,
}

/// Y2V for one mesh: the factored system of Eq. 6 and everything per frame needs.
pub struct ShapeFit {
    params: ShapeFitParams,
    tets: Vec<[usize; 4]>,
    /// Per element the barycentric gradients `∇N₀..₃` (1/m).
    gradients: Vec<[Vector3<f64>; 4]>,
    /// Rest volumes `Vₑ` (m³).
    volumes: Vec<f64>,
    embedding: Vec<Embedded>,
    /// `α βⱼ` per yarn vertex (m).
    yarn_weights: Vec<f64>,
    /// The director transport at the rest pose, cloned for each sequence.
    rest_transport: DirectorTransport,
    /// Per segment `[x̄₁ − x̄₀, n̄₁, n̄₂]⁻¹`.
    rest_inverse: Vec<Matrix3<f64>>,
    average: ElementAverage,
    cholesky: SparseCholesky,
    /// The lower triangle of `K` (for the Hessian product).
    lower: Vec<(usize, usize, f64)>,
    node_count: usize,
    analyses: usize,
    factorizations: usize,
}

impl std::fmt::Debug for ShapeFit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShapeFit")
            .field("nodes", &self.node_count)
            .field("elements", &self.tets.len())
            .field("yarn_vertices", &self.embedding.len())
            .field("params", &self.params)
            .finish_non_exhaustive()
    }
}

fn check_finite(
    what: &'static str,
    values: impl Iterator<Item = f64>,
) -> Result<(), ShapeFitError> {
    for (index, value) in values.enumerate() {
        if !value.is_finite() {
            return Err(ShapeFitError::NotFinite { what, index, value });
        }
    }
    Ok(())
}

impl ShapeFit {
    /// Builds and factors Y2V for `mesh` around the yarns `yarns` at rest pose `rest` (`#Y` rows: x, y, z in
    /// m, θ in rad; the pose the mesh was built around, whose vertices `mesh.embedding` embeds).
    pub fn new(
        mesh: &VolumetricMesh,
        yarns: &[YarnRange],
        rest: &[[f64; 4]],
        params: ShapeFitParams,
    ) -> Result<Self, ShapeFitError> {
        if !(params.alpha > 0.0 && params.alpha.is_finite()) {
            return Err(ShapeFitError::Param {
                name: "alpha",
                value: params.alpha,
                problem: "must be a positive finite number (the paper uses 0.1)",
            });
        }
        let n = mesh.rest.len();
        check_finite("mesh node coordinate", mesh.rest.iter().flatten().copied())?;
        if mesh.tets.is_empty() {
            return Err(ShapeFitError::Mesh {
                problem: "has no tetrahedra".into(),
            });
        }
        let mut used = vec![false; n];
        let mut gradients = Vec::with_capacity(mesh.tets.len());
        let mut volumes = Vec::with_capacity(mesh.tets.len());
        for (e, t) in mesh.tets.iter().enumerate() {
            if let Some(&v) = t.iter().find(|&&v| v >= n) {
                return Err(ShapeFitError::Mesh {
                    problem: format!("tetrahedron {e} names node {v} of {n}"),
                });
            }
            let p = |k: usize| Vector3::from(mesh.rest[t[k]]);
            let d = Matrix3::from_columns(&[p(1) - p(0), p(2) - p(0), p(3) - p(0)]);
            let volume = d.determinant() / 6.0;
            let inv = d.try_inverse().filter(|_| volume > 0.0).ok_or_else(|| ShapeFitError::Mesh {
                problem: format!(
                    "tetrahedron {e} has rest volume {volume:e} m³; every element must be positively \
                     oriented and non-degenerate"
                ),
            })?;
            // ∇N₁..₃ are the rows of D⁻¹; ∇N₀ = −Σ.
            let g1 = inv.row(0).transpose();
            let g2 = inv.row(1).transpose();
            let g3 = inv.row(2).transpose();
            gradients.push([-(g1 + g2 + g3), g1, g2, g3]);
            volumes.push(volume);
            for &v in t {
                used[v] = true;
            }
        }
        if let Some(v) = used.iter().position(|u| !u) {
            return Err(ShapeFitError::Mesh {
                problem: format!("node {v} belongs to no tetrahedron; remove unused nodes"),
            });
        }
        if mesh.embedding.len() != rest.len() {
            return Err(ShapeFitError::Count {
                what: "the mesh's embedding",
                got: mesh.embedding.len(),
                expected: rest.len(),
                per: "yarn vertex of the rest pose",
            });
        }
        for (j, em) in mesh.embedding.iter().enumerate() {
            if em.tet >= mesh.tets.len() {
                return Err(ShapeFitError::Mesh {
                    problem: format!(
                        "embeds yarn vertex {j} in tetrahedron {} of {}",
                        em.tet,
                        mesh.tets.len()
                    ),
                });
            }
            check_finite("embedding weight", em.weights.iter().copied())?;
        }
        let mut transport = DirectorTransport::new(yarns, rest)?;
        let rest_pose = transport.pose(rest)?;
        let edges = transport.edges().to_vec();
        let mut rest_inverse = Vec::with_capacity(edges.len());
        for (s, frame) in rest_pose.segments.iter().enumerate() {
            rest_inverse.push(rest_frame_inverse(frame).ok_or(
                ShapeFitError::DegenerateSegment {
                    segment: s,
                    from: edges[s][0],
                    to: edges[s][1],
                    length_m: frame.edge.norm(),
                },
            )?);
        }
        let segments: Vec<[[f64; 3]; 2]> = edges
            .iter()
            .map(|&[a, b]| [rest_pose.positions[a], rest_pose.positions[b]])
            .collect();
        let lengths = segment_lengths_in_tets(&mesh.rest, &mesh.tets, &segments);
        let average = ElementAverage::new(&mesh.tets, n, lengths)?;

        // Yarn vertex masses ∝ rest Voronoi lengths (half of each adjacent segment).
        let mut voronoi = vec![0.0; rest.len()];
        for &[a, b] in &edges {
            let l = (Vector3::from(rest_pose.positions[b]) - Vector3::from(rest_pose.positions[a]))
                .norm();
            voronoi[a] += 0.5 * l;
            voronoi[b] += 0.5 * l;
        }
        let total_length: f64 = voronoi.iter().sum();
        let total_volume: f64 = volumes.iter().sum();
        let h = (6.0 * total_volume / mesh.tets.len() as f64).cbrt();
        let yarn_weights: Vec<f64> = voronoi
            .iter()
            .map(|l| params.alpha * l / total_length * total_volume / (h * h))
            .collect();

        // K, lower triangle.
        let mut triplets = Vec::with_capacity(10 * mesh.tets.len() + 10 * rest.len());
        let mut push = |a: usize, b: usize, v: f64| {
            // One entry per unordered pair (l ≤ k below), stored in the lower triangle.
            let (r, c) = if a >= b { (a, b) } else { (b, a) };
            triplets.push(Triplet::new(r, c, v));
        };
        for (e, t) in mesh.tets.iter().enumerate() {
            for k in 0..4 {
                for l in 0..=k {
                    push(
                        t[k],
                        t[l],
                        volumes[e] * gradients[e][k].dot(&gradients[e][l]),
                    );
                }
            }
        }
        for (j, em) in mesh.embedding.iter().enumerate() {
            let t = mesh.tets[em.tet];
            for k in 0..4 {
                for l in 0..=k {
                    push(t[k], t[l], yarn_weights[j] * em.weights[k] * em.weights[l]);
                }
            }
        }
        let lower: Vec<(usize, usize, f64)> =
            triplets.iter().map(|t| (t.row, t.col, t.val)).collect();
        let k =
            SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).map_err(|e| {
                ShapeFitError::Mesh {
                    problem: format!("gives a Y2V matrix that cannot be assembled: {e:?}"),
                }
            })?;
        let mut cholesky =
            SparseCholesky::analyze(k.as_ref(), &params.cholesky).map_err(ShapeFitError::Solver)?;
        cholesky
            .factorize(k.as_ref())
            .map_err(ShapeFitError::Solver)?;
        Ok(Self {
            params,
            tets: mesh.tets.clone(),
            gradients,
            volumes,
            embedding: mesh.embedding.clone(),
            yarn_weights,
            rest_transport: transport,
            rest_inverse,
            average,
            cholesky,
            lower,
            node_count: n,
            analyses: 1,
            factorizations: 1,
        })
    }

    /// The settings.
    pub fn params(&self) -> &ShapeFitParams {
        &self.params
    }

    /// A fresh director transport at the rest pose: feed it a sequence's frames in order
    /// ([`DirectorTransport::pose`]) to get the poses [`Self::fit`] takes.
    pub fn transport(&self) -> DirectorTransport {
        self.rest_transport.clone()
    }

    /// Symbolic analyses of `K` done (1: in [`Self::new`]; frames never redo it).
    pub fn analyses(&self) -> usize {
        self.analyses
    }

    /// Numeric factorizations of `K` done (1: in [`Self::new`]; frames never redo it).
    pub fn factorizations(&self) -> usize {
        self.factorizations
    }

    /// The fit target of a pose: the elements' deformation gradients (Eq. 5) and the yarn positions.
    pub fn target(&self, pose: &YarnPose) -> Result<FitTarget, ShapeFitError> {
        if pose.positions.len() != self.embedding.len() {
            return Err(ShapeFitError::Count {
                what: "the pose's positions",
                got: pose.positions.len(),
                expected: self.embedding.len(),
                per: "yarn vertex",
            });
        }
        if pose.segments.len() != self.rest_inverse.len() {
            return Err(ShapeFitError::Count {
                what: "the pose's segments",
                got: pose.segments.len(),
                expected: self.rest_inverse.len(),
                per: "yarn segment",
            });
        }
        check_finite(
            "pose position coordinate",
            pose.positions.iter().flatten().copied(),
        )?;
        check_finite(
            "pose segment frame entry",
            pose.segments
                .iter()
                .flat_map(|s| s.matrix().iter().copied().collect::<Vec<_>>()),
        )?;
        let segment_f: Vec<Matrix3<f64>> = self
            .rest_inverse
            .iter()
            .zip(&pose.segments)
            .map(|(inv, s)| segment_deformation(inv, s))
            .collect();
        Ok(FitTarget {
            elements: self
                .average
                .targets(&segment_f, self.params.karcher_iterations),
            yarn: pose.positions.clone(),
        })
    }

    fn check_target(&self, target: &FitTarget) -> Result<(), ShapeFitError> {
        if target.elements.len() != self.tets.len() {
            return Err(ShapeFitError::Count {
                what: "the target's element deformation gradients",
                got: target.elements.len(),
                expected: self.tets.len(),
                per: "tetrahedron",
            });
        }
        if target.yarn.len() != self.embedding.len() {
            return Err(ShapeFitError::Count {
                what: "the target's yarn positions",
                got: target.yarn.len(),
                expected: self.embedding.len(),
                per: "yarn vertex",
            });
        }
        check_finite(
            "target deformation-gradient entry",
            target
                .elements
                .iter()
                .flat_map(|f| f.iter().copied().collect::<Vec<_>>()),
        )?;
        check_finite(
            "target yarn coordinate",
            target.yarn.iter().flatten().copied(),
        )
    }

    /// The right-hand sides `b`, column-major `#V × 3` (m²).
    fn rhs(&self, target: &FitTarget) -> Vec<f64> {
        let n = self.node_count;
        let mut b = vec![0.0; 3 * n];
        for (e, t) in self.tets.iter().enumerate() {
            let f = &target.elements[e];
            for k in 0..4 {
                let g = self.volumes[e] * (f * self.gradients[e][k]);
                for c in 0..3 {
                    b[c * n + t[k]] += g[c];
                }
            }
        }
        for (j, em) in self.embedding.iter().enumerate() {
            let t = self.tets[em.tet];
            for k in 0..4 {
                for c in 0..3 {
                    b[c * n + t[k]] += self.yarn_weights[j] * em.weights[k] * target.yarn[j][c];
                }
            }
        }
        b
    }

    /// The minimizer of Eq. 6 for `target`: node positions, `#V × 3` (m). Two triangular solves with the
    /// factorization from [`Self::new`].
    pub fn solve(&self, target: &FitTarget) -> Result<Vec<[f64; 3]>, ShapeFitError> {
        self.check_target(target)?;
        let n = self.node_count;
        let mut x = self.rhs(target);
        self.cholesky
            .solve_columns_in_place(&mut x, 3)
            .map_err(ShapeFitError::Solver)?;
        Ok((0..n).map(|v| [x[v], x[n + v], x[2 * n + v]]).collect())
    }

    /// Y2V of a pose (Eq. 5 then Eq. 6): node positions, `#V × 3` (m).
    pub fn fit(&self, pose: &YarnPose) -> Result<Vec<[f64; 3]>, ShapeFitError> {
        self.solve(&self.target(pose)?)
    }

    fn check_x(&self, x: &[f64]) -> Result<(), ShapeFitError> {
        if x.len() != 3 * self.node_count {
            return Err(ShapeFitError::Count {
                what: "the node positions",
                got: x.len(),
                expected: 3 * self.node_count,
                per: "node coordinate (3 per node, flattened)",
            });
        }
        check_finite("node coordinate", x.iter().copied())
    }

    /// The error of Eq. 6 (the loss ε of Eq. 10) of node positions `x` (flattened `3#V`, node-major, m)
    /// against `target` (m³).
    pub fn error(&self, target: &FitTarget, x: &[f64]) -> Result<f64, ShapeFitError> {
        self.check_target(target)?;
        self.check_x(x)?;
        let node = |v: usize| Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
        let mut sum = 0.0;
        for (e, t) in self.tets.iter().enumerate() {
            let f: Matrix3<f64> = (0..4)
                .map(|k| node(t[k]) * self.gradients[e][k].transpose())
                .sum();
            sum += self.volumes[e] * (f - target.elements[e]).norm_squared();
        }
        for (j, em) in self.embedding.iter().enumerate() {
            let t = self.tets[em.tet];
            let p: Vector3<f64> = (0..4).map(|k| node(t[k]) * em.weights[k]).sum();
            sum += self.yarn_weights[j] * (p - Vector3::from(target.yarn[j])).norm_squared();
        }
        Ok(sum)
    }

    /// `∂ error / ∂x`, flattened `3#V` like `x` (m²).
    pub fn error_gradient(&self, target: &FitTarget, x: &[f64]) -> Result<Vec<f64>, ShapeFitError> {
        self.check_target(target)?;
        self.check_x(x)?;
        let node = |v: usize| Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
        let mut g = vec![0.0; x.len()];
        for (e, t) in self.tets.iter().enumerate() {
            let f: Matrix3<f64> = (0..4)
                .map(|k| node(t[k]) * self.gradients[e][k].transpose())
                .sum();
            let r = (f - target.elements[e]) * (2.0 * self.volumes[e]);
            for k in 0..4 {
                let d = r * self.gradients[e][k];
                for c in 0..3 {
                    g[3 * t[k] + c] += d[c];
                }
            }
        }
        for (j, em) in self.embedding.iter().enumerate() {
            let t = self.tets[em.tet];
            let p: Vector3<f64> = (0..4).map(|k| node(t[k]) * em.weights[k]).sum();
            let r = (p - Vector3::from(target.yarn[j])) * (2.0 * self.yarn_weights[j]);
            for k in 0..4 {
                for c in 0..3 {
                    g[3 * t[k] + c] += em.weights[k] * r[c];
                }
            }
        }
        Ok(g)
    }

    /// The product of the error's constant Hessian `2K ⊗ I₃` (m) with `v` (flattened `3#V`, m), in m²: the
    /// Jacobian of [`Self::error_gradient`] applied to `v`.
    pub fn error_hessian_product(&self, v: &[f64]) -> Result<Vec<f64>, ShapeFitError> {
        self.check_x(v)?;
        let mut out = vec![0.0; v.len()];
        for &(r, c, k) in &self.lower {
            for d in 0..3 {
                out[3 * r + d] += 2.0 * k * v[3 * c + d];
                if r != c {
                    out[3 * c + d] += 2.0 * k * v[3 * r + d];
                }
            }
        }
        Ok(out)
    }

    /// The error of [`Self::error`] as a sum of squares `Σ r_k²` (the residual form the elasticity fit's
    /// Gauss-Newton needs): per element the nine entries of `√Vₑ (𝒟(Bₑ x) − Fₑ)` (m^{3/2}, column-major),
    /// then per yarn vertex the three coordinates of `√(α βⱼ) (N x − xʸ)ⱼ` (m^{3/2}); `9#T + 3#Y`
    /// residuals. The second value holds the entries `(k, i, ∂r_k/∂x_i)` of their constant Jacobian
    /// (`x` flattened `3#V`; m^{1/2} per element entry, also m^{1/2} per yarn entry).
    #[allow(clippy::type_complexity)]
    pub fn error_residuals(
        &self,
        target: &FitTarget,
        x: &[f64],
    ) -> Result<(Vec<f64>, Vec<(usize, usize, f64)>), ShapeFitError> {
        self.check_target(target)?;
        self.check_x(x)?;
        let node = |v: usize| Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
        let mut r = Vec::with_capacity(9 * self.tets.len() + 3 * self.embedding.len());
        let mut jac = Vec::with_capacity(36 * self.tets.len() + 12 * self.embedding.len());
        for (e, t) in self.tets.iter().enumerate() {
            let f: Matrix3<f64> = (0..4)
                .map(|k| node(t[k]) * self.gradients[e][k].transpose())
                .sum();
            let s = self.volumes[e].sqrt();
            let d = (f - target.elements[e]) * s;
            // F_ab = Σ_k x_{k,a} ∇N_{k,b}: entry (a, b) at a + 3b.
            for b in 0..3 {
                for a in 0..3 {
                    let k = r.len();
                    r.push(d[(a, b)]);
                    for c in 0..4 {
                        jac.push((k, 3 * t[c] + a, s * self.gradients[e][c][b]));
                    }
                }
            }
        }
        for (j, em) in self.embedding.iter().enumerate() {
            let t = self.tets[em.tet];
            let p: Vector3<f64> = (0..4).map(|k| node(t[k]) * em.weights[k]).sum();
            let s = self.yarn_weights[j].sqrt();
            for a in 0..3 {
                let k = r.len();
                r.push(s * (p[a] - target.yarn[j][a]));
                for c in 0..4 {
                    jac.push((k, 3 * t[c] + a, s * em.weights[c]));
                }
            }
        }
        Ok((r, jac))
    }

    /// The target that node positions `x` (flattened `3#V`, m) match exactly: each element's deformation
    /// gradient `𝒟(Bₑ x)` and V2Y of `x` (Eq. 4). A sequence generated by the mesh itself (a known
    /// material's equilibria) becomes fit targets this way; [`Self::error`] is zero at `x`.
    pub fn target_of_positions(&self, x: &[f64]) -> Result<FitTarget, ShapeFitError> {
        self.check_x(x)?;
        let node = |v: usize| Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
        let elements = self
            .tets
            .iter()
            .enumerate()
            .map(|(e, t)| {
                (0..4)
                    .map(|k| node(t[k]) * self.gradients[e][k].transpose())
                    .sum()
            })
            .collect();
        let yarn = self
            .embedding
            .iter()
            .map(|em| {
                let t = self.tets[em.tet];
                let p: Vector3<f64> = (0..4).map(|k| node(t[k]) * em.weights[k]).sum();
                [p.x, p.y, p.z]
            })
            .collect();
        Ok(FitTarget { elements, yarn })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation_average::rotation_exp;
    use crate::straight_yarn_block::{StraightYarnBlock, straight_yarn_block};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};
    use skintight_knit::frames::parallel_transport;

    fn block() -> StraightYarnBlock {
        straight_yarn_block([3, 2, 2], 2e-3, 1e-3)
    }

    /// The yarn frame after the affine map `x ↦ a x` whose linear part is `q · diag(λ, 1, 1)` (yarns along
    /// x): positions mapped, and each edge angle advanced by the twist ψ of `q` about the new tangent that
    /// twist-free transport does not carry (ψ: the signed angle from `P_{t̄→t} ū` to `q ū`, the same for
    /// every `ū ⊥ t̄`), so the material frames are those of the mapped rod.
    fn mapped(b: &StraightYarnBlock, q: &Matrix3<f64>, lambda: f64) -> Vec<[f64; 4]> {
        let a = q * Matrix3::from_diagonal(&Vector3::new(lambda, 1.0, 1.0));
        let t_rest = Vector3::x();
        let t = q * t_rest;
        let u = Vector3::y();
        let transported =
            Vector3::from(parallel_transport::<f64>(u.into(), t_rest.into(), t.into()));
        let turned = q * u;
        let psi = transported
            .cross(&turned)
            .dot(&t)
            .atan2(transported.dot(&turned));
        b.rest
            .iter()
            .map(|r| {
                let p = a * Vector3::new(r[0], r[1], r[2]);
                [p.x, p.y, p.z, r[3] + psi]
            })
            .collect()
    }

    fn node_error(
        x: &[[f64; 3]],
        expected: impl Fn(&[f64; 3]) -> Vector3<f64>,
        rest: &[[f64; 3]],
    ) -> f64 {
        x.iter()
            .zip(rest)
            .map(|(p, r)| (Vector3::from(*p) - expected(r)).norm())
            .fold(0.0, f64::max)
    }

    #[test]
    fn the_rest_pose_fits_the_rest_mesh() {
        let b = block();
        let fit = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let pose = fit.transport().pose(&b.rest).unwrap();
        let target = fit.target(&pose).unwrap();
        assert!(
            target
                .elements
                .iter()
                .all(|f| (f - Matrix3::identity()).norm() < 1e-14)
        );
        let x = fit.fit(&pose).unwrap();
        let err = node_error(&x, |r| Vector3::from(*r), &b.mesh.rest);
        assert!(err < 1e-15, "{err}");
    }

    #[test]
    fn a_stretch_along_the_yarns_and_a_rotation_are_reproduced() {
        // (a) uniform stretch along the yarns, (b) a rigid rotation, and both: every segment's Fʸ, every
        // element's target and the Y2V shape equal the imposed map (to round-off).
        let b = block();
        let fit = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let q = rotation_exp(&Vector3::new(0.5, -0.3, 0.9));
        let shift = Vector3::new(0.01, -0.02, 0.005);
        for (q, lambda) in [(Matrix3::identity(), 1.3), (q, 1.0), (q, 0.8)] {
            let a = q * Matrix3::from_diagonal(&Vector3::new(lambda, 1.0, 1.0));
            let mut rows = mapped(&b, &q, lambda);
            for r in &mut rows {
                for c in 0..3 {
                    r[c] += shift[c];
                }
            }
            let pose = fit.transport().pose(&rows).unwrap();
            let target = fit.target(&pose).unwrap();
            for f in &target.elements {
                assert!((f - a).norm() < 1e-12, "{f} vs {a}");
            }
            let x = fit.solve(&target).unwrap();
            let err = node_error(&x, |r| a * Vector3::from(*r) + shift, &b.mesh.rest);
            assert!(err < 1e-14, "λ = {lambda}: {err} m");
            // The polar factors of the targets: R = q, S = diag(λ, 1, 1).
            let p = crate::polar_decomposition::polar_decomposition(&target.elements[0]);
            assert!((p.rotation - q).norm() < 1e-12);
        }
    }

    #[test]
    fn a_transverse_stretch_is_seen_only_through_the_position_term() {
        // The segments' cross-sections are rigid (the paper's Fʸ), so a stretch across the yarns leaves
        // every target at the identity; the yarn positions still pull the nodes apart, part of the way.
        let b = block();
        let fit = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let rows: Vec<[f64; 4]> = b
            .rest
            .iter()
            .map(|r| [r[0], 1.2 * r[1], r[2], r[3]])
            .collect();
        let pose = fit.transport().pose(&rows).unwrap();
        let target = fit.target(&pose).unwrap();
        assert!(
            target
                .elements
                .iter()
                .all(|f| (f - Matrix3::identity()).norm() < 1e-12)
        );
        let x = fit.solve(&target).unwrap();
        let spread = |x: &[[f64; 3]]| {
            let ys: Vec<f64> = x.iter().map(|p| p[1]).collect();
            ys.iter().cloned().fold(f64::MIN, f64::max)
                - ys.iter().cloned().fold(f64::MAX, f64::min)
        };
        let (rest, fitted) = (spread(&b.mesh.rest), spread(&x));
        assert!(
            fitted > rest * 1.001 && fitted < rest * 1.2,
            "{rest} → {fitted}"
        );
    }

    #[test]
    fn the_solution_is_the_minimizer_and_the_error_derivatives_match_central_differences() {
        let b = straight_yarn_block([2, 1, 1], 2e-3, 1e-3);
        let fit = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let n = b.mesh.rest.len();
        for _ in 0..3 {
            let target = FitTarget {
                elements: (0..b.mesh.tets.len())
                    .map(|_| Matrix3::from_fn(|_, _| rng.random_range(-1.5..1.5)))
                    .collect(),
                yarn: b
                    .rest
                    .iter()
                    .map(|r| std::array::from_fn(|c| r[c] + rng.random_range(-5e-4..5e-4)))
                    .collect(),
            };
            let x: Vec<f64> = b
                .mesh
                .rest
                .iter()
                .flat_map(|p| p.map(|v| v + rng.random_range(-5e-4..5e-4)))
                .collect();
            let g = fit.error_gradient(&target, &x).unwrap();
            let fd = FdParams {
                step: 1e-7,
                rel_tol: 1e-6,
                abs_tol: 1e-14,
            };
            check_gradient(|x| fit.error(&target, x).unwrap(), &x, &g, &fd).unwrap();
            // The Hessian 2K, column by column from the product, against differences of the gradient.
            let mut h = vec![0.0; 9 * n * n];
            for col in 0..3 * n {
                let mut e = vec![0.0; 3 * n];
                e[col] = 1.0;
                let hc = fit.error_hessian_product(&e).unwrap();
                for row in 0..3 * n {
                    h[row * 3 * n + col] = hc[row];
                }
            }
            check_jacobian(|x| fit.error_gradient(&target, x).unwrap(), &x, &h, &fd).unwrap();
            // The factored solve zeroes the residual-form gradient: K and b agree with the error.
            let best: Vec<f64> = fit.solve(&target).unwrap().into_iter().flatten().collect();
            let g = fit.error_gradient(&target, &best).unwrap();
            let scale = fit
                .error_gradient(&target, &x)
                .unwrap()
                .iter()
                .fold(0.0_f64, |m, v| m.max(v.abs()));
            assert!(g.iter().all(|v| v.abs() < 1e-10 * scale));
            let e0 = fit.error(&target, &best).unwrap();
            for k in 0..5 {
                let d: Vec<f64> = (0..3 * n).map(|_| rng.random_range(-1e-4..1e-4)).collect();
                let moved: Vec<f64> = best
                    .iter()
                    .zip(&d)
                    .map(|(a, b)| a + b * (k + 1) as f64)
                    .collect();
                assert!(fit.error(&target, &moved).unwrap() > e0);
            }
        }
    }

    #[test]
    fn the_factorization_is_reused_across_frames() {
        let b = block();
        let fit = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        assert_eq!((fit.analyses(), fit.factorizations()), (1, 1));
        let mut transport = fit.transport();
        let mut previous = None;
        for k in 1..=5 {
            let q = rotation_exp(&Vector3::new(0.0, 0.0, 0.1 * k as f64));
            let x = fit
                .fit(
                    &transport
                        .pose(&mapped(&b, &q, 1.0 + 0.02 * k as f64))
                        .unwrap(),
                )
                .unwrap();
            assert_ne!(Some(x.clone()), previous);
            previous = Some(x);
        }
        assert_eq!((fit.analyses(), fit.factorizations()), (1, 1));
    }

    #[test]
    fn the_papers_one_step_rotation_average_agrees_near_rest() {
        // Bent and twisted yarns at amplitude ε and ε/2: the shapes move in proportion to ε, and the
        // Karcher refinement changes them at third order (the difference shrinks about 8-fold).
        let b = block();
        let paper = ShapeFitParams {
            karcher_iterations: 0,
            ..ShapeFitParams::default()
        };
        let fit0 = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, paper).unwrap();
        let fit = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let mut figures = Vec::new();
        for eps in [1.0, 0.5] {
            let rows: Vec<[f64; 4]> = b
                .rest
                .iter()
                .map(|r| {
                    let s = r[0] / 2e-3;
                    [
                        r[0],
                        r[1] + eps * 2e-4 * (2.0 * s).sin() * (1.0 + r[2] * 300.0),
                        r[2] + eps * 1e-4 * s * s,
                        r[3] + eps * 0.05 * s,
                    ]
                })
                .collect();
            let x0 = fit0.fit(&fit0.transport().pose(&rows).unwrap()).unwrap();
            let x = fit.fit(&fit.transport().pose(&rows).unwrap()).unwrap();
            let diff = node_error(&x0, |r| Vector3::from(*r), &x);
            let moved = node_error(&x, |r| Vector3::from(*r), &b.mesh.rest);
            figures.push((diff, moved));
        }
        let (d1, m1) = figures[0];
        let (d2, m2) = figures[1];
        assert!(d1 > 0.0 && d1 < 1e-2 * m1, "{d1} vs {m1}");
        assert!((m1 / m2 - 2.0).abs() < 0.2, "{m1} / {m2}");
        assert!(d1 / d2 > 6.0, "{d1} / {d2}");
    }

    #[test]
    fn bad_input_is_named_and_never_panics() {
        let b = block();
        let fit = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let mut transport = fit.transport();
        // Frames with NaN or the wrong vertex count.
        let mut nan = b.rest.clone();
        nan[7][0] = f64::NAN;
        let e = transport.pose(&nan).unwrap_err().to_string();
        assert!(e.contains("frame row (yarn vertex) 7 is not finite"), "{e}");
        let e = transport.pose(&b.rest[1..]).unwrap_err().to_string();
        assert!(e.contains("the frame has"), "{e}");
        let mut pose = transport.pose(&b.rest).unwrap();
        pose.positions.pop();
        let e = fit.fit(&pose).unwrap_err().to_string();
        assert!(e.contains("the pose's positions"), "{e}");
        let mut pose = transport.pose(&b.rest).unwrap();
        pose.segments[2].normals[0].x = f64::INFINITY;
        let e = fit.fit(&pose).unwrap_err().to_string();
        assert!(e.contains("pose segment frame entry"), "{e}");
        let target = fit.target(&transport.pose(&b.rest).unwrap()).unwrap();
        let e = fit.error(&target, &[0.0; 5]).unwrap_err().to_string();
        assert!(e.contains("node positions"), "{e}");
        // Parameters and meshes.
        for alpha in [0.0, -1.0, f64::NAN] {
            let p = ShapeFitParams {
                alpha,
                ..ShapeFitParams::default()
            };
            let e = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, p)
                .unwrap_err()
                .to_string();
            assert!(e.contains("alpha"), "{e}");
        }
        let e = ShapeFit::new(&b.mesh, &b.yarns, &b.rest[..10], ShapeFitParams::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("embedding"), "{e}");
        let mut mesh = b.mesh.clone();
        mesh.tets[3].swap(0, 1);
        let e = ShapeFit::new(&mesh, &b.yarns, &b.rest, ShapeFitParams::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("tetrahedron 3"), "{e}");
        let mut mesh = b.mesh.clone();
        mesh.rest.push([0.0; 3]);
        mesh.node_mass.push(0.0);
        let e = ShapeFit::new(&mesh, &b.yarns, &b.rest, ShapeFitParams::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("belongs to no tetrahedron"), "{e}");
        let mut mesh = b.mesh.clone();
        mesh.embedding[0].tet = 10_000;
        let e = ShapeFit::new(&mesh, &b.yarns, &b.rest, ShapeFitParams::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("yarn vertex 0"), "{e}");
        let mut mesh = b.mesh.clone();
        mesh.rest[4][2] = f64::NAN;
        let e = ShapeFit::new(&mesh, &b.yarns, &b.rest, ShapeFitParams::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("mesh node coordinate 14"), "{e}");
        // A second block beside the first, with no yarn: refused, not singular.
        let mut mesh = b.mesh.clone();
        let offset = mesh.rest.len();
        mesh.rest
            .extend(b.mesh.rest.iter().map(|p| [p[0] + 1.0, p[1], p[2]]));
        mesh.node_mass.extend(b.mesh.node_mass.iter());
        mesh.tets
            .extend(b.mesh.tets.iter().map(|t| t.map(|v| v + offset)));
        let e = ShapeFit::new(&mesh, &b.yarns, &b.rest, ShapeFitParams::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("connected part without yarn"), "{e}");
    }

    #[test]
    fn the_residual_form_sums_to_the_error_and_its_jacobian_gives_the_gradient() {
        let b = block();
        let fit = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(43);
        let x: Vec<f64> = b
            .mesh
            .rest
            .iter()
            .flatten()
            .map(|v| v * 1.1 + rng.random_range(-2e-4..2e-4))
            .collect();
        let target = fit
            .target_of_positions(
                &b.mesh
                    .rest
                    .iter()
                    .flatten()
                    .map(|v| v + rng.random_range(-1e-4..1e-4))
                    .collect::<Vec<_>>(),
            )
            .unwrap();
        let (r, jac) = fit.error_residuals(&target, &x).unwrap();
        let sum: f64 = r.iter().map(|v| v * v).sum();
        let error = fit.error(&target, &x).unwrap();
        assert!((sum - error).abs() <= 1e-12 * error, "{sum} vs {error}");
        let mut g = vec![0.0; x.len()];
        for &(k, i, v) in &jac {
            g[i] += 2.0 * r[k] * v;
        }
        let want = fit.error_gradient(&target, &x).unwrap();
        let scale = want.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        for (a, w) in g.iter().zip(&want) {
            assert!((a - w).abs() <= 1e-12 * scale, "{a} vs {w}");
        }
        // The target of x itself is matched exactly.
        let own = fit.target_of_positions(&x).unwrap();
        assert!(fit.error(&own, &x).unwrap() < 1e-24);
        assert!(fit.target_of_positions(&x[1..]).is_err());
    }
}
