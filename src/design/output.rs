//! The outputs of a finished design: the one-line summary, `patterns.json` and the files written (the
//! simulate artifacts of the final design with the design figures added to `result.json`, plus
//! `patterns.json` and `history.json`).

use serde::Serialize;
use skintight_design::PatternDesignResult;
use skintight_geometry::math::{Real, Vec2};

use super::build::Design;
use super::statistics::{pressure_per_triangle, pressure_statistics, window_fraction};
use crate::simulate::{ArtifactFile, SimulateError, SimulationResult, artifacts};

/// The one-line summary of a finished design (CLI standard output, the job's summary).
pub fn design_summary(result: &PatternDesignResult) -> serde_json::Value {
    serde_json::json!({
        "initial_objective": result.initial_objective,
        "final_objective": result.final_objective,
        "iterations": result.iterations,
        "evaluations": result.evaluations,
        "remeshes": result.remeshes,
        "stop_reason": format!("{:?}", result.stop_reason),
        "seconds": result.seconds,
    })
}

/// One panel of `patterns.json`.
#[derive(Clone, Debug, Serialize)]
pub struct PatternJson {
    /// Panel name.
    pub name: String,
    /// Outer boundary polyline, counter-clockwise, in mm.
    pub boundary_mm: Vec<[Real; 2]>,
}

/// One seam of `patterns.json`: boundary indices sewn together, index by index.
#[derive(Clone, Debug, Serialize)]
pub struct SeamJson {
    /// The two panels (indices into `panels`).
    pub panels: [usize; 2],
    /// Indices into each panel's `boundary_mm`, same length, sewn pairwise.
    pub boundary_indices: [Vec<usize>; 2],
    /// Whether the seam closes on itself.
    pub closed: bool,
}

/// `patterns.json`: per panel the 2D boundary in mm, and the seam correspondences.
pub fn patterns_json(design: &Design, pattern: &[Vec2]) -> serde_json::Value {
    let mesh = design.problem.mesh();
    let panels: Vec<PatternJson> = mesh
        .panels
        .iter()
        .map(|p| PatternJson {
            name: p.name.clone(),
            boundary_mm: p
                .boundary
                .iter()
                .map(|&v| [pattern[v].x * 1e3, pattern[v].y * 1e3])
                .collect(),
        })
        .collect();
    let position_in = |panel: usize, v: usize| -> usize {
        mesh.panels[panel]
            .boundary
            .iter()
            .position(|&b| b == v)
            .unwrap_or(usize::MAX)
    };
    let seams: Vec<SeamJson> = mesh
        .seams
        .iter()
        .map(|s| SeamJson {
            panels: s.panels,
            boundary_indices: [0, 1].map(|k| {
                s.vertices[k]
                    .iter()
                    .map(|&v| position_in(s.panels[k], v))
                    .collect()
            }),
            closed: s.closed,
        })
        .collect();
    serde_json::json!({ "units": "mm", "panels": panels, "seams": seams })
}

/// The outputs of a finished design: the simulate artifacts of the final design (its `result.json` with
/// the design figures added) plus `patterns.json` and `history.json`.
pub fn design_artifacts(
    design: &Design,
    result: &PatternDesignResult,
) -> Result<Vec<ArtifactFile>, SimulateError> {
    let sim_result = SimulationResult::new(
        &design.sim,
        &design.total_report(&result.evaluation.equilibrium),
    )?;
    let mut files = artifacts(&design.sim, &sim_result)?;
    let mut json =
        serde_json::to_value(&sim_result).map_err(|e| SimulateError::failed(e.to_string()))?;
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
        name: "patterns.json",
        content_type: "application/json",
        data: serde_json::to_vec_pretty(&patterns_json(design, &result.pattern))
            .map_err(|e| SimulateError::failed(e.to_string()))?,
    });
    files.push(ArtifactFile {
        name: "history.json",
        content_type: "application/json",
        data: serde_json::to_vec_pretty(&result.history)
            .map_err(|e| SimulateError::failed(e.to_string()))?,
    });
    Ok(files)
}
