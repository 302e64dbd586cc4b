//! Body segmentation of a standing body surface: the floor, the mid-plane, the crotch, and the axis of each
//! leg and arm. The torso is what lies between the crotch and the armpits; the legs below the crotch,
//! the arms beyond the armpits.
//!
//! **Frame.** The bodies of `data/bodies`: metres, +y up, facing +z, standing in an A-pose (or an I-pose
//! with the arms clear of the torso). The body's left side is `+x` of the mid-plane.
//!
//! **Method.** Every rule works on plane sections ([`super::plane_section`]), never on vertices, so the
//! result depends on the surface and not on its resolution or vertex numbering.
//! - *Floor* and *top*: the lowest and highest vertex height; *stature* `H` their difference.
//! - *Mid-plane* `x = x₀`: `x₀` the area-weighted mean of the face centroids' `x`.
//! - *Crotch* (the crotch point of ISO 8559-1): the lowest point of the largest loop of the sagittal
//!   section `x = x₀` — between the legs there is no body in that plane. Its height above the floor `L`
//!   must lie in `[0.3, 0.65]·H`, and a horizontal section at half that height must show a leg on each side,
//!   or the body is refused ("no two legs below the torso").
//! - *Leg axes*: least-squares lines `x(y)`, `z(y)` through the area centroids of the largest loop on the
//!   leg's side of horizontal sections at 25 heights in `[0.25, 0.85]·L` (above the foot, below the crotch).
//! - *Arms*: horizontal sections every `H/200` from the floor to the top; below the crotch the second
//!   largest loop on a side (after the leg), above it the largest loop on a side other than the torso (the
//!   largest loop of the section) is the arm. The longest run of heights with an arm on that side spans
//!   from the fingertip to the armpit; both ends are refined by bisection to 0.1 mm. The arm's axis is first
//!   the least-squares line through the arm loops' centroids in the run's `[0.35, 0.9]` part (above the
//!   hand, whose fingers make the centroids depend on the mesh), then refitted three times to the centroids
//!   of the sections *perpendicular* to it in `[0.35, 0.85]` of its length (the horizontal sections cut an
//!   A-pose arm obliquely and are clipped by the torso near the armpit; the perpendicular sections'
//!   centroids make the axis the limb's own, independent of the axilla's last millimetres).
//! - *Armpit* along the arm axis: the largest distance from the fingertip at which the section
//!   perpendicular to the axis still gives an arm loop clear of the torso (it does not enclose the torso's
//!   vertical axis), by a scan every 5 mm and bisection.
//!
//! Units: metres; directions are unit vectors.

use serde::{Deserialize, Serialize};

use crate::math::{Real, Vec3};
use crate::mesh::TriMesh;

use super::plane_section::{SectionLoop, plane_section};

/// A side of the body: `left` is `+x` of the mid-plane (the body faces `+z`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// `+x` of the mid-plane.
    Left,
    /// `−x` of the mid-plane.
    Right,
}

impl Side {
    /// `+1` for the left (`+x`), `−1` for the right.
    pub fn sign(self) -> Real {
        match self {
            Side::Left => 1.0,
            Side::Right => -1.0,
        }
    }

    /// `"left"` or `"right"`.
    pub fn name(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }

    /// Both sides, left first.
    pub const BOTH: [Side; 2] = [Side::Left, Side::Right];
}

/// Leg or arm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LimbKind {
    /// A leg: from the floor to the crotch.
    Leg,
    /// An arm: from the fingertip to the armpit.
    Arm,
}

/// The straight axis of a limb: `distal + s·direction`, `s ∈ [0, length_m]` from the distal end (the
/// floor for a leg, the fingertip for an arm) to the proximal end (the crotch height, the armpit).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LimbAxis {
    /// Leg or arm.
    pub kind: LimbKind,
    /// Which side.
    pub side: Side,
    /// The axis point at the distal end (m).
    pub distal: [Real; 3],
    /// Unit direction from the distal towards the proximal end (its `y` is positive).
    pub direction: [Real; 3],
    /// Distance along the axis from the distal to the proximal end (m).
    pub length_m: Real,
}

impl LimbAxis {
    /// The axis point at distance `s` (m) from the distal end.
    pub fn point(&self, s: Real) -> Vec3 {
        Vec3::from(self.distal) + Vec3::from(self.direction) * s
    }

    /// The unit direction.
    pub fn dir(&self) -> Vec3 {
        Vec3::from(self.direction)
    }

    /// The section loop of `body` perpendicular to the axis at `s` that encloses the axis point (the one
    /// whose centroid is nearest it when none encloses it, if within 5 cm).
    pub fn section(&self, body: &TriMesh, s: Real) -> Option<SectionLoop> {
        let (n, a) = (self.dir(), self.point(s));
        let loops = plane_section(body, n, n.dot(&a));
        select_loop(loops, n, a, 0.05)
    }
}

/// The loop enclosing `a` (the smallest when nested), else the one whose centroid is nearest `a` if within
/// `reach` (m).
pub fn select_loop(loops: Vec<SectionLoop>, n: Vec3, a: Vec3, reach: Real) -> Option<SectionLoop> {
    let mut inside: Vec<(Real, SectionLoop)> = Vec::new();
    let mut best: Option<(Real, SectionLoop)> = None;
    for l in loops {
        if l.contains(n, a) {
            inside.push((l.area(n), l));
        } else {
            let d = (l.centroid(n) - a).norm();
            if d <= reach && best.as_ref().is_none_or(|(bd, _)| d < *bd) {
                best = Some((d, l));
            }
        }
    }
    inside.sort_by(|x, y| x.0.total_cmp(&y.0));
    inside.into_iter().next().or(best).map(|(_, l)| l)
}

/// Why a body cannot be measured.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeasureError {
    /// The mesh is empty or has a non-finite coordinate.
    #[error("the body mesh is {0}")]
    BadMesh(String),
    /// No crotch with a leg on each side.
    #[error("no two legs below the torso: is this a standing body, +y up? ({0})")]
    NoLegs(String),
    /// No arm clear of the torso on a side.
    #[error(
        "no {0} arm beside the torso: is the body in an A-pose (arms clear of the torso)? ({1})"
    )]
    NoArm(&'static str, String),
    /// A landmark's rule found nothing (a section missed the limb).
    #[error("landmark {0} not found: {1}")]
    NoLandmark(String, String),
}

/// The segmentation of a standing body (see the module documentation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segmentation {
    /// Height of the lowest point (m).
    pub floor_y: Real,
    /// Height of the highest point (m).
    pub top_y: Real,
    /// `x` of the mid-plane (m).
    pub mid_x: Real,
    /// The crotch point (m).
    pub crotch: [Real; 3],
    /// `z` of the torso's vertical axis (centroid of the torso section halfway from crotch to armpit, m).
    pub torso_z: Real,
    /// The legs, left then right.
    pub legs: Vec<LimbAxis>,
    /// The arms, left then right.
    pub arms: Vec<LimbAxis>,
}

fn fit_line(samples: &[Vec3]) -> Option<(Vec3, Vec3)> {
    // x = a + b y, z = c + e y by least squares; returns (point at mean y, unit direction with y > 0).
    let n = samples.len() as Real;
    if samples.len() < 3 {
        return None;
    }
    let my = samples.iter().map(|p| p.y).sum::<Real>() / n;
    let mx = samples.iter().map(|p| p.x).sum::<Real>() / n;
    let mz = samples.iter().map(|p| p.z).sum::<Real>() / n;
    let syy: Real = samples.iter().map(|p| (p.y - my).powi(2)).sum();
    if syy <= 1e-12 {
        return None;
    }
    let b = samples
        .iter()
        .map(|p| (p.y - my) * (p.x - mx))
        .sum::<Real>()
        / syy;
    let e = samples
        .iter()
        .map(|p| (p.y - my) * (p.z - mz))
        .sum::<Real>()
        / syy;
    Some((Vec3::new(mx, my, mz), Vec3::new(b, 1.0, e).normalize()))
}

/// Rounds of [`refit_across`].
const AXIS_REFITS: usize = 3;

/// Refits an arm axis (point `c`, unit direction `d`, spanning the heights `bottom..top`) to the centroids
/// of the arm's sections *perpendicular* to it, [`AXIS_REFITS`] times: the line through the centroids of
/// the sections across itself is the limb's own axis. The first fit's horizontal sections cut an A-pose
/// arm obliquely, and near the armpit their ellipses are clipped by the torso, so their centroids drift
/// with a few millimetres of the axilla (on a re-meshed scan the axis tilted 1.5° and the armpit girth
/// moved 3 %). Sections in `[0.35, 0.85]` of the span from the fingertip (above the hand, below the
/// armpit), every 1 cm; a round that finds fewer than 8 such sections keeps the previous line.
fn refit_across(
    body: &TriMesh,
    side: Side,
    mut c: Vec3,
    mut d: Vec3,
    bottom: Real,
    top: Real,
) -> (Vec3, Vec3) {
    for _ in 0..AXIS_REFITS {
        let distal = c + d * ((bottom - c.y) / d.y);
        let len = (top - bottom) / d.y;
        let axis = LimbAxis {
            kind: LimbKind::Arm,
            side,
            distal: distal.into(),
            direction: d.into(),
            length_m: len,
        };
        let n = ((0.5 * len) / 0.01).floor() as usize;
        let centroids: Vec<Vec3> = (0..=n)
            .map(|k| (0.35 + 0.5 * k as Real / n.max(1) as Real) * len)
            .filter_map(|s| {
                let l = axis.section(body, s)?;
                l.contains(d, axis.point(s)).then(|| l.centroid(d))
            })
            .collect();
        if centroids.len() < 8 {
            break;
        }
        match fit_line(&centroids) {
            Some((c2, d2)) if d2.y > 0.05 => (c, d) = (c2, d2),
            _ => break,
        }
    }
    (c, d)
}

fn horizontal(body: &TriMesh, y: Real) -> Vec<(Real, SectionLoop)> {
    let mut loops: Vec<(Real, SectionLoop)> = plane_section(body, Vec3::y(), y)
        .into_iter()
        .map(|l| (l.area(Vec3::y()), l))
        .collect();
    loops.sort_by(|a, b| b.0.total_cmp(&a.0));
    loops
}

/// Smallest loop area (m²) that counts as a limb section (5 cm²).
const MIN_LIMB_AREA: Real = 5e-4;

impl Segmentation {
    /// The leg on `side`.
    pub fn leg(&self, side: Side) -> &LimbAxis {
        &self.legs[if side == Side::Left { 0 } else { 1 }]
    }

    /// The arm on `side`.
    pub fn arm(&self, side: Side) -> &LimbAxis {
        &self.arms[if side == Side::Left { 0 } else { 1 }]
    }
}

/// Segments a standing body surface (closed, outward, metres, +y up, facing +z): see the module docs.
pub fn segment_body(body: &TriMesh) -> Result<Segmentation, MeasureError> {
    if body.positions.is_empty() || body.faces.is_empty() {
        return Err(MeasureError::BadMesh("empty".into()));
    }
    if body
        .positions
        .iter()
        .any(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(MeasureError::BadMesh(
            "not finite (a vertex has a NaN or infinite coordinate)".into(),
        ));
    }
    if body
        .faces
        .iter()
        .any(|f| f.iter().any(|&i| i >= body.positions.len()))
    {
        return Err(MeasureError::BadMesh(
            "inconsistent (a face indexes a missing vertex)".into(),
        ));
    }
    let (lo, hi) = body.bounding_box().expect("non-empty");
    let (floor_y, top_y) = (lo.y, hi.y);
    let stature = top_y - floor_y;
    if stature <= 0.0 {
        return Err(MeasureError::BadMesh("flat (no height along +y)".into()));
    }
    let (mut ax, mut aa) = (0.0, 0.0);
    for f in 0..body.num_faces() {
        let a = body.face_area(f);
        let [p, q, r] = body.corners(f);
        ax += a * (p.x + q.x + r.x) / 3.0;
        aa += a;
    }
    if aa <= 0.0 {
        return Err(MeasureError::BadMesh("of zero area".into()));
    }
    let mid_x = ax / aa;

    // Crotch: lowest point of the largest sagittal loop.
    let sagittal = plane_section(body, Vec3::x(), mid_x)
        .into_iter()
        .max_by(|a, b| a.area(Vec3::x()).total_cmp(&b.area(Vec3::x())))
        .ok_or_else(|| MeasureError::NoLegs("nothing in the mid-plane".into()))?;
    let crotch = *sagittal
        .points
        .iter()
        .min_by(|a, b| a.y.total_cmp(&b.y))
        .expect("a loop has points");
    let leg_len = crotch.y - floor_y;
    if !(0.3 * stature..=0.65 * stature).contains(&leg_len) {
        return Err(MeasureError::NoLegs(format!(
            "the lowest point of the body in its mid-plane is {:.3} m above the floor, {:.0} % of its \
             height {:.3} m, not 30-65 %",
            leg_len,
            100.0 * leg_len / stature,
            stature
        )));
    }

    // Legs.
    let mut legs = Vec::new();
    for side in Side::BOTH {
        let mut centroids = Vec::new();
        for k in 0..25 {
            let y = floor_y + leg_len * (0.25 + 0.6 * k as Real / 24.0);
            if let Some((_, l)) = horizontal(body, y)
                .into_iter()
                .find(|(_, l)| side.sign() * (l.centroid(Vec3::y()).x - mid_x) > 0.0)
                .filter(|(a, _)| *a >= MIN_LIMB_AREA)
            {
                centroids.push(l.centroid(Vec3::y()));
            }
        }
        if centroids.len() < 20 {
            return Err(MeasureError::NoLegs(format!(
                "no {} leg in {} of 25 horizontal sections between the floor and the crotch",
                side.name(),
                25 - centroids.len()
            )));
        }
        let (c, d) = fit_line(&centroids).expect("20 samples at distinct heights");
        let distal = c + d * ((floor_y - c.y) / d.y);
        legs.push(LimbAxis {
            kind: LimbKind::Leg,
            side,
            distal: distal.into(),
            direction: d.into(),
            length_m: leg_len / d.y,
        });
    }

    // Arms: horizontal scan.
    let steps = 200;
    let dy = stature / steps as Real;
    let arm_loop = |y: Real, side: Side| -> Option<SectionLoop> {
        let loops = horizontal(body, y);
        let on_side = |l: &SectionLoop| side.sign() * (l.centroid(Vec3::y()).x - mid_x) > 0.0;
        let candidate = if y < crotch.y {
            loops.into_iter().filter(|(_, l)| on_side(l)).nth(1)
        } else {
            loops.into_iter().skip(1).find(|(_, l)| on_side(l))
        };
        candidate
            .filter(|(a, _)| *a >= MIN_LIMB_AREA * 0.2)
            .map(|(_, l)| l)
    };
    let mut arms = Vec::new();
    for side in Side::BOTH {
        let present: Vec<bool> = (1..steps)
            .map(|k| arm_loop(floor_y + k as Real * dy, side).is_some())
            .collect();
        // Longest run.
        let (mut best, mut start) = ((0usize, 0usize), None);
        for (i, &p) in present.iter().chain(std::iter::once(&false)).enumerate() {
            match (p, start) {
                (true, None) => start = Some(i),
                (false, Some(s)) => {
                    if i - s > best.1 - best.0 {
                        best = (s, i);
                    }
                    start = None;
                }
                _ => {}
            }
        }
        if best.1 - best.0 < 20 {
            return Err(MeasureError::NoArm(
                side.name(),
                "no separate arm section over 10 % of the body's height".into(),
            ));
        }
        let y_of = |i: usize| floor_y + (i + 1) as Real * dy;
        let bisect = |mut yes: Real, mut no: Real| {
            for _ in 0..12 {
                let m = 0.5 * (yes + no);
                if arm_loop(m, side).is_some() {
                    yes = m;
                } else {
                    no = m;
                }
            }
            yes
        };
        let bottom = if best.0 == 0 {
            y_of(0)
        } else {
            bisect(y_of(best.0), y_of(best.0 - 1))
        };
        let top = bisect(y_of(best.1 - 1), y_of(best.1));
        let span = top - bottom;
        let centroids: Vec<Vec3> = (best.0..best.1)
            .map(y_of)
            .filter(|&y| y >= bottom + 0.35 * span && y <= top - 0.1 * span)
            .filter_map(|y| arm_loop(y, side).map(|l| l.centroid(Vec3::y())))
            .collect();
        let (c, d) = fit_line(&centroids).ok_or_else(|| {
            MeasureError::NoArm(side.name(), "too few arm sections for an axis".into())
        })?;
        let (c, d) = refit_across(body, side, c, d, bottom, top);
        let distal = c + d * ((bottom - c.y) / d.y);
        arms.push((side, distal, d, (top - bottom) / d.y));
    }

    // Torso axis: centroid of the largest loop halfway between the crotch and the lower armpit.
    let pit_y = arms
        .iter()
        .map(|(_, p, d, l)| (p + d * *l).y)
        .fold(Real::INFINITY, Real::min);
    let torso_z = horizontal(body, 0.5 * (crotch.y + pit_y))
        .first()
        .map(|(_, l)| l.centroid(Vec3::y()).z)
        .ok_or_else(|| MeasureError::NoLegs("no torso above the crotch".into()))?;

    // Armpit along each arm axis.
    let mut arm_axes = Vec::new();
    for (side, distal, d, est) in arms {
        let mut axis = LimbAxis {
            kind: LimbKind::Arm,
            side,
            distal: distal.into(),
            direction: d.into(),
            length_m: est,
        };
        let clear = |s: Real| -> bool {
            let a = axis.point(s);
            let n = d;
            let Some(l) = axis.section(body, s) else {
                return false;
            };
            if !l.contains(n, a) {
                return false;
            }
            // The torso axis point on this plane: (mid_x, y, torso_z) with n·p = n·a.
            if n.y.abs() < 1e-6 {
                return true;
            }
            let y = (n.dot(&a) - n.x * mid_x - n.z * torso_z) / n.y;
            !l.contains(n, Vec3::new(mid_x, y, torso_z))
        };
        let h = 0.005;
        let mut s = 0.5 * est;
        if !clear(s) {
            return Err(MeasureError::NoArm(
                side.name(),
                "the section across the arm axis halfway up the arm is not clear of the torso"
                    .into(),
            ));
        }
        while clear(s + h) && s < 2.0 * est {
            s += h;
        }
        let (mut yes, mut no) = (s, s + h);
        for _ in 0..8 {
            let m = 0.5 * (yes + no);
            if clear(m) {
                yes = m;
            } else {
                no = m;
            }
        }
        axis.length_m = yes;
        arm_axes.push(axis);
    }

    Ok(Segmentation {
        floor_y,
        top_y,
        mid_x,
        crotch: crotch.into(),
        torso_z,
        legs,
        arms: arm_axes,
    })
}
