//! Body regions: which part of a standing body (torso, a leg, an arm) each point of its surface belongs
//! to, from the measured landmarks ([`super::landmarks`]).
//!
//! **Method (nearest bone, scaled by its girth).** The body's skeleton is five segments: each leg's axis
//! from the floor to the crotch height, each arm's axis from the fingertip to the armpit, and the torso's
//! vertical axis (`x = x₀`, `z = z_torso`) from the crotch up to the top of the head. Each segment has a
//! radius, the mean girth over 2π of its landmarks (leg: `C`, `E`, `F`, `G`; arm: `forearm`, `elbow`,
//! `upper_arm`; torso: `hip`, `waist`, halved across the depth as the torso is about twice as wide as
//! deep). A point belongs to the segment with the smallest distance over radius, with two cuts that
//! follow the landmarks: a point above the crotch height's plane across a leg axis, or beyond the armpit
//! plane across an arm axis towards the trunk, is never that limb's. The classification is of points, so
//! it applies to any triangulation of the surface.
//!
//! Units: metres.

use serde::{Deserialize, Serialize};

use crate::math::{Real, Vec3};

use super::body_segmentation::{LimbAxis, Side};
use super::landmarks::Measurements;

/// A region of the body.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BodyRegion {
    /// Torso, neck and head.
    Torso,
    /// A leg, below the crotch.
    Leg(Side),
    /// An arm, from the armpit to the fingertips.
    Arm(Side),
}

/// Distance from `p` to the segment `a`–`b` (m).
fn segment_distance(p: Vec3, a: Vec3, b: Vec3) -> Real {
    let ab = b - a;
    let t = ((p - a).dot(&ab) / ab.norm_squared().max(1e-18)).clamp(0.0, 1.0);
    (p - (a + ab * t)).norm()
}

fn mean_radius(m: &Measurements, names: &[&str], side: Option<Side>) -> Real {
    let g: Vec<Real> = names
        .iter()
        .filter_map(|n| m.landmark(n, side).map(|l| l.girth_m))
        .collect();
    g.iter().sum::<Real>() / (g.len().max(1) as Real) / (2.0 * std::f64::consts::PI)
}

/// Classifies points of the body surface (see the module documentation).
pub struct RegionClassifier {
    limbs: Vec<(BodyRegion, LimbAxis, Real)>,
    torso: (Vec3, Vec3, Real),
}

impl RegionClassifier {
    /// The classifier of a measured body.
    pub fn new(m: &Measurements) -> Self {
        let seg = &m.segmentation;
        let mut limbs = Vec::new();
        for side in Side::BOTH {
            let r = mean_radius(m, &["C", "E", "F", "G"], Some(side));
            limbs.push((BodyRegion::Leg(side), seg.leg(side).clone(), r));
            let r = mean_radius(m, &["forearm", "elbow", "upper_arm"], Some(side));
            limbs.push((BodyRegion::Arm(side), seg.arm(side).clone(), r));
        }
        let r = 0.5 * mean_radius(m, &["hip", "waist"], None);
        let torso = (
            Vec3::new(seg.mid_x, seg.crotch[1], seg.torso_z),
            Vec3::new(seg.mid_x, seg.top_y, seg.torso_z),
            r,
        );
        Self { limbs, torso }
    }

    /// The region of the surface point `p`.
    pub fn region(&self, p: Vec3) -> BodyRegion {
        let (a, b, r) = self.torso;
        let mut best = (segment_distance(p, a, b) / r, BodyRegion::Torso);
        for (region, axis, r) in &self.limbs {
            let end = axis.point(axis.length_m);
            if axis.dir().dot(&(p - end)) > 0.0 {
                continue; // beyond the limb's proximal plane
            }
            let d = segment_distance(p, axis.point(0.0), end) / r;
            if d < best.0 {
                best = (d, *region);
            }
        }
        best.1
    }
}

/// The region of every point of `points`.
pub fn body_regions(m: &Measurements, points: &[Vec3]) -> Vec<BodyRegion> {
    let c = RegionClassifier::new(m);
    points.iter().map(|p| c.region(*p)).collect()
}
