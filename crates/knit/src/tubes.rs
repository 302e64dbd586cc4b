//! Yarns as tube meshes for viewing (`.glb` through the workspace's glTF writer,
//! [`skintight_geometry::mesh::io::write_glb`]).
//!
//! Around every vertex `x_i` of a yarn polyline a ring of `s` points `x_i + r (cos φ_j u_i + sin φ_j v_i)`,
//! `φ_j = 2π j/s`, lies in the plane normal to the vertex tangent `t_i` (the normalised sum of the unit
//! tangents of its edges); `u_i` is the previous ring's `u` parallel-transported to `t_i` (a twist-free
//! frame, [`crate::frames::parallel_transport`]) and `v_i = t_i × u_i`. Consecutive rings are joined by two
//! triangles per side; an open yarn is closed by a fan at each end, a closed yarn joins its last ring to
//! its first (turned to the nearest matching point, so the seam is not twisted). Every tube is a closed,
//! consistently oriented surface (outward normals). Positions in m; vertex normals are the unit ring
//! directions.

use skintight_geometry::mesh::io::{MeshIoError, WriteParams, write_glb};
use skintight_geometry::{TriMesh, Vec3};

use crate::frames::{cross, dot, norm, parallel_transport, scale, sub};

/// A triangle mesh of tubes with outward vertex normals.
#[derive(Clone, Debug)]
pub struct Tubes {
    /// The triangles (positions in m).
    pub mesh: TriMesh,
    /// Unit vertex normals.
    pub normals: Vec<Vec3>,
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let l = norm(v);
    if l > 0.0 { scale(v, 1.0 / l) } else { v }
}

/// Any unit vector perpendicular to the unit `t`.
fn perpendicular(t: [f64; 3]) -> [f64; 3] {
    let a = if t[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    unit(sub(a, scale(t, dot(a, t))))
}

/// Tubes of radius `radius` (m) with `sides` (≥ 3) points per ring around the polylines `yarns` (each a
/// list of positions in m and whether it is closed). Polylines with fewer than 2 points are skipped, as
/// are repeated points.
pub fn tubes(yarns: &[(&[[f64; 3]], bool)], radius: f64, sides: usize) -> Tubes {
    let sides = sides.max(3);
    let mut positions: Vec<Vec3> = Vec::new();
    let mut normals: Vec<Vec3> = Vec::new();
    let mut faces: Vec<[usize; 3]> = Vec::new();
    for &(points, closed) in yarns {
        let mut pts: Vec<[f64; 3]> = Vec::with_capacity(points.len());
        for p in points {
            if pts
                .last()
                .is_none_or(|q| norm(sub(*p, *q)) > 1e-12 * radius)
            {
                pts.push(*p);
            }
        }
        let closed = closed && pts.len() >= 3;
        if closed && norm(sub(pts[0], *pts.last().unwrap())) <= 1e-12 * radius {
            pts.pop();
        }
        let n = pts.len();
        if n < 2 {
            continue;
        }
        let edge = |k: usize| unit(sub(pts[(k + 1) % n], pts[k]));
        let edges = if closed { n } else { n - 1 };
        let tangents: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let prev = if closed || i > 0 {
                    Some(edge((i + n - 1) % n))
                } else {
                    None
                };
                let next = (i < edges).then(|| edge(i));
                match (prev, next) {
                    (Some(a), Some(b)) => {
                        let s = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
                        if norm(s) > 1e-9 { unit(s) } else { b }
                    }
                    (Some(a), None) => a,
                    (None, Some(b)) => b,
                    (None, None) => [0.0, 0.0, 1.0],
                }
            })
            .collect();
        let mut u = perpendicular(tangents[0]);
        let mut us = Vec::with_capacity(n);
        for i in 0..n {
            if i > 0 {
                let (t0, t1) = (tangents[i - 1], tangents[i]);
                u = if dot(t0, t1) > -0.999 {
                    unit(parallel_transport(u, t0, t1))
                } else {
                    perpendicular(t1)
                };
                u = unit(sub(u, scale(t1, dot(u, t1))));
            }
            us.push(u);
        }
        let base = positions.len();
        for i in 0..n {
            let (t, u) = (tangents[i], us[i]);
            let v = cross(t, u);
            for j in 0..sides {
                let phi = std::f64::consts::TAU * j as f64 / sides as f64;
                let d = [
                    phi.cos() * u[0] + phi.sin() * v[0],
                    phi.cos() * u[1] + phi.sin() * v[1],
                    phi.cos() * u[2] + phi.sin() * v[2],
                ];
                positions.push(Vec3::new(
                    pts[i][0] + radius * d[0],
                    pts[i][1] + radius * d[1],
                    pts[i][2] + radius * d[2],
                ));
                normals.push(Vec3::new(d[0], d[1], d[2]));
            }
        }
        let ring = |i: usize, j: usize| base + i * sides + j % sides;
        // Ring point j sits at angle φ_j from u toward v = t × u; the triangles (i, j), (i, j+1), (i+1, j+1)
        // and (i, j), (i+1, j+1), (i+1, j) have normals along φ̂ × t = the outward ring direction.
        let join = |i0: usize, i1: usize, turn: usize, faces: &mut Vec<[usize; 3]>| {
            for j in 0..sides {
                let a = ring(i0, j);
                let b = ring(i0, j + 1);
                let c = ring(i1, j + turn);
                let d = ring(i1, j + 1 + turn);
                faces.push([a, b, d]);
                faces.push([a, d, c]);
            }
        };
        for i in 0..n - 1 {
            join(i, i + 1, 0, &mut faces);
        }
        if closed {
            // Turn the first ring's points to the last ring's nearest one.
            let u_last = us[n - 1];
            let u0 = us[0];
            let t0 = tangents[0];
            let carried = unit(parallel_transport(u_last, tangents[n - 1], t0));
            let angle = dot(cross(carried, u0), t0).atan2(dot(carried, u0));
            let turn = ((-angle / std::f64::consts::TAU * sides as f64).round() as i64)
                .rem_euclid(sides as i64) as usize;
            join(n - 1, 0, turn, &mut faces);
        } else {
            for (i, sign) in [(0usize, -1.0), (n - 1, 1.0)] {
                let t = tangents[i];
                let centre = positions.len();
                positions.push(Vec3::new(pts[i][0], pts[i][1], pts[i][2]));
                normals.push(Vec3::new(sign * t[0], sign * t[1], sign * t[2]));
                for j in 0..sides {
                    let (a, b) = (ring(i, j), ring(i, j + 1));
                    // Start cap faces −t, end cap faces +t; the ring turns positively about t.
                    if sign < 0.0 {
                        faces.push([centre, b, a]);
                    } else {
                        faces.push([centre, a, b]);
                    }
                }
            }
        }
    }
    Tubes {
        mesh: TriMesh::new(positions, faces),
        normals,
    }
}

impl Tubes {
    /// The `.glb` bytes (one mesh named `name`, with normals, double-sided off: the tubes are closed).
    pub fn to_glb(&self, name: &str) -> Result<Vec<u8>, MeshIoError> {
        let extras = serde_json::json!({"skintight": "yarn tubes", "units": "m"});
        write_glb(
            &self.mesh,
            &WriteParams {
                normals: Some(&self.normals),
                name: Some(name),
                extras: Some(&extras),
                ..WriteParams::default()
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signed_volume(m: &TriMesh) -> f64 {
        m.faces
            .iter()
            .map(|f| {
                let (a, b, c) = (m.positions[f[0]], m.positions[f[1]], m.positions[f[2]]);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    fn helix(n: usize, turns: f64) -> Vec<[f64; 3]> {
        (0..n)
            .map(|i| {
                let s = i as f64 / (n - 1) as f64 * turns * std::f64::consts::TAU;
                [0.01 * s.cos(), 0.01 * s.sin(), 0.002 * s]
            })
            .collect()
    }

    #[test]
    fn tubes_are_closed_outward_surfaces_of_the_right_volume() {
        let r = 1e-3;
        let sides = 24;
        // A straight open tube: a prism of the ring polygon's area times the length.
        let straight = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.01], [0.0, 0.0, 0.03]];
        let t = tubes(&[(&straight, false)], r, sides);
        let area = 0.5 * sides as f64 * r * r * (std::f64::consts::TAU / sides as f64).sin();
        let v = signed_volume(&t.mesh);
        assert!((v - area * 0.03).abs() < 1e-9 * area * 0.03, "{v}");
        // Every edge of a closed surface is shared by exactly two faces, in opposite directions.
        let helix = helix(60, 1.5);
        let ring: Vec<[f64; 3]> = (0..40)
            .map(|i| {
                let s = i as f64 / 40.0 * std::f64::consts::TAU;
                [0.02 * s.cos(), 0.02 * s.sin(), 0.003 * (3.0 * s).sin()]
            })
            .collect();
        let t = tubes(
            &[(&helix, false), (&ring, true), (&straight[..1], false)],
            r,
            8,
        );
        let mut directed = std::collections::HashMap::new();
        for f in &t.mesh.faces {
            for k in 0..3 {
                *directed.entry((f[k], f[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &count) in &directed {
            assert_eq!(count, 1, "edge {a}-{b} used {count} times");
            assert!(directed.contains_key(&(b, a)), "edge {a}-{b} has no twin");
        }
        assert!(signed_volume(&t.mesh) > 0.0);
        assert_eq!(t.normals.len(), t.mesh.positions.len());
        let glb = t.to_glb("yarns").unwrap();
        assert_eq!(&glb[..4], b"glTF");
    }
}
