//! The report's pressure-by-height curve: at each landmark band the garment covers, the mean interface
//! pressure (a dot) and the lowest and highest probe reading (a whisker), mmHg against the landmark's
//! height above the floor (cm), one line per limb from the bottom up; with a prescription, each prescribed
//! band's window drawn as a box across its height (green where the band passes, red where it fails, grey
//! where the garment does not reach it).

use std::fmt::Write;

use skintight_geometry::anthropometry::Side;

use super::Report;
use super::html::escape;
use super::measurements::side_name;
use crate::simulate::regions::{BAND_HALF_WIDTH, Region};
use skintight_geometry::anthropometry::landmarks::ARM_LANDMARKS;

const WIDTH: f64 = 600.0;
const HEIGHT: f64 = 380.0;
const LEFT: f64 = 60.0;
const RIGHT: f64 = 150.0;
const TOP: f64 = 15.0;
const BOTTOM: f64 = 45.0;

/// The colour of a limb's curve.
fn side_colour(side: Option<Side>) -> &'static str {
    match side {
        Some(Side::Left) => "#1f5fa8",
        Some(Side::Right) => "#8e44ad",
        None => "#333333",
    }
}

/// A limb: whether an arm, and its side (`None`: the torso).
type Limb = (bool, Option<Side>);

/// The limbs' curves: the regions grouped by limb (leg, arm or torso, and side), each by height.
fn curves(regions: &[Region]) -> Vec<Vec<&Region>> {
    let mut groups: Vec<(Limb, Vec<&Region>)> = Vec::new();
    for g in regions {
        let key = (ARM_LANDMARKS.contains(&g.name.as_str()), g.side);
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, v)) => v.push(g),
            None => groups.push((key, vec![g])),
        }
    }
    groups
        .into_iter()
        .map(|(_, mut v)| {
            v.sort_by(|a, b| a.height_m.total_cmp(&b.height_m));
            v
        })
        .collect()
}

/// A "nice" upper end of an axis from 0 to at least `v`.
fn nice_ceiling(v: f64) -> f64 {
    let step = if v <= 50.0 { 10.0 } else { 20.0 };
    ((v / step).ceil() * step).max(step)
}

/// The section.
pub fn section(r: &Report) -> String {
    let mut out = String::from("<h2>Pressure by height</h2>\n");
    // Prescribed windows with their heights (from the landmarks).
    let windows: Vec<(f64, [f64; 2], Option<bool>, String)> = r
        .prescription
        .map(|p| {
            p.bands
                .iter()
                .filter_map(|b| {
                    let l = r
                        .landmarks
                        .iter()
                        .find(|l| l.name == b.name && l.side == b.side)?;
                    let pass = b.measured_mmhg.map(|_| b.pass);
                    let label = format!("{} {}", b.name, side_name(b.side));
                    Some((l.height_m, b.window_mmhg, pass, label))
                })
                .collect()
        })
        .unwrap_or_default();
    if r.regions.is_empty() && windows.is_empty() {
        out.push_str("<p class=\"note\">No landmark band to plot.</p>\n");
        return out;
    }
    out.push_str(
        "<p>Mean pressure (dot) and the lowest to highest probe reading (whisker) at each measuring point, \
         against its height above the floor",
    );
    if r.prescription.is_some() {
        out.push_str("; boxes: the prescribed window of each band (green: met, red: not met, grey: not covered)");
    }
    out.push_str(".</p>\n");
    let heights = r
        .regions
        .iter()
        .map(|g| g.height_m)
        .chain(windows.iter().map(|w| w.0));
    let (lo, hi) = heights.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), h| {
        (a.min(h), b.max(h))
    });
    let (y0, y1) = (
        ((lo - 0.05) * 20.0).floor() / 20.0,
        ((hi + 0.05) * 20.0).ceil() / 20.0,
    );
    let pmax = r
        .regions
        .iter()
        .map(|g| g.pressure_mmhg.max.max(g.pressure_mmhg.mean))
        .chain(windows.iter().map(|w| w.1[1]))
        .filter(|v| v.is_finite())
        .fold(10.0, f64::max);
    let x1 = nice_ceiling(pmax);
    // Below 0 only where a probe reads a negative pressure (cloth bridging a hollow, as at the crotch).
    let pmin = r
        .regions
        .iter()
        .map(|g| g.pressure_mmhg.min.min(g.pressure_mmhg.mean))
        .filter(|v| v.is_finite())
        .fold(0.0, f64::min);
    let x0 = if pmin < 0.0 {
        -nice_ceiling(-pmin)
    } else {
        0.0
    };
    let plot_w = WIDTH - LEFT - RIGHT;
    let plot_h = HEIGHT - TOP - BOTTOM;
    let sx = |p: f64| LEFT + plot_w * ((p.clamp(x0, x1) - x0) / (x1 - x0));
    let sy = |h: f64| TOP + plot_h * (1.0 - (h - y0) / (y1 - y0));
    let mut svg = format!(
        "<div class=\"figure\" id=\"height-curve\">\n<svg xmlns=\"http://www.w3.org/2000/svg\" \
         width=\"{WIDTH:.0}\" height=\"{HEIGHT:.0}\" viewBox=\"0 0 {WIDTH:.0} {HEIGHT:.0}\" role=\"img\" \
         aria-label=\"pressure against height\">\n"
    );
    // Grid and axes.
    let xstep = if x1 - x0 <= 50.0 { 5.0 } else { 10.0 };
    let mut p = x0;
    while p <= x1 + 1e-9 {
        let x = sx(p);
        let _ = writeln!(
            svg,
            "<line x1=\"{x:.1}\" y1=\"{TOP:.1}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"#e3e3e3\"/>\
             <text x=\"{x:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"middle\">{p:.0}</text>",
            TOP + plot_h,
            TOP + plot_h + 15.0
        );
        p += xstep;
    }
    let ystep = if y1 - y0 > 0.6 { 0.1 } else { 0.05 };
    let mut h = (y0 / ystep).ceil() * ystep;
    while h <= y1 + 1e-9 {
        let y = sy(h);
        let _ = writeln!(
            svg,
            "<line x1=\"{LEFT:.1}\" y1=\"{y:.1}\" x2=\"{:.1}\" y2=\"{y:.1}\" stroke=\"#e3e3e3\"/>\
             <text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"end\">{:.0}</text>",
            LEFT + plot_w,
            LEFT - 6.0,
            y + 4.0,
            h * 100.0
        );
        h += ystep;
    }
    let _ = writeln!(
        svg,
        "<rect x=\"{LEFT:.1}\" y=\"{TOP:.1}\" width=\"{plot_w:.1}\" height=\"{plot_h:.1}\" fill=\"none\" \
         stroke=\"#444\"/>\n<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"12\" text-anchor=\"middle\">pressure \
         (mmHg)</text>\n<text x=\"14\" y=\"{:.1}\" font-size=\"12\" text-anchor=\"middle\" \
         transform=\"rotate(-90 14 {:.1})\">height above the floor (cm)</text>",
        LEFT + plot_w / 2.0,
        HEIGHT - 8.0,
        TOP + plot_h / 2.0,
        TOP + plot_h / 2.0
    );
    // Prescribed windows.
    for (h, w, pass, label) in &windows {
        let (fill, stroke) = match pass {
            Some(true) => ("#2e9e4a", "#176b2c"),
            Some(false) => ("#d9534f", "#b00020"),
            None => ("#999999", "#666666"),
        };
        let (ya, yb) = (sy(h + BAND_HALF_WIDTH), sy(h - BAND_HALF_WIDTH));
        let _ = writeln!(
            svg,
            "<rect x=\"{:.1}\" y=\"{ya:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"{fill}\" \
             fill-opacity=\"0.25\" stroke=\"{stroke}\" stroke-width=\"0.8\"><title>{}: {:.1}–{:.1} mmHg \
             prescribed</title></rect>",
            sx(w[0]),
            (sx(w[1]) - sx(w[0])).max(1.0),
            (yb - ya).max(1.0),
            escape(label),
            w[0],
            w[1]
        );
    }
    // The curves.
    let mut key = Vec::new();
    for curve in curves(r.regions) {
        let first = curve[0];
        let colour = side_colour(first.side);
        let arm = ARM_LANDMARKS.contains(&first.name.as_str());
        let points: Vec<String> = curve
            .iter()
            .filter(|g| g.pressure_mmhg.mean.is_finite())
            .map(|g| format!("{:.1},{:.1}", sx(g.pressure_mmhg.mean), sy(g.height_m)))
            .collect();
        if points.len() > 1 {
            let _ = writeln!(
                svg,
                "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\"/>",
                points.join(" ")
            );
        }
        for g in &curve {
            let y = sy(g.height_m);
            let q = &g.pressure_mmhg;
            if q.min.is_finite() && q.max.is_finite() {
                let _ = writeln!(
                    svg,
                    "<path d=\"M{a:.1} {y:.1}H{b:.1}M{a:.1} {:.1}V{:.1}M{b:.1} {:.1}V{:.1}\" \
                     stroke=\"{colour}\" stroke-width=\"1\" fill=\"none\"/>",
                    y - 4.0,
                    y + 4.0,
                    y - 4.0,
                    y + 4.0,
                    a = sx(q.min),
                    b = sx(q.max)
                );
            }
            if q.mean.is_finite() {
                let x = sx(q.mean);
                let title = format!(
                    "{} {}: mean {:.1}, {:.1}–{:.1} mmHg",
                    g.name,
                    side_name(g.side),
                    q.mean,
                    q.min,
                    q.max
                );
                if arm {
                    let _ = writeln!(
                        svg,
                        "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"8\" height=\"8\" fill=\"{colour}\"><title>{}</title></rect>",
                        x - 4.0,
                        y - 4.0,
                        escape(&title)
                    );
                } else {
                    let _ = writeln!(
                        svg,
                        "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"4\" fill=\"{colour}\"><title>{}</title></circle>",
                        escape(&title)
                    );
                }
                // Right-limb names left of the whisker, the others right of it, so two legs measured
                // at the same heights keep their names apart.
                let (x, anchor) = if g.side == Some(Side::Right) {
                    (sx(q.min.min(q.mean)) - 6.0, "end")
                } else {
                    (sx(q.max.max(q.mean)) + 6.0, "start")
                };
                let _ = writeln!(
                    svg,
                    "<text x=\"{x:.1}\" y=\"{:.1}\" font-size=\"10\" fill=\"{colour}\" \
                     text-anchor=\"{anchor}\">{}</text>",
                    y + 3.5,
                    escape(&g.name)
                );
            }
        }
        let limb = match (arm, first.side) {
            (_, None) => "torso".to_string(),
            (true, Some(s)) => format!("{} arm", s.name()),
            (false, Some(s)) => format!("{} leg", s.name()),
        };
        key.push((colour, limb));
    }
    // Key.
    let kx = LEFT + plot_w + 12.0;
    for (i, (colour, limb)) in key.iter().enumerate() {
        let y = TOP + 12.0 + 18.0 * i as f64;
        let _ = writeln!(
            svg,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"4\" fill=\"{colour}\"/><text x=\"{:.1}\" y=\"{:.1}\" \
             font-size=\"11\">{}</text>",
            kx + 4.0,
            y,
            kx + 14.0,
            y + 4.0,
            escape(limb)
        );
    }
    if !windows.is_empty() {
        let y = TOP + 12.0 + 18.0 * key.len() as f64;
        let _ = writeln!(
            svg,
            "<rect x=\"{kx:.1}\" y=\"{:.1}\" width=\"10\" height=\"8\" fill=\"#2e9e4a\" fill-opacity=\"0.25\" \
             stroke=\"#176b2c\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\">prescribed</text>",
            y - 4.0,
            kx + 14.0,
            y + 4.0
        );
    }
    svg.push_str("</svg>\n</div>\n");
    out.push_str(&svg);
    out
}
