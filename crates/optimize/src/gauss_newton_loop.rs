//! A Levenberg-Marquardt-damped Gauss-Newton loop with a halving line search (Sec. 6.3 of the volumetric
//! homogenization paper), for `min_x T(x)` of a [`GaussNewtonProblem`] — e.g. the adjoint Gauss-Newton
//! directions of an equilibrium-constrained least-squares problem ([`crate::AdjointGaussNewton`]).
//!
//! **The problem.** [`crate::Objective::evaluate`] returns the value and the full gradient (units of the problem:
//! `T`, `T` per unit of `x`); an `Err`, a non-finite value or gradient, or a gradient of the wrong length
//! counts as a **step too long** in the line search (e.g. a point the equilibrium cannot be solved at).
//! [`GaussNewtonProblem::direction`] returns the damped Gauss-Newton direction
//! `d = −(2 R_totᵀ R_tot + κ I)⁻¹ g` at the accepted point `x` with gradient `g`; an `Err` makes the loop
//! raise the damping and ask again.
//!
//! **Damping.** `κ = μ ‖g‖₂` with a dimensionless-per-unit-of-`x` factor `μ`: for a problem without
//! residual curvature the direction is `−g / κ`, a step of length `1 / μ` (units of `x`), so `μ` bounds the
//! step like a trust radius. `μ` starts at [`GaussNewtonParams::initial_damping`] and adapts:
//! - a step accepted at full length: by the gain ratio `ρ` of the actual to the model's predicted
//!   decrease, `½(−gᵀd + κ‖d‖²)`, Nielsen's rule `μ ← μ · max(⅓, 1 − (2ρ − 1)³)` (towards pure
//!   Gauss-Newton by up to 3× when the model predicts well, `ρ ≳ 1`; more damping, up to 2×, when it
//!   over-promises, `ρ < ½`), kept in `[10⁻¹⁰, 10¹⁰]`;
//! - a step accepted at a length `α < 1`: `μ ← μ / α` (the model was trusted too far by about `1/α`);
//! - no decrease down to the shortest trial step (and no jump, below), a failed direction solve or a
//!   direction that is not a descent direction: `μ ← 10 μ` and the iteration is tried again from the
//!   same point, at most [`GaussNewtonParams::max_retries`] times in a row, after which the run stops with
//!   [`OptimizerStop::LineSearchFailed`]. `μ` never exceeds `10¹⁰`.
//!
//! **Line search** (backtracking, Nocedal & Wright, *Numerical Optimization*, 2nd ed., Sec. 3.5). Trial
//! steps along `d` start at `α = 1`; the first with `T(x + α d) < T(x)` is accepted. After a trial that
//! did not decrease the loss, `φ(t) = T(x + t d)` is modelled by the quadratic through `φ(0)`,
//! `φ'(0) = gᵀd < 0` and `φ(α)`, whose minimizer
//!
//! ```text
//! α' = −gᵀd α² / (2 (φ(α) − φ(0) − α gᵀd))    (≤ α/2 whenever φ(α) ≥ φ(0))
//! ```
//!
//! is the next trial, kept at least `α / 10`; after a trial that failed (no value) the step is halved.
//! The paper's rule halves after every trial (Sec. 6.3); the model matters where a trial jumps far
//! above `T(x)` — an equilibrium on another branch — and halving then spends trials (each a full
//! equilibrium solve) on steps that are still on that branch.
//! The search gives up below `α = 2^−h`, `h` = [`GaussNewtonParams::max_halvings`] (the shortest step
//! the halving rule tries), or after `h + 1` trials.
//!
//! **A jump ends the run.** When a failed trial's secant slope `(φ(α) − φ(0)) / α` is more than twice
//! that of the failed trial before it (a longer step), the excess `φ(α) − φ(0)` does not vanish with the
//! step as it would if `φ` were continuous at 0: along a convex `φ` the secant slope can only fall as the
//! step shrinks, while the excess of a jump stays about the same, so its slope grows by the factor the
//! backtracking shortened the step, 2–10. The objective jumps at the current point: its value is one the
//! trials do not reach however short the step (a design's trials start from their neighbours'
//! equilibria, a garment that slides or wrinkles has several, and an equilibrium solved loosely can sit
//! off the one a tight solve finds along a soft direction), so no shorter step or stronger damping gets
//! below it. The run stops at once with [`OptimizerStop::LineSearchFailed`] (a coarse-to-fine caller
//! goes on to its next level); what the rule saves is measured in docs/BENCHMARKS.md (session 20).
//!
//! **Step growth.** The first trial of an iteration moves `x` at most [`GaussNewtonParams::max_step_growth`]
//! `γ` times as far (max-norm, units of `x`) as the last accepted step did: `α₀ = min(1, γ ‖α_{k−1}
//! d_{k−1}‖∞ / ‖d_k‖∞)`; a run's first iteration is not bounded (a coarse-to-fine caller starts a run per
//! level, whose variables have their own units). It is a trust region's expansion rule (Nocedal & Wright,
//! Algorithm 4.1, grows the radius at most 2× per iteration) applied to the line search's first trial: the
//! damping `μ` bounds the step only through the gradient's scale, and where the Gauss-Newton model's
//! curvature drops the direction can jump to many times the last step. Where every trial is a full equilibrium
//! solve, such a jump is where the equilibrium leaves its branch (docs/BENCHMARKS.md, session 19). A bounded step accepted at `α₀ < 1` counts as a shortened step (`μ ← μ
//! / α₀`, below), so the damping learns the bound.
//!
//! **Bounds.** Every trial point is passed through [`GaussNewtonProblem::project`] (default: none)
//! before it is evaluated, `x_trial = P(x + α d)`: a projected line search for simple bounds such as
//! the non-negative material parameters of the knitwear paper's Sec. 6.3. The acceptance test (a lower
//! `T`) holds for the projected point as for any other.
//!
//! **Stopping** (checked before every iteration, in this order), as in [`mod@crate::lbfgs`]:
//! [`OptimizerStop::GradientTolerance`] (`‖g‖₂ < gradient_tolerance` or `g = 0`), [`OptimizerStop::NoProgress`]
//! (relative decrease below `min_relative_decrease` for `no_progress_iterations` iterations in a row),
//! [`OptimizerStop::MaxIterations`], [`OptimizerStop::TimeLimit`] (also before every trial evaluation), and
//! [`OptimizerStop::Callback`]. The result always holds the **best point seen**.

use std::ops::ControlFlow;
use std::time::Instant;

use crate::Real;
use crate::optimizer_stop::OptimizerStop;
use crate::problem::GaussNewtonProblem;

/// Settings of [`gauss_newton`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GaussNewtonParams {
    /// Initial damping factor `μ` (> 0, per unit of `x`): `κ = μ ‖g‖`, see the module documentation.
    /// Default 1 (a pure gradient step would move `x` by one unit).
    pub initial_damping: Real,
    /// Stop when `‖g‖₂` is below this (≥ 0, units of the gradient). Default `1e-3`.
    pub gradient_tolerance: Real,
    /// Largest number of accepted steps. Default 100.
    pub max_iterations: usize,
    /// Wall-clock limit (s, > 0), `None` for none. Default `None`.
    pub time_limit_seconds: Option<Real>,
    /// Relative decrease per iteration below which an iteration makes no progress (≥ 0). Default `1e-10`.
    pub min_relative_decrease: Real,
    /// Consecutive no-progress iterations that stop the run (≥ 1). Default 5.
    pub no_progress_iterations: usize,
    /// The line search's reach: at most `max_halvings + 1` trial steps, none shorter than
    /// `2^−max_halvings` (≥ 0). Default 8.
    pub max_halvings: usize,
    /// Most consecutive retries with more damping after a failed line search or direction (≥ 0).
    /// Default 3.
    pub max_retries: usize,
    /// The first trial step of an iteration moves `x` (max-norm) at most this many times as far as the
    /// last accepted step did (≥ 1; `+∞`: no limit); see the module documentation. Default 2.
    pub max_step_growth: Real,
}

impl Default for GaussNewtonParams {
    fn default() -> Self {
        Self {
            initial_damping: 1.0,
            gradient_tolerance: 1e-3,
            max_iterations: 100,
            time_limit_seconds: None,
            min_relative_decrease: 1e-10,
            no_progress_iterations: 5,
            max_halvings: 8,
            max_retries: 3,
            max_step_growth: 2.0,
        }
    }
}

impl GaussNewtonParams {
    /// Checks the settings; the message names the field.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.initial_damping.is_finite() && self.initial_damping > 0.0) {
            return Err(format!(
                "initial_damping must be finite and > 0, got {}",
                self.initial_damping
            ));
        }
        if !(self.gradient_tolerance.is_finite() && self.gradient_tolerance >= 0.0) {
            return Err(format!(
                "gradient_tolerance must be finite and ≥ 0, got {}",
                self.gradient_tolerance
            ));
        }
        if let Some(t) = self.time_limit_seconds
            && (t.is_nan() || t <= 0.0)
        {
            return Err(format!("time_limit_seconds must be > 0, got {t}"));
        }
        if !(self.min_relative_decrease.is_finite() && self.min_relative_decrease >= 0.0) {
            return Err(format!(
                "min_relative_decrease must be finite and ≥ 0, got {}",
                self.min_relative_decrease
            ));
        }
        if self.no_progress_iterations == 0 {
            return Err("no_progress_iterations must be at least 1".into());
        }
        if self.max_step_growth.is_nan() || self.max_step_growth < 1.0 {
            return Err(format!(
                "max_step_growth must be at least 1 (+∞: no limit), got {}",
                self.max_step_growth
            ));
        }
        Ok(())
    }
}

/// What the per-iteration callback sees: the state after an accepted step (iteration 0: the start).
#[derive(Clone, Copy, Debug)]
pub struct GaussNewtonIteration<'a> {
    /// Accepted steps so far.
    pub iteration: usize,
    /// The current point.
    pub x: &'a [Real],
    /// Its value.
    pub value: Real,
    /// Its gradient.
    pub gradient: &'a [Real],
    /// `‖gradient‖₂`.
    pub gradient_norm: Real,
    /// The accepted step length `α` along the direction (0 at the start).
    pub step_length: Real,
    /// The damping factor `μ` for the next direction (per unit of `x`).
    pub damping: Real,
    /// Objective evaluations so far (failed ones included).
    pub evaluations: usize,
    /// Seconds since the start.
    pub elapsed_seconds: Real,
    /// Counters behind [`GaussNewtonIteration::state`]: no-progress iterations, failed evaluations, failed
    /// direction solves.
    counters: (usize, usize, usize),
    /// `‖α d‖∞` of the last accepted step (none yet: `None`).
    last_step: Option<Real>,
}

impl GaussNewtonIteration<'_> {
    /// Everything the run needs to go on from here exactly as it would have (a checkpoint): continue it
    /// with [`gauss_newton_from`].
    pub fn state(&self) -> GaussNewtonState {
        GaussNewtonState {
            iteration: self.iteration,
            x: self.x.to_vec(),
            value: self.value,
            gradient: self.gradient.to_vec(),
            damping: self.damping,
            stalled: self.counters.0,
            evaluations: self.evaluations,
            failed_evaluations: self.counters.1,
            failed_directions: self.counters.2,
            elapsed_seconds: self.elapsed_seconds,
            last_step: self.last_step,
        }
    }
}

/// Where a [`gauss_newton`] run stands after an accepted iteration (see [`GaussNewtonIteration::state`]):
/// the current point (always the best seen), the damping factor and the counters. Serializable, so that a
/// checkpoint can store it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GaussNewtonState {
    /// Accepted steps so far.
    pub iteration: usize,
    /// The current point.
    pub x: Vec<Real>,
    /// Its value.
    pub value: Real,
    /// Its gradient.
    pub gradient: Vec<Real>,
    /// The damping factor `μ` for the next direction (per unit of `x`).
    pub damping: Real,
    /// Consecutive iterations without enough relative decrease.
    pub stalled: usize,
    /// Objective evaluations so far (failed ones included).
    pub evaluations: usize,
    /// Failed evaluations so far.
    pub failed_evaluations: usize,
    /// Failed direction solves so far.
    pub failed_directions: usize,
    /// Seconds the run had taken (counted against `time_limit_seconds` when it goes on).
    pub elapsed_seconds: Real,
    /// How far (max-norm, units of `x`) the last accepted step moved `x`, which bounds the next first
    /// trial ([`GaussNewtonParams::max_step_growth`]); `None` before the first step (and in checkpoints
    /// written before the bound existed).
    #[serde(default)]
    pub last_step: Option<Real>,
}

/// Where [`gauss_newton_from`] starts.
#[derive(Clone, Debug)]
pub enum GaussNewtonStart<'a> {
    /// A fresh run from this point (evaluated first, and reported as iteration 0).
    Point(&'a [Real]),
    /// A run that goes on from a checkpoint: nothing is evaluated or reported until the next accepted step.
    Resume(GaussNewtonState),
}

/// The outcome of [`gauss_newton`]: always the best point seen.
#[derive(Clone, Debug, PartialEq)]
pub struct GaussNewtonOutcome {
    /// The best point seen.
    pub x: Vec<Real>,
    /// Its value.
    pub value: Real,
    /// Its gradient.
    pub gradient: Vec<Real>,
    /// Why the run stopped.
    pub stop_reason: OptimizerStop,
    /// Accepted steps.
    pub iterations: usize,
    /// Objective evaluations (failed ones included).
    pub evaluations: usize,
    /// Failed evaluations.
    pub failed_evaluations: usize,
    /// Direction solves that failed.
    pub failed_directions: usize,
    /// The final damping factor `μ`.
    pub damping: Real,
    /// Seconds the run took.
    pub elapsed_seconds: Real,
}

/// Why [`gauss_newton`] could not run at all.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GaussNewtonRunError<E> {
    /// Impossible settings.
    #[error("invalid Gauss-Newton parameters: {0}")]
    InvalidParameters(String),
    /// The objective failed at the starting point.
    #[error("the objective failed at the starting point: {0}")]
    InitialEvaluation(E),
    /// The starting value or gradient is not usable.
    #[error("the starting point is not usable: {0}")]
    InvalidStart(String),
}

fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The next trial step after `α` raised the loss from `φ(0) = value` to `φ(α) = trial ≥ value`, with
/// `slope = φ'(0) < 0`: the minimizer of the interpolating quadratic, at least `α / 10` (see the module
/// documentation; at most `α / 2` by construction, halving when the quadratic is degenerate).
fn backtrack(alpha: Real, value: Real, slope: Real, trial: Real) -> Real {
    let curvature = trial - value - alpha * slope;
    let minimizer = -slope * alpha * alpha / (2.0 * curvature);
    if minimizer.is_finite() && minimizer > 0.0 {
        minimizer.clamp(0.1 * alpha, 0.5 * alpha)
    } else {
        0.5 * alpha
    }
}

/// A failed trial whose secant slope `(φ(α) − φ(0)) / α` is more than this many times the last failed
/// trial's (a longer step) shows a jump at the current point: the run stops (see the module
/// documentation).
const JUMP_SLOPE_GROWTH: Real = 2.0;

const MU_MIN: Real = 1e-10;
const MU_MAX: Real = 1e10;

/// Minimizes `problem` from `x0` by damped Gauss-Newton (see the module documentation). `callback` sees
/// the start (iteration 0) and every accepted step, with the problem (so that it can read what the
/// evaluations gathered).
pub fn gauss_newton<P, C>(
    problem: &mut P,
    x0: &[Real],
    params: &GaussNewtonParams,
    callback: C,
) -> Result<GaussNewtonOutcome, GaussNewtonRunError<P::Error>>
where
    P: GaussNewtonProblem,
    C: FnMut(&mut P, &GaussNewtonIteration) -> ControlFlow<()>,
{
    gauss_newton_from(problem, GaussNewtonStart::Point(x0), params, callback)
}

/// `‖d‖∞`, the step measure of the growth bound.
fn max_norm(d: &[Real]) -> Real {
    d.iter().fold(0.0, |m, v| m.max(v.abs()))
}

/// [`gauss_newton`] from a point or from a checkpoint ([`GaussNewtonIteration::state`]). Resumed with the
/// same problem and settings, the run takes exactly the steps the uninterrupted run took (time limits
/// aside: the checkpoint's seconds count against `time_limit_seconds`).
pub fn gauss_newton_from<P, C>(
    problem: &mut P,
    from: GaussNewtonStart<'_>,
    params: &GaussNewtonParams,
    mut callback: C,
) -> Result<GaussNewtonOutcome, GaussNewtonRunError<P::Error>>
where
    P: GaussNewtonProblem,
    C: FnMut(&mut P, &GaussNewtonIteration) -> ControlFlow<()>,
{
    params
        .validate()
        .map_err(GaussNewtonRunError::InvalidParameters)?;
    let (resumed, report_start) = match from {
        GaussNewtonStart::Point(x0) => {
            let (value, gradient) = problem
                .evaluate(x0)
                .map_err(GaussNewtonRunError::InitialEvaluation)?;
            let fresh = GaussNewtonState {
                iteration: 0,
                x: x0.to_vec(),
                value,
                gradient,
                damping: params.initial_damping,
                stalled: 0,
                evaluations: 1,
                failed_evaluations: 0,
                failed_directions: 0,
                elapsed_seconds: 0.0,
                last_step: None,
            };
            (fresh, true)
        }
        GaussNewtonStart::Resume(state) => (state, false),
    };
    let GaussNewtonState {
        iteration,
        x,
        value,
        gradient,
        damping,
        stalled,
        evaluations,
        failed_evaluations,
        failed_directions,
        elapsed_seconds,
        last_step,
    } = resumed;
    let start = Instant::now()
        .checked_sub(std::time::Duration::from_secs_f64(elapsed_seconds.max(0.0)))
        .unwrap_or_else(Instant::now);
    let elapsed = || start.elapsed().as_secs_f64();
    let out_of_time = || params.time_limit_seconds.is_some_and(|t| elapsed() >= t);
    if !value.is_finite() {
        return Err(GaussNewtonRunError::InvalidStart(format!(
            "the value is {value}"
        )));
    }
    if gradient.len() != x.len() || gradient.iter().any(|g| !g.is_finite()) {
        return Err(GaussNewtonRunError::InvalidStart(format!(
            "the gradient has {} entries for {} unknowns or is not finite",
            gradient.len(),
            x.len()
        )));
    }
    let (mut x, mut value, mut gradient) = (x, value, gradient);
    let (mut evaluations, mut failed_evaluations, mut failed_directions) =
        (evaluations, failed_evaluations, failed_directions);
    let mut mu = damping;
    let mut iteration = iteration;
    let mut stalled = stalled;
    let mut last_step = last_step;
    let norm = |g: &[Real]| dot(g, g).sqrt();
    // The shortest trial step of a line search, 2^−max_halvings.
    let shortest = (0.5 as Real).powi(params.max_halvings.min(1000) as i32);
    let stop_reason = 'run: {
        let first = GaussNewtonIteration {
            iteration: 0,
            x: &x,
            value,
            gradient: &gradient,
            gradient_norm: norm(&gradient),
            step_length: 0.0,
            damping: mu,
            evaluations,
            elapsed_seconds: elapsed(),
            counters: (stalled, failed_evaluations, failed_directions),
            last_step,
        };
        if report_start && callback(problem, &first).is_break() {
            break 'run OptimizerStop::Callback;
        }
        loop {
            let gnorm = norm(&gradient);
            if gnorm < params.gradient_tolerance || gnorm == 0.0 {
                break 'run OptimizerStop::GradientTolerance;
            }
            if stalled >= params.no_progress_iterations {
                break 'run OptimizerStop::NoProgress;
            }
            if iteration >= params.max_iterations {
                break 'run OptimizerStop::MaxIterations;
            }
            if out_of_time() {
                break 'run OptimizerStop::TimeLimit;
            }
            let mut retries = 0;
            let (next, alpha, predicted, reach) = 'attempt: loop {
                if retries > params.max_retries {
                    break 'run OptimizerStop::LineSearchFailed;
                }
                if out_of_time() {
                    break 'run OptimizerStop::TimeLimit;
                }
                let kappa = mu * gnorm;
                let d = match problem.direction(&x, &gradient, kappa) {
                    Ok(d)
                        if d.len() == x.len()
                            && d.iter().all(|v| v.is_finite())
                            && dot(&d, &gradient) < 0.0 =>
                    {
                        d
                    }
                    _ => {
                        failed_directions += 1;
                        retries += 1;
                        mu = (10.0 * mu).min(MU_MAX);
                        continue;
                    }
                };
                // The decrease the Gauss-Newton model predicts for the full step: with
                // (2RᵀR + κI) d = −g, m(0) − m(d) = −gᵀd − ½dᵀ2RᵀRd = ½(−gᵀd + κ‖d‖²).
                let predicted = 0.5 * (-dot(&gradient, &d) + kappa * dot(&d, &d));
                let slope = dot(&gradient, &d);
                // The first trial: the full step, or as far as the growth bound lets it go.
                let reach = max_norm(&d);
                let mut alpha = match last_step {
                    Some(last) if last > 0.0 && reach > params.max_step_growth * last => {
                        params.max_step_growth * last / reach
                    }
                    _ => 1.0,
                };
                // The last trial of this search that did not lower the loss: its step and excess.
                let mut above: Option<(Real, Real)> = None;
                for _ in 0..=params.max_halvings {
                    if out_of_time() {
                        break 'run OptimizerStop::TimeLimit;
                    }
                    let mut trial: Vec<Real> =
                        x.iter().zip(&d).map(|(x, d)| x + alpha * d).collect();
                    problem.project(&mut trial);
                    evaluations += 1;
                    match problem.evaluate(&trial) {
                        Ok((v, g))
                            if v.is_finite()
                                && g.len() == x.len()
                                && g.iter().all(|g| g.is_finite()) =>
                        {
                            if v < value {
                                break 'attempt ((trial, v, g), alpha, predicted, reach);
                            }
                            let excess = v - value;
                            if let Some((a0, e0)) = above
                                && excess / alpha > JUMP_SLOPE_GROWTH * (e0 / a0)
                            {
                                break 'run OptimizerStop::LineSearchFailed;
                            }
                            above = Some((alpha, excess));
                            alpha = backtrack(alpha, value, slope, v);
                        }
                        _ => {
                            failed_evaluations += 1;
                            alpha *= 0.5;
                        }
                    }
                    // Relative slack: 2^−h itself, reached by halvings, is still tried.
                    if alpha < shortest * (1.0 - 1e-12) {
                        break;
                    }
                }
                retries += 1;
                mu = (10.0 * mu).min(MU_MAX);
            };
            mu = if alpha == 1.0 {
                // Gain ratio ρ = actual / predicted decrease; Nielsen's update.
                let rho = (value - next.1) / predicted;
                let factor = if rho.is_finite() {
                    (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0)
                } else {
                    1.0 / 3.0
                };
                (mu * factor).clamp(MU_MIN, MU_MAX)
            } else {
                (mu / alpha).min(MU_MAX)
            };
            last_step = Some(alpha * reach);
            let (nx, nv, ng) = next;
            let scale = value.abs().max(nv.abs());
            if value - nv < params.min_relative_decrease * scale || scale == 0.0 {
                stalled += 1;
            } else {
                stalled = 0;
            }
            (x, value, gradient) = (nx, nv, ng);
            iteration += 1;
            let info = GaussNewtonIteration {
                iteration,
                x: &x,
                value,
                gradient: &gradient,
                gradient_norm: norm(&gradient),
                step_length: alpha,
                damping: mu,
                evaluations,
                elapsed_seconds: elapsed(),
                counters: (stalled, failed_evaluations, failed_directions),
                last_step,
            };
            if callback(problem, &info).is_break() {
                break 'run OptimizerStop::Callback;
            }
        }
    };
    Ok(GaussNewtonOutcome {
        x,
        value,
        gradient,
        stop_reason,
        iterations: iteration,
        evaluations,
        failed_evaluations,
        failed_directions,
        damping: mu,
        elapsed_seconds: elapsed(),
    })
}

#[cfg(test)]
mod tests;
