//! Plane sections of a triangle mesh: the closed loops in which the plane `{x : n·x = d}` cuts the surface.
//!
//! **Method.** Every vertex gets the signed distance `s = n·p − d` and a side (`s ≥ 0` or `s < 0`; a vertex
//! exactly on the plane counts as above, which removes the degenerate cases). Every edge whose ends lie on
//! different sides is cut at `p_i + s_i/(s_i − s_j)·(p_j − p_i)`; each triangle with a cut holds exactly
//! two cut edges, joined by one segment. On a closed two-manifold each cut edge belongs to two triangles,
//! so the segments chain into closed loops; chains that do not close (an open or non-manifold mesh) are
//! dropped. The result depends only on the surface, not on how its vertices are numbered.
//!
//! Units: positions in metres (m).

use std::collections::HashMap;

use crate::math::{Real, Vec2, Vec3};
use crate::mesh::TriMesh;
use crate::polygon_area::polygon_area;

/// A closed section loop: points on the surface, in order, the last joined to the first (m).
#[derive(Clone, Debug, PartialEq)]
pub struct SectionLoop {
    /// The points, in order around the loop (m).
    pub points: Vec<Vec3>,
}

/// An orthonormal frame `(u, v)` of the plane with unit normal `n` (any such frame; deterministic).
pub fn plane_frame(n: Vec3) -> (Vec3, Vec3) {
    let helper = if n.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let u = n.cross(&helper).normalize();
    let v = n.cross(&u);
    (u, v)
}

impl SectionLoop {
    /// The points in the plane frame `(u, v)` of [`plane_frame`] for normal `n` (m).
    pub fn project(&self, n: Vec3) -> Vec<Vec2> {
        let (u, v) = plane_frame(n);
        self.points
            .iter()
            .map(|p| Vec2::new(p.dot(&u), p.dot(&v)))
            .collect()
    }

    /// Enclosed area (m², unsigned) of the loop projected on the plane with normal `n`.
    pub fn area(&self, n: Vec3) -> Real {
        polygon_area(&self.project(n)).abs()
    }

    /// Area centroid of the loop in the plane with normal `n` (m), lifted back to 3D at the plane of the
    /// loop (the mean offset of its points); the mean of the points for a degenerate loop.
    pub fn centroid(&self, n: Vec3) -> Vec3 {
        let (u, v) = plane_frame(n);
        let q = self.project(n);
        let offset =
            self.points.iter().map(|p| p.dot(&n)).sum::<Real>() / self.points.len().max(1) as Real;
        let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
        for i in 0..q.len() {
            let (p0, p1) = (q[i], q[(i + 1) % q.len()]);
            let c = p0.x * p1.y - p1.x * p0.y;
            a += c;
            cx += (p0.x + p1.x) * c;
            cy += (p0.y + p1.y) * c;
        }
        let c2 = if a.abs() > 1e-14 {
            Vec2::new(cx / (3.0 * a), cy / (3.0 * a))
        } else {
            q.iter().fold(Vec2::zeros(), |s, p| s + p) / q.len().max(1) as Real
        };
        u * c2.x + v * c2.y + n * offset
    }

    /// Whether the projection of `p` on the plane with normal `n` lies inside the loop (even–odd rule).
    pub fn contains(&self, n: Vec3, p: Vec3) -> bool {
        let (u, v) = plane_frame(n);
        let t = Vec2::new(p.dot(&u), p.dot(&v));
        let q = self.project(n);
        let mut inside = false;
        for i in 0..q.len() {
            let (a, b) = (q[i], q[(i + 1) % q.len()]);
            if (a.y > t.y) != (b.y > t.y) {
                let x = a.x + (t.y - a.y) / (b.y - a.y) * (b.x - a.x);
                if x > t.x {
                    inside = !inside;
                }
            }
        }
        inside
    }

    /// Perimeter of the loop itself (m): the length of a string laid along the surface section.
    pub fn length(&self) -> Real {
        (0..self.points.len())
            .map(|i| (self.points[(i + 1) % self.points.len()] - self.points[i]).norm())
            .sum()
    }
}

/// The closed loops in which the plane `{x : normal·x = offset}` cuts `mesh` (see the module
/// documentation). `normal` need not be unit length. Loops with fewer than three points are dropped.
pub fn plane_section(mesh: &TriMesh, normal: Vec3, offset: Real) -> Vec<SectionLoop> {
    let len = normal.norm();
    if !(len > 0.0 && len.is_finite() && offset.is_finite()) {
        return Vec::new();
    }
    let (n, d) = (normal / len, offset / len);
    let s: Vec<Real> = mesh.positions.iter().map(|p| n.dot(p) - d).collect();
    let above = |i: usize| s[i] >= 0.0;
    let key = |i: usize, j: usize| if i < j { (i, j) } else { (j, i) };
    // Cut edge → the (up to two) cut edges it is joined to.
    let mut links: HashMap<(usize, usize), Vec<(usize, usize)>> = HashMap::new();
    for f in &mesh.faces {
        let cut: Vec<(usize, usize)> = (0..3)
            .map(|k| (f[k], f[(k + 1) % 3]))
            .filter(|&(i, j)| i < s.len() && j < s.len() && above(i) != above(j))
            .map(|(i, j)| key(i, j))
            .collect();
        if cut.len() == 2 {
            links.entry(cut[0]).or_default().push(cut[1]);
            links.entry(cut[1]).or_default().push(cut[0]);
        }
    }
    let point = |(i, j): (usize, usize)| {
        let t = s[i] / (s[i] - s[j]);
        mesh.positions[i] + (mesh.positions[j] - mesh.positions[i]) * t
    };
    let mut starts: Vec<(usize, usize)> = links.keys().copied().collect();
    starts.sort_unstable();
    let mut visited: HashMap<(usize, usize), bool> = HashMap::new();
    let mut loops = Vec::new();
    for start in starts {
        if visited.contains_key(&start) || links[&start].len() != 2 {
            continue;
        }
        let mut chain = vec![start];
        visited.insert(start, true);
        let (mut prev, mut cur) = (start, links[&start][0]);
        let closed = loop {
            if cur == start {
                break true;
            }
            if visited.contains_key(&cur) {
                break false;
            }
            let next = match links.get(&cur) {
                Some(l) if l.len() == 2 => {
                    if l[0] == prev {
                        l[1]
                    } else {
                        l[0]
                    }
                }
                _ => break false,
            };
            visited.insert(cur, true);
            chain.push(cur);
            prev = cur;
            cur = next;
        };
        if closed && chain.len() >= 3 {
            loops.push(SectionLoop {
                points: chain.into_iter().map(point).collect(),
            });
        }
    }
    loops
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::icosphere;

    #[test]
    fn a_sphere_cut_through_its_centre_gives_one_great_circle() {
        let m = icosphere(4, 1.0);
        let loops = plane_section(&m, Vec3::new(0.0, 2.0, 0.0), 0.2);
        assert_eq!(loops.len(), 1);
        let r = (1.0 - 0.01_f64).sqrt();
        let l = loops[0].length();
        assert!((l - 2.0 * std::f64::consts::PI * r).abs() < 0.01 * l, "{l}");
        for p in &loops[0].points {
            assert!((p.y - 0.1).abs() < 1e-12);
        }
        let c = loops[0].centroid(Vec3::y());
        assert!(c.norm() - 0.1 < 1e-3, "{c}");
        assert!(loops[0].contains(Vec3::y(), Vec3::zeros()));
        assert!(!loops[0].contains(Vec3::y(), Vec3::new(2.0, 0.0, 0.0)));
        assert!(plane_section(&m, Vec3::y(), 1.5).is_empty());
        assert!(plane_section(&m, Vec3::zeros(), 0.0).is_empty());
    }
}
