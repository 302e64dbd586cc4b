//! The material frames of a yarn-level frame sequence: per yarn segment the edge and the two material
//! normals `n₁, n₂` that the per-segment deformation gradient needs ([`crate::segment_deformation`]).
//!
//! A sequence frame holds per vertex the position (m) and the angle `θ` (rad) of the edge starting there
//! (`skintight_knit::frame_sequence`). `θ` is measured from the rod's reference director `u`, which the
//! simulator carries by time-parallel transport (Bergou et al. 2008, §5; `skintight_knit::frames`):
//! `u ← P_{t_old→t_new} u` as the tangent moves, and the material normals are
//!
//! ```text
//! n₁ = m₁ = cos θ u + sin θ (t × u),    n₂ = m₂ = −sin θ u + cos θ (t × u).
//! ```
//!
//! The directors are not stored in the sequence, so [`DirectorTransport`] rebuilds them the same way:
//! starting from a director chosen at rest (any unit vector ⊥ the rest tangent) it transports each edge's
//! director from frame to frame, in sequence order. Two facts make this sound. (1) The choice at rest does
//! not matter: another choice rotates `u` by some angle `β` about `t`, parallel transport keeps that offset
//! in every frame, so the material frames at rest and deformed turn by the same `β` about their tangents
//! and `Fʸ = [e, n₁, n₂][ē, n̄₁, n̄₂]⁻¹` is unchanged. (2) The simulator transports over its time steps,
//! this over frame intervals; the two differ by the holonomy of the tangent's path on the unit sphere
//! (the solid angle it encloses), second order in the tangent's turn per frame. Frames must therefore be
//! fed in order; an edge that turns by exactly π between two frames (no unique transport) is turned about
//! its director.

use nalgebra::Vector3;
use skintight_knit::frame_sequence::YarnRange;
use skintight_knit::frames::EdgeFrame;

use crate::segment_deformation::SegmentFrame;
use crate::shape_fit_error::ShapeFitError;

/// One yarn pose: vertex positions and the segments' material frames.
#[derive(Clone, Debug, PartialEq)]
pub struct YarnPose {
    /// Yarn vertex positions, `#Y × 3` (m).
    pub positions: Vec<[f64; 3]>,
    /// Per segment (in [`DirectorTransport::edges`] order) its edge and material normals.
    pub segments: Vec<SegmentFrame>,
}

/// The reference directors of every yarn edge, carried from frame to frame by parallel transport.
#[derive(Clone, Debug)]
pub struct DirectorTransport {
    edges: Vec<[usize; 2]>,
    frames: Vec<EdgeFrame>,
    vertex_count: usize,
}

/// The segments `[from, to]` of the yarns: consecutive vertices, and last-to-first for a closed yarn.
/// Fails when the ranges do not cover `0..vertex_count` in order or a closed yarn has fewer than 3 vertices.
pub fn yarn_edges(
    yarns: &[YarnRange],
    vertex_count: usize,
) -> Result<Vec<[usize; 2]>, ShapeFitError> {
    let mut next = 0;
    let mut edges = Vec::new();
    for (i, y) in yarns.iter().enumerate() {
        if y.first_vertex != next {
            return Err(ShapeFitError::Yarns {
                yarn: i,
                problem: format!(
                    "starts at vertex {} but the previous yarn ended at {next}; the yarn ranges must \
                     cover the vertices in order",
                    y.first_vertex
                ),
            });
        }
        if y.closed && y.vertex_count < 3 {
            return Err(ShapeFitError::Yarns {
                yarn: i,
                problem: format!(
                    "is closed with {} vertices; a closed yarn needs at least 3",
                    y.vertex_count
                ),
            });
        }
        let end = y.first_vertex + y.vertex_count;
        for v in y.first_vertex..end.saturating_sub(1) {
            edges.push([v, v + 1]);
        }
        if y.closed {
            edges.push([end - 1, y.first_vertex]);
        }
        next = end;
    }
    if next != vertex_count {
        return Err(ShapeFitError::Count {
            what: "the frame",
            got: vertex_count,
            expected: next,
            per: "yarn vertex of the yarn ranges",
        });
    }
    Ok(edges)
}

fn position(row: &[f64; 4]) -> Vector3<f64> {
    Vector3::new(row[0], row[1], row[2])
}

/// Checks a frame's rows: the count and that every number is finite.
pub fn check_rows(rows: &[[f64; 4]], vertex_count: usize) -> Result<(), ShapeFitError> {
    if rows.len() != vertex_count {
        return Err(ShapeFitError::Count {
            what: "the frame",
            got: rows.len(),
            expected: vertex_count,
            per: "yarn vertex (x, y, z in m, θ in rad)",
        });
    }
    for (i, r) in rows.iter().enumerate() {
        if let Some(&value) = r.iter().find(|v| !v.is_finite()) {
            return Err(ShapeFitError::NotFinite {
                what: "frame row (yarn vertex)",
                index: i,
                value,
            });
        }
    }
    Ok(())
}

impl DirectorTransport {
    /// The transport for `yarns` starting at the rest frame `rest` (`#Y` rows: x, y, z in m, θ in rad):
    /// each edge's director is the unit vector ⊥ its rest tangent closest to the coordinate axis least
    /// aligned with it.
    pub fn new(yarns: &[YarnRange], rest: &[[f64; 4]]) -> Result<Self, ShapeFitError> {
        let edges = yarn_edges(yarns, rest.len())?;
        check_rows(rest, rest.len())?;
        let mut frames = Vec::with_capacity(edges.len());
        for (s, &[a, b]) in edges.iter().enumerate() {
            let e = position(&rest[b]) - position(&rest[a]);
            let length = e.norm();
            if length.is_nan() || length <= 0.0 {
                return Err(ShapeFitError::DegenerateSegment {
                    segment: s,
                    from: a,
                    to: b,
                    length_m: length,
                });
            }
            let t = e / length;
            let k = (0..3)
                .min_by(|&i, &j| t[i].abs().total_cmp(&t[j].abs()))
                .unwrap_or(0);
            let axis = Vector3::ith(k, 1.0);
            let u = (axis - t * axis.dot(&t)).normalize();
            frames.push(EdgeFrame {
                director: u.into(),
                tangent: t.into(),
            });
        }
        Ok(Self {
            edges,
            frames,
            vertex_count: rest.len(),
        })
    }

    /// The segments `[from, to]` (yarn vertex indices), `#S × 2`.
    pub fn edges(&self) -> &[[usize; 2]] {
        &self.edges
    }

    /// Number of yarn vertices `#Y`.
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// The pose of the next frame (`#Y` rows: x, y, z in m, θ in rad): transports every director to the
    /// frame's tangents (and keeps them there for the next call) and returns positions and material
    /// frames. The rest frame itself may be passed first (the transport is then the identity).
    pub fn pose(&mut self, rows: &[[f64; 4]]) -> Result<YarnPose, ShapeFitError> {
        check_rows(rows, self.vertex_count)?;
        let mut segments = Vec::with_capacity(self.edges.len());
        for (s, (&[a, b], frame)) in self.edges.iter().zip(&mut self.frames).enumerate() {
            let e = position(&rows[b]) - position(&rows[a]);
            let length = e.norm();
            if length.is_nan() || length <= 0.0 {
                return Err(ShapeFitError::CollapsedSegment {
                    segment: s,
                    from: a,
                    to: b,
                });
            }
            let t = e / length;
            let old = Vector3::from(frame.tangent);
            let u = if 1.0 + old.dot(&t) < 1e-12 {
                // Reversed tangent: turn by π about the director, which keeps it.
                Vector3::from(frame.director)
            } else {
                Vector3::from(frame.director_at::<f64>(t.into()))
            };
            // Keep the director unit and ⊥ t against rounding drift, as the simulator's re-basing does.
            let u = (u - t * u.dot(&t)).normalize();
            frame.director = u.into();
            frame.tangent = t.into();
            let v = t.cross(&u);
            let (sin, cos) = rows[a][3].sin_cos();
            segments.push(SegmentFrame {
                edge: e,
                normals: [u * cos + v * sin, v * cos - u * sin],
            });
        }
        Ok(YarnPose {
            positions: rows.iter().map(|r| [r[0], r[1], r[2]]).collect(),
            segments,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation_average::rotation_exp;
    use crate::segment_deformation::{rest_frame_inverse, segment_deformation};
    use nalgebra::Matrix3;
    use skintight_knit::frames::parallel_transport;

    fn ring(n: usize, radius: f64) -> Vec<[f64; 4]> {
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                [
                    radius * a.cos(),
                    radius * a.sin(),
                    0.1 * radius * (3.0 * a).sin(),
                    0.1 * i as f64,
                ]
            })
            .collect()
    }

    fn yarns() -> Vec<YarnRange> {
        vec![
            YarnRange {
                first_vertex: 0,
                vertex_count: 12,
                closed: true,
            },
            YarnRange {
                first_vertex: 12,
                vertex_count: 5,
                closed: false,
            },
        ]
    }

    fn rest() -> Vec<[f64; 4]> {
        let mut rows = ring(12, 3e-3);
        rows.extend((0..5).map(|i| [1e-3 * i as f64, 5e-3, 1e-4 * (i * i) as f64, 0.0]));
        rows
    }

    fn rotated(rows: &[[f64; 4]], q: &Matrix3<f64>) -> Vec<[f64; 4]> {
        rows.iter()
            .map(|r| {
                let p = q * Vector3::new(r[0], r[1], r[2]);
                [p.x, p.y, p.z, r[3]]
            })
            .collect()
    }

    #[test]
    fn frames_are_orthonormal_and_follow_a_rigid_rotation() {
        let rest = rest();
        let mut transport = DirectorTransport::new(&yarns(), &rest).unwrap();
        assert_eq!(transport.edges().len(), 12 + 4);
        let start = transport.clone();
        let rest_pose = transport.pose(&rest).unwrap();
        for s in &rest_pose.segments {
            let t = s.edge.normalize();
            let [n1, n2] = s.normals;
            assert!((n1.norm() - 1.0).abs() < 1e-14 && (n2.norm() - 1.0).abs() < 1e-14);
            assert!(
                n1.dot(&t).abs() < 1e-14 && n2.dot(&t).abs() < 1e-14 && n1.dot(&n2).abs() < 1e-14
            );
            assert!((t.cross(&n1) - n2).norm() < 1e-14);
        }
        // One rigid rotation Q. Twist-free transport takes t̄ to Q t̄ by the smallest rotation, so the rod's
        // angle must absorb the twist ψ of Q about the new tangent: θ = θ̄ + ψ, with ψ the signed angle
        // from P_{t̄→t} ū to Q ū (what a simulator reports for a rigidly turned rod). Then Fʸ = Q.
        let q = rotation_exp(&Vector3::new(0.9, -0.4, 1.3));
        let mut rows = rotated(&rest, &q);
        for (s, &[a, b]) in transport.edges().to_vec().iter().enumerate() {
            let f = &start.frames[s];
            let t = (Vector3::new(rows[b][0], rows[b][1], rows[b][2])
                - Vector3::new(rows[a][0], rows[a][1], rows[a][2]))
            .normalize();
            let transported =
                Vector3::from(parallel_transport::<f64>(f.director, f.tangent, t.into()));
            let turned = q * Vector3::from(f.director);
            rows[a][3] += transported
                .cross(&turned)
                .dot(&t)
                .atan2(transported.dot(&turned));
        }
        let pose = transport.pose(&rows).unwrap();
        for (rest_s, s) in rest_pose.segments.iter().zip(&pose.segments) {
            let f = segment_deformation(&rest_frame_inverse(rest_s).unwrap(), s);
            assert!((f - q).norm() < 1e-12, "{f} vs {q}");
        }
        // A planar yarn turned in its plane over 40 frames with θ held: every tangent moves on a great
        // circle, so frame-to-frame transport is the rotation itself and Fʸ = Q exactly.
        let planar: Vec<[f64; 4]> = (0..9)
            .map(|i| {
                let s = i as f64 * 1e-3;
                [s, 2e-3 * (s * 900.0).sin(), 0.0, 0.3 * i as f64]
            })
            .collect();
        let open = [YarnRange {
            first_vertex: 0,
            vertex_count: 9,
            closed: false,
        }];
        let mut transport = DirectorTransport::new(&open, &planar).unwrap();
        let rest_pose = transport.pose(&planar).unwrap();
        let mut pose = rest_pose.clone();
        let steps = 40;
        for k in 1..=steps {
            let q = rotation_exp(&Vector3::new(0.0, 0.0, 2.5 * k as f64 / steps as f64));
            pose = transport.pose(&rotated(&planar, &q)).unwrap();
        }
        let q = rotation_exp(&Vector3::new(0.0, 0.0, 2.5));
        for (rest_s, s) in rest_pose.segments.iter().zip(&pose.segments) {
            let f = segment_deformation(&rest_frame_inverse(rest_s).unwrap(), s);
            assert!((f - q).norm() < 1e-12, "{f} vs {q}");
        }
    }

    #[test]
    fn the_rest_director_choice_does_not_change_the_deformation_gradient() {
        // Two transports whose rest directors differ by β about each tangent, with θ offset by −β so the
        // rest material frames agree: the deformed material frames agree too.
        let rest = rest();
        let mut a = DirectorTransport::new(&yarns(), &rest).unwrap();
        let mut b = a.clone();
        let beta: f64 = 0.7;
        for f in &mut b.frames {
            let t = Vector3::from(f.tangent);
            let u = Vector3::from(f.director);
            f.director = (u * beta.cos() + t.cross(&u) * beta.sin()).into();
        }
        let shift = |rows: &[[f64; 4]]| -> Vec<[f64; 4]> {
            rows.iter()
                .map(|r| [r[0], r[1], r[2], r[3] - beta])
                .collect()
        };
        let ra = a.pose(&rest).unwrap();
        let rb = b.pose(&shift(&rest)).unwrap();
        let moved: Vec<[f64; 4]> = rest
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let w = 1e-4 * (i as f64).sin();
                [
                    r[0] * 1.1 + w,
                    r[1] - 0.3 * r[0],
                    r[2] + w,
                    r[3] + 0.05 * i as f64,
                ]
            })
            .collect();
        let da = a.pose(&moved).unwrap();
        let db = b.pose(&shift(&moved)).unwrap();
        for s in 0..ra.segments.len() {
            let fa = segment_deformation(
                &rest_frame_inverse(&ra.segments[s]).unwrap(),
                &da.segments[s],
            );
            let fb = segment_deformation(
                &rest_frame_inverse(&rb.segments[s]).unwrap(),
                &db.segments[s],
            );
            assert!((fa - fb).norm() < 1e-12);
        }
    }

    #[test]
    fn bad_frames_are_named() {
        let rest = rest();
        let mut t = DirectorTransport::new(&yarns(), &rest).unwrap();
        let e = t.pose(&rest[..5]).unwrap_err().to_string();
        assert!(e.contains("frame has 5 entries, expected 17"), "{e}");
        let mut nan = rest.clone();
        nan[3][1] = f64::NAN;
        let e = t.pose(&nan).unwrap_err().to_string();
        assert!(e.contains("frame row (yarn vertex) 3 is not finite"), "{e}");
        let mut collapsed = rest.clone();
        collapsed[13] = collapsed[12];
        let e = t.pose(&collapsed).unwrap_err().to_string();
        assert!(e.contains("zero length"), "{e}");
        let mut bad = yarns();
        bad[1].first_vertex = 11;
        let e = DirectorTransport::new(&bad, &rest).unwrap_err().to_string();
        assert!(e.contains("yarn 1"), "{e}");
        let e = DirectorTransport::new(&yarns(), &rest[..16])
            .unwrap_err()
            .to_string();
        assert!(e.contains("expected 17"), "{e}");
        let mut dup = rest.clone();
        dup[1] = dup[0];
        let e = DirectorTransport::new(&yarns(), &dup)
            .unwrap_err()
            .to_string();
        assert!(e.contains("degenerate rest frame"), "{e}");
    }
}
