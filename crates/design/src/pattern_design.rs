//! The design loop: L-BFGS or adjoint Gauss-Newton over the pattern boundary (thesis ch. 7; paper
//! Sec. 6.2–6.3, [`crate::gauss_newton_loop`], [`crate::kkt_direction`]), each objective evaluation one
//! equilibrium warm-started from the last ([`DesignProblem::evaluate`]), optionally coarse to fine over
//! low-frequency boundary modes (paper Sec. 6.5, [`BoundaryModes`]).
//!
//! **Scaling.** The optimizer works on the normalized objective `T̃ = T / T₀` (`T₀` the objective of the
//! initial pattern) over the boundary positions measured in cloth edge lengths `ℓ`, `p̃ = p / ℓ`. Its
//! stopping rule `‖dT̃/dp̃‖₂ < gradient_tolerance` (default `10⁻³`) is thus dimensionless and the same
//! for any weights and garment size: no move of the boundary by one edge length changes the objective
//! by more than 0.1 % of where it started. Reports give `T` and `‖dT/dp‖` in the terms' own units.
//!
//! **Gauss-Newton.** With [`Optimizer::GaussNewton`] each iteration linearizes the problem at the accepted
//! design ([`DesignProblem::linearize`]) and solves the adjoint Gauss-Newton KKT system on the normalized
//! problem: residuals divided by `√T₀`, the design map `A = dX̄/dp̃` (m per edge length; at a coarse level
//! composed with the modes basis, `A = W B ℓ`) built once per level, its symbolic LU analysis reused while
//! the structure holds — or, while the dense sensitivity fits ([`GaussNewtonSolver`]), the same direction
//! in reduced form ([`crate::reduced_direction`]), much faster when `A` is dense. If no term has residuals, the direction is the damped gradient `−g / κ` (a
//! steepest-descent step of length `1 / μ` edge lengths, see [`crate::gauss_newton_loop`]) — no KKT solve.
//!
//! **Failures.** A pattern the garment finds no equilibrium for (or that folds a triangle over) counts as
//! a step too long in the line search. The result is always the best design seen, evaluated once more
//! at the end so that its equilibrium, terms and gradient are those reported.

use std::ops::ControlFlow;
use std::time::Instant;

use std::cell::RefCell;

use crate::boundary_modes::BoundaryModes;
use crate::design_checkpoint::{DesignCheckpoint, OptimizerState};
pub use crate::design_iteration::DesignIteration;
use crate::design_problem::{DesignError, DesignEvaluation, DesignProblem};
use crate::gauss_newton_loop::{
    GaussNewtonIteration, GaussNewtonParams, GaussNewtonRunError, GaussNewtonStart,
    gauss_newton_from,
};
use crate::inexact_tolerance::InexactTolerance;
use crate::kkt_direction::{AdjointGaussNewton, GaussNewtonSystem, design_map_matrix};
use crate::lbfgs::{LbfgsIteration, LbfgsParams, LbfgsStart, OptimizerStop, lbfgs_from};
use crate::math::{Real, Vec2};
use crate::pattern_map::PatternMap;
use crate::pattern_quality::{PatternQuality, PatternQualityParams, pattern_quality};
use crate::reduced_direction::reduced_gauss_newton_direction;
use crate::term::Residuals;
use skintight_physics::ClothOnBodyState;

/// Which optimizer [`pattern_design`] runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Optimizer {
    /// L-BFGS with a strong-Wolfe line search ([`mod@crate::lbfgs`]), settings in
    /// [`PatternDesignParams::lbfgs`].
    #[default]
    Lbfgs,
    /// Adjoint Gauss-Newton with Levenberg-Marquardt damping and a backtracking line search
    /// ([`crate::gauss_newton_loop`]), settings in [`PatternDesignParams::gauss_newton`].
    GaussNewton,
}

impl Optimizer {
    /// The name used in job results (`"lbfgs"`, `"gauss_newton"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Lbfgs => "lbfgs",
            Self::GaussNewton => "gauss_newton",
        }
    }
}

/// How the Gauss-Newton direction is solved for; both give the same direction (to round-off).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GaussNewtonSolver {
    /// [`Self::Reduced`] while the dense sensitivity `#q × #c` has at most
    /// [`GaussNewtonSolver::AUTO_REDUCED_ENTRIES`] entries, else [`Self::Kkt`].
    #[default]
    Auto,
    /// The sparse KKT system ([`crate::kkt_direction`], the paper's Eq. 21).
    Kkt,
    /// The sensitivity from one multi-column solve with the equilibrium factor, then the dense
    /// `#c × #c` Gauss-Newton matrix ([`crate::reduced_direction`]).
    Reduced,
}

impl GaussNewtonSolver {
    /// Largest `#q · #c` (entries of the dense sensitivity, 8 bytes each: 400 MB) [`Self::Auto`] solves
    /// in reduced form.
    pub const AUTO_REDUCED_ENTRIES: usize = 50_000_000;

    /// The name used in job specs and results (`"auto"`, `"kkt"`, `"reduced"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Kkt => "kkt",
            Self::Reduced => "reduced",
        }
    }

    /// Whether a problem with `unknowns` state unknowns and `parameters` design parameters is solved in
    /// reduced form.
    pub fn reduced(self, unknowns: usize, parameters: usize) -> bool {
        match self {
            Self::Auto => unknowns.saturating_mul(parameters) <= Self::AUTO_REDUCED_ENTRIES,
            Self::Kkt => false,
            Self::Reduced => true,
        }
    }
}

/// Settings of [`pattern_design`].
#[derive(Clone, Debug, PartialEq)]
pub struct PatternDesignParams {
    /// The optimizer. Default L-BFGS.
    pub method: Optimizer,
    /// How Gauss-Newton directions are solved for. Default [`GaussNewtonSolver::Auto`].
    pub gauss_newton_solver: GaussNewtonSolver,
    /// L-BFGS settings, on the normalized problem (see the module documentation). With L-BFGS its
    /// `max_iterations` and `time_limit_seconds` bound the whole run (all levels together).
    pub lbfgs: LbfgsParams,
    /// Gauss-Newton settings, on the normalized problem (damping per edge length). With Gauss-Newton its
    /// `max_iterations` and `time_limit_seconds` bound the whole run.
    pub gauss_newton: GaussNewtonParams,
    /// Coarse-to-fine levels: the number of boundary modes per panel at each level, increasing; after the
    /// last level the boundary positions themselves are optimized. Empty (default): the boundary
    /// positions from the start.
    pub mode_levels: Vec<usize>,
    /// Most iterations of each mode level (not of the final boundary-position level), so that the finer
    /// levels get their turn when a coarse one keeps making small progress; `None` (default): a level
    /// runs until it stops by itself or the whole run's limits.
    pub level_max_iterations: Option<usize>,
    /// A mode level (not the final boundary-position level) hands over to the next once
    /// [`LEVEL_NO_PROGRESS_ITERATIONS`] iterations in a row each lowered the objective by less than this
    /// fraction of its value (dimensionless, ≥ 0; 0: a level runs until its own stopping rules). A coarse
    /// level that creeps along spends evaluations the finer levels would use better. Default `3·10⁻³`
    /// (session 19: on the tapered cylinder, whose 6-mode level crept at 0.1–0.3 % an iteration for six
    /// iterations, 59 Newton iterations to 1/50 of the objective against 76 at `10⁻³`; the tight, sliding
    /// and seam-traction pants took the same path or within noise, docs/BENCHMARKS.md).
    pub level_min_relative_decrease: Real,
    /// When to stop for a remesh ([`mod@crate::design_remesh`]): after an accepted iteration whose pattern
    /// needs one ([`PatternQualityParams::needs_remesh`], boundary edges compared with the cloth edge
    /// length; where the pattern the run started from is already near a bound, the bound is
    /// relative to that pattern: quality 10 % below its quality, edge ratio 1.5 × its ratio), the run stops with
    /// [`PatternDesignResult::remesh_requested`]; the caller remeshes and calls again. `None` (default):
    /// never. Its `max_remeshes` is the caller's business.
    pub remesh: Option<PatternQualityParams>,
    /// Inexact equilibria ([`mod@crate::inexact_tolerance`]): each evaluation's equilibrium solved to a
    /// tolerance that follows the gradient of the accepted design, between the problem's own
    /// ([`DesignProblem::equilibrium_tolerance`]) and [`InexactTolerance::loosest`]; the best design's
    /// final evaluation is always at the problem's own. `None` (default): every solve at the problem's own.
    pub inexact: Option<InexactTolerance>,
}

/// Consecutive iterations below [`PatternDesignParams::level_min_relative_decrease`] that end a mode level.
pub const LEVEL_NO_PROGRESS_ITERATIONS: usize = 2;

impl Default for PatternDesignParams {
    fn default() -> Self {
        Self {
            method: Optimizer::Lbfgs,
            gauss_newton_solver: GaussNewtonSolver::Auto,
            lbfgs: LbfgsParams {
                max_iterations: 100,
                ..LbfgsParams::default()
            },
            gauss_newton: GaussNewtonParams::default(),
            mode_levels: Vec::new(),
            level_max_iterations: None,
            level_min_relative_decrease: 3e-3,
            remesh: None,
            inexact: None,
        }
    }
}

/// The outcome of [`pattern_design`].
#[derive(Clone, Debug)]
pub struct PatternDesignResult {
    /// The best pattern found (`#Vp`, m).
    pub pattern: Vec<Vec2>,
    /// Its boundary parameters (m, see [`PatternMap`]).
    pub parameters: Vec<Real>,
    /// The objective of the initial pattern.
    pub initial_objective: Real,
    /// The objective of the best pattern.
    pub final_objective: Real,
    /// Accepted steps over all levels.
    pub iterations: usize,
    /// Equilibrium solves.
    pub evaluations: usize,
    /// Why the last level stopped.
    pub stop_reason: OptimizerStop,
    /// Pattern remeshes: 0 from this function (the caller counts its remeshes).
    pub remeshes: usize,
    /// Seconds spent remeshing and re-embedding: 0 from this function (the caller's, like `remeshes`).
    pub remesh_seconds: Real,
    /// Whether the run stopped because the pattern needs a remesh (see [`PatternDesignParams::remesh`]).
    pub remesh_requested: bool,
    /// The coarse-to-fine level the run ended in (index into [`PatternDesignParams::mode_levels`];
    /// its length for the boundary positions).
    pub level: usize,
    /// One entry per accepted iteration, the initial design first.
    pub history: Vec<DesignIteration>,
    /// The best pattern evaluated again: its equilibrium, terms and gradient.
    pub evaluation: DesignEvaluation,
    /// The equilibrium of the best pattern as the run found it: the warm start of `evaluation` (what a
    /// replay of that evaluation starts from, [`mod@crate::design_checkpoint`]).
    pub best_state: ClothOnBodyState,
    /// Seconds of the whole run.
    pub seconds: Real,
}

/// Cloth statistics of an evaluation for the progress report.
fn cloth_figures(problem: &DesignProblem) -> (Real, Real, Real, Real) {
    let system = problem.system();
    let state = problem.state();
    let (mut lo, mut hi) = (Real::INFINITY, 0.0_f64);
    if let Ok(states) = system.element_states(state) {
        for s in &states {
            lo = lo.min(s.principal_stretches[1]);
            hi = hi.max(s.principal_stretches[0]);
        }
    }
    let (mut area, mut weighted, mut max_p) = (0.0, 0.0, 0.0_f64);
    if let Ok(pressures) = system.element_pressures(state) {
        for (p, e) in pressures.iter().zip(system.elements()) {
            area += e.rest_area();
            weighted += p * e.rest_area();
            max_p = max_p.max(*p);
        }
    }
    let mean = if area > 0.0 { weighted / area } else { 0.0 };
    (lo, hi, mean, max_p)
}

/// Young–Laplace pressure mean (Pa), spread and minimum (Pa) of the last evaluation at `pattern`, away
/// from the free boundary; NaN when undefined.
fn young_laplace_figures(problem: &DesignProblem, pattern: &[Vec2]) -> (Real, Real, Real) {
    let Ok(cloth) = problem.system().cloth_positions(problem.state()) else {
        return (Real::NAN, Real::NAN, Real::NAN);
    };
    let input = crate::term::TermInput {
        mesh: problem.mesh(),
        cloth: &cloth,
        pattern,
        fabric: problem.fabric(),
    };
    match crate::young_laplace_pressure::young_laplace_statistics(
        &input,
        crate::mid_edge_shape_operator::BoundaryEdges::Free,
        false,
    ) {
        Ok(s) => (s.mean_pa, s.spread, s.min_pa),
        Err(_) => (Real::NAN, Real::NAN, Real::NAN),
    }
}

/// Optimizes the pattern of `problem` over the boundary positions of `map` from its initial parameters;
/// `on_iteration` sees every accepted iteration (the initial design first) and may stop the run, which
/// then ends with the best design so far. `should_stop` is polled at every Newton iteration of every
/// equilibrium solve and before every trial: once it says yes, the solve in progress stops after its
/// current Newton iteration, no further trial is solved, and the run ends with
/// [`DesignError::Cancelled`] (the final evaluation of the best design stops at its first Newton
/// iteration too). Errors otherwise only when the initial design cannot be evaluated.
pub fn pattern_design(
    problem: &mut DesignProblem,
    map: &PatternMap,
    edge_length: Real,
    params: &PatternDesignParams,
    on_iteration: &mut dyn FnMut(&DesignIteration) -> ControlFlow<()>,
    should_stop: &dyn Fn() -> bool,
) -> Result<PatternDesignResult, DesignError> {
    pattern_design_from(
        problem,
        map,
        edge_length,
        params,
        None,
        &mut |it, _| on_iteration(it),
        should_stop,
    )
}

/// [`pattern_design`] that hands `on_iteration` a checkpoint after every reported iteration, and goes on
/// from such a checkpoint when `resume` is one ([`mod@crate::design_checkpoint`]): with the same problem
/// set-up, map and settings, the resumed run reports the iterations after the checkpoint and ends with the
/// design the uninterrupted run ends with (time limits aside). Errors also when `resume` does not fit the
/// problem.
pub fn pattern_design_from(
    problem: &mut DesignProblem,
    map: &PatternMap,
    edge_length: Real,
    params: &PatternDesignParams,
    resume: Option<DesignCheckpoint>,
    on_iteration: &mut dyn FnMut(&DesignIteration, &DesignCheckpoint) -> ControlFlow<()>,
    should_stop: &dyn Fn() -> bool,
) -> Result<PatternDesignResult, DesignError> {
    // Inexact solves change the problem's tolerance between evaluations: it leaves as it came, whatever
    // the outcome.
    let tight = problem.equilibrium_tolerance();
    let result = design_levels(
        problem,
        map,
        edge_length,
        params,
        resume,
        on_iteration,
        should_stop,
        tight,
    );
    problem.set_equilibrium_tolerance(tight)?;
    result
}

/// The body of [`pattern_design_from`]: the levels one after the other, then the best design evaluated
/// again at the problem's own tolerance `tight` (taken before a resumed run's replay changes it).
#[allow(clippy::too_many_arguments)]
fn design_levels(
    problem: &mut DesignProblem,
    map: &PatternMap,
    edge_length: Real,
    params: &PatternDesignParams,
    resume: Option<DesignCheckpoint>,
    on_iteration: &mut dyn FnMut(&DesignIteration, &DesignCheckpoint) -> ControlFlow<()>,
    should_stop: &dyn Fn() -> bool,
    tight: Real,
) -> Result<PatternDesignResult, DesignError> {
    let seconds_before = resume.as_ref().map_or(0.0, |c| c.seconds.max(0.0));
    let start = Instant::now()
        .checked_sub(std::time::Duration::from_secs_f64(seconds_before))
        .unwrap_or_else(Instant::now);
    if !(edge_length.is_finite() && edge_length > 0.0) {
        return Err(DesignError::Pattern(format!(
            "the cloth edge length must be a positive length (m), got {edge_length}"
        )));
    }
    let p0 = map.initial_parameters();
    let pattern0 = map
        .apply(&p0)
        .map_err(|e| DesignError::Pattern(e.to_string()))?;
    let mut poll = |_: &skintight_physics::IterationInfo| {
        if should_stop() {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    };
    if let Some(cp) = &resume {
        let state = problem.state();
        cp.check(
            p0.len(),
            params.mode_levels.len() + 1,
            map.num_pattern_vertices(),
            state.cloth.len(),
            state.body.len(),
        )
        .map_err(|e| {
            DesignError::Pattern(format!("the checkpoint does not fit this design: {e}"))
        })?;
        // The last solve again, from the same warm start: the state, factorization and last pattern of
        // the uninterrupted run. Its outcome was known (a failed trial fails again).
        if let Some(last) = &cp.last_evaluation {
            match problem.replay(last, &mut poll) {
                Err(DesignError::Cancelled) => return Err(DesignError::Cancelled),
                _ if should_stop() => return Err(DesignError::Cancelled),
                _ => {}
            }
        }
        problem.restore_counts(cp.evaluations, cp.totals);
    }
    if let Some(s) = &params.inexact {
        s.validate()
            .map_err(|e| DesignError::Solve(format!("inexact solves: {e}")))?;
    }
    // The normalized gradient norm of the accepted design that the inexact schedule follows (not known
    // yet: +∞).
    let accepted_gradient = std::cell::Cell::new(
        resume
            .as_ref()
            .map_or(Real::INFINITY, |cp| cp.optimizer.gradient_norm()),
    );
    let gradient_tolerance = match params.method {
        Optimizer::Lbfgs => params.lbfgs.gradient_tolerance,
        Optimizer::GaussNewton => params.gauss_newton.gradient_tolerance,
    };
    let t0 = match &resume {
        Some(cp) => cp.initial_objective,
        None => problem.evaluate(&pattern0, false, &mut poll)?.value,
    };
    let start_quality = pattern_quality(problem.mesh(), &pattern0, edge_length);
    // Set when an accepted iterate needs a remesh: the run stops there.
    let remesh_requested = std::cell::Cell::new(false);
    // The bounds of this run: the settings', or 10 % / 50 % beyond the mesh it starts from where that mesh
    // is already near or beyond them (a remeshed jagged boundary keeps short edges at its corners), so that a
    // run does not stop right after a remesh for what the remesh cannot change.
    let needs_remesh = |q: &PatternQuality| {
        params.remesh.as_ref().is_some_and(|r| {
            let bounds = PatternQualityParams {
                min_quality: r.min_quality.min(0.9 * start_quality.min_quality),
                max_edge_ratio: r.max_edge_ratio.max(1.5 * start_quality.max_edge_ratio),
                ..r.clone()
            };
            bounds.needs_remesh(q)
        })
    };
    let mut final_level = 0;
    if !(t0.is_finite() && t0 > 0.0) {
        // Nothing to improve: the initial design already meets every objective.
        return finish(
            problem,
            map,
            p0,
            t0,
            0,
            OptimizerStop::GradientTolerance,
            Vec::new(),
            start,
            false,
            0,
            should_stop,
        );
    }

    let mut history: Vec<DesignIteration> = Vec::new();
    let mut best = (p0.clone(), t0);
    let mut best_state = problem.state().clone();
    let mut iterations_before = 0;
    let mut stop_reason = OptimizerStop::MaxIterations;
    let mut stopped = false;
    let mut p_start = p0.clone();
    let levels = params.mode_levels.len() + 1;
    // A resumed run: the level it was in, its optimizer, and what the run had gathered.
    let mut resume_level: Option<(OptimizerState, Option<Real>, bool)> = None;
    let mut first_level = 0;
    if let Some(cp) = resume {
        first_level = cp.level;
        history = cp.history;
        best = (cp.best_parameters, cp.best_objective);
        best_state = cp.best_state;
        iterations_before = cp.iterations_before;
        stop_reason = cp.stop_reason;
        p_start = cp.level_start;
        resume_level = Some((cp.optimizer, cp.level_time_left, cp.remesh_requested));
    }
    for level in first_level..levels {
        if stopped {
            break;
        }
        final_level = level;
        let resumed = resume_level.take();
        // A checkpoint taken where the run stopped for a remesh: the level ends there again.
        let resumed_remesh = match &resumed {
            Some((optimizer, _, true)) => {
                remesh_requested.set(true);
                Some(optimizer.iteration())
            }
            _ => None,
        };
        // Parameters of this level: mode coefficients, or the boundary positions themselves.
        let modes = match params.mode_levels.get(level) {
            Some(&k) => Some(
                BoundaryModes::new(
                    problem.mesh(),
                    &map.apply(&p_start)
                        .map_err(|e| DesignError::Pattern(e.to_string()))?,
                    k,
                )
                .map_err(|e| DesignError::Pattern(e.to_string()))?,
            ),
            None => None,
        };
        let to_p = |z: &[Real]| -> Result<Vec<Real>, DesignError> {
            let scaled: Vec<Real> = z.iter().map(|v| v * edge_length).collect();
            match &modes {
                Some(m) => m
                    .apply(&scaled)
                    .map_err(|e| DesignError::Pattern(e.to_string())),
                None => Ok(scaled),
            }
        };
        let z0: Vec<Real> = match &modes {
            Some(m) => m
                .initial_coefficients()
                .iter()
                .map(|v| v / edge_length)
                .collect(),
            None => p_start.iter().map(|v| v / edge_length).collect(),
        };
        let (max_iterations, time_limit) = match params.method {
            Optimizer::Lbfgs => (params.lbfgs.max_iterations, params.lbfgs.time_limit_seconds),
            Optimizer::GaussNewton => (
                params.gauss_newton.max_iterations,
                params.gauss_newton.time_limit_seconds,
            ),
        };
        let mut remaining = max_iterations.saturating_sub(iterations_before);
        if let (Some(cap), true) = (params.level_max_iterations, modes.is_some()) {
            remaining = remaining.min(cap);
        }
        if remaining == 0 {
            break;
        }
        let time_left = match &resumed {
            Some((_, left, _)) => *left,
            None => time_limit.map(|t| (t - start.elapsed().as_secs_f64()).max(1e-3)),
        };
        let coarse_level = modes.is_some() && params.level_min_relative_decrease > 0.0;
        let cell = RefCell::new(&mut *problem);
        // The evaluations since the last accepted point, to report the terms of the next one (the line
        // search may accept a trial other than its last).
        let last: RefCell<Vec<(Vec<Real>, Real, DesignIteration, PatternQuality)>> =
            Default::default();
        let best_cell = RefCell::new((&mut best, &mut best_state));
        let objective = |z: &[Real]| -> Result<(Real, Vec<Real>), DesignError> {
            // Once stopped, every trial fails at once (the line search then gives up without solving).
            if should_stop() {
                return Err(DesignError::Cancelled);
            }
            let p = to_p(z)?;
            let pattern = map
                .apply(&p)
                .map_err(|e| DesignError::Pattern(e.to_string()))?;
            let mut problem = cell.borrow_mut();
            if let Some(s) = &params.inexact {
                problem.set_equilibrium_tolerance(s.tolerance(
                    tight,
                    accepted_gradient.get(),
                    gradient_tolerance,
                ))?;
            }
            let mut eval = problem.evaluate(&pattern, true, &mut |_| stop_flow(should_stop))?;
            if let Some(s) = &params.inexact {
                // An objective its residual misreads beyond the bound: solved again, tighter.
                while let Some(t) = s.tighter(
                    tight,
                    eval.equilibrium.residual,
                    eval.value,
                    eval.value_error.unwrap_or(0.0),
                ) {
                    problem.set_equilibrium_tolerance(t)?;
                    eval = problem.evaluate(&pattern, true, &mut |_| stop_flow(should_stop))?;
                }
            }
            let gradient_pattern = eval.gradient.as_ref().expect("gradient asked for");
            let gp = map
                .apply_jacobian_transpose(gradient_pattern)
                .map_err(|e| DesignError::Pattern(e.to_string()))?;
            let gradient_norm = gp.iter().map(|v| v * v).sum::<Real>().sqrt();
            // Chain to this level's parameters, then normalize.
            let gz = match &modes {
                Some(m) => m
                    .apply_jacobian_transpose(&gp)
                    .map_err(|e| DesignError::Pattern(e.to_string()))?,
                None => gp,
            };
            let gz: Vec<Real> = gz.iter().map(|v| v * edge_length / t0).collect();
            let gz_norm = gz.iter().map(|v| v * v).sum::<Real>().sqrt();
            let (lo, hi, mean_p, max_p) = cloth_figures(&problem);
            let yl = young_laplace_figures(&problem, &pattern);
            let quality = pattern_quality(problem.mesh(), &pattern, edge_length);
            let window = window_area_fraction(&problem, &eval, &pattern);
            {
                let mut b = best_cell.borrow_mut();
                if eval.value < b.0.1 {
                    *b.0 = (p.clone(), eval.value);
                    *b.1 = problem.state().clone();
                }
            }
            last.borrow_mut().push((
                z.to_vec(),
                gz_norm,
                DesignIteration {
                    iteration: 0,
                    level,
                    objective: eval.value,
                    terms: eval
                        .terms
                        .iter()
                        .map(|t| (t.name.to_string(), t.value))
                        .collect(),
                    gradient_norm,
                    step_length: 0.0,
                    min_stretch: lo,
                    max_stretch: hi,
                    mean_pressure_pa: mean_p,
                    max_pressure_pa: max_p,
                    young_laplace_mean_pa: yl.0,
                    young_laplace_spread: yl.1,
                    young_laplace_min_pa: yl.2,
                    min_pattern_quality: quality.min_quality,
                    remeshes: 0,
                    evaluations: problem.evaluations(),
                    newton_iterations: eval.equilibrium.newton_iterations,
                    step_evaluations: 0,
                    step_newton_iterations: 0,
                    step_factorizations: 0,
                    newton_iterations_total: 0,
                    factorizations_total: 0,
                    seconds: 0.0,
                    window_area_fraction: window,
                },
                quality,
            ));
            Ok((eval.value / t0, gz))
        };
        let mut report = |k: usize,
                          x: &[Real],
                          value: Real,
                          step: Real,
                          optimizer: &dyn Fn() -> OptimizerState|
         -> ControlFlow<()> {
            if should_stop() {
                return ControlFlow::Break(());
            }
            // The accepted point is one of the trials evaluated since the last one.
            let found = last
                .borrow()
                .iter()
                .rev()
                .find(|(z, _, _, _)| z.as_slice() == x)
                .map(|(_, gz_norm, entry, quality)| {
                    accepted_gradient.set(*gz_norm);
                    (entry.clone(), *quality)
                });
            last.borrow_mut().clear();
            let remesh_now = k > 0 && found.as_ref().is_some_and(|(_, q)| needs_remesh(q));
            let mut entry = match found {
                Some((entry, _)) => entry,
                None => DesignIteration {
                    iteration: 0,
                    level,
                    objective: value * t0,
                    terms: Vec::new(),
                    gradient_norm: Real::NAN,
                    step_length: 0.0,
                    min_stretch: Real::NAN,
                    max_stretch: Real::NAN,
                    mean_pressure_pa: Real::NAN,
                    max_pressure_pa: Real::NAN,
                    young_laplace_mean_pa: Real::NAN,
                    young_laplace_spread: Real::NAN,
                    young_laplace_min_pa: Real::NAN,
                    min_pattern_quality: Real::NAN,
                    remeshes: 0,
                    evaluations: 0,
                    newton_iterations: 0,
                    step_evaluations: 0,
                    step_newton_iterations: 0,
                    step_factorizations: 0,
                    newton_iterations_total: 0,
                    factorizations_total: 0,
                    seconds: 0.0,
                    window_area_fraction: None,
                },
            };
            if level > 0 && k == 0 {
                // The start of a finer level is the end of the coarser one: already reported.
                return ControlFlow::Continue(());
            }
            entry.iteration = iterations_before + k;
            entry.step_length = step;
            entry.seconds = start.elapsed().as_secs_f64();
            {
                // The work of every solve, so far and since the previous reported iteration.
                let problem = cell.borrow();
                let totals = problem.equilibrium_totals();
                entry.evaluations = problem.evaluations();
                entry.newton_iterations_total = totals.newton_iterations;
                entry.factorizations_total = totals.factorizations;
                let previous = history.last();
                let before = |f: fn(&DesignIteration) -> usize| previous.map_or(0, f);
                entry.step_evaluations =
                    entry.evaluations.saturating_sub(before(|p| p.evaluations));
                entry.step_newton_iterations = entry
                    .newton_iterations_total
                    .saturating_sub(before(|p| p.newton_iterations_total));
                entry.step_factorizations = entry
                    .factorizations_total
                    .saturating_sub(before(|p| p.factorizations_total));
            }
            history.push(entry);
            let checkpoint = {
                let problem = cell.borrow();
                let best = best_cell.borrow();
                DesignCheckpoint {
                    initial_objective: t0,
                    level,
                    level_start: p_start.clone(),
                    level_time_left: time_left,
                    iterations_before,
                    best_parameters: best.0.0.clone(),
                    best_objective: best.0.1,
                    best_state: best.1.clone(),
                    history: history.clone(),
                    optimizer: optimizer(),
                    last_evaluation: problem.last_evaluation().cloned(),
                    evaluations: problem.evaluations(),
                    totals: problem.equilibrium_totals(),
                    remesh_requested: remesh_now,
                    stop_reason,
                    seconds: start.elapsed().as_secs_f64(),
                }
            };
            let flow = on_iteration(history.last().expect("just pushed"), &checkpoint);
            if remesh_now {
                remesh_requested.set(true);
                return ControlFlow::Break(());
            }
            flow
        };
        // Err((error, whether it is fatal at any level)): an initial evaluation that fails ends a finer
        // level with the best design so far; invalid settings are always fatal.
        let outcome: Result<(usize, OptimizerStop), (DesignError, bool)> = match params.method {
            Optimizer::Lbfgs => {
                let mut level_params = LbfgsParams {
                    max_iterations: remaining,
                    time_limit_seconds: time_left,
                    ..params.lbfgs
                };
                if coarse_level {
                    level_params.min_relative_decrease = level_params
                        .min_relative_decrease
                        .max(params.level_min_relative_decrease);
                    level_params.no_progress_iterations = LEVEL_NO_PROGRESS_ITERATIONS;
                }
                let from = match &resumed {
                    Some((OptimizerState::Lbfgs(state), ..)) => LbfgsStart::Resume(state.clone()),
                    Some(_) => {
                        return Err(DesignError::Pattern(
                            "the checkpoint is of a Gauss-Newton run, the design uses L-BFGS"
                                .into(),
                        ));
                    }
                    None => LbfgsStart::Point(&z0),
                };
                match resumed_remesh {
                    Some(k) => Ok((k, OptimizerStop::Callback)),
                    None => {
                        match lbfgs_from(objective, from, &level_params, |it: &LbfgsIteration| {
                            report(it.iteration, it.x, it.value, it.step_length, &|| {
                                OptimizerState::Lbfgs(it.state())
                            })
                        }) {
                            Ok(r) => Ok((r.iterations, r.stop_reason)),
                            Err(crate::lbfgs::LbfgsError::InitialEvaluation(e)) => Err((e, false)),
                            Err(e) => Err((DesignError::Solve(e.to_string()), true)),
                        }
                    }
                }
            }
            Optimizer::GaussNewton => {
                let mut level_params = GaussNewtonParams {
                    max_iterations: remaining,
                    time_limit_seconds: time_left,
                    ..params.gauss_newton
                };
                if coarse_level {
                    level_params.min_relative_decrease = level_params
                        .min_relative_decrease
                        .max(params.level_min_relative_decrease);
                    level_params.no_progress_iterations = LEVEL_NO_PROGRESS_ITERATIONS;
                }
                // A = dX̄/dz (m per edge length), constant over the level.
                let nz = z0.len();
                let design_map = design_map_matrix(2 * map.num_pattern_vertices(), nz, |i| {
                    let mut e = vec![0.0; nz];
                    e[i] = edge_length;
                    let dp = match &modes {
                        Some(m) => m.apply_jacobian(&e).map_err(|e| e.to_string())?,
                        None => e,
                    };
                    let dx = map.apply_jacobian(&dp).map_err(|e| e.to_string())?;
                    Ok(dx.iter().flat_map(|v| [v.x, v.y]).collect())
                })
                .map_err(|e| DesignError::Solve(e.to_string()));
                match design_map {
                    Err(e) => Err((e, true)),
                    Ok(design_map) => {
                        // A by rows (2#Vp × #c, row-major), for K A formed matrix-free.
                        let a_rows = {
                            let mut rows = vec![0.0; design_map.nrows() * nz];
                            let (cp, ri) = (
                                design_map.symbolic().col_ptr(),
                                design_map.symbolic().row_idx(),
                            );
                            for c in 0..nz {
                                for k in cp[c]..cp[c + 1] {
                                    rows[ri[k] * nz + c] += design_map.val()[k];
                                }
                            }
                            rows
                        };
                        let mut solver = AdjointGaussNewton::new();
                        let residual_scale = 1.0 / t0.sqrt();
                        let direction = |z: &[Real],
                                         gz: &[Real],
                                         kappa: Real|
                         -> Result<Vec<Real>, DesignError> {
                            if should_stop() {
                                return Err(DesignError::Cancelled);
                            }
                            let p = to_p(z)?;
                            let pattern = map
                                .apply(&p)
                                .map_err(|e| DesignError::Pattern(e.to_string()))?;
                            let mut problem = cell.borrow_mut();
                            if problem.last_pattern() != Some(pattern.as_slice()) {
                                // After a failed line search the state is a trial's: back to z.
                                problem
                                    .evaluate(&pattern, false, &mut |_| stop_flow(should_stop))?;
                            }
                            let reduced = params
                                .gauss_newton_solver
                                .reduced(problem.system().num_dofs(), gz.len());
                            let lin = if reduced {
                                problem.linearize_times(&a_rows, nz)?
                            } else {
                                problem.linearize()?
                            };
                            if lin.residuals.values.is_empty() {
                                return Ok(gz.iter().map(|g| -g / kappa).collect());
                            }
                            let r = &lin.residuals;
                            let residuals = Residuals {
                                values: r.values.iter().map(|v| v * residual_scale).collect(),
                                cloth_jacobian: r
                                    .cloth_jacobian
                                    .iter()
                                    .map(|&(k, c, d)| (k, c, d * residual_scale))
                                    .collect(),
                                pattern_jacobian: r
                                    .pattern_jacobian
                                    .iter()
                                    .map(|&(k, v, d)| (k, v, d * residual_scale))
                                    .collect(),
                                state_jacobian: r
                                    .state_jacobian
                                    .iter()
                                    .map(|&(k, q, d)| (k, q, d * residual_scale))
                                    .collect(),
                            };
                            let system = GaussNewtonSystem {
                                residuals: &residuals,
                                cloth_jacobian: lin.cloth_jacobian.as_ref(),
                                hessian: lin.hessian.as_ref(),
                                mixed: lin.mixed.as_ref(),
                                design_map: design_map.as_ref(),
                                gradient: gz,
                            };
                            if reduced {
                                reduced_gauss_newton_direction(&system, kappa, |rhs, columns| {
                                    problem
                                        .solve_hessian_columns(rhs, columns)
                                        .map(|_| ())
                                        .map_err(|e| e.to_string())
                                })
                            } else {
                                solver.direction(&system, kappa)
                            }
                            .map(|d| d.design)
                            .map_err(|e| DesignError::Solve(e.to_string()))
                        };
                        let from = match &resumed {
                            Some((OptimizerState::GaussNewton(state), ..)) => {
                                GaussNewtonStart::Resume(state.clone())
                            }
                            Some(_) => {
                                return Err(DesignError::Pattern(
                                    "the checkpoint is of an L-BFGS run, the design uses Gauss-Newton"
                                        .into(),
                                ));
                            }
                            None => GaussNewtonStart::Point(&z0),
                        };
                        match resumed_remesh {
                            Some(k) => Ok((k, OptimizerStop::Callback)),
                            None => match gauss_newton_from(
                                objective,
                                direction,
                                from,
                                &level_params,
                                |it: &GaussNewtonIteration| {
                                    report(it.iteration, it.x, it.value, it.step_length, &|| {
                                        OptimizerState::GaussNewton(it.state())
                                    })
                                },
                            ) {
                                Ok(r) => Ok((r.iterations, r.stop_reason)),
                                Err(GaussNewtonRunError::InitialEvaluation(e)) => Err((e, false)),
                                Err(e) => Err((DesignError::Solve(e.to_string()), true)),
                            },
                        }
                    }
                }
            }
        };
        drop(cell);
        match outcome {
            Ok((iterations, reason)) => {
                iterations_before += iterations;
                stop_reason = reason;
                // A level that used up its own budget (`level_max_iterations`) hands over to the next;
                // the whole run's iteration limit stops everything.
                let run_limit =
                    reason == OptimizerStop::MaxIterations && iterations_before >= max_iterations;
                if should_stop()
                    || run_limit
                    || matches!(reason, OptimizerStop::Callback | OptimizerStop::TimeLimit)
                {
                    stopped = true;
                }
            }
            Err((e, fatal)) => {
                if fatal || level == 0 || should_stop() {
                    return Err(e);
                }
                break;
            }
        }
        // The next level starts from the best design so far, and so does its equilibrium.
        p_start = best.0.clone();
        problem.set_state(best_state.clone());
    }
    problem.set_state(best_state);
    problem.set_equilibrium_tolerance(tight)?;
    finish(
        problem,
        map,
        best.0,
        t0,
        iterations_before,
        stop_reason,
        history,
        start,
        remesh_requested.get(),
        final_level,
        should_stop,
    )
}

/// The fraction of the pattern area (`pattern`: `#Vp`, m) whose triangles the stretch-window term leaves
/// without penalty — both principal stretches inside the window — at `eval`; `None` without that term.
fn window_area_fraction(
    problem: &DesignProblem,
    eval: &DesignEvaluation,
    pattern: &[Vec2],
) -> Option<Real> {
    let term = eval
        .terms
        .iter()
        .find(|t| t.name == crate::StretchWindow::NAME)?;
    let mesh = problem.mesh();
    let (mut inside, mut total) = (0.0, 0.0);
    for (f, &v) in term.per_element.iter().enumerate() {
        let a = mesh.pattern_area(pattern, f);
        total += a;
        if v == 0.0 {
            inside += a;
        }
    }
    (total > 0.0).then(|| inside / total)
}

/// `Break` once `should_stop` says so: the poll of every Newton iteration of every solve.
fn stop_flow(should_stop: &dyn Fn() -> bool) -> ControlFlow<()> {
    if should_stop() {
        ControlFlow::Break(())
    } else {
        ControlFlow::Continue(())
    }
}

#[allow(clippy::too_many_arguments)]
fn finish(
    problem: &mut DesignProblem,
    map: &PatternMap,
    parameters: Vec<Real>,
    initial_objective: Real,
    iterations: usize,
    stop_reason: OptimizerStop,
    history: Vec<DesignIteration>,
    start: Instant,
    remesh_requested: bool,
    level: usize,
    should_stop: &dyn Fn() -> bool,
) -> Result<PatternDesignResult, DesignError> {
    let pattern = map
        .apply(&parameters)
        .map_err(|e| DesignError::Pattern(e.to_string()))?;
    let best_state = problem.state().clone();
    // At the job's own tolerance from the (maybe loosely solved) best equilibrium; a solve that stays
    // short of it is reported, not lost (`evaluation.equilibrium.converged`).
    let evaluation = problem.final_evaluation(&pattern, true, &mut |_| stop_flow(should_stop))?;
    Ok(PatternDesignResult {
        best_state,
        pattern,
        parameters,
        initial_objective,
        final_objective: evaluation.value,
        iterations,
        evaluations: problem.evaluations(),
        stop_reason,
        remeshes: 0,
        remesh_seconds: 0.0,
        remesh_requested,
        level,
        history,
        evaluation,
        seconds: start.elapsed().as_secs_f64(),
    })
}
