//! Where a [`crate::pattern_design()`] run stands after an accepted iteration: everything it needs to go
//! on exactly as the uninterrupted run would have ([`crate::pattern_design::pattern_design_from`]).
//!
//! A run's next step depends on more than the current pattern: the optimizer's memory (L-BFGS curvature
//! pairs, or the Gauss-Newton damping), the coarse-to-fine level and the pattern that level's modes were
//! built from, the best design so far and its equilibrium, and — because every equilibrium solve is
//! warm-started from the last one — the equilibrium the next solve starts from. That last state is not
//! stored as it is but as the **last evaluation** (its warm start, the predicted start and damping if the
//! predictor was on, its pattern: [`crate::design_problem::EvaluationStart`]): a resumed run replays it
//! ([`crate::DesignProblem::replay`]), so that the problem's state, its factorization (what Gauss-Newton
//! linearizes), its damping and its last pattern are bit for bit those of the uninterrupted run, at the
//! cost of one equilibrium solve.
//!
//! Everything is plain data (serde), so a service can store it between iterations and continue after a
//! crash. Units: patterns and parameters in m, the optimizer state on the normalized problem (see
//! [`crate::pattern_design`]), seconds in s.

use skintight_physics::ClothOnBodyState;

use crate::design_iteration::DesignIteration;
use crate::design_problem::{EquilibriumTotals, EvaluationStart};
use crate::math::Real;
use skintight_optimize::{OptimizerState, OptimizerStop};

/// A checkpoint of a design run (see the module documentation).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DesignCheckpoint {
    /// The objective of the initial pattern, `T₀` (units of the terms): the normalization.
    pub initial_objective: Real,
    /// The coarse-to-fine level the run is in.
    pub level: usize,
    /// The boundary parameters the level started from (m): its modes are built from them.
    pub level_start: Vec<Real>,
    /// The level's time limit (s), as it was given to its optimizer.
    pub level_time_left: Option<Real>,
    /// Accepted iterations of the levels before this one.
    pub iterations_before: usize,
    /// The best boundary parameters seen (m), its objective and equilibrium.
    pub best_parameters: Vec<Real>,
    /// See `best_parameters`.
    pub best_objective: Real,
    /// See `best_parameters`.
    pub best_state: ClothOnBodyState,
    /// The reported iterations so far, the initial design first.
    pub history: Vec<DesignIteration>,
    /// The level's optimizer.
    pub optimizer: OptimizerState,
    /// How the last equilibrium solve started ([`crate::DesignProblem::last_evaluation`]), replayed on resume;
    /// `None` when there was none.
    pub last_evaluation: Option<EvaluationStart>,
    /// Equilibrium solves so far, and their work.
    pub evaluations: usize,
    /// See `evaluations`.
    pub totals: EquilibriumTotals,
    /// Whether this iteration asked for a remesh (the run ends there).
    pub remesh_requested: bool,
    /// Why the previous level stopped (the run's answer if this one ends without its own).
    pub stop_reason: OptimizerStop,
    /// Seconds since the run started.
    pub seconds: Real,
}

impl DesignCheckpoint {
    /// Whether it can belong to a run with `parameters` boundary parameters, `levels` coarse-to-fine
    /// levels (modes levels + 1), `pattern_vertices` pattern vertices and a state of `cloth` and `body`
    /// vertices; `Err` says what does not fit.
    pub fn check(
        &self,
        parameters: usize,
        levels: usize,
        pattern_vertices: usize,
        cloth: usize,
        body: usize,
    ) -> Result<(), String> {
        let state_fits = |s: &ClothOnBodyState| s.cloth.len() == cloth && s.body.len() == body;
        if self.level >= levels {
            return Err(format!(
                "level {} of a run with {levels} levels",
                self.level
            ));
        }
        if self.level_start.len() != parameters || self.best_parameters.len() != parameters {
            return Err(format!(
                "{} boundary parameters for a pattern map of {parameters}",
                self.best_parameters.len()
            ));
        }
        if !state_fits(&self.best_state) {
            return Err("the best design's state has another size".into());
        }
        if let Some(last) = &self.last_evaluation
            && (!state_fits(&last.warm_start)
                || !last.solve_start.as_ref().is_none_or(state_fits)
                || last.pattern.len() != pattern_vertices)
        {
            return Err("the last evaluation has another size".into());
        }
        let finite = self.initial_objective.is_finite()
            && self.best_objective.is_finite()
            && self.best_parameters.iter().all(|v| v.is_finite());
        if !finite {
            return Err("a stored objective or parameter is not finite".into());
        }
        Ok(())
    }
}
