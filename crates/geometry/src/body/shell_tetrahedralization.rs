//! Shell tetrahedralization of a closed body surface: a few layers of tetrahedra between the body surface and
//! an inward offset of it, the offset surface forming the fixed core (thesis ch. 5: soft tissue over bone).
//!
//! # Construction
//! 1. Per-vertex inward directions `−n_v`, `n_v` the angle-weighted vertex normal, nudged where needed so
//!    that `n_v · N_f > 0` for every incident face normal `N_f` (this makes every prism tetrahedron positive
//!    for a small enough thickness).
//! 2. A local thickness `h_v ≤ thickness`, capped
//!    - where the body is thin: `h_v ≤ thin_fraction · d_v`, `d_v` the distance along `−n_v` to the first
//!      other wall of the surface (ray cast on a uniform grid);
//!    - where neighbouring inward directions converge (convex, high curvature spots): for every edge `(u, v)`
//!      with `δ = (n_v − n_u) · (x_v − x_u) > 0`, offsetting both ends by `h` shortens the edge's projection by
//!      `h δ / |x_v − x_u|²` of its length, so `h ≤ convergence_fraction · |x_v − x_u|² / δ`;
//!    - then smoothed (`h_v ← min(cap_v, (h_v + mean of the neighbours) / 2)`, repeated) and made
//!      Lipschitz (`h_v ≤ h_u + slope · |x_v − x_u|`) so the inner surface has no steps.
//! 3. Layer `k = 0..=L` holds the points `x_v − (k/L) h_v n_v`; layer 0 is the input surface itself, with the
//!    same vertex ids `0..#V`, layer `k` uses ids `k·#V + v`.
//! 4. Each surface triangle × layer is a prism, split into three tetrahedra by the staircase rule on the
//!    triangle's vertices sorted in one global vertex order `s0 < s1 < s2` (least visible vertex first, see
//!    the code): `{s0 s1 s2 s2'}`, `{s0 s1 s2' s1'}`, `{s0 s1' s2' s0'}`
//!    (primes: the next layer inward). On the quadrilateral side over edge `(u, v)`, `u < v`, the diagonal then
//!    always joins `u` on the outer layer to `v` on the inner one, whichever prism it belongs to, so
//!    neighbouring prisms conform. Orientation is fixed on a reference prism, independently of the geometry.
//! 5. Repair: layer points of inverted tetrahedra are untangled (over-relaxed cyclic projection onto the
//!    half-spaces that keep their tetrahedra positive; the input surface never moves); while some tetrahedron stays inverted or the inner
//!    surface crosses itself, the thickness at the vertices involved shrinks (×`shrink`) and the layers are
//!    rebuilt. Tetrahedra below `min_quality` are only counted (`flat`): shrinking makes them flatter.
//!
//! Known limitation: at a few fold vertices of the real bodies (crotch, toes) inverted tetrahedra can remain,
//! and the function then returns [`ShellError::Inverted`].
//!
//! The inner-layer vertices are fixed. The tetrahedral mesh's outer boundary is the input surface, vertex for
//! vertex and face for face; [`ShellReport::surface_preserved`] checks that on the extracted boundary.

use crate::body::tet_boundary::{canonical_face, outer_boundary_surface};
use crate::body::tet_mesh::{TetMesh, tet_signed_volume};
use crate::math::{Real, Vec3, VertexId};
use crate::mesh::TriMesh;
use crate::mesh::self_intersection::{mean_edge_length, self_intersections};
use crate::mesh::topology::{Topology, TopologyError};
use crate::mesh::triangle_grid::TriangleGrid;
use crate::mesh::triangle_intersection::segment_triangle;

/// Settings of the shell tetrahedralization. Lengths in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct ShellParams {
    /// Largest shell thickness (m), used wherever the body is thick and smooth enough.
    pub thickness: Real,
    /// Number of tetrahedral layers through the thickness (≥ 1).
    pub layers: usize,
    /// Thickness cap as a fraction of the distance to the opposite wall along the inward normal, in (0, 0.5).
    pub thin_fraction: Real,
    /// Largest fraction by which an edge's length may shrink at the inner surface, in (0, 1).
    pub convergence_fraction: Real,
    /// Smoothing passes over the thickness field.
    pub smoothing_iterations: usize,
    /// Largest thickness slope |∇h| (dimensionless) after smoothing.
    pub max_slope: Real,
    /// Tetrahedra below this mean-ratio quality count as too flat and trigger a local thickness reduction.
    pub min_quality: Real,
    /// Factor in (0, 1) applied to the local thickness at each repair.
    pub shrink: Real,
    /// Floor of the local thickness, as a fraction of `thickness`; repairs stop there.
    pub min_thickness_fraction: Real,
    /// Most repair rounds.
    pub max_repairs: usize,
    /// Sweeps of local untangling (moving layer points of inverted tetrahedra) per repair round.
    pub untangle_sweeps: usize,
}

impl Default for ShellParams {
    fn default() -> Self {
        Self {
            thickness: 0.02,
            layers: 2,
            thin_fraction: 0.4,
            convergence_fraction: 0.5,
            smoothing_iterations: 8,
            max_slope: 0.5,
            min_quality: 0.02,
            shrink: 0.6,
            min_thickness_fraction: 0.002,
            max_repairs: 40,
            untangle_sweeps: 20,
        }
    }
}

/// The statistics of a shell tetrahedralization.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ShellReport {
    /// Number of tetrahedra.
    pub tets: usize,
    /// Number of vertices (surface vertices × (layers + 1), less the layer points of pinched vertices).
    pub vertices: usize,
    /// Number of fixed (inner-surface) vertices.
    pub fixed_vertices: usize,
    /// Tetrahedra with signed volume ≤ 0.
    pub inverted: usize,
    /// Smallest signed mean-ratio quality `12 (3V)^(2/3) / Σℓ²` (1 = regular tetrahedron).
    pub min_quality: Real,
    /// Mean mean-ratio quality.
    pub mean_quality: Real,
    /// Whether the extracted outer boundary equals the input surface vertex for vertex and face for face.
    pub surface_preserved: bool,
    /// Smallest local thickness used (m).
    pub thickness_min: Real,
    /// Largest local thickness used (m).
    pub thickness_max: Real,
    /// Crossing pairs of inner-surface triangles, other than those inherited from input crossings.
    pub self_intersections: usize,
    /// Crossing pairs of input-surface triangles (touching or overlapping body parts in the input).
    pub input_self_intersections: usize,
    /// Inner-surface crossings next to input crossings (inherited from the input; not counted above).
    pub inherited_self_intersections: usize,
    /// Repair rounds that were needed.
    pub repairs: usize,
    /// Tetrahedra still below `min_quality` (flat but positive; reported, not fatal).
    pub flat: usize,
    /// Surface vertices at sharp folds or tips where the shell is pinched to zero thickness (the vertex is
    /// part of the fixed core there).
    pub pinched_vertices: usize,
}

/// A body built by [`shell_tetrahedralization`].
#[derive(Clone, Debug)]
pub struct ShellBody {
    /// The tetrahedral mesh; vertices `0..#V` are the input surface's, followed by the layer points
    /// (layer by layer, skipping pinched vertices); `fixed` marks the core (innermost layer and pinched vertices).
    pub mesh: TetMesh,
    /// `#V` local shell thickness (m) per surface vertex.
    pub thickness: Vec<Real>,
    /// `#V` unit outward directions used for the offset.
    pub normals: Vec<Vec3>,
    /// Statistics.
    pub report: ShellReport,
}

/// Why a shell could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShellError {
    /// A setting is out of range.
    #[error("shell setting `{name}` = {value} is invalid: {reason}")]
    BadParam {
        name: &'static str,
        value: Real,
        reason: &'static str,
    },
    /// The surface is empty.
    #[error("the surface has no faces")]
    Empty,
    /// A vertex position is NaN or infinite.
    #[error("surface vertex {vertex} has a non-finite position")]
    NonFinite { vertex: VertexId },
    /// The faces are not an oriented manifold.
    #[error("the surface is not an oriented manifold: {0}")]
    Topology(#[from] TopologyError),
    /// The surface has holes.
    #[error(
        "the surface is not closed: {count} boundary edges, the first from vertex {a} to vertex {b}"
    )]
    NotClosed {
        count: usize,
        a: VertexId,
        b: VertexId,
    },
    /// A vertex has no usable normal (all its faces degenerate).
    #[error("surface vertex {vertex} has no normal: its faces have zero area")]
    NoNormal { vertex: VertexId },
    /// Repairs reached the thickness floor and tetrahedra stayed inverted.
    #[error(
        "{count} tetrahedra stay inverted after {repairs} repairs (first: tetrahedron {tet} at surface vertex {vertex}, local thickness {thickness:.3e} m)"
    )]
    Inverted {
        count: usize,
        tet: usize,
        vertex: VertexId,
        thickness: Real,
        repairs: usize,
    },
    /// Repairs reached the thickness floor and the inner surface still crosses itself.
    #[error(
        "the inner surface still crosses itself at {count} triangle pairs after {repairs} repairs (first: faces {f} and {g})"
    )]
    SelfIntersecting {
        count: usize,
        f: usize,
        g: usize,
        repairs: usize,
    },
}

fn check_params(p: &ShellParams) -> Result<(), ShellError> {
    let bad = |name, value: Real, reason| {
        Err(ShellError::BadParam {
            name,
            value,
            reason,
        })
    };
    if !(p.thickness.is_finite() && p.thickness > 0.0) {
        return bad(
            "thickness",
            p.thickness,
            "must be a positive length in metres",
        );
    }
    if p.layers == 0 || p.layers > 64 {
        return bad("layers", p.layers as Real, "must be between 1 and 64");
    }
    if !(p.thin_fraction > 0.0 && p.thin_fraction < 0.5) {
        return bad("thin_fraction", p.thin_fraction, "must lie in (0, 0.5)");
    }
    if !(p.convergence_fraction > 0.0 && p.convergence_fraction < 1.0) {
        return bad(
            "convergence_fraction",
            p.convergence_fraction,
            "must lie in (0, 1)",
        );
    }
    if !(p.max_slope.is_finite() && p.max_slope > 0.0) {
        return bad("max_slope", p.max_slope, "must be positive");
    }
    if !(p.min_quality.is_finite() && p.min_quality >= 0.0 && p.min_quality < 1.0) {
        return bad("min_quality", p.min_quality, "must lie in [0, 1)");
    }
    if !(p.shrink > 0.0 && p.shrink < 1.0) {
        return bad("shrink", p.shrink, "must lie in (0, 1)");
    }
    if !(p.min_thickness_fraction > 0.0 && p.min_thickness_fraction < 1.0) {
        return bad(
            "min_thickness_fraction",
            p.min_thickness_fraction,
            "must lie in (0, 1)",
        );
    }
    Ok(())
}

/// Builds a shell of tetrahedra under a closed, outward-oriented surface (see the module notes).
pub fn shell_tetrahedralization(
    surface: &TriMesh,
    params: &ShellParams,
) -> Result<ShellBody, ShellError> {
    check_params(params)?;
    let n = surface.num_vertices();
    let faces = &surface.faces;
    if faces.is_empty() {
        return Err(ShellError::Empty);
    }
    let x = &surface.positions;
    if let Some(v) = x
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
    {
        return Err(ShellError::NonFinite { vertex: v });
    }
    let topo = Topology::new(n, faces)?;
    if !topo.is_closed() {
        let edges = topo.boundary_edges();
        return Err(ShellError::NotClosed {
            count: edges.len(),
            a: edges[0].0,
            b: edges[0].1,
        });
    }

    let normals = vertex_normals(surface, &topo)?;
    // Vertices whose fan no single direction sees from inside (folds, sharp tips): no straight offset makes
    // all their tetrahedra positive at small thickness, so shrinking there does not help; untangling does.
    // Visibility of each vertex's fan from its offset direction: min over incident faces of n_v · N_f.
    let visibility: Vec<Real> = (0..n)
        .map(|v| {
            topo.fan(v)
                .iter()
                .map(|c| {
                    let nf = surface.face_area_normal(c.face);
                    let len = nf.norm();
                    if len > 0.0 {
                        nf.dot(&normals[v]) / len
                    } else {
                        0.0
                    }
                })
                .fold(1.0, Real::min)
        })
        .collect();
    // Shrinking helps only where the vertex and its neighbours are all visible: next to a fold vertex the
    // neighbours' depth is what opens room for the fold vertex's layer points.
    let visible: Vec<bool> = (0..n).map(|v| visibility[v] > 0.05).collect();
    // The global vertex order of the diagonal rule: least visible first. A vertex first in all its prisms
    // is constrained only by planes through its neighbours' layer points, never by the plane of an input
    // face, so untangling can place its layer points even at a fold.
    let mut order: Vec<VertexId> = (0..n).collect();
    order.sort_by(|&a, &b| visibility[a].total_cmp(&visibility[b]).then(a.cmp(&b)));
    let mut rank = vec![0usize; n];
    for (r, &v) in order.iter().enumerate() {
        rank[v] = r;
    }
    let cap = thickness_caps(surface, &topo, &normals, params);
    let mut h = smooth_thickness(surface, &topo, &cap, params);
    // Sharp folds and tips (nose, lips, toe and finger tips at coarse resolutions): no inward direction sees
    // the whole fan, so no offset point gives positive tetrahedra. The shell is pinched there: the vertex's
    // layer points collapse onto it (zero thickness, the vertex joins the fixed core), each prism next to it
    // loses the one tetrahedron on its collapsed vertical edge and stays a conforming pyramid, and the
    // neighbours' thickness ramps up from zero under the slope limit.
    let mut pinched: Vec<bool> = visible.iter().map(|&v| !v).collect();
    for v in 0..n {
        if pinched[v] {
            h[v] = 0.0;
        }
    }
    limit_slope(surface, &mut h, params.max_slope);

    let layers = params.layers;
    let prisms = prism_tets(faces, &rank, layers);
    let mut tets = pinched_tets(&prisms, &pinched);
    let mut positions = vec![Vec3::zeros(); n * (layers + 1)];
    let floor = params.thickness * params.min_thickness_fraction;
    let cell = 2.0 * mean_edge_length(x, faces);
    let inner_faces: Vec<[usize; 3]> = faces.iter().map(|f| f.map(|v| v + layers * n)).collect();
    // Where the input surface already crosses itself (touching body parts), the inner surface inherits the
    // crossing; such pairs (both faces within one vertex ring of an input crossing) are reported apart and
    // not repaired.
    let input_crossings = self_intersections(x, faces, cell);
    let mut near_crossing = vec![false; faces.len()];
    {
        let mut near_vertex = vec![false; n];
        for &(f, g) in &input_crossings {
            for &v in faces[f].iter().chain(faces[g].iter()) {
                near_vertex[v] = true;
                for u in topo.one_ring(v) {
                    near_vertex[u] = true;
                }
            }
        }
        for (f, face) in faces.iter().enumerate() {
            near_crossing[f] = face.iter().any(|&v| near_vertex[v]);
        }
    }
    let mut inherited;

    // Tetrahedra around each vertex (CSR).
    let mut incident = vertex_tets(&tets, positions.len());
    let mut repairs = 0;
    let mut shrink_at = vec![false; n];
    let (inverted_tets, intersections) = loop {
        place_layers(x, &normals, &h, layers, &mut positions);
        // Untangle first: move the layer points (never the input surface) of inverted tetrahedra.
        for _ in 0..params.untangle_sweeps {
            let mut moved = false;
            for tet in &tets {
                let [a, b, c, d] = tet.map(|v| positions[v]);
                if tet_signed_volume(&a, &b, &c, &d) > 0.0 {
                    continue;
                }
                for &p in tet {
                    if p >= n {
                        untangle_point(p, &mut positions, &tets, &incident);
                        moved = true;
                    }
                }
            }
            if !moved {
                break;
            }
        }
        // Tetrahedra that are inverted or too flat, and the surface vertices they touch.
        shrink_at.fill(false);
        let mut inverted_tets = Vec::new();
        let mut any_bad = false;
        for (t, tet) in tets.iter().enumerate() {
            let [a, b, c, d] = tet.map(|v| positions[v]);
            let vol = tet_signed_volume(&a, &b, &c, &d);
            if vol <= 0.0 {
                inverted_tets.push(t);
                for &v in tet {
                    let s = v % n;
                    if h[s] > floor && visible[s] {
                        shrink_at[s] = true;
                        any_bad = true;
                    }
                }
            }
        }
        // The inner surface must not cross itself; only worth testing once the tetrahedra are valid.
        let mut intersections = if inverted_tets.is_empty() {
            self_intersections(&positions, &inner_faces, cell)
        } else {
            Vec::new()
        };
        let before = intersections.len();
        intersections.retain(|&(f, g)| !(near_crossing[f] && near_crossing[g]));
        inherited = before - intersections.len();
        // Crossings next to a pinch or at the thickness floor: pinch those vertices too.
        let mut newly_pinched = false;
        for &(f, g) in &intersections {
            for &v in faces[f].iter().chain(faces[g].iter()) {
                if h[v] > floor {
                    shrink_at[v] = true;
                    any_bad = true;
                } else if !pinched[v] && !closes_pinched_face(&topo, faces, &pinched, v) {
                    pinched[v] = true;
                    h[v] = 0.0;
                    newly_pinched = true;
                    any_bad = true;
                }
            }
        }
        if newly_pinched {
            tets = pinched_tets(&prisms, &pinched);
            incident = vertex_tets(&tets, positions.len());
        }
        let done = inverted_tets.is_empty() && intersections.is_empty();
        if done || !any_bad || repairs >= params.max_repairs {
            break (inverted_tets, intersections);
        }
        repairs += 1;
        for v in 0..n {
            if shrink_at[v] {
                h[v] = (h[v] * params.shrink).max(floor);
            }
        }
        limit_slope(surface, &mut h, params.max_slope);
    };
    if let Some(&t) = inverted_tets.first() {
        let vertex = tets[t][0] % n;
        return Err(ShellError::Inverted {
            count: inverted_tets.len(),
            tet: t,
            vertex,
            thickness: h[vertex],
            repairs,
        });
    }
    if let Some(&(f, g)) = intersections.first() {
        return Err(ShellError::SelfIntersecting {
            count: intersections.len(),
            f,
            g,
            repairs,
        });
    }

    // Drop the layer points of pinched vertices (no tetrahedron uses them); surface ids 0..#V stay.
    let mut used = vec![false; positions.len()];
    for t in &tets {
        for &v in t {
            used[v] = true;
        }
    }
    let mut new_id = vec![usize::MAX; positions.len()];
    let mut kept_positions = Vec::with_capacity(positions.len());
    let mut fixed = Vec::with_capacity(positions.len());
    for (p, &u) in used.iter().enumerate() {
        if u || p < n {
            new_id[p] = kept_positions.len();
            kept_positions.push(positions[p]);
            // The innermost layer is the fixed core; a pinched surface vertex belongs to it too.
            fixed.push(p >= layers * n || (p < n && pinched[p]));
        }
    }
    let tets = tets.into_iter().map(|t| t.map(|v| new_id[v])).collect();
    let mesh = TetMesh {
        positions: kept_positions,
        tets,
        fixed,
    };
    let stats = mesh.quality_stats();
    let flat = mesh
        .qualities()
        .iter()
        .filter(|&&q| q < params.min_quality)
        .count();
    let report = ShellReport {
        tets: mesh.num_tets(),
        vertices: mesh.num_vertices(),
        fixed_vertices: mesh.num_fixed(),
        inverted: stats.inverted,
        min_quality: stats.min,
        mean_quality: stats.mean,
        surface_preserved: surface_preserved(&mesh, surface),
        thickness_min: h.iter().cloned().fold(Real::INFINITY, Real::min),
        thickness_max: h.iter().cloned().fold(0.0, Real::max),
        self_intersections: intersections.len(),
        input_self_intersections: input_crossings.len(),
        inherited_self_intersections: inherited,
        repairs,
        flat,
        pinched_vertices: pinched.iter().filter(|&&p| p).count(),
    };
    Ok(ShellBody {
        mesh,
        thickness: h,
        normals,
        report,
    })
}

/// Whether the outer boundary of `mesh` is exactly `surface`: the same vertex ids `0..#V` with bit-identical
/// positions, and the same oriented faces (as a set; face order and the rotation of each face may differ).
pub fn surface_preserved(mesh: &TetMesh, surface: &TriMesh) -> bool {
    let Ok(outer) = outer_boundary_surface(mesh) else {
        return false;
    };
    let n = surface.num_vertices();
    if outer.tet_vertex.len() != n || outer.tet_vertex.iter().enumerate().any(|(i, &v)| i != v) {
        return false;
    }
    if (0..n).any(|v| outer.mesh.positions[v] != surface.positions[v]) {
        return false;
    }
    if outer.mesh.num_faces() != surface.num_faces() {
        return false;
    }
    let mut a: Vec<[usize; 3]> = outer
        .mesh
        .faces
        .iter()
        .map(|&f| canonical_face(f))
        .collect();
    let mut b: Vec<[usize; 3]> = surface.faces.iter().map(|&f| canonical_face(f)).collect();
    a.sort_unstable();
    b.sort_unstable();
    a == b
}

/// Unit angle-weighted vertex normals (outward), then adjusted so that each has a positive component along
/// every incident face normal where that is possible.
fn vertex_normals(surface: &TriMesh, topo: &Topology) -> Result<Vec<Vec3>, ShellError> {
    let x = &surface.positions;
    let face_normals: Vec<Vec3> = (0..surface.num_faces())
        .map(|f| {
            let n = surface.face_area_normal(f);
            let len = n.norm();
            if len > 0.0 { n / len } else { Vec3::zeros() }
        })
        .collect();
    let mut normals = vec![Vec3::zeros(); surface.num_vertices()];
    for (f, face) in surface.faces.iter().enumerate() {
        for c in 0..3 {
            let (p, q, r) = (x[face[c]], x[face[(c + 1) % 3]], x[face[(c + 2) % 3]]);
            let (u, w) = (q - p, r - p);
            let angle = u.cross(&w).norm().atan2(u.dot(&w));
            normals[face[c]] += angle * face_normals[f];
        }
    }
    for (v, nv) in normals.iter_mut().enumerate() {
        let len = nv.norm();
        if !(len > 1e-300) {
            return Err(ShellError::NoNormal { vertex: v });
        }
        *nv /= len;
        // Nudge towards the worst incident face normal until every dot product is comfortably positive.
        for _ in 0..200 {
            let worst = topo
                .fan(v)
                .iter()
                .map(|c| face_normals[c.face])
                .min_by(|a, b| a.dot(nv).total_cmp(&b.dot(nv)));
            let Some(worst) = worst else { break };
            if worst.dot(nv) >= 0.2 {
                break;
            }
            let moved = *nv + 0.05 * worst;
            let len = moved.norm();
            if len <= 0.0 {
                break;
            }
            *nv = moved / len;
        }
    }
    Ok(normals)
}

/// Per-vertex thickness caps from thin walls (ray cast) and converging normals.
fn thickness_caps(
    surface: &TriMesh,
    topo: &Topology,
    normals: &[Vec3],
    params: &ShellParams,
) -> Vec<Real> {
    let x = &surface.positions;
    let faces = &surface.faces;
    let mut cap = vec![params.thickness; x.len()];

    // Thin walls: distance along the inward normal to the first face not incident to the vertex.
    let reach = params.thickness / params.thin_fraction;
    let grid = TriangleGrid::new(
        x,
        faces,
        (2.0 * mean_edge_length(x, faces)).max(reach * 0.5),
    );
    let mut seen = Vec::new();
    for v in 0..x.len() {
        let p = x[v];
        let q = p - reach * normals[v];
        let mut best: Real = 1.0;
        let stamp = v as u32 + 1;
        grid.for_each_in_box(&p.inf(&q), &p.sup(&q), &mut seen, stamp, |f| {
            let face = faces[f];
            if face.contains(&v) {
                return;
            }
            if let Some(t) = segment_triangle(&p, &q, &x[face[0]], &x[face[1]], &x[face[2]]) {
                best = best.min(t);
            }
        });
        if best < 1.0 {
            cap[v] = cap[v].min(params.thin_fraction * best * reach);
        }
    }

    // Converging normals over each edge (each undirected edge is met twice; harmless).
    for face in faces {
        for e in 0..3 {
            let (u, v) = (face[e], face[(e + 1) % 3]);
            let d = x[v] - x[u];
            let delta = (normals[v] - normals[u]).dot(&d);
            if delta > 0.0 {
                let limit = params.convergence_fraction * d.norm_squared() / delta;
                cap[u] = cap[u].min(limit);
                cap[v] = cap[v].min(limit);
            }
        }
    }
    let _ = topo;
    cap
}

/// Smooths the thickness under the caps, then limits its slope.
fn smooth_thickness(
    surface: &TriMesh,
    topo: &Topology,
    cap: &[Real],
    params: &ShellParams,
) -> Vec<Real> {
    let n = cap.len();
    let mut h = cap.to_vec();
    let mut next = vec![0.0; n];
    let rings: Vec<Vec<VertexId>> = (0..n).map(|v| topo.one_ring(v)).collect();
    for _ in 0..params.smoothing_iterations {
        for v in 0..n {
            let ring = &rings[v];
            let mean = if ring.is_empty() {
                h[v]
            } else {
                ring.iter().map(|&u| h[u]).sum::<Real>() / ring.len() as Real
            };
            next[v] = cap[v].min(0.5 * (h[v] + mean));
        }
        std::mem::swap(&mut h, &mut next);
    }
    limit_slope(surface, &mut h, params.max_slope);
    h
}

/// Lowers `h` until `h_v ≤ h_u + slope · |x_v − x_u|` over every edge (a few sweeps; it only decreases).
fn limit_slope(surface: &TriMesh, h: &mut [Real], slope: Real) {
    let x = &surface.positions;
    for _ in 0..50 {
        let mut changed = false;
        for face in &surface.faces {
            for e in 0..3 {
                let (u, v) = (face[e], face[(e + 1) % 3]);
                let bound = slope * (x[v] - x[u]).norm();
                if h[v] > h[u] + bound {
                    h[v] = h[u] + bound;
                    changed = true;
                }
                if h[u] > h[v] + bound {
                    h[u] = h[v] + bound;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
}

/// Writes layer `k` (`k = 0..=layers`) at ids `k·#V + v`: `x_v − (k/L) h_v n_v`. Layer 0 is copied exactly.
fn place_layers(x: &[Vec3], normals: &[Vec3], h: &[Real], layers: usize, out: &mut [Vec3]) {
    let n = x.len();
    out[..n].copy_from_slice(x);
    for k in 1..=layers {
        let s = k as Real / layers as Real;
        for v in 0..n {
            out[k * n + v] = x[v] - (s * h[v]) * normals[v];
        }
    }
}

/// Whether pinching `v` would pinch all three corners of one of its faces (such a face would have no
/// tetrahedron under it and drop out of the body's boundary).
fn closes_pinched_face(
    topo: &Topology,
    faces: &[[usize; 3]],
    pinched: &[bool],
    v: VertexId,
) -> bool {
    topo.fan(v)
        .iter()
        .any(|c| faces[c.face].iter().all(|&u| u == v || pinched[u]))
}

/// The prism tetrahedra with the layer points of pinched surface vertices collapsed onto the vertex; the
/// tetrahedron on each collapsed vertical edge (exactly one per prism layer in the staircase split) becomes
/// degenerate and is dropped, leaving a conforming pyramid (or one tetrahedron when two corners collapse).
fn pinched_tets(prisms: &[[usize; 4]], pinched: &[bool]) -> Vec<[usize; 4]> {
    let n = pinched.len();
    let collapse = |p: usize| if pinched[p % n] { p % n } else { p };
    prisms
        .iter()
        .map(|t| t.map(collapse))
        .filter(|t| (0..4).all(|i| (i + 1..4).all(|j| t[i] != t[j])))
        .collect()
}

/// Tetrahedra incident to each vertex: CSR `(offsets (#V + 1), tetrahedron ids)`.
fn vertex_tets(tets: &[[usize; 4]], num_vertices: usize) -> (Vec<usize>, Vec<u32>) {
    let mut offsets = vec![0usize; num_vertices + 1];
    for t in tets {
        for &v in t {
            offsets[v + 1] += 1;
        }
    }
    for i in 0..num_vertices {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut ids = vec![0u32; offsets[num_vertices]];
    for (ti, t) in tets.iter().enumerate() {
        for &v in t {
            ids[fill[v]] = ti as u32;
            fill[v] += 1;
        }
    }
    (offsets, ids)
}

/// Local untangling: moves point `p` so that it lies at least a margin inside every plane that bounds its
/// tetrahedra (the plane of the face opposite `p`; each volume is linear in `p`, positive on the inner side),
/// by over-relaxed cyclic projection onto the violated half-spaces (the relaxation method of Agmon and
/// Motzkin for linear inequalities, which converges when they are feasible). Margins shrink from 10 % of the local edge length to 0; if none is
/// reachable, `p` stays where it was.
fn untangle_point(
    p: usize,
    positions: &mut [Vec3],
    tets: &[[usize; 4]],
    incident: &(Vec<usize>, Vec<u32>),
) {
    let around = &incident.1[incident.0[p]..incident.0[p + 1]];
    if around.is_empty() {
        return;
    }
    let mut scale = 0.0;
    let mut count = 0;
    for &t in around {
        for &v in &tets[t as usize] {
            if v != p {
                scale += (positions[v] - positions[p]).norm();
                count += 1;
            }
        }
    }
    let scale = scale / count.max(1) as Real;
    let saved = positions[p];
    for margin in [0.05, 0.005, 0.0].map(|f| f * scale) {
        positions[p] = saved;
        for _ in 0..200 {
            let mut satisfied = true;
            for &t in around {
                let tet = tets[t as usize];
                let i = tet.iter().position(|&v| v == p).unwrap_or(0);
                let f = crate::body::tet_mesh::TET_FACES[i].map(|c| positions[tet[c]]);
                // Towards growing volume: against the outward normal of the opposite face.
                let g = -(f[1] - f[0]).cross(&(f[2] - f[0]));
                let len = g.norm();
                if !(len > 0.0) {
                    continue;
                }
                let u = g / len;
                let d = (positions[p] - f[0]).dot(&u);
                if d < margin {
                    positions[p] += 1.9 * (margin - d) * u;
                    satisfied = false;
                }
            }
            if satisfied {
                return;
            }
        }
    }
    positions[p] = saved;
}

/// The tetrahedra of every prism (surface triangle × layer), positively oriented on the reference prism.
/// `rank[v]`: position of surface vertex `v` in the global order of the diagonal rule (any total order
/// gives conforming prisms; the vertex index order is `rank[v] = v`).
fn prism_tets(faces: &[[usize; 3]], rank: &[usize], layers: usize) -> Vec<[usize; 4]> {
    let n = rank.len();
    let mut tets = Vec::with_capacity(faces.len() * layers * 3);
    for face in faces {
        // Reference prism: the face's corners at (0,0), (1,0), (0,1), counter-clockwise seen from +z (outside),
        // layer k at height −k.
        let reference = |v: usize, k: usize| {
            let i = face.iter().position(|&w| w == v).unwrap_or(0);
            let xy = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)][i];
            Vec3::new(xy.0, xy.1, -(k as Real))
        };
        let mut s = *face;
        s.sort_unstable_by_key(|&v| rank[v]);
        for k in 0..layers {
            // (surface vertex, layer offset) per tetrahedron corner.
            let staircase = [
                [(s[0], 0), (s[1], 0), (s[2], 0), (s[2], 1)],
                [(s[0], 0), (s[1], 0), (s[2], 1), (s[1], 1)],
                [(s[0], 0), (s[1], 1), (s[2], 1), (s[0], 1)],
            ];
            for corners in staircase {
                let r = corners.map(|(v, dk)| reference(v, k + dk));
                let mut tet = corners.map(|(v, dk)| (k + dk) * n + v);
                if tet_signed_volume(&r[0], &r[1], &r[2], &r[3]) < 0.0 {
                    tet.swap(2, 3);
                }
                tets.push(tet);
            }
        }
    }
    tets
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An icosphere-like closed surface: an octahedron subdivided `levels` times, projected to a sphere.
    pub(crate) fn sphere(radius: Real, levels: usize) -> TriMesh {
        let mut p = vec![
            Vec3::x(),
            -Vec3::x(),
            Vec3::y(),
            -Vec3::y(),
            Vec3::z(),
            -Vec3::z(),
        ];
        let mut f: Vec<[usize; 3]> = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        for _ in 0..levels {
            let mut mid = std::collections::HashMap::new();
            let mut nf = Vec::new();
            for t in &f {
                let mut m = [0; 3];
                for e in 0..3 {
                    let (a, b) = (t[e].min(t[(e + 1) % 3]), t[e].max(t[(e + 1) % 3]));
                    m[e] = *mid.entry((a, b)).or_insert_with(|| {
                        p.push((p[a] + p[b]) / 2.0);
                        p.len() - 1
                    });
                }
                nf.push([t[0], m[0], m[2]]);
                nf.push([t[1], m[1], m[0]]);
                nf.push([t[2], m[2], m[1]]);
                nf.push(m);
            }
            f = nf;
        }
        let p = p.iter().map(|q| q.normalize() * radius).collect();
        TriMesh::new(p, f)
    }

    #[test]
    fn sphere_shell_is_valid_and_preserves_the_surface() {
        for (levels, radius) in [(2usize, 0.1), (3, 0.15), (4, 0.3)] {
            let s = sphere(radius, levels);
            assert!(s.signed_volume() > 0.0);
            let body = shell_tetrahedralization(&s, &ShellParams::default()).unwrap();
            let r = &body.report;
            assert_eq!(r.inverted, 0);
            assert!(r.surface_preserved);
            assert_eq!(r.self_intersections, 0);
            assert_eq!(r.tets, 3 * 2 * s.num_faces());
            assert_eq!(r.vertices, 3 * s.num_vertices());
            assert_eq!(r.fixed_vertices, s.num_vertices());
            assert!(r.min_quality > 0.0);
            body.mesh.validate(0.0).unwrap();
            // A smooth sphere much larger than the shell keeps the full thickness everywhere.
            assert!((r.thickness_max - 0.02).abs() < 1e-12, "{r:?}");
            // The shell volume matches the spherical shell between R and R − h to discretization accuracy.
            let inner = radius - 0.02;
            let exact = 4.0 / 3.0 * std::f64::consts::PI * (radius.powi(3) - inner.powi(3));
            let rel = (body.mesh.volume() - exact).abs() / exact;
            assert!(rel < 0.15, "levels {levels}: volume off by {rel}");
        }
    }

    #[test]
    fn thin_sphere_caps_thickness_at_the_opposite_wall() {
        // Radius 2 cm: the wall is 4 cm across, so the 2 cm shell must shrink to ≤ 0.4 · 4 cm = 1.6 cm (and
        // the convergence cap, |e|²/δ ≈ radius/2, binds even more).
        let s = sphere(0.02, 3);
        let body = shell_tetrahedralization(&s, &ShellParams::default()).unwrap();
        let r = &body.report;
        assert_eq!(r.inverted, 0);
        assert!(r.surface_preserved);
        assert!(r.thickness_max <= 0.4 * 0.04 + 1e-12, "{r:?}");
        assert!(r.thickness_max > 0.0);
        body.mesh.validate(0.0).unwrap();
    }

    #[test]
    fn layers_and_thickness_settings_are_honoured() {
        let s = sphere(0.2, 3);
        for layers in [1usize, 3] {
            let params = ShellParams {
                thickness: 0.01,
                layers,
                ..ShellParams::default()
            };
            let body = shell_tetrahedralization(&s, &params).unwrap();
            assert_eq!(body.report.tets, 3 * layers * s.num_faces());
            assert!(body.report.surface_preserved);
            let n = s.num_vertices();
            // The core lies 1 cm inside.
            for v in 0..n {
                let depth = (body.mesh.positions[v] - body.mesh.positions[layers * n + v]).norm();
                assert!((depth - 0.01).abs() < 1e-12, "depth {depth}");
                assert!(body.mesh.positions[layers * n + v].norm() < 0.2 - 0.009);
            }
        }
    }

    #[test]
    fn open_surface_is_rejected_naming_an_edge() {
        let mut s = sphere(0.1, 1);
        s.faces.pop();
        let err = shell_tetrahedralization(&s, &ShellParams::default()).unwrap_err();
        assert!(
            matches!(err, ShellError::NotClosed { count: 3, .. }),
            "{err}"
        );
        assert!(err.to_string().contains("not closed"));
    }

    #[test]
    fn bad_settings_and_nan_are_rejected() {
        let s = sphere(0.1, 1);
        for params in [
            ShellParams {
                thickness: -1.0,
                ..Default::default()
            },
            ShellParams {
                thickness: Real::NAN,
                ..Default::default()
            },
            ShellParams {
                layers: 0,
                ..Default::default()
            },
        ] {
            assert!(matches!(
                shell_tetrahedralization(&s, &params),
                Err(ShellError::BadParam { .. })
            ));
        }
        let mut nan = s.clone();
        nan.positions[3].x = Real::NAN;
        assert!(matches!(
            shell_tetrahedralization(&nan, &ShellParams::default()),
            Err(ShellError::NonFinite { vertex: 3 })
        ));
        assert!(matches!(
            shell_tetrahedralization(&TriMesh::default(), &ShellParams::default()),
            Err(ShellError::Empty)
        ));
    }

    #[test]
    fn surface_preserved_detects_a_moved_vertex_and_a_flipped_face() {
        let s = sphere(0.1, 2);
        let body = shell_tetrahedralization(&s, &ShellParams::default()).unwrap();
        assert!(surface_preserved(&body.mesh, &s));
        let mut moved = s.clone();
        moved.positions[5].x += 1e-9;
        assert!(!surface_preserved(&body.mesh, &moved));
        let mut flipped = s.clone();
        flipped.faces[0].swap(1, 2);
        assert!(!surface_preserved(&body.mesh, &flipped));
    }

    #[test]
    fn neighbouring_prisms_share_side_diagonals() {
        // Conformity: every interior triangle is shared by exactly two tetrahedra, which the boundary
        // extraction verifies (a mismatched diagonal would leave four extra boundary triangles per quad).
        let s = sphere(0.1, 2);
        let rank: Vec<usize> = (0..s.num_vertices()).rev().collect();
        let tets = prism_tets(&s.faces, &rank, 2);
        let mesh = TetMesh::new(vec![Vec3::zeros(); 3 * s.num_vertices()], tets);
        let b = crate::body::tet_boundary::boundary_surface(&mesh).unwrap();
        assert_eq!(b.mesh.num_faces(), 2 * s.num_faces());
    }
}
