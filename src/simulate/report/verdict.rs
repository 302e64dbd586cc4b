//! The report's verdict: whether the worn garment stays within its fabric's limits (`admissible`), each
//! broken limit in plain words (`violations`), and — when the order carries a prescription — the
//! compression class at the ankle and the window of every prescribed band, met or not (`prescription`).

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
        _ => "Limit",
    }
}

/// One violation as a sentence, its numbers marked with their fields (`violations.{i}`).
fn violation(i: usize, v: &Violation) -> String {
    let path = format!("violations.{i}");
    let (scale, digits, unit) = match (v.kind.as_str(), v.unit.as_str()) {
        (_, "Pa") => (1.0 / PA_PER_MMHG, Digits::Fixed(1), " mmHg"),
        ("not_converged", _) => (1.0, Digits::Exp(2), ""),
        _ => (1.0, Digits::Fixed(3), ""),
    };
    let bound = if v.kind == "pattern_quality" {
        "at least"
    } else {
        "at most"
    };
    let mut s = format!(
        "<li>{}{}: {}{unit} where {bound} {}{unit} is allowed",
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
    let (class, text) = if a.admissible {
        ("ok", "Within the fabric's limits")
    } else {
        ("bad", "NOT within the fabric's limits")
    };
    out.push_str(&format!(
        "<p id=\"admissible\">{}</p>\n",
        value_field("span", "admissible", &a.admissible.to_string(), text, class)
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
         <th>measured (mmHg)</th><th>window low</th><th>window high</th><th class=\"name\">verdict</th></tr>\n",
    );
    for (i, b) in p.bands.iter().enumerate() {
        let path = format!("prescription.bands.{i}");
        let (class, text) = match (b.measured_mmhg, b.pass) {
            (None, _) => ("bad", "not covered"),
            (Some(_), true) => ("ok", "pass"),
            (Some(_), false) => ("bad", "FAIL"),
        };
        out.push_str(&format!(
            "<tr>{}{}{}{}{}{}</tr>\n",
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
        ));
    }
    out.push_str("</table>\n");
    out
}
