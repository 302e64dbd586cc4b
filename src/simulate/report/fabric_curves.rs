//! The report's fabric section (issue 46): which fabric the garment is made of and, for a fabric given by
//! its test curves (`garment.fabric.curves` or a library fabric `garment.fabric.name`), its course, wale
//! and shear curves as a plot — tension per unit rest width (N/m) against elongation (%) — with the course
//! stretch the garment is worn at marked on the course curve.
//!
//! The curves drawn are the law the solver uses: each curve's monotone cubic Hermite interpolant
//! (`skintight_physics::tension_curve`), sampled at [`SAMPLES`] points from 0 to its last point; the given
//! points are dots. The worn course stretch is read per cloth triangle as the admissibility check reads it
//! (`|F g⊥|`, [`crate::simulate::admissibility::triangle_measures`]): the median and the 95th percentile
//! over the triangles (by rest area), and the largest. The same plot function draws the library's curves
//! for the documentation (`docs/fabrics/*.svg`, checked against the library by a test).

use std::fmt::Write;

use skintight_physics::tension_curve::TensionCurve;

use super::html::escape;
use crate::scene::{FabricCurves, FabricSpec, fabric_library};

const WIDTH: f64 = 600.0;
const HEIGHT: f64 = 340.0;
const LEFT: f64 = 60.0;
const RIGHT: f64 = 130.0;
const TOP: f64 = 15.0;
const BOTTOM: f64 = 45.0;
/// Points of each drawn curve.
pub const SAMPLES: usize = 60;

/// The course stretch a garment is worn at (dimensionless, 1 = unstretched).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WornCourse {
    /// Median over the cloth's rest area.
    pub median: f64,
    /// 95th percentile over the cloth's rest area.
    pub p95: f64,
    /// Largest.
    pub max: f64,
}

impl WornCourse {
    /// From per-triangle course stretches and rest areas (m²); `None` when no triangle has a finite
    /// stretch.
    pub fn from_triangles(stretch: &[f64], area: &[f64]) -> Option<Self> {
        let mut pairs: Vec<(f64, f64)> = stretch
            .iter()
            .zip(area)
            .filter(|(s, a)| s.is_finite() && a.is_finite() && **a > 0.0)
            .map(|(s, a)| (*s, *a))
            .collect();
        if pairs.is_empty() {
            return None;
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let total: f64 = pairs.iter().map(|p| p.1).sum();
        let quantile = |q: f64| {
            let mut acc = 0.0;
            for &(s, a) in &pairs {
                acc += a;
                if acc >= q * total {
                    return s;
                }
            }
            pairs[pairs.len() - 1].0
        };
        Some(Self {
            median: quantile(0.5),
            p95: quantile(0.95),
            max: pairs[pairs.len() - 1].0,
        })
    }
}

/// A fabric's name for a person: the library name, `test curves` or the isotropic moduli.
pub fn fabric_label(fabric: &FabricSpec) -> String {
    if let Some(name) = &fabric.name {
        let what = fabric_library::named_fabric(name)
            .map(|f| format!(" — {}", f.description))
            .unwrap_or_default();
        format!("{name}{what}")
    } else if fabric.curves.is_some() {
        "the order's test curves".into()
    } else {
        format!(
            "isotropic membrane, E = {:.3} MPa, ν = {:.2}",
            fabric.youngs_modulus() / 1e6,
            fabric.poisson_ratio()
        )
    }
}

/// A curve's monotone interpolant, or `None` for a curve the solver would refuse (never one of a
/// validated scene).
fn law(points: &[[f64; 2]]) -> Option<TensionCurve> {
    TensionCurve::new(points).ok()
}

/// A "nice" step for an axis from 0 to `v` with about five ticks.
fn nice_step(v: f64) -> f64 {
    let raw = (v / 5.0).max(1e-12);
    let magnitude = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * magnitude)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * magnitude)
}

/// The plot of `curves` (SVG, self-contained) with an optional worn course stretch; `title` is drawn
/// above the key.
pub fn curves_svg(title: &str, curves: &FabricCurves, worn: Option<WornCourse>) -> String {
    let series: [(&str, &[[f64; 2]], &str, &str); 3] = [
        ("course", &curves.course, "#1f5fa8", ""),
        ("wale", &curves.wale, "#b5651d", ""),
        (
            "shear",
            &curves.shear,
            "#2e8b57",
            " stroke-dasharray=\"5 3\"",
        ),
    ];
    let x_end = series
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p[0]))
        .chain(worn.map(|w| w.max - 1.0))
        .fold(0.0, f64::max)
        * 100.0;
    let y_end = series
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p[1]))
        .fold(0.0, f64::max);
    let (xs, ys) = (nice_step(x_end), nice_step(y_end));
    let (x_max, y_max) = ((x_end / xs).ceil() * xs, (y_end / ys).ceil() * ys);
    let (pw, ph) = (WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM);
    let px = |e_percent: f64| LEFT + pw * e_percent / x_max;
    let py = |t: f64| TOP + ph * (1.0 - t / y_max);
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{WIDTH}\" height=\"{HEIGHT}\" \
         viewBox=\"0 0 {WIDTH} {HEIGHT}\" role=\"img\" aria-label=\"{}\">\n\
         <rect x=\"0\" y=\"0\" width=\"{WIDTH}\" height=\"{HEIGHT}\" fill=\"#ffffff\"/>\n",
        escape(&format!("Fabric curves: {title}"))
    );
    let mut k = 0.0;
    while k <= x_max + 1e-9 {
        let x = px(k);
        let _ = writeln!(
            svg,
            "<line x1=\"{x:.1}\" y1=\"{TOP}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"#e4e4e4\"/>\
             <text x=\"{x:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"middle\">{k:.0}</text>",
            TOP + ph,
            TOP + ph + 14.0
        );
        k += xs;
    }
    let mut k = 0.0;
    while k <= y_max + 1e-9 {
        let y = py(k);
        let _ = writeln!(
            svg,
            "<line x1=\"{LEFT}\" y1=\"{y:.1}\" x2=\"{:.1}\" y2=\"{y:.1}\" stroke=\"#e4e4e4\"/>\
             <text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"end\">{k:.0}</text>",
            LEFT + pw,
            LEFT - 5.0,
            y + 4.0
        );
        k += ys;
    }
    let _ = writeln!(
        svg,
        "<rect x=\"{LEFT}\" y=\"{TOP}\" width=\"{pw:.1}\" height=\"{ph:.1}\" fill=\"none\" stroke=\"#444\"/>\n\
         <text x=\"{:.1}\" y=\"{:.1}\" font-size=\"12\" text-anchor=\"middle\">elongation (%; shear: \
         shear strain × 100)</text>\n<text x=\"14\" y=\"{:.1}\" font-size=\"12\" text-anchor=\"middle\" \
         transform=\"rotate(-90 14 {:.1})\">tension (N/m)</text>",
        LEFT + pw / 2.0,
        HEIGHT - 8.0,
        TOP + ph / 2.0,
        TOP + ph / 2.0
    );
    for (i, (name, points, colour, dash)) in series.iter().enumerate() {
        let Some(curve) = law(points) else { continue };
        let end = curve.max_elongation();
        let line: Vec<String> = (0..=SAMPLES)
            .map(|j| {
                let e = end * j as f64 / SAMPLES as f64;
                format!("{:.1},{:.1}", px(100.0 * e), py(curve.tension(e)))
            })
            .collect();
        let _ = writeln!(
            svg,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.8\"{dash}/>",
            line.join(" ")
        );
        for p in points.iter() {
            let _ = writeln!(
                svg,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2.5\" fill=\"{colour}\"/>",
                px(100.0 * p[0]),
                py(p[1])
            );
        }
        let ky = TOP + 16.0 * (i as f64 + 1.5);
        let _ = writeln!(
            svg,
            "<line x1=\"{:.1}\" y1=\"{ky:.1}\" x2=\"{:.1}\" y2=\"{ky:.1}\" stroke=\"{colour}\" \
             stroke-width=\"1.8\"{dash}/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\">{name}</text>",
            LEFT + pw + 10.0,
            LEFT + pw + 30.0,
            LEFT + pw + 35.0,
            ky + 4.0
        );
    }
    let _ = writeln!(
        svg,
        "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\" font-weight=\"bold\">{}</text>",
        LEFT + pw + 10.0,
        TOP + 10.0,
        escape(title)
    );
    if let (Some(w), Some(course)) = (worn, law(&curves.course)) {
        // The worn course stretch on the course curve: a band from the median to the 95th percentile,
        // a dot at each, a tick at the largest.
        let (e50, e95, emax) = (w.median - 1.0, w.p95 - 1.0, w.max - 1.0);
        let _ = writeln!(
            svg,
            "<rect x=\"{:.1}\" y=\"{TOP}\" width=\"{:.1}\" height=\"{ph:.1}\" fill=\"#1f5fa8\" \
             fill-opacity=\"0.12\"/>",
            px(100.0 * e50.max(0.0)),
            (px(100.0 * e95.max(0.0)) - px(100.0 * e50.max(0.0))).max(1.0)
        );
        for (e, label) in [(e50, "median"), (e95, "95 %")] {
            if e > 0.0 {
                let _ = writeln!(
                    svg,
                    "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"4\" fill=\"none\" stroke=\"#b00020\" \
                     stroke-width=\"1.5\"><title>worn course stretch, {label}: {:.0} % at {:.0} N/m\
                     </title></circle>",
                    px(100.0 * e),
                    py(course.tension(e)),
                    100.0 * e,
                    course.tension(e)
                );
            }
        }
        let _ = writeln!(
            svg,
            "<line x1=\"{x:.1}\" y1=\"{TOP}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"#b00020\" \
             stroke-dasharray=\"2 2\"/>\n<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\" fill=\"#b00020\">worn \
             course</text><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\" fill=\"#b00020\">(band: median–95 %,</text>\
             <text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\" fill=\"#b00020\">dashes: largest)</text>",
            TOP + ph,
            LEFT + pw + 10.0,
            TOP + 16.0 * 5.5,
            LEFT + pw + 10.0,
            TOP + 16.0 * 6.5,
            LEFT + pw + 10.0,
            TOP + 16.0 * 7.5,
            x = px(100.0 * emax.max(0.0)),
        );
    }
    svg.push_str("</svg>\n");
    svg
}

/// The report's fabric section.
pub fn section(fabric: &FabricSpec, worn: Option<WornCourse>) -> String {
    let mut out = String::from("<h2>Fabric</h2>\n");
    let _ = writeln!(
        out,
        "<p>Made of <strong>{}</strong>.</p>",
        escape(&fabric_label(fabric))
    );
    let stretch = |s: f64| format!("{:.0} %", 100.0 * (s - 1.0));
    match (fabric.resolved_curves(), worn) {
        (Some((curves, _)), worn) => {
            if let Some(w) = worn {
                let t = law(&curves.course).map(|c| {
                    (
                        c.tension((w.median - 1.0).max(0.0)),
                        c.tension((w.p95 - 1.0).max(0.0)),
                    )
                });
                let _ = write!(
                    out,
                    "<p>Worn course stretch (around the limb): median {}, 95th percentile {}, largest {} \
                     (the course curve ends at {})",
                    stretch(w.median),
                    stretch(w.p95),
                    stretch(w.max),
                    stretch(1.0 + curves.course.iter().map(|p| p[0]).fold(0.0, f64::max)),
                );
                if let Some((t50, t95)) = t {
                    let _ = write!(
                        out,
                        "; the course curve gives {t50:.0} N/m at the median and {t95:.0} N/m at the 95th \
                         percentile"
                    );
                }
                out.push_str(".</p>\n");
            }
            let _ = writeln!(
                out,
                "<div class=\"figure\" id=\"fabric-curves\">\n{}</div>\n<p class=\"note\">Tension per unit \
                 rest width against elongation, as the solver reads each curve (monotone cubic \
                 interpolation through the given points, the dots); N per 5 cm strip × 20 = N/m.</p>",
                curves_svg(
                    fabric.name.as_deref().unwrap_or("test curves"),
                    &curves,
                    worn
                )
            );
        }
        (None, Some(w)) => {
            let _ = writeln!(
                out,
                "<p>Worn course stretch (around the limb): median {}, 95th percentile {}, largest {}.</p>",
                stretch(w.median),
                stretch(w.p95),
                stretch(w.max)
            );
        }
        (None, None) => {}
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The library's plots in the documentation are these functions' output: regenerate them with
    /// `SKINTIGHT_WRITE_FABRIC_PLOTS=1 cargo test --lib fabric_curves`.
    #[test]
    fn docs_plots_are_the_library_curves() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/fabrics");
        let write = std::env::var_os("SKINTIGHT_WRITE_FABRIC_PLOTS").is_some();
        for name in fabric_library::fabric_names() {
            let f = fabric_library::named_fabric(name).unwrap();
            let svg = curves_svg(name, &f.curves, None);
            let path = dir.join(format!("{name}.svg"));
            if write {
                std::fs::create_dir_all(&dir).unwrap();
                std::fs::write(&path, &svg).unwrap();
            }
            let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
            assert!(
                on_disk == svg,
                "{} is not the plot of fabrics/{name}.json: regenerate with \
                 SKINTIGHT_WRITE_FABRIC_PLOTS=1 cargo test --lib fabric_curves",
                path.display()
            );
        }
    }

    #[test]
    fn the_plot_draws_every_curve_and_the_worn_stretch_on_the_course_curve() {
        let f = fabric_library::named_fabric("power_net_class2").unwrap();
        let worn = WornCourse {
            median: 1.4,
            p95: 1.5,
            max: 1.6,
        };
        let svg = curves_svg("power_net_class2", &f.curves, Some(worn));
        assert_eq!(svg.matches("<polyline").count(), 3);
        let dots = f.curves.course.len() + f.curves.wale.len() + f.curves.shear.len();
        // The given points and the two worn markers.
        assert_eq!(svg.matches("<circle").count(), dots + 2);
        // The median marker sits on the course curve's tension at 40 % (140 N/m, a given point).
        assert!(svg.contains("median: 40 % at 140 N/m"), "{svg}");
        let fabric: FabricSpec =
            serde_json::from_value(serde_json::json!({"name": "power_net_class2"})).unwrap();
        let html = section(&fabric, Some(worn));
        assert!(html.contains("power_net_class2"));
        assert!(html.contains("median 40 %"), "{html}");
        assert!(html.contains("140 N/m at the median"), "{html}");
        // An isotropic fabric: named by its moduli, the worn stretch in words, no plot.
        let html = section(&FabricSpec::default(), Some(worn));
        assert!(html.contains("E = 5.400 MPa"), "{html}");
        assert!(!html.contains("<svg"));
    }

    #[test]
    fn worn_course_quantiles_weigh_by_area() {
        let w =
            WornCourse::from_triangles(&[1.1, 1.2, 1.3, f64::NAN], &[1.0, 1.0, 8.0, 1.0]).unwrap();
        assert_eq!((w.median, w.p95, w.max), (1.3, 1.3, 1.3));
        let w = WornCourse::from_triangles(&[1.3, 1.1, 1.2], &[1.0, 1.0, 1.0]).unwrap();
        assert_eq!((w.median, w.p95, w.max), (1.2, 1.3, 1.3));
        assert!(WornCourse::from_triangles(&[f64::NAN], &[1.0]).is_none());
    }
}
