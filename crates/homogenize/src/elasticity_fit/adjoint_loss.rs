//! The loss of the elasticity fit over the poses (Eq. 9–10), its adjoint gradient (Eq. 15–17) and its
//! linearization for the adjoint Gauss-Newton direction (Eq. 18–21): [`ElasticityFit`], an
//! [`AdjointProblem`] of the shared optimizer. See [`super`] for the equations and the symbols.
//!
//! Derivatives. The loss's gradient in `x` is [`ShapeFit::error_gradient`] (tested there); the mixed
//! derivative `K` and the Hessian `H` are the material's (tested in [`crate::knit_material`]); their
//! composition through the implicit equilibrium is checked against central differences of the loss
//! through the equilibrium solve (the tests below), at a Newton tolerance far below the step's effect.
//! The clamped coordinates are no unknowns of the equilibrium: their rows and columns of `H` are replaced
//! by the identity scaled to the free diagonal, their rows of `K` dropped, so `dx = 0` there.

use faer::sparse::{SparseColMat, Triplet};
use skintight_optimize::{
    AdjointProblem, GaussNewtonError, Linearization, MixedDerivative, MixedForm, Objective, Unknown,
};
use skintight_physics::newton::{NewtonParams, minimize};
use skintight_physics::{SparseCholesky, SparseCholeskyParams};

use crate::closest_volume_preserving::VolumePreservingParams;
use crate::knit_material::{
    KnitMaterial, KnitMaterialError, MaterialHessian, QuasiStaticParams, QuasiStaticProblem,
};
use crate::shape_fit::{FitTarget, ShapeFit};
use crate::volumetric_mesh::VolumetricMesh;

/// One pose of the fit: its loads, its boundary and the shape it should take.
#[derive(Clone, Debug)]
pub struct FitPose {
    /// External plus inertia forces on the nodes (Eq. 14), flattened `3#V` (N).
    pub force: Vec<f64>,
    /// Which coordinates are clamped (`3#V`); they stay at their value in [`Self::start`].
    pub fixed: Vec<bool>,
    /// The positions the first equilibrium solve starts from, flattened `3#V` (m); the clamped
    /// coordinates' prescribed values.
    pub start: Vec<f64>,
    /// The pose's shape-fit target (Eq. 5 element gradients and yarn positions).
    pub target: FitTarget,
}

/// Settings of [`ElasticityFit`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElasticityFitParams {
    /// The equilibrium solves. Default: the toolkit's defaults with tolerance `1e-10`.
    pub newton: NewtonParams,
    /// The quasi-static problem of each pose.
    pub quasi_static: QuasiStaticParams,
    /// The closest volume-preserving matrix of the material.
    pub volume_preserving: VolumePreservingParams,
    /// The factorizations of the equilibrium Hessians.
    pub cholesky: SparseCholeskyParams,
}

impl Default for ElasticityFitParams {
    fn default() -> Self {
        Self {
            newton: NewtonParams {
                tolerance: 1e-10,
                ..NewtonParams::default()
            },
            quasi_static: QuasiStaticParams::default(),
            volume_preserving: VolumePreservingParams::default(),
            cholesky: SparseCholeskyParams::default(),
        }
    }
}

/// Why the fit or one of its evaluations failed.
#[derive(Debug, thiserror::Error)]
pub enum ElasticityFitError {
    /// A pose's data do not fit the mesh; the message names the pose and the field.
    #[error("elasticity fit: pose {pose}: {reason}")]
    Pose {
        /// Index of the pose.
        pose: usize,
        /// What is wrong and how to fix it.
        reason: String,
    },
    /// The parameter map does not have `2#T` rows or holds a non-finite entry.
    #[error("elasticity fit: the parameter map {0}")]
    Map(String),
    /// The material rejected `γ = A c` (e.g. a negative or non-finite entry) or the mesh.
    #[error("elasticity fit: {0}")]
    Material(#[from] KnitMaterialError),
    /// A pose's equilibrium could not be solved at these parameters.
    #[error("elasticity fit: the equilibrium of pose {pose} failed: {reason}")]
    Equilibrium {
        /// Index of the pose.
        pose: usize,
        /// The solver's words.
        reason: String,
    },
    /// The Gauss-Newton direction failed.
    #[error(transparent)]
    Direction(#[from] GaussNewtonError),
}

fn pose_error(pose: usize, reason: impl std::fmt::Display) -> ElasticityFitError {
    ElasticityFitError::Pose {
        pose,
        reason: reason.to_string(),
    }
}

/// The fit of `γ = A c` to the poses (see the module documentation).
pub struct ElasticityFit<'a> {
    shape: &'a ShapeFit,
    material: KnitMaterial,
    poses: Vec<FitPose>,
    /// `A` (`2#T × #c`; row `2e` is `γˢ_e`, row `2e + 1` is `γᵛ_e`, Pa per unit of `c`).
    map: SparseColMat<usize, f64>,
    params: ElasticityFitParams,
    /// The equilibria of the last successful evaluation, one `3#V` vector per pose (m).
    states: Vec<Vec<f64>>,
    /// The variables `c` those equilibria belong to.
    evaluated: Option<Vec<f64>>,
    /// The factored equilibrium Hessians of the last linearization, per pose.
    factors: Vec<SparseCholesky>,
    evaluations: usize,
    newton_iterations: usize,
    /// Whether `A` is a positive diagonal up to the order of its rows (each column one positive entry,
    /// each row at most one), so `γ ≥ 0` is `c ≥ 0` and trial points are clamped to it.
    clamps: bool,
}

impl<'a> ElasticityFit<'a> {
    /// The fit on `mesh` (whose Y2V is `shape`) of the poses `poses` over the variables `c` of
    /// `γ = A c`, `map` = `A` (`2#T × #c`, Pa per unit of `c`). Errors name the pose and field that do
    /// not fit the mesh.
    pub fn new(
        mesh: &VolumetricMesh,
        shape: &'a ShapeFit,
        poses: Vec<FitPose>,
        map: SparseColMat<usize, f64>,
        params: ElasticityFitParams,
    ) -> Result<Self, ElasticityFitError> {
        let tets = mesh.tets.len();
        let material = KnitMaterial::new(mesh, vec![[0.0; 2]; tets], params.volume_preserving)?;
        let n = material.dof_count();
        if poses.is_empty() {
            return Err(pose_error(0, "no poses: give at least one pose to fit"));
        }
        for (i, p) in poses.iter().enumerate() {
            for (what, got) in [
                ("force", p.force.len()),
                ("fixed", p.fixed.len()),
                ("start", p.start.len()),
            ] {
                if got != n {
                    return Err(pose_error(
                        i,
                        format!("{what} has {got} entries, expected 3 × #V = {n}"),
                    ));
                }
            }
            if let Some(k) = p.force.iter().chain(&p.start).position(|v| !v.is_finite()) {
                return Err(pose_error(
                    i,
                    format!("entry {k} of force/start is not finite"),
                ));
            }
            shape
                .error(&p.target, &p.start)
                .map_err(|e| pose_error(i, e))?;
        }
        if map.nrows() != 2 * tets {
            return Err(ElasticityFitError::Map(format!(
                "has {} rows, expected 2 × #T = {}",
                map.nrows(),
                2 * tets
            )));
        }
        if map.val().iter().any(|v| !v.is_finite()) {
            return Err(ElasticityFitError::Map("holds a non-finite entry".into()));
        }
        let states = poses.iter().map(|p| p.start.clone()).collect();
        let mut per_row = vec![0usize; map.nrows()];
        let cp = map.symbolic().col_ptr();
        let mut clamps = (0..map.ncols()).all(|j| cp[j + 1] - cp[j] == 1 && map.val()[cp[j]] > 0.0);
        for &r in map.symbolic().row_idx() {
            per_row[r] += 1;
            clamps &= per_row[r] <= 1;
        }
        Ok(Self {
            shape,
            material,
            poses,
            map,
            params,
            states,
            evaluated: None,
            factors: Vec::new(),
            evaluations: 0,
            newton_iterations: 0,
            clamps,
        })
    }

    /// `γ = A c` (`2#T`, Pa).
    pub fn gamma(&self, c: &[f64]) -> Vec<f64> {
        let mut p = vec![0.0; self.map.nrows()];
        let (cp, ri, v) = (
            self.map.symbolic().col_ptr(),
            self.map.symbolic().row_idx(),
            self.map.val(),
        );
        for (j, &cj) in c.iter().enumerate().take(self.map.ncols()) {
            for k in cp[j]..cp[j + 1] {
                p[ri[k]] += v[k] * cj;
            }
        }
        p
    }

    /// The equilibria of the last successful evaluation, one `3#V` vector per pose (m).
    pub fn states(&self) -> &[Vec<f64>] {
        &self.states
    }

    /// Evaluations of the loss so far (each solves every pose's equilibrium).
    pub fn evaluations(&self) -> usize {
        self.evaluations
    }

    /// Newton iterations of all equilibrium solves so far.
    pub fn newton_iterations(&self) -> usize {
        self.newton_iterations
    }

    /// Solves every pose's equilibrium at `c`, from the last equilibria; keeps them on success.
    fn solve(&mut self, c: &[f64]) -> Result<(), ElasticityFitError> {
        if c.len() != self.map.ncols() {
            return Err(ElasticityFitError::Map(format!(
                "has {} columns but {} variables were given",
                self.map.ncols(),
                c.len()
            )));
        }
        if self.evaluated.as_deref() == Some(c) {
            return Ok(());
        }
        let gamma = self.gamma(c);
        self.material
            .set_gamma(gamma.chunks_exact(2).map(|g| [g[0], g[1]]).collect())?;
        let mut states = Vec::with_capacity(self.poses.len());
        for (i, pose) in self.poses.iter().enumerate() {
            let mut x = self.states[i].clone();
            for (k, &f) in pose.fixed.iter().enumerate() {
                if f {
                    x[k] = pose.start[k];
                }
            }
            let mut problem = QuasiStaticProblem::new(
                &self.material,
                pose.force.clone(),
                pose.fixed.clone(),
                &self.params.quasi_static,
            )
            .map_err(|e| ElasticityFitError::Equilibrium {
                pose: i,
                reason: e.to_string(),
            })?;
            let report = minimize(&mut problem, &mut x, &self.params.newton).map_err(|e| {
                ElasticityFitError::Equilibrium {
                    pose: i,
                    reason: e.to_string(),
                }
            })?;
            self.newton_iterations += report.iterations;
            if !report.converged {
                return Err(ElasticityFitError::Equilibrium {
                    pose: i,
                    reason: format!(
                        "not converged after {} iterations (residual {:.3e}, {})",
                        report.iterations,
                        report.residual,
                        report.stop.phrase()
                    ),
                });
            }
            states.push(x);
        }
        self.states = states;
        self.evaluated = Some(c.to_vec());
        Ok(())
    }

    /// The lower triangle of pose `i`'s equilibrium Hessian at its state (N/m), the clamped coordinates'
    /// rows and columns replaced by the mean free diagonal.
    fn hessian(&self, i: usize) -> Result<Vec<Triplet<usize, usize, f64>>, ElasticityFitError> {
        let fixed = &self.poses[i].fixed;
        let ev = self
            .material
            .evaluate(&self.states[i], MaterialHessian::Exact)?;
        let mut t: Vec<_> = ev
            .hessian
            .into_iter()
            .filter(|t| !fixed[t.row] && !fixed[t.col])
            .collect();
        let mut diagonal = vec![0.0; fixed.len()];
        for e in &t {
            if e.row == e.col {
                diagonal[e.row] += e.val;
            }
        }
        let free = fixed.iter().filter(|f| !**f).count().max(1);
        let mean = diagonal.iter().map(|d| d.abs()).sum::<f64>() / free as f64;
        let mean = if mean > 0.0 { mean } else { 1.0 };
        t.extend(
            fixed
                .iter()
                .enumerate()
                .filter(|(_, f)| **f)
                .map(|(k, _)| Triplet::new(k, k, mean)),
        );
        Ok(t)
    }

    /// Factors pose `i`'s equilibrium Hessian.
    fn factor(
        &self,
        i: usize,
        lower: &[Triplet<usize, usize, f64>],
    ) -> Result<SparseCholesky, ElasticityFitError> {
        let n = self.material.dof_count();
        let m = SparseColMat::try_new_from_triplets(n, n, lower).map_err(|e| {
            ElasticityFitError::Equilibrium {
                pose: i,
                reason: format!("Hessian: {e:?}"),
            }
        })?;
        let fail = |e: skintight_physics::CholeskyError| ElasticityFitError::Equilibrium {
            pose: i,
            reason: format!(
                "the equilibrium Hessian cannot be factored ({e}): an unstable equilibrium"
            ),
        };
        let mut chol = SparseCholesky::analyze(m.as_ref(), &self.params.cholesky).map_err(fail)?;
        chol.factorize(m.as_ref()).map_err(fail)?;
        Ok(chol)
    }

    /// `K = ∂g/∂γ` of pose `i` (`(row, parameter, value)`, m²), clamped rows dropped.
    fn mixed(&self, i: usize) -> Result<Vec<(usize, usize, f64)>, ElasticityFitError> {
        let k = self.material.gradient_per_gamma(&self.states[i])?;
        let fixed = &self.poses[i].fixed;
        let (cp, ri, v) = (k.symbolic().col_ptr(), k.symbolic().row_idx(), k.val());
        let mut out = Vec::with_capacity(v.len());
        for p in 0..k.ncols() {
            for e in cp[p]..cp[p + 1] {
                if !fixed[ri[e]] {
                    out.push((ri[e], p, v[e]));
                }
            }
        }
        Ok(out)
    }
}

impl Objective for ElasticityFit<'_> {
    type Error = ElasticityFitError;

    /// `T = Σᵢ εᵢ` (m³) and `dT/dc = −Aᵀ Σᵢ Kᵢᵀ λᵢ`, `Hᵢ λᵢ = ∂εᵢ/∂x` (m³ per unit of `c`).
    fn evaluate(&mut self, c: &[f64]) -> Result<(f64, Vec<f64>), ElasticityFitError> {
        self.evaluations += 1;
        self.solve(c)?;
        let mut value = 0.0;
        let mut dp = vec![0.0; self.map.nrows()];
        for i in 0..self.poses.len() {
            let pose = &self.poses[i];
            let x = &self.states[i];
            value += self
                .shape
                .error(&pose.target, x)
                .map_err(|e| pose_error(i, e))?;
            let mut lambda = self
                .shape
                .error_gradient(&pose.target, x)
                .map_err(|e| pose_error(i, e))?;
            for (l, &f) in lambda.iter_mut().zip(&pose.fixed) {
                if f {
                    *l = 0.0;
                }
            }
            let chol = self.factor(i, &self.hessian(i)?)?;
            chol.solve_in_place(&mut lambda)
                .map_err(|e| ElasticityFitError::Equilibrium {
                    pose: i,
                    reason: e.to_string(),
                })?;
            for (r, p, v) in self.mixed(i)? {
                dp[p] -= v * lambda[r];
            }
        }
        let (cp, ri, v) = (
            self.map.symbolic().col_ptr(),
            self.map.symbolic().row_idx(),
            self.map.val(),
        );
        let gradient = (0..self.map.ncols())
            .map(|j| (cp[j]..cp[j + 1]).map(|k| v[k] * dp[ri[k]]).sum())
            .collect();
        Ok((value, gradient))
    }
}

impl AdjointProblem for ElasticityFit<'_> {
    fn unknowns(&self) -> usize {
        self.poses.len() * self.material.dof_count()
    }

    fn linearization(
        &mut self,
        c: &[f64],
        mixed: MixedForm<'_>,
    ) -> Result<Linearization, ElasticityFitError> {
        self.solve(c)?;
        let n = self.material.dof_count();
        let nq = self.unknowns();
        let mut residuals = Vec::new();
        let mut jacobian = Vec::new();
        let mut lower = Vec::new();
        let mut k_entries = Vec::new();
        let mut factors = Vec::with_capacity(self.poses.len());
        for i in 0..self.poses.len() {
            let offset = i * n;
            let (r, jac) = self
                .shape
                .error_residuals(&self.poses[i].target, &self.states[i])
                .map_err(|e| pose_error(i, e))?;
            let base = residuals.len();
            residuals.extend(r);
            jacobian.extend(
                jac.into_iter()
                    .map(|(k, q, v)| (base + k, Unknown::State(offset + q), v)),
            );
            let h = self.hessian(i)?;
            factors.push(self.factor(i, &h)?);
            lower.extend(
                h.into_iter()
                    .map(|t| Triplet::new(offset + t.row, offset + t.col, t.val)),
            );
            k_entries.extend(
                self.mixed(i)?
                    .into_iter()
                    .map(|(r, p, v)| (offset + r, p, v)),
            );
        }
        self.factors = factors;
        let hessian = SparseColMat::try_new_from_triplets(nq, nq, &lower)
            .map_err(|e| ElasticityFitError::Map(format!("(Hessian assembly) {e:?}")))?;
        let mixed = match mixed {
            MixedForm::Matrix => {
                let t: Vec<_> = k_entries
                    .iter()
                    .map(|&(r, p, v)| Triplet::new(r, p, v))
                    .collect();
                MixedDerivative::Matrix(
                    SparseColMat::try_new_from_triplets(nq, self.map.nrows(), &t).map_err(|e| {
                        ElasticityFitError::Map(format!("(mixed derivative) {e:?}"))
                    })?,
                )
            }
            MixedForm::TimesParameterMap { rows, columns } => {
                let mut ka = vec![0.0; nq * columns];
                for &(r, p, v) in &k_entries {
                    for j in 0..columns {
                        ka[j * nq + r] += v * rows[p * columns + j];
                    }
                }
                MixedDerivative::TimesParameterMap(ka)
            }
        };
        Ok(Linearization {
            residuals,
            jacobian,
            hessian,
            mixed,
        })
    }

    /// `γ ≥ 0` (Sec. 6.3): where `γ = A c` is a positive diagonal scaling, trial variables are clamped
    /// at 0; under any other map (harmonic coefficients) a trial with a negative `γ` fails to evaluate
    /// and the line search shortens the step.
    fn project(&self, c: &mut [f64]) {
        if self.clamps {
            for v in c {
                *v = v.max(0.0);
            }
        }
    }

    fn solve_hessian(&mut self, rhs: &mut [f64], columns: usize) -> Result<(), ElasticityFitError> {
        let n = self.material.dof_count();
        let nq = self.unknowns();
        if self.factors.len() != self.poses.len() || rhs.len() != nq * columns {
            return Err(ElasticityFitError::Map(format!(
                "solve_hessian: {} entries for {nq} × {columns}, or nothing linearized",
                rhs.len()
            )));
        }
        let mut block = vec![0.0; n * columns];
        for (i, chol) in self.factors.iter().enumerate() {
            for j in 0..columns {
                block[j * n..(j + 1) * n]
                    .copy_from_slice(&rhs[j * nq + i * n..j * nq + (i + 1) * n]);
            }
            chol.solve_columns_in_place(&mut block, columns)
                .map_err(|e| ElasticityFitError::Equilibrium {
                    pose: i,
                    reason: e.to_string(),
                })?;
            for j in 0..columns {
                rhs[j * nq + i * n..j * nq + (i + 1) * n]
                    .copy_from_slice(&block[j * n..(j + 1) * n]);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape_fit::ShapeFitParams;
    use crate::straight_yarn_block::{StraightYarnBlock, straight_yarn_block};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::{FdParams, check_gradient};
    use skintight_optimize::{
        AdjointGaussNewton, GaussNewtonParams, GaussNewtonSolver, gauss_newton,
        parameter_map_matrix,
    };
    use std::ops::ControlFlow;

    const H: f64 = 0.01;
    const NX: usize = 3;
    /// The scale of `γ` (Pa per unit of `c`).
    const SCALE: f64 = 1000.0;

    fn block() -> StraightYarnBlock {
        straight_yarn_block([NX, 1, 1], H, 1e-3)
    }

    /// Six poses: the end face x = L clamped at (a) a 20 % stretch along x, (b) a 10 % compression
    /// sheared by 0.2 L in y, (c) a 10 % stretch under a load along −z on the free nodes, and the face x = 0 clamped
    /// at rest; (d–f) seeded random loads on every node but the face x = 0, held by rollers and two of
    /// its nodes against rigid motion (so no element has a single free node in every pose). Targets: the
    /// equilibria of `truth` (`2#T`, Pa).
    fn poses(b: &StraightYarnBlock, truth: &[f64]) -> Vec<FitPose> {
        let l = NX as f64 * H;
        let rest: Vec<f64> = b.mesh.rest.iter().flatten().copied().collect();
        let n = rest.len();
        let mut out = Vec::new();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let cases = [(1.2, 0.0, 0.0), (0.9, 0.2, 0.0), (1.1, 0.0, -0.02)];
        for (case, &(stretch, shear, load)) in cases.iter().chain(&[(1.0, 0.0, 0.0); 3]).enumerate()
        {
            let mut start = rest.clone();
            let mut fixed = vec![false; n];
            let mut force = vec![0.0; n];
            for v in 0..n / 3 {
                let x = rest[3 * v];
                if case >= cases.len() {
                    // Rollers on x = 0, the rigid motions in y, z and about x held by two of its
                    // nodes; random loads (N) everywhere else.
                    if x < 1e-9 * l {
                        let (y, z) = (rest[3 * v + 1], rest[3 * v + 2]);
                        fixed[3 * v] = true;
                        if y < 1e-9 * l && z < 1e-9 * l {
                            fixed[3 * v..3 * v + 3].fill(true);
                        } else if z < 1e-9 * l {
                            fixed[3 * v + 2] = true;
                        }
                    } else {
                        for c in 0..3 {
                            force[3 * v + c] = rng.random_range(-0.03..0.03);
                        }
                    }
                } else if x < 1e-9 * l {
                    fixed[3 * v..3 * v + 3].fill(true);
                } else if (x - l).abs() < 1e-9 * l {
                    fixed[3 * v..3 * v + 3].fill(true);
                    start[3 * v] = stretch * l;
                    start[3 * v + 1] += shear * l;
                } else {
                    start[3 * v] *= stretch;
                    force[3 * v + 2] = load;
                }
            }
            out.push(FitPose {
                force,
                fixed,
                start,
                target: crate::shape_fit::FitTarget {
                    elements: Vec::new(),
                    yarn: Vec::new(),
                },
            });
        }
        // Solve each pose with the truth, then take its shape as the target.
        let shape = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let material = KnitMaterial::new(
            &b.mesh,
            truth.chunks_exact(2).map(|g| [g[0], g[1]]).collect(),
            VolumePreservingParams::default(),
        )
        .unwrap();
        for p in &mut out {
            let mut problem = QuasiStaticProblem::new(
                &material,
                p.force.clone(),
                p.fixed.clone(),
                &QuasiStaticParams::default(),
            )
            .unwrap();
            let mut x = p.start.clone();
            let params = ElasticityFitParams::default().newton;
            let report = minimize(&mut problem, &mut x, &params).unwrap();
            assert!(report.converged, "{report:?}");
            p.target = shape.target_of_positions(&x).unwrap();
        }
        out
    }

    fn identity_map(tets: usize) -> SparseColMat<usize, f64> {
        parameter_map_matrix(2 * tets, 2 * tets, |c| {
            let mut col = vec![0.0; 2 * tets];
            col[c] = SCALE;
            Ok(col)
        })
        .unwrap()
    }

    /// `γˢ = SCALE c₀`, `γᵛ = SCALE c₁` on every element: the rank-1 harmonic space (the constant field).
    fn uniform_map(tets: usize) -> SparseColMat<usize, f64> {
        parameter_map_matrix(2 * tets, 2, |c| {
            Ok((0..2 * tets)
                .map(|r| if r % 2 == c { SCALE } else { 0.0 })
                .collect())
        })
        .unwrap()
    }

    fn random_gamma(tets: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..tets)
            .flat_map(|_| {
                [
                    rng.random_range(800.0..2000.0),
                    rng.random_range(1500.0..4000.0),
                ]
            })
            .collect()
    }

    #[test]
    fn the_adjoint_gradient_matches_central_differences_through_the_equilibrium() {
        let b = block();
        let tets = b.mesh.tets.len();
        let truth = random_gamma(tets, 1);
        let poses = poses(&b, &truth);
        let shape = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let mut params = ElasticityFitParams::default();
        params.newton.tolerance = 1e-13;
        let c: Vec<f64> = random_gamma(tets, 2).iter().map(|g| g / SCALE).collect();
        let fit = std::cell::RefCell::new(
            ElasticityFit::new(&b.mesh, &shape, poses, identity_map(tets), params).unwrap(),
        );
        let (value, gradient) = fit.borrow_mut().evaluate(&c).unwrap();
        assert!(value > 0.0);
        let scale = gradient.iter().fold(0.0_f64, |m, g| m.max(g.abs()));
        assert!(scale > 0.0);
        check_gradient(
            |c| fit.borrow_mut().evaluate(c).unwrap().0,
            &c,
            &gradient,
            &FdParams {
                step: 1e-4,
                rel_tol: 1e-5,
                abs_tol: 1e-6 * scale,
            },
        )
        .unwrap();
    }

    #[test]
    fn gauss_newton_recovers_a_uniform_material_from_half_of_it() {
        let b = block();
        let tets = b.mesh.tets.len();
        let truth_pair = [1500.0, 3000.0];
        let truth: Vec<f64> = (0..tets).flat_map(|_| truth_pair).collect();
        let shape = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let map = uniform_map(tets);
        let mut fit = ElasticityFit::new(
            &b.mesh,
            &shape,
            poses(&b, &truth),
            map.clone(),
            ElasticityFitParams::default(),
        )
        .unwrap();
        let start: Vec<f64> = truth_pair.iter().map(|g| 0.5 * g / SCALE).collect();
        for solver in [GaussNewtonSolver::Reduced, GaussNewtonSolver::Kkt] {
            let clock = std::time::Instant::now();
            let mut problem = AdjointGaussNewton::new(&mut fit, map.clone(), solver);
            let params = GaussNewtonParams {
                gradient_tolerance: 1e-16,
                max_iterations: 50,
                ..Default::default()
            };
            let out = gauss_newton(&mut problem, &start, &params, |_, _| {
                ControlFlow::Continue(())
            })
            .unwrap();
            let gamma: Vec<f64> = out.x.iter().map(|c| c * SCALE).collect();
            eprintln!(
                "uniform fit ({solver:?}): {} GN iterations, {:.3} s, γ = {gamma:?}, loss {:.3e} m³, stop {:?}",
                out.iterations,
                clock.elapsed().as_secs_f64(),
                out.value,
                out.stop_reason
            );
            for (g, t) in gamma.iter().zip(truth_pair) {
                assert!((g - t).abs() < 0.01 * t, "{solver:?}: {gamma:?}");
            }
            assert!(out.iterations < 30, "{}", out.iterations);
        }
    }

    #[test]
    fn gauss_newton_recovers_a_per_element_material_from_a_rank_one_start() {
        // Every element its own γ: the rank-1 (uniform) fit from half the mean first, then all 2#T
        // parameters from there (the harmonic schedule's first and last ranks, Sec. 6.5).
        let b = block();
        let tets = b.mesh.tets.len();
        let truth = random_gamma(tets, 3);
        let shape = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let poses = poses(&b, &truth);
        let params = GaussNewtonParams {
            gradient_tolerance: 1e-16,
            max_iterations: 100,
            ..Default::default()
        };
        let clock = std::time::Instant::now();
        let map = uniform_map(tets);
        let mut fit = ElasticityFit::new(
            &b.mesh,
            &shape,
            poses.clone(),
            map.clone(),
            ElasticityFitParams::default(),
        )
        .unwrap();
        let mean = |k: usize| truth.iter().skip(k).step_by(2).sum::<f64>() / tets as f64;
        let start = [0.5 * mean(0) / SCALE, 0.5 * mean(1) / SCALE];
        let mut problem = AdjointGaussNewton::new(&mut fit, map, GaussNewtonSolver::Reduced);
        let rank1 = gauss_newton(&mut problem, &start, &params, |_, _| {
            ControlFlow::Continue(())
        })
        .unwrap();
        let map = identity_map(tets);
        let mut fit = ElasticityFit::new(
            &b.mesh,
            &shape,
            poses,
            map.clone(),
            ElasticityFitParams::default(),
        )
        .unwrap();
        let start: Vec<f64> = (0..tets).flat_map(|_| rank1.x.clone()).collect();
        let mut problem = AdjointGaussNewton::new(&mut fit, map, GaussNewtonSolver::Reduced);
        let full = gauss_newton(&mut problem, &start, &params, |_, _| {
            ControlFlow::Continue(())
        })
        .unwrap();
        let gamma: Vec<f64> = full.x.iter().map(|c| c * SCALE).collect();
        let worst = gamma
            .iter()
            .zip(&truth)
            .map(|(g, t)| (g - t).abs() / t)
            .fold(0.0, f64::max);
        eprintln!(
            "per-element fit ({} parameters): rank 1 {} + full {} GN iterations, {:.3} s, worst relative γ error {worst:.2e}, loss {:.3e} m³, stop {:?}",
            2 * tets,
            rank1.iterations,
            full.iterations,
            clock.elapsed().as_secs_f64(),
            full.value,
            full.stop_reason
        );
        assert!(
            worst < 0.01,
            "worst relative error {worst}: {:?}",
            gamma
                .iter()
                .zip(&truth)
                .map(|(g, t)| (g - t) / t)
                .collect::<Vec<_>>()
        );
    }

    #[test]
    fn a_vanishing_parameter_is_reached_at_the_bound() {
        // γᵛ* = 0 on every element, γˢ* random: the full per-element fit from γˢ = 1000, γᵛ = 2000 Pa
        // ends with γᵛ clamped at 0 (the trials' negative values projected) and γˢ recovered.
        let b = block();
        let tets = b.mesh.tets.len();
        let truth: Vec<f64> = random_gamma(tets, 5)
            .chunks_exact(2)
            .flat_map(|g| [g[0], 0.0])
            .collect();
        let shape = ShapeFit::new(&b.mesh, &b.yarns, &b.rest, ShapeFitParams::default()).unwrap();
        let map = identity_map(tets);
        let mut fit = ElasticityFit::new(
            &b.mesh,
            &shape,
            poses(&b, &truth),
            map.clone(),
            ElasticityFitParams::default(),
        )
        .unwrap();
        let mut problem = AdjointGaussNewton::new(&mut fit, map, GaussNewtonSolver::Reduced);
        let params = GaussNewtonParams {
            gradient_tolerance: 1e-16,
            max_iterations: 100,
            ..Default::default()
        };
        let start: Vec<f64> = (0..tets).flat_map(|_| [1.0, 2.0]).collect();
        let out = gauss_newton(&mut problem, &start, &params, |_, _| {
            ControlFlow::Continue(())
        })
        .unwrap();
        let gamma: Vec<f64> = out.x.iter().map(|c| c * SCALE).collect();
        eprintln!(
            "bounded fit: {} GN iterations, loss {:.3e} m³, stop {:?}",
            out.iterations, out.value, out.stop_reason
        );
        for (e, (g, t)) in gamma.chunks_exact(2).zip(truth.chunks_exact(2)).enumerate() {
            assert!(
                (g[0] - t[0]).abs() < 0.01 * t[0],
                "element {e}: {g:?} vs {t:?}"
            );
            assert!(
                g[1] >= 0.0 && g[1] < 0.01 * t[0],
                "element {e}: {g:?} vs {t:?}"
            );
        }
    }
}
