//! The pattern in GarmentCode's JSON pattern specification (Korosteleva & Sorkine-Hornung, "GarmentCode:
//! Programming Parametric Sewing Patterns", 2023; the `pattern_specification.json` its tools read).
//!
//! Layout: `{"pattern": {"panels": {NAME: {"translation": [x, y, z], "rotation": [α, β, γ], "vertices":
//! [[x, y], …], "edges": [{"endpoints": [i, j]}, …]}}, "panel_order": [NAME, …], "stitches": [[{"panel":
//! NAME, "edge": i}, {"panel": NAME, "edge": j}], …]}, "properties": {"curvature_coords": "relative",
//! "units_in_meter": 100}}` — lengths in centimetres (`units_in_meter: 100`), rotations as extrinsic x-y-z
//! Euler angles in degrees. Vertices are the sewing line (GarmentCode's panels have no seam allowance),
//! counter-clockwise; every sewing-line segment is a straight edge, and every pair of corresponding seam
//! segments is one stitch, so a seam of `k` segments is `k` stitches. Panel names are made unique by
//! appending `_2`, `_3`… when two pieces share a name.

use serde_json::{Map, Value, json};

use crate::math::Real;
use crate::pattern::Pattern;

/// Centimetres per metre.
const CM: Real = 100.0;

/// GarmentCode's JSON pattern specification of `pattern` (see the module documentation).
pub fn garmentcode(pattern: &Pattern) -> Value {
    // Unique panel names.
    let mut names: Vec<String> = Vec::with_capacity(pattern.pieces.len());
    for piece in &pattern.pieces {
        let mut name = piece.name.clone();
        let mut k = 2;
        while names.contains(&name) {
            name = format!("{}_{k}", piece.name);
            k += 1;
        }
        names.push(name);
    }
    let mut panels = Map::new();
    for (piece, name) in pattern.pieces.iter().zip(&names) {
        let n = piece.sewing_line.len();
        let vertices: Vec<[Real; 2]> = piece
            .sewing_line
            .iter()
            .map(|p| [p.x * CM, p.y * CM])
            .collect();
        let edges: Vec<Value> = (0..n)
            .map(|i| json!({"endpoints": [i, (i + 1) % n]}))
            .collect();
        let t = piece.placement.translation * CM;
        panels.insert(
            name.clone(),
            json!({
                "translation": [t.x, t.y, t.z],
                "rotation": piece.placement.rotation_xyz.map(Real::to_degrees),
                "vertices": vertices,
                "edges": edges,
            }),
        );
    }
    let mut stitches = Vec::new();
    for seam in &pattern.seams {
        let [p0, p1] = seam.pieces;
        let (e0, e1) = (
            &pattern.pieces[p0].edges[seam.edges[0]],
            &pattern.pieces[p1].edges[seam.edges[1]],
        );
        let (n0, n1) = (
            pattern.pieces[p0].sewing_line.len(),
            pattern.pieces[p1].sewing_line.len(),
        );
        let segments = |start: usize, end: usize, n: usize| match (end + n - start) % n {
            0 => n,
            k => k,
        };
        let count = segments(e0.start, e0.end, n0).min(segments(e1.start, e1.end, n1));
        for j in 0..count {
            // Side 0 forward from its start; side 1 backward from its end.
            let a = (e0.start + j) % n0;
            let b = (e1.end + n1 - 1 - j % n1) % n1;
            stitches.push(json!([
                {"panel": names[p0], "edge": a},
                {"panel": names[p1], "edge": b},
            ]));
        }
    }
    json!({
        "pattern": {
            "panels": panels,
            "panel_order": names,
            "stitches": stitches,
        },
        "properties": {"curvature_coords": "relative", "units_in_meter": 100},
    })
}
