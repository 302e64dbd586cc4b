//! The report's measurements: the customer's landmarks and girths (`landmarks`) and the garment's pressure
//! at each band it covers (`regions`), as tables in cm and mmHg.

use skintight_geometry::anthropometry::Side;

use super::Report;
use super::html::{Digits, escape, num_td, value_field};

/// `left`, `right`, or empty for the torso.
pub fn side_name(side: Option<Side>) -> &'static str {
    side.map_or("", Side::name)
}

/// The `name` and `side` cells of the entry `path` (`landmarks.3`) of `result.json`.
fn name_cells(path: &str, name: &str, side: Option<Side>) -> String {
    format!(
        "{}{}",
        value_field("td", &format!("{path}.name"), name, name, "name"),
        value_field(
            "td",
            &format!("{path}.side"),
            side.map_or("null", Side::name),
            side_name(side),
            "name"
        )
    )
}

/// The section.
pub fn section(r: &Report) -> String {
    let mut out = String::from("<h2>Measurements</h2>\n");
    if let Some(note) = &r.measurement_note {
        out.push_str(&format!("<p class=\"note\">{}</p>\n", escape(note)));
    }
    if !r.landmarks.is_empty() {
        out.push_str(
            "<p>The body's landmarks (ISO 8559-1, RAL-GZ 387 measuring points): height above the floor \
             and tape-measure girth.</p>\n<table id=\"landmarks\">\n<tr><th class=\"name\">landmark</th>\
             <th class=\"name\">side</th><th>height (cm)</th><th>girth (cm)</th></tr>\n",
        );
        for (i, l) in r.landmarks.iter().enumerate() {
            out.push_str(&format!(
                "<tr>{}{}{}</tr>\n",
                name_cells(&format!("landmarks.{i}"), &l.name, l.side),
                num_td(
                    &format!("landmarks.{i}.height_m"),
                    Some(l.height_m),
                    100.0,
                    Digits::Fixed(1)
                ),
                num_td(
                    &format!("landmarks.{i}.girth_m"),
                    Some(l.girth_m),
                    100.0,
                    Digits::Fixed(1)
                ),
            ));
        }
        out.push_str("</table>\n");
    }
    out.push_str("<h2>Pressure at the measuring points</h2>\n");
    if r.regions.is_empty() {
        out.push_str("<p class=\"note\">The garment covers no landmark band.</p>\n");
        return out;
    }
    out.push_str(
        "<p>Per landmark the garment covers, over the band 2.5 cm either side of the girth on that limb: the \
         area-weighted mean interface pressure, and the lowest and highest a 5 cm pressure probe reads \
         there.</p>\n<table id=\"regions\">\n<tr><th class=\"name\">landmark</th><th class=\"name\">side</th>\
         <th>height (cm)</th><th>girth (cm)</th><th>garment in band (cm²)</th><th>mean (mmHg)</th>\
         <th>min (mmHg)</th><th>max (mmHg)</th></tr>\n",
    );
    for (i, g) in r.regions.iter().enumerate() {
        let p = &g.pressure_mmhg;
        out.push_str(&format!(
            "<tr>{}{}{}{}{}{}{}</tr>\n",
            name_cells(&format!("regions.{i}"), &g.name, g.side),
            num_td(
                &format!("regions.{i}.height_m"),
                Some(g.height_m),
                100.0,
                Digits::Fixed(1)
            ),
            num_td(
                &format!("regions.{i}.girth_m"),
                Some(g.girth_m),
                100.0,
                Digits::Fixed(1)
            ),
            num_td(
                &format!("regions.{i}.area_m2"),
                Some(g.area_m2),
                1e4,
                Digits::Fixed(1)
            ),
            num_td(
                &format!("regions.{i}.pressure_mmhg.mean"),
                Some(p.mean),
                1.0,
                Digits::Fixed(1)
            ),
            num_td(
                &format!("regions.{i}.pressure_mmhg.min"),
                Some(p.min),
                1.0,
                Digits::Fixed(1)
            ),
            num_td(
                &format!("regions.{i}.pressure_mmhg.max"),
                Some(p.max),
                1.0,
                Digits::Fixed(1)
            ),
        ));
    }
    out.push_str("</table>\n");
    out
}
