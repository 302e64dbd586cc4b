//! The report's pressure map: the worn garment seen from the front and from the back, each triangle
//! coloured by its probe pressure (mmHg, the colour map of `garment-pressure.glb`: 0 to the fabric's
//! pressure limit), over the body's surface in grey; with the legend in mmHg.
//!
//! **Method.** Orthographic projection along `z` (the body faces `+z`): the front view looks along `−z`
//! with the body's left (`+x`) on the viewer's right; the back view looks along `+z`, mirrored so the
//! body's left is on the viewer's left. Triangles facing away from the viewer are dropped. The body's
//! triangles are drawn far to near (painter's algorithm on their centroids' depth), then the garment's on
//! top of them, far to near, except those whose centroid a body triangle hides by more than
//! [`OCCLUSION_TOLERANCE`] (a garment on the other side of an arm, say): the garment lies on the body's
//! smooth surface, a few millimetres off the flat body triangles under it, so sorting both together would
//! let those triangles cover it. Body triangles are shaded by how squarely they
//! face the viewer, so the silhouette reads as a body. Each view shows the garment and [`CONTEXT`] of the
//! body around it, both views at the same scale.

use std::collections::HashMap;
use std::fmt::Write;

use skintight_geometry::Vec3;

use super::Report;
use super::html::{Digits, num, srgb_hex};
use crate::simulate::colormap::color;
use crate::simulate::result::PA_PER_MMHG;

/// A garment triangle is hidden when the body lies more than this in front of its centroid (m): the
/// garment lies on the smooth surface, within millimetres of the flat body triangles under it.
pub const OCCLUSION_TOLERANCE: f64 = 0.02;
/// Cell size of the grid that finds the body triangles over a point of a view (m).
const CELL: f64 = 0.02;

/// Height of a view's drawing (px).
const VIEW_HEIGHT: f64 = 520.0;
/// Width a view may take at most (px).
const VIEW_WIDTH: f64 = 380.0;
/// How much of the body around the garment a view shows (m).
pub const CONTEXT: f64 = 0.1;
/// Margin around a view (px).
const MARGIN: f64 = 10.0;

/// One triangle to draw: depth towards the viewer, three screen points, fill.
struct Drawn {
    depth: f64,
    points: [[f64; 2]; 3],
    fill: String,
}

/// Screen coordinates of `p` for the view `sign` (`+1` front, `−1` back).
fn project(p: Vec3, sign: f64) -> [f64; 2] {
    [sign * p.x, -p.y]
}

/// A triangle facing the view `sign`: its depth towards the viewer per corner and its screen points.
fn facing(tri: [Vec3; 3], sign: f64) -> Option<(f64, [f64; 3], [[f64; 2]; 3])> {
    if !tri.iter().all(|p| p.iter().all(|c| c.is_finite())) {
        return None;
    }
    let n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
    let len = n.norm();
    let cos = sign * n.z / len;
    (cos > 0.0).then(|| (cos, tri.map(|p| sign * p.z), tri.map(|p| project(p, sign))))
}

/// The depth of the triangle `points`/`depth` at the screen point `q`, if `q` lies in it.
fn depth_at(points: &[[f64; 2]; 3], depth: &[f64; 3], q: [f64; 2]) -> Option<f64> {
    let [a, b, c] = *points;
    let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    if det.abs() < 1e-18 {
        return None;
    }
    let l1 = ((q[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (q[1] - a[1])) / det;
    let l2 = ((b[0] - a[0]) * (q[1] - a[1]) - (q[0] - a[0]) * (b[1] - a[1])) / det;
    let l0 = 1.0 - l1 - l2;
    (l0 >= 0.0 && l1 >= 0.0 && l2 >= 0.0).then(|| l0 * depth[0] + l1 * depth[1] + l2 * depth[2])
}

fn cell(q: [f64; 2]) -> (i64, i64) {
    ((q[0] / CELL).floor() as i64, (q[1] / CELL).floor() as i64)
}

/// The triangles of one view (`sign`: `+1` front, `−1` back): the body's facing triangles far to near,
/// then the garment's facing triangles that no body triangle hides, far to near.
fn view(r: &Report, sign: f64, hi_mmhg: f64) -> Vec<Drawn> {
    let body: Vec<(f64, [f64; 3], [[f64; 2]; 3])> = r
        .body
        .faces
        .iter()
        .filter_map(|f| facing(f.map(|v| r.body.positions[v]), sign))
        .collect();
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (k, (_, _, pts)) in body.iter().enumerate() {
        let lo = cell([
            pts[0][0].min(pts[1][0]).min(pts[2][0]),
            pts[0][1].min(pts[1][1]).min(pts[2][1]),
        ]);
        let hi = cell([
            pts[0][0].max(pts[1][0]).max(pts[2][0]),
            pts[0][1].max(pts[1][1]).max(pts[2][1]),
        ]);
        for i in lo.0..=hi.0 {
            for j in lo.1..=hi.1 {
                grid.entry((i, j)).or_default().push(k);
            }
        }
    }
    let mean = |d: &[f64; 3]| (d[0] + d[1] + d[2]) / 3.0;
    let mut out: Vec<Drawn> = body
        .iter()
        .map(|(cos, depth, points)| {
            // Grey from 0.45 (edge-on) to 0.80 (facing), linear RGB.
            let g = (0.45 + 0.35 * cos) as f32 * 0.55;
            Drawn {
                depth: mean(depth),
                points: *points,
                fill: srgb_hex([g, g, g]),
            }
        })
        .collect();
    out.sort_by(|a, b| a.depth.total_cmp(&b.depth));
    let g = &r.garment;
    let mut garment: Vec<Drawn> = g
        .triangles
        .iter()
        .enumerate()
        .filter_map(|(t, tri)| {
            let (_, depth, points) = facing(tri.map(|i| Vec3::from(g.positions[i])), sign)?;
            let c = [
                (points[0][0] + points[1][0] + points[2][0]) / 3.0,
                (points[0][1] + points[1][1] + points[2][1]) / 3.0,
            ];
            let d = mean(&depth);
            let hidden = grid.get(&cell(c)).is_some_and(|ks| {
                ks.iter().any(|&k| {
                    depth_at(&body[k].2, &body[k].1, c).is_some_and(|z| z > d + OCCLUSION_TOLERANCE)
                })
            });
            if hidden {
                return None;
            }
            let mmhg = g.probe_pressure.get(t).copied().unwrap_or(f64::NAN) / PA_PER_MMHG;
            Some(Drawn {
                depth: d,
                points,
                fill: srgb_hex(color(mmhg, 0.0, hi_mmhg)),
            })
        })
        .collect();
    garment.sort_by(|a, b| a.depth.total_cmp(&b.depth));
    out.extend(garment);
    out
}

/// The screen bounding box `[min u, min v, max u, max v]` of `points` in a view (`sign`).
fn bbox(points: impl Iterator<Item = Vec3>, sign: f64) -> Option<[f64; 4]> {
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for p in points.filter(|p| p.iter().all(|c| c.is_finite())) {
        let [u, v] = project(p, sign);
        b = [b[0].min(u), b[1].min(v), b[2].max(u), b[3].max(v)];
    }
    (b[2] > b[0] && b[3] > b[1]).then_some(b)
}

/// The part of a view (`sign`) drawn, `[min u, min v, max u, max v]` (m): the garment and
/// [`CONTEXT`] around it, within the body's extent.
fn bounds(r: &Report, sign: f64) -> Option<[f64; 4]> {
    let garment = bbox(r.garment.positions.iter().map(|&p| Vec3::from(p)), sign)?;
    let all = bbox(
        r.body
            .positions
            .iter()
            .copied()
            .chain(r.garment.positions.iter().map(|&p| Vec3::from(p))),
        sign,
    )?;
    Some([
        (garment[0] - CONTEXT).max(all[0]),
        (garment[1] - CONTEXT).max(all[1]),
        (garment[2] + CONTEXT).min(all[2]),
        (garment[3] + CONTEXT).min(all[3]),
    ])
}

/// One view ([`bounds`]) as an `<svg>` at `scale` px/m.
fn view_svg(r: &Report, sign: f64, title: &str, hi_mmhg: f64, scale: f64) -> String {
    let Some(b) = bounds(r, sign) else {
        return String::new();
    };
    let w = (b[2] - b[0]) * scale + 2.0 * MARGIN;
    let h = (b[3] - b[1]) * scale + 2.0 * MARGIN + 20.0;
    let mut out = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w:.0}\" height=\"{h:.0}\" \
         viewBox=\"0 0 {w:.1} {h:.1}\" role=\"img\" aria-label=\"{title}\">\n\
         <text x=\"{:.1}\" y=\"14\" text-anchor=\"middle\" font-size=\"13\">{title}</text>\n\
         <svg x=\"0\" y=\"20\" width=\"{w:.1}\" height=\"{:.1}\">\n\
         <g stroke-width=\"0.4\" stroke-linejoin=\"round\">\n",
        w / 2.0,
        h - 20.0
    );
    // The drawing in a nested viewport (below the title), which clips what lies beyond the bounds.
    let (du, dv) = (MARGIN - b[0] * scale, MARGIN - b[1] * scale);
    for d in view(r, sign, hi_mmhg) {
        let outside = d.points.iter().all(|p| p[0] < b[0])
            || d.points.iter().all(|p| p[0] > b[2])
            || d.points.iter().all(|p| p[1] < b[1])
            || d.points.iter().all(|p| p[1] > b[3]);
        if outside {
            continue;
        }
        let p = d.points.map(|[u, v]| [u * scale + du, v * scale + dv]);
        let _ = writeln!(
            out,
            "<path d=\"M{:.1} {:.1}L{:.1} {:.1}L{:.1} {:.1}Z\" fill=\"{f}\" stroke=\"{f}\"/>",
            p[0][0],
            p[0][1],
            p[1][0],
            p[1][1],
            p[2][0],
            p[2][1],
            f = d.fill
        );
    }
    out.push_str("</g>\n</svg>\n</svg>\n");
    out
}

/// The colour legend: the ramp from 0 to `hi_mmhg` with ticks every 10 mmHg (5 below 30).
fn legend(hi_mmhg: f64, height: f64) -> String {
    let bar = (height - 60.0).max(100.0);
    let top = 30.0;
    let mut out = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"120\" height=\"{:.0}\" viewBox=\"0 0 120 {:.0}\" \
         role=\"img\" aria-label=\"pressure legend, mmHg\">\n<defs><linearGradient id=\"pressure-ramp\" \
         x1=\"0\" y1=\"1\" x2=\"0\" y2=\"0\">\n",
        bar + 50.0,
        bar + 50.0
    );
    for k in 0..=7 {
        let t = k as f64 / 7.0;
        let _ = writeln!(
            out,
            "<stop offset=\"{t:.4}\" stop-color=\"{}\"/>",
            srgb_hex(color(t, 0.0, 1.0))
        );
    }
    let _ = writeln!(
        out,
        "</linearGradient></defs>\n<text x=\"0\" y=\"14\" font-size=\"13\">mmHg</text>\n\
         <rect x=\"0\" y=\"{top}\" width=\"22\" height=\"{bar:.1}\" fill=\"url(#pressure-ramp)\" \
         stroke=\"#444\" stroke-width=\"0.5\"/>"
    );
    if hi_mmhg.is_finite() && hi_mmhg > 0.0 {
        let step = if hi_mmhg <= 30.0 { 5.0 } else { 10.0 };
        let mut v = 0.0;
        while v < hi_mmhg - 0.3 * step {
            let y = top + bar * (1.0 - v / hi_mmhg);
            let _ = writeln!(
                out,
                "<line x1=\"22\" y1=\"{y:.1}\" x2=\"28\" y2=\"{y:.1}\" stroke=\"#444\"/>\
                 <text x=\"31\" y=\"{:.1}\" font-size=\"11\">{v:.0}</text>",
                y + 4.0
            );
            v += step;
        }
        let _ = writeln!(
            out,
            "<line x1=\"22\" y1=\"{top}\" x2=\"28\" y2=\"{top}\" stroke=\"#444\"/>\
             <text x=\"31\" y=\"{:.1}\" font-size=\"11\">limit</text>",
            top + 4.0
        );
    }
    out.push_str("</svg>\n");
    out
}

/// The section.
pub fn section(r: &Report) -> String {
    let hi = r.admissibility.limits.max_pressure_pa / PA_PER_MMHG;
    let mut out = format!(
        "<h2>Pressure map</h2>\n<p>Interface pressure as a 5 cm probe reads it, on the worn garment; the \
         colours run from 0 to the fabric's limit, {} mmHg (at or beyond it: the top colour). The body is \
         grey.</p>\n<div class=\"figure\" id=\"pressure-map\">\n",
        num(
            "limits.max_pressure_pa",
            Some(r.admissibility.limits.max_pressure_pa),
            1.0 / PA_PER_MMHG,
            Digits::Fixed(1)
        )
    );
    let scale = match bounds(r, 1.0) {
        Some(b) => {
            (VIEW_HEIGHT / (b[3] - b[1]).max(1e-3)).min(VIEW_WIDTH / (b[2] - b[0]).max(1e-3))
        }
        None => {
            out.push_str("<p class=\"note\">Nothing to draw.</p>\n</div>\n");
            return out;
        }
    };
    out.push_str(&view_svg(r, 1.0, "front", hi, scale));
    out.push_str(&view_svg(r, -1.0, "back", hi, scale));
    let height = bounds(r, 1.0).map_or(VIEW_HEIGHT, |b| (b[3] - b[1]) * scale);
    out.push_str(&legend(hi, height + 2.0 * MARGIN + 20.0));
    out.push_str("</div>\n");
    out
}
