//! The outputs of a finished design: the one-line summary and the files written (the simulate artifacts of
//! the final design — its pattern files among them — with the design figures added to `result.json`, plus
//! `history.json`).

use skintight_design::PatternDesignResult;

use super::build::Design;
use super::prescription_bands::prescription_sides;
use super::statistics::{pressure_per_triangle, pressure_statistics, window_fraction};
use crate::simulate::admissibility::Admissibility;
use crate::simulate::prescription::{prescription_verdict, prescription_violations};
use crate::simulate::{ArtifactFile, SimulateError, SimulationResult, artifacts};
use skintight_physics::PA_PER_MMHG;

/// The one-line summary of a finished design (CLI standard output, the job's summary), with the final
/// garment's verdict against its fabric's limits.
pub fn design_summary(
    result: &PatternDesignResult,
    admissibility: &Admissibility,
) -> serde_json::Value {
    serde_json::json!({
        "initial_objective": result.initial_objective,
        "final_objective": result.final_objective,
        "iterations": result.iterations,
        "evaluations": result.evaluations,
        "remeshes": result.remeshes,
        "stop_reason": format!("{:?}", result.stop_reason),
        "seconds": result.seconds,
        "admissible": admissibility.admissible,
        "violations": admissibility.violations,
    })
}

/// What a finished design produced: its files and the final garment's verdict.
pub struct DesignOutputs {
    /// The simulate artifacts of the final design (its `result.json` with the design figures added, its
    /// pattern files) plus `history.json`.
    pub files: Vec<ArtifactFile>,
    /// The final garment against its fabric's limits (also in `result.json`).
    pub admissibility: Admissibility,
}

/// The outputs of a finished design: the simulate artifacts of the final design (its `result.json` with
/// the design figures added, its pattern files) plus `history.json`, and the final garment's verdict.
pub fn design_artifacts(
    design: &Design,
    result: &PatternDesignResult,
) -> Result<DesignOutputs, SimulateError> {
    let mut sim_result = SimulationResult::new(
        &design.sim,
        &design.total_report(&result.evaluation.equilibrium),
    )?;
    if let Some(p) = &design.job.objectives.prescription {
        // The order's prescription, measured on the final garment: a miss is a violation.
        let sides = prescription_sides(p, &design.sim)?;
        let limit = design.sim.scene.garment.fabric.limits.max_pressure_pa / PA_PER_MMHG;
        let windows = p
            .prescription()
            .windows(
                "objectives.prescription",
                limit,
                design.job.prescription_limb(),
            )
            .map_err(|e| SimulateError::input(e.key, e.message))?;
        let verdict = prescription_verdict(
            &p.prescription(),
            &windows,
            &sides,
            &sim_result.regions,
            limit,
        );
        let a = &mut sim_result.admissibility;
        a.violations.extend(prescription_violations(&verdict));
        a.admissible = a.violations.is_empty();
        sim_result.prescription = Some(verdict);
    }
    let mut files = artifacts(&design.sim, &sim_result)?;
    // The simulate result.json just written (its pattern fields and marker made once), with the design's
    // figures added.
    let mut json: serde_json::Value = files
        .iter()
        .find(|f| f.name == "result.json")
        .map(|f| serde_json::from_slice(&f.data))
        .transpose()
        .map_err(|e| SimulateError::failed(e.to_string()))?
        .ok_or_else(|| SimulateError::failed("the simulate artifacts have no result.json"))?;
    if let Some(obj) = json.as_object_mut() {
        obj.insert("initial_objective".into(), result.initial_objective.into());
        obj.insert("final_objective".into(), result.final_objective.into());
        obj.insert("iterations".into(), result.iterations.into());
        obj.insert("evaluations".into(), result.evaluations.into());
        obj.insert("remeshes".into(), result.remeshes.into());
        obj.insert("remesh_seconds".into(), result.remesh_seconds.into());
        obj.insert(
            "optimizer".into(),
            design.job.optimizer.method.name().into(),
        );
        obj.insert(
            "design_stop_reason".into(),
            format!("{:?}", result.stop_reason).into(),
        );
        obj.insert("design_seconds".into(), result.seconds.into());
        // What the final truing cost the objective: the best design before it, solved as tightly
        // (`final_objective` is the trued design's).
        if let (Some(before), Some(truing)) = (
            design.objective_before_truing,
            obj.get_mut("seam_truing").and_then(|t| t.as_object_mut()),
        ) {
            truing.insert("objective_before".into(), before.into());
        }
        // The work of the whole design: every evaluation's solve and the initial equilibrium.
        let totals = design.total_report(&result.evaluation.equilibrium);
        obj.insert("evaluations_total".into(), result.evaluations.into());
        obj.insert("newton_iterations_total".into(), totals.iterations.into());
        obj.insert("factorizations_total".into(), totals.factorizations.into());
        obj.insert(
            "chord_steps_total".into(),
            totals.figures.chord_steps.into(),
        );
        if let Some(w) = &design.job.objectives.stretch {
            obj.insert(
                "window_area_fraction".into(),
                serde_json::json!({
                    "min": w.min,
                    "max": w.max,
                    "initial": design.initial_window_fraction,
                    "final": window_fraction(&design.sim.system, &design.sim.state, w.min, w.max),
                }),
            );
        }
        obj.insert(
            "young_laplace_pressure".into(),
            serde_json::json!({
                "initial": design.initial_pressure,
                "final": pressure_statistics(&design.job, &design.problem, &design.sim, &result.pattern),
                "per_triangle_pa": pressure_per_triangle(&design.problem, &design.sim, &result.pattern),
            }),
        );
        obj.insert(
            "terms".into(),
            serde_json::to_value(
                result
                    .evaluation
                    .terms
                    .iter()
                    .map(|t| serde_json::json!({"name": t.name, "value": t.value, "per_element": t.per_element}))
                    .collect::<Vec<_>>(),
            )
            .unwrap_or_default(),
        );
    }
    for f in &mut files {
        if f.name == "result.json" {
            f.data = serde_json::to_vec_pretty(&json)
                .map_err(|e| SimulateError::failed(e.to_string()))?;
        }
    }
    files.push(ArtifactFile {
        name: "history.json",
        content_type: "application/json",
        data: serde_json::to_vec_pretty(&result.history)
            .map_err(|e| SimulateError::failed(e.to_string()))?,
    });
    Ok(DesignOutputs {
        files,
        admissibility: sim_result.admissibility,
    })
}
