//! `report.html`: the compression report a fitter reads, one self-contained HTML file (inline CSS and
//! SVG, no script, nothing fetched — its content security policy, [`CSP`], forbids both) written next to
//! `result.json` by `simulate` and `design`.
//!
//! Sections, each from its own file:
//! - the order and the job's headline figures (this file);
//! - the customer's measurements and the pressure per landmark band ([`measurements`]);
//! - the pressure map on the body, front and back, with its legend in mmHg ([`pressure_map`]);
//! - the pressure-by-height curve against the prescribed windows ([`height_curve`]);
//! - the verdict: the fabric's limits ([`Admissibility`], in plain words) and the prescription per band
//!   when there is one ([`verdict`]);
//! - the fabric: its name, and for a fabric of test curves the curves as a plot with the worn course
//!   stretch on the course curve ([`fabric_curves`]);
//! - the pattern pieces with their grain lines and dimensions ([`pieces`]).
//!
//! Every number that `result.json` holds is marked with the field it shows and written with a fixed
//! rounding ([`html`]), so the page can be checked against the file. Lengths display in cm, areas in cm²,
//! pressures in mmHg — the units a fitter reads; `result.json` stays SI (its `_mmhg` fields aside).

pub mod fabric_curves;
pub mod height_curve;
pub mod html;
pub mod measurements;
pub mod pieces;
pub mod pressure_map;
pub mod verdict;

#[cfg(test)]
mod tests;

use skintight_garment::pattern::{OrderLabels, Pattern, Piece};
use skintight_geometry::TriMesh;

use super::admissibility::Admissibility;
use super::prescription::PrescriptionVerdict;
use super::regions::{LandmarkBand, LandmarkGirth};
use super::result::PA_PER_MMHG;
use super::{Simulation, SimulationResult};
use html::{Digits, escape, num, value_field};

/// The worn garment as the pressure map draws it.
pub struct WornGarment<'a> {
    /// Cloth vertex positions at equilibrium (m).
    pub positions: &'a [[f64; 3]],
    /// Cloth triangles (cloth vertex ids).
    pub triangles: &'a [[usize; 3]],
    /// Probe pressure per triangle (Pa).
    pub probe_pressure: &'a [f64],
}

/// Everything the report shows (borrowed from a finished job; a test builds one by hand).
pub struct Report<'a> {
    /// The order's labels (customer, order, template, fabric, size, date, software).
    pub labels: &'a OrderLabels,
    /// Whether the equilibrium solve converged (`converged`).
    pub converged: bool,
    /// Newton iterations (`newton_iterations`).
    pub newton_iterations: usize,
    /// Largest principal stretch (`max_stretch`).
    pub max_stretch: f64,
    /// Mean interface pressure, mmHg (`mean_pressure_mmhg`).
    pub mean_pressure_mmhg: f64,
    /// The verdict against the fabric's limits (`admissible`, `violations`, `limits`).
    pub admissibility: &'a Admissibility,
    /// The body's landmarks (`landmarks`).
    pub landmarks: &'a [LandmarkGirth],
    /// Why the body has no landmarks, when it has none.
    pub measurement_note: Option<String>,
    /// The pressure per landmark band (`regions`).
    pub regions: &'a [LandmarkBand],
    /// The prescription verdict (`prescription`), when the order has one.
    pub prescription: Option<&'a PrescriptionVerdict>,
    /// The body surface at equilibrium (m), drawn grey under the garment.
    pub body: TriMesh,
    /// The worn garment.
    pub garment: WornGarment<'a>,
    /// The pattern pieces.
    pub pieces: &'a [Piece],
    /// The fabric and the course stretch it is worn at (the fabric section; none without).
    pub fabric: Option<(
        &'a crate::scene::FabricSpec,
        Option<fabric_curves::WornCourse>,
    )>,
}

/// `report.html` of a finished simulation (or of a design's final garment), with its cut-ready `pattern`
/// and the prescription verdict when the order has one.
pub fn report_html(
    sim: &Simulation,
    result: &SimulationResult,
    pattern: &Pattern,
    prescription: Option<&PrescriptionVerdict>,
) -> String {
    let body = TriMesh::new(
        sim.system.control_positions(&sim.state.body),
        sim.body.surface.faces.clone(),
    );
    // The course stretch per cloth triangle, as the verdict reads it, weighed by rest area.
    let positions: Vec<skintight_geometry::Vec3> = result
        .cloth_vertex_position
        .iter()
        .map(|p| skintight_geometry::Vec3::new(p[0], p[1], p[2]))
        .collect();
    let measures = super::admissibility::triangle_measures(sim, &positions);
    let course: Vec<f64> = measures.stretch.iter().map(|s| s[1]).collect();
    let area: Vec<f64> = sim
        .system
        .elements()
        .iter()
        .map(|e| e.rest_area())
        .collect();
    let worn = fabric_curves::WornCourse::from_triangles(&course, &area);
    render(&Report {
        labels: &pattern.labels,
        converged: result.converged,
        newton_iterations: result.newton_iterations,
        max_stretch: result.max_stretch,
        mean_pressure_mmhg: result.mean_pressure_mmhg,
        admissibility: &result.admissibility,
        landmarks: &result.landmarks,
        measurement_note: sim.measurements.as_ref().err().map(|e| {
            format!("The body could not be measured, so there are no landmark bands: {e}.")
        }),
        regions: &result.regions,
        prescription,
        body,
        garment: WornGarment {
            positions: &result.cloth_vertex_position,
            triangles: &result.cloth_triangles,
            probe_pressure: &result.elements.probe_pressure,
        },
        pieces: &pattern.pieces,
        fabric: Some((&sim.scene.garment.fabric, worn)),
    })
}

/// The page's content security policy: inline styles and data images only.
pub const CSP: &str = "default-src 'none'; style-src 'unsafe-inline'; img-src data:";

const STYLE: &str = "body{font-family:'DejaVu Sans',Arial,sans-serif;margin:2em auto;padding:0 1em;max-width:62em;\
color:#222;line-height:1.4}h1{margin-bottom:0.2em}h2{border-bottom:1px solid #bbb;margin-top:1.6em}\
table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #ccc;padding:0.15em 0.6em;\
text-align:right}th{background:#f2f2f2}td.name,th.name{text-align:left}.ok{color:#176b2c;font-weight:bold}\
.bad{color:#b00020;font-weight:bold}.warn{color:#a15c00;font-weight:bold}.note{color:#555;font-size:0.9em}.figure{margin:0.8em 0}\
svg text{font-family:'DejaVu Sans',Arial,sans-serif}dl.order{display:grid;grid-template-columns:max-content auto;\
gap:0.1em 1em}dl.order dt{color:#555}dl.order dd{margin:0}@media print{h2{break-after:avoid}.figure{break-inside:avoid}}";

/// The whole page.
pub fn render(r: &Report) -> String {
    let mut out = String::with_capacity(1 << 20);
    out.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    out.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n");
    // Nothing but the page itself: no script runs and nothing is fetched, even from a string that
    // escaped escaping.
    out.push_str(&format!(
        "<meta http-equiv=\"Content-Security-Policy\" content=\"{CSP}\">\n"
    ));
    let who = if r.labels.customer.is_empty() {
        String::new()
    } else {
        format!(" — {}", r.labels.customer)
    };
    out.push_str(&format!(
        "<title>Compression report{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n",
        escape(&who)
    ));
    out.push_str(&format!("<h1>Compression report{}</h1>\n", escape(&who)));
    out.push_str(&order(r));
    out.push_str(&measurements::section(r));
    out.push_str(&pressure_map::section(r));
    out.push_str(&height_curve::section(r));
    out.push_str(&verdict::section(r));
    if let Some((fabric, worn)) = r.fabric {
        out.push_str(&fabric_curves::section(fabric, worn));
    }
    out.push_str(&pieces::section(r));
    out.push_str(
        "<p class=\"note\">Numbers are those of <code>result.json</code> (each element's \
         <code>data-field</code> names its field), in cm, cm² and mmHg; 1 mmHg = 133.322 Pa.</p>\n",
    );
    out.push_str("</body>\n</html>\n");
    out
}

/// The order's labels and the job's headline figures.
fn order(r: &Report) -> String {
    let l = r.labels;
    let mut out = String::from("<dl class=\"order\">\n");
    for (k, v) in [
        ("Order", &l.order_id),
        ("Customer", &l.customer),
        ("Garment", &l.template),
        ("Size", &l.size),
        ("Fabric", &l.fabric),
        ("Date", &l.date),
        ("Software", &l.software),
    ] {
        if !v.is_empty() {
            out.push_str(&format!("<dt>{k}</dt><dd>{}</dd>\n", escape(v)));
        }
    }
    let (class, text) = if r.converged {
        ("ok", "converged")
    } else {
        (
            "bad",
            "NOT converged: the figures below are not an equilibrium",
        )
    };
    out.push_str(&format!(
        "<dt>Simulation</dt><dd>{} in {} Newton iterations</dd>\n",
        value_field("span", "converged", &r.converged.to_string(), text, class),
        num(
            "newton_iterations",
            Some(r.newton_iterations as f64),
            1.0,
            Digits::Fixed(0)
        ),
    ));
    out.push_str(&format!(
        "<dt>Mean pressure</dt><dd>{} mmHg</dd>\n<dt>Largest stretch</dt><dd>{}</dd>\n",
        num(
            "mean_pressure_mmhg",
            Some(r.mean_pressure_mmhg),
            1.0,
            Digits::Fixed(1)
        ),
        num("max_stretch", Some(r.max_stretch), 1.0, Digits::Fixed(3)),
    ));
    out.push_str(&format!(
        "<dt>Pressure limit</dt><dd>{} mmHg</dd>\n</dl>\n",
        num(
            "limits.max_pressure_pa",
            Some(r.admissibility.limits.max_pressure_pa),
            1.0 / PA_PER_MMHG,
            Digits::Fixed(1)
        )
    ));
    out
}
