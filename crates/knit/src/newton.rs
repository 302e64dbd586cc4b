//! Damped Newton minimisation of a yarn energy with the workspace's sparse Cholesky
//! ([`skintight_physics::SparseCholesky`]).
//!
//! One iteration at `x` with energy `E`, gradient `g`, Hessian `H`:
//! 1. factor `H + (μ + μ₀) D` with `D = diag(max(|H_ii|, 10⁻¹²·max|H_ii|))` (Levenberg–Marquardt scaling, so `μ`
//!    is dimensionless and means the same for positions and angles) and `μ₀ = 10⁻¹⁰` a floor that removes
//!    the exact null modes (rigid translation of a periodic cell; a global spin of the material frames when
//!    the rest curvature is zero). If the factorization fails (`H` indefinite — rods under compression,
//!    contact), `μ ← max(10 μ, 10⁻⁶)` and factor again;
//! 2. `h = −(H + (μ+μ₀)D)⁻¹ g`, scaled down to the problem's step limit ([`NewtonProblem::step_scale`]: a
//!    quarter radius per vertex for yarns, so a step cannot jump a yarn through another);
//! 3. backtracking on the energy (Armijo, `c = 10⁻⁴`, at most 8 halvings); when it fails `μ` grows ×10 and
//!    the iteration repeats; a taken step divides `μ` by 3 (to 0 below 10⁻⁸).
//!
//! **Why this solver**: contact and compressed rods make `H` indefinite away from equilibrium, and the
//! Levenberg–Marquardt shift keeps the sparse Cholesky of the garment solver usable (a PD matrix for
//! every accepted shift) instead of an indefinite LDLᵀ, whose faer version has no pivoting for sparse
//! matrices; near a stable equilibrium `μ → 0` and the iteration is plain Newton (quadratic convergence).
//!
//! Converged when the problem's scaled residual ([`NewtonProblem::residual`]) is at most the tolerance.
//! Iteration limits end with `converged = false` and the last accepted state — never a hang.

use std::time::Instant;

use faer::sparse::{SparseColMat, Triplet};
use serde::{Deserialize, Serialize};
use skintight_physics::{CholeskyError, Ordering, SparseCholesky, SparseCholeskyParams};

/// A problem for [`minimize`].
pub trait NewtonProblem {
    /// Number of unknowns.
    fn dof_count(&self) -> usize;
    /// Energy, gradient and (if `hessian`) the lower triangle of the Hessian at `x`.
    fn evaluate(
        &self,
        x: &[f64],
        hessian: bool,
    ) -> (f64, Vec<f64>, Vec<Triplet<usize, usize, f64>>);
    /// The dimensionless residual of gradient `g` (force over the problem's force scale).
    fn residual(&self, g: &[f64]) -> f64;
    /// The factor in `(0, 1]` that brings step `h` within the problem's step limit.
    fn step_scale(&self, h: &[f64]) -> f64;
    /// Called after every accepted step (frame updates); must leave the energy at `x` unchanged.
    fn accepted(&mut self, x: &[f64]);
}

/// Settings of [`minimize`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct NewtonParams {
    /// Converged when the residual is at most this (dimensionless).
    pub tolerance: f64,
    /// Most Newton iterations (each may factor several times).
    pub max_iterations: usize,
    /// Most factorizations in all.
    pub max_factorizations: usize,
    /// Print one line per iteration to stderr.
    pub trace: bool,
}

impl Default for NewtonParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-9,
            max_iterations: 300,
            max_factorizations: 1500,
            trace: false,
        }
    }
}

/// What [`minimize`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NewtonReport {
    /// Whether the residual reached the tolerance.
    pub converged: bool,
    /// Accepted Newton steps.
    pub iterations: usize,
    /// Cholesky factorizations.
    pub factorizations: usize,
    /// Final residual (dimensionless).
    pub residual: f64,
    /// Final energy (J).
    pub energy: f64,
    /// Final damping `μ`.
    pub damping: f64,
    /// Wall-clock time (s).
    pub seconds: f64,
    /// Why the solve stopped.
    pub stop: String,
}

/// Errors of [`minimize`].
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum NewtonError {
    /// The linear solver failed other than by indefiniteness.
    #[error("sparse Cholesky failed: {0}")]
    Cholesky(#[from] CholeskyError),
    /// The energy or gradient is not finite at the start.
    #[error("the energy or its gradient is not finite at the starting state")]
    NonFinite,
}

const MU_FLOOR: f64 = 1e-10;

/// Minimises `problem`'s energy from `x` (updated in place).
pub fn minimize(
    problem: &mut impl NewtonProblem,
    x: &mut [f64],
    params: &NewtonParams,
) -> Result<NewtonReport, NewtonError> {
    let start = Instant::now();
    let n = problem.dof_count();
    let (mut energy, mut g, mut triplets) = problem.evaluate(x, true);
    if !energy.is_finite() || g.iter().any(|v| !v.is_finite()) {
        return Err(NewtonError::NonFinite);
    }
    let mut residual = problem.residual(&g);
    let mut mu = 0.0f64;
    let mut iterations = 0;
    let mut factorizations = 0;
    let chol_params = SparseCholeskyParams {
        ordering: Ordering::Amd,
        threads: None,
    };
    let stop;
    'outer: loop {
        if residual <= params.tolerance {
            stop = "converged".to_string();
            break;
        }
        if iterations >= params.max_iterations {
            stop = "iteration limit".to_string();
            break;
        }
        // Diagonal scaling D.
        let mut diag = vec![0.0f64; n];
        for t in &triplets {
            if t.row == t.col {
                diag[t.row] += t.val;
            }
        }
        let dmax = diag.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
        let dscale: Vec<f64> = diag.iter().map(|v| v.abs().max(1e-12 * dmax)).collect();
        let mut accepted = false;
        while !accepted {
            if factorizations >= params.max_factorizations {
                stop = "factorization limit".to_string();
                break 'outer;
            }
            let mut entries = triplets.clone();
            for (i, s) in dscale.iter().enumerate() {
                entries.push(Triplet::new(i, i, (mu + MU_FLOOR) * s));
            }
            let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &entries)
                .map_err(|e| CholeskyError::Analysis(format!("{e:?}")))?;
            let mut chol = SparseCholesky::analyze(matrix.as_ref(), &chol_params)?;
            factorizations += 1;
            match chol.factorize(matrix.as_ref()) {
                Ok(()) => {}
                Err(CholeskyError::NotPositiveDefinite { .. }) => {
                    mu = (mu * 10.0).max(1e-6);
                    continue;
                }
                Err(e) => return Err(e.into()),
            }
            let mut h: Vec<f64> = g.iter().map(|v| -v).collect();
            chol.solve_in_place(&mut h)?;
            let scale = problem.step_scale(&h);
            for v in &mut h {
                *v *= scale;
            }
            let slope: f64 = g.iter().zip(&h).map(|(a, b)| a * b).sum();
            let mut alpha = 1.0;
            for _ in 0..9 {
                let trial: Vec<f64> = x.iter().zip(&h).map(|(a, b)| a + alpha * b).collect();
                let (e_trial, g_trial, _) = problem.evaluate(&trial, false);
                let r_trial = problem.residual(&g_trial);
                let armijo = e_trial <= energy + 1e-4 * alpha * slope;
                // Near the minimum the energy change drowns in rounding: accept a step that keeps the
                // energy within its rounding band and lowers the residual.
                let rounding = e_trial <= energy + 1e-12 * energy.abs() && r_trial < residual;
                if e_trial.is_finite() && (armijo || rounding) {
                    x.copy_from_slice(&trial);
                    problem.accepted(x);
                    let (e, gg, tt) = problem.evaluate(x, true);
                    energy = e;
                    g = gg;
                    triplets = tt;
                    residual = problem.residual(&g);
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            if params.trace {
                eprintln!(
                    "newton {iterations}: energy {energy:.6e} residual {residual:.3e} mu {mu:.1e} step scale {scale:.2e} alpha {alpha:.2e} accepted {accepted}"
                );
            }
            if accepted {
                iterations += 1;
                mu = if mu < 1e-8 { 0.0 } else { mu / 3.0 };
            } else {
                mu = (mu * 10.0).max(1e-6);
                if mu > 1e12 {
                    stop = "no descent step found".to_string();
                    break 'outer;
                }
            }
        }
    }
    Ok(NewtonReport {
        converged: residual <= params.tolerance,
        iterations,
        factorizations,
        residual,
        energy,
        damping: mu,
        seconds: start.elapsed().as_secs_f64(),
        stop,
    })
}
