//! Running a prepared design: the pattern optimization, remeshing the patterns when they degrade (and
//! undoing a remesh whose garment cannot be solved), and the final design put back into the simulation.

use std::ops::ControlFlow;

use skintight_design::{
    DesignCheckpoint, DesignIteration, DesignMesh, Optimizer, PatternDesignResult, PatternMap,
    pattern_design_from,
};

use super::build::{Design, design_params};
use super::checkpoint::{Gathered, RemeshRecord, RunCheckpoint};
use crate::simulate::SimulateError;

/// Runs the optimization; `on_iteration` sees every design iteration and may stop the run (the best
/// design so far is kept), `should_stop` is polled at every Newton iteration of every solve. Afterwards
/// `design.sim` holds the final design at equilibrium.
///
/// Remeshing (`optimizer.remesh`): when a run stops because its pattern degraded, the patterns are
/// remeshed so that the worn triangles keep about the cloth edge length ([`skintight_design::remesh_edge_length`]), the worn garment is
/// re-embedded ([`mod@skintight_design::design_remesh`]) and the optimization continues from there — at the
/// coarse-to-fine level it had reached, within what is left of the iteration and time limits — until
/// `max_remeshes`. A remesh that fails (a boundary crossing itself, say) ends the remeshing; the design
/// goes on without it. The history numbers iterations across remeshes and counts them in `remeshes`.
pub fn run_design(
    design: &mut Design,
    on_iteration: &mut dyn FnMut(&DesignIteration) -> ControlFlow<()>,
    should_stop: &dyn Fn() -> bool,
) -> Result<PatternDesignResult, SimulateError> {
    run_design_from(design, None, &mut |it, _| on_iteration(it), should_stop)
}

/// [`run_design`] that hands `on_iteration` a checkpoint with every design iteration after the first, and
/// goes on from such a checkpoint when `resume` is one: `design` freshly prepared from the same job (its
/// set-up is deterministic), the remeshes the checkpoint records are replayed, then the optimization goes
/// on where it was ([`skintight_design::pattern_design_from`]) and ends with the design the
/// uninterrupted run ends with (time limits aside).
pub fn run_design_from(
    design: &mut Design,
    resume: Option<RunCheckpoint>,
    on_iteration: &mut dyn FnMut(&DesignIteration, &RunCheckpoint) -> ControlFlow<()>,
    should_stop: &dyn Fn() -> bool,
) -> Result<PatternDesignResult, SimulateError> {
    let seconds_before = resume.as_ref().map_or(0.0, |c| c.seconds.max(0.0));
    let start = std::time::Instant::now()
        .checked_sub(std::time::Duration::from_secs_f64(seconds_before))
        .unwrap_or_else(std::time::Instant::now);
    let base = design_params(&design.job);
    let edge_length = design.job.garment.edge_length;
    let max_remeshes = design.job.optimizer.remesh.max_remeshes;
    let (max_iterations, time_limit) = match base.method {
        Optimizer::Lbfgs => (base.lbfgs.max_iterations, base.lbfgs.time_limit_seconds),
        Optimizer::GaussNewton => (
            base.gauss_newton.max_iterations,
            base.gauss_newton.time_limit_seconds,
        ),
    };
    // What the runs before the last remesh gathered, and the result so far.
    let mut gathered: Option<Gathered> = None;
    let mut total: Option<PatternDesignResult> = None;
    let mut level = 0;
    let mut remeshes = 0;
    let mut remesh_seconds = 0.0;
    let mut remesh_on = base.remesh.is_some();
    let mut remesh_log: Vec<RemeshRecord> = Vec::new();
    // The design before the last remesh, to go back to if the remeshed garment cannot be solved.
    let mut before_remesh: Option<Backup> = None;
    // The checkpoint of the run in progress: with a resume, the one to go on from.
    let mut resume_run: Option<DesignCheckpoint> = None;
    let mut offset_seconds = 0.0;
    if let Some(cp) = resume {
        for (k, record) in cp.remesh_log.iter().enumerate() {
            if k + 1 == cp.remesh_log.len() {
                before_remesh = Some(Backup::of(design));
            }
            replay_remesh(design, record, edge_length, should_stop)?;
        }
        gathered = cp.gathered;
        level = cp.level;
        remeshes = cp.remeshes;
        remesh_seconds = cp.remesh_seconds;
        remesh_on = cp.remesh_on;
        remesh_log = cp.remesh_log;
        offset_seconds = cp.offset_seconds;
        resume_run = Some(cp.design);
    }
    loop {
        let done = gathered.as_ref().map_or(0, |t| t.iterations);
        let mut params = base.clone();
        let left = max_iterations.saturating_sub(done).max(1);
        let time_left = time_limit.map(|t| (t - start.elapsed().as_secs_f64()).max(1e-3));
        params.lbfgs.max_iterations = left;
        params.lbfgs.time_limit_seconds = time_left;
        params.gauss_newton.max_iterations = left;
        params.gauss_newton.time_limit_seconds = time_left;
        params.mode_levels = base.mode_levels[level.min(base.mode_levels.len())..].to_vec();
        if !remesh_on || remeshes >= max_remeshes {
            params.remesh = None;
        }
        let resuming = resume_run.is_some();
        if !resuming {
            offset_seconds = start.elapsed().as_secs_f64();
        }
        let continuing = gathered.is_some();
        let before_remesh_last = gathered.as_ref().and_then(|g| g.history.last().cloned());
        let shift = |it: &DesignIteration| {
            let mut it = it.clone();
            it.iteration += done;
            it.level += level;
            it.remeshes = remeshes;
            it.seconds += offset_seconds;
            // The first iteration after a remesh: its work counts from the last one reported before it
            // (the final evaluation, the remesh's re-embedding and the new start included).
            if let Some(previous) = before_remesh_last
                .as_ref()
                .filter(|p| p.iteration + 1 == it.iteration)
            {
                it.step_evaluations = it.evaluations.saturating_sub(previous.evaluations);
                it.step_newton_iterations = it
                    .newton_iterations_total
                    .saturating_sub(previous.newton_iterations_total);
                it.step_factorizations = it
                    .factorizations_total
                    .saturating_sub(previous.factorizations_total);
            }
            it
        };
        let mut forward = |it: &DesignIteration, run: &DesignCheckpoint| {
            // After a remesh the new start is the previous run's last iteration, already reported.
            if continuing && it.iteration == 0 {
                return ControlFlow::Continue(());
            }
            let checkpoint = RunCheckpoint {
                design: run.clone(),
                gathered: gathered.clone(),
                level,
                remeshes,
                remesh_seconds,
                remesh_on,
                remesh_log: remesh_log.clone(),
                offset_seconds,
                seconds: start.elapsed().as_secs_f64(),
            };
            on_iteration(&shift(it), &checkpoint)
        };
        let result = match pattern_design_from(
            &mut design.problem,
            &design.map,
            edge_length,
            &params,
            resume_run.take(),
            &mut forward,
            should_stop,
        ) {
            Ok(r) => r,
            Err(e) => match before_remesh.take() {
                // The remeshed garment failed: the best design is the one before the remesh.
                Some(b) if gathered.is_some() => {
                    b.restore(design)?;
                    remeshes -= 1;
                    if total.is_none() {
                        // Resumed after the remesh: the result before it, evaluated again.
                        total = Some(result_before_remesh(design, &remesh_log, &gathered)?);
                    }
                    break;
                }
                _ => return Err(SimulateError::failed(format!("design failed: {e}"))),
            },
        };
        let remesh_requested = result.remesh_requested;
        let reached = level + result.level;
        let pattern = result.pattern.clone();
        let remeshed_from = RemeshRecord {
            parameters: result.parameters.clone(),
            best_state: result.best_state.clone(),
        };
        let merged = match gathered.take() {
            None => PatternDesignResult {
                history: result.history.iter().map(&shift).collect(),
                ..result
            },
            Some(t) => {
                let mut history = t.history;
                history.extend(
                    result
                        .history
                        .iter()
                        .filter(|it| it.iteration > 0)
                        .map(&shift),
                );
                PatternDesignResult {
                    initial_objective: t.initial_objective,
                    iterations: t.iterations + result.iterations,
                    history,
                    ..result
                }
            }
        };
        if !remesh_requested || should_stop() {
            total = Some(merged);
            break;
        }
        gathered = Some(Gathered {
            initial_objective: merged.initial_objective,
            iterations: merged.iterations,
            history: merged.history.clone(),
        });
        let used = merged.iterations;
        total = Some(merged);
        before_remesh = Some(Backup::of(design));
        let remesh_start = std::time::Instant::now();
        let target = skintight_design::remesh_edge_length(&design.problem, edge_length);
        let remeshed = skintight_design::design_remesh(
            &mut design.problem,
            &design.sim.garment,
            &pattern,
            target,
        );
        remesh_seconds += remesh_start.elapsed().as_secs_f64();
        match remeshed {
            Ok(r) => {
                design.sim.garment = r.garment;
                design.sim.pinned = r.pinned;
                design.map = r.map;
                design.sim.initial_state = design.problem.state().clone();
                remeshes += 1;
                level = reached;
                remesh_log.push(remeshed_from);
            }
            Err(_) => {
                // The design goes on with the mesh it has (the problem was left as it was).
                before_remesh = None;
                remesh_on = false;
                level = reached;
            }
        }
        if used >= max_iterations || time_limit.is_some_and(|t| start.elapsed().as_secs_f64() >= t)
        {
            break;
        }
    }
    let mut result = total.expect("at least one run");
    result.remeshes = remeshes;
    result.remesh_seconds = remesh_seconds;
    // The final design into the simulation's pattern panels.
    let mesh = design.problem.mesh();
    for (p, panel) in design.sim.garment.panels.iter_mut().enumerate() {
        let first = mesh.panels[p].first_vertex;
        for (k, v) in panel.pattern.iter_mut().enumerate() {
            *v = result.pattern[first + k];
        }
    }
    true_final_seams(design, &mut result, should_stop)?;
    result.seconds = start.elapsed().as_secs_f64();
    // Its rest shapes and equilibrium.
    design.sim.system = design.problem.system().clone();
    design.sim.state = design.problem.state().clone();
    Ok(result)
}

/// Seams that sew after a design: the optimizer moves the two sides of a seam independently, so the final
/// patterns are trued ([`crate::simulate::pattern_files::true_seams_of`]) and the garment is solved once
/// more with them; `result` then describes the trued design (its pattern, objective and equilibrium),
/// which is the one the pattern files cut.
fn true_final_seams(
    design: &mut Design,
    result: &mut PatternDesignResult,
    should_stop: &dyn Fn() -> bool,
) -> Result<(), SimulateError> {
    let report =
        crate::simulate::pattern_files::true_seams_of(&design.sim.scene, &mut design.sim.garment)?;
    design.sim.seam_truing = report;
    if report.iterations == 0 {
        return Ok(());
    }
    let mesh = design.problem.mesh();
    let mut trued = result.pattern.clone();
    for (p, panel) in design.sim.garment.panels.iter().enumerate() {
        let first = mesh.panels[p].first_vertex;
        trued[first..first + panel.pattern.len()].copy_from_slice(&panel.pattern);
    }
    let evaluation = design
        .problem
        .final_evaluation(&trued, false, &mut |_| {
            if should_stop() {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .map_err(|e| {
            SimulateError::failed(format!(
                "the design with trued seams has no equilibrium: {e}; set patterns.true_seams to false"
            ))
        })?;
    design.objective_before_truing = Some(result.final_objective);
    result.final_objective = evaluation.value;
    result.evaluation = evaluation;
    result.pattern = trued;
    Ok(())
}

/// Replays a remesh a checkpoint recorded: the final evaluation of the run that asked for it (from the
/// same warm start, so bit for bit) and the remesh itself.
fn replay_remesh(
    design: &mut Design,
    record: &RemeshRecord,
    edge_length: f64,
    should_stop: &dyn Fn() -> bool,
) -> Result<(), SimulateError> {
    let failed = |e: String| SimulateError::failed(format!("resuming the design: {e}"));
    let pattern = design
        .map
        .apply(&record.parameters)
        .map_err(|e| failed(e.to_string()))?;
    design.problem.set_state(record.best_state.clone());
    design
        .problem
        .evaluate(&pattern, true, &mut |_| {
            if should_stop() {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .map_err(|e| failed(e.to_string()))?;
    let target = skintight_design::remesh_edge_length(&design.problem, edge_length);
    let r =
        skintight_design::design_remesh(&mut design.problem, &design.sim.garment, &pattern, target)
            .map_err(|e| failed(e.to_string()))?;
    design.sim.garment = r.garment;
    design.sim.pinned = r.pinned;
    design.map = r.map;
    design.sim.initial_state = design.problem.state().clone();
    Ok(())
}

/// The result of a resumed design whose remeshed garment failed: the design before the last remesh
/// (`design` restored to it), evaluated again.
fn result_before_remesh(
    design: &mut Design,
    remesh_log: &[RemeshRecord],
    gathered: &Option<Gathered>,
) -> Result<PatternDesignResult, SimulateError> {
    let (Some(record), Some(gathered)) = (remesh_log.last(), gathered) else {
        return Err(SimulateError::failed(
            "the remeshed design failed and there is no design before it",
        ));
    };
    let pattern = design
        .map
        .apply(&record.parameters)
        .map_err(|e| SimulateError::failed(e.to_string()))?;
    design.problem.set_state(record.best_state.clone());
    let evaluation = design
        .problem
        .final_evaluation(&pattern, true, &mut |_| ControlFlow::Continue(()))
        .map_err(|e| SimulateError::failed(format!("design failed: {e}")))?;
    let last = gathered.history.last();
    Ok(PatternDesignResult {
        pattern,
        parameters: record.parameters.clone(),
        initial_objective: gathered.initial_objective,
        final_objective: evaluation.value,
        iterations: gathered.iterations,
        evaluations: design.problem.evaluations(),
        stop_reason: skintight_design::OptimizerStop::Callback,
        remeshes: 0,
        remesh_seconds: 0.0,
        remesh_requested: true,
        level: last.map_or(0, |it| it.level),
        history: gathered.history.clone(),
        evaluation,
        best_state: record.best_state.clone(),
        seconds: 0.0,
    })
}

/// What a remesh replaces, to undo it.
struct Backup {
    garment: skintight_garment::garment::Garment,
    pinned: Vec<bool>,
    initial_state: skintight_physics::ClothOnBodyState,
    map: PatternMap,
    system: skintight_physics::ClothOnBody,
    state: skintight_physics::ClothOnBodyState,
    mesh: DesignMesh,
}

impl Backup {
    fn of(design: &Design) -> Self {
        Self {
            garment: design.sim.garment.clone(),
            pinned: design.sim.pinned.clone(),
            initial_state: design.sim.initial_state.clone(),
            map: design.map.clone(),
            system: design.problem.system().clone(),
            state: design.problem.state().clone(),
            mesh: design.problem.mesh().clone(),
        }
    }

    fn restore(self, design: &mut Design) -> Result<(), SimulateError> {
        design.sim.garment = self.garment;
        design.sim.pinned = self.pinned;
        design.sim.initial_state = self.initial_state;
        design.map = self.map;
        design
            .problem
            .replace_cloth(self.system, self.state, self.mesh)
            .map_err(|e| SimulateError::failed(e.to_string()))
    }
}
