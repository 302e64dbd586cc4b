//! Exact cutting of a body surface along planes into garment panels.
//!
//! A garment panel is given as a region ([`PanelShape::Region`]): a conjunction of half-spaces `{x : n·x ≤ d}`. The body mesh is
//! split exactly along every plane of every region (each crossed triangle is cut; the new vertex on an edge is
//! computed once and shared by both neighbouring triangles, so there are no cracks), then every resulting face
//! is assigned to the region containing it. Each panel comes with
//! * its own [`TriMesh`] (a refinement of the body faces it covers; disk topology expected),
//! * the body location of each of its vertices and faces (original face and barycentric coordinates), so
//!   that anything defined on the panel can be embedded on the body surface,
//! * its boundary loops, each boundary edge tagged by what lies across it: another panel (a seam) or nothing
//!   (the free boundary: uncovered body surface, or the border of an open body mesh).
//!
//! A panel may instead be given as a list of original body faces ([`PanelShape::Faces`]); such a panel is
//! not cut by planes of its own, but planes of region panels still refine its faces.
//!
//! Seams — where two panels meet — are returned as pairs of polylines that coincide vertex by vertex in 3D.
//!
//! Every plane of every region cuts the whole surface, so a panel may contain extra interior cut lines
//! (from planes of other regions that pass through it). They are harmless: the pattern is remeshed anyway.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use crate::math::{FaceId, Real, Vec3, VertexId};
use skintight_geometry::mesh::TriMesh;
use skintight_geometry::mesh::topology::{Topology, TopologyError};
pub use skintight_geometry::region::{HalfSpace, Region};

/// How a panel's part of the body surface is given.
///
/// JSON form: `{"region": [{"normal": [0, 0, -1], "offset": 0.0}, …]}` or `{"faces": [12, 13, 40, …]}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum PanelShape {
    /// The body surface inside the intersection of these half-spaces (cut exactly along their planes).
    Region(Vec<HalfSpace>),
    /// These faces of the original body mesh (indices into `TriMesh::faces`), whole: every cut face whose
    /// original face is listed. Face lists transfer between bodies of the same connectivity.
    Faces(Vec<FaceId>),
}

/// A named garment panel.
///
/// JSON form: `{"name": "front", "shape": {"faces": [0, 1, 2]}}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PanelSpec {
    /// Name of the panel, used in error messages and on patterns.
    pub name: String,
    /// Which part of the body surface the panel covers.
    pub shape: PanelShape,
}

/// Settings of the plane cut.
#[derive(Clone, Copy, Debug)]
pub struct PlaneCutParams {
    /// A vertex whose distance to a cutting plane is below this fraction of the mesh's bounding-box diagonal
    /// is taken to lie on the plane (no sliver triangle is created next to it). Dimensionless; the default
    /// 1e-6 is 2 µm on a 2 m body. Such a vertex stays where it is, so panel boundaries pass through it
    /// within this distance of the plane; vertices created by the cut lie on their plane to rounding.
    pub snap_tolerance: Real,
}

impl Default for PlaneCutParams {
    fn default() -> Self {
        Self {
            snap_tolerance: 1e-6,
        }
    }
}

/// Why a set of panels could not be cut from the body.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlaneCutError {
    /// The body mesh has no faces.
    #[error("the body mesh has no faces to cut")]
    EmptyMesh,
    /// A vertex position is NaN or infinite.
    #[error("body vertex {vertex} has a non-finite position")]
    NonFinitePosition { vertex: VertexId },
    /// The body mesh is not an oriented 2-manifold.
    #[error("the body mesh is not an oriented manifold: {0}")]
    Topology(TopologyError),
    /// No panels were given.
    #[error("no panels were given")]
    NoRegions,
    /// A half-space has a zero or non-finite normal or a non-finite offset.
    #[error("panel '{panel}': half-space {index} is invalid: {problem}")]
    BadHalfSpace {
        panel: String,
        index: usize,
        problem: &'static str,
    },
    /// A region contains none of the surface.
    #[error("panel '{panel}': its region covers none of the body surface")]
    EmptyRegion { panel: String },
    /// A face-list panel has an empty list.
    #[error("panel '{panel}': its face list is empty")]
    EmptyFaceList { panel: String },
    /// A face-list panel names a face the body does not have.
    #[error(
        "panel '{panel}': face {face} does not exist (the body has {num_faces} faces, numbered from 0)"
    )]
    FaceOutOfRange {
        panel: String,
        face: FaceId,
        num_faces: usize,
    },
    /// A face-list panel names the same face twice.
    #[error("panel '{panel}': face {face} is listed more than once")]
    DuplicateFace { panel: String, face: FaceId },
    /// The per-face panel labels given to [`assemble_panels`] do not fit the cut mesh.
    #[error("invalid panel labels: {problem}")]
    BadLabels { problem: String },
    /// Two regions share part of the surface.
    #[error(
        "panels '{first}' and '{second}' overlap (both contain body face {face} near ({x:.4}, {y:.4}, {z:.4}) m)"
    )]
    Overlap {
        first: String,
        second: String,
        face: FaceId,
        x: Real,
        y: Real,
        z: Real,
    },
    /// The part of the surface in a region is not a manifold (e.g. two pieces touching at one vertex).
    #[error("panel '{panel}': the surface inside the region is not a manifold: {source}")]
    NonManifoldPanel {
        panel: String,
        source: TopologyError,
    },
}

/// A point on the body's triangle mesh: an original body face and barycentric coordinates in it (summing to
/// 1). (A point on the smooth limit surface is `skintight_geometry::SurfacePoint`.)
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshPoint {
    /// Face of the original body mesh.
    pub face: FaceId,
    /// Barycentric coordinates with respect to that face's three corners (dimensionless).
    pub bary: [Real; 3],
}

impl MeshPoint {
    /// The 3D position of this point on `body` (m).
    pub fn position(&self, body: &TriMesh) -> Vec3 {
        let [a, b, c] = body.corners(self.face);
        a * self.bary[0] + b * self.bary[1] + c * self.bary[2]
    }
}

/// Where a face of a cut mesh lies on the body: the original face and the barycentric coordinates of its
/// three corners in that face. A point with barycentric coordinates `λ` in the cut face lies at
/// `Σ λ_i · corner_bary[i]` in the original face (the map is affine).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceOrigin {
    /// Face of the original body mesh.
    pub face: FaceId,
    /// Barycentric coordinates of corner `i` of the cut face in the original face.
    pub corner_bary: [[Real; 3]; 3],
}

impl FaceOrigin {
    /// The body point at barycentric coordinates `lambda` of the cut face.
    pub fn mesh_point(&self, lambda: [Real; 3]) -> MeshPoint {
        let mut bary = [0.0; 3];
        for (i, cb) in self.corner_bary.iter().enumerate() {
            for k in 0..3 {
                bary[k] += lambda[i] * cb[k];
            }
        }
        MeshPoint {
            face: self.face,
            bary,
        }
    }
}

/// A mesh refined by plane cuts, with the body location of every face.
#[derive(Clone, Debug)]
pub struct CutMesh {
    /// The refined mesh; its first `#V_body` vertices are the body's vertices, in order.
    pub mesh: TriMesh,
    /// `#F_cut` origins, one per face of `mesh`.
    pub face_origin: Vec<FaceOrigin>,
}

/// What lies across a panel boundary edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Border {
    /// Nothing: uncovered body surface, or the border of an open body mesh.
    Free,
    /// Another panel (index into [`PanelSet::panels`]): the edge is part of a seam.
    Seam {
        /// The panel across the edge.
        panel: usize,
    },
}

/// One closed boundary loop of a panel, oriented with the panel's faces (the panel lies to the left).
#[derive(Clone, Debug, PartialEq)]
pub struct BoundaryLoop {
    /// Panel vertex indices along the loop (not repeated at the end).
    pub vertices: Vec<VertexId>,
    /// `borders[i]` tags the edge from `vertices[i]` to `vertices[(i + 1) % n]`.
    pub borders: Vec<Border>,
}

/// A garment panel cut from the body.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Name of the panel (region or spec).
    pub name: String,
    /// The panel's part of the cut body surface (positions in m).
    pub mesh: TriMesh,
    /// Body location of each panel vertex (`#V_panel`).
    pub vertex_origin: Vec<MeshPoint>,
    /// Body location of each panel face (`#F_panel`).
    pub face_origin: Vec<FaceOrigin>,
    /// Index of each panel vertex in the cut mesh ([`PanelSet::cut`]), shared between panels along seams.
    pub cut_vertex: Vec<VertexId>,
    /// Boundary loops (one for a disk).
    pub boundary: Vec<BoundaryLoop>,
}

/// One side of a seam: a polyline of vertices of one panel.
#[derive(Clone, Debug, PartialEq)]
pub struct SeamSide {
    /// Index of the panel.
    pub panel: usize,
    /// Panel vertex indices along the seam.
    pub vertices: Vec<VertexId>,
}

/// Where two panels meet: two polylines that coincide vertex by vertex in 3D (`sides[0].vertices[i]` and
/// `sides[1].vertices[i]` are the same cut-mesh vertex). Side 0 follows its panel's boundary orientation, side
/// 1 runs against its own (the two panels lie on opposite sides of the seam).
#[derive(Clone, Debug, PartialEq)]
pub struct CutSeam {
    /// The two panels, `sides[0].panel < sides[1].panel`.
    pub sides: [SeamSide; 2],
    /// Whether the seam is a closed loop (the last vertex connects back to the first).
    pub closed: bool,
}

/// The result of cutting a body into panels.
#[derive(Clone, Debug)]
pub struct PanelSet {
    /// The whole body refined by all cuts (covered and uncovered parts).
    pub cut: CutMesh,
    /// One panel per region (or spec), in the given order.
    pub panels: Vec<Panel>,
    /// All seams between pairs of panels.
    pub seams: Vec<CutSeam>,
}

/// Sign of a snapped plane distance: −1 inside, 0 on the plane, +1 outside.
fn sign(s: Real) -> i8 {
    if s > 0.0 {
        1
    } else if s < 0.0 {
        -1
    } else {
        0
    }
}

fn lerp_bary(a: [Real; 3], b: [Real; 3], t: Real) -> [Real; 3] {
    [
        a[0] + t * (b[0] - a[0]),
        a[1] + t * (b[1] - a[1]),
        a[2] + t * (b[2] - a[2]),
    ]
}

/// Validates a half-space and returns it with a unit normal.
fn unit_half_space(
    h: &HalfSpace,
    panel: &str,
    index: usize,
) -> Result<(Vec3, Real), PlaneCutError> {
    let bad = |problem| PlaneCutError::BadHalfSpace {
        panel: panel.to_string(),
        index,
        problem,
    };
    if !h.normal.iter().all(|c| c.is_finite()) {
        return Err(bad("the normal has a non-finite component"));
    }
    if !h.offset.is_finite() {
        return Err(bad("the offset is not finite"));
    }
    let len = h.normal.norm();
    if len < 1e-12 {
        return Err(bad("the normal is zero"));
    }
    Ok((h.normal / len, h.offset / len))
}

fn validate_mesh(mesh: &TriMesh) -> Result<Topology, PlaneCutError> {
    if mesh.faces.is_empty() {
        return Err(PlaneCutError::EmptyMesh);
    }
    if let Some(v) = mesh
        .positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(PlaneCutError::NonFinitePosition { vertex: v });
    }
    Topology::new(mesh.num_vertices(), &mesh.faces).map_err(PlaneCutError::Topology)
}

/// Splits every face of `mesh` crossed by one of `planes` (each `(n, d)` with unit `n`, plane `n·x = d`).
///
/// New vertices are appended after the original ones; each lies exactly (to rounding) on its plane and is
/// shared by the faces on both sides of the split edge. Vertices within `params.snap_tolerance` (relative to
/// the bounding-box diagonal) of a plane are treated as lying on it. The input must be an oriented manifold.
pub fn cut(
    mesh: &TriMesh,
    planes: &[(Vec3, Real)],
    params: &PlaneCutParams,
) -> Result<CutMesh, PlaneCutError> {
    validate_mesh(mesh)?;
    let (lo, hi) = mesh.bounding_box().ok_or(PlaneCutError::EmptyMesh)?;
    let eps = params.snap_tolerance * (hi - lo).norm();

    let mut positions = mesh.positions.clone();
    let mut faces = mesh.faces.clone();
    let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut origin: Vec<FaceOrigin> = (0..faces.len())
        .map(|f| FaceOrigin {
            face: f,
            corner_bary: identity,
        })
        .collect();

    let mut dist: Vec<Real> = Vec::new();
    let mut edge_point: HashMap<(VertexId, VertexId), (VertexId, Real)> = HashMap::new();
    for &(n, d) in planes {
        dist.clear();
        dist.extend(positions.iter().map(|p| {
            let s = n.dot(p) - d;
            if s.abs() <= eps { 0.0 } else { s }
        }));
        edge_point.clear();
        let mut next_faces = Vec::with_capacity(faces.len() + faces.len() / 4);
        let mut next_origin = Vec::with_capacity(next_faces.capacity());

        // The point where the plane crosses edge (u, v), computed once per undirected edge in a canonical order
        // so both neighbouring faces get the same vertex. Returns the vertex and its parameter from u to v.
        let mut crossing =
            |u: VertexId, v: VertexId, positions: &mut Vec<Vec3>| -> (VertexId, Real) {
                let key = (u.min(v), u.max(v));
                let (id, t) = *edge_point.entry(key).or_insert_with(|| {
                    let (a, b) = key;
                    let t = dist[a] / (dist[a] - dist[b]);
                    positions.push(positions[a] + (positions[b] - positions[a]) * t);
                    (positions.len() - 1, t)
                });
                if u == key.0 { (id, t) } else { (id, 1.0 - t) }
            };

        for (f, face) in faces.iter().enumerate() {
            let sg = face.map(|v| sign(dist[v]));
            let has_pos = sg.contains(&1);
            let has_neg = sg.contains(&-1);
            let o = origin[f];
            if !(has_pos && has_neg) {
                next_faces.push(*face);
                next_origin.push(o);
                continue;
            }
            // Rotate so that corner 0 is the distinguished one: the vertex on the plane, or the lone vertex
            // on its side.
            let r = if let Some(z) = sg.iter().position(|&s| s == 0) {
                z
            } else {
                (0..3)
                    .find(|&i| sg[(i + 1) % 3] == sg[(i + 2) % 3])
                    .expect("a crossed face without a zero has a lone vertex")
            };
            let [a, b, c] = [face[r], face[(r + 1) % 3], face[(r + 2) % 3]];
            let [ba, bb, bc] = [
                o.corner_bary[r],
                o.corner_bary[(r + 1) % 3],
                o.corner_bary[(r + 2) % 3],
            ];
            let sub = |corners: [(VertexId, [Real; 3]); 3]| {
                (
                    corners.map(|c| c.0),
                    FaceOrigin {
                        face: o.face,
                        corner_bary: corners.map(|c| c.1),
                    },
                )
            };
            if sg[r] == 0 {
                // The plane passes through a and crosses edge (b, c).
                let (m, t) = crossing(b, c, &mut positions);
                let bm = lerp_bary(bb, bc, t);
                for (fc, fo) in [
                    sub([(a, ba), (b, bb), (m, bm)]),
                    sub([(a, ba), (m, bm), (c, bc)]),
                ] {
                    next_faces.push(fc);
                    next_origin.push(fo);
                }
            } else {
                // a alone on its side: the plane crosses (a, b) and (c, a).
                let (m1, t1) = crossing(a, b, &mut positions);
                let (m2, t2) = crossing(c, a, &mut positions);
                let b1 = lerp_bary(ba, bb, t1);
                let b2 = lerp_bary(bc, ba, t2);
                // Split the quad (m1, b, c, m2) along its shorter diagonal.
                let d1 = (positions[c] - positions[m1]).norm_squared();
                let d2 = (positions[m2] - positions[b]).norm_squared();
                let tris = if d1 <= d2 {
                    [
                        sub([(a, ba), (m1, b1), (m2, b2)]),
                        sub([(m1, b1), (b, bb), (c, bc)]),
                        sub([(m1, b1), (c, bc), (m2, b2)]),
                    ]
                } else {
                    [
                        sub([(a, ba), (m1, b1), (m2, b2)]),
                        sub([(m1, b1), (b, bb), (m2, b2)]),
                        sub([(b, bb), (c, bc), (m2, b2)]),
                    ]
                };
                for (fc, fo) in tris {
                    next_faces.push(fc);
                    next_origin.push(fo);
                }
            }
        }
        faces = next_faces;
        origin = next_origin;
    }
    Ok(CutMesh {
        mesh: TriMesh::new(positions, faces),
        face_origin: origin,
    })
}

/// Whether face `face` (of the cut mesh) lies inside the region given by unit half-spaces.
fn face_inside(positions: &[Vec3], face: &[VertexId; 3], hs: &[(Vec3, Real)], eps: Real) -> bool {
    hs.iter().all(|&(n, d)| {
        let s = face.map(|v| n.dot(&positions[v]) - d);
        let snapped = s.map(|x| if x.abs() <= eps { 0.0 } else { x });
        if snapped.iter().any(|&x| x > 0.0) {
            false
        } else if snapped.iter().any(|&x| x < 0.0) {
            true
        } else {
            // A face lying in the plane: decide by its centroid.
            s.iter().sum::<Real>() <= 0.0
        }
    })
}

/// Cuts `mesh` (the body: an oriented manifold, closed or open; m) into one panel per region, and finds the
/// seams between them.
///
/// Errors name the offending panel: a region covering none of the surface, two overlapping regions, an
/// invalid half-space, or a region whose surface is not a manifold.
pub fn panels(
    mesh: &TriMesh,
    regions: &[Region],
    params: &PlaneCutParams,
) -> Result<PanelSet, PlaneCutError> {
    let specs: Vec<PanelSpec> = regions
        .iter()
        .map(|r| PanelSpec {
            name: r.label.clone(),
            shape: PanelShape::Region(r.half_spaces.clone()),
        })
        .collect();
    panels_from_specs(mesh, &specs, params)
}

/// Cuts `mesh` (the body: an oriented manifold, closed or open; m) into one panel per spec, and finds the
/// seams between them.
///
/// All planes of all [`PanelShape::Region`] panels cut the whole surface. A region panel takes every cut face
/// inside its region; a [`PanelShape::Faces`] panel takes every cut face whose original body face
/// ([`FaceOrigin::face`]) is in its list. Errors name the offending panel: an invalid half-space, a face index
/// out of range, a repeated face, an empty face list, a panel covering none of the surface, two overlapping
/// panels, or a panel whose surface is not a manifold.
pub fn panels_from_specs(
    mesh: &TriMesh,
    specs: &[PanelSpec],
    params: &PlaneCutParams,
) -> Result<PanelSet, PlaneCutError> {
    if specs.is_empty() {
        return Err(PlaneCutError::NoRegions);
    }
    // Validate every spec before cutting; region panels become unit half-spaces, face-list panels a mask.
    enum Shape {
        Region(Vec<(Vec3, Real)>),
        Faces(Vec<bool>),
    }
    let nf = mesh.num_faces();
    let mut shapes: Vec<Shape> = Vec::with_capacity(specs.len());
    for spec in specs {
        match &spec.shape {
            PanelShape::Region(half_spaces) => {
                let hs = half_spaces
                    .iter()
                    .enumerate()
                    .map(|(i, h)| unit_half_space(h, &spec.name, i))
                    .collect::<Result<Vec<_>, _>>()?;
                shapes.push(Shape::Region(hs));
            }
            PanelShape::Faces(list) => {
                if list.is_empty() {
                    return Err(PlaneCutError::EmptyFaceList {
                        panel: spec.name.clone(),
                    });
                }
                let mut mask = vec![false; nf];
                for &f in list {
                    if f >= nf {
                        return Err(PlaneCutError::FaceOutOfRange {
                            panel: spec.name.clone(),
                            face: f,
                            num_faces: nf,
                        });
                    }
                    if std::mem::replace(&mut mask[f], true) {
                        return Err(PlaneCutError::DuplicateFace {
                            panel: spec.name.clone(),
                            face: f,
                        });
                    }
                }
                shapes.push(Shape::Faces(mask));
            }
        }
    }
    let planes: Vec<(Vec3, Real)> = shapes
        .iter()
        .filter_map(|s| match s {
            Shape::Region(hs) => Some(hs.iter().copied()),
            Shape::Faces(_) => None,
        })
        .flatten()
        .collect();
    let cut = cut(mesh, &planes, params)?;
    let (lo, hi) = mesh.bounding_box().ok_or(PlaneCutError::EmptyMesh)?;
    let eps = params.snap_tolerance * (hi - lo).norm();
    let cm = &cut.mesh;

    // Assign faces to panels.
    let mut panel_of_face: Vec<Option<usize>> = vec![None; cm.num_faces()];
    for (f, face) in cm.faces.iter().enumerate() {
        for (p, shape) in shapes.iter().enumerate() {
            let inside = match shape {
                Shape::Region(hs) => face_inside(&cm.positions, face, hs, eps),
                Shape::Faces(mask) => mask[cut.face_origin[f].face],
            };
            if !inside {
                continue;
            }
            if let Some(q) = panel_of_face[f] {
                let c =
                    (cm.positions[face[0]] + cm.positions[face[1]] + cm.positions[face[2]]) / 3.0;
                return Err(PlaneCutError::Overlap {
                    first: specs[q].name.clone(),
                    second: specs[p].name.clone(),
                    face: cut.face_origin[f].face,
                    x: c.x,
                    y: c.y,
                    z: c.z,
                });
            }
            panel_of_face[f] = Some(p);
        }
    }
    let names: Vec<String> = specs.iter().map(|s| s.name.clone()).collect();
    assemble_panels(cut, &names, &panel_of_face)
}

/// Builds the panels of a cut mesh from a per-face panel label: panel `p` (named `names[p]`) is made of the
/// faces `f` of `cut.mesh` with `panel_of_face[f] == Some(p)` (`#F_cut` labels; `None`: uncovered surface).
/// Boundary loops are tagged with what lies across each edge, and the seams between panels are collected.
///
/// Errors: a label list of the wrong length or naming a panel that does not exist, a cut mesh that is not an
/// oriented manifold, a panel with no faces, or a panel whose faces do not form a manifold (named).
pub fn assemble_panels(
    cut: CutMesh,
    names: &[String],
    panel_of_face: &[Option<usize>],
) -> Result<PanelSet, PlaneCutError> {
    let cm = &cut.mesh;
    if names.is_empty() {
        return Err(PlaneCutError::NoRegions);
    }
    if panel_of_face.len() != cm.num_faces() || cut.face_origin.len() != cm.num_faces() {
        return Err(PlaneCutError::BadLabels {
            problem: format!(
                "{} face labels and {} face origins for a cut mesh of {} faces",
                panel_of_face.len(),
                cut.face_origin.len(),
                cm.num_faces()
            ),
        });
    }
    if let Some((f, p)) = panel_of_face
        .iter()
        .enumerate()
        .find_map(|(f, p)| p.filter(|&p| p >= names.len()).map(|p| (f, p)))
    {
        return Err(PlaneCutError::BadLabels {
            problem: format!(
                "face {f} is labelled panel {p}, but there are {} panels",
                names.len()
            ),
        });
    }
    let topo = Topology::new(cm.num_vertices(), &cm.faces).map_err(PlaneCutError::Topology)?;
    let mut out_panels = Vec::with_capacity(names.len());
    for (p, name) in names.iter().enumerate() {
        let mut local = vec![usize::MAX; cm.num_vertices()];
        let mut cut_vertex = Vec::new();
        let mut faces = Vec::new();
        let mut face_origin = Vec::new();
        let mut face_of_local: Vec<(usize, usize)> = Vec::new(); // (cut face, local face)
        for (f, face) in cm.faces.iter().enumerate() {
            if panel_of_face[f] != Some(p) {
                continue;
            }
            let lf = face.map(|v| {
                if local[v] == usize::MAX {
                    local[v] = cut_vertex.len();
                    cut_vertex.push(v);
                }
                local[v]
            });
            face_of_local.push((f, faces.len()));
            faces.push(lf);
            face_origin.push(cut.face_origin[f]);
        }
        if faces.is_empty() {
            return Err(PlaneCutError::EmptyRegion {
                panel: name.clone(),
            });
        }
        let positions: Vec<Vec3> = cut_vertex.iter().map(|&v| cm.positions[v]).collect();
        let ptopo = Topology::new(positions.len(), &faces).map_err(|e| {
            PlaneCutError::NonManifoldPanel {
                panel: name.clone(),
                source: e,
            }
        })?;
        // Body location of each vertex, from any face that uses it.
        let mut vertex_origin = vec![
            MeshPoint {
                face: 0,
                bary: [0.0; 3]
            };
            positions.len()
        ];
        for (lf, face) in faces.iter().enumerate() {
            for (k, &v) in face.iter().enumerate() {
                vertex_origin[v] = MeshPoint {
                    face: face_origin[lf].face,
                    bary: face_origin[lf].corner_bary[k],
                };
            }
        }
        // Boundary loops, with what lies across each edge.
        let mut next: HashMap<VertexId, (VertexId, Border)> = HashMap::new();
        for &(cf, lf) in &face_of_local {
            for e in 0..3 {
                if ptopo.twin(lf, e).is_some() {
                    continue;
                }
                let (a, b) = (faces[lf][e], faces[lf][(e + 1) % 3]);
                let border = match topo.twin(cf, e).and_then(|t| panel_of_face[t.face]) {
                    Some(q) if q != p => Border::Seam { panel: q },
                    _ => Border::Free,
                };
                next.insert(a, (b, border));
            }
        }
        let mut starts: Vec<VertexId> = next.keys().copied().collect();
        starts.sort_unstable();
        let mut visited = vec![false; positions.len()];
        let mut boundary = Vec::new();
        for s in starts {
            if visited[s] {
                continue;
            }
            let mut vertices = Vec::new();
            let mut borders = Vec::new();
            let mut v = s;
            while !visited[v] {
                visited[v] = true;
                let (w, border) = next[&v];
                vertices.push(v);
                borders.push(border);
                v = w;
            }
            boundary.push(BoundaryLoop { vertices, borders });
        }
        out_panels.push(Panel {
            name: name.clone(),
            mesh: TriMesh::new(positions, faces),
            vertex_origin,
            face_origin,
            cut_vertex,
            boundary,
        });
    }
    let seams = seams(&out_panels);
    Ok(PanelSet {
        cut,
        panels: out_panels,
        seams,
    })
}

/// Splits a boundary loop into maximal runs of edges with the same border; returns `(first edge, edge count,
/// border)` per run. A loop with a single border throughout is one run starting at edge 0.
pub fn border_runs(lp: &BoundaryLoop) -> Vec<(usize, usize, Border)> {
    let n = lp.borders.len();
    let Some(start) = (0..n).find(|&i| lp.borders[i] != lp.borders[(i + n - 1) % n]) else {
        return vec![(0, n, lp.borders[0])];
    };
    let mut runs = Vec::new();
    let mut i = 0;
    while i < n {
        let first = (start + i) % n;
        let mut len = 1;
        while i + len < n && lp.borders[(start + i + len) % n] == lp.borders[first] {
            len += 1;
        }
        runs.push((first, len, lp.borders[first]));
        i += len;
    }
    runs
}

/// Seams between panels: every run of boundary edges of panel `p` bordering panel `q > p`, with the matching
/// vertices of `q`.
fn seams(panels: &[Panel]) -> Vec<CutSeam> {
    let inverse: Vec<HashMap<VertexId, VertexId>> = panels
        .iter()
        .map(|p| {
            p.cut_vertex
                .iter()
                .enumerate()
                .map(|(l, &g)| (g, l))
                .collect()
        })
        .collect();
    let mut out = Vec::new();
    for (p, panel) in panels.iter().enumerate() {
        for lp in &panel.boundary {
            let n = lp.vertices.len();
            for (first, len, border) in border_runs(lp) {
                let Border::Seam { panel: q } = border else {
                    continue;
                };
                if q < p {
                    continue;
                }
                let closed = len == n;
                let count = if closed { n } else { len + 1 };
                let a: Vec<VertexId> = (0..count).map(|k| lp.vertices[(first + k) % n]).collect();
                let b: Vec<VertexId> = a
                    .iter()
                    .map(|&v| inverse[q][&panel.cut_vertex[v]])
                    .collect();
                out.push(CutSeam {
                    sides: [
                        SeamSide {
                            panel: p,
                            vertices: a,
                        },
                        SeamSide {
                            panel: q,
                            vertices: b,
                        },
                    ],
                    closed,
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use skintight_geometry::test_meshes::{body_path, cylinder, icosphere, read_obj};

    fn hs(n: [Real; 3], d: Real) -> HalfSpace {
        HalfSpace::new(n, d)
    }

    /// Four panels on a sphere of radius 1: top cap z ≥ 0.3, two half bands split by x = 0.05, bottom cap
    /// z ≤ −0.4. Planes are chosen off the icosphere's symmetry planes so that they cross faces generically.
    fn sphere_regions() -> Vec<Region> {
        vec![
            Region {
                label: "top".into(),
                half_spaces: vec![hs([0.0, 0.0, -1.0], -0.3)],
            },
            Region {
                label: "left".into(),
                half_spaces: vec![
                    hs([0.0, 0.0, 1.0], 0.3),
                    hs([0.0, 0.0, -1.0], 0.4),
                    hs([1.0, 0.0, 0.0], 0.05),
                ],
            },
            Region {
                label: "right".into(),
                half_spaces: vec![
                    hs([0.0, 0.0, 1.0], 0.3),
                    hs([0.0, 0.0, -1.0], 0.4),
                    hs([-1.0, 0.0, 0.0], -0.05),
                ],
            },
            Region {
                label: "bottom".into(),
                half_spaces: vec![hs([0.0, 0.0, 1.0], -0.4)],
            },
        ]
    }

    #[test]
    fn sphere_panels_partition_the_area() {
        for levels in [2, 3, 4] {
            let m = icosphere(levels, 1.0);
            let set = panels(&m, &sphere_regions(), &PlaneCutParams::default()).unwrap();
            let total: Real = set.panels.iter().map(|p| p.mesh.area()).sum();
            assert!(
                (total - m.area()).abs() < 1e-12 * m.area(),
                "levels {levels}"
            );
            assert!((set.cut.mesh.area() - m.area()).abs() < 1e-12);
            // The refined mesh is still a closed manifold: no cracks.
            let t = Topology::new(set.cut.mesh.num_vertices(), &set.cut.mesh.faces).unwrap();
            assert!(t.is_closed());
            assert!((set.cut.mesh.signed_volume() - m.signed_volume()).abs() < 1e-12);
        }
    }

    #[test]
    fn cut_vertices_lie_on_their_planes() {
        let m = icosphere(3, 1.0);
        let regions = sphere_regions();
        let set = panels(&m, &regions, &PlaneCutParams::default()).unwrap();
        let planes: Vec<(Vec3, Real)> = regions
            .iter()
            .flat_map(|r| r.half_spaces.iter().map(|h| (h.normal, h.offset)))
            .collect();
        let nv = m.num_vertices();
        assert!(set.cut.mesh.num_vertices() > nv);
        for (v, p) in set.cut.mesh.positions.iter().enumerate().skip(nv) {
            let on_some = planes.iter().any(|(n, d)| (n.dot(p) - d).abs() < 1e-12);
            assert!(on_some, "new vertex {v} at {p:?} lies on no plane");
        }
        // Every boundary vertex of every panel lies on one of that panel's planes.
        for (panel, region) in set.panels.iter().zip(&regions) {
            for lp in &panel.boundary {
                for &v in &lp.vertices {
                    let p = panel.mesh.positions[v];
                    assert!(
                        region
                            .half_spaces
                            .iter()
                            .any(|h| (h.normal.dot(&p) - h.offset).abs() < 1e-12),
                        "{}: boundary vertex {v} off the region's planes",
                        panel.name
                    );
                }
            }
        }
    }

    #[test]
    fn vertex_origins_reproduce_positions() {
        let m = icosphere(3, 1.0);
        let set = panels(&m, &sphere_regions(), &PlaneCutParams::default()).unwrap();
        for panel in &set.panels {
            for (v, o) in panel.vertex_origin.iter().enumerate() {
                let sum: Real = o.bary.iter().sum();
                assert!((sum - 1.0).abs() < 1e-12);
                assert!(o.bary.iter().all(|&b| b > -1e-12));
                assert!((o.position(&m) - panel.mesh.positions[v]).norm() < 1e-12);
            }
            for (f, fo) in panel.face_origin.iter().enumerate() {
                let c = fo.mesh_point([1.0 / 3.0; 3]).position(&m);
                let [a, b, d] = panel.mesh.corners(f);
                assert!((c - (a + b + d) / 3.0).norm() < 1e-12);
            }
        }
    }

    #[test]
    fn panels_are_disks_with_tagged_borders() {
        let m = icosphere(3, 1.0);
        let set = panels(&m, &sphere_regions(), &PlaneCutParams::default()).unwrap();
        for panel in &set.panels {
            let t = Topology::new(panel.mesh.num_vertices(), &panel.mesh.faces).unwrap();
            assert_eq!(t.face_components().1, 1, "{}", panel.name);
            assert_eq!(
                panel.boundary.len(),
                1,
                "{} has one boundary loop",
                panel.name
            );
            let euler = panel.mesh.num_vertices() as i64 - t.num_edges() as i64
                + panel.mesh.num_faces() as i64;
            assert_eq!(euler, 1, "{} is a disk", panel.name);
            assert_eq!(t.boundary_edges().len(), panel.boundary[0].vertices.len());
        }
        // The top cap borders only the two bands.
        let top = &set.panels[0].boundary[0];
        assert!(
            top.borders
                .iter()
                .all(|b| matches!(b, Border::Seam { panel: 1 | 2 }))
        );
        assert!(top.borders.contains(&Border::Seam { panel: 1 }));
        assert!(top.borders.contains(&Border::Seam { panel: 2 }));
    }

    #[test]
    fn seam_polylines_coincide() {
        let m = icosphere(3, 1.0);
        let set = panels(&m, &sphere_regions(), &PlaneCutParams::default()).unwrap();
        // top–left, top–right, left–right twice (x = 0.05 on front and back), left–bottom, right–bottom.
        assert_eq!(set.seams.len(), 6);
        let mut seam_edges = 0;
        for s in &set.seams {
            let [a, b] = &s.sides;
            assert!(!s.closed);
            assert_eq!(a.vertices.len(), b.vertices.len());
            assert!(a.vertices.len() >= 2);
            for (&va, &vb) in a.vertices.iter().zip(&b.vertices) {
                let pa = set.panels[a.panel].mesh.positions[va];
                let pb = set.panels[b.panel].mesh.positions[vb];
                assert_eq!(pa, pb);
            }
            seam_edges += a.vertices.len() - 1;
        }
        // Every seam-tagged boundary edge belongs to exactly one seam (counted from both sides).
        let tagged: usize = set
            .panels
            .iter()
            .flat_map(|p| &p.boundary)
            .flat_map(|l| &l.borders)
            .filter(|b| matches!(b, Border::Seam { .. }))
            .count();
        assert_eq!(tagged, 2 * seam_edges);
    }

    #[test]
    fn uncovered_surface_gives_free_borders_and_slab_annulus() {
        let m = icosphere(3, 1.0);
        // A slab −0.2 ≤ z ≤ 0.25 alone: an annulus with two free loops.
        let slab = Region {
            label: "slab".into(),
            half_spaces: vec![hs([0.0, 0.0, 1.0], 0.25), hs([0.0, 0.0, -1.0], 0.2)],
        };
        let set = panels(&m, &[slab], &PlaneCutParams::default()).unwrap();
        let p = &set.panels[0];
        assert_eq!(p.boundary.len(), 2);
        assert!(
            p.boundary
                .iter()
                .flat_map(|l| &l.borders)
                .all(|b| *b == Border::Free)
        );
        // Exact area of a spherical zone: 2πRh.
        let zone = 2.0 * std::f64::consts::PI * 0.45;
        assert!((p.mesh.area() - zone).abs() < 0.02 * zone);
        assert!(set.seams.is_empty());
    }

    #[test]
    fn closed_seam_between_two_caps() {
        let m = icosphere(2, 1.0);
        let regions = vec![
            Region {
                label: "north".into(),
                half_spaces: vec![hs([0.1, 0.2, -1.0], -0.1)],
            },
            Region {
                label: "south".into(),
                half_spaces: vec![hs([-0.1, -0.2, 1.0], 0.1)],
            },
        ];
        let set = panels(&m, &regions, &PlaneCutParams::default()).unwrap();
        assert_eq!(set.seams.len(), 1);
        assert!(set.seams[0].closed);
        let total: Real = set.panels.iter().map(|p| p.mesh.area()).sum();
        assert!((total - m.area()).abs() < 1e-12);
    }

    #[test]
    fn empty_region_is_named() {
        let m = icosphere(2, 1.0);
        let regions = vec![Region {
            label: "moon".into(),
            half_spaces: vec![hs([0.0, 0.0, -1.0], -5.0)],
        }];
        let err = panels(&m, &regions, &PlaneCutParams::default()).unwrap_err();
        assert_eq!(
            err,
            PlaneCutError::EmptyRegion {
                panel: "moon".into()
            }
        );
        assert!(err.to_string().contains("'moon'"));
    }

    #[test]
    fn overlapping_regions_are_rejected() {
        let m = icosphere(2, 1.0);
        let regions = vec![
            Region {
                label: "a".into(),
                half_spaces: vec![hs([0.0, 0.0, 1.0], 0.2)],
            },
            Region {
                label: "b".into(),
                half_spaces: vec![hs([0.0, 0.0, -1.0], 0.1)],
            },
        ];
        let err = panels(&m, &regions, &PlaneCutParams::default()).unwrap_err();
        assert!(matches!(err, PlaneCutError::Overlap { .. }), "{err}");
        let msg = err.to_string();
        assert!(msg.contains("'a'") && msg.contains("'b'"), "{msg}");
    }

    #[test]
    fn bad_half_space_is_rejected() {
        let m = icosphere(1, 1.0);
        for (h, what) in [
            (hs([0.0, 0.0, 0.0], 0.0), "zero"),
            (hs([Real::NAN, 0.0, 1.0], 0.0), "non-finite"),
            (hs([0.0, 0.0, 1.0], Real::INFINITY), "offset"),
        ] {
            let regions = vec![Region {
                label: "p".into(),
                half_spaces: vec![h],
            }];
            let err = panels(&m, &regions, &PlaneCutParams::default()).unwrap_err();
            assert!(err.to_string().contains(what), "{err}");
        }
        assert_eq!(
            panels(&m, &[], &PlaneCutParams::default()).unwrap_err(),
            PlaneCutError::NoRegions
        );
    }

    #[test]
    fn non_unit_normal_describes_the_same_half_space() {
        let m = icosphere(2, 1.0);
        let a = vec![Region {
            label: "a".into(),
            half_spaces: vec![hs([0.0, 0.0, -1.0], -0.3)],
        }];
        let b = vec![Region {
            label: "a".into(),
            half_spaces: vec![hs([0.0, 0.0, -4.0], -1.2)],
        }];
        let pa = panels(&m, &a, &PlaneCutParams::default()).unwrap();
        let pb = panels(&m, &b, &PlaneCutParams::default()).unwrap();
        assert_eq!(pa.panels[0].mesh, pb.panels[0].mesh);
    }

    #[test]
    fn plane_through_vertices_snaps_without_slivers() {
        // z = 0 passes exactly through icosphere vertices: no new vertex may be created next to them.
        let m = icosphere(2, 1.0);
        let cut_mesh = cut(&m, &[(Vec3::z(), 0.0)], &PlaneCutParams::default()).unwrap();
        let min_edge = cut_mesh
            .mesh
            .faces
            .iter()
            .flat_map(|f| (0..3).map(move |e| (f[e], f[(e + 1) % 3])))
            .map(|(a, b)| (cut_mesh.mesh.positions[a] - cut_mesh.mesh.positions[b]).norm())
            .fold(Real::INFINITY, Real::min);
        assert!(min_edge > 1e-6, "sliver edge of length {min_edge}");
        assert!((cut_mesh.mesh.area() - m.area()).abs() < 1e-12);
    }

    fn shortest_edge(m: &TriMesh) -> Real {
        m.faces
            .iter()
            .flat_map(|f| (0..3).map(move |e| (f[e], f[(e + 1) % 3])))
            .map(|(a, b)| (m.positions[a] - m.positions[b]).norm())
            .fold(Real::INFINITY, Real::min)
    }

    #[test]
    fn plane_grazing_vertices_snaps_to_them() {
        // z = 1e-13 misses the equator vertices by a hair: without snapping, the cut would create sliver
        // triangles with edges of about 1e-13 m; with the default tolerance the vertices are reused.
        let m = icosphere(2, 1.0);
        let plane = [(Vec3::z(), 1e-13)];
        let snapped = cut(&m, &plane, &PlaneCutParams::default()).unwrap();
        assert!(shortest_edge(&snapped.mesh) > 1e-6);
        let exact = cut(
            &m,
            &plane,
            &PlaneCutParams {
                snap_tolerance: 0.0,
            },
        )
        .unwrap();
        assert!(shortest_edge(&exact.mesh) < 1e-12);
        for c in [&snapped, &exact] {
            assert!((c.mesh.area() - m.area()).abs() < 1e-12);
            assert!(
                Topology::new(c.mesh.num_vertices(), &c.mesh.faces)
                    .unwrap()
                    .is_closed()
            );
        }
    }

    #[test]
    fn region_json_round_trip_and_unknown_field() {
        let r = &sphere_regions()[1];
        let text = serde_json::to_string(r).unwrap();
        let back: Region = serde_json::from_str(&text).unwrap();
        assert_eq!(&back, r);
        let bad = r#"{"label": "x", "half_spaces": [], "colour": 3}"#;
        assert!(serde_json::from_str::<Region>(bad).is_err());
        let bad = r#"{"label": "x", "half_spaces": [{"normal": [0,0,1], "offset": 0, "d": 1}]}"#;
        assert!(serde_json::from_str::<Region>(bad).is_err());
    }

    fn face_centroid(m: &TriMesh, f: usize) -> Vec3 {
        let [a, b, c] = m.corners(f);
        (a + b + c) / 3.0
    }

    fn faces_where(m: &TriMesh, keep: impl Fn(Vec3) -> bool) -> Vec<FaceId> {
        (0..m.num_faces())
            .filter(|&f| keep(face_centroid(m, f)))
            .collect()
    }

    fn spec(name: &str, shape: PanelShape) -> PanelSpec {
        PanelSpec {
            name: name.into(),
            shape,
        }
    }

    #[test]
    fn face_list_panels_split_a_sphere_exactly() {
        let m = icosphere(3, 1.0);
        let north = faces_where(&m, |c| c.z > 0.0);
        let south = faces_where(&m, |c| c.z <= 0.0);
        let specs = vec![
            spec("north", PanelShape::Faces(north.clone())),
            spec("south", PanelShape::Faces(south)),
        ];
        let set = panels_from_specs(&m, &specs, &PlaneCutParams::default()).unwrap();
        // No planes: the cut mesh is the body itself, and each panel is exactly its faces.
        assert_eq!(set.cut.mesh.faces, m.faces);
        let north_area: Real = north.iter().map(|&f| m.face_area(f)).sum();
        assert!((set.panels[0].mesh.area() - north_area).abs() < 1e-12);
        assert_eq!(set.panels[0].mesh.num_faces(), north.len());
        for p in &set.panels {
            assert!(
                p.face_origin
                    .iter()
                    .all(|o| north.contains(&o.face) == (p.name == "north"))
            );
            assert_eq!(p.boundary.len(), 1);
        }
        assert_eq!(set.seams.len(), 1);
        assert!(set.seams[0].closed);
        assert!(
            set.panels[0].boundary[0]
                .borders
                .iter()
                .all(|b| *b == Border::Seam { panel: 1 })
        );
    }

    #[test]
    fn face_list_and_region_panels_mix_on_a_cylinder() {
        // Open tube about z: the face list takes the half with y > 0, the region the half with y ≤ 0.
        let m = cylinder(0.5, 1.0, 16, 6, std::f64::consts::TAU);
        let front = faces_where(&m, |c| c.y > 0.0);
        let specs = vec![
            spec("front", PanelShape::Faces(front.clone())),
            spec("back", PanelShape::Region(vec![hs([0.0, 1.0, 0.0], 0.0)])),
        ];
        let set = panels_from_specs(&m, &specs, &PlaneCutParams::default()).unwrap();
        let total: Real = set.panels.iter().map(|p| p.mesh.area()).sum();
        assert!((total - m.area()).abs() < 1e-12);
        let front_area: Real = front.iter().map(|&f| m.face_area(f)).sum();
        assert!((set.panels[0].mesh.area() - front_area).abs() < 1e-12);
        // Two straight seams along the tube at angles 0 and π; top and bottom rims are free.
        assert_eq!(set.seams.len(), 2);
        for s in &set.seams {
            assert!(!s.closed);
            assert_eq!(s.sides[0].vertices.len(), 7);
            for (&a, &b) in s.sides[0].vertices.iter().zip(&s.sides[1].vertices) {
                let pa = set.panels[s.sides[0].panel].mesh.positions[a];
                assert_eq!(pa, set.panels[s.sides[1].panel].mesh.positions[b]);
                assert!(pa.y.abs() < 1e-12);
            }
        }
        for p in &set.panels {
            assert_eq!(p.boundary.len(), 1, "{} is a disk", p.name);
            assert!(p.boundary[0].borders.contains(&Border::Free));
        }
    }

    #[test]
    fn region_planes_refine_face_list_panels() {
        // A region plane through the face-list panel splits its faces but the panel keeps them all.
        let m = icosphere(2, 1.0);
        let top = faces_where(&m, |c| c.z > 0.2);
        let specs = vec![
            spec("top", PanelShape::Faces(top.clone())),
            spec(
                "bottom",
                PanelShape::Region(vec![hs([0.0, 0.1, 1.0], -0.3)]),
            ),
        ];
        let set = panels_from_specs(&m, &specs, &PlaneCutParams::default()).unwrap();
        let top_area: Real = top.iter().map(|&f| m.face_area(f)).sum();
        assert!((set.panels[0].mesh.area() - top_area).abs() < 1e-12);
        assert!(set.panels[1].mesh.area() > 0.0);
        assert!(set.seams.is_empty(), "the two panels do not touch");
    }

    #[test]
    fn face_list_errors_name_the_panel() {
        let m = icosphere(1, 1.0);
        let params = PlaneCutParams::default();
        let err = panels_from_specs(&m, &[spec("cuff", PanelShape::Faces(vec![3, 80]))], &params)
            .unwrap_err();
        assert_eq!(
            err,
            PlaneCutError::FaceOutOfRange {
                panel: "cuff".into(),
                face: 80,
                num_faces: 80
            }
        );
        assert!(err.to_string().contains("80 faces"), "{err}");
        let err = panels_from_specs(
            &m,
            &[spec("cuff", PanelShape::Faces(vec![3, 4, 3]))],
            &params,
        )
        .unwrap_err();
        assert!(
            matches!(err, PlaneCutError::DuplicateFace { face: 3, .. }),
            "{err}"
        );
        assert!(err.to_string().contains("'cuff'"));
        let err =
            panels_from_specs(&m, &[spec("cuff", PanelShape::Faces(vec![]))], &params).unwrap_err();
        assert_eq!(
            err,
            PlaneCutError::EmptyFaceList {
                panel: "cuff".into()
            }
        );
        // Overlap between two face lists, and between a face list and a region.
        let specs = vec![
            spec("a", PanelShape::Faces(vec![0, 1, 2])),
            spec("b", PanelShape::Faces(vec![2, 5])),
        ];
        let err = panels_from_specs(&m, &specs, &params).unwrap_err();
        assert!(
            matches!(err, PlaneCutError::Overlap { face: 2, .. }),
            "{err}"
        );
        assert!(err.to_string().contains("'a'") && err.to_string().contains("'b'"));
        let specs = vec![
            spec("a", PanelShape::Faces((0..80).collect())),
            spec("r", PanelShape::Region(vec![hs([0.0, 0.0, 1.0], 0.0)])),
        ];
        let err = panels_from_specs(&m, &specs, &params).unwrap_err();
        assert!(matches!(err, PlaneCutError::Overlap { .. }), "{err}");
        // Two faces touching at a single vertex: not a manifold.
        let (f, g) = (0..m.num_faces())
            .flat_map(|f| (0..m.num_faces()).map(move |g| (f, g)))
            .find(|&(f, g)| {
                f < g && m.faces[f].iter().filter(|v| m.faces[g].contains(v)).count() == 1
            })
            .unwrap();
        let err = panels_from_specs(&m, &[spec("bow", PanelShape::Faces(vec![f, g]))], &params)
            .unwrap_err();
        assert!(
            matches!(err, PlaneCutError::NonManifoldPanel { ref panel, .. } if panel == "bow"),
            "{err}"
        );
    }

    #[test]
    fn assemble_panels_rejects_bad_labels() {
        let m = icosphere(1, 1.0);
        let c = cut(&m, &[], &PlaneCutParams::default()).unwrap();
        let names = vec!["a".to_string()];
        let err = assemble_panels(c.clone(), &names, &[Some(0)]).unwrap_err();
        assert!(matches!(err, PlaneCutError::BadLabels { .. }), "{err}");
        let mut labels = vec![Some(0); 80];
        labels[7] = Some(1);
        let err = assemble_panels(c.clone(), &names, &labels).unwrap_err();
        assert!(err.to_string().contains("face 7"), "{err}");
        labels[7] = None;
        let set = assemble_panels(c, &names, &labels).unwrap();
        assert_eq!(set.panels[0].mesh.num_faces(), 79);
        assert_eq!(set.panels[0].boundary[0].borders, vec![Border::Free; 3]);
    }

    #[test]
    fn panel_spec_json() {
        let text = r#"{"name": "f", "shape": {"faces": [1, 2]}}"#;
        let s: PanelSpec = serde_json::from_str(text).unwrap();
        assert_eq!(s.shape, PanelShape::Faces(vec![1, 2]));
        let text = r#"{"name": "r", "shape": {"region": [{"normal": [0, 0, 1], "offset": 0.5}]}}"#;
        let s: PanelSpec = serde_json::from_str(text).unwrap();
        assert_eq!(s.shape, PanelShape::Region(vec![hs([0.0, 0.0, 1.0], 0.5)]));
    }

    #[test]
    fn body_torso_cut_front_and_back() {
        let body = read_obj(&body_path("regular_1k.obj"));
        // Torso between hips and chest (metres, +y up, body faces +z), split front/back at z = 0.02.
        let (lo, hi) = body.bounding_box().unwrap();
        let y0 = lo.y + 0.5 * (hi.y - lo.y);
        let y1 = lo.y + 0.7 * (hi.y - lo.y);
        let slab = |n: [Real; 3], d: Real| {
            vec![
                hs([0.0, -1.0, 0.0], -y0),
                hs([0.0, 1.0, 0.0], y1),
                hs([1.0, 0.0, 0.0], 0.2),
                hs([-1.0, 0.0, 0.0], 0.2),
                hs(n, d),
            ]
        };
        let regions = vec![
            Region {
                label: "front".into(),
                half_spaces: slab([0.0, 0.0, -1.0], -0.02),
            },
            Region {
                label: "back".into(),
                half_spaces: slab([0.0, 0.0, 1.0], 0.02),
            },
        ];
        let set = panels(&body, &regions, &PlaneCutParams::default()).unwrap();
        assert!(!set.seams.is_empty());
        for s in &set.seams {
            for (&va, &vb) in s.sides[0].vertices.iter().zip(&s.sides[1].vertices) {
                assert_eq!(
                    set.panels[s.sides[0].panel].mesh.positions[va],
                    set.panels[s.sides[1].panel].mesh.positions[vb]
                );
            }
        }
        assert!((set.cut.mesh.area() - body.area()).abs() < 1e-12 * body.area());
    }
}
