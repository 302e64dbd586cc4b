//! The design loop: L-BFGS or adjoint Gauss-Newton (`skintight_optimize`) over the pattern boundary
//! (thesis ch. 7; paper Sec. 6.2–6.3), each objective evaluation one equilibrium warm-started from the
//! last ([`DesignProblem::evaluate`]), optionally coarse to fine over low-frequency boundary modes (paper
//! Sec. 6.5, [`BoundaryModes`]).
//!
//! **Scaling.** The optimizer works on the normalized objective `T̃ = T / T₀` (`T₀` the objective of the
//! initial pattern) over the boundary positions measured in cloth edge lengths `ℓ`, `p̃ = p / ℓ`. Its
//! stopping rule `‖dT̃/dp̃‖₂ < gradient_tolerance` (default `10⁻³`) is thus dimensionless and the same
//! for any weights and garment size: no move of the boundary by one edge length changes the objective
//! by more than 0.1 % of where it started. Reports give `T` and `‖dT/dp‖` in the terms' own units.
//!
//! **The problem the optimizers see.** Each coarse-to-fine level is a `Level`: an
//! [`Objective`] (the normalized objective and its gradient over the level's parameters) and, for
//! Gauss-Newton, an [`AdjointProblem`]: its linearization at the accepted design
//! ([`DesignProblem::linearize`], residuals divided by `√T₀`, in the optimizers' form by
//! [`crate::DesignLinearization::adjoint`]) with the parameter map `A = dX̄/dp̃` (m per edge length; at a
//! coarse level composed with the modes basis, `A = W B ℓ`) built once per level. The directions are
//! solved by the KKT system or, while the dense sensitivity fits, in reduced form
//! ([`GaussNewtonSolver`]). The optimizer's callback gets the level back to report the accepted
//! iteration and its checkpoint; what the run carries from level to level is a `DesignRun`.
//!
//! **Failures.** A pattern the garment finds no equilibrium for (or that folds a triangle over) counts as
//! a step too long in the line search. The result is always the best design seen, evaluated once more
//! at the end so that its equilibrium, terms and gradient are those reported.

use std::ops::ControlFlow;
use std::time::Instant;

use skintight_optimize::{
    AdjointGaussNewton, AdjointProblem, GaussNewtonParams, GaussNewtonRunError, GaussNewtonSolver,
    GaussNewtonStart, LbfgsError, LbfgsIteration, LbfgsParams, LbfgsStart, Linearization,
    MixedForm, Objective, OptimizerState, OptimizerStop, gauss_newton_from, lbfgs_from,
    parameter_map_matrix,
};
use skintight_physics::ClothOnBodyState;

use crate::boundary_modes::BoundaryModes;
use crate::design_checkpoint::DesignCheckpoint;
pub use crate::design_iteration::DesignIteration;
use crate::design_problem::{DesignError, DesignEvaluation, DesignProblem};
use crate::inexact_tolerance::InexactTolerance;
use crate::math::{Real, Vec2};
use crate::pattern_map::PatternMap;
use crate::pattern_quality::{PatternQuality, PatternQualityParams, pattern_quality};
use crate::seam_projection::{SeamProjected, SeamProjection};

/// Which optimizer [`pattern_design`] runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Optimizer {
    /// L-BFGS with a strong-Wolfe line search ([`mod@skintight_optimize::lbfgs`]), settings in
    /// [`PatternDesignParams::lbfgs`].
    #[default]
    Lbfgs,
    /// Adjoint Gauss-Newton with Levenberg-Marquardt damping and a backtracking line search
    /// ([`skintight_optimize::gauss_newton_loop`]), settings in [`PatternDesignParams::gauss_newton`].
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
    /// (measured in docs/BENCHMARKS.md, session 19).
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
    /// Seams held during the design ([`mod@crate::seam_projection`]): every evaluated pattern is the map
    /// of the sewable parameters nearest the optimizer's, so every pair of sewn edges is equally long
    /// (to [`SeamProjection::DEFAULT_TOLERANCE`]) in every design, the best one included. `false`
    /// (default): the boundary parameters are free and only a [`crate::SeamLength`] term keeps the seams
    /// near sewable.
    pub hold_seams: bool,
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
            hold_seams: false,
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
    let settings = RunSettings {
        map,
        edge_length,
        params,
        should_stop,
        tight,
    };
    let mut run = DesignRun::new(problem, settings, resume.as_ref(), on_iteration)?;
    if !(run.t0.is_finite() && run.t0 > 0.0) {
        // Nothing to improve: the initial design already meets every objective.
        run.stop_reason = OptimizerStop::GradientTolerance;
        return run.finish(problem, 0);
    }
    let (first_level, mut resumed) = match resume {
        Some(cp) => (cp.level, Some(run.resume(cp))),
        None => (0, None),
    };
    let (mut final_level, mut stopped) = (0, false);
    for level in first_level..params.mode_levels.len() + 1 {
        if stopped {
            break;
        }
        final_level = level;
        match run.level(problem, level, resumed.take())? {
            LevelEnd::Skipped => break,
            LevelEnd::Stopped(iterations, reason) => stopped = run.ends_with(iterations, reason),
            LevelEnd::Failed(e, fatal) => {
                if fatal || level == 0 || should_stop() {
                    return Err(e);
                }
                break;
            }
        }
        // The next level starts from the best design so far, and so does its equilibrium.
        run.p_start = run.best.0.clone();
        problem.set_state(run.best_state.clone());
    }
    problem.set_state(run.best_state.clone());
    problem.set_equilibrium_tolerance(tight)?;
    run.finish(problem, final_level)
}

/// The fixed inputs of a design run.
#[derive(Clone, Copy)]
struct RunSettings<'a> {
    map: &'a PatternMap,
    /// The cloth edge length `ℓ` (m): the unit of the optimizer's parameters.
    edge_length: Real,
    params: &'a PatternDesignParams,
    should_stop: &'a dyn Fn() -> bool,
    /// The problem's own equilibrium tolerance.
    tight: Real,
}

/// Where a checkpoint puts a resumed run's level: its optimizer, time limit and whether it stopped for a
/// remesh.
struct LevelResume {
    optimizer: OptimizerState,
    time_left: Option<Real>,
    remesh_requested: bool,
}

/// How a level ended.
enum LevelEnd {
    /// No iterations were left for it.
    Skipped,
    /// Its optimizer stopped after this many accepted steps, for this reason.
    Stopped(usize, OptimizerStop),
    /// Its optimizer could not start: the error and whether it is fatal at any level (invalid settings;
    /// otherwise a finer level ends the run with the best design so far).
    Failed(DesignError, bool),
}

/// A design run across its levels: the normalization, the best design so far and the history (what a
/// checkpoint stores besides the level's optimizer).
struct DesignRun<'a> {
    settings: RunSettings<'a>,
    on_iteration: &'a mut dyn FnMut(&DesignIteration, &DesignCheckpoint) -> ControlFlow<()>,
    start: Instant,
    /// `T₀`, the objective of the initial pattern.
    t0: Real,
    gradient_tolerance: Real,
    /// The quality of the pattern the run started from (the remesh bounds are relative to it).
    start_quality: PatternQuality,
    /// The normalized gradient norm of the accepted design that the inexact schedule follows (not known
    /// yet: +∞).
    accepted_gradient: Real,
    history: Vec<DesignIteration>,
    /// The best boundary parameters (m) and objective, and its equilibrium.
    best: (Vec<Real>, Real),
    best_state: ClothOnBodyState,
    /// Accepted iterations of the levels before the current one.
    iterations_before: usize,
    stop_reason: OptimizerStop,
    /// Set when an accepted iterate needs a remesh: the run stops there.
    remesh_requested: bool,
    /// The boundary parameters (m) the current level started from.
    p_start: Vec<Real>,
    /// The projection onto sewable parameters when the seams are held
    /// ([`PatternDesignParams::hold_seams`]).
    seams: Option<SeamProjection>,
}

/// The parameters `p` made sewable by `seams` (unchanged without it).
fn sewn(
    seams: Option<&SeamProjection>,
    p: Vec<Real>,
) -> Result<(Vec<Real>, Option<SeamProjected>), DesignError> {
    match seams {
        None => Ok((p, None)),
        Some(s) => {
            let out = s
                .project(&p)
                .map_err(|e| DesignError::Pattern(format!("holding the seams: {e}")))?;
            Ok((out.parameters.clone(), Some(out)))
        }
    }
}

impl<'a> DesignRun<'a> {
    /// Checks the settings, replays a checkpoint's last evaluation, and evaluates the initial design
    /// (`T₀`; a resumed run takes the checkpoint's).
    fn new(
        problem: &mut DesignProblem,
        settings: RunSettings<'a>,
        resume: Option<&DesignCheckpoint>,
        on_iteration: &'a mut dyn FnMut(&DesignIteration, &DesignCheckpoint) -> ControlFlow<()>,
    ) -> Result<Self, DesignError> {
        let RunSettings {
            map,
            edge_length,
            params,
            should_stop,
            ..
        } = settings;
        let seconds_before = resume.map_or(0.0, |c| c.seconds.max(0.0));
        let start = Instant::now()
            .checked_sub(std::time::Duration::from_secs_f64(seconds_before))
            .unwrap_or_else(Instant::now);
        if !(edge_length.is_finite() && edge_length > 0.0) {
            return Err(DesignError::Pattern(format!(
                "the cloth edge length must be a positive length (m), got {edge_length}"
            )));
        }
        let seams = if params.hold_seams {
            Some(
                SeamProjection::new(problem.mesh(), map)
                    .map_err(|e| DesignError::Pattern(format!("holding the seams: {e}")))?,
            )
        } else {
            None
        };
        // The start made sewable (the caller's patterns are usually trued already: then it stays).
        let (p0, _) = sewn(seams.as_ref(), map.initial_parameters())?;
        let pattern0 = map
            .apply(&p0)
            .map_err(|e| DesignError::Pattern(e.to_string()))?;
        let mut poll = |_: &skintight_physics::IterationInfo| stop_flow(should_stop);
        if let Some(cp) = resume {
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
            // The last solve again, from the same warm start: the state, factorization and last pattern
            // of the uninterrupted run. Its outcome was known (a failed trial fails again).
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
        let accepted_gradient = resume.map_or(Real::INFINITY, |cp| cp.optimizer.gradient_norm());
        let gradient_tolerance = match params.method {
            Optimizer::Lbfgs => params.lbfgs.gradient_tolerance,
            Optimizer::GaussNewton => params.gauss_newton.gradient_tolerance,
        };
        let t0 = match resume {
            Some(cp) => cp.initial_objective,
            None => problem.evaluate(&pattern0, false, &mut poll)?.value,
        };
        let start_quality = pattern_quality(problem.mesh(), &pattern0, edge_length);
        Ok(Self {
            settings,
            on_iteration,
            start,
            t0,
            gradient_tolerance,
            start_quality,
            accepted_gradient,
            history: Vec::new(),
            best: (p0.clone(), t0),
            best_state: problem.state().clone(),
            iterations_before: 0,
            stop_reason: OptimizerStop::MaxIterations,
            remesh_requested: false,
            p_start: p0,
            seams,
        })
    }

    /// Takes over what the checkpoint's run had gathered; returns its level's optimizer.
    fn resume(&mut self, cp: DesignCheckpoint) -> LevelResume {
        self.history = cp.history;
        self.best = (cp.best_parameters, cp.best_objective);
        self.best_state = cp.best_state;
        self.iterations_before = cp.iterations_before;
        self.stop_reason = cp.stop_reason;
        self.p_start = cp.level_start;
        LevelResume {
            optimizer: cp.optimizer,
            time_left: cp.level_time_left,
            remesh_requested: cp.remesh_requested,
        }
    }

    /// The whole run's iteration limit and time limit (s), of its optimizer's settings.
    fn limits(&self) -> (usize, Option<Real>) {
        let params = self.settings.params;
        match params.method {
            Optimizer::Lbfgs => (params.lbfgs.max_iterations, params.lbfgs.time_limit_seconds),
            Optimizer::GaussNewton => (
                params.gauss_newton.max_iterations,
                params.gauss_newton.time_limit_seconds,
            ),
        }
    }

    /// Counts a level that stopped after `iterations` steps for `reason`; whether the run ends with it.
    fn ends_with(&mut self, iterations: usize, reason: OptimizerStop) -> bool {
        self.iterations_before += iterations;
        self.stop_reason = reason;
        // A level that used up its own budget (`level_max_iterations`) hands over to the next; the whole
        // run's iteration limit stops everything.
        let run_limit =
            reason == OptimizerStop::MaxIterations && self.iterations_before >= self.limits().0;
        (self.settings.should_stop)()
            || run_limit
            || matches!(reason, OptimizerStop::Callback | OptimizerStop::TimeLimit)
    }

    /// Whether an accepted pattern of quality `q` needs a remesh. The bounds of this run are the
    /// settings', or 10 % / 50 % beyond the mesh it starts from where that mesh is already near or beyond
    /// them (a remeshed jagged boundary keeps short edges at its corners), so that a run does not stop
    /// right after a remesh for what the remesh cannot change.
    fn needs_remesh(&self, q: &PatternQuality) -> bool {
        let start = &self.start_quality;
        self.settings.params.remesh.as_ref().is_some_and(|r| {
            let bounds = PatternQualityParams {
                min_quality: r.min_quality.min(0.9 * start.min_quality),
                max_edge_ratio: r.max_edge_ratio.max(1.5 * start.max_edge_ratio),
                ..r.clone()
            };
            bounds.needs_remesh(q)
        })
    }

    /// Runs coarse-to-fine level `index` (from its checkpoint when `resumed`) with the run's optimizer.
    /// Errors when the level's modes cannot be built or the checkpoint is of the other optimizer.
    fn level(
        &mut self,
        problem: &mut DesignProblem,
        index: usize,
        resumed: Option<LevelResume>,
    ) -> Result<LevelEnd, DesignError> {
        let RunSettings {
            map,
            edge_length,
            params,
            ..
        } = self.settings;
        // A checkpoint taken where the run stopped for a remesh: the level ends there again.
        let resumed_remesh = match &resumed {
            Some(r) if r.remesh_requested => {
                self.remesh_requested = true;
                Some(r.optimizer.iteration())
            }
            _ => None,
        };
        // Parameters of this level: mode coefficients, or the boundary positions themselves.
        let modes = match params.mode_levels.get(index) {
            Some(&k) => Some(
                BoundaryModes::new(
                    problem.mesh(),
                    &map.apply(&self.p_start)
                        .map_err(|e| DesignError::Pattern(e.to_string()))?,
                    k,
                )
                .map_err(|e| DesignError::Pattern(e.to_string()))?,
            ),
            None => None,
        };
        let z0: Vec<Real> = match &modes {
            Some(m) => m
                .initial_coefficients()
                .iter()
                .map(|v| v / edge_length)
                .collect(),
            None => self.p_start.iter().map(|v| v / edge_length).collect(),
        };
        let (max_iterations, time_limit) = self.limits();
        let mut remaining = max_iterations.saturating_sub(self.iterations_before);
        if let (Some(cap), true) = (params.level_max_iterations, modes.is_some()) {
            remaining = remaining.min(cap);
        }
        if remaining == 0 {
            return Ok(LevelEnd::Skipped);
        }
        let time_left = match &resumed {
            Some(r) => r.time_left,
            None => time_limit.map(|t| (t - self.start.elapsed().as_secs_f64()).max(1e-3)),
        };
        let coarse_level = modes.is_some() && params.level_min_relative_decrease > 0.0;
        let limits = LevelLimits {
            max_iterations: remaining,
            time_left,
            coarse: coarse_level,
        };
        let mut level = Level {
            run: self,
            problem,
            index,
            modes,
            time_left,
            trials: Vec::new(),
            seam_map: None,
        };
        let from = resumed.map(|r| r.optimizer);
        match params.method {
            Optimizer::Lbfgs => level.lbfgs(&z0, from, resumed_remesh, limits),
            Optimizer::GaussNewton => level.gauss_newton(&z0, from, resumed_remesh, limits),
        }
    }

    /// The best design evaluated again (see [`finish`]).
    fn finish(
        self,
        problem: &mut DesignProblem,
        level: usize,
    ) -> Result<PatternDesignResult, DesignError> {
        finish(
            problem,
            self.settings.map,
            self.best.0,
            self.t0,
            self.iterations_before,
            self.stop_reason,
            self.history,
            self.start,
            self.remesh_requested,
            level,
            self.settings.should_stop,
        )
    }
}

/// A level's share of the run's limits.
#[derive(Clone, Copy)]
struct LevelLimits {
    /// Accepted steps left to it.
    max_iterations: usize,
    /// Seconds left to it.
    time_left: Option<Real>,
    /// A coarse level that hands over when it creeps ([`PatternDesignParams::level_min_relative_decrease`]).
    coarse: bool,
}

impl LevelLimits {
    /// `min_relative_decrease` and `no_progress_iterations` of a coarse level.
    fn no_progress(self, params: &PatternDesignParams, own: (Real, usize)) -> (Real, usize) {
        if self.coarse {
            (
                own.0.max(params.level_min_relative_decrease),
                LEVEL_NO_PROGRESS_ITERATIONS,
            )
        } else {
            own
        }
    }
}

/// One evaluation since the last accepted point: its parameters, normalized gradient norm, report and
/// pattern quality (the line search may accept a trial other than its last).
struct Trial {
    z: Vec<Real>,
    gradient_norm: Real,
    entry: DesignIteration,
    quality: PatternQuality,
}

/// One coarse-to-fine level of a run: the design problem over this level's parameters `z` (mode
/// coefficients or boundary positions, in edge lengths), normalized by `T₀`, as the optimizers see it.
struct Level<'r, 'a> {
    run: &'r mut DesignRun<'a>,
    problem: &'r mut DesignProblem,
    index: usize,
    modes: Option<BoundaryModes>,
    time_left: Option<Real>,
    trials: Vec<Trial>,
    /// With the seams held and Gauss-Newton: what the design map at a point is built from.
    seam_map: Option<SeamMap>,
}

/// The parts of the level's design map `dX̄/dz = W (dq/dp) (dp/dz)` that do not change with `z`: the map
/// without the projection `A = W (dp/dz)` and the columns `W e_s` of the parameters `s` the projection
/// moves, so that at a point `dX̄/dz = A + W_s [(dq/dp − I)(dp/dz)]_s` (`dq/dp − I` is zero outside them).
struct SeamMap {
    /// `A` (`2#Vp × #z`, m per edge length).
    base: faer::sparse::SparseColMat<usize, Real>,
    /// The parameters `s` the projection moves.
    parameters: Vec<usize>,
    /// `W_s` (`2#Vp × #s`, dimensionless).
    columns: faer::Mat<Real>,
}

impl Level<'_, '_> {
    /// The boundary parameters (m) of the level's parameters `z`.
    fn to_p(&self, z: &[Real]) -> Result<Vec<Real>, DesignError> {
        let scaled: Vec<Real> = z
            .iter()
            .map(|v| v * self.run.settings.edge_length)
            .collect();
        match &self.modes {
            Some(m) => m
                .apply(&scaled)
                .map_err(|e| DesignError::Pattern(e.to_string())),
            None => Ok(scaled),
        }
    }

    /// The pattern (m) of the level's parameters `z` (through the seams' projection when they are held).
    fn pattern(&self, z: &[Real]) -> Result<Vec<Vec2>, DesignError> {
        let (q, _) = sewn(self.run.seams.as_ref(), self.to_p(z)?)?;
        self.run
            .settings
            .map
            .apply(&q)
            .map_err(|e| DesignError::Pattern(e.to_string()))
    }

    /// The level by L-BFGS from `z0` or from the checkpoint's optimizer `from`.
    fn lbfgs(
        &mut self,
        z0: &[Real],
        from: Option<OptimizerState>,
        resumed_remesh: Option<usize>,
        limits: LevelLimits,
    ) -> Result<LevelEnd, DesignError> {
        let own = self.run.settings.params.lbfgs;
        let (min_relative_decrease, no_progress_iterations) = limits.no_progress(
            self.run.settings.params,
            (own.min_relative_decrease, own.no_progress_iterations),
        );
        let params = LbfgsParams {
            max_iterations: limits.max_iterations,
            time_limit_seconds: limits.time_left,
            min_relative_decrease,
            no_progress_iterations,
            ..own
        };
        let from = match from {
            Some(OptimizerState::Lbfgs(state)) => LbfgsStart::Resume(state),
            Some(_) => {
                return Err(DesignError::Pattern(
                    "the checkpoint is of a Gauss-Newton run, the design uses L-BFGS".into(),
                ));
            }
            None => LbfgsStart::Point(z0),
        };
        if let Some(k) = resumed_remesh {
            return Ok(LevelEnd::Stopped(k, OptimizerStop::Callback));
        }
        let run = lbfgs_from(self, from, &params, |level, it: &LbfgsIteration| {
            level.report(it.iteration, it.x, it.value, it.step_length, &|| {
                OptimizerState::Lbfgs(it.state())
            })
        });
        Ok(match run {
            Ok(r) => LevelEnd::Stopped(r.iterations, r.stop_reason),
            Err(LbfgsError::InitialEvaluation(e)) => LevelEnd::Failed(e, false),
            Err(e) => LevelEnd::Failed(DesignError::Solve(e.to_string()), true),
        })
    }

    /// The level by adjoint Gauss-Newton from `z0` or from the checkpoint's optimizer `from`.
    fn gauss_newton(
        &mut self,
        z0: &[Real],
        from: Option<OptimizerState>,
        resumed_remesh: Option<usize>,
        limits: LevelLimits,
    ) -> Result<LevelEnd, DesignError> {
        let settings = self.run.settings;
        let own = settings.params.gauss_newton;
        let (min_relative_decrease, no_progress_iterations) = limits.no_progress(
            settings.params,
            (own.min_relative_decrease, own.no_progress_iterations),
        );
        let params = GaussNewtonParams {
            max_iterations: limits.max_iterations,
            time_limit_seconds: limits.time_left,
            min_relative_decrease,
            no_progress_iterations,
            ..own
        };
        // A = dX̄/dz (m per edge length), constant over the level.
        let nz = z0.len();
        let design_map = parameter_map_matrix(2 * settings.map.num_pattern_vertices(), nz, |i| {
            let mut e = vec![0.0; nz];
            e[i] = settings.edge_length;
            let dp = match &self.modes {
                Some(m) => m.apply_jacobian(&e).map_err(|e| e.to_string())?,
                None => e,
            };
            let dx = settings
                .map
                .apply_jacobian(&dp)
                .map_err(|e| e.to_string())?;
            Ok(dx.iter().flat_map(|v| [v.x, v.y]).collect())
        });
        let design_map = match design_map {
            Ok(m) => m,
            Err(e) => return Ok(LevelEnd::Failed(DesignError::Solve(e.to_string()), true)),
        };
        if let Some(seams) = &self.run.seams {
            // The columns of W for the parameters the seams' projection moves.
            let parameters = seams.constrained_parameters();
            let rows = 2 * settings.map.num_pattern_vertices();
            let mut columns = faer::Mat::<Real>::zeros(rows, parameters.len());
            let np = settings.map.num_parameters();
            for (c, &s) in parameters.iter().enumerate() {
                let mut e = vec![0.0; np];
                e[s] = 1.0;
                let dx = match settings.map.apply_jacobian(&e) {
                    Ok(dx) => dx,
                    Err(e) => {
                        return Ok(LevelEnd::Failed(DesignError::Pattern(e.to_string()), true));
                    }
                };
                for (v, d) in dx.iter().enumerate() {
                    columns[(2 * v, c)] = d.x;
                    columns[(2 * v + 1, c)] = d.y;
                }
            }
            self.seam_map = Some(SeamMap {
                base: design_map.clone(),
                parameters,
                columns,
            });
        }
        let from = match from {
            Some(OptimizerState::GaussNewton(state)) => GaussNewtonStart::Resume(state),
            Some(_) => {
                return Err(DesignError::Pattern(
                    "the checkpoint is of an L-BFGS run, the design uses Gauss-Newton".into(),
                ));
            }
            None => GaussNewtonStart::Point(z0),
        };
        if let Some(k) = resumed_remesh {
            return Ok(LevelEnd::Stopped(k, OptimizerStop::Callback));
        }
        let mut adjoint =
            AdjointGaussNewton::new(self, design_map, settings.params.gauss_newton_solver);
        let run = gauss_newton_from(&mut adjoint, from, &params, |adjoint, it| {
            let state = || OptimizerState::GaussNewton(it.state());
            adjoint
                .problem()
                .report(it.iteration, it.x, it.value, it.step_length, &state)
        });
        Ok(match run {
            Ok(r) => LevelEnd::Stopped(r.iterations, r.stop_reason),
            Err(GaussNewtonRunError::InitialEvaluation(e)) => LevelEnd::Failed(e, false),
            Err(e) => LevelEnd::Failed(DesignError::Solve(e.to_string()), true),
        })
    }

    /// Reports the accepted point `x` (iteration `k` of the level's optimizer, normalized `value`, step
    /// length `step`) with a checkpoint to `on_iteration`; breaks when it or `should_stop` says so, or
    /// when the pattern needs a remesh.
    fn report(
        &mut self,
        k: usize,
        x: &[Real],
        value: Real,
        step: Real,
        optimizer: &dyn Fn() -> OptimizerState,
    ) -> ControlFlow<()> {
        if (self.run.settings.should_stop)() {
            return ControlFlow::Break(());
        }
        // The accepted point is one of the trials evaluated since the last one.
        let found = self
            .trials
            .iter()
            .rev()
            .find(|t| t.z.as_slice() == x)
            .map(|t| (t.gradient_norm, t.entry.clone(), t.quality));
        let found = found.map(|(gradient_norm, entry, quality)| {
            self.run.accepted_gradient = gradient_norm;
            (entry, quality)
        });
        self.trials.clear();
        let remesh_now = k > 0
            && found
                .as_ref()
                .is_some_and(|(_, q)| self.run.needs_remesh(q));
        let mut entry = match found {
            Some((entry, _)) => entry,
            None => unknown_iteration(self.index, value * self.run.t0),
        };
        if self.index > 0 && k == 0 {
            // The start of a finer level is the end of the coarser one: already reported.
            return ControlFlow::Continue(());
        }
        entry.iteration = self.run.iterations_before + k;
        entry.step_length = step;
        entry.seconds = self.run.start.elapsed().as_secs_f64();
        self.count_work(&mut entry);
        self.run.history.push(entry);
        let checkpoint = self.checkpoint(optimizer(), remesh_now);
        let flow =
            (self.run.on_iteration)(self.run.history.last().expect("just pushed"), &checkpoint);
        if remesh_now {
            self.run.remesh_requested = true;
            return ControlFlow::Break(());
        }
        flow
    }

    /// The work of every solve, so far and since the previous reported iteration, into `entry`.
    fn count_work(&self, entry: &mut DesignIteration) {
        let totals = self.problem.equilibrium_totals();
        entry.evaluations = self.problem.evaluations();
        entry.newton_iterations_total = totals.newton_iterations;
        entry.factorizations_total = totals.factorizations;
        let previous = self.run.history.last();
        let before = |f: fn(&DesignIteration) -> usize| previous.map_or(0, f);
        entry.step_evaluations = entry.evaluations.saturating_sub(before(|p| p.evaluations));
        entry.step_newton_iterations = entry
            .newton_iterations_total
            .saturating_sub(before(|p| p.newton_iterations_total));
        entry.step_factorizations = entry
            .factorizations_total
            .saturating_sub(before(|p| p.factorizations_total));
    }

    /// The checkpoint after the iteration just reported.
    fn checkpoint(&self, optimizer: OptimizerState, remesh_requested: bool) -> DesignCheckpoint {
        let run = &*self.run;
        DesignCheckpoint {
            initial_objective: run.t0,
            level: self.index,
            level_start: run.p_start.clone(),
            level_time_left: self.time_left,
            iterations_before: run.iterations_before,
            best_parameters: run.best.0.clone(),
            best_objective: run.best.1,
            best_state: run.best_state.clone(),
            history: run.history.clone(),
            optimizer,
            last_evaluation: self.problem.last_evaluation().cloned(),
            evaluations: self.problem.evaluations(),
            totals: self.problem.equilibrium_totals(),
            remesh_requested,
            stop_reason: run.stop_reason,
            seconds: run.start.elapsed().as_secs_f64(),
        }
    }

    /// The progress report of an evaluation at `z` (its iteration, step and work counts are filled in
    /// when it is accepted).
    fn entry(
        &self,
        eval: &DesignEvaluation,
        pattern: &[Vec2],
        gradient_norm: Real,
        quality: &PatternQuality,
    ) -> DesignIteration {
        let (lo, hi, mean_p, max_p) = cloth_figures(self.problem);
        let yl = young_laplace_figures(self.problem, pattern);
        let window = window_area_fraction(self.problem, eval, pattern);
        DesignIteration {
            objective: eval.value,
            terms: eval
                .terms
                .iter()
                .map(|t| (t.name.to_string(), t.value))
                .collect(),
            gradient_norm,
            min_stretch: lo,
            max_stretch: hi,
            mean_pressure_pa: mean_p,
            max_pressure_pa: max_p,
            young_laplace_mean_pa: yl.0,
            young_laplace_spread: yl.1,
            young_laplace_min_pa: yl.2,
            min_pattern_quality: quality.min_quality,
            evaluations: self.problem.evaluations(),
            newton_iterations: eval.equilibrium.iterations,
            window_area_fraction: window,
            ..unknown_iteration(self.index, eval.value)
        }
    }
}

/// The report of an accepted point that no evaluation since the last one matches: its objective `T`,
/// everything else unknown (NaN, 0, `None`).
fn unknown_iteration(level: usize, objective: Real) -> DesignIteration {
    DesignIteration {
        iteration: 0,
        level,
        objective,
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
    }
}

impl Objective for Level<'_, '_> {
    type Error = DesignError;

    /// The normalized objective `T / T₀` and its gradient with respect to `z`: one equilibrium solve
    /// (at the inexact schedule's tolerance, tightened while its residual misreads the objective), its
    /// report kept as a trial, and the best design updated.
    fn evaluate(&mut self, z: &[Real]) -> Result<(Real, Vec<Real>), DesignError> {
        let RunSettings {
            map,
            edge_length,
            params,
            should_stop,
            tight,
        } = self.run.settings;
        // Once stopped, every trial fails at once (the line search then gives up without solving).
        if should_stop() {
            return Err(DesignError::Cancelled);
        }
        let (p, projected) = sewn(self.run.seams.as_ref(), self.to_p(z)?)?;
        let pattern = map
            .apply(&p)
            .map_err(|e| DesignError::Pattern(e.to_string()))?;
        let t0 = self.run.t0;
        if let Some(s) = &params.inexact {
            self.problem.set_equilibrium_tolerance(s.tolerance(
                tight,
                self.run.accepted_gradient,
                self.run.gradient_tolerance,
            ))?;
        }
        let mut eval = self
            .problem
            .evaluate(&pattern, true, &mut |_| stop_flow(should_stop))?;
        if let Some(s) = &params.inexact {
            // An objective its residual misreads beyond the bound: solved again, tighter.
            while let Some(t) = s.tighter(
                tight,
                eval.equilibrium.residual,
                eval.value,
                eval.value_error.unwrap_or(0.0),
            ) {
                self.problem.set_equilibrium_tolerance(t)?;
                eval = self
                    .problem
                    .evaluate(&pattern, true, &mut |_| stop_flow(should_stop))?;
            }
        }
        let gradient_pattern = eval.gradient.as_ref().expect("gradient asked for");
        let gp = map
            .apply_jacobian_transpose(gradient_pattern)
            .map_err(|e| DesignError::Pattern(e.to_string()))?;
        // Through the seams' projection: `∂T/∂p = (dq/dp)ᵀ ∂T/∂q`.
        let gp = match &projected {
            Some(s) => s
                .pull_back(&gp)
                .map_err(|e| DesignError::Pattern(format!("holding the seams: {e}")))?,
            None => gp,
        };
        let gradient_norm = gp.iter().map(|v| v * v).sum::<Real>().sqrt();
        // Chain to this level's parameters, then normalize.
        let gz = match &self.modes {
            Some(m) => m
                .apply_jacobian_transpose(&gp)
                .map_err(|e| DesignError::Pattern(e.to_string()))?,
            None => gp,
        };
        let gz: Vec<Real> = gz.iter().map(|v| v * edge_length / t0).collect();
        let gz_norm = gz.iter().map(|v| v * v).sum::<Real>().sqrt();
        let quality = pattern_quality(self.problem.mesh(), &pattern, edge_length);
        let entry = self.entry(&eval, &pattern, gradient_norm, &quality);
        if eval.value < self.run.best.1 {
            self.run.best = (p, eval.value);
            self.run.best_state = self.problem.state().clone();
        }
        self.trials.push(Trial {
            z: z.to_vec(),
            gradient_norm: gz_norm,
            entry,
            quality,
        });
        Ok((eval.value / t0, gz))
    }
}

impl AdjointProblem for Level<'_, '_> {
    fn unknowns(&self) -> usize {
        self.problem.system().num_dofs()
    }

    /// The linearization at the accepted `z` (solved again there after a failed line search left a
    /// trial's state), its residuals divided by `√T₀`.
    fn linearization(
        &mut self,
        z: &[Real],
        mixed: MixedForm<'_>,
    ) -> Result<Linearization, DesignError> {
        let should_stop = self.run.settings.should_stop;
        if should_stop() {
            return Err(DesignError::Cancelled);
        }
        let pattern = self.pattern(z)?;
        if self.problem.last_pattern() != Some(pattern.as_slice()) {
            // After a failed line search the state is a trial's: back to z.
            self.problem
                .evaluate(&pattern, false, &mut |_| stop_flow(should_stop))?;
        }
        let lin = match mixed {
            MixedForm::Matrix => self.problem.linearize()?,
            MixedForm::TimesParameterMap { rows, columns } => {
                self.problem.linearize_times(rows, columns)?
            }
        };
        Ok(lin.adjoint(1.0 / self.run.t0.sqrt())?)
    }

    fn solve_hessian(&mut self, rhs: &mut [Real], columns: usize) -> Result<(), DesignError> {
        self.problem.solve_hessian_columns(rhs, columns).map(|_| ())
    }

    /// With the seams held, `dX̄/dz` through the projection at `z` (see [`SeamMap`]); otherwise the
    /// level's constant map.
    fn parameter_map_at(
        &mut self,
        z: &[Real],
    ) -> Result<Option<faer::sparse::SparseColMat<usize, Real>>, DesignError> {
        let (Some(seams), Some(seam_map)) = (&self.run.seams, &self.seam_map) else {
            return Ok(None);
        };
        let edge_length = self.run.settings.edge_length;
        let fail = |e: String| DesignError::Pattern(format!("holding the seams: {e}"));
        let projected = seams
            .project(&self.to_p(z)?)
            .map_err(|e| fail(e.to_string()))?;
        let nz = z.len();
        let ns = seam_map.parameters.len();
        // D = [(dq/dp − I)(dp/dz)]_s, column by column.
        let mut d = faer::Mat::<Real>::zeros(ns, nz);
        for i in 0..nz {
            let mut e = vec![0.0; nz];
            e[i] = edge_length;
            let dp = match &self.modes {
                Some(m) => m.apply_jacobian(&e).map_err(|e| fail(e.to_string()))?,
                None => e,
            };
            let dq = projected
                .push_forward(&dp)
                .map_err(|e| fail(e.to_string()))?;
            for (r, &s) in seam_map.parameters.iter().enumerate() {
                d[(r, i)] = dq[s] - dp[s];
            }
        }
        let correction = &seam_map.columns * &d;
        let base = seam_map.base.as_ref();
        let rows = base.nrows();
        let (cp, ri, val) = (
            base.symbolic().col_ptr(),
            base.symbolic().row_idx(),
            base.val(),
        );
        let map = parameter_map_matrix(rows, nz, |i| {
            let mut col: Vec<Real> = (0..rows).map(|r| correction[(r, i)]).collect();
            for k in cp[i]..cp[i + 1] {
                col[ri[k]] += val[k];
            }
            Ok(col)
        })?;
        Ok(Some(map))
    }
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
