//! The global step of projective dynamics (the knitwear paper, Eq. 27–28): with every element's target
//! `P_e` held fixed by the local step, the positions minimize the quadratic
//!
//! ```text
//! Φ(x) = 1/(2Δt²) Σ_v m_v |x_v − y_v|² + Σ_e ½ ω_e ‖F_e(x) − P_e‖²_F − Σ_v f_v · x_v,
//! F_e(x) = Σ_a x_a ⊗ g_a      (a over the four corners, g_a = ∇ of corner a's barycentric function),
//! ```
//!
//! with `y = x* + Δt ẋ*` the inertial target of Eq. 25 (m), `m_v` the lumped masses (kg), `f` the external
//! forces (N), `ω_e` the element weight (J) and `P_e` its target. The material of Eq. 7 is this form with
//! `ω_e = 2 V_e (γˢ_e + γᵛ_e)` and `P_e = (γˢ_e R_e + γᵛ_e V_e) / (γˢ_e + γᵛ_e)`, which differs from the two
//! separate terms by a constant only (complete the square), so the caller decides the energy's convention.
//!
//! **Three scalar systems.** Row `i` of `F_e` is `Σ_a g_a x_{a,i}`, so `Φ` splits into one quadratic per
//! coordinate with the same matrix:
//!
//! ```text
//! K = M / Δt² + Σ_e ω_e G_eᵀ G_e,      K_ab += ω_e g_a · g_b       (#V × #V, N/m),
//! b_i = M y_i / Δt² + f_i + Σ_e ω_e G_eᵀ (P_e)_{i,:}              (N),
//! ```
//!
//! `K X = B` with three right-hand sides — a third of the unknowns and a ninth of the entries of the
//! `3#V` system of Eq. 27, and one factorization. Clamped nodes (their positions prescribed, moving or
//! not) are eliminated: their columns move to the right-hand side. `K` depends on the mesh, `ω` and `Δt`
//! only, so it is factored once by [`GlobalStep::new`] (analyze, factorize) and every PD iteration of
//! every step costs three triangular solves. `Δt = ∞` drops the mass term: the quasi-static problem,
//! which needs at least one clamped node in each connected part of the mesh.
//!
//! **Point constraints.** [`GlobalStep::with_points`] adds `Σ_j ½ w ‖N_j x − p_j‖²` over the *active*
//! embedded points `N_j x = Σ_a b_{j,a} x_a` (a yarn vertex in its tetrahedron, barycentric `b_j`) with
//! targets `p_j` (m) and one weight `w` (N/m): `K_ab += w b_{j,a} b_{j,b}`, `b_i += w b_{j,a} (p_j)_i` —
//! the collision constraints of [`super::body_collision`]. `N_jᵀN_j` couples the nodes of one
//! tetrahedron, which `K` couples already, so a change of the active set
//! ([`GlobalStep::set_active_points`]) keeps the pattern and its analysis: one numeric factorization.

use crate::knit_material::RestTet;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef, Triplet};
use nalgebra::{Matrix3, Vector3};
use skintight_physics::newton::{CompressedLower, compressed_lower};
use skintight_physics::{CholeskyError, SparseCholesky, SparseCholeskyParams};
use thiserror::Error;

use crate::volumetric_mesh::{Embedded, VolumetricMesh};

/// Why a [`GlobalStep`] could not be set up or solved.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum GlobalStepError {
    /// The time step is not positive (or NaN).
    #[error(
        "the time step Δt = {0} s is not positive; give a step > 0 (or ∞ for a quasi-static solve)"
    )]
    TimeStep(f64),
    /// One weight per element is needed.
    #[error(
        "{given} element weights for a mesh of {elements} tetrahedra; give one per tetrahedron"
    )]
    WeightCount {
        /// Weights given.
        given: usize,
        /// Tetrahedra of the mesh.
        elements: usize,
    },
    /// A weight is negative or not finite.
    #[error("the weight of tetrahedron {tet} is {weight} J; weights must be finite and ≥ 0")]
    Weight {
        /// The tetrahedron.
        tet: usize,
        /// Its weight (J).
        weight: f64,
    },
    /// A tetrahedron has no positive rest volume or names a missing node.
    #[error("tetrahedron {tet} is degenerate or names a missing node at rest; rebuild the mesh")]
    Tet {
        /// The tetrahedron.
        tet: usize,
    },
    /// A clamped node does not exist.
    #[error("clamped node {node} is not a node of the mesh ({nodes} nodes)")]
    Clamped {
        /// The node index given.
        node: usize,
        /// Nodes of the mesh.
        nodes: usize,
    },
    /// An input array has the wrong length.
    #[error("{what} has {given} entries where {expected} are needed")]
    Length {
        /// Which input.
        what: &'static str,
        /// Entries given.
        given: usize,
        /// Entries needed.
        expected: usize,
    },
    /// An input holds NaN or ∞.
    #[error("{what} holds a value that is not finite at entry {index}")]
    NotFinite {
        /// Which input.
        what: &'static str,
        /// The entry.
        index: usize,
    },
    /// `K` is singular: a part of the mesh that nothing holds (no mass with `Δt = ∞`, no clamp).
    #[error(
        "the global matrix is singular ({0}); with Δt = ∞ every connected part of the mesh needs a \
         clamped node"
    )]
    Singular(String),
}

/// The factored global step of one mesh, weights and time step.
#[derive(Debug)]
pub struct GlobalStep {
    /// Per node: its unknown's index, or `None` when clamped.
    unknown: Vec<Option<usize>>,
    clamped: Vec<usize>,
    /// Per element the corner gradients `g_a` (1/m).
    gradients: Vec<[Vector3<f64>; 4]>,
    weights: Vec<f64>,
    tets: Vec<[usize; 4]>,
    /// The embedded points' tetrahedra (node indices) and barycentric weights.
    points: Vec<([usize; 4], [f64; 4])>,
    /// Which points' constraints are in `K` (and the right-hand side).
    active: Vec<bool>,
    /// Their weight `w` (N/m).
    point_weight: f64,
    /// `m_v / Δt²` (kg/s², 0 when Δt = ∞).
    inertia: Vec<f64>,
    /// The coupling of the unknowns to the clamped nodes, `(unknown, clamped node, K entry)`.
    coupling: Vec<(usize, usize, f64)>,
    /// The lower triangle of `K` over the unknowns (N/m), for the iterative solvers.
    lower: CompressedLower,
    chol: SparseCholesky,
}

impl GlobalStep {
    /// Assembles and factors `K` for `mesh` with element weights `weights` (`#T`, J), the nodes
    /// `clamped` prescribed, and time step `dt` (s; `f64::INFINITY` for the quasi-static problem).
    pub fn new(
        mesh: &VolumetricMesh,
        weights: &[f64],
        clamped: &[usize],
        dt: f64,
    ) -> Result<Self, GlobalStepError> {
        Self::with_points(mesh, weights, clamped, dt, &[], 0.0)
    }

    /// As [`Self::new`], with the point constraints of the embedded points `points` (`#P`, e.g. the
    /// mesh's V2Y embedding) at weight `point_weight` (N/m, ≥ 0; see the module doc).
    pub fn with_points(
        mesh: &VolumetricMesh,
        weights: &[f64],
        clamped: &[usize],
        dt: f64,
        points: &[Embedded],
        point_weight: f64,
    ) -> Result<Self, GlobalStepError> {
        if dt.is_nan() || dt <= 0.0 {
            return Err(GlobalStepError::TimeStep(dt));
        }
        let nodes = mesh.rest.len();
        if weights.len() != mesh.tets.len() {
            return Err(GlobalStepError::WeightCount {
                given: weights.len(),
                elements: mesh.tets.len(),
            });
        }
        if let Some((tet, &weight)) = weights
            .iter()
            .enumerate()
            .find(|(_, w)| !w.is_finite() || **w < 0.0)
        {
            return Err(GlobalStepError::Weight { tet, weight });
        }
        if mesh.node_mass.len() != nodes {
            return Err(GlobalStepError::Length {
                what: "the nodal masses",
                given: mesh.node_mass.len(),
                expected: nodes,
            });
        }
        let mut unknown: Vec<Option<usize>> = vec![Some(0); nodes];
        for &c in clamped {
            if c >= nodes {
                return Err(GlobalStepError::Clamped { node: c, nodes });
            }
            unknown[c] = None;
        }
        let mut count = 0;
        for u in unknown.iter_mut().flatten() {
            *u = count;
            count += 1;
        }
        let mut clamped: Vec<usize> = clamped.to_vec();
        clamped.sort_unstable();
        clamped.dedup();

        let mut gradients = Vec::with_capacity(mesh.tets.len());
        for (t, tet) in mesh.tets.iter().enumerate() {
            if tet.iter().any(|&v| v >= nodes) {
                return Err(GlobalStepError::Tet { tet: t });
            }
            let corners = tet.map(|v| mesh.rest[v]);
            let rest = RestTet::new(&corners).map_err(|_| GlobalStepError::Tet { tet: t })?;
            gradients.push(rest.corner_gradients());
        }
        let inv_dt2 = if dt.is_infinite() {
            0.0
        } else {
            1.0 / (dt * dt)
        };
        let inertia: Vec<f64> = mesh.node_mass.iter().map(|m| m * inv_dt2).collect();
        if let Some(index) = inertia.iter().position(|m| !m.is_finite() || *m < 0.0) {
            return Err(GlobalStepError::NotFinite {
                what: "the nodal masses",
                index,
            });
        }

        // Every connected part needs mass (Δt < ∞) or a clamp, else K is singular — which round-off can
        // hide from the factorization, so it is checked on the graph.
        let mut parent: Vec<usize> = (0..nodes).collect();
        fn root(parent: &mut [usize], mut v: usize) -> usize {
            while parent[v] != v {
                parent[v] = parent[parent[v]];
                v = parent[v];
            }
            v
        }
        for tet in &mesh.tets {
            for &v in &tet[1..] {
                let (a, b) = (root(&mut parent, tet[0]), root(&mut parent, v));
                parent[a] = b;
            }
        }
        let mut held = vec![false; nodes];
        for v in 0..nodes {
            if unknown[v].is_none() || inertia[v] > 0.0 {
                let r = root(&mut parent, v);
                held[r] = true;
            }
        }
        if let Some(v) = (0..nodes).find(|&v| {
            let r = root(&mut parent, v);
            !held[r]
        }) {
            return Err(GlobalStepError::Singular(format!(
                "the part of the mesh with node {v} has neither mass nor a clamped node"
            )));
        }

        if !(point_weight.is_finite() && point_weight >= 0.0) {
            return Err(GlobalStepError::NotFinite {
                what: "the point weight (N/m, ≥ 0)",
                index: 0,
            });
        }
        let mut embedded = Vec::with_capacity(points.len());
        for (j, e) in points.iter().enumerate() {
            if e.tet >= mesh.tets.len() || !e.weights.iter().all(|b| b.is_finite()) {
                return Err(GlobalStepError::NotFinite {
                    what: "the embedded points (tetrahedron index, barycentric weights)",
                    index: j,
                });
            }
            embedded.push((mesh.tets[e.tet], e.weights));
        }

        let active = vec![true; embedded.len()];
        let (lower, coupling) = assemble(
            &unknown,
            &inertia,
            &mesh.tets,
            &gradients,
            weights,
            &embedded,
            &active,
            point_weight,
        );
        let symbolic = SymbolicSparseColMatRef::new_checked(
            count,
            count,
            &lower.col_ptr,
            None,
            &lower.row_idx,
        );
        let matrix = SparseColMatRef::new(symbolic, &lower.values);
        let singular = |e: CholeskyError| GlobalStepError::Singular(e.to_string());
        let mut chol =
            SparseCholesky::analyze(matrix, &SparseCholeskyParams::default()).map_err(singular)?;
        chol.factorize(matrix).map_err(singular)?;
        Ok(Self {
            unknown,
            clamped,
            gradients,
            weights: weights.to_vec(),
            tets: mesh.tets.clone(),
            points: embedded,
            active,
            point_weight,
            inertia,
            coupling,
            lower,
            chol,
        })
    }

    /// The weight `w` of the point constraints (N/m; 0 without points).
    pub fn point_weight(&self) -> f64 {
        self.point_weight
    }

    /// Which point constraints are active (`#P`).
    pub fn active_points(&self) -> &[bool] {
        &self.active
    }

    /// Makes the point constraints `active` (`#P`) the ones in `K` and refactors it (numerically; the
    /// pattern and its analysis are kept). Returns whether anything changed (no work when not).
    pub fn set_active_points(&mut self, active: &[bool]) -> Result<bool, GlobalStepError> {
        if active.len() != self.points.len() {
            return Err(GlobalStepError::Length {
                what: "the active points",
                given: active.len(),
                expected: self.points.len(),
            });
        }
        if active == self.active.as_slice() {
            return Ok(false);
        }
        self.active.copy_from_slice(active);
        let (lower, coupling) = assemble(
            &self.unknown,
            &self.inertia,
            &self.tets,
            &self.gradients,
            &self.weights,
            &self.points,
            &self.active,
            self.point_weight,
        );
        let n = self.chol.dimension();
        let symbolic =
            SymbolicSparseColMatRef::new_checked(n, n, &lower.col_ptr, None, &lower.row_idx);
        let matrix = SparseColMatRef::new(symbolic, &lower.values);
        self.chol
            .factorize(matrix)
            .map_err(|e| GlobalStepError::Singular(e.to_string()))?;
        self.lower = lower;
        self.coupling = coupling;
        Ok(true)
    }

    /// The nodes held at prescribed positions, sorted.
    pub fn clamped(&self) -> &[usize] {
        &self.clamped
    }

    /// The corner gradients of element `e` (1/m), for the local step's `F_e`.
    pub fn gradients(&self, e: usize) -> &[Vector3<f64>; 4] {
        &self.gradients[e]
    }

    /// Writes into `x` (`#V × 3`, m) the minimizer of `Φ` for the inertial target `y` (`#V × 3`, m;
    /// ignored when `Δt = ∞`), external forces `forces` (`#V × 3`, N), element targets `targets`
    /// (`#T`) and point targets `points` (`#P × 3`, m; empty without point constraints); the clamped
    /// nodes keep the positions `x` holds on entry.
    pub fn solve(
        &self,
        y: &[[f64; 3]],
        forces: &[[f64; 3]],
        targets: &[Matrix3<f64>],
        points: &[[f64; 3]],
        x: &mut [[f64; 3]],
    ) -> Result<(), GlobalStepError> {
        self.check(y, forces, targets, points, x)?;
        let mut rhs = self.right_hand_side(y, forces, targets, points, x);
        self.chol
            .solve_columns_in_place(&mut rhs, 3)
            .map_err(|e| GlobalStepError::Singular(e.to_string()))?;
        self.scatter(&rhs, x);
        Ok(())
    }

    /// Checks the inputs of [`Self::solve`] (lengths, finiteness).
    pub(crate) fn check(
        &self,
        y: &[[f64; 3]],
        forces: &[[f64; 3]],
        targets: &[Matrix3<f64>],
        points: &[[f64; 3]],
        x: &[[f64; 3]],
    ) -> Result<(), GlobalStepError> {
        let nodes = self.unknown.len();
        for (what, len, expected) in [
            ("the inertial target y", y.len(), nodes),
            ("the forces", forces.len(), nodes),
            ("the element targets", targets.len(), self.tets.len()),
            ("the point targets", points.len(), self.points.len()),
            ("the positions x", x.len(), nodes),
        ] {
            if len != expected {
                return Err(GlobalStepError::Length {
                    what,
                    given: len,
                    expected,
                });
            }
        }
        let finite3 = |a: &[[f64; 3]], what: &'static str| match a
            .iter()
            .position(|p| !p.iter().all(|v| v.is_finite()))
        {
            Some(index) => Err(GlobalStepError::NotFinite { what, index }),
            None => Ok(()),
        };
        finite3(y, "the inertial target y")?;
        finite3(forces, "the forces")?;
        finite3(points, "the point targets")?;
        finite3(x, "the positions x")?;
        if let Some(index) = targets
            .iter()
            .position(|p| !p.iter().all(|v| v.is_finite()))
        {
            return Err(GlobalStepError::NotFinite {
                what: "the element targets",
                index,
            });
        }
        Ok(())
    }

    /// The active point constraints with their targets `points` (`#P × 3`, m): tetrahedron's nodes,
    /// barycentric weights, target.
    fn active_with<'a>(
        &'a self,
        points: &'a [[f64; 3]],
    ) -> impl Iterator<Item = (&'a [usize; 4], &'a [f64; 4], &'a [f64; 3])> {
        self.points
            .iter()
            .zip(points)
            .zip(&self.active)
            .filter(|(_, active)| **active)
            .map(|(((tet, b), p), _)| (tet, b, p))
    }

    /// The unknowns' count `n` (the free nodes).
    pub(crate) fn unknowns(&self) -> usize {
        self.chol.dimension()
    }

    /// The lower triangle of `K` over the unknowns (N/m).
    pub(crate) fn lower(&self) -> &CompressedLower {
        &self.lower
    }

    /// The right-hand side `b` of `K X = B` (`3n`, coordinate `i` of unknown `u` at `i n + u`, N), the
    /// clamped nodes' columns moved over at the positions `x` holds.
    pub(crate) fn right_hand_side(
        &self,
        y: &[[f64; 3]],
        forces: &[[f64; 3]],
        targets: &[Matrix3<f64>],
        points: &[[f64; 3]],
        x: &[[f64; 3]],
    ) -> Vec<f64> {
        let n = self.chol.dimension();
        let mut rhs = vec![0.0; 3 * n];
        for (v, u) in self.unknown.iter().enumerate() {
            if let Some(u) = *u {
                for i in 0..3 {
                    rhs[i * n + u] = self.inertia[v] * y[v][i] + forces[v][i];
                }
            }
        }
        for (((tet, g), &w), p) in self
            .tets
            .iter()
            .zip(&self.gradients)
            .zip(&self.weights)
            .zip(targets)
        {
            for a in 0..4 {
                if let Some(u) = self.unknown[tet[a]] {
                    // ω G_eᵀ P row by row: Σ_j P_{ij} g_{a,j}.
                    let pg = p * g[a];
                    for i in 0..3 {
                        rhs[i * n + u] += w * pg[i];
                    }
                }
            }
        }
        for (tet, b, p) in self.active_with(points) {
            for a in 0..4 {
                if let Some(u) = self.unknown[tet[a]] {
                    for i in 0..3 {
                        rhs[i * n + u] += self.point_weight * b[a] * p[i];
                    }
                }
            }
        }
        for &(u, node, k) in &self.coupling {
            for i in 0..3 {
                rhs[i * n + u] -= k * x[node][i];
            }
        }
        rhs
    }

    /// The unknowns (`3n`, as [`Self::right_hand_side`]) of the free nodes of `x` (m).
    pub(crate) fn gather(&self, x: &[[f64; 3]]) -> Vec<f64> {
        let n = self.chol.dimension();
        let mut out = vec![0.0; 3 * n];
        for (v, u) in self.unknown.iter().enumerate() {
            if let Some(u) = *u {
                for i in 0..3 {
                    out[i * n + u] = x[v][i];
                }
            }
        }
        out
    }

    /// Writes the unknowns `z` (`3n`) into the free nodes of `x` (m).
    pub(crate) fn scatter(&self, z: &[f64], x: &mut [[f64; 3]]) {
        let n = self.chol.dimension();
        for (v, u) in self.unknown.iter().enumerate() {
            if let Some(u) = *u {
                for i in 0..3 {
                    x[v][i] = z[i * n + u];
                }
            }
        }
    }

    /// `Φ(x)` (J) for the same inputs as [`Self::solve`], and its gradient (`#V × 3`, N; zero rows at the
    /// clamped nodes): what the PD iteration's convergence test and the tests read.
    pub fn objective(
        &self,
        y: &[[f64; 3]],
        forces: &[[f64; 3]],
        targets: &[Matrix3<f64>],
        points: &[[f64; 3]],
        x: &[[f64; 3]],
    ) -> (f64, Vec<[f64; 3]>) {
        let mut value = 0.0;
        let mut gradient = vec![[0.0; 3]; x.len()];
        for v in 0..x.len() {
            for i in 0..3 {
                let d = x[v][i] - y[v][i];
                value += 0.5 * self.inertia[v] * d * d - forces[v][i] * x[v][i];
                gradient[v][i] += self.inertia[v] * d - forces[v][i];
            }
        }
        for (((tet, g), &w), p) in self
            .tets
            .iter()
            .zip(&self.gradients)
            .zip(&self.weights)
            .zip(targets)
        {
            let f = deformation_gradient(x, tet, g);
            let r = f - p;
            value += 0.5 * w * r.norm_squared();
            for a in 0..4 {
                let rg = r * g[a];
                for i in 0..3 {
                    gradient[tet[a]][i] += w * rg[i];
                }
            }
        }
        for (tet, b, p) in self.active_with(points) {
            let r = [0, 1, 2].map(|i| (0..4).map(|a| b[a] * x[tet[a]][i]).sum::<f64>() - p[i]);
            value += 0.5 * self.point_weight * (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
            for a in 0..4 {
                for i in 0..3 {
                    gradient[tet[a]][i] += self.point_weight * b[a] * r[i];
                }
            }
        }
        for &c in &self.clamped {
            gradient[c] = [0.0; 3];
        }
        (value, gradient)
    }
}

/// The lower triangle of `K` over the unknowns and the coupling of the unknowns to the clamped nodes,
/// for the element weights and the active point constraints (see the module doc).
#[allow(clippy::too_many_arguments)]
fn assemble(
    unknown: &[Option<usize>],
    inertia: &[f64],
    tets: &[[usize; 4]],
    gradients: &[[Vector3<f64>; 4]],
    weights: &[f64],
    points: &[([usize; 4], [f64; 4])],
    active: &[bool],
    point_weight: f64,
) -> (CompressedLower, Vec<(usize, usize, f64)>) {
    let count = unknown.iter().flatten().count();
    let mut triplets = Vec::with_capacity(count + 10 * tets.len());
    let mut coupling = Vec::new();
    for (v, u) in unknown.iter().enumerate() {
        if let Some(u) = *u {
            triplets.push(Triplet::new(u, u, inertia[v]));
        }
    }
    let mut add = |na: usize, nb: usize, k: f64| match (unknown[na], unknown[nb]) {
        (Some(ra), Some(rb)) if ra >= rb => triplets.push(Triplet::new(ra, rb, k)),
        (Some(ra), None) => coupling.push((ra, nb, k)),
        _ => {}
    };
    for ((tet, g), &w) in tets.iter().zip(gradients).zip(weights) {
        for a in 0..4 {
            for b in 0..4 {
                add(tet[a], tet[b], w * g[a].dot(&g[b]));
            }
        }
    }
    if point_weight > 0.0 {
        for ((tet, b), _) in points.iter().zip(active).filter(|(_, a)| **a) {
            for i in 0..4 {
                for k in 0..4 {
                    add(tet[i], tet[k], point_weight * b[i] * b[k]);
                }
            }
        }
    }
    (compressed_lower(count, &triplets), coupling)
}

/// `F_e = Σ_a x_a ⊗ g_a` of the tetrahedron `tet` at positions `x` (dimensionless).
pub fn deformation_gradient(
    x: &[[f64; 3]],
    tet: &[usize; 4],
    g: &[Vector3<f64>; 4],
) -> Matrix3<f64> {
    let mut f = Matrix3::zeros();
    for a in 0..4 {
        f += Vector3::from(x[tet[a]]) * g[a].transpose();
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volumetric_mesh::VolumetricMesh;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::{FdParams, check_gradient};

    /// A `k` block of cubes of side `h` (the construction's split), 1 g a node.
    fn block(k: [usize; 3], h: f64) -> VolumetricMesh {
        let mut mesh = crate::knit_material::test_states::block_mesh(k[0], k[1], k[2], h);
        mesh.node_mass = vec![1e-3; mesh.rest.len()];
        mesh
    }

    #[test]
    fn an_affine_target_gives_the_affine_field_quasi_statically() {
        let mesh = block([3, 2, 2], 0.01);
        let a = Matrix3::new(1.2, 0.1, 0.0, -0.05, 0.9, 0.2, 0.0, 0.1, 1.05);
        let c = Vector3::new(0.3, -0.1, 0.02);
        let map = |p: &[f64; 3]| -> [f64; 3] { (a * Vector3::from(*p) + c).into() };
        let clamped: Vec<usize> = (0..mesh.rest.len())
            .filter(|&v| mesh.rest[v][0] == 0.0)
            .collect();
        let weights = vec![2.5; mesh.tets.len()];
        let step = GlobalStep::new(&mesh, &weights, &clamped, f64::INFINITY).unwrap();
        let mut x = mesh.rest.clone();
        for &v in &clamped {
            x[v] = map(&mesh.rest[v]);
        }
        let zeros = vec![[0.0; 3]; x.len()];
        step.solve(&zeros, &zeros, &vec![a; mesh.tets.len()], &[], &mut x)
            .unwrap();
        for (v, p) in x.iter().enumerate() {
            let want = map(&mesh.rest[v]);
            for i in 0..3 {
                assert!(
                    (p[i] - want[i]).abs() < 1e-12,
                    "node {v}: {p:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn the_solution_is_stationary_and_the_gradient_matches_differences() {
        // Without and with point constraints (embedded points at random barycentric coordinates).
        for with_points in [false, true] {
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let mut mesh = block([2, 2, 1], 0.02);
            for m in &mut mesh.node_mass {
                *m = rng.random_range(1e-4..1e-3);
            }
            let weights: Vec<f64> = (0..mesh.tets.len())
                .map(|_| rng.random_range(0.0..5.0))
                .collect();
            let targets: Vec<Matrix3<f64>> = (0..mesh.tets.len())
                .map(|_| Matrix3::identity() + Matrix3::from_fn(|_, _| rng.random_range(-0.3..0.3)))
                .collect();
            let jitter =
                |p: &[f64; 3], rng: &mut ChaCha8Rng| p.map(|v| v + rng.random_range(-0.003..0.003));
            let y: Vec<[f64; 3]> = mesh.rest.iter().map(|p| jitter(p, &mut rng)).collect();
            let forces: Vec<[f64; 3]> =
                mesh.rest.iter().map(|_| [0.0, 0.0, -1e-3 * 9.81]).collect();
            let clamped = [0, 5];
            let (points, point_targets, w): (Vec<Embedded>, Vec<[f64; 3]>, f64) = if with_points {
                let points: Vec<Embedded> = (0..30)
                    .map(|_| {
                        let b: [f64; 4] = [0, 1, 2, 3].map(|_| rng.random_range(0.05..1.0));
                        let sum: f64 = b.iter().sum();
                        Embedded {
                            tet: rng.random_range(0..mesh.tets.len()),
                            weights: b.map(|v| v / sum),
                        }
                    })
                    .collect();
                let p = (0..30)
                    .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..0.04)))
                    .collect();
                (points, p, 3.0)
            } else {
                (Vec::new(), Vec::new(), 0.0)
            };
            let new = |clamped: &[usize]| {
                GlobalStep::with_points(&mesh, &weights, clamped, 1.0 / 150.0, &points, w).unwrap()
            };
            let step = new(&clamped);

            // The gradient of Φ against central differences, at a random state.
            let x0: Vec<[f64; 3]> = mesh.rest.iter().map(|p| jitter(p, &mut rng)).collect();
            let flat: Vec<f64> = x0.iter().flatten().copied().collect();
            let unflat =
                |v: &[f64]| -> Vec<[f64; 3]> { v.chunks(3).map(|c| [c[0], c[1], c[2]]).collect() };
            // `objective` zeroes the clamped rows; the unclamped problem's gradient is checked in full.
            let unclamped = new(&[]);
            let pt = &point_targets;
            let value = |v: &[f64]| unclamped.objective(&y, &forces, &targets, pt, &unflat(v)).0;
            let full = unclamped.objective(&y, &forces, &targets, pt, &x0).1;
            let analytic: Vec<f64> = full.iter().flatten().copied().collect();
            check_gradient(
                value,
                &flat,
                &analytic,
                &FdParams {
                    step: 1e-7,
                    rel_tol: 1e-6,
                    abs_tol: 1e-10,
                },
            )
            .unwrap();

            // The solve zeroes the gradient of the free nodes.
            let mut x = x0.clone();
            step.solve(&y, &forces, &targets, pt, &mut x).unwrap();
            assert_eq!(x[0], x0[0]);
            assert_eq!(x[5], x0[5]);
            let (_, g) = step.objective(&y, &forces, &targets, pt, &x);
            let scale = analytic.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for row in &g {
                for v in row {
                    assert!(
                        v.abs() < 1e-9 * scale,
                        "with points {with_points}: gradient {v} after the solve (scale {scale})"
                    );
                }
            }
            // A wrong number of point targets is refused by name.
            if with_points {
                let err = step
                    .solve(&y, &forces, &targets, &pt[1..], &mut x)
                    .unwrap_err();
                assert!(err.to_string().contains("point targets"), "{err}");
            }
        }
    }

    #[test]
    fn a_wrong_gradient_fails_the_check() {
        let mesh = block([1, 1, 1], 0.02);
        let weights = vec![1.0; mesh.tets.len()];
        let step = GlobalStep::new(&mesh, &weights, &[], 0.01).unwrap();
        let y = mesh.rest.clone();
        let zeros = vec![[0.0; 3]; y.len()];
        let targets = vec![Matrix3::identity() * 1.1; mesh.tets.len()];
        let x0: Vec<[f64; 3]> = mesh
            .rest
            .iter()
            .map(|p| [p[0] * 1.05, p[1], p[2]])
            .collect();
        let flat: Vec<f64> = x0.iter().flatten().copied().collect();
        let unflat =
            |v: &[f64]| -> Vec<[f64; 3]> { v.chunks(3).map(|c| [c[0], c[1], c[2]]).collect() };
        let mut wrong: Vec<f64> = step
            .objective(&y, &zeros, &targets, &[], &x0)
            .1
            .iter()
            .flatten()
            .copied()
            .collect();
        wrong[4] *= 1.5;
        wrong[4] += 1e-3;
        let value = |v: &[f64]| step.objective(&y, &zeros, &targets, &[], &unflat(v)).0;
        assert!(check_gradient(value, &flat, &wrong, &FdParams::default()).is_err());
    }

    #[test]
    fn bad_inputs_are_refused_by_name() {
        let mesh = block([1, 1, 1], 0.01);
        let w = vec![1.0; mesh.tets.len()];
        assert!(matches!(
            GlobalStep::new(&mesh, &w, &[], 0.0),
            Err(GlobalStepError::TimeStep(_))
        ));
        assert!(matches!(
            GlobalStep::new(&mesh, &w, &[], f64::NAN),
            Err(GlobalStepError::TimeStep(_))
        ));
        assert!(matches!(
            GlobalStep::new(&mesh, &w[1..], &[], 0.01),
            Err(GlobalStepError::WeightCount {
                given: 5,
                elements: 6
            })
        ));
        let mut bad = w.clone();
        bad[3] = -1.0;
        assert!(matches!(
            GlobalStep::new(&mesh, &bad, &[], 0.01),
            Err(GlobalStepError::Weight { tet: 3, .. })
        ));
        assert!(matches!(
            GlobalStep::new(&mesh, &w, &[99], 0.01),
            Err(GlobalStepError::Clamped { node: 99, nodes: 8 })
        ));
        // Quasi-static with nothing clamped: singular, said so.
        let err = GlobalStep::new(&mesh, &w, &[], f64::INFINITY).unwrap_err();
        assert!(matches!(err, GlobalStepError::Singular(_)), "{err}");
        let step = GlobalStep::new(&mesh, &w, &[0], 0.01).unwrap();
        let mut x = mesh.rest.clone();
        let mut y = mesh.rest.clone();
        y[2][1] = f64::NAN;
        let zeros = vec![[0.0; 3]; x.len()];
        let targets = vec![Matrix3::identity(); mesh.tets.len()];
        assert!(matches!(
            step.solve(&y, &zeros, &targets, &[], &mut x),
            Err(GlobalStepError::NotFinite { index: 2, .. })
        ));
        assert!(matches!(
            step.solve(&mesh.rest, &zeros, &targets[1..], &[], &mut x),
            Err(GlobalStepError::Length {
                given: 5,
                expected: 6,
                ..
            })
        ));
    }
}
