//! Triangle surface meshes.

use crate::math::{Real, Vec3};

/// A triangle surface mesh: `#V` positions (m) and `#F` faces of three vertex indices, counter-clockwise seen
/// from outside when the mesh is a correctly oriented closed surface.
///
/// Faces may carry a group label (OBJ `g`/`o` names): `face_groups[f]` indexes `group_names`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// `#V` vertex positions (m).
    pub positions: Vec<Vec3>,
    /// `#F` triangles as vertex indices.
    pub faces: Vec<[usize; 3]>,
    /// `#F` group labels indexing `group_names`; empty when the source had no groups.
    pub face_groups: Vec<u32>,
    /// Names of the face groups.
    pub group_names: Vec<String>,
}

impl TriMesh {
    /// A mesh without group labels.
    pub fn new(positions: Vec<Vec3>, faces: Vec<[usize; 3]>) -> Self {
        Self {
            positions,
            faces,
            face_groups: Vec::new(),
            group_names: Vec::new(),
        }
    }

    /// Number of vertices `#V`.
    pub fn num_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of faces `#F`.
    pub fn num_faces(&self) -> usize {
        self.faces.len()
    }

    /// The three corner positions of face `f` (m).
    pub fn corners(&self, f: usize) -> [Vec3; 3] {
        let [a, b, c] = self.faces[f];
        [self.positions[a], self.positions[b], self.positions[c]]
    }

    /// Area-weighted normal of face `f`: `(b − a) × (c − a)`, of length twice the face area (m²).
    pub fn face_area_normal(&self, f: usize) -> Vec3 {
        let [a, b, c] = self.corners(f);
        (b - a).cross(&(c - a))
    }

    /// Unit area-weighted vertex normals (`#V × 3`; zero at a vertex with no face or a zero-area fan).
    pub fn vertex_normals(&self) -> Vec<Vec3> {
        let mut n = vec![Vec3::zeros(); self.num_vertices()];
        for f in 0..self.num_faces() {
            let a = self.face_area_normal(f);
            for &v in &self.faces[f] {
                n[v] += a;
            }
        }
        for x in &mut n {
            let l = x.norm();
            if l > 0.0 {
                *x /= l;
            }
        }
        n
    }

    /// Area of face `f` (m²).
    pub fn face_area(&self, f: usize) -> Real {
        0.5 * self.face_area_normal(f).norm()
    }

    /// Total surface area (m²).
    pub fn area(&self) -> Real {
        (0..self.num_faces()).map(|f| self.face_area(f)).sum()
    }

    /// Signed enclosed volume (m³) by the divergence theorem; positive for a closed, outward-oriented surface.
    /// Meaningless for an open surface.
    pub fn signed_volume(&self) -> Real {
        self.faces
            .iter()
            .map(|&[a, b, c]| {
                self.positions[a].dot(&self.positions[b].cross(&self.positions[c])) / 6.0
            })
            .sum()
    }

    /// Axis-aligned bounding box `(min, max)` (m); `None` for a mesh without vertices.
    pub fn bounding_box(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
        )
    }

    /// Reverses the orientation of every face (turns inward normals outward and vice versa).
    pub fn flip_orientation(&mut self) {
        for f in &mut self.faces {
            f.swap(1, 2);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetrahedron() -> TriMesh {
        TriMesh::new(
            vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
    }

    #[test]
    fn unit_tetrahedron_volume_and_area() {
        let m = tetrahedron();
        assert!((m.signed_volume() - 1.0 / 6.0).abs() < 1e-15);
        let area = 1.5 + 0.5 * 3f64.sqrt();
        assert!((m.area() - area).abs() < 1e-14);
    }

    #[test]
    fn flipping_negates_volume() {
        let mut m = tetrahedron();
        m.flip_orientation();
        assert!((m.signed_volume() + 1.0 / 6.0).abs() < 1e-15);
    }
}
