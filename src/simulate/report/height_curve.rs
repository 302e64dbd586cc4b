//! The report's pressure-by-height curve: at each landmark band the garment covers, the mean interface
//! pressure (a dot) and the lowest and highest probe reading (a whisker), mmHg against the landmark's
//! height above the floor (cm), one line per limb from the bottom up; with a prescription, each prescribed
//! band's window drawn as a box across its height (green where the band passes, red where it fails, grey
//! where the garment does not reach it).
//!
//! The figure's data ([`HeightCurve`]: the windows, the limbs' curves and the axes' ranges) is computed
//! first, then written as SVG text, one method per layer (grid, windows, curves, key).

use std::fmt::Write;

use skintight_geometry::anthropometry::Side;

use super::Report;
use super::html::escape;
use super::measurements::side_name;
use crate::simulate::regions::{BAND_HALF_WIDTH, LandmarkBand};
use skintight_geometry::anthropometry::landmarks::ARM_LANDMARKS;

const WIDTH: f64 = 600.0;
const HEIGHT: f64 = 380.0;
const LEFT: f64 = 60.0;
const RIGHT: f64 = 150.0;
const TOP: f64 = 15.0;
const BOTTOM: f64 = 45.0;

/// A limb: whether an arm, and its side (`None`: the torso).
type Limb = (bool, Option<Side>);

/// A "nice" upper end of an axis from 0 to at least `v`.
fn nice_ceiling(v: f64) -> f64 {
    let step = if v <= 50.0 { 10.0 } else { 20.0 };
    ((v / step).ceil() * step).max(step)
}

/// A prescribed band's window at its landmark's height.
struct Window {
    /// Height of the landmark above the floor (m).
    height_m: f64,
    /// The prescribed window (mmHg).
    window_mmhg: [f64; 2],
    /// Whether the band passes; `None` where the garment does not cover it.
    pass: Option<bool>,
    /// The band's name and side.
    label: String,
}

/// One limb's curve: its bands by height.
struct Curve<'a> {
    arm: bool,
    side: Option<Side>,
    bands: Vec<&'a LandmarkBand>,
}

impl Curve<'_> {
    /// The curve's colour, by the limb's side.
    fn colour(&self) -> &'static str {
        match self.side {
            Some(Side::Left) => "#1f5fa8",
            Some(Side::Right) => "#8e44ad",
            None => "#333333",
        }
    }

    /// The limb's name in the key.
    fn limb(&self) -> String {
        match (self.arm, self.side) {
            (_, None) => "torso".to_string(),
            (true, Some(s)) => format!("{} arm", s.name()),
            (false, Some(s)) => format!("{} leg", s.name()),
        }
    }
}

/// The limbs' curves: the bands grouped by limb (leg, arm or torso, and side), each by height.
fn curves(regions: &[LandmarkBand]) -> Vec<Curve<'_>> {
    let mut groups: Vec<(Limb, Vec<&LandmarkBand>)> = Vec::new();
    for g in regions {
        let key = (ARM_LANDMARKS.contains(&g.name.as_str()), g.side);
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, v)) => v.push(g),
            None => groups.push((key, vec![g])),
        }
    }
    groups
        .into_iter()
        .map(|(_, mut bands)| {
            bands.sort_by(|a, b| a.height_m.total_cmp(&b.height_m));
            // The limb as its lowest band's name and side say.
            let first = bands[0];
            Curve {
                arm: ARM_LANDMARKS.contains(&first.name.as_str()),
                side: first.side,
                bands,
            }
        })
        .collect()
}

/// The plotted ranges: pressure `x0 … x1` (mmHg) across, height `y0 … y1` (m) up.
struct Axes {
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
}

const PLOT_W: f64 = WIDTH - LEFT - RIGHT;
const PLOT_H: f64 = HEIGHT - TOP - BOTTOM;

impl Axes {
    /// Heights to 5 cm beyond the bands and windows, rounded out to 5 cm; pressures from 0 (or below,
    /// where a probe reads a negative pressure: cloth bridging a hollow, as at the crotch) to a round
    /// number above the highest reading or window, at least 10 mmHg.
    fn of(regions: &[LandmarkBand], windows: &[Window]) -> Self {
        let heights = regions
            .iter()
            .map(|g| g.height_m)
            .chain(windows.iter().map(|w| w.height_m));
        let (lo, hi) = heights.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), h| {
            (a.min(h), b.max(h))
        });
        let pmax = regions
            .iter()
            .map(|g| g.pressure_mmhg.max.max(g.pressure_mmhg.mean))
            .chain(windows.iter().map(|w| w.window_mmhg[1]))
            .filter(|v| v.is_finite())
            .fold(10.0, f64::max);
        let pmin = regions
            .iter()
            .map(|g| g.pressure_mmhg.min.min(g.pressure_mmhg.mean))
            .filter(|v| v.is_finite())
            .fold(0.0, f64::min);
        Self {
            x0: if pmin < 0.0 {
                -nice_ceiling(-pmin)
            } else {
                0.0
            },
            x1: nice_ceiling(pmax),
            y0: ((lo - 0.05) * 20.0).floor() / 20.0,
            y1: ((hi + 0.05) * 20.0).ceil() / 20.0,
        }
    }

    /// The figure's x (px) of pressure `p` (mmHg), clamped to the plot.
    fn x(&self, p: f64) -> f64 {
        LEFT + PLOT_W * ((p.clamp(self.x0, self.x1) - self.x0) / (self.x1 - self.x0))
    }

    /// The figure's y (px) of height `h` (m).
    fn y(&self, h: f64) -> f64 {
        TOP + PLOT_H * (1.0 - (h - self.y0) / (self.y1 - self.y0))
    }
}

/// The figure's data: the prescribed windows, the limbs' curves and the ranges they are drawn in.
struct HeightCurve<'a> {
    windows: Vec<Window>,
    curves: Vec<Curve<'a>>,
    axes: Axes,
}

impl<'a> HeightCurve<'a> {
    /// The figure of `r`, or `None` with no band and no prescribed window to plot.
    fn of(r: &Report<'a>) -> Option<Self> {
        // Prescribed windows with their heights (from the landmarks).
        let windows: Vec<Window> = r
            .prescription
            .map(|p| {
                p.bands
                    .iter()
                    .filter_map(|b| {
                        let l = r
                            .landmarks
                            .iter()
                            .find(|l| l.name == b.name && l.side == b.side)?;
                        Some(Window {
                            height_m: l.height_m,
                            window_mmhg: b.window_mmhg,
                            pass: b.measured_mmhg.map(|_| b.pass),
                            label: format!("{} {}", b.name, side_name(b.side)),
                        })
                    })
                    .collect()
            })
            .unwrap_or_default();
        if r.regions.is_empty() && windows.is_empty() {
            return None;
        }
        let axes = Axes::of(r.regions, &windows);
        Some(Self {
            windows,
            curves: curves(r.regions),
            axes,
        })
    }

    /// The figure as an SVG element in its `div`.
    fn svg(&self) -> String {
        let mut svg = format!(
            "<div class=\"figure\" id=\"height-curve\">\n<svg xmlns=\"http://www.w3.org/2000/svg\" \
             width=\"{WIDTH:.0}\" height=\"{HEIGHT:.0}\" viewBox=\"0 0 {WIDTH:.0} {HEIGHT:.0}\" role=\"img\" \
             aria-label=\"pressure against height\">\n"
        );
        self.grid(&mut svg);
        for w in &self.windows {
            self.window(w, &mut svg);
        }
        for c in &self.curves {
            self.curve(c, &mut svg);
        }
        self.key(&mut svg);
        svg.push_str("</svg>\n</div>\n");
        svg
    }

    /// The grid lines with their numbers, the plot's frame and the axis titles.
    fn grid(&self, svg: &mut String) {
        let Axes { x0, x1, y0, y1 } = self.axes;
        let xstep = if x1 - x0 <= 50.0 { 5.0 } else { 10.0 };
        let mut p = x0;
        while p <= x1 + 1e-9 {
            let x = self.axes.x(p);
            let _ = writeln!(
                svg,
                "<line x1=\"{x:.1}\" y1=\"{TOP:.1}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"#e3e3e3\"/>\
                 <text x=\"{x:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"middle\">{p:.0}</text>",
                TOP + PLOT_H,
                TOP + PLOT_H + 15.0
            );
            p += xstep;
        }
        let ystep = if y1 - y0 > 0.6 { 0.1 } else { 0.05 };
        let mut h = (y0 / ystep).ceil() * ystep;
        while h <= y1 + 1e-9 {
            let y = self.axes.y(h);
            let _ = writeln!(
                svg,
                "<line x1=\"{LEFT:.1}\" y1=\"{y:.1}\" x2=\"{:.1}\" y2=\"{y:.1}\" stroke=\"#e3e3e3\"/>\
                 <text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"end\">{:.0}</text>",
                LEFT + PLOT_W,
                LEFT - 6.0,
                y + 4.0,
                h * 100.0
            );
            h += ystep;
        }
        let _ = writeln!(
            svg,
            "<rect x=\"{LEFT:.1}\" y=\"{TOP:.1}\" width=\"{PLOT_W:.1}\" height=\"{PLOT_H:.1}\" fill=\"none\" \
             stroke=\"#444\"/>\n<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"12\" text-anchor=\"middle\">pressure \
             (mmHg)</text>\n<text x=\"14\" y=\"{:.1}\" font-size=\"12\" text-anchor=\"middle\" \
             transform=\"rotate(-90 14 {:.1})\">height above the floor (cm)</text>",
            LEFT + PLOT_W / 2.0,
            HEIGHT - 8.0,
            TOP + PLOT_H / 2.0,
            TOP + PLOT_H / 2.0
        );
    }

    /// A prescribed window: a box across its band's height, coloured by the verdict.
    fn window(&self, w: &Window, svg: &mut String) {
        let (fill, stroke) = match w.pass {
            Some(true) => ("#2e9e4a", "#176b2c"),
            Some(false) => ("#d9534f", "#b00020"),
            None => ("#999999", "#666666"),
        };
        let (h, [lo, hi]) = (w.height_m, w.window_mmhg);
        let (ya, yb) = (
            self.axes.y(h + BAND_HALF_WIDTH),
            self.axes.y(h - BAND_HALF_WIDTH),
        );
        let _ = writeln!(
            svg,
            "<rect x=\"{:.1}\" y=\"{ya:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"{fill}\" \
             fill-opacity=\"0.25\" stroke=\"{stroke}\" stroke-width=\"0.8\"><title>{}: {:.1}–{:.1} mmHg \
             prescribed</title></rect>",
            self.axes.x(lo),
            (self.axes.x(hi) - self.axes.x(lo)).max(1.0),
            (yb - ya).max(1.0),
            escape(&w.label),
            lo,
            hi
        );
    }

    /// A limb's curve: the line through its means, and each band's whisker, dot (a square on an arm)
    /// and name.
    fn curve(&self, c: &Curve, svg: &mut String) {
        let colour = c.colour();
        let points: Vec<String> = c
            .bands
            .iter()
            .filter(|g| g.pressure_mmhg.mean.is_finite())
            .map(|g| {
                format!(
                    "{:.1},{:.1}",
                    self.axes.x(g.pressure_mmhg.mean),
                    self.axes.y(g.height_m)
                )
            })
            .collect();
        if points.len() > 1 {
            let _ = writeln!(
                svg,
                "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\"/>",
                points.join(" ")
            );
        }
        for g in &c.bands {
            let y = self.axes.y(g.height_m);
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
                    a = self.axes.x(q.min),
                    b = self.axes.x(q.max)
                );
            }
            if q.mean.is_finite() {
                self.dot(c, g, svg);
            }
        }
    }

    /// The mean of band `g` on curve `c` as a dot with its figures in a tooltip, and the band's name.
    fn dot(&self, c: &Curve, g: &LandmarkBand, svg: &mut String) {
        let colour = c.colour();
        let (q, y) = (&g.pressure_mmhg, self.axes.y(g.height_m));
        let x = self.axes.x(q.mean);
        let title = format!(
            "{} {}: mean {:.1}, {:.1}–{:.1} mmHg",
            g.name,
            side_name(g.side),
            q.mean,
            q.min,
            q.max
        );
        if c.arm {
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
        // Right-limb names left of the whisker, the others right of it, so two legs measured at the same
        // heights keep their names apart.
        let (x, anchor) = if g.side == Some(Side::Right) {
            (self.axes.x(q.min.min(q.mean)) - 6.0, "end")
        } else {
            (self.axes.x(q.max.max(q.mean)) + 6.0, "start")
        };
        let _ = writeln!(
            svg,
            "<text x=\"{x:.1}\" y=\"{:.1}\" font-size=\"10\" fill=\"{colour}\" \
             text-anchor=\"{anchor}\">{}</text>",
            y + 3.5,
            escape(&g.name)
        );
    }

    /// The key: each limb's colour, then the prescribed windows' box where there are any.
    fn key(&self, svg: &mut String) {
        let kx = LEFT + PLOT_W + 12.0;
        for (i, c) in self.curves.iter().enumerate() {
            let y = TOP + 12.0 + 18.0 * i as f64;
            let _ = writeln!(
                svg,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"4\" fill=\"{}\"/><text x=\"{:.1}\" y=\"{:.1}\" \
                 font-size=\"11\">{}</text>",
                kx + 4.0,
                y,
                c.colour(),
                kx + 14.0,
                y + 4.0,
                escape(&c.limb())
            );
        }
        if !self.windows.is_empty() {
            let y = TOP + 12.0 + 18.0 * self.curves.len() as f64;
            let _ = writeln!(
                svg,
                "<rect x=\"{kx:.1}\" y=\"{:.1}\" width=\"10\" height=\"8\" fill=\"#2e9e4a\" fill-opacity=\"0.25\" \
                 stroke=\"#176b2c\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\">prescribed</text>",
                y - 4.0,
                kx + 14.0,
                y + 4.0
            );
        }
    }
}

/// The section: a heading, a caption and the figure ([`HeightCurve`]), or a note when there is nothing
/// to plot.
pub fn section(r: &Report) -> String {
    let mut out = String::from("<h2>Pressure by height</h2>\n");
    let Some(figure) = HeightCurve::of(r) else {
        out.push_str("<p class=\"note\">No landmark band to plot.</p>\n");
        return out;
    };
    out.push_str(
        "<p>Mean pressure (dot) and the lowest to highest probe reading (whisker) at each measuring point, \
         against its height above the floor",
    );
    if r.prescription.is_some() {
        out.push_str("; boxes: the prescribed window of each band (green: met, red: not met, grey: not covered)");
    }
    out.push_str(".</p>\n");
    out.push_str(&figure.svg());
    out
}
