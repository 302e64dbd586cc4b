//! The report on a hand-built job: a prescription verdict rendered and read back, every number equal to
//! the JSON it came from.

use skintight_garment::pattern::OrderLabels;
use skintight_geometry::anthropometry::Side;
use skintight_geometry::{TriMesh, Vec3};

use super::html::read_back;
use super::{Report, WornGarment, render};
use crate::simulate::admissibility::{Admissibility, Violation};
use crate::simulate::prescription::{BandVerdict, PrescriptionVerdict};
use crate::simulate::regions::{LandmarkBand, LandmarkGirth, PressureRange};
use crate::simulate::result::PA_PER_MMHG;

fn region(name: &str, h: f64, mean: f64) -> LandmarkBand {
    let mmhg = PressureRange {
        mean,
        min: mean - 3.0,
        max: mean + 4.0,
    };
    LandmarkBand {
        name: name.into(),
        side: Some(Side::Left),
        height_m: h,
        girth_m: 0.25,
        area_m2: 0.0123,
        pressure_pa: PressureRange {
            mean: mean * PA_PER_MMHG,
            min: mmhg.min * PA_PER_MMHG,
            max: mmhg.max * PA_PER_MMHG,
        },
        pressure_mmhg: mmhg,
    }
}

fn band(name: &str, measured: Option<f64>, window: [f64; 2]) -> BandVerdict {
    BandVerdict::new(
        name.into(),
        Side::Left,
        measured,
        measured.map(|m| m + 4.0),
        window,
        measured.is_some_and(|m| window[0] <= m && m <= window[1]),
        60.0,
    )
}

#[test]
fn a_prescription_verdict_renders_and_reads_back() {
    let left = Some(Side::Left);
    let landmarks: Vec<LandmarkGirth> = [("B", 0.10, 0.22), ("C", 0.30, 0.36), ("D", 0.42, 0.33)]
        .iter()
        .map(|&(name, h, g)| LandmarkGirth {
            name: name.into(),
            side: left,
            height_m: h,
            girth_m: g,
        })
        .collect();
    let regions = vec![region("B", 0.10, 27.44), region("C", 0.30, 19.96)];
    let verdict = PrescriptionVerdict {
        standard: "RAL-GZ 387".into(),
        class: 2,
        window_mmhg: [23.0, 32.0],
        measured_b_mmhg: Some(27.44),
        bands: vec![
            band("B", Some(27.44), [23.0, 32.0]),
            band("C", Some(19.96), [13.7, 19.2]),
            band("D", None, [11.0, 16.5]),
        ],
        pass: false,
        max_pressure_mmhg: 60.0,
        warnings: vec!["band C (left): a probe reads 63.96 mmHg, above the fabric's limit".into()],
    };
    let limits = serde_json::from_value(serde_json::json!({})).unwrap();
    let admissibility = Admissibility {
        admissible: false,
        violations: vec![Violation {
            kind: "pressure".into(),
            location: "panel \"front\": 3 triangles".into(),
            value: 8500.0,
            limit: 7999.32,
            unit: "Pa".into(),
            panel: Some("front".into()),
            triangles: 3,
            area_m2: 2.5e-4,
            point: Some([0.1, 0.2, 0.3]),
        }],
        limits,
    };
    // A tetrahedron for a body and one garment triangle on its front.
    let body = TriMesh::new(
        vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.2, 0.0, 0.0),
            Vec3::new(0.1, 0.5, 0.05),
            Vec3::new(0.1, 0.1, 0.2),
        ],
        vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
    );
    // One garment triangle in front of the body, one behind it (facing the front view too, but hidden).
    let positions = [
        [0.05, 0.05, 0.25],
        [0.15, 0.05, 0.25],
        [0.1, 0.3, 0.25],
        [0.05, 0.05, -0.5],
        [0.15, 0.05, -0.5],
        [0.1, 0.3, -0.5],
    ];
    let labels = OrderLabels {
        customer: "A. Customer <test>".into(),
        ..Default::default()
    };
    let report = Report {
        labels: &labels,
        converged: true,
        newton_iterations: 7,
        max_stretch: 1.234567,
        mean_pressure_mmhg: 22.25,
        admissibility: &admissibility,
        landmarks: &landmarks,
        measurement_note: None,
        regions: &regions,
        prescription: Some(&verdict),
        body,
        garment: WornGarment {
            positions: &positions,
            triangles: &[[0, 1, 2], [3, 4, 5]],
            probe_pressure: &[3000.0, 6000.0],
        },
        pieces: &[],
        fabric: None,
    };
    let html = render(&report);
    let mut json = serde_json::json!({
        "converged": true, "newton_iterations": 7, "max_stretch": 1.234567, "mean_pressure_mmhg": 22.25,
        "landmarks": landmarks, "regions": regions, "prescription": verdict,
    });
    for (k, v) in serde_json::to_value(&admissibility)
        .unwrap()
        .as_object()
        .unwrap()
    {
        json[k] = v.clone();
    }
    // Headline 5 (the limit among them) + landmarks 3×4 + regions 2×8 + map 1 + verdict 1 + limits 4 +
    // violation 5 + prescription 6 + limit 1 + warning 1 + bands 3×9.
    assert_eq!(read_back(&html, &json), Ok(79));
    for words in [
        "does NOT meet its prescription",
        "not covered",
        "FAIL",
        "Interface pressure (5 cm probe)</strong> on panel “front”",
        "A. Customer &lt;test&gt;",
        "Not admissible: NOT within the fabric&#39;s limits</span>",
        "yes (check)",
        "a probe reads 63.96 mmHg",
    ] {
        assert!(html.contains(words), "{words}");
    }
    // The band B window is drawn green, C's red, D's grey (not covered).
    assert!(html.contains("<title>B left: 23.0–32.0 mmHg prescribed</title>"));
    for colour in ["fill=\"#2e9e4a\"", "fill=\"#d9534f\"", "fill=\"#999999\""] {
        assert!(html.contains(colour), "{colour}");
    }
    // The garment triangle in front faces the front view only, coloured by 3000 Pa on 0..60 mmHg; the one
    // behind the body is not drawn.
    let fill = super::html::srgb_hex(crate::simulate::colormap::color(
        3000.0 / PA_PER_MMHG,
        0.0,
        7999.32 / PA_PER_MMHG,
    ));
    assert_eq!(html.matches(&format!("fill=\"{fill}\"")).count(), 1);
    let hidden = super::html::srgb_hex(crate::simulate::colormap::color(
        6000.0 / PA_PER_MMHG,
        0.0,
        7999.32 / PA_PER_MMHG,
    ));
    assert_eq!(html.matches(&format!("fill=\"{hidden}\"")).count(), 0);
    assert!(!html.contains("<script") && !html.contains("NaN"));
    assert!(!html.contains("\"inf") && !html.contains(">inf"));
    assert_eq!(html.matches("<svg").count(), html.matches("</svg>").count());
    // A number changed in the page is caught.
    let tampered = html.replacen(">27.4<", ">27.6<", 1);
    assert!(
        read_back(&tampered, &json)
            .unwrap_err()
            .starts_with("regions.0.pressure_mmhg.mean")
    );
}
