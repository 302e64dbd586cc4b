//! The garment's connectivity as the design sees it: cloth triangles over the `#Vc` shared 3D cloth
//! vertices, and the same triangles over the `#Vp` pattern vertices of all panels (numbered panel after
//! panel). A cloth vertex on a seam has one pattern vertex on each side of the seam.

use crate::math::{Real, Vec2};
use skintight_garment::garment::Garment;
use skintight_garment::plane_cut::Border;

/// One panel's slice of the global pattern vertex numbering.
#[derive(Clone, Debug, PartialEq)]
pub struct DesignPanel {
    /// Name of the panel, as given in the scene.
    pub name: String,
    /// First global pattern vertex id of the panel.
    pub first_vertex: usize,
    /// Number of pattern vertices of the panel.
    pub num_vertices: usize,
    /// The outer boundary loop in global pattern vertex ids, counter-clockwise (panel to the left), not
    /// repeated at the end.
    pub boundary: Vec<usize>,
    /// `boundary.len()` entries: `Some(panel)` when the edge from `boundary[i]` to `boundary[i + 1]` is sewn
    /// to that panel, `None` on the garment's free boundary.
    pub boundary_borders: Vec<Option<usize>>,
}

/// Two pattern polylines sewn together, index by index the same cloth vertex.
#[derive(Clone, Debug, PartialEq)]
pub struct DesignSeam {
    /// The two panels (indices into [`DesignMesh::panels`]).
    pub panels: [usize; 2],
    /// Global pattern vertex ids along the seam on each side, same length; `vertices[0][k]` and
    /// `vertices[1][k]` are sewn together.
    pub vertices: [Vec<usize>; 2],
    /// Whether the seam is a closed loop (the last vertex connects back to the first).
    pub closed: bool,
}

/// Cloth and pattern connectivity of one garment.
#[derive(Clone, Debug, PartialEq)]
pub struct DesignMesh {
    /// `#Fc × 3` cloth triangles in cloth vertex ids (`#Vc` vertices), counter-clockwise from outside.
    pub cloth_triangles: Vec<[usize; 3]>,
    /// `#Fc × 3` the same triangles in global pattern vertex ids, corner `k` of triangle `f` being the
    /// pattern vertex of cloth vertex `cloth_triangles[f][k]`; counter-clockwise in the pattern plane.
    pub pattern_triangles: Vec<[usize; 3]>,
    /// `#Vp` cloth vertex of each pattern vertex.
    pub pattern_cloth_vertex: Vec<usize>,
    /// `#Vp` panel of each pattern vertex.
    pub pattern_panel: Vec<usize>,
    /// The panels.
    pub panels: Vec<DesignPanel>,
    /// The seams.
    pub seams: Vec<DesignSeam>,
    /// Number of cloth vertices `#Vc`.
    pub num_cloth_vertices: usize,
}

impl DesignMesh {
    /// The connectivity of `garment`, and its `#Vp` pattern positions (m) in the global numbering.
    pub fn from_garment(garment: &Garment) -> (Self, Vec<Vec2>) {
        let mut first = Vec::with_capacity(garment.panels.len());
        let mut pattern = Vec::new();
        let mut pattern_cloth_vertex = Vec::new();
        let mut pattern_panel = Vec::new();
        for (p, panel) in garment.panels.iter().enumerate() {
            first.push(pattern.len());
            pattern.extend_from_slice(&panel.pattern);
            pattern_cloth_vertex.extend_from_slice(&panel.cloth_vertex);
            pattern_panel.extend(std::iter::repeat_n(p, panel.pattern.len()));
        }
        let pattern_triangles = (0..garment.num_faces())
            .map(|f| {
                let p = garment.face_panel[f];
                garment.panels[p].faces[garment.face_pattern[f]].map(|v| first[p] + v)
            })
            .collect();
        let panels = garment
            .panels
            .iter()
            .enumerate()
            .map(|(p, panel)| {
                let outer = &panel.boundary[0];
                DesignPanel {
                    name: panel.name.clone(),
                    first_vertex: first[p],
                    num_vertices: panel.pattern.len(),
                    boundary: outer.vertices.iter().map(|&v| first[p] + v).collect(),
                    boundary_borders: outer
                        .borders
                        .iter()
                        .map(|b| match b {
                            Border::Seam { panel } => Some(*panel),
                            Border::Free => None,
                        })
                        .collect(),
                }
            })
            .collect();
        let seams = garment
            .seams
            .iter()
            .map(|s| DesignSeam {
                panels: s.panels,
                vertices: [0, 1].map(|k| {
                    s.vertices[k]
                        .iter()
                        .map(|&v| first[s.panels[k]] + v)
                        .collect()
                }),
                closed: s.closed,
            })
            .collect();
        let mesh = Self {
            cloth_triangles: garment.faces.clone(),
            pattern_triangles,
            pattern_cloth_vertex,
            pattern_panel,
            panels,
            seams,
            num_cloth_vertices: garment.num_vertices(),
        };
        (mesh, pattern)
    }

    /// Number of pattern vertices `#Vp`.
    pub fn num_pattern_vertices(&self) -> usize {
        self.pattern_cloth_vertex.len()
    }

    /// Number of triangles `#Fc`.
    pub fn num_triangles(&self) -> usize {
        self.cloth_triangles.len()
    }

    /// Rest area (m²) of triangle `f` at pattern positions `pattern` (signed: positive when
    /// counter-clockwise).
    pub fn pattern_area(&self, pattern: &[Vec2], f: usize) -> Real {
        let [a, b, c] = self.pattern_triangles[f].map(|v| pattern[v]);
        0.5 * (b - a).perp(&(c - a))
    }
}
