//! `patterns.json`: the whole pattern model, versioned, in millimetres.
//!
//! Top level: `schema_version` ([`SCHEMA_VERSION`]), `units: "mm"`, `labels` (the order's text),
//! `pieces` and `seams`. A piece has its `sewing_line_mm` and `cut_line_mm` (closed, counter-clockwise, face
//! side up, not repeated at the end), `edges` (named runs of the sewing line: `start`/`end` vertex indices,
//! `kind` `seam` with `seam`, `side`, `partner` or `opening` with `role` `top`/`bottom`/`side`,
//! `allowance_mm`, `length_mm`), `notches` (`at_mm` on the sewing line, `on_cut_line_mm`, `depth_mm`,
//! `seam`, `arc_length_mm`, `user`), `grain_line_mm` (`from`, `to`: the wale direction), `drill_holes_mm`,
//! `cut_quantity`, `mirrored`, `face_side` and `label_lines` (the text printed on it). A seam has its
//! `pieces`, `edges` (index into each piece's `edges`), `lengths_mm`, `difference_mm` and
//! `intended_ease_mm` (`difference_mm` minus the intended ease is what the sewer would have to ease in),
//! and `closed`.

use serde_json::{Value, json};

use crate::math::{Real, Vec2};
use crate::pattern::{EdgeKind, Pattern, SCHEMA_VERSION};

/// Millimetres per metre.
const MM: Real = 1000.0;

fn mm(p: Vec2) -> [Real; 2] {
    [p.x * MM, p.y * MM]
}

fn mm_list(points: &[Vec2]) -> Vec<[Real; 2]> {
    points.iter().map(|&p| mm(p)).collect()
}

/// `patterns.json` of `pattern` (see the module documentation).
pub fn patterns_json(pattern: &Pattern) -> Value {
    let pieces: Vec<Value> = pattern
        .pieces
        .iter()
        .map(|piece| {
            let edges: Vec<Value> = piece
                .edges
                .iter()
                .map(|e| {
                    let mut v = json!({
                        "name": e.name,
                        "start": e.start,
                        "end": e.end,
                        "allowance_mm": e.allowance * MM,
                        "length_mm": e.length * MM,
                    });
                    let kind = match e.kind {
                        EdgeKind::Seam {
                            seam,
                            side,
                            partner,
                        } => {
                            json!({"type": "seam", "seam": seam, "side": side, "partner": partner})
                        }
                        EdgeKind::Opening { role } => json!({"type": "opening", "role": role}),
                    };
                    v["kind"] = kind;
                    v
                })
                .collect();
            let notches: Vec<Value> = piece
                .notches
                .iter()
                .map(|n| {
                    json!({
                        "at_mm": mm(n.at),
                        "on_cut_line_mm": mm(n.on_cut_line),
                        "depth_mm": n.depth * MM,
                        "seam": n.seam,
                        "arc_length_mm": n.arc_length * MM,
                        "user": n.user,
                    })
                })
                .collect();
            json!({
                "name": piece.name,
                "sewing_line_mm": mm_list(&piece.sewing_line),
                "cut_line_mm": mm_list(&piece.cut_line),
                "edges": edges,
                "notches": notches,
                "grain_line_mm": {"from": mm(piece.grain_line.from), "to": mm(piece.grain_line.to)},
                "drill_holes_mm": mm_list(&piece.drill_holes),
                "cut_quantity": piece.cut_quantity,
                "mirrored": piece.mirrored,
                "face_side": piece.face_side,
                "label_anchor_mm": mm(piece.label_anchor),
                "label_lines": piece.label_lines(&pattern.labels),
            })
        })
        .collect();
    json!({
        "schema_version": SCHEMA_VERSION,
        "units": "mm",
        "labels": pattern.labels,
        "pieces": pieces,
        "seams": seam_table(pattern),
    })
}

/// The seam table (`result.json` `seams` and `patterns.json` `seams`): per seam its name, `panels`
/// (piece indices), `edges`, `lengths_mm: [a, b]`, `difference_mm` (`a − b`), `intended_ease_mm` and
/// `closed`.
pub fn seam_table(pattern: &Pattern) -> Vec<Value> {
    pattern
        .seams
        .iter()
        .map(|s| {
            json!({
                "name": s.name,
                "panels": s.pieces,
                "panel_names": s.pieces.map(|p| pattern.pieces[p].name.clone()),
                "edges": s.edges,
                "lengths_mm": [s.lengths[0] * MM, s.lengths[1] * MM],
                "difference_mm": (s.lengths[0] - s.lengths[1]) * MM,
                "intended_ease_mm": s.intended_ease * MM,
                "closed": s.closed,
            })
        })
        .collect()
}
