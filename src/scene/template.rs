//! Garment templates anchored to body landmarks (`garment.template`, an alternative to `garment.panels`).
//!
//! A template is data: a JSON file per template (`templates/garments/NAME.json` in the repository, built in;
//! a shop adds or overrides templates by putting `NAME.json` files in the folder named by the environment
//! variable `SKINTIGHT_GARMENT_TEMPLATES`). It says which limb the garment covers (`leg`, `arm`, or `legs`:
//! both legs and the torso up to a torso landmark), where it starts and ends (anchors: a landmark, or a
//! fraction of the way from one landmark to another, plus an offset, along the limb axis), how its seams
//! run (`front_back`: seams along the medial and lateral sides, panels front and back; `medial_lateral`:
//! seams at the front and the back), and the two panel names.
//!
//! **Resolution** ([`resolve_template`]): the body is measured ([`measure_body`]), and each panel becomes
//! ordinary `half_spaces`:
//! - two cut planes perpendicular to the limb axis at the anchors' distances along it (for `legs`: one
//!   ankle plane per leg, and a horizontal plane at the torso anchor's height);
//! - a seam plane through the limb axis (for `legs`: per side, the plane through that leg's axis, and the
//!   mid-plane: four panels, like the pants examples);
//! - bounding planes that keep the panel to its limb: four planes parallel to the axis, `margin_m` outside
//!   the limb's sections between the cuts (so a hand hanging beside the thigh or the other leg is not
//!   caught), and for a leg the body's mid-plane; for `legs`, two planes `x = const` `margin_m` outside the
//!   hips and legs, which keep the hands out (refused if a hand hangs closer).
//!
//! The resolved panels are an ordinary scene (written by `simulate` as `resolved_scene.json`), so a job
//! is reproducible without the template. Units: metres.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use skintight_geometry::anthropometry::landmarks::Measurements;
use skintight_geometry::anthropometry::plane_section::plane_section;
use skintight_geometry::anthropometry::{LimbAxis, MeasureError, Side, measure_body};
use skintight_geometry::region::HalfSpace;
use skintight_geometry::{TriMesh, Vec3};

use super::error::SceneError;
use super::spec::{Anchor, PanelShapeSpec, ScenePanel, TemplateSpec};

/// Which part of the body a template covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TemplateLimb {
    /// One leg (`side` required).
    Leg,
    /// One arm (`side` required).
    Arm,
    /// Both legs and the torso up to the top anchor (a torso landmark).
    Legs,
}

/// How the seams split the tube into two panels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SeamLayout {
    /// Panels front and back; seams along the medial and lateral sides.
    FrontBack,
    /// Panels medial and lateral; seams at the front and the back.
    MedialLateral,
}

/// A template file (`templates/garments/NAME.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GarmentTemplate {
    /// Its name (the file's stem).
    pub name: String,
    /// What it is, for people.
    #[serde(default)]
    pub description: String,
    /// The part of the body it covers.
    pub limb: TemplateLimb,
    /// Where it starts (the distal end).
    pub bottom: Anchor,
    /// Where it ends (towards the trunk).
    pub top: Anchor,
    /// The seam layout.
    pub seam: SeamLayout,
    /// The two panel names: front and back, or medial and lateral.
    pub panels: [String; 2],
    /// The openings that must grip without silicone (a waistband, a thigh band, a wrist hem): each the
    /// band of a landmark (`result.json`'s `regions`) with the least band-mean pressure it needs. Checked
    /// in the verdict of every garment cut from the template, and aimed at by its design
    /// (`src/simulate/grip.rs`). Default none.
    #[serde(default)]
    pub grip: Vec<GripBand>,
}

/// An opening that must grip: the landmark band at it and its least pressure.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GripBand {
    /// The landmark whose band is the opening (`waist`, `G`, `wrist`, …; on the garment's limb, or on
    /// both legs for a `legs` template's leg landmark).
    pub landmark: String,
    /// The least band-mean interface pressure (mmHg, > 0) that holds the opening up without silicone;
    /// besides, no 5 cm probe in the band may read below 0 (the fabric lifting off the skin).
    pub min_pressure_mmhg: f64,
}

/// The built-in templates: (name, JSON).
pub const BUILTIN_TEMPLATES: [(&str, &str); 5] = [
    (
        "knee_high",
        include_str!("../../templates/garments/knee_high.json"),
    ),
    (
        "thigh_high",
        include_str!("../../templates/garments/thigh_high.json"),
    ),
    (
        "leggings",
        include_str!("../../templates/garments/leggings.json"),
    ),
    (
        "calf_sleeve",
        include_str!("../../templates/garments/calf_sleeve.json"),
    ),
    (
        "arm_sleeve",
        include_str!("../../templates/garments/arm_sleeve.json"),
    ),
];

/// The environment variable naming a shop's template folder.
pub const TEMPLATES_ENV: &str = "SKINTIGHT_GARMENT_TEMPLATES";

const KEY: &str = "garment.template";

/// The template `name`: the shop's `NAME.json` in the folder of [`TEMPLATES_ENV`] if there is one, else the
/// built-in one.
pub fn find_template(name: &str) -> Result<GarmentTemplate, SceneError> {
    let key = format!("{KEY}.name");
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        return Err(SceneError::new(
            key,
            format!("'{name}' is not a template name (letters, digits, _ and - only)"),
        ));
    }
    let parse = |text: &str, from: &str| -> Result<GarmentTemplate, SceneError> {
        let t: GarmentTemplate = serde_json::from_str(text).map_err(|e| {
            SceneError::new(key.clone(), format!("template {from} is not valid: {e}"))
        })?;
        if t.name != name {
            return Err(SceneError::new(
                key.clone(),
                format!("template {from} is named '{}', not '{name}'", t.name),
            ));
        }
        Ok(t)
    };
    if let Some(dir) = std::env::var_os(TEMPLATES_ENV) {
        let path = PathBuf::from(dir).join(format!("{name}.json"));
        if path.is_file() {
            let text = std::fs::read_to_string(&path)
                .map_err(|e| SceneError::new(key.clone(), format!("{}: {e}", path.display())))?;
            return parse(&text, &path.display().to_string());
        }
    }
    match BUILTIN_TEMPLATES.iter().find(|(n, _)| *n == name) {
        Some((_, text)) => parse(text, &format!("'{name}'")),
        None => Err(SceneError::new(
            key,
            format!(
                "no template '{name}' (built in: {})",
                BUILTIN_TEMPLATES
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}

impl TemplateSpec {
    /// Checks what can be checked without a body: the template exists, the side fits its limb, the
    /// options are finite.
    pub fn validate(&self) -> Result<GarmentTemplate, SceneError> {
        let t = find_template(&self.name)?;
        match (t.limb, self.side) {
            (TemplateLimb::Legs, Some(_)) => {
                return Err(SceneError::new(
                    format!("{KEY}.side"),
                    format!("template '{}' covers both legs: give no side", t.name),
                ));
            }
            (TemplateLimb::Leg | TemplateLimb::Arm, None) => {
                return Err(SceneError::new(
                    format!("{KEY}.side"),
                    format!("template '{}' needs a side: left or right", t.name),
                ));
            }
            _ => {}
        }
        if let Some(m) = self.options.margin_m
            && !(m.is_finite() && (0.0..=0.2).contains(&m))
        {
            return Err(SceneError::new(
                format!("{KEY}.options.margin_m"),
                "must be finite, in [0, 0.2] m",
            ));
        }
        for (k, a) in [("bottom", &self.options.bottom), ("top", &self.options.top)] {
            if let Some(a) = a
                && !(a.fraction.is_finite() && a.offset_m.is_finite())
            {
                return Err(SceneError::new(
                    format!("{KEY}.options.{k}"),
                    "fraction and offset_m must be finite",
                ));
            }
        }
        Ok(t)
    }
}

fn landmark_s(
    m: &Measurements,
    side: Side,
    name: &str,
    which: &str,
    axis: &LimbAxis,
) -> Result<f64, SceneError> {
    let l = m.landmark(name, Some(side)).ok_or_else(|| {
        SceneError::new(
            format!("{KEY}.{which}"),
            format!(
                "'{name}' is not a landmark of the {} {:?}",
                side.name(),
                axis.kind
            ),
        )
    })?;
    l.axis_m
        .filter(|_| l.normal == axis.direction)
        .ok_or_else(|| {
            SceneError::new(
                format!("{KEY}.{which}"),
                format!("'{name}' is not on the {} {:?}", side.name(), axis.kind),
            )
        })
}

fn anchor_s(
    m: &Measurements,
    side: Side,
    a: &Anchor,
    which: &str,
    axis: &LimbAxis,
) -> Result<f64, SceneError> {
    let s0 = landmark_s(m, side, &a.landmark, which, axis)?;
    let s = match &a.toward {
        Some(t) => s0 + a.fraction * (landmark_s(m, side, t, which, axis)? - s0),
        None => s0,
    };
    Ok(s + a.offset_m)
}

fn torso_height(m: &Measurements, a: &Anchor) -> Result<f64, SceneError> {
    let y = |name: &str| {
        m.landmark(name, None).map(|l| l.point[1]).ok_or_else(|| {
            SceneError::new(
                format!("{KEY}.top"),
                format!("'{name}' is not a torso landmark (crotch, hip, waist)"),
            )
        })
    };
    let y0 = y(&a.landmark)?;
    let v = match &a.toward {
        Some(t) => y0 + a.fraction * (y(t)? - y0),
        None => y0,
    };
    Ok(v + a.offset_m)
}

fn hs(n: Vec3, offset: f64) -> HalfSpace {
    HalfSpace { normal: n, offset }
}

/// The front direction across the limb axis `d`: `+z` made perpendicular to `d`.
fn front_across(d: Vec3) -> Vec3 {
    (Vec3::z() - d * d.z).normalize()
}

/// Resolves `spec` on `body` (the body surface, metres, +y up, facing +z) into half-space panels: the
/// template's two panels for one limb; for `legs`, four (`left_front`, `left_back`, `right_front`,
/// `right_back` with the template's panel names), split also at the mid-plane.
pub fn resolve_template(
    spec: &TemplateSpec,
    body: &TriMesh,
) -> Result<Vec<ScenePanel>, SceneError> {
    resolve_template_measured(spec, body, measure_body(body).as_ref())
}

/// [`resolve_template`] with the body's measurements already taken (`measured`: what
/// [`measure_body`] gave for `body`), so a job measures its body once.
pub fn resolve_template_measured(
    spec: &TemplateSpec,
    body: &TriMesh,
    measured: Result<&Measurements, &MeasureError>,
) -> Result<Vec<ScenePanel>, SceneError> {
    let t = spec.validate()?;
    let m = measured.map_err(|e| {
        SceneError::new(
            KEY,
            format!("template '{}' needs the body's landmarks: {e}", t.name),
        )
    })?;
    let bottom = spec.options.bottom.clone().unwrap_or(t.bottom.clone());
    let top = spec.options.top.clone().unwrap_or(t.top.clone());
    let margin = spec.options.margin_m.unwrap_or(0.02);
    let seg = &m.segmentation;
    let panel = |name: &str, half_spaces: Vec<HalfSpace>| ScenePanel {
        name: name.to_string(),
        shape: PanelShapeSpec::HalfSpaces(half_spaces),
    };
    let (common, seam_n, seam_p) = match t.limb {
        TemplateLimb::Leg | TemplateLimb::Arm => {
            let side = spec.side.expect("validated");
            let axis = if t.limb == TemplateLimb::Leg {
                seg.leg(side)
            } else {
                seg.arm(side)
            };
            let (s0, s1) = (
                anchor_s(m, side, &bottom, "bottom", axis)?,
                anchor_s(m, side, &top, "top", axis)?,
            );
            if !(0.0 <= s0 && s0 + 0.02 < s1 && s1 <= axis.length_m) {
                return Err(SceneError::new(
                    KEY,
                    format!(
                        "the garment would run from {s0:.3} m to {s1:.3} m along the limb axis (length \
                         {:.3} m): the bottom must lie at least 2 cm below the top, both on the limb",
                        axis.length_m
                    ),
                ));
            }
            let d = axis.dir();
            let front = front_across(d);
            let mut lateral = d.cross(&front);
            if lateral.x * side.sign() < 0.0 {
                lateral = -lateral;
            }
            let a = axis.point(s0);
            // Extents of the limb's sections between the cuts (and 2 cm beyond) across the axis.
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            let n = (((s1 - s0) + 0.04) / 0.01).ceil() as usize;
            for k in 0..=n {
                let s = (s0 - 0.02 + k as f64 * 0.01).clamp(0.0, axis.length_m);
                if let Some(l) = axis.section(body, s) {
                    let c = axis.point(s);
                    for p in &l.points {
                        for (i, e) in [front, lateral].iter().enumerate() {
                            let u = e.dot(&(p - c));
                            lo[i] = lo[i].min(u);
                            hi[i] = hi[i].max(u);
                        }
                    }
                }
            }
            if !(lo[0].is_finite() && lo[1].is_finite()) {
                return Err(SceneError::new(
                    KEY,
                    "no section of the limb between the cuts",
                ));
            }
            let mut common = vec![
                hs(-d, -d.dot(&axis.point(s0))),
                hs(d, d.dot(&axis.point(s1))),
            ];
            for (i, e) in [front, lateral].iter().enumerate() {
                common.push(hs(*e, e.dot(&a) + hi[i] + margin));
                common.push(hs(-*e, -(e.dot(&a) + lo[i] - margin)));
            }
            if t.limb == TemplateLimb::Leg {
                let sg = side.sign();
                common.push(hs(Vec3::new(-sg, 0.0, 0.0), -sg * seg.mid_x));
            }
            let seam_n = match t.seam {
                SeamLayout::FrontBack => front,
                SeamLayout::MedialLateral => -lateral,
            };
            (common, seam_n, a)
        }
        TemplateLimb::Legs => {
            let top_y = torso_height(m, &top)?;
            let crotch_y = seg.crotch[1];
            if top_y <= crotch_y + 0.02 {
                return Err(SceneError::new(
                    format!("{KEY}.top"),
                    "the top of a legs garment must lie at least 2 cm above the crotch",
                ));
            }
            let mut common = vec![hs(Vec3::y(), top_y)];
            for side in Side::BOTH {
                let axis = seg.leg(side);
                let s0 = anchor_s(m, side, &bottom, "bottom", axis)?;
                let d = axis.dir();
                common.push(hs(-d, -d.dot(&axis.point(s0))));
                // Lateral extent of the leg and of the torso below the top.
                let sg = side.sign();
                let mut x = f64::NEG_INFINITY;
                let mut k = 0;
                while s0 + k as f64 * 0.01 <= axis.length_m {
                    if let Some(l) = axis.section(body, s0 + k as f64 * 0.01) {
                        x = l
                            .points
                            .iter()
                            .map(|p| sg * (p.x - seg.mid_x))
                            .fold(x, f64::max);
                    }
                    k += 1;
                }
                let mut y = crotch_y + 0.005;
                while y <= top_y + 0.02 {
                    if let Some(l) = plane_section(body, Vec3::y(), y)
                        .into_iter()
                        .max_by(|a, b| a.area(Vec3::y()).total_cmp(&b.area(Vec3::y())))
                    {
                        x = l
                            .points
                            .iter()
                            .map(|p| sg * (p.x - seg.mid_x))
                            .fold(x, f64::max);
                    }
                    y += 0.01;
                }
                let bound = x + margin;
                // The hand must hang clear of that bound.
                let arm = seg.arm(side);
                let tip = arm.point(0.0);
                let wrist = m.landmark("wrist", Some(side)).map(|l| Vec3::from(l.point));
                for p in std::iter::once(tip).chain(wrist) {
                    if p.y < top_y && sg * (p.x - seg.mid_x) < bound + 0.03 {
                        return Err(SceneError::new(
                            KEY,
                            format!(
                                "the {} hand hangs within {:.0} cm of the hip: template '{}' cannot be \
                                 cut clear of it (stand the body with the arms further out)",
                                side.name(),
                                100.0 * (sg * (p.x - seg.mid_x) - x).max(0.0),
                                t.name
                            ),
                        ));
                    }
                }
                common.push(hs(Vec3::new(sg, 0.0, 0.0), sg * seg.mid_x + bound));
            }
            // Four panels: each side's front and back, split at the mid-plane (centre front and back
            // seams) and by the plane through that leg's axis across the front direction (side seams).
            let mut panels = Vec::new();
            for side in Side::BOTH {
                let axis = seg.leg(side);
                let d = axis.dir();
                let seam_n = match t.seam {
                    SeamLayout::FrontBack => front_across(d),
                    SeamLayout::MedialLateral => {
                        return Err(SceneError::new(
                            KEY,
                            format!(
                                "template '{}': a legs garment has front and back panels (seam front_back)",
                                t.name
                            ),
                        ));
                    }
                };
                let a = axis.point(axis.length_m);
                let sg = side.sign();
                let mut half = common.clone();
                half.push(hs(Vec3::new(-sg, 0.0, 0.0), -sg * seg.mid_x));
                for (k, n) in [seam_n, -seam_n].into_iter().enumerate() {
                    let mut h = half.clone();
                    h.push(hs(-n, -n.dot(&a)));
                    panels.push(panel(&format!("{}_{}", side.name(), t.panels[k]), h));
                }
            }
            return Ok(panels);
        }
    };
    let (first, second) = (seam_n, -seam_n);
    let mut a = common.clone();
    a.push(hs(-first, -first.dot(&seam_p)));
    let mut b = common;
    b.push(hs(-second, -second.dot(&seam_p)));
    Ok(vec![panel(&t.panels[0], a), panel(&t.panels[1], b)])
}
