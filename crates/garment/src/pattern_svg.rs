//! True-scale SVG drawing of a garment's sewing patterns, to print at 1:1.
//!
//! The document is measured in millimetres: `width="…mm" height="…mm"` with a `viewBox` of the same numbers, so
//! one user unit is one millimetre on paper. Panels are drawn as flattened (same orientation, pattern +y up),
//! only translated, side by side from left to right in panel order with a gap between their bounding boxes, so
//! they never overlap. Each panel shows
//! * its outline: one closed path per boundary loop (free boundary in a plain black line),
//! * its seams drawn over the outline in a dashed red line, seam `k` labelled "k" at the middle of its
//!   polyline on both panels (`k` is 1-based: seam `k` is `Garment::seams[k - 1]`),
//! * its name and pattern area (m²) at its area centroid.
//!
//! A 10 cm scale bar sits below the panels to check the print scale.

use std::fmt::Write;

use crate::garment::Garment;
use crate::math::{Real, Vec2};
use crate::plane_cut::Border;

/// Margin around the drawing (mm).
const MARGIN: Real = 10.0;
/// Horizontal gap between the bounding boxes of neighbouring panels (mm).
const GAP: Real = 20.0;
/// Space below the panels for the scale bar (mm).
const SCALE_BAR_SPACE: Real = 20.0;
/// Length of the scale bar (mm).
const SCALE_BAR: Real = 100.0;

/// Millimetres per metre.
const MM: Real = 1000.0;

/// Escapes text for XML character data and attribute values.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if (c as u32) < 0x20 && c != '\t' && c != '\n' && c != '\r' => {}
            c => out.push(c),
        }
    }
    out
}

/// A finite number for the document (a non-finite one, which a valid garment never has, is written as 0).
fn num(x: Real) -> String {
    if x.is_finite() {
        format!("{x:.3}")
    } else {
        "0".into()
    }
}

/// Axis-aligned bounding box of points (m); zeros for no points.
fn bounds(points: &[Vec2]) -> (Vec2, Vec2) {
    let finite = points.iter().filter(|p| p.iter().all(|c| c.is_finite()));
    let (lo, hi) = finite.fold(
        (Vec2::repeat(Real::INFINITY), Vec2::repeat(-Real::INFINITY)),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    if lo.x > hi.x {
        (Vec2::zeros(), Vec2::zeros())
    } else {
        (lo, hi)
    }
}

/// Where each panel goes: the page offset (mm) added to `(x − lo.x, hi.y − y) · 1000`, and the page size
/// (mm). Returns `(per panel (lo, hi, x offset), width, height, panel band height)`.
fn layout(garment: &Garment) -> (Vec<(Vec2, Vec2, Real)>, Real, Real, Real) {
    let mut placed = Vec::with_capacity(garment.panels.len());
    let mut x = MARGIN;
    let mut band: Real = 0.0;
    for (i, gp) in garment.panels.iter().enumerate() {
        if i > 0 {
            x += GAP;
        }
        let (lo, hi) = bounds(&gp.pattern);
        placed.push((lo, hi, x));
        x += (hi.x - lo.x) * MM;
        band = band.max((hi.y - lo.y) * MM);
    }
    let width = (x + MARGIN).max(2.0 * MARGIN + SCALE_BAR);
    let height = MARGIN + band + SCALE_BAR_SPACE + MARGIN;
    (placed, width, height, band)
}

/// Arc-length midpoint of a polyline (`points` in mm, open or `closed`).
fn polyline_middle(points: &[Vec2], closed: bool) -> Vec2 {
    let n = points.len();
    let segs = if closed { n } else { n.saturating_sub(1) };
    let seg = |i: usize| (points[i], points[(i + 1) % n]);
    let total: Real = (0..segs).map(|i| (seg(i).1 - seg(i).0).norm()).sum();
    let mut s = 0.5 * total;
    for i in 0..segs {
        let (a, b) = seg(i);
        let len = (b - a).norm();
        if s <= len && len > 0.0 {
            return a + (b - a) * (s / len);
        }
        s -= len;
    }
    points.first().copied().unwrap_or_else(Vec2::zeros)
}

/// `M x y L x y … [Z]` for points in mm.
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

/// The sewing patterns of `garment` as an SVG document at true scale (1 user unit = 1 mm): panels side by
/// side, outlines, numbered seams (the same number on both panels), name and area labels, a 10 cm scale bar.
/// Paths: one per boundary loop, one per seam side, one for the scale bar.
pub fn pattern_svg(garment: &Garment) -> String {
    let (placed, width, height, band) = layout(garment);
    let to_page = |p: usize, q: Vec2| -> Vec2 {
        let (lo, hi, x) = placed[p];
        Vec2::new(x + (q.x - lo.x) * MM, MARGIN + (hi.y - q.y) * MM)
    };
    let mut out = String::new();
    let _ = writeln!(out, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}mm" height="{h}mm" viewBox="0 0 {w} {h}">"#,
        w = num(width),
        h = num(height)
    );
    let _ = writeln!(
        out,
        "<style>.outline{{fill:#f6f1e7;stroke:#000;stroke-width:0.4}} \
         .seam{{fill:none;stroke:#c0392b;stroke-width:0.8;stroke-dasharray:3 1.5}} \
         .seam-label{{fill:#c0392b;font:bold 6px sans-serif;text-anchor:middle;dominant-baseline:middle}} \
         .name{{font:7px sans-serif;text-anchor:middle}} .area{{font:5px sans-serif;text-anchor:middle}} \
         .scale{{fill:none;stroke:#000;stroke-width:0.5}} .scale-label{{font:5px sans-serif}}</style>"
    );

    // The sides of every seam per panel: (seam number, local vertices, closed).
    let mut sides: Vec<Vec<(usize, &[usize], bool)>> = vec![Vec::new(); garment.panels.len()];
    for (k, s) in garment.seams.iter().enumerate() {
        for side in 0..2 {
            if let Some(list) = sides.get_mut(s.panels[side]) {
                list.push((k + 1, s.vertices[side].as_slice(), s.closed));
            }
        }
    }

    for (p, gp) in garment.panels.iter().enumerate() {
        let _ = writeln!(out, r#"<g id="panel-{p}">"#);
        let point = |v: usize| to_page(p, gp.pattern.get(v).copied().unwrap_or_else(Vec2::zeros));
        for lp in &gp.boundary {
            let pts: Vec<Vec2> = lp.vertices.iter().map(|&v| point(v)).collect();
            let free = lp.borders.iter().filter(|b| **b == Border::Free).count();
            let _ = writeln!(
                out,
                r#"<path class="outline" data-free-edges="{free}" d="{}"/>"#,
                path_data(&pts, true)
            );
        }
        for &(k, vertices, closed) in &sides[p] {
            let pts: Vec<Vec2> = vertices.iter().map(|&v| point(v)).collect();
            let _ = writeln!(
                out,
                r#"<path class="seam" data-seam="{k}" d="{}"/>"#,
                path_data(&pts, closed)
            );
            let m = polyline_middle(&pts, closed);
            let _ = writeln!(
                out,
                r#"<text class="seam-label" x="{}" y="{}">{k}</text>"#,
                num(m.x),
                num(m.y)
            );
        }
        // Name and area at the area centroid.
        let mut area = 0.0;
        let mut c = Vec2::zeros();
        for f in &gp.faces {
            let [a, b, d] = f.map(|v| gp.pattern.get(v).copied().unwrap_or_else(Vec2::zeros));
            let t = 0.5 * ((b - a).x * (d - a).y - (b - a).y * (d - a).x);
            area += t;
            c += (a + b + d) * (t / 3.0);
        }
        let centre = if area > 0.0 {
            to_page(p, c / area)
        } else {
            to_page(p, Vec2::zeros())
        };
        let _ = writeln!(
            out,
            r#"<text class="name" x="{}" y="{}">{}</text>"#,
            num(centre.x),
            num(centre.y),
            escape(&gp.name)
        );
        let _ = writeln!(
            out,
            r#"<text class="area" x="{}" y="{}">{:.4} m²</text>"#,
            num(centre.x),
            num(centre.y + 7.0),
            if area.is_finite() { area } else { 0.0 }
        );
        let _ = writeln!(out, "</g>");
    }

    // Scale bar: 100 mm with end ticks.
    let y = MARGIN + band + 0.5 * SCALE_BAR_SPACE;
    let (x0, x1) = (MARGIN, MARGIN + SCALE_BAR);
    let _ = writeln!(
        out,
        r#"<path class="scale" d="M {a} {t} L {a} {b} M {a} {y} L {c} {y} M {c} {t} L {c} {b}"/>"#,
        a = num(x0),
        c = num(x1),
        y = num(y),
        t = num(y - 2.0),
        b = num(y + 2.0)
    );
    let _ = writeln!(
        out,
        r#"<text class="scale-label" x="{}" y="{}">10 cm</text>"#,
        num(x1 + 3.0),
        num(y + 2.0)
    );
    out.push_str("</svg>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::garment::{GarmentParams, PanelShape, PanelSpec, garment};
    use crate::plane_cut::HalfSpace;
    use skintight_geometry::test_meshes::cylinder;

    /// An open tube cut into three panels (two seams along the tube, one free rim at each end), with a name
    /// that needs escaping.
    fn tube() -> Garment {
        let body = cylinder(0.1, 0.3, 24, 6, std::f64::consts::TAU);
        let specs = vec![
            PanelSpec {
                name: "front <A&B>".into(),
                shape: PanelShape::Region(vec![HalfSpace::new([0.0, -1.0, 0.0], -0.02)]),
            },
            PanelSpec {
                name: "back".into(),
                shape: PanelShape::Region(vec![HalfSpace::new([0.0, 1.0, 0.0], 0.02)]),
            },
        ];
        garment(
            &body,
            &specs,
            &GarmentParams {
                edge_length: 0.02,
                ..Default::default()
            },
        )
        .unwrap()
    }

    fn attr(svg: &str, name: &str) -> String {
        let start = svg.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
        let end = start + svg[start..].find('"').unwrap();
        svg[start..end].to_string()
    }

    #[test]
    fn svg_is_true_scale_with_matching_seam_labels() {
        let g = tube();
        let svg = pattern_svg(&g);
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        assert!(svg.starts_with("<?xml") && svg.trim_end().ends_with("</svg>"));
        // Balanced elements.
        assert_eq!(svg.matches("<g ").count(), svg.matches("</g>").count());
        assert_eq!(svg.matches("<text").count(), svg.matches("</text>").count());
        assert_eq!(svg.matches("<svg").count(), 1);
        // Paths: one per loop, one per seam side, the scale bar.
        let loops: usize = g.panels.iter().map(|p| p.boundary.len()).sum();
        assert_eq!(g.seams.len(), 2);
        assert_eq!(svg.matches("<path").count(), loops + 2 * g.seams.len() + 1);
        for k in 1..=g.seams.len() {
            let label = r#"class="seam-label""#;
            let hits = svg
                .lines()
                .filter(|l| l.contains(label) && l.ends_with(&format!(">{k}</text>")))
                .count();
            assert_eq!(hits, 2, "seam {k}");
        }
        // Names escaped.
        assert!(svg.contains("front &lt;A&amp;B&gt;"));
        assert!(!svg.contains("<A&B>"));
        // Width: margins, panel widths (m → mm) and gaps.
        let panels: Real = g
            .panels
            .iter()
            .map(|p| {
                let (lo, hi) = bounds(&p.pattern);
                (hi.x - lo.x) * MM
            })
            .sum();
        let expected = 2.0 * MARGIN + panels + GAP * (g.panels.len() - 1) as Real;
        let width = attr(&svg, "width");
        assert!(width.ends_with("mm"));
        let w: Real = width.trim_end_matches("mm").parse().unwrap();
        assert!((w - expected).abs() < 1e-3, "{w} vs {expected}");
        let vb = attr(&svg, "viewBox");
        let vb: Vec<Real> = vb.split(' ').map(|s| s.parse().unwrap()).collect();
        assert_eq!(vb[2], w);
        // Each panel is at least 0.2 m across (the tube is 0.3 m long, 0.63 m around) before the ease.
        assert!(w > 2.0 * MARGIN + GAP + 2.0 * 0.9 * 200.0, "{w}");
        assert!(svg.contains("10 cm"));
    }

    #[test]
    fn escape_handles_all_specials() {
        assert_eq!(escape(r#"a&b<c>"d'"#), "a&amp;b&lt;c&gt;&quot;d&apos;");
        assert_eq!(escape("x\u{1}y"), "xy");
    }
}
