//! The scene's `patterns` section (docs/SCENE.md): how the cut-ready pattern files are drawn — seam
//! allowances, corners, notches, paper, seam truing, the marker's fabric — and the order's text printed on
//! every piece. All lengths in metres. Also the mapping of the pattern model's errors onto these keys.

use serde::{Deserialize, Serialize};
use skintight_garment::marker::{MarkerError, MarkerParams};
use skintight_garment::pattern::{
    CornerStyle, OrderLabels, PatternError, PatternParams, UserNotch,
};
use skintight_geometry::math::Real;

use super::error::SceneError;

/// Largest seam or opening allowance accepted (m): wider than any hem a knit garment takes.
pub const MAX_ALLOWANCE: Real = 0.05;
/// Range of the automatic notch spacing (m).
pub const NOTCH_SPACING_RANGE: (Real, Real) = (0.01, 2.0);
/// Largest notch depth (m).
pub const MAX_NOTCH_DEPTH: Real = 0.02;
/// Longest text of an order field (characters).
pub const MAX_TEXT: usize = 200;
/// Most user notches and per-seam allowances.
pub const MAX_LIST: usize = 1000;
/// Widest fabric a marker is made for (m): past any knitting machine's or cutting table's width.
pub const MAX_FABRIC_WIDTH: Real = 10.0;

/// The `patterns` section: everything about the pattern files, all optional.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatternsSpec {
    /// Seam allowance of every seam (m), in [0, 0.05]; default 0.006 (an overlock seam on knits).
    #[serde(default = "default_seam_allowance")]
    pub seam_allowance: Real,
    /// Allowance of the garment's openings — hems, waist, cuffs (m), in [0, 0.05]; default 0.02 (a turned,
    /// coverstitched hem).
    #[serde(default = "default_opening_allowance")]
    pub opening_allowance: Real,
    /// Per-seam allowances overriding `seam_allowance`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub seam_allowances: Vec<SeamAllowanceSpec>,
    /// How convex corners between a seam and an opening are drawn in the cut line; default `"mitre"`.
    #[serde(default)]
    pub corners: CornerSpec,
    /// Distance between the automatic notches along every seam (m), in [0.01, 2]; default 0.1.
    #[serde(default = "default_notch_spacing")]
    pub notch_spacing: Real,
    /// Depth of a notch slit into the allowance (m), in [0, 0.02]; default 0.003 (never deeper than the
    /// allowance where it is cut).
    #[serde(default = "default_notch_depth")]
    pub notch_depth: Real,
    /// Extra notches, on both sides of a seam.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notches: Vec<NotchSpec>,
    /// Paper of the tiled PDF (`patterns-a4.pdf`); default `"a4"`.
    #[serde(default)]
    pub paper: PaperSpec,
    /// Whether the two sides of every seam are made equally long before the simulation (and after a
    /// design), so that the pieces sew up; default true.
    #[serde(default = "default_true")]
    pub true_seams: bool,
    /// The order's text, printed on every piece.
    #[serde(default)]
    pub order: OrderSpec,
    /// The marker (`patterns-marker.pdf`/`.dxf`): the fabric the pieces are packed on.
    #[serde(default)]
    pub marker: MarkerSpec,
}

/// The `patterns.marker` section.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerSpec {
    /// Width of the fabric (m), across the grain; in (0, 10] and at least every piece's extent across its
    /// grain plus the marker's 2 mm gap. Default 1.5.
    #[serde(default = "default_fabric_width")]
    pub width_m: Real,
}

impl Default for MarkerSpec {
    fn default() -> Self {
        MarkerSpec {
            width_m: default_fabric_width(),
        }
    }
}

impl MarkerSpec {
    /// The marker's settings.
    pub fn params(&self) -> MarkerParams {
        MarkerParams {
            width: self.width_m,
            ..MarkerParams::default()
        }
    }

    /// The scene key a marker error is about, with its message.
    pub fn error(&self, e: &MarkerError) -> SceneError {
        let key = match e {
            MarkerError::BadParameter { field: "width", .. } | MarkerError::TooWide { .. } => {
                "patterns.marker.width_m"
            }
            _ => "patterns.marker",
        };
        SceneError::new(key, e.to_string())
    }
}

/// A per-seam allowance: `{"seam": 2, "allowance": 0.01}`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeamAllowanceSpec {
    /// The seam's number as printed on the pieces (1-based).
    pub seam: usize,
    /// Its allowance (m), in [0, 0.05].
    pub allowance: Real,
}

/// A user notch: `{"seam": 1, "at": 0.15}`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NotchSpec {
    /// The seam's number as printed on the pieces (1-based).
    pub seam: usize,
    /// Arc length from the seam's start (m), between 0 and the seam's length.
    pub at: Real,
}

/// Corner drawing of the cut line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CornerSpec {
    /// `"mitre"`: the allowance lines meet at their intersection.
    #[default]
    Mitre,
    /// `"square"`: each allowance line runs on past the corner by the other's allowance.
    Square,
}

/// Paper sizes of the tiled PDF.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PaperSpec {
    /// `"a4"`: 210 × 297 mm.
    #[default]
    A4,
    /// `"letter"`: US Letter, 8.5 × 11 in (215.9 × 279.4 mm).
    Letter,
    /// `"a3"`: 297 × 420 mm.
    A3,
}

/// The order's text fields (each at most 200 characters; empty when left out).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrderSpec {
    /// The shop's order id.
    #[serde(default)]
    pub id: String,
    /// The customer's reference.
    #[serde(default)]
    pub customer: String,
    /// The garment template (e.g. "knee-high stocking").
    #[serde(default)]
    pub template: String,
    /// Size or compression class.
    #[serde(default)]
    pub size: String,
    /// The fabric's name.
    #[serde(default)]
    pub fabric: String,
    /// The date printed on the pieces (`YYYY-MM-DD`); default: the day the files are written (UTC).
    #[serde(default)]
    pub date: String,
}

fn default_seam_allowance() -> Real {
    0.006
}
fn default_opening_allowance() -> Real {
    0.02
}
fn default_notch_spacing() -> Real {
    0.1
}
fn default_notch_depth() -> Real {
    0.003
}
fn default_true() -> bool {
    true
}
fn default_fabric_width() -> Real {
    1.5
}

impl Default for PatternsSpec {
    fn default() -> Self {
        Self {
            seam_allowance: default_seam_allowance(),
            opening_allowance: default_opening_allowance(),
            seam_allowances: Vec::new(),
            corners: CornerSpec::Mitre,
            notch_spacing: default_notch_spacing(),
            notch_depth: default_notch_depth(),
            notches: Vec::new(),
            paper: PaperSpec::A4,
            true_seams: true,
            order: OrderSpec::default(),
            marker: MarkerSpec::default(),
        }
    }
}

fn in_range(key: &str, x: Real, lo: Real, hi: Real) -> Result<(), SceneError> {
    if !(x.is_finite() && x >= lo && x <= hi) {
        return Err(SceneError::new(
            key,
            format!("must be a length between {lo} and {hi} m, got {x}"),
        ));
    }
    Ok(())
}

impl PatternsSpec {
    /// Checks every value that does not depend on the garment (key `patterns.…`).
    pub fn validate(&self) -> Result<(), SceneError> {
        in_range(
            "patterns.seam_allowance",
            self.seam_allowance,
            0.0,
            MAX_ALLOWANCE,
        )?;
        in_range(
            "patterns.opening_allowance",
            self.opening_allowance,
            0.0,
            MAX_ALLOWANCE,
        )?;
        let w = self.marker.width_m;
        if !(w.is_finite() && w > 0.0 && w <= MAX_FABRIC_WIDTH) {
            return Err(SceneError::new(
                "patterns.marker.width_m",
                format!(
                    "must be the fabric's width, a length in (0, {MAX_FABRIC_WIDTH}] m, got {w}"
                ),
            ));
        }
        let (lo, hi) = NOTCH_SPACING_RANGE;
        in_range("patterns.notch_spacing", self.notch_spacing, lo, hi)?;
        in_range(
            "patterns.notch_depth",
            self.notch_depth,
            0.0,
            MAX_NOTCH_DEPTH,
        )?;
        for (key, len) in [
            ("patterns.seam_allowances", self.seam_allowances.len()),
            ("patterns.notches", self.notches.len()),
        ] {
            if len > MAX_LIST {
                return Err(SceneError::new(
                    key,
                    format!("has {len} entries; at most {MAX_LIST} are accepted"),
                ));
            }
        }
        for (i, s) in self.seam_allowances.iter().enumerate() {
            if s.seam == 0 {
                return Err(SceneError::new(
                    format!("patterns.seam_allowances[{i}].seam"),
                    "seams are numbered from 1, as printed on the pieces",
                ));
            }
            in_range(
                &format!("patterns.seam_allowances[{i}].allowance"),
                s.allowance,
                0.0,
                MAX_ALLOWANCE,
            )?;
        }
        for (i, n) in self.notches.iter().enumerate() {
            if n.seam == 0 {
                return Err(SceneError::new(
                    format!("patterns.notches[{i}].seam"),
                    "seams are numbered from 1, as printed on the pieces",
                ));
            }
            if !(n.at.is_finite() && n.at >= 0.0) {
                return Err(SceneError::new(
                    format!("patterns.notches[{i}].at"),
                    format!("must be a length ≥ 0 m along the seam, got {}", n.at),
                ));
            }
        }
        let o = &self.order;
        for (key, text) in [
            ("patterns.order.id", &o.id),
            ("patterns.order.customer", &o.customer),
            ("patterns.order.template", &o.template),
            ("patterns.order.size", &o.size),
            ("patterns.order.fabric", &o.fabric),
            ("patterns.order.date", &o.date),
        ] {
            if text.chars().count() > MAX_TEXT {
                return Err(SceneError::new(
                    key,
                    format!("is longer than {MAX_TEXT} characters"),
                ));
            }
            if text.chars().any(char::is_control) {
                return Err(SceneError::new(
                    key,
                    "must be one line of text without control characters",
                ));
            }
        }
        if !o.date.is_empty() && !is_iso_date(&o.date) {
            return Err(SceneError::new(
                "patterns.order.date",
                format!("must be a date written YYYY-MM-DD, got '{}'", o.date),
            ));
        }
        Ok(())
    }

    /// The pattern model's settings (seams renumbered from 0).
    pub fn params(&self) -> PatternParams {
        PatternParams {
            seam_allowance: self.seam_allowance,
            opening_allowance: self.opening_allowance,
            seam_allowances: self
                .seam_allowances
                .iter()
                .map(|s| (s.seam.saturating_sub(1), s.allowance))
                .collect(),
            corner: match self.corners {
                CornerSpec::Mitre => CornerStyle::Mitre,
                CornerSpec::Square => CornerStyle::Square,
            },
            notch_spacing: self.notch_spacing,
            notch_depth: self.notch_depth,
            notches: self
                .notches
                .iter()
                .map(|n| UserNotch {
                    seam: n.seam.saturating_sub(1),
                    arc_length: n.at,
                })
                .collect(),
            ..PatternParams::default()
        }
    }

    /// The text printed on the pieces: the order's fields, `template` defaulting to `fallback_template`,
    /// the date defaulting to today (UTC), and this software's name and version.
    pub fn labels(&self, fallback_template: &str) -> OrderLabels {
        let o = &self.order;
        OrderLabels {
            order_id: o.id.clone(),
            customer: o.customer.clone(),
            template: if o.template.is_empty() {
                fallback_template.to_string()
            } else {
                o.template.clone()
            },
            size: o.size.clone(),
            fabric: o.fabric.clone(),
            date: if o.date.is_empty() {
                today_utc()
            } else {
                o.date.clone()
            },
            software: format!("skintight {}", env!("CARGO_PKG_VERSION")),
        }
    }

    /// The scene key a pattern model error is about.
    pub fn error(&self, e: &PatternError) -> SceneError {
        let key = match e {
            PatternError::BadParameter { field, .. } => format!("patterns.{field}"),
            PatternError::NoSuchSeam { field, index, .. } => {
                format!("patterns.{field}[{index}].seam")
            }
            PatternError::NotchOffSeam { index, .. } => format!("patterns.notches[{index}].at"),
            PatternError::NotADisk { .. } => "garment.panels".into(),
            PatternError::CutLine { opening: true, .. } => "patterns.opening_allowance".into(),
            PatternError::CutLine { .. } => "patterns.seam_allowance".into(),
        };
        SceneError::new(key, e.to_string())
    }
}

/// Whether `s` is a calendar date written `YYYY-MM-DD`.
fn is_iso_date(s: &str) -> bool {
    let parts: Vec<&str> = s.split('-').collect();
    let [y, m, d] = parts.as_slice() else {
        return false;
    };
    if y.len() != 4 || m.len() != 2 || d.len() != 2 {
        return false;
    }
    let (Ok(y), Ok(m), Ok(d)) = (y.parse::<i64>(), m.parse::<u32>(), d.parse::<u32>()) else {
        return false;
    };
    let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    let days = [
        31,
        if leap { 29 } else { 28 },
        31,
        30,
        31,
        30,
        31,
        31,
        30,
        31,
        30,
        31,
    ];
    (1..=12).contains(&m) && d >= 1 && d <= days[(m - 1) as usize]
}

/// Today's date in UTC, `YYYY-MM-DD` (the proleptic Gregorian calendar from the Unix day number).
pub fn today_utc() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    civil_date(secs.div_euclid(86_400))
}

/// The calendar date of day `days` after 1970-01-01 (H. Hinnant's days-to-civil algorithm).
fn civil_date(days: i64) -> String {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + if m <= 2 { 1 } else { 0 };
    format!("{y:04}-{m:02}-{d:02}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;
    use crate::scene::tests::{minimal, with};

    #[test]
    fn the_scene_reads_its_patterns_section_and_names_bad_keys() {
        let s = Scene::from_json(&minimal().to_string()).unwrap();
        assert_eq!(s.patterns, PatternsSpec::default());
        let doc = with(
            minimal(),
            "/patterns",
            serde_json::json!({
                "seam_allowance": 0.008, "corners": "square", "paper": "letter",
                "notches": [{"seam": 1, "at": 0.05}], "seam_allowances": [{"seam": 1, "allowance": 0.01}],
                "order": {"id": "A-1", "customer": "Jo", "date": "2026-12-01"}
            }),
        );
        let s = Scene::from_json(&doc.to_string()).unwrap();
        assert_eq!(s.patterns.marker.width_m, 1.5);
        assert_eq!(s.patterns.paper, PaperSpec::Letter);
        assert_eq!(s.patterns.corners, CornerSpec::Square);
        let params = s.patterns.params();
        assert_eq!(params.seam_allowance, 0.008);
        assert_eq!(params.seam_allowances, vec![(0, 0.01)]);
        assert_eq!(params.notches[0].seam, 0);
        let labels = s.patterns.labels("tube");
        assert_eq!(
            (labels.order_id.as_str(), labels.template.as_str()),
            ("A-1", "tube")
        );
        assert_eq!(labels.date, "2026-12-01");
        assert!(labels.software.starts_with("skintight "));
        for (value, key) in [
            (serde_json::json!({"paper": "tabloid"}), "patterns.paper"),
            (serde_json::json!({"corners": "round"}), "patterns.corners"),
            (
                serde_json::json!({"seam_alowance": 0.01}),
                "patterns.seam_alowance",
            ),
            (
                serde_json::json!({"seam_allowance": 0.2}),
                "patterns.seam_allowance",
            ),
            (
                serde_json::json!({"notches": [{"seam": 1}]}),
                "patterns.notches[0]",
            ),
            (serde_json::json!({"order": {"id": 7}}), "patterns.order.id"),
            (
                serde_json::json!({"marker": {"width": 1.5}}),
                "patterns.marker.width",
            ),
            (
                serde_json::json!({"marker": {"width_m": -1.5}}),
                "patterns.marker.width_m",
            ),
        ] {
            let e = Scene::from_json(&with(minimal(), "/patterns", value.clone()).to_string())
                .expect_err("refused");
            assert!(e.key.starts_with(key), "{value}: {e}");
        }
    }

    #[test]
    fn pattern_errors_name_their_key() {
        use skintight_garment::pattern::seam_allowance::OffsetError;
        let spec = PatternsSpec::default();
        let cut = |opening| PatternError::CutLine {
            piece: "front".into(),
            allowance: 0.05,
            opening,
            source: OffsetError::SelfIntersects {
                first: 3,
                second: 40,
            },
        };
        assert_eq!(spec.error(&cut(true)).key, "patterns.opening_allowance");
        let e = spec.error(&cut(false));
        assert_eq!(e.key, "patterns.seam_allowance");
        assert!(
            e.message.contains("front") && e.message.contains("reduce"),
            "{e}"
        );
        let off = PatternError::NotchOffSeam {
            index: 2,
            seam: 1,
            arc_length: 5.0,
            length: 0.6,
        };
        assert_eq!(spec.error(&off).key, "patterns.notches[2].at");
        let bad = PatternError::BadParameter {
            field: "notch_spacing",
            value: 0.0,
            expected: "> 0",
        };
        assert_eq!(spec.error(&bad).key, "patterns.notch_spacing");
    }

    #[test]
    fn dates_are_civil() {
        assert_eq!(civil_date(0), "1970-01-01");
        assert_eq!(civil_date(11_016), "2000-02-29");
        assert_eq!(civil_date(20_788), "2026-12-01");
        assert!(is_iso_date("2026-12-01") && is_iso_date("2024-02-29"));
        assert!(!is_iso_date("2025-02-29") && !is_iso_date("2026-13-01") && !is_iso_date("26-1-1"));
        assert!(is_iso_date(&today_utc()));
    }

    #[test]
    fn validation_names_the_key() {
        let ok = PatternsSpec::default();
        assert!(ok.validate().is_ok());
        let cases: Vec<(PatternsSpec, &str)> = vec![
            (
                PatternsSpec {
                    seam_allowance: -0.001,
                    ..ok.clone()
                },
                "patterns.seam_allowance",
            ),
            (
                PatternsSpec {
                    opening_allowance: 0.5,
                    ..ok.clone()
                },
                "patterns.opening_allowance",
            ),
            (
                PatternsSpec {
                    notch_spacing: 0.0,
                    ..ok.clone()
                },
                "patterns.notch_spacing",
            ),
            (
                PatternsSpec {
                    notch_depth: Real::NAN,
                    ..ok.clone()
                },
                "patterns.notch_depth",
            ),
            (
                PatternsSpec {
                    marker: MarkerSpec { width_m: 0.0 },
                    ..ok.clone()
                },
                "patterns.marker.width_m",
            ),
            (
                PatternsSpec {
                    marker: MarkerSpec {
                        width_m: Real::INFINITY,
                    },
                    ..ok.clone()
                },
                "patterns.marker.width_m",
            ),
            (
                PatternsSpec {
                    notches: vec![NotchSpec { seam: 0, at: 0.1 }],
                    ..ok.clone()
                },
                "patterns.notches[0].seam",
            ),
            (
                PatternsSpec {
                    notches: vec![NotchSpec { seam: 1, at: -1.0 }],
                    ..ok.clone()
                },
                "patterns.notches[0].at",
            ),
            (
                PatternsSpec {
                    seam_allowances: vec![SeamAllowanceSpec {
                        seam: 1,
                        allowance: 1.0,
                    }],
                    ..ok.clone()
                },
                "patterns.seam_allowances[0].allowance",
            ),
            (
                PatternsSpec {
                    order: OrderSpec {
                        customer: "a\nb".into(),
                        ..Default::default()
                    },
                    ..ok.clone()
                },
                "patterns.order.customer",
            ),
            (
                PatternsSpec {
                    order: OrderSpec {
                        date: "2026-02-30".into(),
                        ..Default::default()
                    },
                    ..ok.clone()
                },
                "patterns.order.date",
            ),
        ];
        for (spec, key) in cases {
            assert_eq!(spec.validate().unwrap_err().key, key);
        }
    }
}
