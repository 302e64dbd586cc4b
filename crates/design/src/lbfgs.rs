//! Limited-memory BFGS (Nocedal & Wright, *Numerical Optimization*, 2nd ed., Alg. 7.4–7.5) with a
//! strong-Wolfe line search (Alg. 3.5 bracketing, Alg. 3.6 zoom), for the pattern design problem
//! `min_p T(p)`.
//!
//! The objective is a callback `FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>` returning the value and
//! the gradient (units: those of the problem — `T` and `T` per unit of `x`). An evaluation may fail (a
//! simulation that does not converge): an `Err`, a non-finite value or gradient entry, or a gradient of the
//! wrong length **counts as "step too long"** inside the line search — the step is shrunk and retried, and
//! never again extended beyond the failed one. At the starting point a failure is a hard error
//! ([`LbfgsError`]).
//!
//! **Direction.** The two-loop recursion over the last [`LbfgsParams::memory`] pairs `(s, y)`, with the
//! initial inverse Hessian `γ I`, `γ = sᵀy / yᵀy` of the newest pair. A pair is stored only when
//! `sᵀy > 10⁻¹⁰ ‖s‖ ‖y‖` (always true after a strong-Wolfe step of a smooth function). Without memory the
//! direction is `−g` and the first trial step has length [`LbfgsParams::initial_step_length`] (trial
//! `α = min(1, L / ‖g‖)`, after N&W §3.5); otherwise the first trial is `α = 1`.
//!
//! **Line search.** Accepts `α` when `φ(α) ≤ φ(0) + c1 α φ'(0)` and `|φ'(α)| ≤ c2 |φ'(0)|`
//! (`φ(α) = T(x + α d)`). Bracketing doubles `α` (or bisects towards the smallest failed step) until the
//! interval holds a Wolfe point; zoom picks the minimizer of the cubic through both ends' values and
//! slopes, else of the quadratic through the low end's value and slope and the high end's value, else
//! bisects; the trial is kept at least 10 % of the interval away from either end (else bisection), so the
//! interval shrinks geometrically. It gives up after [`LbfgsParams::max_line_search_evaluations`]
//! evaluations or when the interval has collapsed. **When it gives up** having seen a trial with
//! sufficient decrease (but none meeting the curvature condition — an objective known only to the
//! accuracy of its equilibrium solves is not smooth at the finest scales), it moves to the lowest such
//! trial; the curvature pair is stored only if `yᵀs > 0`. With no such trial, the memory is cleared and
//! the steepest-descent direction is tried once from the same point; if that fails as well the run stops
//! with [`StopReason::LineSearchFailed`].
//!
//! **Stopping** (checked before every iteration, in this order):
//! - [`StopReason::GradientTolerance`]: `‖g‖₂ < gradient_tolerance` (absolute, in the gradient's units;
//!   default `1e-3`), or `g = 0` exactly;
//! - [`StopReason::NoProgress`]: for [`LbfgsParams::no_progress_iterations`] consecutive iterations
//!   (default 5) the relative decrease `(T_{k−1} − T_k) / max(|T_{k−1}|, |T_k|)` was below
//!   [`LbfgsParams::min_relative_decrease`] (default `1e-10`);
//! - [`StopReason::MaxIterations`]: [`LbfgsParams::max_iterations`] accepted steps;
//! - [`StopReason::TimeLimit`]: [`LbfgsParams::time_limit_seconds`] passed (also checked before every
//!   evaluation inside a line search, so a run overruns by at most one evaluation);
//! - [`StopReason::Callback`]: the per-iteration callback returned `ControlFlow::Break`;
//! - [`StopReason::LineSearchFailed`]: see above.
//!
//! Whatever the reason, the result holds the **best point seen** (lowest value among all successful
//! evaluations, line-search trials included), its value, gradient and gradient norm.

use std::collections::VecDeque;
use std::ops::ControlFlow;
use std::time::Instant;

use crate::math::Real;

/// Settings of [`lbfgs`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LbfgsParams {
    /// Number of stored `(s, y)` pairs `m` (≥ 1). Default 8.
    pub memory: usize,
    /// Stop when the gradient's Euclidean norm is below this (≥ 0, absolute, units of the gradient).
    /// Default `1e-3`.
    pub gradient_tolerance: Real,
    /// Largest number of iterations (accepted steps). Default 1000.
    pub max_iterations: usize,
    /// Wall-clock limit (s, > 0), `None` for none. Default `None`.
    pub time_limit_seconds: Option<Real>,
    /// Relative decrease per iteration below which an iteration counts as making no progress (≥ 0,
    /// dimensionless). Default `1e-10`.
    pub min_relative_decrease: Real,
    /// Number of consecutive no-progress iterations that stop the run (≥ 1). Default 5.
    pub no_progress_iterations: usize,
    /// Sufficient-decrease constant `c1` (Armijo), `0 < c1 < c2`. Default `1e-4`.
    pub c1: Real,
    /// Curvature constant `c2` (strong Wolfe), `c1 < c2 < 1`. Default `0.9`.
    pub c2: Real,
    /// Length of the first trial step along the steepest-descent direction, in the units of `x` (> 0):
    /// the trial is `α = min(1, L / ‖g‖)`. Default 1.
    pub initial_step_length: Real,
    /// Largest number of evaluations in one line search (≥ 1). Default 30.
    pub max_line_search_evaluations: usize,
}

impl Default for LbfgsParams {
    fn default() -> Self {
        Self {
            memory: 8,
            gradient_tolerance: 1e-3,
            max_iterations: 1000,
            time_limit_seconds: None,
            min_relative_decrease: 1e-10,
            no_progress_iterations: 5,
            c1: 1e-4,
            c2: 0.9,
            initial_step_length: 1.0,
            max_line_search_evaluations: 30,
        }
    }
}

impl LbfgsParams {
    fn validate(&self) -> Result<(), String> {
        let finite_nonneg = |v: Real| v.is_finite() && v >= 0.0;
        if self.memory == 0 {
            return Err("memory must be at least 1".into());
        }
        if !finite_nonneg(self.gradient_tolerance) {
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
        if !finite_nonneg(self.min_relative_decrease) {
            return Err(format!(
                "min_relative_decrease must be finite and ≥ 0, got {}",
                self.min_relative_decrease
            ));
        }
        if self.no_progress_iterations == 0 {
            return Err("no_progress_iterations must be at least 1".into());
        }
        if !(self.c1 > 0.0 && self.c1 < self.c2 && self.c2 < 1.0) {
            return Err(format!(
                "the Wolfe constants must satisfy 0 < c1 < c2 < 1, got c1 = {}, c2 = {}",
                self.c1, self.c2
            ));
        }
        if !(self.initial_step_length.is_finite() && self.initial_step_length > 0.0) {
            return Err(format!(
                "initial_step_length must be finite and > 0, got {}",
                self.initial_step_length
            ));
        }
        if self.max_line_search_evaluations == 0 {
            return Err("max_line_search_evaluations must be at least 1".into());
        }
        Ok(())
    }
}

/// Why [`lbfgs`] stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// `‖g‖ < gradient_tolerance`.
    GradientTolerance,
    /// Too little relative decrease for several iterations.
    NoProgress,
    /// The line search found no strong-Wolfe step, neither along the quasi-Newton direction nor along
    /// steepest descent.
    LineSearchFailed,
    /// `max_iterations` reached.
    MaxIterations,
    /// `time_limit_seconds` passed.
    TimeLimit,
    /// The per-iteration callback asked to stop.
    Callback,
}

/// What the per-iteration callback sees: the state after an accepted step (iteration 0: the start).
#[derive(Clone, Copy, Debug)]
pub struct LbfgsIteration<'a> {
    /// Iteration number (accepted steps so far; 0 at the start).
    pub iteration: usize,
    /// The current point.
    pub x: &'a [Real],
    /// Its value.
    pub value: Real,
    /// Its gradient.
    pub gradient: &'a [Real],
    /// `‖gradient‖₂`.
    pub gradient_norm: Real,
    /// The accepted step length `α` along the search direction (0 at the start).
    pub step_length: Real,
    /// Whether the step was taken along steepest descent (no memory: first iteration or a restart).
    pub steepest_descent: bool,
    /// Objective evaluations so far (including failed ones).
    pub evaluations: usize,
    /// Seconds since the start of the run.
    pub elapsed_seconds: Real,
}

/// The outcome of [`lbfgs`]: always the best point seen.
#[derive(Clone, Debug, PartialEq)]
pub struct LbfgsResult {
    /// The best point seen (lowest value).
    pub x: Vec<Real>,
    /// Its value.
    pub value: Real,
    /// Its gradient.
    pub gradient: Vec<Real>,
    /// `‖gradient‖₂`.
    pub gradient_norm: Real,
    /// Why the run stopped.
    pub stop_reason: StopReason,
    /// Accepted steps.
    pub iterations: usize,
    /// Objective evaluations (including failed ones).
    pub evaluations: usize,
    /// Evaluations that failed (`Err`, non-finite, wrong gradient length).
    pub failed_evaluations: usize,
    /// Seconds the run took.
    pub elapsed_seconds: Real,
}

/// Why [`lbfgs`] could not run at all.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LbfgsError<E> {
    /// Impossible settings.
    #[error("invalid L-BFGS parameters: {0}")]
    InvalidParameters(String),
    /// The objective failed at the starting point.
    #[error("the objective failed at the starting point: {0}")]
    InitialEvaluation(E),
    /// The objective's value or gradient at the starting point is not usable.
    #[error("the starting point is not usable: {0}")]
    InvalidStart(String),
}

fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[Real]) -> Real {
    dot(a, a).sqrt()
}

/// A successfully evaluated point.
#[derive(Clone, Debug)]
struct Point {
    x: Vec<Real>,
    value: Real,
    gradient: Vec<Real>,
}

/// Wraps the objective: counts, times, and keeps the best point.
struct Evaluator<'f, F> {
    objective: &'f mut F,
    evaluations: usize,
    failed: usize,
    best: Point,
    start: Instant,
    time_limit: Option<Real>,
}

impl<F, E> Evaluator<'_, F>
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
{
    fn elapsed(&self) -> Real {
        self.start.elapsed().as_secs_f64()
    }

    fn out_of_time(&self) -> bool {
        self.time_limit.is_some_and(|t| self.elapsed() >= t)
    }

    /// `None` when the evaluation failed.
    fn evaluate(&mut self, x: &[Real]) -> Option<Point> {
        self.evaluations += 1;
        match (self.objective)(x) {
            Ok((value, gradient))
                if value.is_finite()
                    && gradient.len() == x.len()
                    && gradient.iter().all(|g| g.is_finite()) =>
            {
                let point = Point {
                    x: x.to_vec(),
                    value,
                    gradient,
                };
                if value < self.best.value {
                    self.best = point.clone();
                }
                Some(point)
            }
            _ => {
                self.failed += 1;
                None
            }
        }
    }
}

/// One line-search trial: step length, and the point, value and slope `φ'(α)` when it succeeded.
struct Trial {
    alpha: Real,
    point: Option<(Point, Real)>,
}

enum Search {
    Accepted(Point, Real),
    Failed,
    OutOfTime,
}

/// Minimizer of the cubic interpolating `(a, fa, da)` and `(b, fb, db)` (N&W Eq. 3.59), if it exists.
fn cubic_minimizer(a: Real, fa: Real, da: Real, b: Real, fb: Real, db: Real) -> Option<Real> {
    let d1 = da + db - 3.0 * (fa - fb) / (a - b);
    let disc = d1 * d1 - da * db;
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let d2 = (b - a).signum() * disc.sqrt();
    let denom = db - da + 2.0 * d2;
    let t = b - (b - a) * (db + d2 - d1) / denom;
    t.is_finite().then_some(t)
}

/// Minimizer of the quadratic with value `fa` and slope `da` at `a` and value `fb` at `b`, if convex.
fn quadratic_minimizer(a: Real, fa: Real, da: Real, b: Real, fb: Real) -> Option<Real> {
    let h = b - a;
    let curvature = fb - fa - da * h;
    if curvature.is_nan() || curvature <= 0.0 {
        return None;
    }
    let t = a - da * h * h / (2.0 * curvature);
    t.is_finite().then_some(t)
}

/// The next zoom trial between `lo` (successful) and `hi` (successful or failed).
fn zoom_trial(lo: &Trial, lo_values: (Real, Real), hi: &Trial) -> Real {
    let (a, b) = (lo.alpha, hi.alpha);
    let (fa, da) = lo_values;
    let candidate = hi.point.as_ref().and_then(|(p, db)| {
        cubic_minimizer(a, fa, da, b, p.value, *db)
            .or_else(|| quadratic_minimizer(a, fa, da, b, p.value))
    });
    let margin = 0.1 * (b - a).abs();
    let (low, high) = (a.min(b) + margin, a.max(b) - margin);
    match candidate {
        Some(t) if t >= low && t <= high => t,
        _ => 0.5 * (a + b),
    }
}

fn line_search<F, E>(
    ev: &mut Evaluator<'_, F>,
    start: &Point,
    direction: &[Real],
    alpha_init: Real,
    params: &LbfgsParams,
) -> Search
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
{
    let mut sufficient = None;
    match wolfe_search(ev, start, direction, alpha_init, params, &mut sufficient) {
        // A search that cannot meet the curvature condition (an objective known only to the accuracy of
        // its equilibrium solves is not smooth at the finest scales) still moves to its lowest trial with
        // sufficient decrease, if it had one.
        Search::Failed => match sufficient {
            Some((p, alpha)) => Search::Accepted(p, alpha),
            None => Search::Failed,
        },
        outcome => outcome,
    }
}

/// The strong-Wolfe search of [`line_search`]; `sufficient` keeps the lowest trial that satisfied the
/// sufficient-decrease condition.
fn wolfe_search<F, E>(
    ev: &mut Evaluator<'_, F>,
    start: &Point,
    direction: &[Real],
    alpha_init: Real,
    params: &LbfgsParams,
    sufficient: &mut Option<(Point, Real)>,
) -> Search
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
{
    let f0 = start.value;
    let mut keep = |p: &Point, alpha: Real| {
        if sufficient.as_ref().is_none_or(|(b, _)| p.value < b.value) {
            *sufficient = Some((p.clone(), alpha));
        }
    };
    let slope0 = dot(&start.gradient, direction);
    let mut evaluations = 0;
    let mut try_step = |ev: &mut Evaluator<'_, F>, alpha: Real| -> Result<Trial, Search> {
        if evaluations >= params.max_line_search_evaluations {
            return Err(Search::Failed);
        }
        if ev.out_of_time() {
            return Err(Search::OutOfTime);
        }
        evaluations += 1;
        let x: Vec<Real> = start
            .x
            .iter()
            .zip(direction)
            .map(|(x, d)| x + alpha * d)
            .collect();
        let point = ev.evaluate(&x).map(|p| {
            let slope = dot(&p.gradient, direction);
            (p, slope)
        });
        Ok(Trial { alpha, point })
    };
    let armijo = |alpha: Real, value: Real| value <= f0 + params.c1 * alpha * slope0;
    let curvature = |slope: Real| slope.abs() <= -params.c2 * slope0;

    // Bracketing (N&W Alg. 3.5).
    let mut prev = Trial {
        alpha: 0.0,
        point: Some((start.clone(), slope0)),
    };
    let mut alpha = alpha_init;
    let mut smallest_failure = Real::INFINITY;
    let (mut lo, mut hi) = loop {
        let trial = match try_step(ev, alpha) {
            Ok(t) => t,
            Err(outcome) => return outcome,
        };
        let prev_value = prev.point.as_ref().map_or(f0, |(p, _)| p.value);
        match &trial.point {
            None => {
                smallest_failure = smallest_failure.min(alpha);
                alpha = prev.alpha + 0.5 * (alpha - prev.alpha);
                if alpha <= prev.alpha * (1.0 + 4.0 * Real::EPSILON) {
                    return Search::Failed;
                }
                continue;
            }
            Some((p, slope)) => {
                if armijo(alpha, p.value) && p.value < f0 {
                    keep(p, alpha);
                }
                if !armijo(alpha, p.value) || (prev.alpha > 0.0 && p.value >= prev_value) {
                    break (prev, trial);
                }
                if curvature(*slope) {
                    let (p, _) = trial.point.expect("successful trial");
                    return Search::Accepted(p, alpha);
                }
                if *slope >= 0.0 {
                    break (trial, prev);
                }
            }
        }
        prev = trial;
        alpha = if smallest_failure.is_finite() {
            prev.alpha + 0.5 * (smallest_failure - prev.alpha)
        } else {
            2.0 * prev.alpha
        };
        if !(alpha.is_finite() && alpha > prev.alpha * (1.0 + 4.0 * Real::EPSILON)) {
            return Search::Failed;
        }
    };

    // Zoom (N&W Alg. 3.6): `lo` always succeeded and satisfies sufficient decrease.
    loop {
        let lo_values = lo
            .point
            .as_ref()
            .map(|(p, s)| (p.value, *s))
            .expect("the low end of the bracket succeeded");
        if (hi.alpha - lo.alpha).abs() <= 4.0 * Real::EPSILON * lo.alpha.abs().max(hi.alpha.abs()) {
            return Search::Failed;
        }
        let alpha = zoom_trial(&lo, lo_values, &hi);
        let trial = match try_step(ev, alpha) {
            Ok(t) => t,
            Err(outcome) => return outcome,
        };
        let Some((p, slope)) = &trial.point else {
            hi = trial;
            continue;
        };
        if armijo(alpha, p.value) && p.value < f0 {
            keep(p, alpha);
        }
        if !armijo(alpha, p.value) || p.value >= lo_values.0 {
            hi = trial;
            continue;
        }
        if curvature(*slope) {
            let (p, _) = trial.point.expect("successful trial");
            return Search::Accepted(p, alpha);
        }
        if *slope * (hi.alpha - lo.alpha) >= 0.0 {
            hi = lo;
        }
        lo = trial;
    }
}

/// The two-loop recursion: `−H g` for the stored pairs (oldest first).
fn two_loop(memory: &VecDeque<(Vec<Real>, Vec<Real>, Real)>, gradient: &[Real]) -> Vec<Real> {
    let mut q = gradient.to_vec();
    let mut alphas = vec![0.0; memory.len()];
    for (k, (s, y, rho)) in memory.iter().enumerate().rev() {
        let a = rho * dot(s, &q);
        alphas[k] = a;
        q.iter_mut().zip(y).for_each(|(q, y)| *q -= a * y);
    }
    if let Some((s, y, _)) = memory.back() {
        let gamma = dot(s, y) / dot(y, y);
        q.iter_mut().for_each(|q| *q *= gamma);
    }
    for ((s, y, rho), a) in memory.iter().zip(&alphas) {
        let b = rho * dot(y, &q);
        q.iter_mut().zip(s).for_each(|(q, s)| *q += (a - b) * s);
    }
    q.iter_mut().for_each(|q| *q = -*q);
    q
}

/// Minimizes `objective` from `x0` by L-BFGS (see the module documentation). `callback` is called at the
/// start (iteration 0) and after every accepted step; returning `ControlFlow::Break(())` stops the run.
///
/// Errors only when the run cannot start: invalid `params`, or an objective that fails (or returns a
/// non-finite value, a non-finite gradient or a gradient of the wrong length) at `x0`.
pub fn lbfgs<E, F, C>(
    mut objective: F,
    x0: &[Real],
    params: &LbfgsParams,
    mut callback: C,
) -> Result<LbfgsResult, LbfgsError<E>>
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
    C: FnMut(&LbfgsIteration) -> ControlFlow<()>,
{
    params.validate().map_err(LbfgsError::InvalidParameters)?;
    let start = Instant::now();
    let (value, gradient) = objective(x0).map_err(LbfgsError::InitialEvaluation)?;
    if !value.is_finite() {
        return Err(LbfgsError::InvalidStart(format!("the value is {value}")));
    }
    if gradient.len() != x0.len() {
        return Err(LbfgsError::InvalidStart(format!(
            "the gradient has {} entries for {} unknowns",
            gradient.len(),
            x0.len()
        )));
    }
    if let Some(i) = gradient.iter().position(|g| !g.is_finite()) {
        return Err(LbfgsError::InvalidStart(format!(
            "gradient entry {i} is not finite"
        )));
    }
    let mut current = Point {
        x: x0.to_vec(),
        value,
        gradient,
    };
    let mut ev = Evaluator {
        objective: &mut objective,
        evaluations: 1,
        failed: 0,
        best: current.clone(),
        start,
        time_limit: params.time_limit_seconds,
    };
    let mut memory: VecDeque<(Vec<Real>, Vec<Real>, Real)> = VecDeque::with_capacity(params.memory);
    let mut iteration = 0;
    let mut stalled = 0;
    let mut report = |ev: &Evaluator<'_, F>, p: &Point, k: usize, step: Real, steepest: bool| {
        callback(&LbfgsIteration {
            iteration: k,
            x: &p.x,
            value: p.value,
            gradient: &p.gradient,
            gradient_norm: norm(&p.gradient),
            step_length: step,
            steepest_descent: steepest,
            evaluations: ev.evaluations,
            elapsed_seconds: ev.elapsed(),
        })
    };
    let stop_reason = 'run: {
        if report(&ev, &current, 0, 0.0, true).is_break() {
            break 'run StopReason::Callback;
        }
        loop {
            let gnorm = norm(&current.gradient);
            if gnorm < params.gradient_tolerance || gnorm == 0.0 {
                break 'run StopReason::GradientTolerance;
            }
            if stalled >= params.no_progress_iterations {
                break 'run StopReason::NoProgress;
            }
            if iteration >= params.max_iterations {
                break 'run StopReason::MaxIterations;
            }
            if ev.out_of_time() {
                break 'run StopReason::TimeLimit;
            }
            let steepest_alpha = (params.initial_step_length / gnorm).min(1.0);
            let mut direction = two_loop(&memory, &current.gradient);
            let mut steepest = memory.is_empty();
            let mut alpha_init = if steepest { steepest_alpha } else { 1.0 };
            let slope = dot(&direction, &current.gradient);
            if !(slope < 0.0 && slope.is_finite()) {
                memory.clear();
                direction = current.gradient.iter().map(|g| -g).collect();
                steepest = true;
                alpha_init = steepest_alpha;
            }
            let (next, alpha) = loop {
                match line_search(&mut ev, &current, &direction, alpha_init, params) {
                    Search::Accepted(p, a) => break (p, a),
                    Search::OutOfTime => break 'run StopReason::TimeLimit,
                    Search::Failed if steepest => break 'run StopReason::LineSearchFailed,
                    Search::Failed => {
                        memory.clear();
                        direction = current.gradient.iter().map(|g| -g).collect();
                        steepest = true;
                        alpha_init = steepest_alpha;
                    }
                }
            };
            let s: Vec<Real> = next.x.iter().zip(&current.x).map(|(a, b)| a - b).collect();
            let y: Vec<Real> = next
                .gradient
                .iter()
                .zip(&current.gradient)
                .map(|(a, b)| a - b)
                .collect();
            let sy = dot(&s, &y);
            if sy > 1e-10 * norm(&s) * norm(&y) && sy.is_finite() {
                if memory.len() == params.memory {
                    memory.pop_front();
                }
                memory.push_back((s, y, 1.0 / sy));
            }
            let scale = current.value.abs().max(next.value.abs());
            let decrease = current.value - next.value;
            if decrease < params.min_relative_decrease * scale || scale == 0.0 {
                stalled += 1;
            } else {
                stalled = 0;
            }
            current = next;
            iteration += 1;
            if report(&ev, &current, iteration, alpha, steepest).is_break() {
                break 'run StopReason::Callback;
            }
        }
    };
    let best = ev.best;
    Ok(LbfgsResult {
        gradient_norm: norm(&best.gradient),
        x: best.x,
        value: best.value,
        gradient: best.gradient,
        stop_reason,
        iterations: iteration,
        evaluations: ev.evaluations,
        failed_evaluations: ev.failed,
        elapsed_seconds: start.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;
    use std::convert::Infallible;

    /// Extended Rosenbrock (Moré, Garbow, Hillstrom #21): independent 2D Rosenbrock pairs, minimum 0 at
    /// all ones, no other stationary point.
    fn rosenbrock(x: &[Real]) -> (Real, Vec<Real>) {
        let mut f = 0.0;
        let mut g = vec![0.0; x.len()];
        for i in (0..x.len()).step_by(2) {
            let (a, b) = (x[i], x[i + 1]);
            let t = b - a * a;
            f += 100.0 * t * t + (1.0 - a) * (1.0 - a);
            g[i] = -400.0 * a * t - 2.0 * (1.0 - a);
            g[i + 1] = 200.0 * t;
        }
        (f, g)
    }

    fn ok(x: &[Real]) -> Result<(Real, Vec<Real>), Infallible> {
        Ok(rosenbrock(x))
    }

    fn start(n: usize) -> Vec<Real> {
        (0..n)
            .map(|i| if i % 2 == 0 { -1.2 } else { 1.0 })
            .collect()
    }

    fn tight() -> LbfgsParams {
        LbfgsParams {
            gradient_tolerance: 1e-9,
            min_relative_decrease: 0.0,
            ..LbfgsParams::default()
        }
    }

    fn continue_(_: &LbfgsIteration) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }

    #[test]
    fn default_parameters_are_valid_and_bad_ones_are_errors() {
        assert!(LbfgsParams::default().validate().is_ok());
        let bad = [
            LbfgsParams {
                memory: 0,
                ..Default::default()
            },
            LbfgsParams {
                c1: 0.95,
                ..Default::default()
            },
            LbfgsParams {
                c2: 1.0,
                ..Default::default()
            },
            LbfgsParams {
                gradient_tolerance: -1.0,
                ..Default::default()
            },
            LbfgsParams {
                time_limit_seconds: Some(0.0),
                ..Default::default()
            },
            LbfgsParams {
                initial_step_length: Real::NAN,
                ..Default::default()
            },
            LbfgsParams {
                no_progress_iterations: 0,
                ..Default::default()
            },
            LbfgsParams {
                max_line_search_evaluations: 0,
                ..Default::default()
            },
            LbfgsParams {
                min_relative_decrease: Real::INFINITY,
                ..Default::default()
            },
        ];
        for p in bad {
            assert!(matches!(
                lbfgs(ok, &[0.0, 0.0], &p, continue_),
                Err(LbfgsError::InvalidParameters(_))
            ));
        }
    }

    #[test]
    fn rosenbrock_2d_converges() {
        let r = lbfgs(ok, &start(2), &tight(), continue_).unwrap();
        assert_eq!(r.stop_reason, StopReason::GradientTolerance);
        for x in &r.x {
            assert!((x - 1.0).abs() < 1e-6, "{:?}", r.x);
        }
        assert!(r.value < 1e-12);
        assert!(r.iterations < 100, "{} iterations", r.iterations);
    }

    #[test]
    fn rosenbrock_10d_converges() {
        let r = lbfgs(ok, &start(10), &tight(), continue_).unwrap();
        assert_eq!(r.stop_reason, StopReason::GradientTolerance);
        for x in &r.x {
            assert!((x - 1.0).abs() < 1e-6, "{:?}", r.x);
        }
        assert_eq!(r.failed_evaluations, 0);
    }

    #[test]
    fn wolfe_conditions_hold_at_every_accepted_step() {
        let params = tight();
        for n in [2, 10] {
            let mut previous: Option<(Vec<Real>, Real, Vec<Real>)> = None;
            let mut steps = 0;
            let check = |it: &LbfgsIteration| {
                if let Some((x0, f0, g0)) = &previous {
                    // The search direction, recovered from the step: d = (x1 − x0) / α.
                    let d: Vec<Real> =
                        it.x.iter()
                            .zip(x0)
                            .map(|(a, b)| (a - b) / it.step_length)
                            .collect();
                    let slope0 = dot(g0, &d);
                    let slope1 = dot(it.gradient, &d);
                    assert!(slope0 < 0.0, "not a descent direction");
                    assert!(
                        it.value <= f0 + params.c1 * it.step_length * slope0,
                        "sufficient decrease fails at iteration {}",
                        it.iteration
                    );
                    assert!(
                        slope1.abs() <= params.c2 * slope0.abs() * (1.0 + 1e-9),
                        "curvature fails at iteration {}",
                        it.iteration
                    );
                    steps += 1;
                }
                previous = Some((it.x.to_vec(), it.value, it.gradient.to_vec()));
                ControlFlow::Continue(())
            };
            let r = lbfgs(ok, &start(n), &params, check).unwrap();
            assert_eq!(steps, r.iterations);
            assert!(steps > 10);
        }
    }

    #[test]
    fn convex_quadratic_converges_in_few_iterations() {
        // f = ½ xᵀ A x − bᵀ x with A = R diag(1..10) Rᵀ, R = I − 2 v vᵀ / vᵀv (orthogonal): n = 10,
        // condition number 10.
        let n = 10;
        let v: Vec<Real> = (0..n).map(|i| 1.0 + (i as Real * 0.7).sin()).collect();
        let vv = dot(&v, &v);
        let r = |i: usize, j: usize| (if i == j { 1.0 } else { 0.0 }) - 2.0 * v[i] * v[j] / vv;
        let a: Vec<Vec<Real>> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| (0..n).map(|k| r(i, k) * (1.0 + k as Real) * r(j, k)).sum())
                    .collect()
            })
            .collect();
        let b: Vec<Real> = (0..n).map(|i| (i as Real * 0.5).cos()).collect();
        let f = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
            let ax: Vec<Real> = (0..n).map(|i| dot(&a[i], x)).collect();
            let value = 0.5 * dot(x, &ax) - dot(&b, x);
            let grad = ax.iter().zip(&b).map(|(p, q)| p - q).collect();
            Ok((value, grad))
        };
        let params = LbfgsParams {
            memory: n,
            // f* ≈ −0.65: a gradient of 1e-6 leaves f − f* ≈ 1e-13, well above round-off.
            gradient_tolerance: 1e-6,
            min_relative_decrease: 0.0,
            ..LbfgsParams::default()
        };
        let result = lbfgs(f, &vec![0.0; n], &params, continue_).unwrap();
        assert_eq!(result.stop_reason, StopReason::GradientTolerance);
        assert!(
            result.iterations <= n + 5,
            "{} iterations",
            result.iterations
        );
    }

    #[test]
    fn failures_beyond_a_radius_are_shrunk_and_it_still_converges() {
        // f = ‖x − a‖² with ‖a‖ = 0.9, undefined (Err) outside the unit ball; a first trial step of 10
        // leaves the ball.
        let a = [0.6, -0.6, 0.3];
        let failures = RefCell::new(0);
        let f = |x: &[Real]| -> Result<(Real, Vec<Real>), String> {
            if norm(x) > 1.0 {
                *failures.borrow_mut() += 1;
                return Err("outside".into());
            }
            let d: Vec<Real> = x.iter().zip(&a).map(|(x, a)| x - a).collect();
            Ok((dot(&d, &d), d.iter().map(|d| 2.0 * d).collect()))
        };
        let params = LbfgsParams {
            initial_step_length: 10.0,
            gradient_tolerance: 1e-10,
            ..LbfgsParams::default()
        };
        let r = lbfgs(f, &[-0.5, 0.5, 0.0], &params, continue_).unwrap();
        assert_eq!(r.stop_reason, StopReason::GradientTolerance);
        assert!(*failures.borrow() > 0);
        assert_eq!(r.failed_evaluations, *failures.borrow());
        for (x, a) in r.x.iter().zip(&a) {
            assert!((x - a).abs() < 1e-9);
        }
        // Non-finite values count as failures too.
        let g = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
            if norm(x) > 1.0 {
                return Ok((Real::NAN, vec![0.0; 3]));
            }
            let d: Vec<Real> = x.iter().zip(&a).map(|(x, a)| x - a).collect();
            Ok((dot(&d, &d), d.iter().map(|d| 2.0 * d).collect()))
        };
        let r = lbfgs(g, &[-0.5, 0.5, 0.0], &params, continue_).unwrap();
        assert_eq!(r.stop_reason, StopReason::GradientTolerance);
        assert!(r.failed_evaluations > 0);
    }

    #[test]
    fn failure_at_the_start_is_an_error() {
        let f = |_: &[Real]| -> Result<(Real, Vec<Real>), &str> { Err("no") };
        assert_eq!(
            lbfgs(f, &[1.0], &LbfgsParams::default(), continue_),
            Err(LbfgsError::InitialEvaluation("no"))
        );
        let g = |_: &[Real]| -> Result<(Real, Vec<Real>), &str> { Ok((Real::INFINITY, vec![0.0])) };
        assert!(matches!(
            lbfgs(g, &[1.0], &LbfgsParams::default(), continue_),
            Err(LbfgsError::InvalidStart(_))
        ));
        let h = |_: &[Real]| -> Result<(Real, Vec<Real>), &str> { Ok((1.0, vec![0.0, 1.0])) };
        assert!(matches!(
            lbfgs(h, &[1.0], &LbfgsParams::default(), continue_),
            Err(LbfgsError::InvalidStart(_))
        ));
        let k = |_: &[Real]| -> Result<(Real, Vec<Real>), &str> { Ok((1.0, vec![Real::NAN])) };
        assert!(matches!(
            lbfgs(k, &[1.0], &LbfgsParams::default(), continue_),
            Err(LbfgsError::InvalidStart(_))
        ));
    }

    #[test]
    fn iteration_limit_returns_the_best_point() {
        let params = LbfgsParams {
            max_iterations: 3,
            ..tight()
        };
        let r = lbfgs(ok, &start(2), &params, continue_).unwrap();
        assert_eq!(r.stop_reason, StopReason::MaxIterations);
        assert_eq!(r.iterations, 3);
        let (f0, _) = rosenbrock(&start(2));
        assert!(r.value < f0);
        let (f, g) = rosenbrock(&r.x);
        assert_eq!(f, r.value);
        assert_eq!(g, r.gradient);
        assert_eq!(r.gradient_norm, norm(&g));
    }

    #[test]
    fn time_limit_returns_the_best_point() {
        let slow = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
            std::thread::sleep(std::time::Duration::from_millis(2));
            Ok(rosenbrock(x))
        };
        let params = LbfgsParams {
            time_limit_seconds: Some(0.03),
            ..tight()
        };
        let r = lbfgs(slow, &start(10), &params, continue_).unwrap();
        assert_eq!(r.stop_reason, StopReason::TimeLimit);
        assert!(r.elapsed_seconds < 1.0);
        let (f0, _) = rosenbrock(&start(10));
        assert!(r.value <= f0);
        assert_eq!(rosenbrock(&r.x).0, r.value);
    }

    #[test]
    fn callback_can_stop_the_run() {
        let mut seen = Vec::new();
        let stop = |it: &LbfgsIteration| {
            seen.push((it.iteration, it.evaluations, it.elapsed_seconds));
            if it.iteration == 2 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        };
        let r = lbfgs(ok, &start(2), &tight(), stop).unwrap();
        assert_eq!(r.stop_reason, StopReason::Callback);
        assert_eq!(r.iterations, 2);
        assert_eq!(seen.iter().map(|s| s.0).collect::<Vec<_>>(), vec![0, 1, 2]);
        assert!(seen.windows(2).all(|w| w[0].1 < w[1].1 && w[0].2 <= w[1].2));
        // Stopping at the start returns the start.
        let r = lbfgs(ok, &start(2), &tight(), |_: &LbfgsIteration| {
            ControlFlow::Break(())
        })
        .unwrap();
        assert_eq!(r.stop_reason, StopReason::Callback);
        assert_eq!(r.x, start(2));
        assert_eq!(r.iterations, 0);
    }

    #[test]
    fn no_progress_stops_the_run() {
        // A huge constant offset makes every decrease relatively tiny.
        // f = 1e8 + ½ Σ λ_i x_i² with λ_i = 1 + 11 i: at most 250 to gain from x = 1, relatively < 1e-5.
        let f = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
            let lambda = |i: usize| 1.0 + 11.0 * i as Real;
            let value = 1e8
                + 0.5
                    * x.iter()
                        .enumerate()
                        .map(|(i, x)| lambda(i) * x * x)
                        .sum::<Real>();
            Ok((
                value,
                x.iter().enumerate().map(|(i, x)| lambda(i) * x).collect(),
            ))
        };
        let params = LbfgsParams {
            gradient_tolerance: 0.0,
            min_relative_decrease: 1e-5,
            no_progress_iterations: 3,
            ..LbfgsParams::default()
        };
        let r = lbfgs(f, &[1.0; 10], &params, continue_).unwrap();
        assert_eq!(r.stop_reason, StopReason::NoProgress);
        assert_eq!(r.iterations, 3);
        assert!(r.value < 1e8 + 250.0);
    }

    #[test]
    fn a_search_without_a_curvature_step_moves_to_its_lowest_sufficient_decrease() {
        // f = (x − 3)², but the reported slope is −6 everywhere (as at x = 0): no step meets the curvature
        // condition, several meet sufficient decrease. The search moves to the lowest of those instead of
        // failing (regression: the hourglass design stopped with LineSearchFailed at 17.5× reduction).
        let f = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
            Ok(((x[0] - 3.0).powi(2), vec![-6.0]))
        };
        let params = LbfgsParams {
            max_iterations: 1,
            max_line_search_evaluations: 12,
            ..LbfgsParams::default()
        };
        let r = lbfgs(f, &[0.0], &params, continue_).unwrap();
        assert_eq!(r.stop_reason, StopReason::MaxIterations);
        assert_eq!(r.iterations, 1);
        assert!(r.value < 9.0 * 0.5, "value {} after one step", r.value);
        assert!(r.x[0] > 0.0 && r.x[0] < 6.0);
    }

    #[test]
    fn a_wrong_gradient_fails_the_line_search() {
        // The reported gradient points uphill: no step satisfies sufficient decrease.
        let evaluations = RefCell::new(0);
        let f = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
            *evaluations.borrow_mut() += 1;
            Ok((dot(x, x), x.iter().map(|x| -2.0 * x).collect()))
        };
        let params = LbfgsParams {
            max_line_search_evaluations: 10,
            ..LbfgsParams::default()
        };
        let r = lbfgs(f, &[1.0, 2.0], &params, continue_).unwrap();
        assert_eq!(r.stop_reason, StopReason::LineSearchFailed);
        assert_eq!(r.x, vec![1.0, 2.0]);
        assert_eq!(r.iterations, 0);
        // The first direction is already steepest descent: one search only (1 + 10 evaluations).
        assert_eq!(*evaluations.borrow(), 11);
    }

    #[test]
    fn a_failed_quasi_newton_search_retries_steepest_descent() {
        // f = 5x² + 9xy + 5y² (eigenvalues ½ and 9½). Run once to learn the first iterate x1 and the
        // quasi-Newton direction d of the second iteration (its first trial is x1 + d); then make the
        // objective fail inside a thin cone around d with apex x1: every quasi-Newton trial fails, the
        // steepest-descent retry succeeds.
        let quadratic = |x: &[Real]| {
            (
                5.0 * x[0] * x[0] + 9.0 * x[0] * x[1] + 5.0 * x[1] * x[1],
                vec![10.0 * x[0] + 9.0 * x[1], 9.0 * x[0] + 10.0 * x[1]],
            )
        };
        let x0 = [1.0, 0.0];
        let log = RefCell::new(Vec::new());
        let logged = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
            log.borrow_mut().push(x.to_vec());
            Ok(quadratic(x))
        };
        let mut x1 = Vec::new();
        let mut evals_at_x1 = 0;
        let params = LbfgsParams {
            max_iterations: 2,
            ..LbfgsParams::default()
        };
        lbfgs(logged, &x0, &params, |it: &LbfgsIteration| {
            if it.iteration == 1 {
                x1 = it.x.to_vec();
                evals_at_x1 = it.evaluations;
            }
            ControlFlow::Continue(())
        })
        .unwrap();
        let trial = log.borrow()[evals_at_x1].clone();
        let d = [trial[0] - x1[0], trial[1] - x1[1]];
        let g1 = quadratic(&x1).1;
        let cos_sd = -(g1[0] * d[0] + g1[1] * d[1]) / (norm(&g1) * norm(&d));
        assert!(
            cos_sd < 0.9999,
            "the directions must differ for this test ({cos_sd})"
        );
        let in_cone = |x: &[Real]| {
            let v = [x[0] - x1[0], x[1] - x1[1]];
            let nv = norm(&v);
            nv > 0.0 && (v[0] * d[0] + v[1] * d[1]) / (nv * norm(&d)) > 0.99999
        };
        let failing = |x: &[Real]| -> Result<(Real, Vec<Real>), &str> {
            if in_cone(x) {
                Err("in the cone")
            } else {
                Ok(quadratic(x))
            }
        };
        let mut steepest = Vec::new();
        let r = lbfgs(failing, &x0, &params, |it: &LbfgsIteration| {
            steepest.push(it.steepest_descent);
            ControlFlow::Continue(())
        })
        .unwrap();
        assert_eq!(r.iterations, 2);
        assert_eq!(r.stop_reason, StopReason::MaxIterations);
        // Iteration 2 was taken along steepest descent after the quasi-Newton search failed.
        assert_eq!(steepest, vec![true, true, true]);
        assert_eq!(r.failed_evaluations, params.max_line_search_evaluations);
        assert!(r.value < quadratic(&x1).0);
    }

    #[test]
    fn empty_problem_stops_at_once() {
        let f = |_: &[Real]| -> Result<(Real, Vec<Real>), Infallible> { Ok((2.0, Vec::new())) };
        let r = lbfgs(f, &[], &LbfgsParams::default(), continue_).unwrap();
        assert_eq!(r.stop_reason, StopReason::GradientTolerance);
        assert_eq!(r.value, 2.0);
    }
}
