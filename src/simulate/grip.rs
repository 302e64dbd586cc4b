//! Openings that grip: a garment's waistband, thigh band or wrist hem holds itself up by its pressure
//! alone (no silicone), so the template names each opening's landmark band and the least pressure it
//! needs (`GarmentTemplate::grip`, mmHg). The verdict ([`grip_verdict`]) reads the band in `result.json`'s
//! `regions` — the same band, kernel and triangles the prescription is judged on, hem included — and an
//! opening grips when
//!
//! - its band mean (the `ω`·area-weighted interface pressure, normal force over deformed area) is at least
//!   the template's `min_pressure_mmhg`, and
//! - no 5 cm probe anywhere in the band reads below 0 mmHg (`regions[…].pressure_mmhg.min`): the fabric
//!   does not lift off the skin anywhere around the opening.
//!
//! A failing opening is a violation of kind `grip` (not admissible, exit 4), one per band. The design aims
//! at it with a band-pressure term ([`grip_term`]: the window `[min_pressure_mmhg, fabric limit]` on the
//! band, centred on the landmark's girth plane along its normal, with the verdict's half-width and taper).
//! Units: mmHg in the verdict, Pa in the term (`PA_PER_MMHG`).

use serde::{Deserialize, Serialize};
use skintight_design::{BandPressure, PressureBand};
use skintight_geometry::Vec3;
use skintight_geometry::anthropometry::landmarks::{LEG_LANDMARKS, TORSO_LANDMARKS};
use skintight_geometry::anthropometry::{Measurements, Side};
use skintight_physics::PA_PER_MMHG;

use super::admissibility::Violation;
use super::regions::{BAND_HALF_WIDTH, BAND_TAPER, LandmarkBand};
use crate::scene::template::{GarmentTemplate, GripBand, TemplateLimb};

/// One opening's verdict.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GripVerdict {
    /// The landmark of the opening's band (`waist`, `G`, `wrist`, …).
    pub landmark: String,
    /// The limb's side; `null` for a torso landmark.
    pub side: Option<Side>,
    /// The band mean (mmHg); `null` when the garment does not cover the band.
    pub measured_mmhg: Option<f64>,
    /// The lowest probe reading in the band (mmHg); `null` when not covered.
    pub lowest_probe_mmhg: Option<f64>,
    /// The least band mean the template asks for (mmHg).
    pub required_mmhg: f64,
    /// Whether the band mean reaches `required_mmhg` and no probe reads below 0.
    pub pass: bool,
}

/// The sides the grip band `g` of `template` is on: the garment's side for a one-limb template, both legs
/// for a `legs` template's leg landmark, none (`[None]`) for a torso landmark.
pub fn grip_sides(
    template: &GarmentTemplate,
    side: Option<Side>,
    g: &GripBand,
) -> Vec<Option<Side>> {
    if TORSO_LANDMARKS.contains(&g.landmark.as_str()) {
        return vec![None];
    }
    match (template.limb, side) {
        (TemplateLimb::Legs, _) if LEG_LANDMARKS.contains(&g.landmark.as_str()) => {
            Side::BOTH.iter().map(|&s| Some(s)).collect()
        }
        (_, s) => vec![s],
    }
}

/// The verdict of every opening of `template` (worn on `side`, `None` for `legs`) from the garment's
/// landmark bands `regions`.
pub fn grip_verdict(
    template: &GarmentTemplate,
    side: Option<Side>,
    regions: &[LandmarkBand],
) -> Vec<GripVerdict> {
    let mut out = Vec::new();
    for g in &template.grip {
        for s in grip_sides(template, side, g) {
            let band = regions.iter().find(|r| r.name == g.landmark && r.side == s);
            let measured = band.map(|b| b.pressure_mmhg.mean);
            let lowest = band.map(|b| b.pressure_mmhg.min);
            out.push(GripVerdict {
                landmark: g.landmark.clone(),
                side: s,
                measured_mmhg: measured,
                lowest_probe_mmhg: lowest,
                required_mmhg: g.min_pressure_mmhg,
                pass: measured.is_some_and(|m| m >= g.min_pressure_mmhg)
                    && lowest.is_some_and(|l| l >= 0.0),
            });
        }
    }
    out
}

/// The openings that do not grip as violations (kind `grip`, unit mmHg): the band mean against the least
/// pressure when it is below it, else the lowest probe reading against 0.
pub fn grip_violations(verdicts: &[GripVerdict]) -> Vec<Violation> {
    verdicts
        .iter()
        .filter(|v| !v.pass)
        .map(|v| {
            let side = v.side.map_or(String::new(), |s| format!(" ({})", s.name()));
            let (value, limit, text) = match (v.measured_mmhg, v.lowest_probe_mmhg) {
                (None, _) | (_, None) => (
                    0.0,
                    v.required_mmhg,
                    format!("opening band {}{side}: not covered by the garment", v.landmark),
                ),
                (Some(m), _) if m < v.required_mmhg => (
                    m,
                    v.required_mmhg,
                    format!(
                        "opening band {}{side}: mean {m:.1} mmHg, below the {:.1} mmHg it needs to grip",
                        v.landmark, v.required_mmhg
                    ),
                ),
                (_, Some(l)) => (
                    l,
                    0.0,
                    format!(
                        "opening band {}{side}: a probe reads {l:.1} mmHg (the fabric lifts off the skin)",
                        v.landmark
                    ),
                ),
            };
            Violation {
                kind: "grip".into(),
                location: text,
                value,
                limit,
                unit: "mmHg".into(),
                panel: None,
                triangles: 0,
                area_m2: 0.0,
                point: None,
            }
        })
        .collect()
}

/// The design's term for the opening `g` on `side` (`None`: torso) of the body measured as `m`: the band
/// pressure inside `[g.min_pressure_mmhg, max_pressure_mmhg]` (mmHg) at weight `weight`, centred on the
/// landmark's girth plane along its normal, counting the hem's triangles as the verdict does; a leg
/// landmark's band counts only the cloth on that leg's side of the body's mid-plane. `None` when the body
/// has no such landmark.
pub fn grip_term(
    g: &GripBand,
    side: Option<Side>,
    m: &Measurements,
    weight: f64,
    max_pressure_mmhg: f64,
) -> Option<Result<BandPressure, String>> {
    let landmark = m.landmark(&g.landmark, side)?;
    let band = PressureBand {
        name: format!("grip {}", g.landmark),
        center: 0.0,
        half_width: BAND_HALF_WIDTH,
        taper: BAND_TAPER,
        min: g.min_pressure_mmhg * PA_PER_MMHG,
        max: max_pressure_mmhg.max(g.min_pressure_mmhg) * PA_PER_MMHG,
    };
    let term = BandPressure::new(
        weight,
        Vec3::from(landmark.point),
        Vec3::from(landmark.normal),
        vec![band],
    )
    .map(|t| t.with_boundary_ring(true));
    let term = match side {
        Some(s) => term.and_then(|t| {
            t.with_side(
                Vec3::new(s.sign(), 0.0, 0.0),
                s.sign() * m.segmentation.mid_x,
            )
        }),
        None => term,
    };
    Some(term.map_err(|e| e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::template::find_template;
    use crate::simulate::regions::PressureRange;

    fn band(name: &str, side: Option<Side>, mean: f64, min: f64) -> LandmarkBand {
        LandmarkBand {
            name: name.into(),
            side,
            height_m: 1.0,
            girth_m: 0.7,
            area_m2: 0.01,
            pressure_pa: PressureRange {
                mean: mean * PA_PER_MMHG,
                min: min * PA_PER_MMHG,
                max: mean * PA_PER_MMHG,
            },
            pressure_mmhg: PressureRange {
                mean,
                min,
                max: mean,
            },
        }
    }

    #[test]
    fn the_leggings_waist_grips_only_with_its_least_pressure_and_no_lift() {
        let t = find_template("leggings").unwrap();
        let waist = t.grip.iter().find(|g| g.landmark == "waist").unwrap();
        let need = waist.min_pressure_mmhg;
        assert!(need > 0.0);
        let ok = grip_verdict(&t, None, &[band("waist", None, need + 0.1, 0.5)]);
        assert_eq!(ok.len(), 1);
        assert!(ok[0].pass, "{ok:?}");
        assert!(grip_violations(&ok).is_empty());
        let low = grip_verdict(&t, None, &[band("waist", None, need - 0.1, 0.5)]);
        let v = grip_violations(&low);
        assert_eq!(v.len(), 1);
        assert_eq!(v[0].kind, "grip");
        assert!(v[0].location.contains("below the"), "{}", v[0].location);
        let lifting = grip_verdict(&t, None, &[band("waist", None, need + 3.0, -0.7)]);
        let v = grip_violations(&lifting);
        assert!(v[0].location.contains("lifts off"), "{}", v[0].location);
        assert_eq!((v[0].value, v[0].limit), (-0.7, 0.0));
        let uncovered = grip_verdict(&t, None, &[band("hip", None, 9.0, 1.0)]);
        assert!(!uncovered[0].pass);
    }

    #[test]
    fn every_opening_the_issue_names_has_a_grip_band() {
        for (name, landmark) in [
            ("leggings", "waist"),
            ("thigh_high", "G"),
            ("arm_sleeve", "wrist"),
        ] {
            let t = find_template(name).unwrap();
            assert!(
                t.grip
                    .iter()
                    .any(|g| g.landmark == landmark && g.min_pressure_mmhg > 0.0),
                "{name}: {:?}",
                t.grip
            );
        }
        // A one-limb template's band is on its side.
        let t = find_template("thigh_high").unwrap();
        let g = &t.grip[0];
        assert_eq!(grip_sides(&t, Some(Side::Left), g), vec![Some(Side::Left)]);
    }
}
