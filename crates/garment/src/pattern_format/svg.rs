//! `patterns.svg`: the pattern drawn at true scale, to view or print at 1:1.
//!
//! The document is measured in millimetres (`width="…mm"`, `viewBox` in the same numbers: one user unit is
//! one millimetre on paper). Pieces are laid out side by side as [`sheet`] places them, face side up,
//! with the page's y axis pointing down (pattern +y up). One layer (`<g inkscape:groupmode="layer">`) per
//! kind of line, as in the DXF files: `cut-line` (filled outline), `sew-line` (dashed), `seams` (the seam
//! number at the middle of each seam side, the same on both pieces), `notches` (the slits), `grain-line`
//! (arrows along the wales), `drill-holes`, `labels` (the piece's text) and `scale` (a 100 mm test square,
//! to check the print scale). Every element of a piece carries `data-piece="INDEX"`.

use std::fmt::Write;

use crate::math::{Real, Vec2};
use crate::pattern::{Pattern, sheet};
use crate::pattern_format::xml_text::escape;

/// Margin around the drawing and gap between pieces (m).
const MARGIN: Real = 0.01;
const GAP: Real = 0.02;
/// Space below the pieces for the test square (m).
const SCALE_SPACE: Real = 0.12;
/// Side of the test square (mm).
const TEST_SQUARE_MM: Real = 100.0;
/// Millimetres per metre.
const MM: Real = 1000.0;

/// A finite number for the document (a non-finite one, which a valid pattern never has, is written as 0).
fn num(x: Real) -> String {
    if x.is_finite() {
        format!("{x:.3}")
    } else {
        "0".into()
    }
}

/// `M x y L x y … [Z]` for points already on the page (mm).
fn path_data(points: &[Vec2], closed: bool) -> String {
    let mut d = String::new();
    for (i, p) in points.iter().enumerate() {
        let _ = write!(
            d,
            "{}{} {} ",
            if i == 0 { "M" } else { "L" },
            num(p.x),
            num(p.y)
        );
    }
    if closed {
        d.push('Z');
    }
    d.trim_end().to_string()
}

/// The pattern as an SVG document at true scale (see the module documentation).
pub fn pattern_svg(pattern: &Pattern) -> String {
    let layout = sheet(pattern, GAP, MARGIN);
    let width = (layout.size.x * MM).max(2.0 * MARGIN * MM + TEST_SQUARE_MM);
    let height = (layout.size.y + SCALE_SPACE) * MM;
    // Page point (mm, y down) of pattern point `q` of piece `p`.
    let page = |p: usize, q: Vec2| {
        let s = q + layout.offsets[p];
        Vec2::new(s.x * MM, height - (s.y + SCALE_SPACE) * MM)
    };
    let mut out = String::new();
    let _ = writeln!(out, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" width="{w}mm" height="{h}mm" viewBox="0 0 {w} {h}">"#,
        w = num(width),
        h = num(height)
    );
    let _ = writeln!(
        out,
        "<style>.cut{{fill:#f6f1e7;stroke:#000;stroke-width:0.5}} \
         .sew{{fill:none;stroke:#555;stroke-width:0.3;stroke-dasharray:2 1}} \
         .seam-label{{fill:#c0392b;font:bold 6px sans-serif;text-anchor:middle;dominant-baseline:middle}} \
         .notch{{stroke:#000;stroke-width:0.5}} .grain{{fill:none;stroke:#1f4e9c;stroke-width:0.5}} \
         .drill{{fill:none;stroke:#000;stroke-width:0.3}} .label{{font:5px sans-serif}} \
         .scale{{fill:none;stroke:#000;stroke-width:0.3}} .scale-label{{font:5px sans-serif}}</style>"
    );
    let layer = |out: &mut String, id: &str, body: &dyn Fn(&mut String)| {
        let _ = writeln!(
            out,
            r#"<g id="{id}" inkscape:groupmode="layer" inkscape:label="{id}">"#
        );
        body(out);
        let _ = writeln!(out, "</g>");
    };
    let pieces = &pattern.pieces;
    layer(&mut out, "cut-line", &|out| {
        for (p, piece) in pieces.iter().enumerate() {
            let pts: Vec<Vec2> = piece.cut_line.iter().map(|&q| page(p, q)).collect();
            let _ = writeln!(
                out,
                r#"<path class="cut" data-piece="{p}" d="{}"/>"#,
                path_data(&pts, true)
            );
        }
    });
    layer(&mut out, "sew-line", &|out| {
        for (p, piece) in pieces.iter().enumerate() {
            let pts: Vec<Vec2> = piece.sewing_line.iter().map(|&q| page(p, q)).collect();
            let _ = writeln!(
                out,
                r#"<path class="sew" data-piece="{p}" d="{}"/>"#,
                path_data(&pts, true)
            );
        }
    });
    layer(&mut out, "seams", &|out| {
        for (p, piece) in pieces.iter().enumerate() {
            for (at, number) in piece.seam_labels() {
                let m = page(p, at);
                let _ = writeln!(
                    out,
                    r#"<text class="seam-label" data-piece="{p}" x="{}" y="{}">{}</text>"#,
                    num(m.x),
                    num(m.y),
                    escape(number)
                );
            }
        }
    });
    layer(&mut out, "notches", &|out| {
        for (p, piece) in pieces.iter().enumerate() {
            for n in &piece.notches {
                let dir = n.at - n.on_cut_line;
                let len = dir.norm();
                let end = if len > 0.0 {
                    n.on_cut_line + dir * (n.depth / len)
                } else {
                    n.at
                };
                let (a, b) = (page(p, n.on_cut_line), page(p, end));
                let _ = writeln!(
                    out,
                    r#"<line class="notch" data-piece="{p}" x1="{}" y1="{}" x2="{}" y2="{}"/>"#,
                    num(a.x),
                    num(a.y),
                    num(b.x),
                    num(b.y)
                );
            }
        }
    });
    layer(&mut out, "grain-line", &|out| {
        for (p, piece) in pieces.iter().enumerate() {
            let g = piece.grain_line;
            let d = g.to - g.from;
            let len = d.norm().max(1e-12);
            let (u, n) = (d / len, Vec2::new(-d.y, d.x) / len);
            let head = 0.008_f64.min(0.3 * len);
            let pts = [
                page(p, g.from),
                page(p, g.to),
                page(p, g.to - u * head + n * 0.4 * head),
                page(p, g.to - u * head - n * 0.4 * head),
            ];
            let _ = writeln!(
                out,
                r#"<path class="grain" data-piece="{p}" d="M {} {} L {} {} M {} {} L {} {} L {} {}"/>"#,
                num(pts[0].x),
                num(pts[0].y),
                num(pts[1].x),
                num(pts[1].y),
                num(pts[2].x),
                num(pts[2].y),
                num(pts[1].x),
                num(pts[1].y),
                num(pts[3].x),
                num(pts[3].y)
            );
        }
    });
    layer(&mut out, "drill-holes", &|out| {
        for (p, piece) in pieces.iter().enumerate() {
            for &h in &piece.drill_holes {
                let c = page(p, h);
                let _ = writeln!(
                    out,
                    r#"<circle class="drill" data-piece="{p}" cx="{}" cy="{}" r="1.5"/>"#,
                    num(c.x),
                    num(c.y)
                );
            }
        }
    });
    layer(&mut out, "labels", &|out| {
        for (p, piece) in pieces.iter().enumerate() {
            let a = page(p, piece.label_anchor);
            let _ = writeln!(
                out,
                r#"<text class="label" data-piece="{p}" x="{}" y="{}">"#,
                num(a.x),
                num(a.y)
            );
            for (i, line) in piece.label_lines(&pattern.labels).iter().enumerate() {
                let _ = writeln!(
                    out,
                    r#"<tspan x="{}" dy="{}">{}</tspan>"#,
                    num(a.x),
                    if i == 0 { "0" } else { "6" },
                    escape(line)
                );
            }
            let _ = writeln!(out, "</text>");
        }
    });
    layer(&mut out, "scale", &|out| {
        let (x, y) = (MARGIN * MM, height - MARGIN * MM - TEST_SQUARE_MM);
        let _ = writeln!(
            out,
            r#"<rect class="scale" x="{}" y="{}" width="{s}" height="{s}"/>"#,
            num(x),
            num(y),
            s = num(TEST_SQUARE_MM)
        );
        let _ = writeln!(
            out,
            r#"<text class="scale-label" x="{}" y="{}">test square 100 mm × 100 mm</text>"#,
            num(x + 3.0),
            num(y + 8.0)
        );
    });
    out.push_str("</svg>\n");
    out
}
