//! What is wrong with a triangle mesh, all at once: a [`MeshReport`] for any mesh, however broken, and
//! [`body_surface`], the gate a body mesh must pass (closed, oriented, one component, 2-manifold, finite,
//! no degenerate faces).
//!
//! [`Topology::new`] stops at the first violation; a report must list every problem, so edges are counted
//! here by sorting half-edges, and [`Topology`] is built only once the mesh is known to be clean.

use std::fmt;

use serde::Serialize;

use crate::math::{FaceId, Real, Vec3, VertexId};
use crate::mesh::TriMesh;
use crate::mesh::topology::{Topology, TopologyError};

/// Settings of [`mesh_report`] and [`body_surface`].
#[derive(Clone, Copy, Debug)]
pub struct MeshCheckParams {
    /// A face is degenerate when its area (m²) is at most this times the squared mean edge length (m²).
    /// An equilateral triangle has ratio √3/4 ≈ 0.43.
    pub degenerate_area_ratio: Real,
}

impl Default for MeshCheckParams {
    fn default() -> Self {
        Self {
            degenerate_area_ratio: 1e-10,
        }
    }
}

/// Which way the faces of a closed, consistently oriented surface turn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Orientation {
    /// Counter-clockwise seen from outside: positive enclosed volume.
    Outward,
    /// Clockwise seen from outside: negative enclosed volume.
    Inward,
    /// Open, inconsistent, non-manifold, non-finite, mixed across components, or zero volume.
    Unknown,
}

/// Axis-aligned bounding box of the finite vertices (m).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BoundingBox {
    pub min: [Real; 3],
    pub max: [Real; 3],
}

/// One problem of a mesh, naming where it is. Lists hold every occurrence (in index order); the message
/// shows the first five.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshIssue {
    /// No faces at all.
    Empty,
    /// Vertices with a NaN or infinite coordinate.
    NonFinite { vertices: Vec<VertexId> },
    /// Faces naming a vertex index `≥ #V`: `(face, vertex)`.
    BadIndex {
        faces: Vec<(FaceId, usize)>,
        num_vertices: usize,
    },
    /// Faces using one vertex twice: `(face, vertex)`.
    RepeatedVertex { faces: Vec<(FaceId, VertexId)> },
    /// Faces whose area is at most `ratio` × mean edge².
    Degenerate { faces: Vec<FaceId>, ratio: Real },
    /// Edges `(a, b)` shared by `count > 2` faces.
    NonManifoldEdges {
        edges: Vec<(VertexId, VertexId, usize)>,
    },
    /// Vertices whose faces form several fans (pinched, "bow-tie" vertices): `(vertex, fans)`.
    NonManifoldVertices { vertices: Vec<(VertexId, usize)> },
    /// Pairs of faces `(f, g)` traversing their shared edge `(a, b)` in the same direction.
    InconsistentOrientation {
        pairs: Vec<(FaceId, FaceId, VertexId, VertexId)>,
    },
    /// Edges with one face: how many, and one of them `(a, b)` as its face traverses it.
    Open {
        boundary_edges: usize,
        example: (VertexId, VertexId),
    },
    /// Several connected components; faces per component.
    Components { faces: Vec<usize> },
    /// Vertices that no face uses.
    Unreferenced { vertices: Vec<VertexId> },
    /// A closed oriented surface with zero signed volume (m³): inside cannot be told from outside.
    NoInside { volume: Real },
    /// The connectivity builder refused the mesh (not expected after the checks above).
    Topology(TopologyError),
}

impl MeshIssue {
    /// Whether the issue stops a mesh from serving as a body ([`body_surface`] repairs the others).
    pub fn is_blocking(&self) -> bool {
        !matches!(self, MeshIssue::Unreferenced { .. })
    }
}

/// `a, b, c and 7 more`, showing at most `max` items.
fn listing<T>(items: &[T], max: usize, show: impl Fn(&T) -> String) -> String {
    let mut s = items
        .iter()
        .take(max)
        .map(show)
        .collect::<Vec<_>>()
        .join(", ");
    if items.len() > max {
        s.push_str(&format!(" and {} more", items.len() - max));
    }
    s
}

const LISTED: usize = 5;

impl fmt::Display for MeshIssue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use MeshIssue::*;
        match self {
            Empty => write!(f, "the mesh has no faces"),
            NonFinite { vertices } => match vertices.as_slice() {
                [v] => write!(
                    f,
                    "vertex {v} has a non-finite coordinate (NaN or infinity)"
                ),
                vs => write!(
                    f,
                    "{} vertices have non-finite coordinates (NaN or infinity): {}",
                    vs.len(),
                    listing(vs, LISTED, |v| v.to_string())
                ),
            },
            BadIndex {
                faces,
                num_vertices,
            } => match faces.as_slice() {
                [(face, v)] => write!(
                    f,
                    "face {face} names vertex {v}, but the mesh has {num_vertices} vertices"
                ),
                fs => write!(
                    f,
                    "{} faces name vertices that do not exist (the mesh has {num_vertices}): {}",
                    fs.len(),
                    listing(fs, LISTED, |(face, v)| format!("face {face} (vertex {v})"))
                ),
            },
            RepeatedVertex { faces } => match faces.as_slice() {
                [(face, v)] => write!(f, "face {face} uses vertex {v} twice"),
                fs => write!(
                    f,
                    "{} faces use a vertex twice: {}",
                    fs.len(),
                    listing(fs, LISTED, |(face, v)| format!("face {face} (vertex {v})"))
                ),
            },
            Degenerate { faces, ratio } => match faces.as_slice() {
                [face] => write!(
                    f,
                    "face {face} is degenerate: zero or near-zero area (at most {ratio:e} × mean edge²)"
                ),
                fs => write!(
                    f,
                    "{} faces are degenerate, with zero or near-zero area (at most {ratio:e} × mean edge²): {}",
                    fs.len(),
                    listing(fs, LISTED, |face| face.to_string())
                ),
            },
            NonManifoldEdges { edges } => match edges.as_slice() {
                [(a, b, n)] => write!(
                    f,
                    "edge ({a}, {b}) is shared by {n} faces (non-manifold edge)"
                ),
                es => write!(
                    f,
                    "{} edges are shared by more than two faces (non-manifold): {}",
                    es.len(),
                    listing(es, LISTED, |(a, b, n)| format!("({a}, {b}) by {n} faces"))
                ),
            },
            NonManifoldVertices { vertices } => match vertices.as_slice() {
                [(v, fans)] => write!(
                    f,
                    "vertex {v} is non-manifold: its faces form {fans} separate fans"
                ),
                vs => write!(
                    f,
                    "{} vertices are non-manifold (their faces form separate fans): {}",
                    vs.len(),
                    listing(vs, LISTED, |(v, n)| format!("{v} ({n} fans)"))
                ),
            },
            InconsistentOrientation { pairs } => match pairs.as_slice() {
                [(g, h, a, b)] => write!(
                    f,
                    "faces {g} and {h} traverse edge ({a}, {b}) in the same direction (inconsistent orientation)"
                ),
                ps => write!(
                    f,
                    "{} edges have inconsistently oriented faces (traversed twice in the same direction): {}",
                    ps.len(),
                    listing(ps, LISTED, |(g, h, a, b)| format!(
                        "faces {g} and {h} at edge ({a}, {b})"
                    ))
                ),
            },
            Open {
                boundary_edges,
                example: (a, b),
            } => write!(
                f,
                "the surface is open: {boundary_edges} boundary edge{} (with only one face), e.g. edge ({a}, {b})",
                if *boundary_edges == 1 { "" } else { "s" }
            ),
            Components { faces } => write!(
                f,
                "the mesh has {} separate components (faces per component: {})",
                faces.len(),
                listing(faces, LISTED, |n| n.to_string())
            ),
            Unreferenced { vertices } => match vertices.as_slice() {
                [v] => write!(f, "vertex {v} is used by no face"),
                vs => write!(
                    f,
                    "{} vertices are used by no face: {}",
                    vs.len(),
                    listing(vs, LISTED, |v| v.to_string())
                ),
            },
            NoInside { volume } => write!(
                f,
                "the closed surface encloses no volume (signed volume {volume:e} m³), so inside and outside cannot be told apart"
            ),
            Topology(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for MeshIssue {}

/// What is known about a mesh. Serialises to the JSON that `skintight mesh inspect` prints.
#[derive(Clone, Debug, Serialize)]
pub struct MeshReport {
    /// `#V`, including unreferenced vertices.
    pub vertices: usize,
    /// `#F` triangles.
    pub faces: usize,
    /// Undirected edges among the valid faces.
    pub edges: usize,
    /// Every edge has exactly two faces (and there is at least one face).
    pub closed: bool,
    /// No invalid faces, no edge with more than two faces, no pinched vertex.
    pub manifold: bool,
    /// Every two-face edge is traversed once in each direction.
    pub oriented: bool,
    /// Outward or inward when closed, manifold, oriented and finite, with the same sign in every component.
    pub orientation: Orientation,
    /// `V − E + F` over referenced vertices and valid faces.
    pub euler_characteristic: i64,
    /// Sum of the components' genera `g = (2 − χ)/2`; only for a closed, oriented manifold.
    pub genus: Option<i64>,
    /// Connected components (faces linked through shared vertices).
    pub components: usize,
    /// Total area of the valid faces with finite corners (m²).
    pub area: Real,
    /// Enclosed volume (m³, positive), only for a closed, oriented, finite manifold.
    pub volume: Option<Real>,
    /// Bounding box of the finite vertices (m).
    pub bounding_box: Option<BoundingBox>,
    /// Mean edge length of the valid finite faces (m).
    pub mean_edge_length: Option<Real>,
    /// Every problem, in words that name where.
    pub problems: Vec<String>,
    /// The same problems, structured.
    #[serde(skip)]
    pub issues: Vec<MeshIssue>,
}

impl MeshReport {
    /// The first problem that stops the mesh from serving as a body.
    pub fn first_blocking(&self) -> Option<&MeshIssue> {
        self.issues.iter().find(|i| i.is_blocking())
    }
}

/// Disjoint sets with path halving.
struct UnionFind(Vec<usize>);

impl UnionFind {
    fn new(n: usize) -> Self {
        Self((0..n).collect())
    }
    fn root(&mut self, mut i: usize) -> usize {
        while self.0[i] != i {
            self.0[i] = self.0[self.0[i]];
            i = self.0[i];
        }
        i
    }
    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.root(a), self.root(b));
        if ra != rb {
            self.0[ra] = rb;
        }
    }
}

/// Examines a mesh that may be broken in any way and reports everything found.
pub fn mesh_report(mesh: &TriMesh, params: &MeshCheckParams) -> MeshReport {
    let nv = mesh.num_vertices();
    let nf = mesh.num_faces();
    let mut issues = Vec::new();
    if nf == 0 {
        issues.push(MeshIssue::Empty);
    }

    // Vertices.
    let finite: Vec<bool> = mesh
        .positions
        .iter()
        .map(|p| p.iter().all(|x| x.is_finite()))
        .collect();
    let non_finite: Vec<VertexId> = (0..nv).filter(|&v| !finite[v]).collect();
    if !non_finite.is_empty() {
        issues.push(MeshIssue::NonFinite {
            vertices: non_finite.clone(),
        });
    }

    // Faces: indices in range and distinct.
    let mut bad_index = Vec::new();
    let mut repeated = Vec::new();
    let mut valid = vec![true; nf];
    for (f, face) in mesh.faces.iter().enumerate() {
        if let Some(&v) = face.iter().find(|&&v| v >= nv) {
            bad_index.push((f, v));
            valid[f] = false;
        } else if let Some(k) = (0..3).find(|&k| face[k] == face[(k + 1) % 3]) {
            repeated.push((f, face[k]));
            valid[f] = false;
        }
    }
    if !bad_index.is_empty() {
        issues.push(MeshIssue::BadIndex {
            faces: bad_index,
            num_vertices: nv,
        });
    }
    if !repeated.is_empty() {
        issues.push(MeshIssue::RepeatedVertex { faces: repeated });
    }
    let finite_face = |f: usize| valid[f] && mesh.faces[f].iter().all(|&v| finite[v]);

    // Geometry of the valid finite faces: area and degeneracy relative to the mean edge.
    let mut edge_sum = 0.0;
    let mut edge_count = 0usize;
    let mut area = 0.0;
    for f in (0..nf).filter(|&f| finite_face(f)) {
        let [a, b, c] = mesh.corners(f);
        edge_sum += (b - a).norm() + (c - b).norm() + (a - c).norm();
        edge_count += 3;
        area += mesh.face_area(f);
    }
    let mean_edge = (edge_count > 0).then(|| edge_sum / edge_count as Real);
    if let Some(h) = mean_edge {
        let threshold = params.degenerate_area_ratio * h * h;
        let degenerate: Vec<FaceId> = (0..nf)
            .filter(|&f| finite_face(f) && mesh.face_area(f) <= threshold)
            .collect();
        if !degenerate.is_empty() {
            issues.push(MeshIssue::Degenerate {
                faces: degenerate,
                ratio: params.degenerate_area_ratio,
            });
        }
    }

    // Edges: sort half-edges (min, max, face, local edge) so each undirected edge's faces are adjacent.
    let mut half: Vec<(VertexId, VertexId, FaceId, u8)> = Vec::with_capacity(3 * nf);
    for (f, face) in mesh.faces.iter().enumerate() {
        if valid[f] {
            for e in 0..3u8 {
                let (a, b) = (face[e as usize], face[(e as usize + 1) % 3]);
                half.push((a.min(b), a.max(b), f, e));
            }
        }
    }
    half.sort_unstable();
    let mut corners = UnionFind::new(3 * nf); // corner 3f + k
    let corner =
        |f: FaceId, v: VertexId| 3 * f + mesh.faces[f].iter().position(|&w| w == v).unwrap_or(0);
    let mut edges = 0usize;
    let mut boundary = 0usize;
    let mut boundary_example = None;
    let mut non_manifold_edges = Vec::new();
    let mut inconsistent = Vec::new();
    let mut on_bad_edge = vec![false; nv];
    let mut start = 0;
    while start < half.len() {
        let (a, b, _, _) = half[start];
        let mut end = start + 1;
        while end < half.len() && half[end].0 == a && half[end].1 == b {
            end += 1;
        }
        edges += 1;
        let group = &half[start..end];
        // Direction of a half-edge: true when the face runs a → b (from the smaller index).
        let forward =
            |&(_, _, f, e): &(VertexId, VertexId, FaceId, u8)| mesh.faces[f][e as usize] == a;
        match group.len() {
            1 => {
                boundary += 1;
                if boundary_example.is_none() {
                    let (f, e) = (group[0].2, group[0].3 as usize);
                    boundary_example = Some((mesh.faces[f][e], mesh.faces[f][(e + 1) % 3]));
                }
            }
            2 => {
                let (f, g) = (group[0].2, group[1].2);
                if forward(&group[0]) == forward(&group[1]) {
                    let (p, q) = if forward(&group[0]) { (a, b) } else { (b, a) };
                    inconsistent.push((f.min(g), f.max(g), p, q));
                }
                corners.union(corner(f, a), corner(g, a));
                corners.union(corner(f, b), corner(g, b));
            }
            n => {
                non_manifold_edges.push((a, b, n));
                on_bad_edge[a] = true;
                on_bad_edge[b] = true;
            }
        }
        start = end;
    }
    let edge_manifold = non_manifold_edges.is_empty();
    if !edge_manifold {
        issues.push(MeshIssue::NonManifoldEdges {
            edges: non_manifold_edges,
        });
    }

    // Vertex fans: corners of one vertex joined across two-face edges; more than one group is a pinch.
    // Vertices on a non-manifold edge are already reported there.
    let mut vertex_fans: Vec<(VertexId, usize)> = Vec::with_capacity(3 * nf);
    for f in (0..nf).filter(|&f| valid[f]) {
        for k in 0..3 {
            vertex_fans.push((mesh.faces[f][k], corners.root(3 * f + k)));
        }
    }
    vertex_fans.sort_unstable();
    vertex_fans.dedup();
    let mut pinched = Vec::new();
    let mut referenced = vec![false; nv];
    let mut i = 0;
    while i < vertex_fans.len() {
        let v = vertex_fans[i].0;
        let mut j = i + 1;
        while j < vertex_fans.len() && vertex_fans[j].0 == v {
            j += 1;
        }
        referenced[v] = true;
        if j - i > 1 && !on_bad_edge[v] {
            pinched.push((v, j - i));
        }
        i = j;
    }
    let vertex_manifold = pinched.is_empty();
    if !vertex_manifold {
        issues.push(MeshIssue::NonManifoldVertices { vertices: pinched });
    }
    let oriented = inconsistent.is_empty();
    if !oriented {
        issues.push(MeshIssue::InconsistentOrientation {
            pairs: inconsistent,
        });
    }
    let closed = nf > 0 && boundary == 0;
    if let Some(example) = boundary_example {
        issues.push(MeshIssue::Open {
            boundary_edges: boundary,
            example,
        });
    }

    // Components through shared vertices.
    let mut verts = UnionFind::new(nv);
    for f in (0..nf).filter(|&f| valid[f]) {
        let [a, b, c] = mesh.faces[f];
        verts.union(a, b);
        verts.union(a, c);
    }
    let mut component_of = vec![usize::MAX; nv];
    let mut components = 0;
    for v in (0..nv).filter(|&v| referenced[v]) {
        let r = verts.root(v);
        if component_of[r] == usize::MAX {
            component_of[r] = components;
            components += 1;
        }
        component_of[v] = component_of[r];
    }
    let mut comp_faces = vec![0usize; components];
    let mut comp_chi = vec![0i64; components];
    let mut comp_volume = vec![0.0; components];
    for v in (0..nv).filter(|&v| referenced[v]) {
        comp_chi[component_of[v]] += 1;
    }
    for f in (0..nf).filter(|&f| valid[f]) {
        let [a, b, c] = mesh.faces[f];
        let comp = component_of[a];
        comp_faces[comp] += 1;
        comp_chi[comp] += 1;
        let (pa, pb, pc) = (mesh.positions[a], mesh.positions[b], mesh.positions[c]);
        comp_volume[comp] += pa.dot(&pb.cross(&pc)) / 6.0;
    }
    let mut s = 0;
    while s < half.len() {
        let (a, b, _, _) = half[s];
        while s < half.len() && half[s].0 == a && half[s].1 == b {
            s += 1;
        }
        comp_chi[component_of[a]] -= 1;
    }
    if components > 1 {
        issues.push(MeshIssue::Components {
            faces: comp_faces.clone(),
        });
    }
    let unreferenced: Vec<VertexId> = (0..nv).filter(|&v| !referenced[v]).collect();
    if !unreferenced.is_empty() {
        issues.push(MeshIssue::Unreferenced {
            vertices: unreferenced,
        });
    }

    let manifold = edge_manifold && vertex_manifold && valid.iter().all(|&ok| ok);
    let clean_shell = closed && manifold && oriented;
    let genus = clean_shell.then(|| comp_chi.iter().map(|chi| (2 - chi) / 2).sum());
    let all_finite = non_finite.is_empty();
    let orientation = if clean_shell && all_finite {
        if comp_volume.iter().all(|&v| v > 0.0) {
            Orientation::Outward
        } else if comp_volume.iter().all(|&v| v < 0.0) {
            Orientation::Inward
        } else {
            Orientation::Unknown
        }
    } else {
        Orientation::Unknown
    };
    let volume = (clean_shell && all_finite).then(|| comp_volume.iter().map(|v| v.abs()).sum());

    let bounding_box = mesh
        .positions
        .iter()
        .zip(&finite)
        .filter(|&(_, &ok)| ok)
        .map(|(p, _)| *p)
        .fold(None, |acc: Option<(Vec3, Vec3)>, p| match acc {
            None => Some((p, p)),
            Some((lo, hi)) => Some((lo.inf(&p), hi.sup(&p))),
        })
        .map(|(lo, hi)| BoundingBox {
            min: [lo.x, lo.y, lo.z],
            max: [hi.x, hi.y, hi.z],
        });

    let problems = issues.iter().map(ToString::to_string).collect();
    MeshReport {
        vertices: nv,
        faces: nf,
        edges,
        closed,
        manifold,
        oriented,
        orientation,
        euler_characteristic: comp_chi.iter().sum(),
        genus,
        components,
        area,
        volume,
        bounding_box,
        mean_edge_length: mean_edge,
        problems,
        issues,
    }
}

/// A mesh accepted as a body surface.
#[derive(Clone, Debug)]
pub struct BodySurface {
    /// The surface: closed, consistently oriented outward, one component, 2-manifold, finite, without
    /// degenerate faces or unused vertices.
    pub mesh: TriMesh,
    /// Its connectivity.
    pub topology: Topology,
    /// `#V` of the input: the new index of each input vertex (`None` for a removed unreferenced vertex).
    pub vertex_map: Vec<Option<VertexId>>,
    /// Whether the faces were flipped from inward to outward.
    pub flipped: bool,
    /// What was repaired, for the user.
    pub warnings: Vec<String>,
}

/// Accepts a mesh as a body surface, or names the first reason it cannot be one.
///
/// Requires a closed, consistently oriented, single-component 2-manifold with finite coordinates and no
/// degenerate faces. Repairs, with a warning each: an inward orientation (faces flipped) and unreferenced
/// vertices (removed; see [`BodySurface::vertex_map`]). Face order is kept.
pub fn body_surface(mesh: TriMesh, params: &MeshCheckParams) -> Result<BodySurface, MeshIssue> {
    let report = mesh_report(&mesh, params);
    if let Some(issue) = report.first_blocking() {
        return Err(issue.clone());
    }
    let mut mesh = mesh;
    let mut warnings = Vec::new();
    let nv = mesh.num_vertices();
    let mut vertex_map: Vec<Option<VertexId>> = (0..nv).map(Some).collect();
    if let Some(issue @ MeshIssue::Unreferenced { vertices }) = report
        .issues
        .iter()
        .find(|i| matches!(i, MeshIssue::Unreferenced { .. }))
    {
        warnings.push(format!("removed unused vertices: {issue}"));
        let mut used = vec![true; nv];
        for &v in vertices {
            used[v] = false;
        }
        let mut next = 0;
        for v in 0..nv {
            vertex_map[v] = used[v].then(|| {
                next += 1;
                next - 1
            });
        }
        mesh.positions = (0..nv)
            .filter(|&v| used[v])
            .map(|v| mesh.positions[v])
            .collect();
        for face in &mut mesh.faces {
            for v in face.iter_mut() {
                *v = vertex_map[*v].expect("faces use only referenced vertices");
            }
        }
    }
    let flipped = match report.orientation {
        Orientation::Outward => false,
        Orientation::Inward => {
            mesh.flip_orientation();
            warnings.push(format!(
                "the surface was oriented inward (signed volume −{:.6} m³); every face was flipped to face outward",
                report.volume.unwrap_or(0.0)
            ));
            true
        }
        Orientation::Unknown => {
            return Err(MeshIssue::NoInside {
                volume: mesh.signed_volume(),
            });
        }
    };
    let topology = Topology::new(mesh.num_vertices(), &mesh.faces).map_err(MeshIssue::Topology)?;
    Ok(BodySurface {
        mesh,
        topology,
        vertex_map,
        flipped,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::read_mesh;
    use crate::test_meshes;

    fn octahedron() -> TriMesh {
        let mut m = test_meshes::octahedron();
        m.face_groups.clear();
        m.group_names.clear();
        m
    }

    fn report(m: &TriMesh) -> MeshReport {
        mesh_report(m, &MeshCheckParams::default())
    }

    /// A torus as an `n × m` grid of quads split into triangles, outward oriented.
    fn torus(n: usize, m: usize) -> TriMesh {
        let (big, small) = (1.0, 0.3);
        let mut positions = Vec::new();
        for i in 0..n {
            for j in 0..m {
                let u = std::f64::consts::TAU * i as f64 / n as f64;
                let v = std::f64::consts::TAU * j as f64 / m as f64;
                let r = big + small * v.cos();
                positions.push(Vec3::new(r * u.cos(), r * u.sin(), small * v.sin()));
            }
        }
        let id = |i: usize, j: usize| (i % n) * m + (j % m);
        let mut faces = Vec::new();
        for i in 0..n {
            for j in 0..m {
                faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        TriMesh::new(positions, faces)
    }

    fn only_problem(m: &TriMesh) -> MeshIssue {
        let r = report(m);
        assert_eq!(r.issues.len(), 1, "{:?}", r.problems);
        r.issues[0].clone()
    }

    #[test]
    fn clean_octahedron() {
        let m = octahedron();
        let r = report(&m);
        assert!(r.problems.is_empty(), "{:?}", r.problems);
        assert!(r.closed && r.manifold && r.oriented);
        assert_eq!(r.orientation, Orientation::Outward);
        assert_eq!(
            (r.edges, r.euler_characteristic, r.genus, r.components),
            (12, 2, Some(0), 1)
        );
        assert!((r.volume.unwrap() - m.signed_volume()).abs() < 1e-15);
        assert!((r.area - m.area()).abs() < 1e-15);
        let b = body_surface(m.clone(), &MeshCheckParams::default()).unwrap();
        assert!(!b.flipped && b.warnings.is_empty());
        assert_eq!(b.mesh, m);
        assert!(b.topology.is_closed());
    }

    #[test]
    fn torus_has_genus_one_at_several_sizes() {
        for (n, m) in [(6, 4), (12, 8), (30, 17)] {
            let r = report(&torus(n, m));
            assert!(r.problems.is_empty(), "{:?}", r.problems);
            assert_eq!(r.euler_characteristic, 0);
            assert_eq!(r.genus, Some(1));
            assert_eq!(r.orientation, Orientation::Outward);
            // A torus is still a usable closed surface, but genus is for the caller to judge.
            assert!(body_surface(torus(n, m), &MeshCheckParams::default()).is_ok());
        }
    }

    #[test]
    fn open_mesh_names_a_boundary_edge() {
        let mut m = octahedron();
        m.faces.pop(); // [0, 3, 5]
        let issue = only_problem(&m);
        assert_eq!(
            issue,
            MeshIssue::Open {
                boundary_edges: 3,
                example: (3, 0)
            }
        );
        assert!(
            issue.to_string().contains("open: 3 boundary edges"),
            "{issue}"
        );
        let r = report(&m);
        assert!(!r.closed && r.manifold && r.genus.is_none() && r.volume.is_none());
        assert_eq!(
            body_surface(m, &MeshCheckParams::default()).unwrap_err(),
            issue
        );
    }

    #[test]
    fn non_manifold_edge_names_its_vertices_and_face_count() {
        let mut m = octahedron();
        m.positions.push(Vec3::new(0.3, 0.3, 0.3));
        m.faces.push([0, 2, 6]); // a fin on edge (0, 2)
        let r = report(&m);
        assert!(!r.manifold);
        assert_eq!(
            r.issues[0],
            MeshIssue::NonManifoldEdges {
                edges: vec![(0, 2, 3)]
            }
        );
        assert_eq!(
            r.problems[0],
            "edge (0, 2) is shared by 3 faces (non-manifold edge)"
        );
        assert!(body_surface(m, &MeshCheckParams::default()).is_err());
    }

    #[test]
    fn bow_tie_vertex_is_non_manifold() {
        // Two octahedra touching at one vertex: vertex 0 of the first is vertex 1 of the second.
        let a = octahedron();
        let s = a.positions[0].x;
        let mut positions = a.positions.clone();
        let shift = Vec3::new(2.0 * s, 0.0, 0.0);
        let second: Vec<usize> = (0..6)
            .map(|v| {
                if v == 1 {
                    0
                } else {
                    positions.len() + v - usize::from(v > 1)
                }
            })
            .collect();
        for v in (0..6).filter(|&v| v != 1) {
            positions.push(a.positions[v] + shift);
        }
        let mut faces = a.faces.clone();
        faces.extend(a.faces.iter().map(|f| f.map(|v| second[v])));
        let m = TriMesh::new(positions, faces);
        let issue = only_problem(&m);
        assert_eq!(
            issue,
            MeshIssue::NonManifoldVertices {
                vertices: vec![(0, 2)]
            }
        );
        assert_eq!(
            issue.to_string(),
            "vertex 0 is non-manifold: its faces form 2 separate fans"
        );
        let r = report(&m);
        assert!(r.closed && !r.manifold && r.genus.is_none());
        assert_eq!(r.components, 1);
    }

    #[test]
    fn flipped_face_is_named() {
        let mut m = octahedron();
        m.faces[3].swap(1, 2); // [3, 4, 0]
        let r = report(&m);
        assert!(!r.oriented && r.closed && r.manifold);
        assert_eq!(r.orientation, Orientation::Unknown);
        let MeshIssue::InconsistentOrientation { pairs } = &r.issues[0] else {
            panic!("{:?}", r.problems);
        };
        assert_eq!(pairs.len(), 3);
        assert!(pairs.iter().all(|&(f, g, _, _)| f == 3 || g == 3));
        assert!(r.problems[0].contains("faces 0 and 3") || r.problems[0].contains("faces 2 and 3"));
    }

    #[test]
    fn nan_vertex_is_named() {
        let mut m = octahedron();
        m.positions[4].z = Real::NAN;
        let r = report(&m);
        assert_eq!(r.issues[0], MeshIssue::NonFinite { vertices: vec![4] });
        assert_eq!(
            r.problems[0],
            "vertex 4 has a non-finite coordinate (NaN or infinity)"
        );
        assert!(r.area.is_finite() && r.volume.is_none());
        assert!(serde_json::to_string(&r).is_ok());
        assert!(body_surface(m, &MeshCheckParams::default()).is_err());
    }

    #[test]
    fn degenerate_face_is_named() {
        let mut m = octahedron();
        m.positions[4] = (m.positions[0] + m.positions[2]) / 2.0; // face 0 = [0, 2, 4] collinear
        let r = report(&m);
        assert_eq!(
            r.issues[0],
            MeshIssue::Degenerate {
                faces: vec![0],
                ratio: 1e-10
            }
        );
        assert!(
            r.problems[0].starts_with("face 0 is degenerate"),
            "{}",
            r.problems[0]
        );
    }

    #[test]
    fn bad_index_and_repeated_vertex() {
        let mut m = octahedron();
        m.faces[5] = [1, 2, 17];
        m.faces[6] = [3, 3, 5];
        let r = report(&m);
        assert_eq!(
            r.issues[0],
            MeshIssue::BadIndex {
                faces: vec![(5, 17)],
                num_vertices: 6
            }
        );
        assert_eq!(
            r.problems[0],
            "face 5 names vertex 17, but the mesh has 6 vertices"
        );
        assert_eq!(r.problems[1], "face 6 uses vertex 3 twice");
        assert!(!r.manifold);
    }

    #[test]
    fn two_components_are_counted() {
        let a = octahedron();
        let mut m = a.clone();
        m.positions
            .extend(a.positions.iter().map(|p| p + Vec3::new(1.0, 0.0, 0.0)));
        m.faces.extend(a.faces.iter().map(|f| f.map(|v| v + 6)));
        let issue = only_problem(&m);
        assert_eq!(issue, MeshIssue::Components { faces: vec![8, 8] });
        let r = report(&m);
        assert_eq!(
            (r.components, r.genus, r.euler_characteristic),
            (2, Some(0), 4)
        );
        assert!((r.volume.unwrap() - 2.0 * a.signed_volume()).abs() < 1e-15);
        assert!(body_surface(m, &MeshCheckParams::default()).is_err());
    }

    #[test]
    fn inward_mesh_is_flipped_with_a_warning() {
        let mut m = octahedron();
        m.flip_orientation();
        let r = report(&m);
        assert!(r.problems.is_empty());
        assert_eq!(r.orientation, Orientation::Inward);
        assert!(r.volume.unwrap() > 0.0);
        let b = body_surface(m, &MeshCheckParams::default()).unwrap();
        assert!(b.flipped);
        assert!(b.mesh.signed_volume() > 0.0);
        assert_eq!(b.warnings.len(), 1);
        assert!(b.warnings[0].contains("inward"), "{}", b.warnings[0]);
    }

    #[test]
    fn unreferenced_vertices_are_removed_with_a_map() {
        let a = octahedron();
        let mut m = a.clone();
        m.positions.insert(2, Vec3::new(5.0, 5.0, 5.0));
        m.positions.push(Vec3::new(6.0, 6.0, 6.0));
        for f in &mut m.faces {
            for v in f.iter_mut() {
                if *v >= 2 {
                    *v += 1;
                }
            }
        }
        let r = report(&m);
        assert_eq!(
            r.issues,
            vec![MeshIssue::Unreferenced {
                vertices: vec![2, 7]
            }]
        );
        assert_eq!(r.problems[0], "2 vertices are used by no face: 2, 7");
        let b = body_surface(m, &MeshCheckParams::default()).unwrap();
        assert_eq!(b.mesh, a);
        assert_eq!(
            b.vertex_map,
            vec![
                Some(0),
                Some(1),
                None,
                Some(2),
                Some(3),
                Some(4),
                Some(5),
                None
            ]
        );
        assert!(
            b.warnings[0].contains("2 vertices are used by no face"),
            "{}",
            b.warnings[0]
        );
    }

    #[test]
    fn empty_mesh_is_a_problem_not_a_panic() {
        let r = report(&TriMesh::default());
        assert_eq!(r.issues[0], MeshIssue::Empty);
        assert!(!r.closed && r.bounding_box.is_none());
        assert!(body_surface(TriMesh::default(), &MeshCheckParams::default()).is_err());
    }

    #[test]
    fn many_problems_of_one_kind_list_five() {
        let mut m = octahedron();
        for _ in 0..8 {
            m.positions.push(Vec3::zeros());
        }
        let r = report(&m);
        assert_eq!(
            r.problems[0],
            "8 vertices are used by no face: 6, 7, 8, 9, 10 and 3 more"
        );
    }

    #[test]
    fn regular_1k_is_a_genus_zero_body() {
        let m = read_mesh(&test_meshes::body("regular_1k.obj")).unwrap();
        let r = report(&m);
        assert!(r.problems.is_empty(), "{:?}", r.problems);
        assert!(r.closed && r.manifold && r.oriented);
        assert_eq!((r.vertices, r.faces), (1229, 2030 + 2 * 212));
        assert_eq!((r.genus, r.components), (Some(0), 1));
        assert_eq!(r.orientation, Orientation::Outward);
        let v = r.volume.unwrap();
        assert!((v - 0.0470).abs() < 0.01 * 0.0470, "volume {v}");
    }

    #[test]
    fn all_twenty_bodies_pass_the_body_check() {
        let mut n = 0;
        for shape in ["regular", "male", "athletic", "overweight", "kid"] {
            for res in ["370", "600", "1k", "12k"] {
                let m = read_mesh(&test_meshes::body(&format!("{shape}_{res}.obj"))).unwrap();
                let b = body_surface(m, &MeshCheckParams::default())
                    .unwrap_or_else(|e| panic!("{shape}_{res}: {e}"));
                assert!(!b.flipped && b.warnings.is_empty(), "{shape}_{res}");
                n += 1;
            }
        }
        assert_eq!(n, 20);
    }
}
