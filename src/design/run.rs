//! Running a prepared design: the pattern optimization, remeshing the patterns when they degrade (and
//! undoing a remesh whose garment cannot be solved), and the final design put back into the simulation.

use std::ops::ControlFlow;

use skintight_design::{
    DesignIteration, DesignMesh, Optimizer, PatternDesignResult, PatternMap, pattern_design,
};

use super::build::{Design, design_params};
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
    let start = std::time::Instant::now();
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
    let mut total: Option<PatternDesignResult> = None;
    let mut level = 0;
    let mut remeshes = 0;
    let mut remesh_seconds = 0.0;
    let mut remesh_on = base.remesh.is_some();
    // The design before the last remesh, to go back to if the remeshed garment cannot be solved.
    let mut before_remesh: Option<Backup> = None;
    loop {
        let done = total.as_ref().map_or(0, |t| t.iterations);
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
        let offset_seconds = start.elapsed().as_secs_f64();
        let continuing = total.is_some();
        let shift = |it: &DesignIteration| {
            let mut it = it.clone();
            it.iteration += done;
            it.level += level;
            it.remeshes = remeshes;
            it.seconds += offset_seconds;
            it
        };
        let mut forward = |it: &DesignIteration| {
            // After a remesh the new start is the previous run's last iteration, already reported.
            if continuing && it.iteration == 0 {
                return ControlFlow::Continue(());
            }
            on_iteration(&shift(it))
        };
        let result = match pattern_design(
            &mut design.problem,
            &design.map,
            edge_length,
            &params,
            &mut forward,
            should_stop,
        ) {
            Ok(r) => r,
            Err(e) => match before_remesh.take() {
                // The remeshed garment failed: the best design is the one before the remesh.
                Some(b) if total.is_some() => {
                    b.restore(design)?;
                    remeshes -= 1;
                    break;
                }
                _ => return Err(SimulateError::failed(format!("design failed: {e}"))),
            },
        };
        let remesh_requested = result.remesh_requested;
        let reached = level + result.level;
        let pattern = result.pattern.clone();
        total = Some(match total.take() {
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
        });
        if !remesh_requested || should_stop() {
            break;
        }
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
            }
            Err(_) => {
                // The design goes on with the mesh it has (the problem was left as it was).
                before_remesh = None;
                remesh_on = false;
                level = reached;
            }
        }
        let used = total.as_ref().map_or(0, |t| t.iterations);
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
    true_final_seams(design, &mut result)?;
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
        .evaluate(&trued, false, &mut |_| ControlFlow::Continue(()))
        .map_err(|e| {
            SimulateError::failed(format!(
                "the design with trued seams has no equilibrium: {e}; set patterns.true_seams to false"
            ))
        })?;
    result.final_objective = evaluation.value;
    result.evaluation = evaluation;
    result.pattern = trued;
    Ok(())
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
