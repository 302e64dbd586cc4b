//! The units, up axis and facing direction of a raw body scan, and the similarity transform that brings it
//! into the body frame of skintight (metres, +y up, facing +z; see `data/bodies/README.md`).
//!
//! Units: input in the scan's own units (millimetres, centimetres or metres); output in metres.
//!
//! Method (written here; no published algorithm is needed):
//! - **Up axis**: declared, or the coordinate axis of the longest bounding-box extent (a standing body is
//!   taller than it is wide or deep, also in an A-pose). Its sign, when not declared: the area-weighted
//!   centroid of the surface lies above mid-height (head, torso and arms carry more surface than the legs;
//!   0.55–0.65 of the height on the sample bodies).
//! - **Units**: declared, or the one reading among mm, cm and m whose height lies in 1.0–2.1 m (a standing
//!   adult or older child). A height that fits no reading, or several, is refused.
//! - **Facing**: of the two horizontal axes, the one of larger extent is lateral (shoulders and arms are
//!   wider than the body is deep). The front is told from the feet, which point forward: the area centroid
//!   of the lowest 4 % of the height (the feet) lies in front of that of the 10–35 % band (the shins), by
//!   several centimetres on a standing body. When that offset is below 1 % of the height the front cannot be
//!   told and the usual convention of the up axis is kept (a +y-up file faces +z; a +z-up file faces −y, as
//!   in Blender), which the report says (`facing_detected: false`).
//! - The transform is `x' = s · R · x` with `R` a proper rotation (det R = +1, never a reflection: the
//!   lateral axis is `up × front`), so left and right are never swapped. No translation is applied.

use crate::math::{Mat3, Real, Vec3};

/// Length unit of a scan.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LengthUnit {
    /// Millimetres.
    Mm,
    /// Centimetres.
    Cm,
    /// Metres.
    M,
}

impl LengthUnit {
    /// Metres per unit.
    pub fn scale(self) -> Real {
        match self {
            LengthUnit::Mm => 1e-3,
            LengthUnit::Cm => 1e-2,
            LengthUnit::M => 1.0,
        }
    }

    /// `mm`, `cm` or `m`.
    pub fn name(self) -> &'static str {
        match self {
            LengthUnit::Mm => "mm",
            LengthUnit::Cm => "cm",
            LengthUnit::M => "m",
        }
    }

    /// Parses `mm`, `cm` or `m`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "mm" => Some(LengthUnit::Mm),
            "cm" => Some(LengthUnit::Cm),
            "m" => Some(LengthUnit::M),
            _ => None,
        }
    }
}

/// A signed coordinate axis: `axis` 0, 1, 2 for x, y, z.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SignedAxis {
    /// 0 = x, 1 = y, 2 = z.
    pub axis: usize,
    /// Whether it points along −axis.
    pub negative: bool,
}

impl SignedAxis {
    /// Parses `x`, `y`, `z`, `+x`, …, `-z`.
    pub fn parse(s: &str) -> Option<Self> {
        let (negative, rest) = match s.as_bytes().first() {
            Some(b'-') => (true, &s[1..]),
            Some(b'+') => (false, &s[1..]),
            _ => (false, s),
        };
        let axis = match rest {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return None,
        };
        Some(Self { axis, negative })
    }

    /// The unit vector.
    pub fn vector(self) -> Vec3 {
        let mut v = Vec3::zeros();
        v[self.axis] = if self.negative { -1.0 } else { 1.0 };
        v
    }

    /// `+x`, `-z`, ….
    pub fn name(self) -> String {
        format!(
            "{}{}",
            if self.negative { '-' } else { '+' },
            ['x', 'y', 'z'][self.axis]
        )
    }
}

/// Tallest and shortest accepted standing bodies (m).
pub const HEIGHT_RANGE_M: (Real, Real) = (1.0, 2.1);

/// What was found or declared.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub units: LengthUnit,
    pub units_detected: bool,
    pub up: SignedAxis,
    pub up_detected: bool,
    /// The scan's forward direction (unit, scan coordinates).
    pub front: Vec3,
    pub facing_detected: bool,
    /// Height along the up axis (m).
    pub height_m: Real,
    /// `x' = scale · rotation · x`.
    pub rotation: Mat3,
    pub scale: Real,
}

/// Why no frame fits.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FrameError {
    #[error("the scan has no area")]
    Empty,
    #[error(
        "the scan is {height} units tall along {axis}: no reading as mm, cm or m gives a standing body of 1.0–2.1 m"
    )]
    NoUnits { height: Real, axis: String },
    #[error(
        "the scan is {height} units tall along {axis}: read as {units} that is {metres:.2} m, outside the 1.0–2.1 m of a standing body"
    )]
    DeclaredUnits {
        height: Real,
        axis: String,
        units: &'static str,
        metres: Real,
    },
    #[error("the scan's height {height} fits both {a} and {b}: declare the units")]
    Ambiguous {
        height: Real,
        a: &'static str,
        b: &'static str,
    },
}

/// Area-weighted face centroids and areas.
fn samples(positions: &[Vec3], faces: &[[usize; 3]]) -> Vec<(Vec3, Real)> {
    faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| positions[v]);
            ((a + b + c) / 3.0, 0.5 * (b - a).cross(&(c - a)).norm())
        })
        .filter(|(c, w)| w.is_finite() && *w > 0.0 && c.iter().all(|x| x.is_finite()))
        .collect()
}

/// Finds (or takes) units, up and facing of a body surface given in scan coordinates.
pub fn detect_frame(
    positions: &[Vec3],
    faces: &[[usize; 3]],
    units: Option<LengthUnit>,
    up: Option<SignedAxis>,
) -> Result<Frame, FrameError> {
    let s = samples(positions, faces);
    let total: Real = s.iter().map(|x| x.1).sum();
    if s.is_empty() || total <= 0.0 {
        return Err(FrameError::Empty);
    }
    let mut lo = Vec3::repeat(Real::INFINITY);
    let mut hi = Vec3::repeat(Real::NEG_INFINITY);
    for f in faces {
        for &v in f {
            lo = lo.inf(&positions[v]);
            hi = hi.sup(&positions[v]);
        }
    }
    let ext = hi - lo;
    let centroid = s.iter().map(|(c, w)| c * *w).sum::<Vec3>() / total;
    let (up, up_detected) = match up {
        Some(u) => (u, false),
        None => {
            let axis = ext.imax();
            let frac = (centroid[axis] - lo[axis]) / ext[axis].max(Real::MIN_POSITIVE);
            (
                SignedAxis {
                    axis,
                    negative: frac < 0.5,
                },
                true,
            )
        }
    };
    let height = ext[up.axis];
    let axis_name = up.name();
    let in_range = |m: Real| (HEIGHT_RANGE_M.0..=HEIGHT_RANGE_M.1).contains(&m);
    let (units, units_detected) = match units {
        Some(u) => {
            if !in_range(height * u.scale()) {
                return Err(FrameError::DeclaredUnits {
                    height,
                    axis: axis_name,
                    units: u.name(),
                    metres: height * u.scale(),
                });
            }
            (u, false)
        }
        None => {
            let fits: Vec<LengthUnit> = [LengthUnit::Mm, LengthUnit::Cm, LengthUnit::M]
                .into_iter()
                .filter(|u| in_range(height * u.scale()))
                .collect();
            match fits.as_slice() {
                [u] => (*u, true),
                [] => {
                    return Err(FrameError::NoUnits {
                        height,
                        axis: axis_name,
                    });
                }
                [a, b, ..] => {
                    return Err(FrameError::Ambiguous {
                        height,
                        a: a.name(),
                        b: b.name(),
                    });
                }
            }
        }
    };
    // Facing: lateral = larger horizontal extent; front along the other one, by the feet.
    let up_v = up.vector();
    let horizontal: Vec<usize> = (0..3).filter(|&a| a != up.axis).collect();
    let (lat, depth) = if ext[horizontal[0]] >= ext[horizontal[1]] {
        (horizontal[0], horizontal[1])
    } else {
        (horizontal[1], horizontal[0])
    };
    let _ = lat;
    let rel = |c: &Vec3| {
        let h = (c - lo).dot(&up_v.abs());
        if up.negative { height - h } else { h }
    };
    let band = |a: Real, b: Real| {
        let (mut sum, mut w) = (0.0, 0.0);
        for (c, area) in &s {
            let t = rel(c) / height;
            if t >= a && t <= b {
                sum += c[depth] * area;
                w += area;
            }
        }
        (w > 0.0).then(|| sum / w)
    };
    let mut depth_axis = Vec3::zeros();
    depth_axis[depth] = 1.0;
    let (front, facing_detected) = match (band(0.0, 0.04), band(0.10, 0.35)) {
        (Some(feet), Some(shins)) if (feet - shins).abs() > 0.01 * height => {
            (depth_axis * (feet - shins).signum(), true)
        }
        _ => {
            // Convention: y-up faces +z; z-up faces −y; x-up faces +z.
            let f = match up.axis {
                1 => Vec3::z(),
                2 => -Vec3::y(),
                _ => Vec3::z(),
            };
            let f = if up.negative && up.axis == 2 { -f } else { f };
            (f, false)
        }
    };
    // Rows of R: the images of the new axes in scan coordinates: x' = lateral, y' = up, z' = front.
    let y_axis = up_v;
    let z_axis = front;
    let x_axis = y_axis.cross(&z_axis);
    let rotation = Mat3::from_rows(&[x_axis.transpose(), y_axis.transpose(), z_axis.transpose()]);
    Ok(Frame {
        units,
        units_detected,
        up,
        up_detected,
        front,
        facing_detected,
        height_m: height * units.scale(),
        rotation,
        scale: units.scale(),
    })
}

/// Applies the frame's transform to every position.
pub fn apply_frame(positions: &mut [Vec3], frame: &Frame) {
    for p in positions {
        *p = frame.rotation * *p * frame.scale;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::read_mesh;
    use crate::test_meshes;

    /// The body rotated to +z up (facing −y), in millimetres, comes back exactly.
    #[test]
    fn z_up_millimetres_body_comes_back() {
        let body = read_mesh(&test_meshes::body("regular_1k.obj")).unwrap();
        let scan: Vec<Vec3> = body
            .positions
            .iter()
            .map(|p| Vec3::new(p.x, -p.z, p.y) * 1000.0)
            .collect();
        let frame = detect_frame(&scan, &body.faces, None, None).unwrap();
        assert_eq!(frame.units, LengthUnit::Mm);
        assert_eq!(frame.up.name(), "+z");
        assert!(frame.facing_detected);
        assert!((frame.rotation.determinant() - 1.0).abs() < 1e-12);
        let mut back = scan.clone();
        apply_frame(&mut back, &frame);
        for (a, b) in back.iter().zip(&body.positions) {
            assert!((a - b).norm() < 1e-12);
        }
    }

    #[test]
    fn every_body_keeps_its_frame_and_facing() {
        for shape in ["regular", "male", "athletic", "overweight", "kid"] {
            let body = read_mesh(&test_meshes::body(&format!("{shape}_1k.obj"))).unwrap();
            let frame = detect_frame(&body.positions, &body.faces, None, None).unwrap();
            assert_eq!(frame.units, LengthUnit::M, "{shape}");
            assert_eq!(frame.up.name(), "+y", "{shape}");
            assert!(frame.facing_detected, "{shape}");
            assert!(
                (frame.rotation - Mat3::identity()).norm() < 1e-12,
                "{shape}"
            );
            // Upside down (a proper rotation by π about x): found again.
            let flipped: Vec<Vec3> = body
                .positions
                .iter()
                .map(|p| Vec3::new(p.x, -p.y, -p.z))
                .collect();
            let frame = detect_frame(&flipped, &body.faces, None, None).unwrap();
            assert_eq!(frame.up.name(), "-y", "{shape}");
            let mut back = flipped.clone();
            apply_frame(&mut back, &frame);
            assert!((back[0] - body.positions[0]).norm() < 1e-12, "{shape}");
        }
    }

    #[test]
    fn heights_that_fit_no_reading_are_refused() {
        let body = read_mesh(&test_meshes::body("regular_370.obj")).unwrap();
        let giant: Vec<Vec3> = body.positions.iter().map(|p| p * 25.0).collect();
        let e = detect_frame(&giant, &body.faces, None, None).unwrap_err();
        assert!(e.to_string().contains("no reading"), "{e}");
        let e = detect_frame(&body.positions, &body.faces, Some(LengthUnit::Mm), None).unwrap_err();
        assert!(e.to_string().contains("outside the 1.0–2.1 m"), "{e}");
        assert_eq!(detect_frame(&[], &[], None, None), Err(FrameError::Empty));
    }
}
