//! The flat, piecewise-linear body surface of thesis Eq. 119: `x = s1 y1 + s2 y2 + (1 − s1 − s2) y3`.

use crate::math::{FaceId, Vec2, VertexId};
use crate::mesh::topology::Topology;
use crate::surface::{LimitSurface, Stencil, SurfaceError, checked_coords};

/// The control mesh itself as a surface: each point depends on its face's three vertices (Eq. 119), with
/// `s1` the weight of `f[0]`, `s2` of `f[1]` and `s3 = 1 − s1 − s2` of `f[2]`. Second derivatives vanish.
#[derive(Clone, Debug)]
pub struct LinearSurface {
    topology: Topology,
}

impl LinearSurface {
    /// The linear surface over `faces` of a mesh with `num_vertices` control vertices. Boundaries are
    /// allowed; the faces must form an oriented manifold.
    pub fn new(num_vertices: usize, faces: &[[VertexId; 3]]) -> Result<Self, SurfaceError> {
        Ok(Self {
            topology: Topology::new(num_vertices, faces)?,
        })
    }
}

impl LimitSurface for LinearSurface {
    fn num_faces(&self) -> usize {
        self.topology.num_faces()
    }

    fn num_control_vertices(&self) -> usize {
        self.topology.num_vertices()
    }

    fn topology(&self) -> &Topology {
        &self.topology
    }

    fn stencil(&self, face: FaceId, s: Vec2, out: &mut Stencil) -> Result<(), SurfaceError> {
        let [s1, s2] = checked_coords(face, self.num_faces(), s)?;
        let [a, b, c] = self.topology.faces()[face];
        out.clear();
        out.add(a, 1.0, s1, [1.0, 0.0], [0.0; 3]);
        out.add(b, 1.0, s2, [0.0, 1.0], [0.0; 3]);
        out.add(c, 1.0, 1.0 - s1 - s2, [-1.0, -1.0], [0.0; 3]);
        Ok(())
    }
}
