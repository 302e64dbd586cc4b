//! The report's verdict: whether the worn garment stays within its fabric's limits (`admissible`), each
//! broken limit in plain words (`violations`), and — when the order carries a prescription — the
//! compression class at the ankle and the window of every prescribed band, met or not, with each band's
//! peak probe reading flagged above the fabric's limit or above its window (`prescription`). The headline
//! says what failed: the fabric's limits, the equilibrium, the prescription, or several.

use super::Report;
use super::html::{Digits, escape, num, num_td, value_field};
use super::measurements::side_name;
use crate::simulate::admissibility::Violation;
use crate::simulate::result::PA_PER_MMHG;

/// What a violation's kind means, for a fitter.
fn kind_words(kind: &str) -> &'static str {
    match kind {
        "stretch_wale" => "Stretch along the grain (wales)",
        "stretch_course" => "Stretch across the grain (courses)",
        "pressure" => "Interface pressure (5 cm probe)",
        "pattern_quality" => "Pattern triangle shape quality",
        "not_converged" => "The simulation did not reach equilibrium (relative force residual)",
        "prescription" => "Prescribed band pressure (band mean)",
        _ => "Limit",
    }
}

/// Which way a violation's limit bounds its value, and what the limit is (`allowed` of the fabric,
/// `prescribed` of a band): a band below its window was asked for at least its window's low end.
fn bound_words(v: &Violation) -> (&'static str, &'static str) {
    match v.kind.as_str() {
        "pattern_quality" => ("at least", "allowed"),
        "prescription" if v.value < v.limit => ("at least", "prescribed"),
        "prescription" => ("at most", "prescribed"),
        _ => ("at most", "allowed"),
    }
}

/// The verdict's headline: what failed, by kind — the fabric's limits (stretch, pressure, pattern), the
/// equilibrium, the prescription — so that a garment missing only its prescription is not said to break
/// its fabric's limits.
pub fn headline(violations: &[Violation]) -> (&'static str, String) {
    if violations.is_empty() {
        return ("ok", "Within the fabric's limits".into());
    }
    let has = |f: &dyn Fn(&str) -> bool| violations.iter().any(|v| f(&v.kind));
    let mut failed = Vec::new();
    if has(&|k| k != "prescription" && k != "not_converged") {
        failed.push("NOT within the fabric's limits");
    }
    if has(&|k| k == "not_converged") {
        failed.push("its simulation did NOT reach equilibrium");
    }
    if has(&|k| k == "prescription") {
        failed.push("does NOT meet its prescription");
    }
    let mut text = failed.join("; ");
    if !has(&|k| k != "prescription") {
        text.push_str(" (within the fabric's limits)");
    }
    ("bad", format!("Not admissible: {text}"))
}

/// One violation as a sentence, its numbers marked with their fields (`violations.{i}`).
fn violation(i: usize, v: &Violation) -> String {
    let path = format!("violations.{i}");
    let (scale, digits, unit) = match (v.kind.as_str(), v.unit.as_str()) {
        (_, "Pa") => (1.0 / PA_PER_MMHG, Digits::Fixed(1), " mmHg"),
        (_, "mmHg") => (1.0, Digits::Fixed(1), " mmHg"),
        ("not_converged", _) => (1.0, Digits::Exp(2), ""),
        _ => (1.0, Digits::Fixed(3), ""),
    };
    let (bound, allowed) = bound_words(v);
    let mut s = format!(
        "<li>{}{}: {}{unit} where {bound} {}{unit} is {allowed}",
        value_field(
            "strong",
            &format!("{path}.kind"),
            &v.kind,
            kind_words(&v.kind),
            ""
        ),
        v.panel
            .as_ref()
            .map(|p| format!(" on panel “{}”", escape(p)))
            .unwrap_or_default(),
        num(&format!("{path}.value"), Some(v.value), scale, digits),
        num(&format!("{path}.limit"), Some(v.limit), scale, digits),
    );
    if v.triangles > 0 && v.kind != "not_converged" {
        s.push_str(&format!(
            ", over {} triangles ({} cm²)",
            num(
                &format!("{path}.triangles"),
                Some(v.triangles as f64),
                1.0,
                Digits::Fixed(0)
            ),
            num(
                &format!("{path}.area_m2"),
                Some(v.area_m2),
                1e4,
                Digits::Fixed(1)
            ),
        ));
    }
    s.push_str(&format!(
        ". <span class=\"note\">{}</span></li>\n",
        escape(&v.location)
    ));
    s
}

/// The section.
pub fn section(r: &Report) -> String {
    let a = r.admissibility;
    let mut out = String::from("<h2>Verdict</h2>\n");
    let (class, text) = headline(&a.violations);
    out.push_str(&format!(
        "<p id=\"admissible\">{}</p>\n",
        value_field(
            "span",
            "admissible",
            &a.admissible.to_string(),
            &text,
            class
        )
    ));
    out.push_str(&format!(
        "<p class=\"note\">Limits: stretch at most {} along the grain and {} across it, a probe pressure of \
         at most {} mmHg, pattern triangle quality at least {}.</p>\n",
        num(
            "limits.max_stretch.wale",
            Some(a.limits.max_stretch.wale),
            1.0,
            Digits::Fixed(2)
        ),
        num(
            "limits.max_stretch.course",
            Some(a.limits.max_stretch.course),
            1.0,
            Digits::Fixed(2)
        ),
        num(
            "limits.max_pressure_pa",
            Some(a.limits.max_pressure_pa),
            1.0 / PA_PER_MMHG,
            Digits::Fixed(1)
        ),
        num(
            "limits.min_pattern_quality",
            Some(a.limits.min_pattern_quality),
            1.0,
            Digits::Fixed(2)
        ),
    ));
    if !a.violations.is_empty() {
        out.push_str("<ul id=\"violations\">\n");
        for (i, v) in a.violations.iter().enumerate() {
            out.push_str(&violation(i, v));
        }
        out.push_str("</ul>\n");
    }
    let Some(p) = r.prescription else {
        out.push_str(
            "<p class=\"note\">No compression prescription was given with this order.</p>\n",
        );
        return out;
    };
    let (class, text) = if p.pass {
        ("ok", "meets its prescription")
    } else {
        ("bad", "does NOT meet its prescription")
    };
    out.push_str(&format!(
        "<h3>Prescription</h3>\n<p id=\"prescription\">{} class {}: the garment {}. At the ankle (B) the \
         class asks {}–{} mmHg; measured {} mmHg.</p>\n",
        value_field(
            "span",
            "prescription.standard",
            &p.standard,
            &p.standard,
            ""
        ),
        num(
            "prescription.class",
            Some(p.class as f64),
            1.0,
            Digits::Fixed(0)
        ),
        value_field("span", "prescription.pass", &p.pass.to_string(), text, class),
        num(
            "prescription.window_mmhg.0",
            Some(p.window_mmhg[0]),
            1.0,
            Digits::Fixed(1)
        ),
        num(
            "prescription.window_mmhg.1",
            Some(p.window_mmhg[1]),
            1.0,
            Digits::Fixed(1)
        ),
        num(
            "prescription.measured_b_mmhg",
            p.measured_b_mmhg,
            1.0,
            Digits::Fixed(1)
        ),
    ));
    out.push_str(
        "<table id=\"prescription-bands\">\n<tr><th class=\"name\">band</th><th class=\"name\">side</th>\
         <th>measured (mmHg)</th><th>window low</th><th>window high</th><th class=\"name\">verdict</th>\
         <th>peak (mmHg)</th><th class=\"name\">peak: above the fabric's limit</th>\
         <th class=\"name\">peak: above the window</th></tr>\n",
    );
    for (i, b) in p.bands.iter().enumerate() {
        let path = format!("prescription.bands.{i}");
        let (class, text) = match (b.measured_mmhg, b.pass) {
            (None, _) => ("bad", "not covered"),
            (Some(_), true) => ("ok", "pass"),
            (Some(_), false) => ("bad", "FAIL"),
        };
        let yes_no = |field: &str, flag: bool, yes: &str, class: &str| {
            value_field(
                "td",
                &format!("{path}.{field}"),
                &flag.to_string(),
                if flag { yes } else { "no" },
                if flag { class } else { "name" },
            )
        };
        out.push_str(&format!(
            "<tr>{}{}{}{}{}{}{}{}{}</tr>\n",
            value_field("td", &format!("{path}.name"), &b.name, &b.name, "name"),
            value_field(
                "td",
                &format!("{path}.side"),
                b.side.map_or("null", |s| s.name()),
                side_name(b.side),
                "name"
            ),
            num_td(
                &format!("{path}.measured_mmhg"),
                b.measured_mmhg,
                1.0,
                Digits::Fixed(1)
            ),
            num_td(
                &format!("{path}.window_mmhg.0"),
                Some(b.window_mmhg[0]),
                1.0,
                Digits::Fixed(1)
            ),
            num_td(
                &format!("{path}.window_mmhg.1"),
                Some(b.window_mmhg[1]),
                1.0,
                Digits::Fixed(1)
            ),
            value_field(
                "td",
                &format!("{path}.pass"),
                &b.pass.to_string(),
                text,
                &format!("name {class}")
            ),
            num_td(
                &format!("{path}.peak_mmhg"),
                b.peak_mmhg,
                1.0,
                Digits::Fixed(1)
            ),
            yes_no(
                "peak_over_limit",
                b.peak_over_limit,
                "OVER THE LIMIT",
                "name bad"
            ),
            yes_no(
                "peak_above_window",
                b.peak_above_window,
                "yes (check)",
                "name warn"
            ),
        ));
    }
    out.push_str("</table>\n");
    out.push_str(&format!(
        "<p class=\"note\">Peak: the highest 5 cm probe reading in the band. The standard judges band \
         means; a peak above the fabric's limit of {} mmHg is not admissible (a pressure violation), a \
         peak above the band's window is shown for the fitter to check that spot on the wearer.</p>\n",
        num(
            "prescription.max_pressure_mmhg",
            Some(p.max_pressure_mmhg),
            1.0,
            Digits::Fixed(1)
        ),
    ));
    if !p.warnings.is_empty() {
        out.push_str("<ul id=\"peak-warnings\">\n");
        for (i, w) in p.warnings.iter().enumerate() {
            out.push_str(&format!(
                "<li>{}</li>\n",
                value_field(
                    "strong",
                    &format!("prescription.warnings.{i}"),
                    w,
                    w,
                    "warn"
                )
            ));
        }
        out.push_str("</ul>\n");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn violation_of(kind: &str, value: f64, limit: f64, unit: &str) -> Violation {
        Violation {
            kind: kind.into(),
            location: "somewhere".into(),
            value,
            limit,
            unit: unit.into(),
            panel: None,
            triangles: 0,
            area_m2: 0.0,
            point: None,
        }
    }

    /// A garment missing only its prescription is not said to break its fabric's limits; the headline
    /// names each kind of failure.
    #[test]
    fn the_headline_says_what_failed() {
        let prescription = violation_of("prescription", 14.2, 14.98, "mmHg");
        let pressure = violation_of("pressure", 8500.0, 7999.0, "Pa");
        let stalled = violation_of("not_converged", 1e-5, 1e-6, "1");
        assert_eq!(
            headline(&[]),
            ("ok", "Within the fabric's limits".to_string())
        );
        assert_eq!(
            headline(std::slice::from_ref(&prescription)),
            (
                "bad",
                "Not admissible: does NOT meet its prescription (within the fabric's limits)"
                    .to_string()
            )
        );
        assert_eq!(
            headline(&[pressure.clone(), prescription.clone()]).1,
            "Not admissible: NOT within the fabric's limits; does NOT meet its prescription"
        );
        assert_eq!(
            headline(&[stalled, prescription]).1,
            "Not admissible: its simulation did NOT reach equilibrium; does NOT meet its prescription"
        );
        assert_eq!(
            headline(&[pressure]).1,
            "Not admissible: NOT within the fabric's limits"
        );
    }

    /// A band below its window was prescribed at least the window's low end, in mmHg with one decimal; one
    /// above it at most the high end.
    #[test]
    fn a_band_below_its_window_reads_at_least() {
        let below = violation(0, &violation_of("prescription", 14.2, 14.98, "mmHg"));
        assert!(
            below.contains("14.2</span> mmHg where at least <span")
                && below.contains(">15.0</span> mmHg is prescribed"),
            "{below}"
        );
        let above = violation(0, &violation_of("prescription", 21.8, 21.0, "mmHg"));
        assert!(
            above.contains("where at most <span") && above.contains("is prescribed"),
            "{above}"
        );
        let stretch = violation(0, &violation_of("stretch_wale", 1.6, 1.5, "1"));
        assert!(stretch.contains("where at most <span") && stretch.contains("is allowed"));
    }
}
