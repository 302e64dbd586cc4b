//! The SVG plot of a stretch test (`skintight knit stretch-test`, `stretch_test.svg`): force (N) against
//! extension (mm), the measured mean curve as a line with the band between the least and greatest
//! per-pull means shaded, the simulated equilibria as a line with dots. Linear axes from 0 to a rounded
//! maximum of both curves, ticks at 1, 2 or 5 × a power of ten.

use skintight_knit::measured_stretch::MeasuredStretch;

/// A "nice" tick step for the range `0 ..= max` with about five ticks.
fn tick_step(max: f64) -> f64 {
    let raw = (max / 5.0).max(1e-12);
    let p = 10f64.powf(raw.log10().floor());
    let m = raw / p;
    let k = if m <= 1.0 {
        1.0
    } else if m <= 2.0 {
        2.0
    } else if m <= 5.0 {
        5.0
    } else {
        10.0
    };
    k * p
}

/// The plot of `measured` and the simulated points `(extension_mm, force_n)` with a title.
pub fn stretch_svg(measured: &MeasuredStretch, simulated: &[(f64, f64)], title: &str) -> String {
    let (w, h) = (640.0, 440.0);
    let (l, r, t, b) = (70.0, 20.0, 40.0, 55.0);
    let emax = measured
        .extension
        .iter()
        .map(|e| e * 1e3)
        .chain(simulated.iter().map(|p| p.0))
        .fold(0.0f64, f64::max);
    let fmax = measured
        .force_max
        .iter()
        .copied()
        .chain(simulated.iter().map(|p| p.1))
        .filter(|f| f.is_finite())
        .fold(0.0f64, f64::max);
    let (xs, ys) = (tick_step(emax), tick_step(fmax));
    let (xtop, ytop) = (
        (emax / xs).ceil().max(1.0) * xs,
        (fmax / ys).ceil().max(1.0) * ys,
    );
    let px = |e: f64| l + (w - l - r) * e / xtop;
    let py = |f: f64| h - b - (h - t - b) * f.max(0.0).min(ytop) / ytop;
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" \
         font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n"
    );
    s.push_str(&format!(
        "<text x=\"{}\" y=\"22\" text-anchor=\"middle\" font-size=\"14\">{}</text>\n",
        w / 2.0,
        escape(title)
    ));
    // axes and ticks
    let mut k = 0.0;
    while k <= xtop + 1e-9 * xtop {
        s.push_str(&format!(
            "<line x1=\"{0:.1}\" y1=\"{1}\" x2=\"{0:.1}\" y2=\"{2}\" stroke=\"#ddd\"/>\
             <text x=\"{0:.1}\" y=\"{3}\" text-anchor=\"middle\">{4}</text>\n",
            px(k),
            t,
            h - b,
            h - b + 16.0,
            fmt_tick(k)
        ));
        k += xs;
    }
    let mut k = 0.0;
    while k <= ytop + 1e-9 * ytop {
        s.push_str(&format!(
            "<line x1=\"{0}\" y1=\"{1:.1}\" x2=\"{2}\" y2=\"{1:.1}\" stroke=\"#ddd\"/>\
             <text x=\"{3}\" y=\"{4:.1}\" text-anchor=\"end\">{5}</text>\n",
            l,
            py(k),
            w - r,
            l - 6.0,
            py(k) + 4.0,
            fmt_tick(k)
        ));
        k += ys;
    }
    s.push_str(&format!(
        "<rect x=\"{l}\" y=\"{t}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"black\"/>\n\
         <text x=\"{}\" y=\"{}\" text-anchor=\"middle\">extension (mm)</text>\n\
         <text x=\"18\" y=\"{}\" text-anchor=\"middle\" transform=\"rotate(-90 18 {})\">force (N)</text>\n",
        w - l - r,
        h - t - b,
        (l + w - r) / 2.0,
        h - 12.0,
        (t + h - b) / 2.0,
        (t + h - b) / 2.0
    ));
    // measured band and line
    let mut band: Vec<String> = measured
        .extension
        .iter()
        .zip(&measured.force_max)
        .map(|(e, f)| format!("{:.1},{:.1}", px(e * 1e3), py(*f)))
        .collect();
    band.extend(
        measured
            .extension
            .iter()
            .zip(&measured.force_min)
            .rev()
            .map(|(e, f)| format!("{:.1},{:.1}", px(e * 1e3), py(*f))),
    );
    s.push_str(&format!(
        "<polygon points=\"{}\" fill=\"#1f77b4\" fill-opacity=\"0.2\" stroke=\"none\"/>\n",
        band.join(" ")
    ));
    let line: Vec<String> = measured
        .extension
        .iter()
        .zip(&measured.force)
        .map(|(e, f)| format!("{:.1},{:.1}", px(e * 1e3), py(*f)))
        .collect();
    s.push_str(&format!(
        "<polyline points=\"{}\" fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"2\"/>\n",
        line.join(" ")
    ));
    let sim: Vec<String> = simulated
        .iter()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .map(|(e, f)| format!("{:.1},{:.1}", px(*e), py(*f)))
        .collect();
    s.push_str(&format!(
        "<polyline points=\"{}\" fill=\"none\" stroke=\"#d62728\" stroke-width=\"2\"/>\n",
        sim.join(" ")
    ));
    for p in &sim {
        let (x, y) = p.split_once(',').unwrap_or(("0", "0"));
        s.push_str(&format!(
            "<circle cx=\"{x}\" cy=\"{y}\" r=\"3\" fill=\"#d62728\"/>\n"
        ));
    }
    // legend
    s.push_str(&format!(
        "<line x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\" stroke=\"#1f77b4\" stroke-width=\"2\"/>\
         <text x=\"{3}\" y=\"{4}\">measured (mean, range of pulls)</text>\n\
         <line x1=\"{0}\" y1=\"{5}\" x2=\"{2}\" y2=\"{5}\" stroke=\"#d62728\" stroke-width=\"2\"/>\
         <text x=\"{3}\" y=\"{6}\">yarn-level patch</text>\n",
        l + 12.0,
        t + 16.0,
        l + 36.0,
        l + 42.0,
        t + 20.0,
        t + 34.0,
        t + 38.0
    ));
    s.push_str("</svg>\n");
    s
}

fn fmt_tick(v: f64) -> String {
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn the_plot_holds_both_curves_inside_its_frame() {
        let m = MeasuredStretch::parse(
            "# fabric_width_mm 50\n# clamp_distance_mm 20\n\
             extension_mm,force_n,force_min_n,force_max_n,videos\n1,1,0.5,1.5,4\n2,3,2.5,3.5,4\n",
            Path::new("m.csv"),
        )
        .unwrap();
        let svg = stretch_svg(&m, &[(0.0, 0.0), (1.0, 2.0), (2.5, 7.0)], "a <b> & c");
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>\n"));
        assert!(svg.contains("a &lt;b&gt; &amp; c"));
        assert_eq!(svg.matches("<circle").count(), 3);
        assert_eq!(svg.matches("<polyline").count(), 2);
        // every drawn point lies in the frame [70, 620] × [40, 385]
        for c in svg.split("<circle cx=\"").skip(1) {
            let x: f64 = c.split('"').next().unwrap().parse().unwrap();
            let y: f64 = c
                .split("cy=\"")
                .nth(1)
                .unwrap()
                .split('"')
                .next()
                .unwrap()
                .parse()
                .unwrap();
            assert!(
                (70.0..=620.0).contains(&x) && (40.0..=385.0).contains(&y),
                "{x} {y}"
            );
        }
        assert_eq!(tick_step(7.0), 2.0);
        assert_eq!(tick_step(30.0), 10.0);
        assert!((tick_step(0.4) - 0.1).abs() < 1e-12);
    }
}
