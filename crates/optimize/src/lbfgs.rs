//! Limited-memory BFGS (Nocedal & Wright, *Numerical Optimization*, 2nd ed., Alg. 7.4–7.5) with a
//! strong-Wolfe line search (Alg. 3.5 bracketing, Alg. 3.6 zoom), for `min_x T(x)`.
//!
//! The objective is an [`Objective`] returning the value and the gradient (units: those of the problem —
//! `T` and `T` per unit of `x`). An evaluation may fail (a
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
//! with [`OptimizerStop::LineSearchFailed`].
//!
//! **Stopping** (checked before every iteration, in this order):
//! - [`OptimizerStop::GradientTolerance`]: `‖g‖₂ < gradient_tolerance` (absolute, in the gradient's units;
//!   default `1e-3`), or `g = 0` exactly;
//! - [`OptimizerStop::NoProgress`]: for [`LbfgsParams::no_progress_iterations`] consecutive iterations
//!   (default 5) the relative decrease `(T_{k−1} − T_k) / max(|T_{k−1}|, |T_k|)` was below
//!   [`LbfgsParams::min_relative_decrease`] (default `1e-10`);
//! - [`OptimizerStop::MaxIterations`]: [`LbfgsParams::max_iterations`] accepted steps;
//! - [`OptimizerStop::TimeLimit`]: [`LbfgsParams::time_limit_seconds`] passed (also checked before every
//!   evaluation inside a line search, so a run overruns by at most one evaluation);
//! - [`OptimizerStop::Callback`]: the per-iteration callback returned `ControlFlow::Break`;
//! - [`OptimizerStop::LineSearchFailed`]: see above.
//!
//! Whatever the reason, the result holds the **best point seen** (lowest value among all successful
//! evaluations, line-search trials included), its value, gradient and gradient norm.

use std::collections::VecDeque;
use std::ops::ControlFlow;
use std::time::Instant;

use crate::Real;
use crate::optimizer_stop::OptimizerStop;
use crate::problem::Objective;

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
    /// What [`LbfgsIteration::state`] copies besides the fields above.
    resume: ResumeParts<'a>,
}

/// The run's memory and counters behind an [`LbfgsIteration`].
#[derive(Clone, Copy, Debug)]
struct ResumeParts<'a> {
    memory: &'a VecDeque<(Vec<Real>, Vec<Real>, Real)>,
    stalled: usize,
    failed_evaluations: usize,
    best: &'a Point,
}

impl LbfgsIteration<'_> {
    /// Everything the run needs to go on from here exactly as it would have (a checkpoint): continue it
    /// with [`lbfgs_from`].
    pub fn state(&self) -> LbfgsState {
        LbfgsState {
            iteration: self.iteration,
            x: self.x.to_vec(),
            value: self.value,
            gradient: self.gradient.to_vec(),
            memory: self.resume.memory.iter().cloned().collect(),
            stalled: self.resume.stalled,
            evaluations: self.evaluations,
            failed_evaluations: self.resume.failed_evaluations,
            best_x: self.resume.best.x.clone(),
            best_value: self.resume.best.value,
            best_gradient: self.resume.best.gradient.clone(),
            elapsed_seconds: self.elapsed_seconds,
        }
    }
}

/// Where an [`lbfgs`] run stands after an accepted iteration (see [`LbfgsIteration::state`]): the current
/// point, the curvature pairs, the no-progress count, the counters and the best point seen. Values in the
/// units of the problem; serializable, so that a checkpoint can store it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LbfgsState {
    /// Accepted steps so far.
    pub iteration: usize,
    /// The current point.
    pub x: Vec<Real>,
    /// Its value.
    pub value: Real,
    /// Its gradient.
    pub gradient: Vec<Real>,
    /// The stored pairs `(s, y, 1 / sᵀy)`, oldest first.
    pub memory: Vec<(Vec<Real>, Vec<Real>, Real)>,
    /// Consecutive iterations without enough relative decrease.
    pub stalled: usize,
    /// Objective evaluations so far (failed ones included).
    pub evaluations: usize,
    /// Failed evaluations so far.
    pub failed_evaluations: usize,
    /// The best point seen, its value and gradient.
    pub best_x: Vec<Real>,
    /// See `best_x`.
    pub best_value: Real,
    /// See `best_x`.
    pub best_gradient: Vec<Real>,
    /// Seconds the run had taken (counted against `time_limit_seconds` when it goes on).
    pub elapsed_seconds: Real,
}

/// Where [`lbfgs_from`] starts.
#[derive(Clone, Debug)]
pub enum LbfgsStart<'a> {
    /// A fresh run from this point (evaluated first, and reported as iteration 0).
    Point(&'a [Real]),
    /// A run that goes on from a checkpoint: nothing is evaluated or reported until the next accepted step.
    Resume(LbfgsState),
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
    pub stop_reason: OptimizerStop,
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
struct Evaluator<'f, P> {
    problem: &'f mut P,
    evaluations: usize,
    failed: usize,
    best: Point,
    start: Instant,
    time_limit: Option<Real>,
}

impl<P: Objective> Evaluator<'_, P> {
    fn elapsed(&self) -> Real {
        self.start.elapsed().as_secs_f64()
    }

    fn out_of_time(&self) -> bool {
        self.time_limit.is_some_and(|t| self.elapsed() >= t)
    }

    /// `None` when the evaluation failed.
    fn evaluate(&mut self, x: &[Real]) -> Option<Point> {
        self.evaluations += 1;
        match self.problem.evaluate(x) {
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

fn line_search<P: Objective>(
    ev: &mut Evaluator<'_, P>,
    start: &Point,
    direction: &[Real],
    alpha_init: Real,
    params: &LbfgsParams,
) -> Search {
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
fn wolfe_search<P: Objective>(
    ev: &mut Evaluator<'_, P>,
    start: &Point,
    direction: &[Real],
    alpha_init: Real,
    params: &LbfgsParams,
    sufficient: &mut Option<(Point, Real)>,
) -> Search {
    let f0 = start.value;
    let mut keep = |p: &Point, alpha: Real| {
        if sufficient.as_ref().is_none_or(|(b, _)| p.value < b.value) {
            *sufficient = Some((p.clone(), alpha));
        }
    };
    let slope0 = dot(&start.gradient, direction);
    let mut evaluations = 0;
    let mut try_step = |ev: &mut Evaluator<'_, P>, alpha: Real| -> Result<Trial, Search> {
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

/// Minimizes `problem` from `x0` by L-BFGS (see the module documentation). `callback` is called at the
/// start (iteration 0) and after every accepted step, with the problem (so that it can read what the
/// evaluations gathered); returning `ControlFlow::Break(())` stops the run.
///
/// Errors only when the run cannot start: invalid `params`, or an objective that fails (or returns a
/// non-finite value, a non-finite gradient or a gradient of the wrong length) at `x0`.
pub fn lbfgs<P, C>(
    problem: &mut P,
    x0: &[Real],
    params: &LbfgsParams,
    callback: C,
) -> Result<LbfgsResult, LbfgsError<P::Error>>
where
    P: Objective,
    C: FnMut(&mut P, &LbfgsIteration) -> ControlFlow<()>,
{
    lbfgs_from(problem, LbfgsStart::Point(x0), params, callback)
}

/// [`lbfgs`] from a point or from a checkpoint ([`LbfgsIteration::state`]). Resumed with the same
/// objective and settings, the run takes exactly the steps the uninterrupted run took (time limits aside:
/// the checkpoint's seconds count against `time_limit_seconds`).
pub fn lbfgs_from<P, C>(
    problem: &mut P,
    from: LbfgsStart<'_>,
    params: &LbfgsParams,
    callback: C,
) -> Result<LbfgsResult, LbfgsError<P::Error>>
where
    P: Objective,
    C: FnMut(&mut P, &LbfgsIteration) -> ControlFlow<()>,
{
    params.validate().map_err(LbfgsError::InvalidParameters)?;
    let x0 = match from {
        LbfgsStart::Point(x0) => x0,
        LbfgsStart::Resume(state) => return resume(problem, state, params, callback),
    };
    let start = Instant::now();
    let (value, gradient) = problem
        .evaluate(x0)
        .map_err(LbfgsError::InitialEvaluation)?;
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
    let current = Point {
        x: x0.to_vec(),
        value,
        gradient,
    };
    let run = Run {
        best: current.clone(),
        current,
        memory: VecDeque::with_capacity(params.memory),
        iteration: 0,
        stalled: 0,
        evaluations: 1,
        failed: 0,
    };
    iterate(problem, run, start, true, params, callback)
}

/// [`lbfgs_from`] from a checkpoint.
fn resume<P, C>(
    problem: &mut P,
    state: LbfgsState,
    params: &LbfgsParams,
    callback: C,
) -> Result<LbfgsResult, LbfgsError<P::Error>>
where
    P: Objective,
    C: FnMut(&mut P, &LbfgsIteration) -> ControlFlow<()>,
{
    let n = state.x.len();
    let lengths_agree = state.gradient.len() == n
        && state.best_x.len() == n
        && state.best_gradient.len() == n
        && state
            .memory
            .iter()
            .all(|(s, y, _)| s.len() == n && y.len() == n);
    if !lengths_agree || state.memory.len() > params.memory {
        return Err(LbfgsError::InvalidStart(format!(
            "the checkpoint does not fit: {n} unknowns, memory of {} pairs for at most {}",
            state.memory.len(),
            params.memory
        )));
    }
    let elapsed = std::time::Duration::from_secs_f64(state.elapsed_seconds.max(0.0));
    let start = Instant::now()
        .checked_sub(elapsed)
        .unwrap_or_else(Instant::now);
    let mut memory = VecDeque::with_capacity(params.memory);
    memory.extend(state.memory);
    let run = Run {
        current: Point {
            x: state.x,
            value: state.value,
            gradient: state.gradient,
        },
        best: Point {
            x: state.best_x,
            value: state.best_value,
            gradient: state.best_gradient,
        },
        memory,
        iteration: state.iteration,
        stalled: state.stalled,
        evaluations: state.evaluations,
        failed: state.failed_evaluations,
    };
    iterate(problem, run, start, false, params, callback)
}

/// The state of a run between iterations (what [`LbfgsState`] stores).
struct Run {
    current: Point,
    best: Point,
    memory: VecDeque<(Vec<Real>, Vec<Real>, Real)>,
    iteration: usize,
    stalled: usize,
    evaluations: usize,
    failed: usize,
}

/// The iterations of [`lbfgs_from`] from `run`; `report_start`: whether `run.current` is reported first
/// (a fresh run's iteration 0).
fn iterate<P, C>(
    problem: &mut P,
    run: Run,
    start: Instant,
    report_start: bool,
    params: &LbfgsParams,
    mut callback: C,
) -> Result<LbfgsResult, LbfgsError<P::Error>>
where
    P: Objective,
    C: FnMut(&mut P, &LbfgsIteration) -> ControlFlow<()>,
{
    let Run {
        mut current,
        best,
        mut memory,
        mut iteration,
        mut stalled,
        evaluations,
        failed,
    } = run;
    let mut ev = Evaluator {
        problem,
        evaluations,
        failed,
        best,
        start,
        time_limit: params.time_limit_seconds,
    };
    let mut report = |ev: &mut Evaluator<'_, P>,
                      memory: &VecDeque<(Vec<Real>, Vec<Real>, Real)>,
                      stalled: usize,
                      p: &Point,
                      k: usize,
                      step: Real,
                      steepest: bool| {
        let info = LbfgsIteration {
            iteration: k,
            x: &p.x,
            value: p.value,
            gradient: &p.gradient,
            gradient_norm: norm(&p.gradient),
            step_length: step,
            steepest_descent: steepest,
            evaluations: ev.evaluations,
            elapsed_seconds: ev.elapsed(),
            resume: ResumeParts {
                memory,
                stalled,
                failed_evaluations: ev.failed,
                best: &ev.best,
            },
        };
        callback(&mut *ev.problem, &info)
    };
    let stop_reason = 'run: {
        if report_start && report(&mut ev, &memory, stalled, &current, 0, 0.0, true).is_break() {
            break 'run OptimizerStop::Callback;
        }
        loop {
            let gnorm = norm(&current.gradient);
            if gnorm < params.gradient_tolerance || gnorm == 0.0 {
                break 'run OptimizerStop::GradientTolerance;
            }
            if stalled >= params.no_progress_iterations {
                break 'run OptimizerStop::NoProgress;
            }
            if iteration >= params.max_iterations {
                break 'run OptimizerStop::MaxIterations;
            }
            if ev.out_of_time() {
                break 'run OptimizerStop::TimeLimit;
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
                    Search::OutOfTime => break 'run OptimizerStop::TimeLimit,
                    Search::Failed if steepest => break 'run OptimizerStop::LineSearchFailed,
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
            if report(
                &mut ev, &memory, stalled, &current, iteration, alpha, steepest,
            )
            .is_break()
            {
                break 'run OptimizerStop::Callback;
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
mod tests;
