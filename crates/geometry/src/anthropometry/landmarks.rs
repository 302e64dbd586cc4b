//! Anthropometric landmarks and girths of a standing body, as a compression-garment maker measures them.
//!
//! **Sources.** ISO 8559-1:2017 (anthropometric definitions for body measurement) for the names and the
//! girth convention (tape snug on the skin, perpendicular to the limb axis for limb girths, horizontal for
//! torso girths); RAL-GZ 387/1 (medical compression hosiery) for the leg measuring points
//! `B` (ankle, narrowest girth above the malleoli), `B1` (where the Achilles tendon turns into the calf
//! muscle), `C` (calf, widest), `D` (below the knee), `E` (knee), `F` (mid-thigh), `G` (upper thigh, below
//! the crotch).
//!
//! **Method.** The body is segmented first ([`super::body_segmentation`]): floor, crotch, a straight axis
//! per leg (floor → crotch height) and per arm (fingertip → armpit). A limb's *profile* is its girth
//! ([`super::girth`], the convex-hull perimeter) of the section perpendicular to its axis that encloses the
//! axis point, every 5 mm along the axis. Extremes are taken on the profile smoothed by a moving average
//! over ±1.5 cm, at the middle of the run of samples within 0.3 % of the extreme value (flat extremes make
//! the plain arg-min jump between resolutions). With `u ∈ [0, 1]` the fraction of the leg axis from the
//! floor to the crotch height and `t ∈ [0, 1]` the fraction of the arm axis from the fingertip to the
//! armpit, the rules are:
//!
//! | landmark | rule |
//! |---|---|
//! | `B` ankle | minimum girth for `u ∈ [0.08, 0.30]` (above the malleoli, below the calf) |
//! | `C` calf | maximum girth for `u ∈ [u_B, 0.55]` |
//! | `B1` | one third of the way from `B` to `C` (the Achilles tendon meets the calf muscle) |
//! | `E` knee | `u = 0.64` (mid-patella: on the shared bodies the narrowing below the knee lies at
//! |   | `u ≈ 0.53–0.58` and the knee ≈ 5 cm above it; a fixed fraction is stable where that narrowing is flat) |
//! | `D` below the knee | `u = 0.59` (5 % of the crotch height, ≈ 4 cm, below `E`) |
//! | `G` upper thigh | `u = 0.94` (a few cm below the crotch) |
//! | `F` mid-thigh | halfway between `E` and `G` |
//! | `crotch` | the crotch point; girth of the horizontal torso section 5 mm above it |
//! | `hip` | the height of the greatest buttock protrusion (the torso section's most backward point, as ISO 8559-1 defines the hip girth at the buttocks' greatest protrusion; plateau within 2 mm) from the crotch to 30 % of the crotch height above it |
//! | `waist` | minimum horizontal torso girth from the hip to 60 % of the way to the armpit |
//! | `wrist` | minimum girth from the palm (maximum girth for `t ∈ [0.1, 0.4]`) to `t = 0.55` |
//! | `elbow` | 56 % of the way from the wrist to the armpit |
//! | `forearm` | maximum girth between the wrist and the elbow |
//! | `upper_arm` | halfway between the elbow and the armpit |
//! | `armpit` | 1 cm below the armpit along the arm axis (the last section clear of the torso) |
//!
//! The torso sections are horizontal; the torso loop is the largest loop of the section.
//!
//! Units: metres. `height_m` is the height of the landmark's point above the floor (the body's lowest
//! point); `point` is the centroid of the girth curve (on the limb axis for a limb), in the body's
//! coordinates; `curve` is the section loop on the body surface.

use serde::{Deserialize, Serialize};

use crate::math::{Real, Vec3};
use crate::mesh::TriMesh;

use super::body_segmentation::{LimbAxis, MeasureError, Segmentation, Side, segment_body};
use super::girth::girth;
use super::plane_section::{SectionLoop, plane_section};

/// One landmark with its girth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Landmark {
    /// `B`, `B1`, `C`, `D`, `E`, `F`, `G` (legs), `crotch`, `hip`, `waist` (torso), `wrist`, `forearm`,
    /// `elbow`, `upper_arm`, `armpit` (arms).
    pub name: String,
    /// The side for a limb landmark, `None` (JSON `null`) for the torso.
    pub side: Option<Side>,
    /// Height of `point` above the floor (m).
    pub height_m: Real,
    /// Tape-measure girth: convex-hull perimeter of `curve` in its plane (m).
    pub girth_m: Real,
    /// The landmark's point (m): the centroid of `curve`, on the limb axis for a limb; the crotch point
    /// itself for `crotch`.
    pub point: [Real; 3],
    /// Unit normal of the plane of `curve`: the limb axis direction (towards the trunk), `+y` for the torso.
    pub normal: [Real; 3],
    /// Distance from the limb's distal end along its axis (m); `None` for the torso.
    pub axis_m: Option<Real>,
    /// The closed girth curve on the body surface (m), in order.
    pub curve: Vec<[Real; 3]>,
}

/// The landmarks of a body and the segmentation they come from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Measurements {
    /// Stature: highest minus lowest point (m).
    pub stature_m: Real,
    /// The landmarks: per leg `B B1 C D E F G` (left, then right), `crotch hip waist`, per arm
    /// `wrist forearm elbow upper_arm armpit` (left, then right).
    pub landmarks: Vec<Landmark>,
    /// Floor, mid-plane, crotch and the limb axes.
    pub segmentation: Segmentation,
}

impl Measurements {
    /// The landmark `name` on `side` (`None` for the torso).
    pub fn landmark(&self, name: &str, side: Option<Side>) -> Option<&Landmark> {
        self.landmarks
            .iter()
            .find(|l| l.name == name && l.side == side)
    }
}

/// Leg landmark names in order from the ankle up.
pub const LEG_LANDMARKS: [&str; 7] = ["B", "B1", "C", "D", "E", "F", "G"];
/// Torso landmark names from the bottom up.
pub const TORSO_LANDMARKS: [&str; 3] = ["crotch", "hip", "waist"];
/// Arm landmark names from the wrist up.
pub const ARM_LANDMARKS: [&str; 5] = ["wrist", "forearm", "elbow", "upper_arm", "armpit"];

/// Profile sampling step along a limb axis (m).
const STEP: Real = 0.005;
/// Half-width of the smoothing window (samples): ±1.5 cm.
const SMOOTH: usize = 3;
/// Relative tolerance defining the run of an extreme.
const PLATEAU: Real = 0.02;

/// A limb's girth profile: `(s, girth)` every [`STEP`] along the axis (girth `NaN` where no section).
pub fn limb_profile(body: &TriMesh, axis: &LimbAxis) -> Vec<(Real, Real)> {
    let n = (axis.length_m / STEP).floor() as usize;
    (0..=n)
        .map(|k| {
            let s = k as Real * STEP;
            let g = axis
                .section(body, s)
                .map(|l| girth(&l, axis.dir()))
                .unwrap_or(Real::NAN);
            (s, g)
        })
        .collect()
}

fn smooth(profile: &[(Real, Real)]) -> Vec<(Real, Real)> {
    (0..profile.len())
        .map(|i| {
            let lo = i.saturating_sub(SMOOTH);
            let hi = (i + SMOOTH).min(profile.len() - 1);
            let vals: Vec<Real> = profile[lo..=hi]
                .iter()
                .map(|p| p.1)
                .filter(|g| g.is_finite())
                .collect();
            let g = if vals.is_empty() {
                Real::NAN
            } else {
                vals.iter().sum::<Real>() / vals.len() as Real
            };
            (profile[i].0, g)
        })
        .collect()
}

/// The position `s` of the extreme (minimum if `min`) of the smoothed profile within `[a, b]`, at the middle
/// of its plateau; `None` if no finite sample lies there.
pub fn extreme(profile: &[(Real, Real)], a: Real, b: Real, min: bool) -> Option<Real> {
    extreme_tol(profile, a, b, min, Real::NAN)
}

/// [`extreme`] with an absolute plateau tolerance `tol` (the relative [`PLATEAU`] when `tol` is NaN).
pub fn extreme_tol(
    profile: &[(Real, Real)],
    a: Real,
    b: Real,
    min: bool,
    tol: Real,
) -> Option<Real> {
    let sm = smooth(profile);
    let idx: Vec<usize> = (0..sm.len())
        .filter(|&i| sm[i].0 >= a - 1e-9 && sm[i].0 <= b + 1e-9 && sm[i].1.is_finite())
        .collect();
    let key = |i: usize| if min { sm[i].1 } else { -sm[i].1 };
    let &best = idx.iter().min_by(|&&i, &&j| key(i).total_cmp(&key(j)))?;
    let tol = if tol.is_nan() {
        PLATEAU * sm[best].1.abs()
    } else {
        tol
    };
    let within = |i: usize| (key(i) - key(best)).abs() <= tol;
    let pos = idx.iter().position(|&i| i == best).expect("best is in idx");
    let (mut lo, mut hi) = (pos, pos);
    while lo > 0 && idx[lo - 1] + 1 == idx[lo] && within(idx[lo - 1]) {
        lo -= 1;
    }
    while hi + 1 < idx.len() && idx[hi + 1] == idx[hi] + 1 && within(idx[hi + 1]) {
        hi += 1;
    }
    // The centroid of the run weighted by how close each sample is to the extreme (1 at it, 0 at the
    // tolerance): unlike the run's midpoint it does not jump when a sample enters or leaves the run.
    let (mut sw, mut sws) = (0.0, 0.0);
    for &i in &idx[lo..=hi] {
        let w = if tol > 0.0 {
            (1.0 - (key(i) - key(best)).abs() / tol).max(0.0)
        } else {
            1.0
        };
        sw += w;
        sws += w * sm[i].0;
    }
    Some(if sw > 0.0 { sws / sw } else { sm[best].0 })
}

fn to_arr(p: Vec3) -> [Real; 3] {
    [p.x, p.y, p.z]
}

fn curve_of(l: &SectionLoop) -> Vec<[Real; 3]> {
    l.points.iter().map(|p| to_arr(*p)).collect()
}

fn limb_landmark(
    body: &TriMesh,
    seg: &Segmentation,
    axis: &LimbAxis,
    name: &str,
    s: Real,
) -> Result<Landmark, MeasureError> {
    let l = axis.section(body, s).ok_or_else(|| {
        MeasureError::NoLandmark(
            format!("{} ({})", name, axis.side.name()),
            format!("no section of the limb {s:.3} m along its axis"),
        )
    })?;
    let n = axis.dir();
    let c = l.centroid(n);
    Ok(Landmark {
        name: name.into(),
        side: Some(axis.side),
        height_m: c.y - seg.floor_y,
        girth_m: girth(&l, n),
        point: to_arr(c),
        normal: to_arr(n),
        axis_m: Some(s),
        curve: curve_of(&l),
    })
}

/// The torso section at height `y`: the largest loop of the horizontal section.
fn torso_section(body: &TriMesh, y: Real) -> Option<SectionLoop> {
    plane_section(body, Vec3::y(), y)
        .into_iter()
        .max_by(|a, b| a.area(Vec3::y()).total_cmp(&b.area(Vec3::y())))
}

fn torso_landmark(
    body: &TriMesh,
    seg: &Segmentation,
    name: &str,
    y: Real,
    point: Option<Vec3>,
) -> Result<Landmark, MeasureError> {
    let l = torso_section(body, y).ok_or_else(|| {
        MeasureError::NoLandmark(name.into(), format!("no torso section at height {y:.3} m"))
    })?;
    let p = point.unwrap_or_else(|| l.centroid(Vec3::y()));
    Ok(Landmark {
        name: name.into(),
        side: None,
        height_m: p.y - seg.floor_y,
        girth_m: girth(&l, Vec3::y()),
        point: to_arr(p),
        normal: [0.0, 1.0, 0.0],
        axis_m: None,
        curve: curve_of(&l),
    })
}

fn missing(name: &str, side: Option<Side>) -> MeasureError {
    MeasureError::NoLandmark(
        match side {
            Some(s) => format!("{name} ({})", s.name()),
            None => name.into(),
        },
        "no limb section in its search range".into(),
    )
}

/// Measures a standing body surface (closed, outward, metres, +y up, facing +z): see the module docs.
pub fn measure_body(body: &TriMesh) -> Result<Measurements, MeasureError> {
    let seg = segment_body(body)?;
    let mut landmarks = Vec::new();
    for side in Side::BOTH {
        let axis = seg.leg(side);
        let len = axis.length_m;
        let prof = limb_profile(body, axis);
        let m = |n| missing(n, Some(side));
        let b = extreme(&prof, 0.08 * len, 0.30 * len, true).ok_or_else(|| m("B"))?;
        let c = extreme(&prof, b, 0.55 * len, false).ok_or_else(|| m("C"))?;
        let e = 0.64 * len;
        let d = e - 0.05 * len;
        let g = 0.94 * len;
        let f = 0.5 * (e + g);
        let b1 = b + (c - b) / 3.0;
        for (name, s) in [
            ("B", b),
            ("B1", b1),
            ("C", c),
            ("D", d),
            ("E", e),
            ("F", f),
            ("G", g),
        ] {
            landmarks.push(limb_landmark(body, &seg, axis, name, s)?);
        }
    }
    let crotch = Vec3::from(seg.crotch);
    let leg_len = crotch.y - seg.floor_y;
    landmarks.push(torso_landmark(
        body,
        &seg,
        "crotch",
        crotch.y + 0.005,
        Some(crotch),
    )?);
    let pit_y = seg
        .arms
        .iter()
        .map(|a| a.point(a.length_m).y)
        .fold(Real::INFINITY, Real::min);
    let torso_prof: Vec<(Real, Real)> = {
        let (lo, hi) = (crotch.y + 0.01, pit_y - 0.01);
        let n = ((hi - lo) / STEP).floor().max(0.0) as usize;
        (0..=n)
            .map(|k| {
                let y = lo + k as Real * STEP;
                let g = torso_section(body, y)
                    .map(|l| girth(&l, Vec3::y()))
                    .unwrap_or(Real::NAN);
                (y, g)
            })
            .collect()
    };
    // Buttock protrusion: the most backward (−z) point of the torso section.
    let back_prof: Vec<(Real, Real)> = torso_prof
        .iter()
        .map(|&(y, _)| {
            let z = torso_section(body, y)
                .map(|l| l.points.iter().map(|p| p.z).fold(Real::INFINITY, Real::min))
                .unwrap_or(Real::NAN);
            (y, z)
        })
        .collect();
    let hip = extreme_tol(&back_prof, crotch.y, crotch.y + 0.3 * leg_len, true, 0.002)
        .ok_or_else(|| missing("hip", None))?;
    let waist = extreme(&torso_prof, hip, hip + 0.6 * (pit_y - hip), true)
        .ok_or_else(|| missing("waist", None))?;
    landmarks.push(torso_landmark(body, &seg, "hip", hip, None)?);
    landmarks.push(torso_landmark(body, &seg, "waist", waist, None)?);
    for side in Side::BOTH {
        let axis = seg.arm(side);
        let len = axis.length_m;
        let prof = limb_profile(body, axis);
        let palm = extreme(&prof, 0.1 * len, 0.4 * len, false)
            .ok_or_else(|| missing("wrist", Some(side)))?;
        let w =
            extreme(&prof, palm, 0.55 * len, true).ok_or_else(|| missing("wrist", Some(side)))?;
        let e = w + 0.56 * (len - w);
        let fa = extreme(&prof, w, e, false).ok_or_else(|| missing("forearm", Some(side)))?;
        let ua = 0.5 * (e + len);
        let pit = len - 0.01;
        for (name, s) in [
            ("wrist", w),
            ("forearm", fa),
            ("elbow", e),
            ("upper_arm", ua),
            ("armpit", pit),
        ] {
            landmarks.push(limb_landmark(body, &seg, axis, name, s)?);
        }
    }
    for l in &landmarks {
        if !(l.girth_m.is_finite() && l.girth_m > 0.0 && l.height_m.is_finite()) {
            return Err(MeasureError::NoLandmark(
                l.name.clone(),
                "its girth is not a positive number".into(),
            ));
        }
    }
    Ok(Measurements {
        stature_m: seg.top_y - seg.floor_y,
        landmarks,
        segmentation: seg,
    })
}
