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
use crate::pattern::notches::Run;
use crate::pattern::{EdgeKind, Pattern, sheet};
use crate::pattern_format::ascii_text;
use crate::pattern_format::dxf::notch_slit;

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
        let n = piece.sewing_line.len();
        for edge in &piece.edges {
            if let (EdgeKind::Seam { .. }, true) = (edge.kind, n >= 2) {
                let run = Run {
                    sewing: &piece.sewing_line,
                    start: edge.start % n,
                    end: edge.end % n,
                };
                let (at, normal) = run.point_at(0.5 * edge.length);
                label(
                    &mut out,
                    at - normal * 0.006 + o,
                    edge.name.trim_start_matches("seam "),
                );
            }
        }
    }
    out.push_str("PU;SP0;\n");
    out.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pattern_format::test_pattern::bulged_tube_pattern;

    /// What a plotter does with the file: strokes per pen (each from a `PU` to the last `PD`) and labels.
    #[derive(Default, Debug)]
    struct Plot {
        strokes: Vec<(u32, Vec<(i64, i64)>)>,
        labels: Vec<(u32, (i64, i64), String)>,
    }

    /// A small HP-GL/2 reader for the commands the writer uses (IN, DT, SP, SI, PU, PD, LB).
    fn parse(file: &[u8]) -> Plot {
        let text = std::str::from_utf8(file).expect("ASCII");
        let mut plot = Plot::default();
        let (mut pen, mut at, mut terminator) = (0u32, (0i64, 0i64), '\u{3}');
        let mut rest = text;
        loop {
            rest = rest.trim_start_matches([';', '\n', ' ']);
            if rest.is_empty() {
                break;
            }
            let (cmd, args) = rest.split_at(2);
            if cmd == "LB" {
                let end = args.find(terminator).expect("label terminator");
                plot.labels.push((pen, at, args[..end].to_string()));
                rest = &args[end + terminator.len_utf8()..];
                continue;
            }
            let end = args.find(';').expect("command terminator");
            let params = &args[..end];
            rest = &args[end + 1..];
            let numbers = || -> Vec<i64> {
                if params.is_empty() {
                    vec![]
                } else {
                    params.split(',').map(|v| v.parse().unwrap()).collect()
                }
            };
            match cmd {
                "IN" | "SI" => {}
                "DT" => terminator = params.chars().next().unwrap(),
                "SP" => pen = params.parse().unwrap(),
                "PU" => {
                    let v = numbers();
                    if let [x, y, ..] = v[..] {
                        at = (x, y);
                    }
                    plot.strokes.push((pen, vec![at]));
                }
                "PD" => {
                    let v = numbers();
                    let s = &mut plot.strokes.last_mut().expect("PU before PD").1;
                    for xy in v.chunks(2) {
                        at = (xy[0], xy[1]);
                        s.push(at);
                    }
                }
                other => panic!("unexpected command {other}"),
            }
        }
        plot.strokes.retain(|(_, s)| s.len() > 1);
        plot
    }

    #[test]
    fn hpgl_reads_back_the_cut_lines_to_a_plotter_unit() {
        let pattern = bulged_tube_pattern();
        let file = pattern_hpgl(&pattern);
        assert!(file.starts_with(b"IN;"));
        assert!(file.is_ascii());
        let plot = parse(&file);
        let layout = sheet(&pattern, GAP, MARGIN);
        let cut: Vec<&Vec<(i64, i64)>> = plot
            .strokes
            .iter()
            .filter(|(pen, _)| *pen == 1)
            .map(|(_, s)| s)
            .collect();
        assert_eq!(cut.len(), pattern.pieces.len());
        for ((piece, stroke), o) in pattern.pieces.iter().zip(cut).zip(&layout.offsets) {
            // Closed: back to the first point.
            assert_eq!(stroke.len(), piece.cut_line.len() + 1);
            assert_eq!(stroke.first(), stroke.last());
            for (&(x, y), q) in stroke.iter().zip(&piece.cut_line) {
                let want = (q + o) * 1000.0;
                let (dx, dy) = (x as Real / 40.0 - want.x, y as Real / 40.0 - want.y);
                assert!(dx.hypot(dy) <= 0.025, "({x}, {y}) vs {want:?} mm");
            }
        }
        let sew = plot.strokes.iter().filter(|(pen, _)| *pen == 2).count();
        assert_eq!(sew, pattern.pieces.len());
        let notches: usize = pattern.pieces.iter().map(|p| p.notches.len()).sum();
        // Notches, the grain line and its head per piece, on pen 3.
        let marks = plot.strokes.iter().filter(|(pen, _)| *pen == 3).count();
        assert_eq!(marks, notches + 2 * pattern.pieces.len());
        let texts: Vec<&str> = plot.labels.iter().map(|(_, _, t)| t.as_str()).collect();
        assert!(texts.contains(&"Piece: front"), "{texts:?}");
        assert!(texts.contains(&"Customer: Zoe Muller"), "{texts:?}");
        assert!(plot.labels.iter().all(|(pen, _, _)| *pen == 3));
    }

    #[test]
    fn hpgl_survives_degenerate_models() {
        let mut pattern = bulged_tube_pattern();
        pattern.pieces[0].cut_line.clear();
        pattern.pieces[1].sewing_line.truncate(1);
        pattern.pieces[1].grain_line.to = pattern.pieces[1].grain_line.from;
        pattern.pieces[1].label_anchor.x = Real::NAN;
        pattern.pieces[0].name = "x;\u{3}y\nz".into();
        let plot = parse(&pattern_hpgl(&pattern));
        assert!(plot.labels.iter().any(|(_, _, t)| t == "Piece: x;yz"));
    }
}
