//! The cut-ready pattern of a simulation: seam truing before the solve, the pattern model of the garment,
//! its files (`patterns.svg`, `patterns.json`, `patterns-garmentcode.json`, …) and the seam table of
//! `result.json`.

use serde_json::{Value, json};
use skintight_garment::garment::Garment;
use skintight_garment::pattern::{Pattern, pattern};
use skintight_garment::pattern_format::{garmentcode, json as pattern_json, svg};
use skintight_garment::seam_truing::{
    SeamTruingParams, SeamTruingReport, max_seam_mismatch, true_seams,
};

use super::{ArtifactFile, SimulateError, Simulation};
use crate::scene::Scene;

/// Trues the seams of `garment` when the scene asks for it (`patterns.true_seams`, on by default); the
/// report says by how much the sides differed before and after.
pub fn true_seams_of(
    scene: &Scene,
    garment: &mut Garment,
) -> Result<SeamTruingReport, SimulateError> {
    if !scene.patterns.true_seams {
        let mismatch = max_seam_mismatch(garment);
        return Ok(SeamTruingReport {
            max_seam_mismatch_before: mismatch,
            max_seam_mismatch_after: mismatch,
            ..SeamTruingReport::default()
        });
    }
    true_seams(garment, &SeamTruingParams::default()).map_err(|e| {
        SimulateError::input(
            "patterns.true_seams",
            format!(
                "{e}; set patterns.true_seams to false to keep the flattened patterns as they are"
            ),
        )
    })
}

/// The cut-ready pattern of `garment` as `scene.patterns` draws it; errors name the `patterns.…` key.
pub fn pattern_of(scene: &Scene, garment: &Garment) -> Result<Pattern, SimulateError> {
    let spec = &scene.patterns;
    pattern(garment, &spec.params(), spec.labels("")).map_err(|e| spec.error(&e).into())
}

/// `result.json`'s pattern fields: `seams` (per seam `panels`, `lengths_mm: [a, b]`, `difference_mm`, …)
/// and `seam_truing` (what truing changed, mm).
pub fn result_fields(pattern: &Pattern, report: &SeamTruingReport) -> [(&'static str, Value); 2] {
    [
        ("seams", Value::Array(pattern_json::seam_table(pattern))),
        (
            "seam_truing",
            json!({
                "iterations": report.iterations,
                "edge_pairs": report.edge_pairs,
                "max_seam_mismatch_before_mm": report.max_seam_mismatch_before * 1e3,
                "max_seam_mismatch_after_mm": report.max_seam_mismatch_after * 1e3,
                "max_displacement_mm": report.max_displacement * 1e3,
            }),
        ),
    ]
}

fn to_json_bytes(value: &Value) -> Result<Vec<u8>, SimulateError> {
    serde_json::to_vec_pretty(value).map_err(|e| SimulateError::failed(e.to_string()))
}

/// The pattern files of a simulation's garment.
pub fn pattern_artifacts(
    sim: &Simulation,
    pattern: &Pattern,
) -> Result<Vec<ArtifactFile>, SimulateError> {
    let _ = sim;
    Ok(vec![
        ArtifactFile {
            name: "patterns.svg",
            content_type: "image/svg+xml",
            data: svg::pattern_svg(pattern).into_bytes(),
        },
        ArtifactFile {
            name: "patterns.json",
            content_type: "application/json",
            data: to_json_bytes(&pattern_json::patterns_json(pattern))?,
        },
        ArtifactFile {
            name: "patterns-garmentcode.json",
            content_type: "application/json",
            data: to_json_bytes(&garmentcode::garmentcode(pattern))?,
        },
    ])
}
