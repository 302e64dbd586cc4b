//! Damped Newton minimisation of an energy given by triplets ([`NewtonProblem`]), with the
//! Levenberg–Marquardt shift ([`LevenbergMarquardt`]) and Armijo backtracking: the yarn solves' Newton.
//!
//! One iteration at `x` with energy `E`, gradient `g`, Hessian `H`:
//! 1. factor `H + (μ + μ₀) D` ([`LevenbergMarquardt`]: `D` the scaled diagonal, `μ₀` a floor against
//!    exact null modes), raising `μ` while the factorization fails ([`shifted_factorization`]);
//! 2. `h = −(H + (μ+μ₀)D)⁻¹ g`, scaled down to the problem's step limit ([`NewtonProblem::step_scale`]: a
//!    quarter radius per vertex for yarns, so a step cannot jump a yarn through another);
//! 3. backtracking on the energy (Armijo, `c = 10⁻⁴`, at most 8 halvings); when it fails `μ` is raised
//!    and the iteration repeats; a taken step lowers it.
//!
//! The line search's trial points evaluate the energy alone ([`NewtonProblem::energy`], no derivatives),
//! and the gradient only where Armijo fails but the energy lies in its rounding band (`10⁻¹² |E|`): there
//! a step that lowers the residual is taken, since the energy change drowns in rounding near a minimum.
//! The Hessian's triplets become compressed columns once an iteration ([`compressed_lower`]) and are
//! scattered into the pattern held by the [`NewtonWorkspace`] ([`PatternCache`]), so a shift retry costs
//! the numeric factorization alone and an analysis is made only when an entry falls outside the pattern.
//! `μ` starts where the previous solve on the same workspace ended (successive time steps need about the
//! same shift, and a climb from 0 costs failed factorizations).
//! [`NewtonParams`] can switch each of these off (`energy_line_search`, `reuse_analysis`, `warm_shift`)
//! to measure it; [`MinimizeFigures::timings`] says where the time went. Measurements:
//! docs/BENCHMARKS.md ("Moved from module docs (issue 42, newton)").
//!
//! **Why this solver**: contact and compressed rods make `H` indefinite away from equilibrium, and the
//! shift keeps the sparse Cholesky usable (a positive definite matrix for every accepted shift) instead
//! of an indefinite LDLᵀ, whose faer version has no pivoting for sparse matrices; near a stable
//! equilibrium `μ → 0` and the iteration is plain Newton (quadratic convergence).
//!
//! Converged when the problem's scaled residual ([`NewtonProblem::residual`]) is at most the tolerance.
//! Iteration and factorization limits end with `converged = false` and the last accepted state — never a
//! hang.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::{
    DampingPolicy, LevenbergMarquardt, MinimizeFigures, NewtonProblem, NewtonReport, NewtonTimings,
    PatternCache, StopReason, add_to_diagonal, compressed_lower, shifted_factorization,
};
use crate::sparse_cholesky::{CholeskyError, Ordering, SparseCholeskyParams};

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
    /// Trial points of the line search evaluate the energy alone ([`NewtonProblem::energy`]), and the
    /// gradient only in the rounding band; `false` evaluates the gradient at every trial point (kept to
    /// measure the difference).
    pub energy_line_search: bool,
    /// Keep the analyzed sparsity pattern while every new matrix fits in it (a union of the recent
    /// patterns, [`PatternCache`]); `false` analyzes at every iteration.
    pub reuse_analysis: bool,
    /// Start from the shift `μ` the previous solve on the same workspace ended with; `false` starts at 0.
    pub warm_shift: bool,
}

impl Default for NewtonParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-9,
            max_iterations: 300,
            max_factorizations: 1500,
            trace: false,
            energy_line_search: true,
            reuse_analysis: true,
            warm_shift: true,
        }
    }
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

/// What [`minimize_with`] keeps between solves: the analyzed sparsity pattern with its symbolic Cholesky
/// factorization, and the last Levenberg–Marquardt shift. Cloning gives an empty workspace (a cache).
#[derive(Debug, Default)]
pub struct NewtonWorkspace {
    patterns: PatternCache,
    mu: f64,
}

impl NewtonWorkspace {
    /// The Levenberg–Marquardt shift the next solve starts from (dimensionless; see the module doc).
    pub fn shift(&self) -> f64 {
        self.mu
    }

    /// Sets the starting shift (a resumed run's; negative or non-finite values count as 0).
    pub fn set_shift(&mut self, mu: f64) {
        self.mu = if mu.is_finite() { mu.max(0.0) } else { 0.0 };
    }
}

impl Clone for NewtonWorkspace {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// Why a factorization attempt of [`minimize_with`] failed.
enum Attempt {
    /// The most factorizations allowed were made.
    Limit,
    Cholesky(CholeskyError),
}

/// Minimises `problem`'s energy from `x` (updated in place) with a fresh [`NewtonWorkspace`].
pub fn minimize(
    problem: &mut impl NewtonProblem,
    x: &mut [f64],
    params: &NewtonParams,
) -> Result<NewtonReport, NewtonError> {
    minimize_with(problem, x, params, &mut NewtonWorkspace::default())
}

/// Minimises `problem`'s energy from `x` (updated in place), reusing and updating `workspace` (the
/// analyzed pattern and the starting shift; pass the same workspace to the solves of successive time
/// steps).
pub fn minimize_with(
    problem: &mut impl NewtonProblem,
    x: &mut [f64],
    params: &NewtonParams,
    workspace: &mut NewtonWorkspace,
) -> Result<NewtonReport, NewtonError> {
    let start = Instant::now();
    let mut timings = NewtonTimings::default();
    let n = problem.dof_count();
    let clock = Instant::now();
    let (mut energy, mut g, mut triplets) = problem.evaluate(x, true);
    timings.evaluation += clock.elapsed().as_secs_f64();
    if !energy.is_finite() || g.iter().any(|v| !v.is_finite()) {
        return Err(NewtonError::NonFinite);
    }
    workspace.patterns.keep_if_size(n);
    let mut residual = problem.residual(&g);
    let mut lm = LevenbergMarquardt {
        mu: if params.warm_shift { workspace.mu } else { 0.0 },
    };
    let mut iterations = 0;
    let mut factorizations = 0;
    let chol_params = SparseCholeskyParams {
        ordering: Ordering::Amd,
        threads: None,
    };
    let stop;
    'outer: loop {
        if residual <= params.tolerance {
            stop = StopReason::Converged;
            break;
        }
        if iterations >= params.max_iterations {
            stop = StopReason::IterationLimit;
            break;
        }
        if problem.interrupted() {
            stop = StopReason::Cancelled;
            break;
        }
        // Assemble once per iteration: the lower triangle with every diagonal entry present, scattered into
        // the analyzed pattern (analyzed anew only when an entry falls outside it).
        let clock = Instant::now();
        if let Some(t) = triplets.iter().find(|t| t.row >= n || t.col > t.row) {
            return Err(CholeskyError::NotLowerTriangular {
                row: t.row,
                col: t.col,
            }
            .into());
        }
        let matrix = compressed_lower(n, &triplets);
        let base = if params.reuse_analysis {
            workspace.patterns.scatter(&matrix)
        } else {
            None
        };
        timings.assembly += clock.elapsed().as_secs_f64();
        let base = match base {
            Some(base) => base,
            None => {
                let clock = Instant::now();
                let base = workspace.patterns.analyze(
                    &matrix,
                    problem.group_size(),
                    params.reuse_analysis,
                    &chol_params,
                    params.trace,
                )?;
                timings.analyses += 1;
                timings.analysis += clock.elapsed().as_secs_f64();
                base
            }
        };
        drop(matrix);
        let pattern = workspace.patterns.pattern_mut().expect("analyzed above");
        let diag: Vec<f64> = pattern.diagonal.iter().map(|&p| base[p]).collect();
        let dscale = LevenbergMarquardt::scaling(&diag);
        let mut accepted = false;
        let mut values = base.clone();
        while !accepted {
            let factored = shifted_factorization(
                lm.mu,
                |mu| Some(LevenbergMarquardt::raised(mu)),
                |mu| {
                    if factorizations >= params.max_factorizations {
                        return Err(Attempt::Limit);
                    }
                    let clock = Instant::now();
                    values.copy_from_slice(&base);
                    let shift = LevenbergMarquardt { mu }.factored_shift();
                    add_to_diagonal(&mut values, &pattern.diagonal, shift, &dscale);
                    let result = pattern.factorize(&values);
                    factorizations += 1;
                    timings.factorization += clock.elapsed().as_secs_f64();
                    result.map_err(Attempt::Cholesky)
                },
                |e| {
                    matches!(
                        e,
                        Attempt::Cholesky(CholeskyError::NotPositiveDefinite { .. })
                    )
                },
            );
            match factored {
                Ok(mu) => lm.mu = mu,
                Err((mu, Attempt::Limit)) => {
                    lm.mu = mu;
                    stop = StopReason::FactorizationLimit;
                    break 'outer;
                }
                Err((_, Attempt::Cholesky(e))) => return Err(e.into()),
            }
            let clock = Instant::now();
            let mut h: Vec<f64> = g.iter().map(|v| -v).collect();
            pattern.chol.solve_in_place(&mut h)?;
            timings.solve += clock.elapsed().as_secs_f64();
            let scale = problem.step_scale(&h);
            for v in &mut h {
                *v *= scale;
            }
            let slope: f64 = g.iter().zip(&h).map(|(a, b)| a * b).sum();
            let mut alpha = 1.0;
            let clock = Instant::now();
            for _ in 0..9 {
                let trial: Vec<f64> = x.iter().zip(&h).map(|(a, b)| a + alpha * b).collect();
                let armijo_bound = energy + 1e-4 * alpha * slope;
                let rounding_bound = energy + 1e-12 * energy.abs();
                // The energy alone decides Armijo; the gradient (for the residual) is needed only in the
                // rounding band.
                let (e_trial, r_trial) = if params.energy_line_search {
                    let e = problem.energy(&trial);
                    if e.is_finite() && e > armijo_bound && e <= rounding_bound {
                        let (e, g_trial, _) = problem.evaluate(&trial, false);
                        (e, problem.residual(&g_trial))
                    } else {
                        (e, f64::INFINITY)
                    }
                } else {
                    let (e, g_trial, _) = problem.evaluate(&trial, false);
                    (e, problem.residual(&g_trial))
                };
                let armijo = e_trial <= armijo_bound;
                // Near the minimum the energy change drowns in rounding: accept a step that keeps the
                // energy within its rounding band and lowers the residual.
                let rounding = e_trial <= rounding_bound && r_trial < residual;
                if e_trial.is_finite() && (armijo || rounding) {
                    timings.line_search += clock.elapsed().as_secs_f64();
                    x.copy_from_slice(&trial);
                    problem.accepted(x);
                    let clock = Instant::now();
                    let (e, gg, tt) = problem.evaluate(x, true);
                    timings.evaluation += clock.elapsed().as_secs_f64();
                    energy = e;
                    g = gg;
                    problem.recycle(std::mem::replace(&mut triplets, tt));
                    residual = problem.residual(&g);
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            if !accepted {
                timings.line_search += clock.elapsed().as_secs_f64();
            }
            if params.trace {
                let mu = lm.mu;
                eprintln!(
                    "newton {iterations}: energy {energy:.6e} residual {residual:.3e} mu {mu:.1e} step scale {scale:.2e} alpha {alpha:.2e} accepted {accepted}"
                );
            }
            if accepted {
                iterations += 1;
                // The Levenberg–Marquardt rule does not read the step's quality.
                lm.accepted(1.0);
            } else {
                lm.rejected();
                if lm.exhausted() {
                    stop = StopReason::NoProgress;
                    break 'outer;
                }
            }
        }
    }
    workspace.mu = lm.mu;
    Ok(NewtonReport {
        converged: residual <= params.tolerance,
        stop,
        iterations,
        factorizations,
        residual,
        energy,
        damping: lm.mu,
        figures: MinimizeFigures {
            seconds: start.elapsed().as_secs_f64(),
            timings,
        },
    })
}
