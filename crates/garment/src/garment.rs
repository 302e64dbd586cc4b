//! Garment construction: from named panels on the body surface to cloth triangles sewn together along seams,
//! each with its flat rest shape (the sewing pattern).
//!
//! Pipeline ([`garment`]):
//! 1. the body surface is cut into panels ([`panels_from_specs`]): regions are cut exactly along their planes,
//!    face-list panels take whole body faces;
//! 2. each panel is flattened by the least squares conformal map ([`lscm`]; 2D area = 3D area);
//! 3. all panels are remeshed together at the cloth edge length ([`remesh_panels`]): one shared boundary
//!    sampling, so the two sides of every seam carry the very same samples;
//! 4. each pattern is scaled by `1 + ease` about its area centroid ([`crate::ease::ease`]);
//! 5. pattern vertices are merged into 3D cloth vertices: interior vertices are the panel's own, boundary
//!    samples with the same [`sample_key`] (same cut-mesh edge and parameter) are one cloth vertex shared by
//!    every panel that meets there. Their 3D positions are checked to coincide.
//!
//! The cloth vertices start on the (flat-triangle) body mesh; each knows its body location. Cloth triangles
//! keep the body's orientation (counter-clockwise seen from outside) and their pattern triangles are
//! counter-clockwise in the plane with positive area.

use std::collections::HashMap;

use crate::ease::{EaseError, ease};
use crate::lscm::{LscmError, lscm, signed_area};
use crate::math::{Real, Vec2, Vec3};
use crate::pattern_remesh::{
    PatternMesh, RemeshError, RemeshParams, SampleKey, remesh_panels, sample_key,
};
use crate::plane_cut::{
    Border, BoundaryLoop, MeshPoint, PanelSet, PlaneCutError, PlaneCutParams, border_runs,
    panels_from_specs,
};
use skintight_geometry::mesh::TriMesh;

pub use crate::plane_cut::{PanelShape, PanelSpec};

/// Largest distance (m) allowed between the 3D positions two panels give a shared seam vertex. They are
/// computed from the same cut-mesh edge and parameter, so they agree to rounding.
const SEAM_TOLERANCE: Real = 1e-9;

/// Settings of the garment construction.
#[derive(Clone, Copy, Debug)]
pub struct GarmentParams {
    /// Target edge length of the cloth triangles (m), on the boundary and inside; should be below the body's
    /// edge length (the cloth must be finer than the body). Overrides `remesh.target_edge_length`.
    pub edge_length: Real,
    /// Relative change of every pattern length (dimensionless, > −1): −0.1 makes the pattern 10 % smaller
    /// than the body (areas 19 % smaller) so that no cloth element starts slack.
    pub ease: Real,
    /// Remeshing settings (angle bound, vertex cap); its `target_edge_length` is replaced by `edge_length`.
    pub remesh: RemeshParams,
    /// Plane-cut settings.
    pub cut: PlaneCutParams,
}

impl Default for GarmentParams {
    fn default() -> Self {
        Self {
            edge_length: 0.02,
            ease: -0.1,
            remesh: RemeshParams::default(),
            cut: PlaneCutParams::default(),
        }
    }
}

/// Why a garment could not be built. Every problem with one panel names it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GarmentError {
    /// The panel list is empty.
    #[error("no panels were given")]
    NoPanels,
    /// `edge_length` is not a positive finite length.
    #[error(
        "edge_length {value} m is invalid: it must be a finite length in metres greater than 0 (e.g. 0.01 for 1 cm)"
    )]
    BadEdgeLength { value: Real },
    /// `edge_length` is too large to resample a panel's boundary with at least 3 edges per loop.
    #[error(
        "edge_length {value} m is too large for panel '{panel}': its shortest boundary loop is {loop_length:.4} m long and needs at least 3 edges, so edge_length must be at most {limit:.4} m"
    )]
    EdgeLengthTooLarge {
        panel: String,
        value: Real,
        loop_length: Real,
        limit: Real,
    },
    /// `ease` is not finite or not above −1.
    #[error(
        "ease {value} is invalid: it must be a finite number greater than -1 (e.g. -0.1 for a pattern 10 % smaller than the body)"
    )]
    BadEase { value: Real },
    /// The body could not be cut into the panels (the message names the panel).
    #[error(transparent)]
    Cut(#[from] PlaneCutError),
    /// A panel is not one piece with one boundary loop, so it cannot be flattened into one pattern piece.
    #[error(
        "panel '{panel}' is not a topological disk ({components} piece(s), {loops} boundary loop(s), Euler characteristic {euler}): a pattern piece must be one piece with one boundary loop; split it with another plane or face list"
    )]
    NotADisk {
        panel: String,
        components: usize,
        loops: usize,
        euler: i64,
    },
    /// The flattening of a panel failed for another reason.
    #[error("panel '{panel}': flattening failed: {source}")]
    Flattening { panel: String, source: LscmError },
    /// The flattening of a panel folds over itself.
    #[error(
        "panel '{panel}': {flipped} of its {faces} triangles are flipped in the flattened pattern; the panel is too curved to flatten in one piece: split it"
    )]
    FlippedFlattening {
        panel: String,
        flipped: usize,
        faces: usize,
    },
    /// Remeshing failed (the message names the panel).
    #[error(transparent)]
    Remesh(#[from] RemeshError),
    /// The remeshing refinement hit its vertex cap.
    #[error(
        "panel '{panel}': remeshing stopped at the cap of {cap} added vertices; raise edge_length or remesh.max_added_vertices"
    )]
    RefinementIncomplete { panel: String, cap: usize },
    /// The ease could not be applied to a panel's pattern.
    #[error("panel '{panel}': {source}")]
    Ease { panel: String, source: EaseError },
    /// A rest triangle has no positive area.
    #[error(
        "panel '{panel}': rest triangle {face} has area {area:.3e} m², but it must be positive"
    )]
    DegenerateRestTriangle {
        panel: String,
        face: usize,
        area: Real,
    },
    /// Two panels place a shared seam vertex at different 3D points (internal consistency check).
    #[error(
        "panels '{first}' and '{second}' place a shared seam vertex {distance:.3e} m apart (internal error)"
    )]
    SeamMismatch {
        first: String,
        second: String,
        distance: Real,
    },
    /// A seam vertex of one panel has no partner on the other (internal consistency check).
    #[error(
        "panels '{first}' and '{second}': a seam vertex has no partner across the seam (internal error)"
    )]
    UnmatchedSeam { first: String, second: String },
}

/// Flattening and remeshing figures of one panel, for reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PanelStats {
    /// Area of the panel on the body (m²).
    pub area_3d: Real,
    /// Area of the rest pattern after the ease (m²); about `(1 + ease)² · area_3d`.
    pub pattern_area: Real,
    /// Uniform scale that made the conformal map's area equal the 3D area (dimensionless; 1 if developable).
    pub area_scale: Real,
    /// Largest difference between a flattened and the matching 3D corner angle (rad).
    pub max_angle_distortion: Real,
    /// Mean absolute corner angle difference of the flattening (rad).
    pub mean_angle_distortion: Real,
    /// Smallest corner angle of the remeshed pattern (rad).
    pub min_angle: Real,
}

/// One boundary loop of a pattern panel, the panel to the left (counter-clockwise for the outer loop).
#[derive(Clone, Debug, PartialEq)]
pub struct PatternLoop {
    /// Local pattern vertex ids along the loop (not repeated at the end).
    pub vertices: Vec<usize>,
    /// `borders[i]` is what lies across the edge from `vertices[i]` to `vertices[(i + 1) % n]`: another panel
    /// (index into [`Garment::panels`]) or nothing.
    pub borders: Vec<Border>,
}

/// One pattern piece of a garment.
#[derive(Clone, Debug)]
pub struct GarmentPanel {
    /// Name of the panel, as given.
    pub name: String,
    /// `#Vp` pattern (rest) positions in the plane after the ease (m).
    pub pattern: Vec<Vec2>,
    /// `#Fp` triangles in local pattern ids, counter-clockwise with positive area.
    pub faces: Vec<[usize; 3]>,
    /// `#Vp` cloth vertex (index into [`Garment::positions`]) of each pattern vertex.
    pub cloth_vertex: Vec<usize>,
    /// `#Fp` cloth triangle (index into [`Garment::faces`]) of each pattern triangle.
    pub cloth_face: Vec<usize>,
    /// Boundary loops (one: panels are disks), with what lies across each edge.
    pub boundary: Vec<PatternLoop>,
    /// Flattening and remeshing figures.
    pub stats: PanelStats,
}

/// Where two pattern panels are sewn together: two polylines of local pattern ids, index by index the same
/// cloth vertex. `vertices[0]` follows its panel's boundary orientation, `vertices[1]` runs against its own.
#[derive(Clone, Debug, PartialEq)]
pub struct GarmentSeam {
    /// The two panels (indices into [`Garment::panels`]), `panels[0] < panels[1]`.
    pub panels: [usize; 2],
    /// Local pattern vertex ids along the seam on each panel, same length.
    pub vertices: [Vec<usize>; 2],
    /// Whether the seam is a closed loop (the last vertex connects back to the first).
    pub closed: bool,
}

/// A garment: 3D cloth triangles on the body, sewn from flat pattern panels.
#[derive(Clone, Debug)]
pub struct Garment {
    /// `#Vc` location of each cloth vertex on the mesh the garment was cut from (face and barycentric
    /// coordinates summing to 1): the body mesh for [`garment`], the previous cloth for
    /// [`garment_remesh`](crate::garment_remesh::garment_remesh). Cloth vertices on a seam are shared by
    /// the panels meeting there.
    pub vertex_body: Vec<MeshPoint>,
    /// `#Vc` initial 3D positions on that mesh (m): on the (flat-triangle) body mesh for [`garment`], on the
    /// deformed previous cloth for [`garment_remesh`](crate::garment_remesh::garment_remesh).
    pub positions: Vec<Vec3>,
    /// `#Fc` cloth triangles in cloth vertex ids, counter-clockwise seen from outside the body (the
    /// orientation of the body faces).
    pub faces: Vec<[usize; 3]>,
    /// `#Fc` panel (index into `panels`) of each cloth triangle.
    pub face_panel: Vec<usize>,
    /// `#Fc` index of each cloth triangle in its panel's [`GarmentPanel::faces`].
    pub face_pattern: Vec<usize>,
    /// `#Vc` whether the cloth vertex lies on the free boundary (an edge with uncovered surface next to it),
    /// as opposed to the interior or a seam only.
    pub free_boundary: Vec<bool>,
    /// The pattern panels, in the order given.
    pub panels: Vec<GarmentPanel>,
    /// The seams between panels.
    pub seams: Vec<GarmentSeam>,
}

impl Garment {
    /// Number of cloth vertices `#Vc`.
    pub fn num_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of cloth triangles `#Fc`.
    pub fn num_faces(&self) -> usize {
        self.faces.len()
    }

    /// Rest (pattern) corners of cloth triangle `f` (m), in the order of `faces[f]`, counter-clockwise.
    /// Panics if `f >= num_faces()`, like slice indexing.
    pub fn rest_triangle(&self, f: usize) -> [Vec2; 3] {
        let panel = &self.panels[self.face_panel[f]];
        panel.faces[self.face_pattern[f]].map(|v| panel.pattern[v])
    }
}

/// Length (m) of the shortest boundary loop of a panel mesh; infinite for a closed panel.
fn shortest_loop(mesh: &TriMesh, loops: &[BoundaryLoop]) -> Real {
    loops
        .iter()
        .map(|lp| {
            let n = lp.vertices.len();
            (0..n)
                .map(|i| {
                    (mesh.positions[lp.vertices[(i + 1) % n]] - mesh.positions[lp.vertices[i]])
                        .norm()
                })
                .sum::<Real>()
        })
        .fold(Real::INFINITY, Real::min)
}

/// Builds the garment made of `panels` on `body` (an oriented manifold mesh, m): cut, flatten, remesh at
/// `params.edge_length`, ease, and sew (see the module documentation).
///
/// Errors name the panel at fault: one covering nothing or overlapping another, one that is not a disk, a
/// flattening that folds over, an `edge_length` that is not a positive length or too large for a panel, an
/// ease outside `(−1, ∞)`, or a rest triangle without positive area.
pub fn garment(
    body: &TriMesh,
    panels: &[PanelSpec],
    params: &GarmentParams,
) -> Result<Garment, GarmentError> {
    if panels.is_empty() {
        return Err(GarmentError::NoPanels);
    }
    let h = params.edge_length;
    if !(h.is_finite() && h > 0.0) {
        return Err(GarmentError::BadEdgeLength { value: h });
    }
    if !(params.ease.is_finite() && params.ease > -1.0) {
        return Err(GarmentError::BadEase { value: params.ease });
    }
    let set = panels_from_specs(body, panels, &params.cut)?;
    for panel in &set.panels {
        let loop_length = shortest_loop(&panel.mesh, &panel.boundary);
        if h > loop_length / 3.0 {
            return Err(GarmentError::EdgeLengthTooLarge {
                panel: panel.name.clone(),
                value: h,
                loop_length,
                limit: loop_length / 3.0,
            });
        }
    }

    // Flatten.
    let mut flats = Vec::with_capacity(set.panels.len());
    let mut flat_stats = Vec::with_capacity(set.panels.len());
    for panel in &set.panels {
        let flat = lscm(&panel.mesh).map_err(|e| match e {
            LscmError::NotADisk {
                components,
                loops,
                euler,
            } => GarmentError::NotADisk {
                panel: panel.name.clone(),
                components,
                loops,
                euler,
            },
            source => GarmentError::Flattening {
                panel: panel.name.clone(),
                source,
            },
        })?;
        if flat.flipped > 0 {
            return Err(GarmentError::FlippedFlattening {
                panel: panel.name.clone(),
                flipped: flat.flipped,
                faces: panel.mesh.num_faces(),
            });
        }
        flat_stats.push((
            flat.area_scale,
            flat.max_angle_distortion,
            flat.mean_angle_distortion,
        ));
        flats.push(flat.positions);
    }

    // Remesh with one shared boundary sampling.
    let remesh = RemeshParams {
        target_edge_length: h,
        ..params.remesh
    };
    let meshes = remesh_panels(&set, &flats, &remesh)?;
    let stats: Vec<PanelStats> = set
        .panels
        .iter()
        .zip(&flat_stats)
        .zip(&meshes)
        .map(|((panel, &(area_scale, max_ad, mean_ad)), m)| PanelStats {
            area_3d: panel.mesh.area(),
            pattern_area: 0.0,
            area_scale,
            max_angle_distortion: max_ad,
            mean_angle_distortion: mean_ad,
            min_angle: m.min_angle,
        })
        .collect();
    sew(
        &set,
        &meshes,
        &stats,
        params.ease,
        remesh.max_added_vertices,
    )
}

/// Sews remeshed panels into a garment (step 5 of [`garment`]): boundary samples with the same
/// [`sample_key`] become one cloth vertex, every pattern is scaled by `1 + ease` about its area centroid
/// (left as it is for `ease == 0`), and the seams are read off the boundary borders.
///
/// * `set`: the panels the meshes were remeshed from (their names, cut vertices and borders);
/// * `meshes`: one [`PatternMesh`] per panel from [`remesh_panels`]; `body` and `positions3` become the
///   cloth vertices' [`Garment::vertex_body`] and [`Garment::positions`];
/// * `stats`: one per panel; its `pattern_area` is filled in here;
/// * `max_added_vertices`: the refinement cap the meshes were made with (for the error message).
///
/// Errors: a refinement that hit its cap, a rest triangle without positive area, or (internal) two panels
/// placing one seam vertex more than 1 nm apart.
pub fn sew(
    set: &PanelSet,
    meshes: &[PatternMesh],
    stats: &[PanelStats],
    ease_amount: Real,
    max_added_vertices: usize,
) -> Result<Garment, GarmentError> {
    if !(ease_amount.is_finite() && ease_amount > -1.0) {
        return Err(GarmentError::BadEase { value: ease_amount });
    }
    if meshes.len() != set.panels.len() || stats.len() != set.panels.len() {
        return Err(GarmentError::Remesh(RemeshError::BadSamples {
            panel: String::new(),
            problem: format!(
                "{} meshes and {} panel figures given for {} panels",
                meshes.len(),
                stats.len(),
                set.panels.len()
            ),
        }));
    }
    // Sew: merge boundary samples by key into cloth vertices.
    let mut vertex_body: Vec<MeshPoint> = Vec::new();
    let mut positions: Vec<Vec3> = Vec::new();
    let mut vertex_panel: Vec<usize> = Vec::new();
    let mut faces: Vec<[usize; 3]> = Vec::new();
    let mut face_panel = Vec::new();
    let mut face_pattern = Vec::new();
    let mut free_boundary: Vec<bool> = Vec::new();
    let mut by_key: HashMap<SampleKey, usize> = HashMap::new();
    let mut out_panels = Vec::with_capacity(meshes.len());
    for (p, ((panel, m), stat)) in set.panels.iter().zip(meshes).zip(stats).enumerate() {
        if !m.refinement_complete {
            return Err(GarmentError::RefinementIncomplete {
                panel: panel.name.clone(),
                cap: max_added_vertices,
            });
        }
        let mut cloth_vertex = Vec::with_capacity(m.positions.len());
        for i in 0..m.positions.len() {
            let key = m.boundary_samples.get(i).map(|s| sample_key(panel, s));
            if let Some(&c) = key.as_ref().and_then(|k| by_key.get(k)) {
                let distance = (positions[c] - m.positions3[i]).norm();
                if !(distance <= SEAM_TOLERANCE) {
                    return Err(GarmentError::SeamMismatch {
                        first: set.panels[vertex_panel[c]].name.clone(),
                        second: panel.name.clone(),
                        distance,
                    });
                }
                cloth_vertex.push(c);
                continue;
            }
            let c = positions.len();
            vertex_body.push(m.body[i]);
            positions.push(m.positions3[i]);
            vertex_panel.push(p);
            free_boundary.push(false);
            if let Some(k) = key {
                by_key.insert(k, c);
            }
            cloth_vertex.push(c);
        }

        let mut pattern = m.positions.clone();
        if ease_amount != 0.0 {
            ease(&mut pattern, &m.faces, ease_amount).map_err(|source| GarmentError::Ease {
                panel: panel.name.clone(),
                source,
            })?;
        }
        let mut cloth_face = Vec::with_capacity(m.faces.len());
        let mut pattern_area = 0.0;
        for (lf, tri) in m.faces.iter().enumerate() {
            let area = signed_area(pattern[tri[0]], pattern[tri[1]], pattern[tri[2]]);
            if !(area > 0.0) {
                return Err(GarmentError::DegenerateRestTriangle {
                    panel: panel.name.clone(),
                    face: lf,
                    area,
                });
            }
            pattern_area += area;
            cloth_face.push(faces.len());
            faces.push(tri.map(|v| cloth_vertex[v]));
            face_panel.push(p);
            face_pattern.push(lf);
        }

        let mut boundary = Vec::with_capacity(m.boundary.len());
        for lp in &m.boundary {
            let borders: Vec<Border> = lp.iter().map(|&v| m.boundary_samples[v].border).collect();
            let n = lp.len();
            for (k, b) in borders.iter().enumerate() {
                if *b == Border::Free {
                    free_boundary[cloth_vertex[lp[k]]] = true;
                    free_boundary[cloth_vertex[lp[(k + 1) % n]]] = true;
                }
            }
            boundary.push(PatternLoop {
                vertices: lp.clone(),
                borders,
            });
        }
        out_panels.push(GarmentPanel {
            name: panel.name.clone(),
            pattern,
            faces: m.faces.clone(),
            cloth_vertex,
            cloth_face,
            boundary,
            stats: PanelStats {
                pattern_area,
                ..*stat
            },
        });
    }
    let seams = seams(&out_panels)?;
    Ok(Garment {
        vertex_body,
        positions,
        faces,
        face_panel,
        face_pattern,
        free_boundary,
        panels: out_panels,
        seams,
    })
}

/// Seams between pattern panels: every run of boundary edges of panel `p` bordering panel `q > p`, with the
/// local ids of the same cloth vertices on `q`.
fn seams(panels: &[GarmentPanel]) -> Result<Vec<GarmentSeam>, GarmentError> {
    let local: Vec<HashMap<usize, usize>> = panels
        .iter()
        .map(|gp| {
            gp.boundary
                .iter()
                .flat_map(|lp| lp.vertices.iter().map(|&v| (gp.cloth_vertex[v], v)))
                .collect()
        })
        .collect();
    let mut out = Vec::new();
    for (p, gp) in panels.iter().enumerate() {
        for lp in &gp.boundary {
            let bl = BoundaryLoop {
                vertices: lp.vertices.clone(),
                borders: lp.borders.clone(),
            };
            let n = lp.vertices.len();
            for (first, len, border) in border_runs(&bl) {
                let Border::Seam { panel: q } = border else {
                    continue;
                };
                if q <= p {
                    continue;
                }
                let closed = len == n;
                let count = if closed { n } else { len + 1 };
                let a: Vec<usize> = (0..count).map(|k| lp.vertices[(first + k) % n]).collect();
                let b = a
                    .iter()
                    .map(|&v| local[q].get(&gp.cloth_vertex[v]).copied())
                    .collect::<Option<Vec<usize>>>()
                    .ok_or_else(|| GarmentError::UnmatchedSeam {
                        first: gp.name.clone(),
                        second: panels[q].name.clone(),
                    })?;
                out.push(GarmentSeam {
                    panels: [p, q],
                    vertices: [a, b],
                    closed,
                });
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plane_cut::HalfSpace;
    use skintight_geometry::mesh::topology::Topology;
    use skintight_geometry::test_meshes::{body_path, capped_cylinder, read_obj};

    fn region(name: &str, hs: Vec<HalfSpace>) -> PanelSpec {
        PanelSpec {
            name: name.into(),
            shape: PanelShape::Region(hs),
        }
    }

    fn params(edge_length: Real, ease: Real) -> GarmentParams {
        GarmentParams {
            edge_length,
            ease,
            ..Default::default()
        }
    }

    /// A leg-like closed tube (radius 0.1 m, height 0.4 m), split front/back by a slightly tilted plane.
    fn tube_garment(edge_length: Real, ease: Real) -> (TriMesh, Garment) {
        let body = capped_cylinder(0.1, 0.4, 24, 8);
        let (n, d) = ([0.1, 1.0, 0.05], 0.01);
        let specs = vec![
            region("front", vec![HalfSpace::new(n.map(|c| -c), -d)]),
            region("back", vec![HalfSpace::new(n, d)]),
        ];
        let g = garment(&body, &specs, &params(edge_length, ease)).unwrap();
        (body, g)
    }

    /// Checks that hold for every garment: consistent indices, positive rest areas, cloth on the body with
    /// the body's orientation, seams matching one-to-one.
    fn check_garment(body: &TriMesh, g: &Garment) {
        let nv = g.num_vertices();
        assert_eq!(g.vertex_body.len(), nv);
        assert_eq!(g.free_boundary.len(), nv);
        assert_eq!(g.face_panel.len(), g.num_faces());
        for (v, sp) in g.vertex_body.iter().enumerate() {
            assert!((sp.bary.iter().sum::<Real>() - 1.0).abs() < 1e-12);
            assert!(sp.bary.iter().all(|&b| b > -1e-9), "{sp:?}");
            let err = (sp.position(body) - g.positions[v]).norm();
            assert!(
                err < 1e-9,
                "cloth vertex {v} is {err:.2e} m off its body point"
            );
        }
        // The cloth is a manifold; each panel's triangles map to cloth triangles and back.
        Topology::new(nv, &g.faces).unwrap();
        for (p, gp) in g.panels.iter().enumerate() {
            for (lf, &cf) in gp.cloth_face.iter().enumerate() {
                assert_eq!(g.face_panel[cf], p);
                assert_eq!(g.faces[cf], gp.faces[lf].map(|v| gp.cloth_vertex[v]));
                let [a, b, c] = g.rest_triangle(cf);
                assert!(signed_area(a, b, c) > 0.0, "{}: rest face {lf}", gp.name);
            }
        }
        // Same orientation as the body: the cloth normal agrees with the body faces under its corners.
        for f in &g.faces {
            let [a, b, c] = f.map(|v| g.positions[v]);
            let n = (b - a).cross(&(c - a));
            let body_n: Vec3 = f
                .iter()
                .map(|&v| body.face_area_normal(g.vertex_body[v].face).normalize())
                .sum();
            assert!(n.dot(&body_n) > 0.0);
        }
        // Seams: one-to-one, same cloth vertex index by index, consecutive vertices joined by a boundary edge.
        for s in &g.seams {
            let [pa, pb] = s.panels;
            assert!(pa < pb);
            assert_eq!(s.vertices[0].len(), s.vertices[1].len());
            for (&va, &vb) in s.vertices[0].iter().zip(&s.vertices[1]) {
                assert_eq!(g.panels[pa].cloth_vertex[va], g.panels[pb].cloth_vertex[vb]);
            }
        }
        // Every vertex of a seam-tagged edge belongs to both panels.
        let mut owners: Vec<Vec<usize>> = vec![Vec::new(); nv];
        for (p, gp) in g.panels.iter().enumerate() {
            for &c in &gp.cloth_vertex {
                owners[c].push(p);
            }
        }
        for (p, gp) in g.panels.iter().enumerate() {
            for lp in &gp.boundary {
                let n = lp.vertices.len();
                for (k, b) in lp.borders.iter().enumerate() {
                    if let Border::Seam { panel: q } = *b {
                        for v in [lp.vertices[k], lp.vertices[(k + 1) % n]] {
                            let o = &owners[gp.cloth_vertex[v]];
                            assert!(o.contains(&p) && o.contains(&q));
                        }
                    }
                }
            }
        }
        // Every cloth vertex is used exactly once per panel it belongs to.
        for o in &owners {
            let mut d = o.clone();
            d.dedup();
            assert_eq!(&d, o);
            assert!(!o.is_empty());
        }
    }

    fn edge_lengths(g: &Garment) -> Vec<Real> {
        (0..g.num_faces())
            .flat_map(|f| {
                let t = g.rest_triangle(f);
                (0..3).map(move |e| (t[(e + 1) % 3] - t[e]).norm())
            })
            .collect()
    }

    #[test]
    fn tube_front_back_sews_one_closed_seam() {
        let h = 0.02;
        let ease = -0.1;
        let (body, g) = tube_garment(h, ease);
        check_garment(&body, &g);
        assert_eq!(g.panels.len(), 2);
        assert_eq!(g.seams.len(), 1);
        assert!(g.seams[0].closed);
        // The tube is closed: no free boundary, every boundary vertex is on the seam of both panels.
        assert!(g.free_boundary.iter().all(|&f| !f));
        let seam_vertices: std::collections::HashSet<usize> = g.seams[0].vertices[0]
            .iter()
            .map(|&v| g.panels[0].cloth_vertex[v])
            .collect();
        for gp in &g.panels {
            assert_eq!(gp.boundary.len(), 1);
            for &v in &gp.boundary[0].vertices {
                assert!(seam_vertices.contains(&gp.cloth_vertex[v]));
            }
            assert_eq!(gp.boundary[0].vertices.len(), seam_vertices.len());
        }
        // Pattern area: the flattening keeps the 3D area exactly and the ease scales it by (1 + ease)². The
        // remeshed boundary replaces the flattened boundary polyline by chords between samples about h
        // apart; on this tube the polyline bends by at most ~15° per body edge, which loses well under 1 %.
        for gp in &g.panels {
            let s = &gp.stats;
            let expected = (1.0 + ease).powi(2) * s.area_3d;
            let rel = (s.pattern_area - expected).abs() / expected;
            assert!(
                rel < 0.01,
                "{}: pattern area off by {:.3} %",
                gp.name,
                100.0 * rel
            );
            assert!(
                s.min_angle > 10f64.to_radians(),
                "{}: min angle {}",
                gp.name,
                s.min_angle
            );
        }
        // Edge lengths: rest edges are (1 + ease)·h-ish; the refinement only bounds triangle area from
        // above, so edges run shorter near corners but stay within a factor of two of the target.
        let e = edge_lengths(&g);
        let mean = e.iter().sum::<Real>() / e.len() as Real;
        let max = e.iter().copied().fold(0.0, Real::max);
        let target = (1.0 + ease) * h;
        println!(
            "tube: {} vertices, {} faces, rest edge mean {:.4} max {:.4} target {:.4}",
            g.num_vertices(),
            g.num_faces(),
            mean,
            max,
            target
        );
        assert!(
            mean > 0.6 * target && mean < 1.2 * target,
            "mean edge {mean}"
        );
        assert!(max < 2.0 * target, "max edge {max}");
    }

    #[test]
    fn face_list_panels_build_a_garment() {
        let body = capped_cylinder(0.1, 0.4, 24, 8);
        let front: Vec<usize> = (0..body.num_faces())
            .filter(|&f| {
                let [a, b, c] = body.corners(f);
                (a + b + c).y > 0.0
            })
            .collect();
        let specs = vec![
            PanelSpec {
                name: "front".into(),
                shape: PanelShape::Faces(front),
            },
            region("back", vec![HalfSpace::new([0.0, 1.0, 0.0], 0.0)]),
        ];
        let g = garment(&body, &specs, &params(0.02, -0.1)).unwrap();
        check_garment(&body, &g);
        assert_eq!(g.seams.len(), 1);
        assert!(g.seams[0].closed);
    }

    #[test]
    fn errors_name_the_panel_and_value() {
        let body = capped_cylinder(0.1, 0.4, 24, 8);
        let halves = vec![
            region("front", vec![HalfSpace::new([0.0, -1.0, 0.0], 0.0)]),
            region("back", vec![HalfSpace::new([0.0, 1.0, 0.0], 0.0)]),
        ];
        // Region covering nothing.
        let moon = vec![region("moon", vec![HalfSpace::new([0.0, 0.0, 1.0], -1.0)])];
        let err = garment(&body, &moon, &params(0.02, -0.1)).unwrap_err();
        assert_eq!(
            err,
            GarmentError::Cut(PlaneCutError::EmptyRegion {
                panel: "moon".into()
            })
        );
        assert!(err.to_string().contains("'moon'"));
        // A band around the tube is an annulus, not a disk.
        let band = vec![region(
            "band",
            vec![
                HalfSpace::new([0.0, 0.0, 1.0], 0.3),
                HalfSpace::new([0.0, 0.0, -1.0], -0.1),
            ],
        )];
        let err = garment(&body, &band, &params(0.02, -0.1)).unwrap_err();
        assert!(
            matches!(err, GarmentError::NotADisk { ref panel, loops: 2, .. } if panel == "band"),
            "{err}"
        );
        assert!(err.to_string().contains("'band'"), "{err}");
        // Edge length.
        for bad in [0.0, -0.01, Real::NAN, Real::INFINITY] {
            let err = garment(&body, &halves, &params(bad, -0.1)).unwrap_err();
            assert!(matches!(err, GarmentError::BadEdgeLength { .. }), "{err}");
            assert!(err.to_string().contains("edge_length"), "{err}");
        }
        let err = garment(&body, &halves, &params(0.5, -0.1)).unwrap_err();
        assert!(
            matches!(err, GarmentError::EdgeLengthTooLarge { ref panel, value, .. } if panel == "front" && value == 0.5),
            "{err}"
        );
        assert!(err.to_string().contains("0.5 m"), "{err}");
        // Ease.
        for bad in [-1.0, -2.0, Real::NAN] {
            let err = garment(&body, &halves, &params(0.02, bad)).unwrap_err();
            assert!(matches!(err, GarmentError::BadEase { .. }), "{err}");
        }
        assert_eq!(
            garment(&body, &[], &params(0.02, -0.1)).unwrap_err(),
            GarmentError::NoPanels
        );
    }

    /// Four pants panels on the regular body: left/right by x = 0, front/back by z = `Z_SPLIT`, from the
    /// waist (y = 0, below the hands) to above the ankles (y = −0.7).
    const WAIST: Real = 0.0;
    const ANKLE: Real = -0.7;
    const Z_SPLIT: Real = 0.03;

    fn pants_specs() -> Vec<PanelSpec> {
        let mut specs = Vec::new();
        for (side, sx) in [("left", 1.0), ("right", -1.0)] {
            for (part, sz) in [("front", -1.0), ("back", 1.0)] {
                specs.push(region(
                    &format!("{side} {part}"),
                    vec![
                        HalfSpace::new([0.0, 1.0, 0.0], WAIST),
                        HalfSpace::new([0.0, -1.0, 0.0], -ANKLE),
                        HalfSpace::new([sx, 0.0, 0.0], 0.0),
                        HalfSpace::new([0.0, 0.0, sz], sz * Z_SPLIT),
                    ],
                ));
            }
        }
        specs
    }

    #[test]
    fn pants_on_the_regular_body() {
        let body = read_obj(&body_path("regular_1k.obj"));
        let (lo, hi) = body.bounding_box().unwrap();
        println!("regular_1k bounding box {lo:?} .. {hi:?}");
        let t = std::time::Instant::now();
        let g = garment(&body, &pants_specs(), &params(0.02, -0.1)).unwrap();
        println!(
            "pants at 0.02 m: {} vertices, {} faces in {:.2} s",
            g.num_vertices(),
            g.num_faces(),
            t.elapsed().as_secs_f64()
        );
        check_garment(&body, &g);
        for gp in &g.panels {
            let s = &gp.stats;
            println!(
                "  {}: area {:.4} m² -> pattern {:.4} m², area scale {:.3}, max angle distortion {:.1}°, min angle {:.1}°",
                gp.name,
                s.area_3d,
                s.pattern_area,
                s.area_scale,
                s.max_angle_distortion.to_degrees(),
                s.min_angle.to_degrees()
            );
            assert_eq!(gp.boundary.len(), 1);
        }
        // Free boundary: exactly the cloth vertices on the waist and ankle planes (within the cut's snap
        // tolerance, 1e-6 of the body diagonal).
        let tol = 1e-5;
        for (v, p) in g.positions.iter().enumerate() {
            let on_rim = (p.y - WAIST).abs() < tol || (p.y - ANKLE).abs() < tol;
            assert_eq!(g.free_boundary[v], on_rim, "vertex {v} at {p:?}");
        }
        // The waist loop joins all four panels; each ankle loop two.
        assert!(g.free_boundary.iter().filter(|&&f| f).count() > 30);
        assert!(g.seams.len() >= 4);
        // A finer cloth: timing for reports, same checks.
        let t = std::time::Instant::now();
        let fine = garment(&body, &pants_specs(), &params(0.01, -0.1)).unwrap();
        println!(
            "pants at 0.01 m: {} vertices, {} faces in {:.2} s",
            fine.num_vertices(),
            fine.num_faces(),
            t.elapsed().as_secs_f64()
        );
        check_garment(&body, &fine);
        assert!(fine.num_faces() > 3 * g.num_faces());
    }
}
