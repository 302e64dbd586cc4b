//! Compression prescriptions: the standards' class windows and pressure profiles as a table, the
//! prescribed window of every band, and the verdict (`result.json`'s `prescription`) of a garment's
//! measured band pressures ([`super::regions`]) against them.
//!
//! # The standards
//!
//! A class fixes the pressure window at the ankle, measuring point `B` (mmHg; on an arm, at the wrist);
//! the profile fixes the pressure at the points above it (`B1`, `C`, `D`, `E`, `F`, `G`, see
//! `skintight_geometry::anthropometry::landmarks`) as a percentage window of the pressure at `B`.
//!
//! | standard | I | II | III | IV | source |
//! |---|---|---|---|---|---|
//! | `RAL-GZ 387` (Germany) | 18–21 | 23–32 | 34–46 | ≥ 49 | RAL-GZ 387/1 (2008), as manufacturers publish it (e.g. ofa Bamberg's compression-class table: 2.4–2.8, 3.1–4.3, 4.5–6.1, ≥ 6.5 kPa) |
//! | `BS 6612` (UK) | 14–17 | 18–24 | 25–35 | — | BS 6612:1985 classes as UK suppliers list them (e.g. Credenhill's "How much compression?") |
//! | `ASQUAL` (France) | 10–15 | 15–20 | 20–36 | > 36 | the French ASQUAL/NF G30-102 classes as commonly cited |
//!
//! Class IV has no upper end in the standards; its window is closed by the order's own pressure limit
//! (`garment.fabric.limits.max_pressure_pa`).
//!
//! The **graduated** profile (percent of the `B` pressure):
//!
//! | point | B1 | C | D | E | F | G |
//! |---|---|---|---|---|---|---|
//! | window (%) | 70–100 | 50–80 | 40–70 | 35–65 | 30–60 | 20–40 |
//!
//! **Provenance, honestly:** these percentages follow the graduated-profile table of RAL-GZ 387/1 as it is
//! reproduced in the compression-hosiery literature; the standard's own text is not freely available and
//! could not be consulted for this table, so check it against your copy and give the profile yourself
//! (`"profile": {"B1": [70, 100], …}`) where yours differs. The British and French tables use the same
//! profile here (no separate profile was sourced for them).
//!
//! # The verdict
//!
//! `B` passes when its measured band mean lies in the class window; every other prescribed point the
//! garment covers passes when its band mean lies in its percentage window **of the measured `B`
//! pressure**. The prescription passes when the garment reaches `B` and every band passes.
//!
//! # Peaks
//!
//! The standards judge band means, so a band can pass while a probe inside it reads far more (a class-III
//! stocking's `B` band has read 25–58 mmHg around a 40 mmHg mean). Every band therefore names its
//! **peak**, the highest probe reading in it (`regions`' `max`, mmHg), and flags it:
//!
//! - `peak_over_limit`: the peak exceeds the fabric's pressure limit (`garment.fabric.limits.max_pressure_pa`,
//!   the safety limit of the wearer and the knit). This is not admissible: the same probe reading is a
//!   `pressure` violation of [`super::admissibility`], which bounds every probe reading, not band means.
//!   Each such band is also a sentence in `warnings`, which the report lists in bold.
//! - `peak_above_window`: the peak exceeds the band's prescribed window. Shown, not failed: the standard
//!   judges the mean, and on the simulated garments a band's peak probe reading is commonly well above its
//!   mean (the arm sleeves of docs/BENCHMARKS.md, issue 47: 1.2–3 ×, every band), so a sentence for each would
//!   drown the one that matters.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use skintight_geometry::anthropometry::{LimbKind, Side};

use super::admissibility::Violation;
use super::regions::LandmarkBand;
use crate::scene::SceneError;

pub use skintight_physics::PA_PER_MMHG;

/// One standard of the table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompressionStandard {
    /// Its name as jobs give it.
    pub name: &'static str,
    /// Class windows at `B` (mmHg), classes 1, 2, …: `[low, high]`, `high` infinite for an open class.
    pub classes: &'static [[f64; 2]],
    /// The graduated profile: `(point, [low %, high %])` from the ankle up.
    pub graduated: &'static [(&'static str, [f64; 2])],
}

const GRADUATED: &[(&str, [f64; 2])] = &[
    ("B1", [70.0, 100.0]),
    ("C", [50.0, 80.0]),
    ("D", [40.0, 70.0]),
    ("E", [35.0, 65.0]),
    ("F", [30.0, 60.0]),
    ("G", [20.0, 40.0]),
];

/// The standards; see the module documentation for the sources.
pub const STANDARDS: &[CompressionStandard] = &[
    CompressionStandard {
        name: "RAL-GZ 387",
        classes: &[
            [18.0, 21.0],
            [23.0, 32.0],
            [34.0, 46.0],
            [49.0, f64::INFINITY],
        ],
        graduated: GRADUATED,
    },
    CompressionStandard {
        name: "BS 6612",
        classes: &[[14.0, 17.0], [18.0, 24.0], [25.0, 35.0]],
        graduated: GRADUATED,
    },
    CompressionStandard {
        name: "ASQUAL",
        classes: &[
            [10.0, 15.0],
            [15.0, 20.0],
            [20.0, 36.0],
            [36.0, f64::INFINITY],
        ],
        graduated: GRADUATED,
    },
];

/// The leg's prescribed points, from the ankle up; the class window applies at the first.
pub const LEG_POINTS: [&str; 7] = ["B", "B1", "C", "D", "E", "F", "G"];

/// The arm's prescribed points, from the wrist up; the class window applies at the wrist. No graduated
/// arm profile is tabled: an arm prescription gives its own percent windows.
pub const ARM_POINTS: [&str; 4] = ["wrist", "forearm", "elbow", "upper_arm"];

/// The prescribed points of a limb, from its distal end.
pub fn limb_points(kind: LimbKind) -> &'static [&'static str] {
    match kind {
        LimbKind::Leg => &LEG_POINTS,
        LimbKind::Arm => &ARM_POINTS,
    }
}

/// How the pressure falls above `B`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ProfileSpec {
    /// `"graduated"`: the standard's profile.
    Named(String),
    /// Percent windows of the `B` pressure per point, e.g. `{"C": [50, 80], "D": [40, 70]}`; points left
    /// out are not prescribed.
    Custom(BTreeMap<String, [f64; 2]>),
}

impl Default for ProfileSpec {
    fn default() -> Self {
        Self::Named("graduated".into())
    }
}

/// A compression prescription: a standard's class and a profile, on one leg.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Prescription {
    /// `RAL-GZ 387`, `BS 6612` or `ASQUAL`.
    pub standard: String,
    /// The class, 1 to 4 (as the standard has them).
    pub class: u8,
    /// The profile above `B`.
    pub profile: ProfileSpec,
}

/// A prescription resolved against the table: windows in mmHg.
#[derive(Clone, Debug, PartialEq)]
pub struct PrescribedWindows {
    /// The point the class window applies at (`B` on a leg, `wrist` on an arm).
    pub class_point: &'static str,
    /// The class window at `B` (mmHg), closed above by the pressure limit for an open class.
    pub class_window: [f64; 2],
    /// `(point, [low %, high %])` above `B`, from the ankle up.
    pub profile: Vec<(String, [f64; 2])>,
}

impl Prescription {
    /// The windows on a limb of kind `kind`, with `max_pressure_mmhg` closing an open class; errors name
    /// `key`'s fields.
    pub fn windows(
        &self,
        key: &str,
        max_pressure_mmhg: f64,
        kind: LimbKind,
    ) -> Result<PrescribedWindows, SceneError> {
        let points = limb_points(kind);
        let standard = STANDARDS
            .iter()
            .find(|s| s.name == self.standard)
            .ok_or_else(|| {
                let names: Vec<&str> = STANDARDS.iter().map(|s| s.name).collect();
                SceneError::new(
                    format!("{key}.standard"),
                    format!(
                        "unknown standard '{}'; use one of {}",
                        self.standard,
                        names.join(", ")
                    ),
                )
            })?;
        let n = standard.classes.len();
        if !(1..=n).contains(&(self.class as usize)) {
            return Err(SceneError::new(
                format!("{key}.class"),
                format!("{} has classes 1 to {n}, got {}", standard.name, self.class),
            ));
        }
        let [low, high] = standard.classes[self.class as usize - 1];
        let high = high.min(max_pressure_mmhg);
        if high <= low {
            return Err(SceneError::new(
                format!("{key}.class"),
                format!(
                    "class {} of {} starts at {low} mmHg, above the order's pressure limit \
                     ({max_pressure_mmhg:.1} mmHg, garment.fabric.limits.max_pressure_pa): raise the \
                     limit or prescribe a lower class",
                    self.class, standard.name
                ),
            ));
        }
        let profile = match &self.profile {
            ProfileSpec::Named(n) if n == "graduated" && kind == LimbKind::Arm => {
                return Err(SceneError::new(
                    format!("{key}.profile"),
                    format!(
                        "no graduated arm profile is tabled: give percent windows of the wrist \
                         pressure for {}, e.g. {{\"elbow\": [60, 90]}}",
                        ARM_POINTS[1..].join(", ")
                    ),
                ));
            }
            ProfileSpec::Named(n) if n == "graduated" => standard
                .graduated
                .iter()
                .map(|(p, w)| (p.to_string(), *w))
                .collect(),
            ProfileSpec::Named(n) => {
                return Err(SceneError::new(
                    format!("{key}.profile"),
                    format!(
                        "unknown profile '{n}'; use \"graduated\" or percent windows per point, \
                         e.g. {{\"C\": [50, 80]}}"
                    ),
                ));
            }
            ProfileSpec::Custom(map) => {
                let mut out = Vec::new();
                for (point, w) in map {
                    let k = format!("{key}.profile.{point}");
                    if !points[1..].contains(&point.as_str()) {
                        return Err(SceneError::new(
                            k,
                            format!(
                                "not a measuring point above {} on this limb; use {}",
                                points[0],
                                points[1..].join(", ")
                            ),
                        ));
                    }
                    if !(w[0].is_finite()
                        && w[1].is_finite()
                        && 0.0 <= w[0]
                        && w[0] < w[1]
                        && w[1] <= 200.0)
                    {
                        return Err(SceneError::new(
                            k,
                            format!(
                                "a window [low, high] in percent of the {} pressure, 0 ≤ low < high \
                                 ≤ 200, got {w:?}",
                                points[0]
                            ),
                        ));
                    }
                    out.push((point.clone(), *w));
                }
                out.sort_by_key(|(p, _)| points.iter().position(|q| q == p));
                out
            }
        };
        Ok(PrescribedWindows {
            class_point: points[0],
            class_window: [low, high],
            profile,
        })
    }
}

/// The verdict of the bands `regions` on the legs `sides` (one, or both for leggings) against
/// `windows` of `prescription`, their peaks against the fabric's pressure limit `max_pressure_mmhg`
/// (mmHg).
pub fn prescription_verdict(
    prescription: &Prescription,
    windows: &PrescribedWindows,
    sides: &[Side],
    regions: &[LandmarkBand],
    max_pressure_mmhg: f64,
) -> PrescriptionVerdict {
    let band_of = |name: &str, side: Side| {
        regions
            .iter()
            .find(|r| r.name == name && r.side == Some(side))
    };
    let measured = |name: &str, side: Side| band_of(name, side).map(|r| r.pressure_mmhg.mean);
    let peak = |name: &str, side: Side| band_of(name, side).map(|r| r.pressure_mmhg.max);
    let inside = |v: Option<f64>, w: [f64; 2]| v.is_some_and(|v| v >= w[0] && v <= w[1]);
    let mut bands = Vec::new();
    let mut first_b = None;
    for (i, &side) in sides.iter().enumerate() {
        let b = measured(windows.class_point, side);
        if i == 0 {
            first_b = b;
        }
        bands.push(BandVerdict::new(
            windows.class_point.into(),
            side,
            b,
            peak(windows.class_point, side),
            windows.class_window,
            inside(b, windows.class_window),
            max_pressure_mmhg,
        ));
        for (point, pct) in &windows.profile {
            let Some(value) = measured(point, side) else {
                continue;
            };
            let reference = b.unwrap_or(0.5 * (windows.class_window[0] + windows.class_window[1]));
            let window = [reference * pct[0] / 100.0, reference * pct[1] / 100.0];
            bands.push(BandVerdict::new(
                point.clone(),
                side,
                Some(value),
                peak(point, side),
                window,
                b.is_some() && inside(Some(value), window),
                max_pressure_mmhg,
            ));
        }
    }
    let pass = !bands.is_empty() && bands.iter().all(|b| b.pass);
    let warnings = bands.iter().filter_map(peak_warning).collect();
    PrescriptionVerdict {
        standard: prescription.standard.clone(),
        class: prescription.class,
        window_mmhg: windows.class_window,
        measured_b_mmhg: first_b,
        bands,
        pass,
        max_pressure_mmhg,
        warnings,
    }
}

/// The fitter's warning about a band's peak above the fabric's limit, if it has one.
fn peak_warning(b: &BandVerdict) -> Option<String> {
    let peak = b.peak_mmhg.filter(|_| b.peak_over_limit)?;
    let side = b.side.map_or(String::new(), |s| format!(" ({})", s.name()));
    Some(format!(
        "band {}{side}: a probe reads {peak:.1} mmHg, above the fabric's limit of {:.1} mmHg (not \
         admissible: a pressure violation), although the band mean is {}",
        b.name,
        b.peak_limit_mmhg,
        b.measured_mmhg
            .map_or("not measured".into(), |m| format!("{m:.1} mmHg"))
    ))
}

/// The prescription's failures as admissibility violations (kind `prescription`, unit `mmHg`, one per
/// failing band): an order that misses its prescription is not presented as a success.
pub fn prescription_violations(v: &PrescriptionVerdict) -> Vec<Violation> {
    v.bands
        .iter()
        .enumerate()
        .filter(|(_, b)| !b.pass)
        .map(|(i, b)| {
            let limb = if ARM_POINTS.contains(&b.name.as_str()) {
                "arm"
            } else {
                "leg"
            };
            let side = b
                .side
                .map_or(String::new(), |s| format!(" on the {} {limb}", s.name()));
            let [low, high] = b.window_mmhg;
            let (value, limit, text) = match b.measured_mmhg {
                None => (
                    0.0,
                    low,
                    format!("band {}{side}: not covered by the garment", b.name),
                ),
                Some(m) if i > 0 && v.measured_b_mmhg.is_none() => (
                    m,
                    low,
                    format!(
                        "band {}{side}: {m:.1} mmHg, but {} is not covered to compare with",
                        b.name, v.bands[0].name
                    ),
                ),
                Some(m) => (
                    m,
                    if m < low { low } else { high },
                    format!(
                        "band {}{side}: {m:.1} mmHg, prescribed {low:.1}–{high:.1} mmHg ({} class {})",
                        b.name, v.standard, v.class
                    ),
                ),
            };
            Violation {
                kind: "prescription".into(),
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

/// The verdict of a garment against its prescription.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PrescriptionVerdict {
    /// The standard (`RAL-GZ 387`, `BS 6612`, `ASQUAL`).
    pub standard: String,
    /// The compression class (1–4).
    pub class: u8,
    /// The class window at the ankle, point `B` (mmHg), `[low, high]`.
    pub window_mmhg: [f64; 2],
    /// The measured pressure at `B` (band mean, mmHg; at the wrist for an arm) of the (first) prescribed
    /// limb — the left leg for a garment over both legs, whose `B` bands are both in `bands`; `null`
    /// when the garment does not reach it.
    pub measured_b_mmhg: Option<f64>,
    /// Every prescribed band the garment covers (and `B` always), from the ankle up, leg by leg.
    pub bands: Vec<BandVerdict>,
    /// Whether `B` is inside the class window and every band inside its profile window.
    pub pass: bool,
    /// The fabric's pressure limit the bands' peaks are checked against (mmHg).
    pub max_pressure_mmhg: f64,
    /// For the fitter: each band whose peak is above the fabric's limit, in words.
    pub warnings: Vec<String>,
}

/// One prescribed band.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BandVerdict {
    /// The landmark's name (`B`, `B1`, `C`, `D`, `E`, `F`, `G`).
    pub name: String,
    /// The leg.
    pub side: Option<Side>,
    /// The measured band mean (mmHg); `null` when the garment does not cover the band.
    pub measured_mmhg: Option<f64>,
    /// The prescribed window (mmHg), `[low, high]`: the class window at `B`, elsewhere the profile's
    /// percentages of the measured `B` pressure.
    pub window_mmhg: [f64; 2],
    /// Whether the measured value lies in the window.
    pub pass: bool,
    /// The band's peak: the highest 5 cm probe reading in it (mmHg); `null` when not covered.
    pub peak_mmhg: Option<f64>,
    /// The limit the peak is checked against: the fabric's pressure limit (mmHg).
    pub peak_limit_mmhg: f64,
    /// Whether the peak exceeds the fabric's limit (then also a `pressure` violation: not admissible).
    pub peak_over_limit: bool,
    /// Whether the peak exceeds the band's window (a warning: the standard judges the mean).
    pub peak_above_window: bool,
}

impl BandVerdict {
    /// The verdict of band `name` on `side` with mean `measured` and peak `peak` (mmHg) against
    /// `window` (mmHg), the mean's verdict `pass`, and the peak checked against `limit` (mmHg).
    pub fn new(
        name: String,
        side: Side,
        measured: Option<f64>,
        peak: Option<f64>,
        window: [f64; 2],
        pass: bool,
        limit: f64,
    ) -> Self {
        Self {
            name,
            side: Some(side),
            measured_mmhg: measured,
            window_mmhg: window,
            pass,
            peak_mmhg: peak,
            peak_limit_mmhg: limit,
            peak_over_limit: peak.is_some_and(|p| !(p <= limit)),
            peak_above_window: peak.is_some_and(|p| !(p <= window[1])),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::regions::PressureRange;

    fn region(name: &str, side: Side, mean: f64) -> LandmarkBand {
        let r = PressureRange {
            mean,
            min: mean - 1.0,
            max: mean + 1.0,
        };
        LandmarkBand {
            name: name.into(),
            side: Some(side),
            height_m: 0.1,
            girth_m: 0.2,
            area_m2: 0.01,
            pressure_pa: PressureRange {
                mean: mean * PA_PER_MMHG,
                min: r.min * PA_PER_MMHG,
                max: r.max * PA_PER_MMHG,
            },
            pressure_mmhg: r,
        }
    }

    fn ral(class: u8) -> Prescription {
        Prescription {
            standard: "RAL-GZ 387".into(),
            class,
            profile: ProfileSpec::default(),
        }
    }

    #[test]
    fn the_table_gives_the_class_windows_and_closes_an_open_class_with_the_limit() {
        let w = ral(2).windows("p", 60.0, LimbKind::Leg).unwrap();
        assert_eq!(w.class_window, [23.0, 32.0]);
        assert_eq!(w.profile[1], ("C".to_string(), [50.0, 80.0]));
        assert_eq!(
            ral(4)
                .windows("p", 60.0, LimbKind::Leg)
                .unwrap()
                .class_window,
            [49.0, 60.0]
        );
        let e = ral(4)
            .windows("p", 45.0, LimbKind::Leg)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("p.class") && e.contains("raise the limit"),
            "{e}"
        );
        let e = ral(5)
            .windows("p", 60.0, LimbKind::Leg)
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.class") && e.contains("classes 1 to 4"), "{e}");
        let mut bs = ral(2);
        bs.standard = "BS 6612".into();
        assert_eq!(
            bs.windows("p", 60.0, LimbKind::Leg).unwrap().class_window,
            [18.0, 24.0]
        );
        bs.standard = "DIN".into();
        let e = bs
            .windows("p", 60.0, LimbKind::Leg)
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.standard") && e.contains("RAL-GZ 387"), "{e}");
    }

    #[test]
    fn an_arm_prescription_takes_its_class_at_the_wrist_and_needs_its_own_profile() {
        let mut p = ral(2);
        let e = p.windows("p", 60.0, LimbKind::Arm).unwrap_err().to_string();
        assert!(
            e.contains("p.profile") && e.contains("no graduated arm profile"),
            "{e}"
        );
        p.profile = ProfileSpec::Custom(BTreeMap::from([
            ("upper_arm".to_string(), [50.0, 80.0]),
            ("elbow".to_string(), [60.0, 90.0]),
        ]));
        let w = p.windows("p", 60.0, LimbKind::Arm).unwrap();
        assert_eq!(w.class_point, "wrist");
        assert_eq!(w.profile[0].0, "elbow");
        // Leg points are not arm points.
        assert!(p.windows("p", 60.0, LimbKind::Leg).is_err());
        let l = Side::Left;
        let regions = vec![region("wrist", l, 25.0), region("elbow", l, 24.0)];
        let v = prescription_verdict(&p, &w, &[l], &regions, 60.0);
        assert_eq!(v.measured_b_mmhg, Some(25.0));
        assert!(!v.pass && v.bands[0].pass && !v.bands[1].pass);
        let violations = prescription_violations(&v);
        assert!(
            violations[0]
                .location
                .starts_with("band elbow on the left arm: 24.0 mmHg")
        );
    }

    #[test]
    fn custom_profiles_are_checked_and_ordered_from_the_ankle_up() {
        let mut p = ral(2);
        p.profile = ProfileSpec::Custom(BTreeMap::from([
            ("D".to_string(), [40.0, 60.0]),
            ("C".to_string(), [60.0, 90.0]),
        ]));
        let w = p.windows("p", 60.0, LimbKind::Leg).unwrap();
        assert_eq!(w.profile[0].0, "C");
        assert_eq!(w.profile[1].0, "D");
        for (point, win, needle) in [
            ("X", [10.0, 20.0], "p.profile.X"),
            ("C", [80.0, 20.0], "p.profile.C"),
            ("C", [f64::NAN, 20.0], "p.profile.C"),
        ] {
            p.profile = ProfileSpec::Custom(BTreeMap::from([(point.to_string(), win)]));
            let e = p.windows("p", 60.0, LimbKind::Leg).unwrap_err().to_string();
            assert!(e.contains(needle), "{e}");
        }
        p.profile = ProfileSpec::Named("steep".into());
        assert!(
            p.windows("p", 60.0, LimbKind::Leg)
                .unwrap_err()
                .to_string()
                .contains("p.profile")
        );
    }

    #[test]
    fn the_verdict_checks_b_against_the_class_and_the_rest_against_the_measured_b() {
        let p = ral(2);
        let w = p.windows("p", 60.0, LimbKind::Leg).unwrap();
        let l = Side::Left;
        // B 28, B1 25 (89 %), C 18 (64 %), D 13 (46 %): passes; the right leg's bands are ignored.
        let mut regions = vec![
            region("B", l, 28.0),
            region("B1", l, 25.0),
            region("C", l, 18.0),
            region("D", l, 13.0),
            region("B", Side::Right, 50.0),
        ];
        let v = prescription_verdict(&p, &w, &[l], &regions, 60.0);
        assert!(v.pass, "{v:?}");
        assert_eq!(v.measured_b_mmhg, Some(28.0));
        assert_eq!(v.bands.len(), 4);
        // Both legs: the right leg's B (50 mmHg) fails, and its other bands are not covered.
        let both = prescription_verdict(&p, &w, &Side::BOTH, &regions, 60.0);
        assert!(!both.pass);
        assert_eq!(both.bands.len(), 5);
        assert_eq!(both.measured_b_mmhg, Some(28.0));
        assert!(!both.bands[4].pass && both.bands[4].side == Some(Side::Right));
        assert_eq!(v.bands[2].window_mmhg, [14.0, 22.4]);
        // C above 80 % of B fails, only C.
        regions[2] = region("C", l, 23.0);
        let v = prescription_verdict(&p, &w, &[l], &regions, 60.0);
        assert!(!v.pass);
        assert_eq!(
            v.bands.iter().map(|b| b.pass).collect::<Vec<_>>(),
            [true, true, false, true]
        );
        // B outside the class window fails B.
        regions[0] = region("B", l, 33.0);
        assert!(!prescription_verdict(&p, &w, &[l], &regions, 60.0).bands[0].pass);
        // No B band: fails, with B unmeasured.
        let v = prescription_verdict(&p, &w, &[l], &regions[1..], 60.0);
        assert!(!v.pass && v.measured_b_mmhg.is_none() && !v.bands[0].pass);
        let violations = prescription_violations(&v);
        assert_eq!(violations.len(), v.bands.iter().filter(|b| !b.pass).count());
        assert!(
            violations[0]
                .location
                .contains("band B on the left leg: not covered")
        );
        // A failing C names its value and window.
        regions[0] = region("B", l, 28.0);
        regions[2] = region("C", l, 23.0);
        let v = prescription_verdict(&p, &w, &[l], &regions, 60.0);
        let violations = prescription_violations(&v);
        assert_eq!(violations.len(), 1);
        let c = &violations[0];
        assert_eq!(
            (c.kind.as_str(), c.value, c.limit),
            ("prescription", 23.0, 22.4)
        );
        assert!(
            c.location
                .contains("23.0 mmHg, prescribed 14.0–22.4 mmHg (RAL-GZ 387 class 2)")
        );
    }

    /// Each band names its highest probe reading; a peak above the band's window is a warning (the band
    /// mean still passes) is flagged, a peak above the fabric's limit flagged and said in words.
    #[test]
    fn a_band_names_its_peak_and_flags_one_above_its_window_or_the_fabric_s_limit() {
        let p = ral(3);
        let w = p.windows("p", 60.0, LimbKind::Leg).unwrap();
        let l = Side::Left;
        let mut b = region("B", l, 40.0);
        b.pressure_mmhg.max = 58.0;
        let regions = vec![b, region("B1", l, 35.0)];
        let v = prescription_verdict(&p, &w, &[l], &regions, 60.0);
        assert!(v.pass, "{v:?}");
        assert_eq!(v.max_pressure_mmhg, 60.0);
        let band_b = &v.bands[0];
        assert_eq!(band_b.peak_mmhg, Some(58.0));
        assert!(band_b.peak_above_window && !band_b.peak_over_limit);
        assert_eq!(v.bands[1].peak_mmhg, Some(36.0));
        assert!(!v.bands[1].peak_above_window && !v.bands[1].peak_over_limit);
        // Above the window only: flagged in the table, no warning sentence.
        assert!(v.warnings.is_empty(), "{:?}", v.warnings);
        // Above the fabric's limit: flagged, and said to be not admissible.
        let v = prescription_verdict(&p, &w, &[l], &regions, 55.0);
        assert!(v.bands[0].peak_over_limit && v.bands[0].peak_limit_mmhg == 55.0);
        assert_eq!(v.warnings.len(), 1, "{:?}", v.warnings);
        assert!(
            v.warnings[0].starts_with(
                "band B (left): a probe reads 58.0 mmHg, above the fabric's limit of 55.0 mmHg (not \
                 admissible"
            ),
            "{}",
            v.warnings[0]
        );
        // A band not covered has no peak and no flag.
        let v = prescription_verdict(&p, &w, &[l], &regions[1..], 60.0);
        assert_eq!(v.bands[0].peak_mmhg, None);
        assert!(!v.bands[0].peak_over_limit && !v.bands[0].peak_above_window);
    }
}
