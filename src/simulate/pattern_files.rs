//! The cut-ready pattern of a simulation: seam truing before the solve, the pattern model of the garment,
//! its marker, its files (docs/OUTPUTS.md: SVG, JSON, GarmentCode JSON, DXF-AAMA/ASTM, PDF, tiled PDF,
//! HP-GL, the marker's PDF and DXF) and the seam table and marker of `result.json`.

use serde_json::{Value, json};
use skintight_garment::garment::Garment;
use skintight_garment::marker::{Marker, fits, marker};
use skintight_garment::pattern::{Pattern, pattern};
use skintight_garment::pattern_format::pdf::Paper;
use skintight_garment::pattern_format::{dxf, garmentcode, hpgl, json as pattern_json, pdf, svg};
use skintight_garment::seam_truing::{
    SeamTruingParams, SeamTruingReport, max_seam_mismatch, true_seams,
};

use super::{ArtifactFile, SimulateError, Simulation};
use crate::scene::{PaperSpec, Scene};

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

/// Checks that every piece of `pattern` fits across the fabric of `patterns.marker.width_m` with its grain
/// along the length (cheap: no nesting), so that a job whose marker cannot be made is refused before its
/// solve; the error names the key.
pub fn marker_fits(scene: &Scene, pattern: &Pattern) -> Result<(), SimulateError> {
    let spec = &scene.patterns.marker;
    fits(&[pattern], &spec.params()).map_err(|e| spec.error(&e).into())
}

/// The marker of `pattern` on the fabric of `patterns.marker` (every piece, its cut quantity of times,
/// grain along the length); errors name `patterns.marker.width_m`.
pub fn marker_of(scene: &Scene, pattern: &Pattern) -> Result<Marker, SimulateError> {
    let spec = &scene.patterns.marker;
    marker(&[pattern], &spec.params()).map_err(|e| spec.error(&e).into())
}

/// `result.json`'s pattern fields: `seams` (per seam `panels`, `lengths_mm: [a, b]`, `difference_mm`, …),
/// `seam_truing` (what truing changed, mm) and `marker` (`width_m`, `length_m`, `efficiency`: the pieces'
/// area over width × length, `lower_bound_m`, `pieces_area_m2`, `pieces`, `seconds`).
pub fn result_fields(
    pattern: &Pattern,
    report: &SeamTruingReport,
    marker: &Marker,
) -> [(&'static str, Value); 3] {
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
                "seconds": report.seconds,
            }),
        ),
        (
            "marker",
            json!({
                "width_m": marker.width,
                "length_m": marker.length,
                "efficiency": marker.efficiency,
                "lower_bound_m": marker.lower_bound,
                "pieces_area_m2": marker.pieces_area,
                "pieces": marker.placements.len(),
                "seconds": marker.seconds,
            }),
        ),
    ]
}

fn to_json_bytes(value: &Value) -> Result<Vec<u8>, SimulateError> {
    serde_json::to_vec_pretty(value).map_err(|e| SimulateError::failed(e.to_string()))
}

/// The tiled PDF's paper and file name for the scene's `patterns.paper`.
fn paper(spec: PaperSpec) -> (Paper, &'static str) {
    match spec {
        PaperSpec::A4 => (Paper::A4, "patterns-a4.pdf"),
        PaperSpec::Letter => (Paper::Letter, "patterns-letter.pdf"),
        PaperSpec::A3 => (Paper::A3, "patterns-a3.pdf"),
    }
}

/// The pattern files of a simulation's garment (docs/OUTPUTS.md): SVG, the model's JSON, GarmentCode JSON,
/// DXF-AAMA and DXF-ASTM, the 1:1 PDF, the tiled PDF on the scene's paper, HP-GL/2, and the marker's 1:1
/// PDF and DXF-AAMA.
pub fn pattern_artifacts(
    sim: &Simulation,
    pattern: &Pattern,
    marker: &Marker,
) -> Result<Vec<ArtifactFile>, SimulateError> {
    let placed = marker.pattern(&[pattern]);
    let dxf_error =
        |e: dxf::DxfWriteError| SimulateError::failed(format!("writing the DXF failed: {e}"));
    let (paper, tiled_name) = paper(sim.scene.patterns.paper);
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
        ArtifactFile {
            name: dxf::AAMA_FILE,
            content_type: dxf::CONTENT_TYPE,
            data: dxf::dxf_aama(pattern).map_err(dxf_error)?,
        },
        ArtifactFile {
            name: dxf::ASTM_FILE,
            content_type: dxf::CONTENT_TYPE,
            data: dxf::dxf_astm(pattern).map_err(dxf_error)?,
        },
        ArtifactFile {
            name: pdf::WIDE_FILE,
            content_type: pdf::CONTENT_TYPE,
            data: pdf::pattern_pdf(pattern),
        },
        ArtifactFile {
            name: tiled_name,
            content_type: pdf::CONTENT_TYPE,
            data: pdf::tiled_pdf(pattern, paper).0,
        },
        ArtifactFile {
            name: hpgl::FILE,
            content_type: hpgl::CONTENT_TYPE,
            data: hpgl::pattern_hpgl(pattern),
        },
        ArtifactFile {
            name: pdf::MARKER_FILE,
            content_type: pdf::CONTENT_TYPE,
            data: pdf::marker_pdf(&placed, marker),
        },
        ArtifactFile {
            name: dxf::MARKER_FILE,
            content_type: dxf::CONTENT_TYPE,
            data: dxf::dxf_marker(&placed, marker).map_err(dxf_error)?,
        },
    ])
}
