//! `patterns.plt`: the pattern in HP-GL/2, for pen plotters and cutting plotters.
//!
//! Plotter units: 40 per millimetre (0.025 mm, HP-GL's own unit), absolute coordinates (`PA`, the default
//! after `IN`), origin at the sheet's lower-left corner, +y up; true scale. The pieces are laid out side by
//! side as [`sheet`] places them. The file starts with `IN;` (initialise) and `DT` (label terminator ETX,
//! `\x03`, not printed), then draws with three pens:
//!
//! - `SP1`: the cut lines (closed: the pen returns to the first point);
//! - `SP2`: the sew lines;
//! - `SP3`: the marks: notch slits (from the cut line inwards, `depth` long), grain-line arrows, drill-hole
//!   crosses, the piece text (`LB…\x03`) and the seam numbers.
//!
//! Every stroke is `PU x,y;` then `PD x,y,x,y,…;` with integer coordinates. Label text is ASCII: control
//! characters (the label terminator among them) are dropped, letters with diacritics folded to their base
//! letters and any other non-ASCII character written `?`. The file ends with `PU;SP0;`.

use std::fmt::Write;

use crate::math::{Real, Vec2};
use crate::pattern::{Pattern, sheet};
use crate::pattern_format::ascii_text;
use crate::pattern_format::dxf::notch_slit;

/// File name of the HP-GL/2 pattern in an output folder.
pub const FILE: &str = "patterns.plt";
/// Media type of the HP-GL/2 file.
pub const CONTENT_TYPE: &str = "application/vnd.hp-hpgl";

/// Margin around the sheet and gap between pieces (m), as in the other writers.
const MARGIN: Real = 0.01;
const GAP: Real = 0.02;
/// Plotter units per metre (40 per mm).
pub const UNITS_PER_M: Real = 40_000.0;
/// Height of the label characters (cm, as `SI` takes it): 3.5 mm, 2.5 mm wide.
const LABEL_SIZE: &str = "SI0.25,0.35;";
/// Line spacing of the label text (m).
const LINE_STEP: Real = 0.006;
/// Half the size of a drill-hole cross (m).
const DRILL_CROSS: Real = 0.002;

/// A point in plotter units (a non-finite coordinate, which a valid pattern never has, is written as 0;
/// one beyond HP-GL's ±2³⁰ range is clamped to it).
fn units(p: Vec2) -> (i64, i64) {
    let f = |x: Real| {
        if x.is_finite() {
            (x * UNITS_PER_M).round().clamp(-1.0e9, 1.0e9) as i64
        } else {
            0
        }
    };
    (f(p.x), f(p.y))
}

/// Label text an HP-GL device carries: printable ASCII only ([`ascii_text`]: control characters, the
/// terminator among them, dropped; diacritics folded; other characters `?`).
fn label_text(text: &str) -> String {
    ascii_text(text)
}

/// One stroke through `points` (sheet coordinates, m); `closed` returns to the first point.
fn stroke(out: &mut String, points: &[Vec2], closed: bool) {
    let Some(&first) = points.first() else {
        return;
    };
    let (x, y) = units(first);
    let _ = write!(out, "PU{x},{y};");
    if points.len() < 2 {
        return;
    }
    out.push_str("PD");
    let rest = points[1..]
        .iter()
        .chain(if closed { Some(&points[0]) } else { None });
    for (k, &p) in rest.enumerate() {
        let (x, y) = units(p);
        let _ = write!(out, "{}{x},{y}", if k == 0 { "" } else { "," });
    }
    out.push_str(";\n");
}

fn label(out: &mut String, at: Vec2, text: &str) {
    let (x, y) = units(at);
    let _ = writeln!(out, "PU{x},{y};LB{}\x03", label_text(text));
}

/// The pattern as HP-GL/2 (see the module documentation).
pub fn pattern_hpgl(pattern: &Pattern) -> Vec<u8> {
    let layout = sheet(pattern, GAP, MARGIN);
    let offset = |p: usize| layout.offsets.get(p).copied().unwrap_or_else(Vec2::zeros);
    let mut out = String::from("IN;DT\x03,1;\n");
    out.push_str("SP1;\n");
    for (p, piece) in pattern.pieces.iter().enumerate() {
        let pts: Vec<Vec2> = piece.cut_line.iter().map(|&q| q + offset(p)).collect();
        stroke(&mut out, &pts, true);
    }
    out.push_str("SP2;\n");
    for (p, piece) in pattern.pieces.iter().enumerate() {
        let pts: Vec<Vec2> = piece.sewing_line.iter().map(|&q| q + offset(p)).collect();
        stroke(&mut out, &pts, true);
    }
    out.push_str("SP3;\n");
    out.push_str(LABEL_SIZE);
    out.push('\n');
    for (p, piece) in pattern.pieces.iter().enumerate() {
        let o = offset(p);
        for n in &piece.notches {
            if let Some((a, b)) = notch_slit(n.on_cut_line, n.at, n.depth) {
                stroke(&mut out, &[a + o, b + o], false);
            }
        }
        let g = piece.grain_line;
        let d = g.to - g.from;
        let len = d.norm();
        if len > 0.0 && len.is_finite() {
            let (u, n) = (d / len, Vec2::new(-d.y, d.x) / len);
            let head = 0.008_f64.min(0.3 * len);
            stroke(&mut out, &[g.from + o, g.to + o], false);
            stroke(
                &mut out,
                &[
                    g.to - u * head + n * 0.4 * head + o,
                    g.to + o,
                    g.to - u * head - n * 0.4 * head + o,
                ],
                false,
            );
        }
        for &h in &piece.drill_holes {
            let c = h + o;
            stroke(
                &mut out,
                &[c - Vec2::x() * DRILL_CROSS, c + Vec2::x() * DRILL_CROSS],
                false,
            );
            stroke(
                &mut out,
                &[c - Vec2::y() * DRILL_CROSS, c + Vec2::y() * DRILL_CROSS],
                false,
            );
        }
        for (k, line) in piece.label_lines(&pattern.labels).iter().enumerate() {
            label(
                &mut out,
                piece.label_anchor + o - Vec2::y() * (k as Real * LINE_STEP),
                line,
            );
        }
        for (at, number) in piece.seam_labels() {
            label(&mut out, at + o, number);
        }
    }
    out.push_str("PU;SP0;\n");
    out.into_bytes()
}

#[cfg(test)]
mod tests;
