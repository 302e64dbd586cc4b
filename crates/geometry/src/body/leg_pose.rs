//! A body pose with the legs bent at hip and knee: a deformed copy of a standing body surface (same
//! vertices, same triangles), for the multi-pose sliding objective.
//!
//! **Frame.** The bodies of `data/bodies` (metres, +y up, facing +z, legs apart along ±x). Flexion turns
//! the thigh forward (the knee moves to +z) about a hip joint and the shank backward about the knee, both
//! about the x axis (the sagittal plane y–z).
//!
//! **Joints, found from the geometry.** The crotch is the lowest vertex within `crotch_band` of the
//! body's mid-plane `x = 0` (between the legs there are no vertices near that plane). For the leg on side
//! `σ = ±1`, with `L` the crotch height above the body's lowest point:
//! - hip joint: height `crotch + hip_above_crotch · L`, at the mean `x` and `z` of the leg's vertices in a
//!   slab of half-height `blend` around the crotch height;
//! - knee joint: height `crotch − knee_fraction · L`, at the mean `x` and `z` of the leg's vertices in a
//!   slab of half-height `blend` around that height.
//!
//! **Deformation (a smooth bend, not matrix blending).** Every vertex of the leg (`σ x > 0`) gets the
//! angles `θ_hip · w_h` and `θ_knee · w_k`, with weights that rise smoothly (smoothstep) across a band of
//! half-width `blend` around each joint's height (`w = 1` below it, `0` above) and, for the hip, fade to 0
//! within `crotch_band` of the mid-plane so the two sides stay joined. The vertex is turned first about
//! the knee's axis (the shank backward by `θ_knee w_k`), then about the hip's axis (forward by
//! `θ_hip w_h`). Zero angles give the input exactly.

use crate::math::{Real, Vec3};
use crate::mesh::TriMesh;

/// Which legs to bend.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Legs {
    /// The leg at `x > 0` (the body's left).
    Left,
    /// The leg at `x < 0`.
    Right,
    /// Both.
    Both,
}

/// Settings of [`leg_pose`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegPoseParams {
    /// Hip flexion (rad, thigh forward), `|θ| ≤ π/2`.
    pub hip: Real,
    /// Knee flexion (rad, shank backward), `|θ| ≤ 2π/3`.
    pub knee: Real,
    /// Which legs.
    pub legs: Legs,
    /// Half-width of the band in which a joint's rotation fades in (m, > 0). Default 0.06.
    pub blend: Real,
    /// Distance from the mid-plane `x = 0` within which the crotch is sought and the hip rotation fades
    /// out (m, > 0). Default 0.03.
    pub crotch_band: Real,
    /// Hip joint height above the crotch as a fraction of the crotch height `L` (≥ 0). Default 0.08.
    pub hip_above_crotch: Real,
    /// Knee height below the crotch as a fraction of `L` (in (0, 1)). Default 0.47.
    pub knee_fraction: Real,
}

impl Default for LegPoseParams {
    fn default() -> Self {
        Self {
            hip: 0.0,
            knee: 0.0,
            legs: Legs::Both,
            blend: 0.06,
            crotch_band: 0.03,
            hip_above_crotch: 0.08,
            knee_fraction: 0.47,
        }
    }
}

/// Why a pose cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LegPoseError {
    /// Settings out of range; the message names the setting.
    #[error("invalid leg pose setting: {0}")]
    Parameter(String),
    /// The body's legs could not be found (no crotch near the mid-plane, or an empty slab at a joint).
    #[error("cannot find the legs: {0}")]
    NoLegs(String),
}

/// One leg's joints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegJoints {
    /// Hip joint centre (m).
    pub hip: Vec3,
    /// Knee joint centre (m).
    pub knee: Vec3,
}

fn smoothstep(t: Real) -> Real {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Rotation of `p` about the axis through `centre` along +x by `angle` (rad; positive turns +y towards +z).
fn rotate_x(p: Vec3, centre: Vec3, angle: Real) -> Vec3 {
    if angle == 0.0 {
        return p;
    }
    let d = p - centre;
    let (s, c) = angle.sin_cos();
    centre + Vec3::new(d.x, c * d.y - s * d.z, s * d.y + c * d.z)
}

/// The joints of the leg on side `side` (+1: `x > 0`, −1: `x < 0`) of `body`.
pub fn leg_joints(
    body: &TriMesh,
    side: Real,
    params: &LegPoseParams,
) -> Result<LegJoints, LegPoseError> {
    let p = &body.positions;
    let lowest = p.iter().map(|v| v.y).fold(Real::INFINITY, Real::min);
    let crotch = p
        .iter()
        .filter(|v| v.x.abs() < params.crotch_band)
        .map(|v| v.y)
        .fold(Real::INFINITY, Real::min);
    if !(crotch.is_finite() && lowest.is_finite() && crotch > lowest) {
        return Err(LegPoseError::NoLegs(format!(
            "no vertex within {} m of the mid-plane x = 0 above the lowest point",
            params.crotch_band
        )));
    }
    let length = crotch - lowest;
    let centre = |y: Real, what: &str| -> Result<Vec3, LegPoseError> {
        let (mut sum, mut n) = (Vec3::zeros(), 0usize);
        for v in p {
            if side * v.x > 0.0 && (v.y - y).abs() <= params.blend {
                sum += v;
                n += 1;
            }
        }
        if n == 0 {
            return Err(LegPoseError::NoLegs(format!(
                "no vertex of the {} leg near the {what} height {y:.3} m",
                if side > 0.0 { "x > 0" } else { "x < 0" }
            )));
        }
        let m = sum / n as Real;
        Ok(Vec3::new(m.x, y, m.z))
    };
    let hip = centre(crotch + params.hip_above_crotch * length, "hip")?;
    let knee = centre(crotch - params.knee_fraction * length, "knee")?;
    Ok(LegJoints { hip, knee })
}

/// `body` with the legs bent (see the module documentation): same vertex count and triangles.
pub fn leg_pose(body: &TriMesh, params: &LegPoseParams) -> Result<TriMesh, LegPoseError> {
    let bad = |m: String| Err(LegPoseError::Parameter(m));
    if !(params.hip.is_finite() && params.hip.abs() <= std::f64::consts::FRAC_PI_2) {
        return bad(format!(
            "hip angle {} rad is outside [−π/2, π/2]",
            params.hip
        ));
    }
    if !(params.knee.is_finite() && params.knee.abs() <= 2.0 * std::f64::consts::FRAC_PI_3) {
        return bad(format!(
            "knee angle {} rad is outside [−2π/3, 2π/3]",
            params.knee
        ));
    }
    for (name, v) in [("blend", params.blend), ("crotch_band", params.crotch_band)] {
        if !(v.is_finite() && v > 0.0) {
            return bad(format!("{name} must be finite and > 0, got {v}"));
        }
    }
    if !(params.hip_above_crotch.is_finite() && params.hip_above_crotch >= 0.0) {
        return bad(format!(
            "hip_above_crotch must be finite and ≥ 0, got {}",
            params.hip_above_crotch
        ));
    }
    if !(params.knee_fraction > 0.0 && params.knee_fraction < 1.0) {
        return bad(format!(
            "knee_fraction must lie in (0, 1), got {}",
            params.knee_fraction
        ));
    }
    if body
        .positions
        .iter()
        .any(|v| !v.iter().all(|c| c.is_finite()))
    {
        return Err(LegPoseError::NoLegs("a vertex is not finite".into()));
    }
    let sides: &[Real] = match params.legs {
        Legs::Left => &[1.0],
        Legs::Right => &[-1.0],
        Legs::Both => &[1.0, -1.0],
    };
    let mut out = body.clone();
    for &side in sides {
        let joints = leg_joints(body, side, params)?;
        for (q, p) in out.positions.iter_mut().zip(&body.positions) {
            if side * p.x <= 0.0 {
                continue;
            }
            let w_hip = smoothstep((joints.hip.y + params.blend - p.y) / (2.0 * params.blend))
                * smoothstep(side * p.x / params.crotch_band);
            let w_knee = smoothstep((joints.knee.y + params.blend - p.y) / (2.0 * params.blend));
            // rotate_x turns +y towards +z: a downward thigh goes forward under a negative angle.
            let bent = rotate_x(*p, joints.knee, params.knee * w_knee);
            *q = rotate_x(bent, joints.hip, -params.hip * w_hip);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::self_intersection::self_intersections;

    /// `regular_1k.obj` from `<repo root>/../shared/data/bodies` or the nearest ancestor's
    /// `shared/data/bodies` (a worktree may sit deeper).
    fn body() -> TriMesh {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .ancestors()
            .map(|a| a.join("shared/data/bodies"))
            .find(|p| p.is_dir())
            .expect("shared/data/bodies");
        crate::mesh::io::read_mesh(&dir.join("regular_1k.obj")).unwrap()
    }

    #[test]
    fn zero_angles_give_the_body_and_bad_settings_are_refused() {
        let b = body();
        let same = leg_pose(&b, &LegPoseParams::default()).unwrap();
        assert_eq!(same.positions, b.positions);
        for p in [
            LegPoseParams {
                hip: 2.0,
                ..Default::default()
            },
            LegPoseParams {
                knee: Real::NAN,
                ..Default::default()
            },
            LegPoseParams {
                blend: 0.0,
                ..Default::default()
            },
            LegPoseParams {
                knee_fraction: 1.0,
                ..Default::default()
            },
        ] {
            assert!(matches!(leg_pose(&b, &p), Err(LegPoseError::Parameter(_))));
        }
        let no_legs = TriMesh {
            positions: vec![
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
            ],
            faces: vec![[0, 1, 2]],
            ..Default::default()
        };
        assert!(matches!(
            leg_pose(
                &no_legs,
                &LegPoseParams {
                    hip: 0.3,
                    ..Default::default()
                }
            ),
            Err(LegPoseError::NoLegs(_))
        ));
    }

    #[test]
    fn bent_legs_move_the_knee_forward_keep_the_torso_and_do_not_self_intersect() {
        let b = body();
        for (hip, knee, legs) in [(30_f64, 45_f64, Legs::Left), (15.0, 60.0, Legs::Both)] {
            let params = LegPoseParams {
                hip: hip.to_radians(),
                knee: knee.to_radians(),
                legs,
                ..Default::default()
            };
            let posed = leg_pose(&b, &params).unwrap();
            assert_eq!(posed.faces, b.faces);
            assert_eq!(posed.positions.len(), b.positions.len());
            let joints = leg_joints(&b, 1.0, &params).unwrap();
            // Above the hip band nothing moves.
            for (p, q) in b.positions.iter().zip(&posed.positions) {
                if p.y > joints.hip.y + params.blend {
                    assert_eq!(p, q);
                }
            }
            // A thigh point between the bands turns by the hip angle about the hip.
            let thigh_y = 0.5 * (joints.hip.y - params.blend + joints.knee.y + params.blend);
            let (i, p) = b
                .positions
                .iter()
                .enumerate()
                .filter(|(_, p)| p.x > params.crotch_band && (p.y - thigh_y).abs() < 0.02)
                .min_by(|a, b| (a.1.y - thigh_y).abs().total_cmp(&(b.1.y - thigh_y).abs()))
                .unwrap();
            let (d0, d1) = (p - joints.hip, posed.positions[i] - joints.hip);
            let a0 = d0.z.atan2(-d0.y);
            let a1 = d1.z.atan2(-d1.y);
            assert!(
                ((a1 - a0) - hip.to_radians()).abs() < 1e-9,
                "thigh turned by {} rad",
                a1 - a0
            );
            // The knee moved forward.
            let knee_vertex = b
                .positions
                .iter()
                .enumerate()
                .filter(|(_, p)| p.x > 0.0)
                .min_by(|a, c| {
                    (a.1 - joints.knee)
                        .norm()
                        .total_cmp(&(c.1 - joints.knee).norm())
                })
                .unwrap()
                .0;
            assert!(posed.positions[knee_vertex].z > b.positions[knee_vertex].z + 0.05);
            let hits = self_intersections(&posed.positions, &posed.faces, 0.0);
            let before = self_intersections(&b.positions, &b.faces, 0.0);
            assert!(
                hits.len() <= before.len(),
                "{} new self-intersections",
                hits.len() - before.len()
            );
        }
    }
}
