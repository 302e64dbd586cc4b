//! Remeshing of flattened panels into well-shaped pattern triangulations at a target edge length, with every
//! new vertex mapped back onto the body surface.
//!
//! 1. [`BoundarySampling`] (or [`boundary_samples`]) resamples the boundary loops of all panels of a
//!    [`PanelSet`] at the target length, measured in 3D along the cut polylines. Vertices where the border
//!    changes (a seam starts or ends) and where the 3D boundary turns sharply at the scale of half the
//!    target length (its corners, [`RemeshParams::corner_angle`]) are kept. Each seam is resampled
//!    **once**, by its lower-numbered panel, and stored per cut-mesh edge; both panels read the very same
//!    samples (same cut-mesh edge, same parameter, bit for bit), so the remeshed panels match one-to-one along
//!    every seam (see [`sample_key`]).
//! 2. [`pattern_remesh`] triangulates one flattened panel: the 2D images of its boundary samples become the
//!    constraint loops of a constrained Delaunay triangulation (spade) refined to a minimum angle and a maximum
//!    area (equilateral triangle of the target edge length), without splitting boundary edges.
//!    [`remesh_panels`] does this for all panels and refines the shared boundary sampling wherever the
//!    refinement needs a boundary split, until the angle bound holds everywhere.
//! 3. Every interior vertex is located in the flattened source triangles (uniform grid; a point just outside
//!    the flattened panel, behind a boundary chord across a concave stretch, takes the nearest point of the
//!    nearest triangle) and carried to the body by the barycentric coordinates of its source triangle,
//!    composed with the panel's [`FaceOrigin`](crate::plane_cut::FaceOrigin) map; boundary vertices use their
//!    polyline parameter.

use std::collections::{HashMap, HashSet};

use spade::{
    AngleLimit, ConstrainedDelaunayTriangulation, Point2, RefinementParameters, Triangulation,
};

use crate::lscm::signed_area;
use crate::math::{Real, Vec2, Vec3, VertexId};
use crate::plane_cut::{Border, MeshPoint, Panel, PanelSet};

/// Settings of the boundary resampling and remeshing.
#[derive(Clone, Copy, Debug)]
pub struct RemeshParams {
    /// Target edge length of the pattern mesh (m), on the boundary and inside.
    pub target_edge_length: Real,
    /// Smallest corner angle the refinement aims for (rad). Spade terminates reliably up to about 30°.
    pub min_angle: Real,
    /// A boundary vertex is kept as a corner when the 3D boundary turns by more than this angle there (rad),
    /// measured between the chords to the points half a target edge length back and ahead, and more than
    /// at any other vertex that close.
    pub corner_angle: Real,
    /// Safety cap on the number of vertices the refinement may add.
    pub max_added_vertices: usize,
    /// Rounds of boundary refinement in [`remesh_panels`] before the boundary is frozen.
    pub max_boundary_rounds: usize,
    /// A boundary segment shorter than this fraction of `target_edge_length` (3D, dimensionless, in
    /// `(0, 1]`) is not split again in [`remesh_panels`]. Next to a boundary corner sharper than
    /// `min_angle` no split can meet the angle bound, and each round halved the segments there again —
    /// down to samples nanometres apart and pattern triangles of zero area (an arm sleeve on a 1k body:
    /// three vertices within 30 nm, a face LSCM refused as degenerate). Default 1/128: small enough that
    /// splits still reach the quality floor next to the pants' and leggings' corners (docs/BENCHMARKS.md,
    /// "The remesh's split floor").
    pub min_split_fraction: Real,
}

impl Default for RemeshParams {
    fn default() -> Self {
        Self {
            target_edge_length: 0.01,
            min_angle: 28f64.to_radians(),
            corner_angle: 35f64.to_radians(),
            max_added_vertices: 500_000,
            max_boundary_rounds: 30,
            min_split_fraction: 0.0078125,
        }
    }
}

/// Why boundaries could not be resampled or a panel remeshed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RemeshError {
    /// A setting is out of range.
    #[error("remesh setting '{field}' = {value} is invalid: {problem}")]
    BadParam {
        field: &'static str,
        value: Real,
        problem: &'static str,
    },
    /// The flattening does not have one position per panel vertex.
    #[error("panel '{panel}': {got} flattened positions for {expected} vertices")]
    FlatteningSize {
        panel: String,
        got: usize,
        expected: usize,
    },
    /// The boundary sample list does not match the panel.
    #[error("panel '{panel}': boundary samples {problem}")]
    BadSamples { panel: String, problem: String },
    /// Two boundary samples fall on the same 2D point.
    #[error("panel '{panel}': boundary samples {a} and {b} coincide in the flattened pattern")]
    CoincidentSamples { panel: String, a: usize, b: usize },
    /// The flattened boundary crosses itself.
    #[error(
        "panel '{panel}': the flattened boundary crosses itself or touches another sample near boundary sample {sample}"
    )]
    SelfIntersection { panel: String, sample: usize },
    /// The triangulation failed (non-finite positions).
    #[error("panel '{panel}': triangulation failed: {problem}")]
    Triangulation { panel: String, problem: String },
    /// The boundaries would need more samples than the cap `max_added_vertices` (the edge length is too
    /// small for the panels' size).
    #[error(
        "the panel boundaries would need more than {max} samples at this edge length; use a larger edge length"
    )]
    TooManySamples { max: usize },
}

/// A point on a panel boundary: the point `(1 − t)·from + t·to` on the panel edge `(from, to)` (panel vertex
/// indices, in the orientation the seam was resampled in, not necessarily the loop's). A point at a panel
/// vertex has `from == to` and `t = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundarySample {
    /// Start vertex of the edge (panel index).
    pub from: VertexId,
    /// End vertex of the edge (panel index).
    pub to: VertexId,
    /// Parameter along the edge (dimensionless, in `[0, 1)`).
    pub t: Real,
    /// What lies across the boundary after this sample, following the loop.
    pub border: Border,
}

impl BoundarySample {
    /// Interpolates a per-vertex quantity at the sample.
    fn lerp<T>(&self, values: &[T]) -> T
    where
        T: Copy
            + std::ops::Add<Output = T>
            + std::ops::Sub<Output = T>
            + std::ops::Mul<Real, Output = T>,
    {
        if self.from == self.to {
            values[self.from]
        } else {
            values[self.from] + (values[self.to] - values[self.from]) * self.t
        }
    }
}

/// A key identifying a boundary sample across panels: cut-mesh vertices of its edge and the parameter bits.
pub type SampleKey = (VertexId, VertexId, u64);

/// The cross-panel key of a sample of `panel`.
pub fn sample_key(panel: &Panel, s: &BoundarySample) -> SampleKey {
    (
        panel.cut_vertex[s.from],
        panel.cut_vertex[s.to],
        s.t.to_bits(),
    )
}

fn check_params(p: &RemeshParams) -> Result<(), RemeshError> {
    let bad = |field, value, problem| {
        Err(RemeshError::BadParam {
            field,
            value,
            problem,
        })
    };
    if !(p.target_edge_length.is_finite() && p.target_edge_length > 0.0) {
        return bad(
            "target_edge_length",
            p.target_edge_length,
            "must be a positive length in metres",
        );
    }
    if !(p.min_angle >= 0.0 && p.min_angle <= 34f64.to_radians()) {
        return bad(
            "min_angle",
            p.min_angle,
            "must be between 0 and 34° (in radians); refinement beyond does not terminate",
        );
    }
    if !(p.corner_angle.is_finite() && p.corner_angle >= 0.0) {
        return bad(
            "corner_angle",
            p.corner_angle,
            "must be a non-negative angle in radians",
        );
    }
    if !(p.min_split_fraction > 0.0 && p.min_split_fraction <= 1.0) {
        return bad(
            "min_split_fraction",
            p.min_split_fraction,
            "must lie in (0, 1]: a fraction of the target edge length",
        );
    }
    Ok(())
}

/// The shared boundary resampling of all panels of a [`PanelSet`].
///
/// Samples are stored once per cut-mesh edge, as parameters `t` from the edge's lower-numbered cut vertex to
/// its higher-numbered one, plus the set of cut vertices kept as samples. Both panels along a seam read the
/// same storage, so their samples are identical bit for bit.
#[derive(Clone, Debug)]
pub struct BoundarySampling {
    /// Cut-mesh vertices that are samples themselves (corners, seam ends).
    kept: HashSet<VertexId>,
    /// Sorted interior sample parameters per undirected cut-mesh edge `(lo, hi)`, measured from `lo`.
    edge_ts: HashMap<(VertexId, VertexId), Vec<Real>>,
}

/// Where a sample lies along a loop: loop edge index and parameter along the loop direction.
type LoopPos = (usize, Real);

/// The point at 3D arc length `r` (m) from vertex `i` of the closed polyline `loop_` (positions `pos`)
/// walking in direction `dir` (±1), or the first vertex with `stop[j]` set, or the vertex after a full turn,
/// whichever comes first.
fn walk(pos: &[Vec3], loop_: &[VertexId], stop: &[bool], i: usize, dir: isize, r: Real) -> Vec3 {
    let n = loop_.len();
    let step = |j: usize| (j as isize + dir).rem_euclid(n as isize) as usize;
    let (mut j, mut walked) = (i, 0.0);
    for _ in 0..n {
        let k = step(j);
        let (a, b) = (pos[loop_[j]], pos[loop_[k]]);
        let len = (b - a).norm();
        if walked + len >= r && len > 0.0 {
            return a + (b - a) * ((r - walked) / len);
        }
        walked += len;
        j = k;
        if stop[j] || j == i {
            break;
        }
    }
    pos[loop_[j]]
}

/// The corners of the closed boundary polyline `loop_` (vertex ids into `pos`, m): vertices where the
/// polyline turns by more than `acos(cos_corner)` *at the scale `r`* (m), and more than any other vertex
/// within arc length `r` of it. The turn at a vertex is the angle between the chords to the points `r` back
/// and `r` ahead along the polyline (clamped at the `stop` vertices — where the border changes — which are
/// kept anyway). Measured between consecutive polyline edges instead, a cut line that wanders a few
/// millimetres in a crease of the body (a plane along the gluteal cleft) made a "corner" every 2 mm, and the
/// pattern millimetre triangles; at half the cloth edge length only what the cloth can resolve counts.
/// Ties go to the lower vertex id, so both sides of a seam choose alike.
fn corners(
    pos: &[Vec3],
    loop_: &[VertexId],
    stop: &[bool],
    r: Real,
    cos_corner: Real,
) -> Vec<usize> {
    let n = loop_.len();
    let turn: Vec<Real> = (0..n)
        .map(|i| {
            if stop[i] {
                return Real::NEG_INFINITY;
            }
            let v = pos[loop_[i]];
            let back = walk(pos, loop_, stop, i, -1, r);
            let ahead = walk(pos, loop_, stop, i, 1, r);
            let (a, b) = (v - back, ahead - v);
            let (na, nb) = (a.norm(), b.norm());
            if na <= 0.0 || nb <= 0.0 {
                return Real::NEG_INFINITY;
            }
            // 1 − cos of the turn: grows with the turn, no acos needed.
            1.0 - a.dot(&b) / (na * nb)
        })
        .collect();
    let stronger =
        |j: usize, i: usize| turn[j] > turn[i] || (turn[j] == turn[i] && loop_[j] < loop_[i]);
    (0..n)
        .filter(|&i| turn[i] > 1.0 - cos_corner)
        .filter(|&i| {
            // No stronger corner within arc length r either way (the walk stops at border changes).
            for dir in [-1isize, 1] {
                let (mut j, mut walked) = (i, 0.0);
                for _ in 0..n {
                    let k = (j as isize + dir).rem_euclid(n as isize) as usize;
                    walked += (pos[loop_[k]] - pos[loop_[j]]).norm();
                    j = k;
                    if walked > r || stop[j] || j == i {
                        break;
                    }
                    if stronger(j, i) {
                        return false;
                    }
                }
            }
            true
        })
        .collect()
}

fn canonical(a: VertexId, b: VertexId, tau: Real) -> ((VertexId, VertexId), Real) {
    if a < b {
        ((a, b), tau)
    } else {
        ((b, a), 1.0 - tau)
    }
}

impl BoundarySampling {
    /// Resamples the boundary loops of every panel at `params.target_edge_length` (3D arc length), keeping
    /// vertices where the border changes and where the 3D boundary turns by more than `params.corner_angle`.
    /// Each seam piece is resampled once, by its lower-numbered panel.
    pub fn new(set: &PanelSet, params: &RemeshParams) -> Result<Self, RemeshError> {
        check_params(params)?;
        let h = params.target_edge_length;
        let cos_corner = params.corner_angle.cos();

        // Kept vertices, in cut-mesh numbering: border changes and corners, both symmetric between the two
        // sides of a seam (and `kept` is shared, so a vertex kept from one side is kept for both).
        let mut kept: HashSet<VertexId> = HashSet::new();
        for panel in &set.panels {
            for lp in &panel.boundary {
                let n = lp.vertices.len();
                let change: Vec<bool> = (0..n)
                    .map(|i| lp.borders[i] != lp.borders[(i + n - 1) % n])
                    .collect();
                for i in (0..n).filter(|&i| change[i]) {
                    kept.insert(panel.cut_vertex[lp.vertices[i]]);
                }
                // Half a target length, or less on a loop so short that a circle would turn by more
                // than 22.5° over it (a circle of length L turns by 2π r / L over arc length r).
                let p = &panel.mesh.positions;
                let length: Real = (0..n)
                    .map(|i| (p[lp.vertices[(i + 1) % n]] - p[lp.vertices[i]]).norm())
                    .sum();
                let r = (0.5 * h).min(length / 16.0);
                for i in corners(p, &lp.vertices, &change, r, cos_corner) {
                    kept.insert(panel.cut_vertex[lp.vertices[i]]);
                }
            }
        }
        // Loops without any kept vertex keep the one of smallest cut-mesh index (the same from both sides).
        for panel in &set.panels {
            for lp in &panel.boundary {
                if !lp
                    .vertices
                    .iter()
                    .any(|v| kept.contains(&panel.cut_vertex[*v]))
                {
                    let v = lp
                        .vertices
                        .iter()
                        .map(|v| panel.cut_vertex[*v])
                        .min()
                        .expect("non-empty loop");
                    kept.insert(v);
                }
            }
        }

        let mut edge_ts: HashMap<(VertexId, VertexId), Vec<Real>> = HashMap::new();
        // Samples so far: capped by `max_added_vertices` before any is stored.
        let mut sampled = 0usize;
        for (pi, panel) in set.panels.iter().enumerate() {
            let pos = &panel.mesh.positions;
            let cv = &panel.cut_vertex;
            for lp in &panel.boundary {
                let n = lp.vertices.len();
                let start = (0..n)
                    .find(|&i| kept.contains(&cv[lp.vertices[i]]))
                    .expect("every loop has a kept vertex");
                // Pieces between consecutive kept vertices: (first edge index, edge count). Border changes are
                // kept vertices, so each piece has one border.
                let mut pieces = Vec::new();
                let mut i = 0;
                while i < n {
                    let mut len = 1;
                    while i + len < n && !kept.contains(&cv[lp.vertices[(start + i + len) % n]]) {
                        len += 1;
                    }
                    pieces.push(((start + i) % n, len));
                    i += len;
                }
                // A loop needs at least three samples to enclose any area.
                let min_count = 3usize.div_ceil(pieces.len());
                for &(first, len) in &pieces {
                    if matches!(lp.borders[first], Border::Seam { panel: q } if q < pi) {
                        continue; // the lower-numbered panel resampled this seam piece already
                    }
                    let verts: Vec<VertexId> =
                        (0..=len).map(|k| lp.vertices[(first + k) % n]).collect();
                    let mut cum = Vec::with_capacity(len + 1);
                    cum.push(0.0);
                    for k in 0..len {
                        cum.push(cum[k] + (pos[verts[k + 1]] - pos[verts[k]]).norm());
                    }
                    let total = cum[len];
                    let count = ((total / h).round() as usize).max(min_count);
                    sampled = sampled.saturating_add(count);
                    if sampled > params.max_added_vertices {
                        return Err(RemeshError::TooManySamples {
                            max: params.max_added_vertices,
                        });
                    }
                    let mut k = 0;
                    for j in 1..count {
                        let s = total * j as Real / count as Real;
                        while k + 1 < len && cum[k + 1] <= s {
                            k += 1;
                        }
                        let l = cum[k + 1] - cum[k];
                        let tau = if l > 0.0 {
                            ((s - cum[k]) / l).clamp(0.0, 1.0)
                        } else {
                            0.0
                        };
                        if tau <= 0.0 || tau >= 1.0 {
                            // Exactly on a vertex: the vertex itself becomes the sample.
                            let v = if tau <= 0.0 { verts[k] } else { verts[k + 1] };
                            kept.insert(cv[v]);
                            continue;
                        }
                        let (key, t) = canonical(cv[verts[k]], cv[verts[k + 1]], tau);
                        edge_ts.entry(key).or_default().push(t);
                    }
                }
            }
        }
        for ts in edge_ts.values_mut() {
            ts.sort_by(Real::total_cmp);
            ts.dedup();
        }
        Ok(Self { kept, edge_ts })
    }

    /// The samples of every panel, per boundary loop (same order as [`Panel::boundary`]), in loop order.
    pub fn samples(&self, set: &PanelSet) -> Vec<Vec<Vec<BoundarySample>>> {
        set.panels
            .iter()
            .map(|p| {
                (0..p.boundary.len())
                    .map(|l| self.loop_samples(p, l).0)
                    .collect()
            })
            .collect()
    }

    /// Samples of loop `l` of `panel` in loop order, with their loop positions.
    fn loop_samples(&self, panel: &Panel, l: usize) -> (Vec<BoundarySample>, Vec<LoopPos>) {
        let lp = &panel.boundary[l];
        let cv = &panel.cut_vertex;
        let n = lp.vertices.len();
        let start = (0..n)
            .find(|&i| self.kept.contains(&cv[lp.vertices[i]]))
            .unwrap_or(0);
        let mut samples = Vec::new();
        let mut at = Vec::new();
        for k in 0..n {
            let e = (start + k) % n;
            let (a, b) = (lp.vertices[e], lp.vertices[(e + 1) % n]);
            let border = lp.borders[e];
            if self.kept.contains(&cv[a]) {
                samples.push(BoundarySample {
                    from: a,
                    to: a,
                    t: 0.0,
                    border,
                });
                at.push((e, 0.0));
            }
            let forward = cv[a] < cv[b];
            let key = if forward {
                (cv[a], cv[b])
            } else {
                (cv[b], cv[a])
            };
            if let Some(ts) = self.edge_ts.get(&key) {
                let push = |t: Real, samples: &mut Vec<BoundarySample>, at: &mut Vec<LoopPos>| {
                    let (from, to, tau) = if forward { (a, b, t) } else { (b, a, 1.0 - t) };
                    samples.push(BoundarySample {
                        from,
                        to,
                        t,
                        border,
                    });
                    at.push((e, tau));
                };
                if forward {
                    ts.iter().for_each(|&t| push(t, &mut samples, &mut at));
                } else {
                    ts.iter()
                        .rev()
                        .for_each(|&t| push(t, &mut samples, &mut at));
                }
            }
        }
        (samples, at)
    }

    /// Adds a sample halfway (in 3D arc length along the boundary polyline) between consecutive samples `k`
    /// and `k + 1` of loop `l` of `panel`. Returns false when the two are too close to split.
    fn split(
        &mut self,
        panel: &Panel,
        l: usize,
        at: &[LoopPos],
        k: usize,
        min_length: Real,
    ) -> bool {
        let lp = &panel.boundary[l];
        let n = lp.vertices.len();
        let pos = &panel.mesh.positions;
        let point = |(e, tau): LoopPos| {
            let (a, b) = (pos[lp.vertices[e]], pos[lp.vertices[(e + 1) % n]]);
            a + (b - a) * tau
        };
        let (a, b) = (at[k], at[(k + 1) % at.len()]);
        // The polyline from a to b: a, the loop vertices passed, b.
        let mut pts: Vec<LoopPos> = vec![a];
        let steps = if b.0 == a.0 && b.1 > a.1 {
            0
        } else if b.0 == a.0 {
            n
        } else {
            (b.0 + n - a.0) % n
        };
        for s in 1..=steps {
            pts.push(((a.0 + s) % n, 0.0));
        }
        pts.push(b);
        let lens: Vec<Real> = pts
            .windows(2)
            .map(|w| (point(w[1]) - point(w[0])).norm())
            .collect();
        let total: Real = lens.iter().sum();
        if total.is_nan() || total <= 0.0 || total < min_length {
            return false;
        }
        let mut s = 0.5 * total;
        for (i, &len) in lens.iter().enumerate() {
            if s <= len {
                let (e, tau0) = pts[i];
                let tau1 = if pts[i + 1].0 == e && pts[i + 1].1 > tau0 {
                    pts[i + 1].1
                } else {
                    1.0
                };
                let tau = tau0 + (tau1 - tau0) * (s / len);
                let (u, v) = (
                    panel.cut_vertex[lp.vertices[e]],
                    panel.cut_vertex[lp.vertices[(e + 1) % n]],
                );
                if tau <= 0.0 {
                    return self.kept.insert(u);
                }
                if tau >= 1.0 {
                    return self.kept.insert(v);
                }
                let (key, t) = canonical(u, v, tau);
                let ts = self.edge_ts.entry(key).or_default();
                let idx = ts.partition_point(|&x| x < t);
                if ts.get(idx) == Some(&t) {
                    return false;
                }
                ts.insert(idx, t);
                return true;
            }
            s -= len;
        }
        false
    }
}

/// Resamples the boundary loops of every panel at `params.target_edge_length` (3D arc length); see
/// [`BoundarySampling::new`]. Returns, per panel and per boundary loop, the samples in loop order. Samples on
/// a seam are identical on both sides (same [`sample_key`]).
pub fn boundary_samples(
    set: &PanelSet,
    params: &RemeshParams,
) -> Result<Vec<Vec<Vec<BoundarySample>>>, RemeshError> {
    Ok(BoundarySampling::new(set, params)?.samples(set))
}

/// A remeshed pattern panel.
#[derive(Clone, Debug)]
pub struct PatternMesh {
    /// `#V` pattern positions (m): the boundary samples first (loop by loop, in order), then interior vertices.
    pub positions: Vec<Vec2>,
    /// `#F` triangles, counter-clockwise in the pattern plane.
    pub faces: Vec<[usize; 3]>,
    /// Body location of each vertex (`#V`).
    pub body: Vec<MeshPoint>,
    /// 3D position of each vertex on the body surface (m, `#V`).
    pub positions3: Vec<Vec3>,
    /// Boundary loops as vertex index lists (into `positions`).
    pub boundary: Vec<Vec<usize>>,
    /// The boundary sample of each boundary vertex (vertex `i < boundary_samples.len()`).
    pub boundary_samples: Vec<BoundarySample>,
    /// Smallest corner angle of the triangulation (rad).
    pub min_angle: Real,
    /// Whether the refinement finished within `max_added_vertices`.
    pub refinement_complete: bool,
}

/// Uniform grid over the flattened source triangles for point location.
struct FlatTriangleGrid {
    lo: Vec2,
    cell: Real,
    nx: usize,
    ny: usize,
    cells: Vec<Vec<usize>>,
}

impl FlatTriangleGrid {
    fn new(uv: &[Vec2], faces: &[[usize; 3]]) -> Self {
        let (lo, hi) = uv.iter().fold(
            (Vec2::repeat(Real::INFINITY), Vec2::repeat(-Real::INFINITY)),
            |(lo, hi), p| (lo.inf(p), hi.sup(p)),
        );
        let extent = (hi - lo).max().max(1e-300);
        let side = (faces.len() as Real).sqrt().ceil().max(1.0);
        let cell = extent / side;
        let nx = ((hi.x - lo.x) / cell).floor() as usize + 1;
        let ny = ((hi.y - lo.y) / cell).floor() as usize + 1;
        let mut cells = vec![Vec::new(); nx * ny];
        for (f, face) in faces.iter().enumerate() {
            let q = face.map(|v| uv[v]);
            let flo = q[0].inf(&q[1]).inf(&q[2]);
            let fhi = q[0].sup(&q[1]).sup(&q[2]);
            let (i0, j0) = Self::index(lo, cell, nx, ny, flo);
            let (i1, j1) = Self::index(lo, cell, nx, ny, fhi);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    cells[j * nx + i].push(f);
                }
            }
        }
        Self {
            lo,
            cell,
            nx,
            ny,
            cells,
        }
    }

    fn index(lo: Vec2, cell: Real, nx: usize, ny: usize, p: Vec2) -> (usize, usize) {
        let i = (((p.x - lo.x) / cell).floor().max(0.0) as usize).min(nx - 1);
        let j = (((p.y - lo.y) / cell).floor().max(0.0) as usize).min(ny - 1);
        (i, j)
    }

    /// The source triangle containing `p` and the barycentric coordinates there; when `p` lies in no
    /// triangle (outside the flattened panel, e.g. across a concave boundary chord), the triangle nearest to
    /// `p` and the coordinates of the nearest point in it.
    fn locate(&self, uv: &[Vec2], faces: &[[usize; 3]], p: Vec2) -> (usize, [Real; 3]) {
        let (i, j) = Self::index(self.lo, self.cell, self.nx, self.ny, p);
        let mut best = (usize::MAX, [0.0; 3], Real::INFINITY);
        let mut consider = |f: usize| {
            let q = faces[f].map(|v| uv[v]);
            let lam = barycentric(q, p);
            let worst = lam.iter().copied().fold(Real::INFINITY, Real::min);
            if worst >= 0.0 {
                return Some((f, lam));
            }
            let (lam_c, d) = closest_in_triangle(q, p);
            if d < best.2 {
                best = (f, lam_c, d);
            }
            None
        };
        for &f in &self.cells[j * self.nx + i] {
            if let Some(hit) = consider(f) {
                return hit;
            }
        }
        for f in 0..faces.len() {
            if let Some(hit) = consider(f) {
                return hit;
            }
        }
        (best.0, best.1)
    }
}

fn barycentric(q: [Vec2; 3], p: Vec2) -> [Real; 3] {
    let a = signed_area(q[0], q[1], q[2]);
    let l0 = signed_area(p, q[1], q[2]) / a;
    let l1 = signed_area(q[0], p, q[2]) / a;
    [l0, l1, 1.0 - l0 - l1]
}

/// Barycentric coordinates of the point of triangle `q` closest to `p`, and its distance (m).
fn closest_in_triangle(q: [Vec2; 3], p: Vec2) -> ([Real; 3], Real) {
    let lam = barycentric(q, p);
    if lam.iter().all(|&l| l >= 0.0) {
        return (lam, 0.0);
    }
    let mut best = ([0.0; 3], Real::INFINITY);
    for e in 0..3 {
        let (a, b) = (q[e], q[(e + 1) % 3]);
        let d = b - a;
        let t = if d.norm_squared() > 0.0 {
            ((p - a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let dist = (a + d * t - p).norm();
        if dist < best.1 {
            let mut l = [0.0; 3];
            l[e] = 1.0 - t;
            l[(e + 1) % 3] = t;
            best = (l, dist);
        }
    }
    best
}

fn corner_min_angle(q: [Vec2; 3]) -> Real {
    (0..3)
        .map(|i| {
            let u = q[(i + 1) % 3] - q[i];
            let v = q[(i + 2) % 3] - q[i];
            (u.x * v.y - u.y * v.x).abs().atan2(u.dot(&v))
        })
        .fold(Real::INFINITY, Real::min)
}

/// Remeshes one flattened panel with its boundary fixed to the given samples.
///
/// * `panel`: the panel from [`crate::plane_cut::panels`];
/// * `flat`: its flattened positions (`#V_panel`, m), e.g. from [`crate::lscm::lscm`], counter-clockwise;
/// * `samples`: its boundary samples from [`boundary_samples`] (one list per boundary loop).
///
/// The boundary of the result is exactly the samples (never split), so panels remeshed from the same
/// [`boundary_samples`] match one-to-one along seams. Because boundary edges may not be split, triangles next
/// to a boundary that is coarse compared with the interior can fall below `params.min_angle`; the achieved
/// value is reported in [`PatternMesh::min_angle`]. [`remesh_panels`] refines the shared boundary sampling
/// until the angle bound holds everywhere.
pub fn pattern_remesh(
    panel: &Panel,
    flat: &[Vec2],
    samples: &[Vec<BoundarySample>],
    params: &RemeshParams,
) -> Result<PatternMesh, RemeshError> {
    match remesh_one(panel, flat, samples, params, true)? {
        Remeshed::Done(m) => Ok(m),
        Remeshed::Split(_) => unreachable!("boundary edges are kept"),
    }
}

/// Outcome of one remeshing attempt.
enum Remeshed {
    Done(PatternMesh),
    /// The refinement wanted to split these boundary segments: `(loop, k)` is the segment from sample `k`
    /// to sample `k + 1` of that loop.
    Split(Vec<(usize, usize)>),
}

fn remesh_one(
    panel: &Panel,
    flat: &[Vec2],
    samples: &[Vec<BoundarySample>],
    params: &RemeshParams,
    keep_boundary: bool,
) -> Result<Remeshed, RemeshError> {
    check_params(params)?;
    let name = || panel.name.clone();
    let nv = panel.mesh.num_vertices();
    if flat.len() != nv {
        return Err(RemeshError::FlatteningSize {
            panel: name(),
            got: flat.len(),
            expected: nv,
        });
    }
    if samples.len() != panel.boundary.len() {
        return Err(RemeshError::BadSamples {
            panel: name(),
            problem: format!(
                "have {} loops but the panel has {} boundary loops",
                samples.len(),
                panel.boundary.len()
            ),
        });
    }
    if let Some(v) = flat.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(RemeshError::Triangulation {
            panel: name(),
            problem: format!("flattened vertex {v} is not finite"),
        });
    }
    // The panel face holding each boundary edge, both orientations.
    let mut edge_face: HashMap<(VertexId, VertexId), (usize, usize)> = HashMap::new();
    for (f, face) in panel.mesh.faces.iter().enumerate() {
        for e in 0..3 {
            edge_face.insert((face[e], face[(e + 1) % 3]), (f, e));
        }
    }
    let all: Vec<BoundarySample> = samples.iter().flatten().copied().collect();
    for (i, s) in all.iter().enumerate() {
        let ok = s.from < nv
            && s.to < nv
            && (0.0..1.0).contains(&s.t)
            && (s.from == s.to
                || edge_face.contains_key(&(s.from, s.to))
                || edge_face.contains_key(&(s.to, s.from)));
        if !ok {
            return Err(RemeshError::BadSamples {
                panel: name(),
                problem: format!("sample {i} does not lie on an edge of the panel"),
            });
        }
    }
    for lp in samples {
        if lp.len() < 3 {
            return Err(RemeshError::BadSamples {
                panel: name(),
                problem: format!(
                    "a loop has only {} samples (at least 3 are needed)",
                    lp.len()
                ),
            });
        }
    }

    // Constrained Delaunay triangulation of the boundary samples.
    let mut cdt: ConstrainedDelaunayTriangulation<Point2<Real>> =
        ConstrainedDelaunayTriangulation::new();
    let mut handles = Vec::with_capacity(all.len());
    for (i, s) in all.iter().enumerate() {
        let p = s.lerp(flat);
        let before = cdt.num_vertices();
        let hnd = cdt
            .insert(Point2::new(p.x, p.y))
            .map_err(|e| RemeshError::Triangulation {
                panel: name(),
                problem: format!("inserting boundary sample {i}: {e:?}"),
            })?;
        if cdt.num_vertices() == before {
            return Err(RemeshError::CoincidentSamples {
                panel: name(),
                a: hnd.index(),
                b: i,
            });
        }
        handles.push(hnd);
    }
    let mut offset = 0;
    let mut boundary = Vec::with_capacity(samples.len());
    for lp in samples {
        let n = lp.len();
        for k in 0..n {
            let (a, b) = (handles[offset + k], handles[offset + (k + 1) % n]);
            if cdt.try_add_constraint(a, b).len() != 1 {
                return Err(RemeshError::SelfIntersection {
                    panel: name(),
                    sample: offset + k,
                });
            }
        }
        boundary.push((offset..offset + n).collect());
        offset += n;
    }
    let h = params.target_edge_length;
    let mut refinement = RefinementParameters::<Real>::new()
        .exclude_outer_faces(true)
        .with_angle_limit(AngleLimit::from_rad(params.min_angle))
        .with_max_allowed_area(0.25 * 3f64.sqrt() * h * h)
        .with_max_additional_vertices(params.max_added_vertices);
    if keep_boundary {
        refinement = refinement.keep_constraint_edges();
    }
    let result = cdt.refine(refinement);
    if !keep_boundary {
        let mut split = Vec::new();
        let mut offset = 0;
        for (l, lp) in samples.iter().enumerate() {
            let n = lp.len();
            for k in 0..n {
                let (a, b) = (handles[offset + k], handles[offset + (k + 1) % n]);
                if cdt.get_edge_from_neighbors(a, b).is_none() {
                    split.push((l, k));
                }
            }
            offset += n;
        }
        if !split.is_empty() {
            return Ok(Remeshed::Split(split));
        }
    }
    let excluded: HashSet<usize> = result.excluded_faces.iter().map(|f| f.index()).collect();

    // Vertices: spade keeps insertion order, so the boundary samples come first.
    let positions: Vec<Vec2> = cdt
        .vertices()
        .map(|v| {
            let p = v.position();
            Vec2::new(p.x, p.y)
        })
        .collect();
    let mut faces = Vec::new();
    let mut min_angle = Real::INFINITY;
    for f in cdt.inner_faces() {
        if excluded.contains(&f.fix().index()) {
            continue;
        }
        let tri = f.vertices().map(|v| v.fix().index());
        min_angle = min_angle.min(corner_min_angle(tri.map(|v| positions[v])));
        faces.push(tri);
    }

    // Body location of every vertex.
    let body_tri = |f: usize, lam: [Real; 3]| panel.face_origin[f].mesh_point(lam);
    let mut body = Vec::with_capacity(positions.len());
    for s in &all {
        let sp = if s.from == s.to {
            panel.vertex_origin[s.from]
        } else {
            let (f, e, forward) = match edge_face.get(&(s.from, s.to)) {
                Some(&(f, e)) => (f, e, true),
                None => {
                    let (f, e) = edge_face[&(s.to, s.from)];
                    (f, e, false)
                }
            };
            let mut lam = [0.0; 3];
            let (ta, tb) = if forward {
                (1.0 - s.t, s.t)
            } else {
                (s.t, 1.0 - s.t)
            };
            lam[e] = ta;
            lam[(e + 1) % 3] = tb;
            body_tri(f, lam)
        };
        body.push(sp);
    }
    let mut positions3: Vec<Vec3> = all.iter().map(|s| s.lerp(&panel.mesh.positions)).collect();
    let grid = FlatTriangleGrid::new(flat, &panel.mesh.faces);
    for &p in &positions[all.len()..] {
        let (f, lam) = grid.locate(flat, &panel.mesh.faces, p);
        body.push(body_tri(f, lam));
        let [p0, p1, p2] = panel.mesh.corners(f);
        positions3.push(p0 * lam[0] + p1 * lam[1] + p2 * lam[2]);
    }
    Ok(Remeshed::Done(PatternMesh {
        positions,
        faces,
        body,
        positions3,
        boundary,
        boundary_samples: all,
        min_angle,
        refinement_complete: result.refinement_complete,
    }))
}

/// Remeshes every panel of `set` from its flattening (`flats[p]`: `#V_panel` positions, m), with one shared
/// boundary sampling so that panels match one-to-one along seams.
///
/// Quality: each round triangulates every panel letting the refinement split boundary segments where it needs
/// to (Ruppert's rule); every segment it wanted to split is instead split at its 3D arc-length midpoint in the
/// shared sampling — on both sides of a seam — and the round is repeated; a segment already shorter than
/// `params.min_split_fraction` of the target edge length is left as it is (next to a corner sharper than the
/// bound, splits would go on halving it to nothing). When no panel needs a split, the
/// meshes meet `params.min_angle` (except next to boundary corners sharper than the bound, which no
/// triangulation can fix) and their boundaries are exactly the shared samples. After
/// `params.max_boundary_rounds` rounds the boundary is frozen and the achieved angle is reported.
pub fn remesh_panels(
    set: &PanelSet,
    flats: &[Vec<Vec2>],
    params: &RemeshParams,
) -> Result<Vec<PatternMesh>, RemeshError> {
    if flats.len() != set.panels.len() {
        return Err(RemeshError::BadSamples {
            panel: String::new(),
            problem: format!(
                "{} flattenings given for {} panels",
                flats.len(),
                set.panels.len()
            ),
        });
    }
    let mut sampling = BoundarySampling::new(set, params)?;
    for _ in 0..params.max_boundary_rounds {
        let mut meshes = Vec::with_capacity(set.panels.len());
        let mut splits = Vec::new();
        for (p, (panel, flat)) in set.panels.iter().zip(flats).enumerate() {
            let samples: Vec<Vec<BoundarySample>> = (0..panel.boundary.len())
                .map(|l| sampling.loop_samples(panel, l).0)
                .collect();
            match remesh_one(panel, flat, &samples, params, false)? {
                Remeshed::Done(m) => meshes.push(m),
                Remeshed::Split(s) => splits.extend(s.into_iter().map(|(l, k)| (p, l, k))),
            }
        }
        if splits.is_empty() {
            return Ok(meshes);
        }
        let positions: Vec<Vec<Vec<LoopPos>>> = set
            .panels
            .iter()
            .map(|panel| {
                (0..panel.boundary.len())
                    .map(|l| sampling.loop_samples(panel, l).1)
                    .collect()
            })
            .collect();
        // A seam segment split from both sides is split once: skip the second by its sample keys.
        let mut done: HashSet<(SampleKey, SampleKey)> = HashSet::new();
        let keys: Vec<Vec<Vec<SampleKey>>> = set
            .panels
            .iter()
            .map(|panel| {
                (0..panel.boundary.len())
                    .map(|l| {
                        sampling
                            .loop_samples(panel, l)
                            .0
                            .iter()
                            .map(|s| sample_key(panel, s))
                            .collect()
                    })
                    .collect()
            })
            .collect();
        let mut changed = false;
        for (p, l, k) in splits {
            let ks = &keys[p][l];
            let (a, b) = (ks[k], ks[(k + 1) % ks.len()]);
            let pair = if a <= b { (a, b) } else { (b, a) };
            if done.insert(pair) {
                changed |= sampling.split(
                    &set.panels[p],
                    l,
                    &positions[p][l],
                    k,
                    params.min_split_fraction * params.target_edge_length,
                );
            }
        }
        if !changed {
            break;
        }
    }
    // Freeze the boundary.
    let samples = sampling.samples(set);
    set.panels
        .iter()
        .zip(flats)
        .zip(&samples)
        .map(|((panel, flat), s)| pattern_remesh(panel, flat, s, params))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lscm::lscm;
    use crate::plane_cut::{HalfSpace, PlaneCutParams, Region, panels};
    use skintight_geometry::mesh::TriMesh;
    use skintight_geometry::test_meshes::{body_path, icosphere, read_obj};

    fn hs(n: [Real; 3], d: Real) -> HalfSpace {
        HalfSpace::new(n, d)
    }

    fn sphere_regions() -> Vec<Region> {
        let band = |side: Real| {
            vec![
                hs([0.0, 0.0, 1.0], 0.3),
                hs([0.0, 0.0, -1.0], 0.4),
                hs([side, 0.0, 0.0], side * 0.05),
            ]
        };
        vec![
            Region {
                label: "top".into(),
                half_spaces: vec![hs([0.0, 0.0, -1.0], -0.3)],
            },
            Region {
                label: "left".into(),
                half_spaces: band(1.0),
            },
            Region {
                label: "right".into(),
                half_spaces: band(-1.0),
            },
            Region {
                label: "bottom".into(),
                half_spaces: vec![hs([0.0, 0.0, 1.0], -0.4)],
            },
        ]
    }

    /// Cuts, flattens and remeshes every panel.
    fn remesh_all(
        body: &TriMesh,
        regions: &[Region],
        params: &RemeshParams,
    ) -> (PanelSet, Vec<PatternMesh>) {
        let set = panels(body, regions, &PlaneCutParams::default()).unwrap();
        let flats: Vec<Vec<Vec2>> = set
            .panels
            .iter()
            .map(|p| lscm(&p.mesh).unwrap().positions)
            .collect();
        let meshes = remesh_panels(&set, &flats, params).unwrap();
        (set, meshes)
    }

    #[test]
    fn fixed_boundary_remesh_keeps_the_samples() {
        let body = icosphere(3, 1.0);
        let params = RemeshParams {
            target_edge_length: 0.1,
            min_angle: 0.0,
            ..Default::default()
        };
        let set = panels(&body, &sphere_regions(), &PlaneCutParams::default()).unwrap();
        let samples = boundary_samples(&set, &params).unwrap();
        for (p, s) in set.panels.iter().zip(&samples) {
            let flat = lscm(&p.mesh).unwrap();
            let m = pattern_remesh(p, &flat.positions, s, &params).unwrap();
            check_pattern(&body, &m, &params, &p.name);
            let all: Vec<BoundarySample> = s.iter().flatten().copied().collect();
            assert_eq!(m.boundary_samples, all);
            assert_eq!(m.boundary.iter().map(Vec::len).sum::<usize>(), all.len());
        }
    }

    fn check_pattern(body: &TriMesh, m: &PatternMesh, params: &RemeshParams, label: &str) {
        // Quality.
        assert!(m.refinement_complete, "{label}");
        assert!(
            m.min_angle >= params.min_angle - 1e-9,
            "{label}: min angle {:.2}° below {:.2}°",
            m.min_angle.to_degrees(),
            params.min_angle.to_degrees()
        );
        // All faces counter-clockwise and the area equals the area enclosed by the boundary samples.
        let mut area = 0.0;
        for f in &m.faces {
            let a = signed_area(m.positions[f[0]], m.positions[f[1]], m.positions[f[2]]);
            assert!(a > 0.0, "{label}: face {f:?} not counter-clockwise");
            area += a;
        }
        let enclosed: Real = m
            .boundary
            .iter()
            .map(|lp| {
                let n = lp.len();
                (0..n)
                    .map(|k| {
                        let (a, b) = (m.positions[lp[k]], m.positions[lp[(k + 1) % n]]);
                        0.5 * (a.x * b.y - a.y * b.x)
                    })
                    .sum::<Real>()
            })
            .sum();
        assert!(
            (area - enclosed).abs() < 1e-12 * enclosed.abs().max(1.0),
            "{label}"
        );
        // Every vertex used, and every vertex on the body surface.
        let mut used = vec![false; m.positions.len()];
        m.faces.iter().flatten().for_each(|&v| used[v] = true);
        assert!(used.iter().all(|&u| u), "{label}: unused vertex");
        for (v, sp) in m.body.iter().enumerate() {
            assert!(
                sp.bary.iter().all(|&b| (-1e-12..=1.0 + 1e-12).contains(&b)),
                "{label} {v}"
            );
            assert!((sp.bary.iter().sum::<Real>() - 1.0).abs() < 1e-12);
            let on_body = sp.position(body);
            assert!(
                (on_body - m.positions3[v]).norm() < 1e-12,
                "{label}: vertex {v}"
            );
            let [a, b, c] = body.corners(sp.face);
            let n = (b - a).cross(&(c - a)).normalize();
            assert!(n.dot(&(m.positions3[v] - a)).abs() < 1e-12);
        }
    }

    #[test]
    fn sphere_panels_remesh_with_quality_and_cover_the_area() {
        for (levels, h) in [(2, 0.25), (3, 0.12), (3, 0.06)] {
            let body = icosphere(levels, 1.0);
            let params = RemeshParams {
                target_edge_length: h,
                ..Default::default()
            };
            let (set, meshes) = remesh_all(&body, &sphere_regions(), &params);
            for (p, m) in set.panels.iter().zip(&meshes) {
                let label = format!("levels {levels}, h {h}, panel {}", p.name);
                check_pattern(&body, m, &params, &label);
                // Boundary spacing near the target, measured in 3D.
                for lp in &m.boundary {
                    let n = lp.len();
                    for k in 0..n {
                        let l = (m.positions3[lp[k]] - m.positions3[lp[(k + 1) % n]]).norm();
                        assert!(l < 1.6 * h, "{label}: boundary edge {l}");
                    }
                }
                eprintln!(
                    "{label}: {} vertices, {} faces, min angle {:.1}°",
                    m.positions.len(),
                    m.faces.len(),
                    m.min_angle.to_degrees()
                );
            }
            // Finer than the body: more pattern vertices than panel vertices.
            let total: usize = meshes.iter().map(|m| m.positions.len()).sum();
            if h < 0.1 {
                assert!(total > set.cut.mesh.num_vertices());
            }
        }
    }

    #[test]
    fn seam_vertices_match_one_to_one() {
        let body = icosphere(3, 1.0);
        let params = RemeshParams {
            target_edge_length: 0.08,
            ..Default::default()
        };
        let (set, meshes) = remesh_all(&body, &sphere_regions(), &params);
        for seam in &set.seams {
            let [a, b] = [seam.sides[0].panel, seam.sides[1].panel];
            let keys = |p: usize, q: usize| -> HashMap<SampleKey, usize> {
                meshes[p]
                    .boundary_samples
                    .iter()
                    .enumerate()
                    .filter(|(_, s)| s.from != s.to && s.border == Border::Seam { panel: q })
                    .map(|(i, s)| (sample_key(&set.panels[p], s), i))
                    .collect()
            };
            let (ka, kb) = (keys(a, b), keys(b, a));
            assert!(!ka.is_empty());
            assert_eq!(ka.len(), kb.len(), "seam {a}–{b}");
            for (k, &ia) in &ka {
                let ib = kb[k];
                assert_eq!(meshes[a].positions3[ia], meshes[b].positions3[ib]);
            }
        }
        // Corner vertices (kept cut vertices) are shared too.
        let corner_keys = |p: usize| -> HashSet<VertexId> {
            meshes[p]
                .boundary_samples
                .iter()
                .filter(|s| s.from == s.to)
                .map(|s| set.panels[p].cut_vertex[s.from])
                .collect()
        };
        let top = corner_keys(0);
        let left = corner_keys(1);
        assert!(top.intersection(&left).count() >= 2);
    }

    #[test]
    fn closed_seam_is_resampled_identically() {
        let body = icosphere(3, 1.0);
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
        let params = RemeshParams {
            target_edge_length: 0.1,
            ..Default::default()
        };
        let (set, meshes) = remesh_all(&body, &regions, &params);
        let ka: HashSet<SampleKey> = meshes[0]
            .boundary_samples
            .iter()
            .map(|s| sample_key(&set.panels[0], s))
            .collect();
        let kb: HashSet<SampleKey> = meshes[1]
            .boundary_samples
            .iter()
            .map(|s| sample_key(&set.panels[1], s))
            .collect();
        assert_eq!(ka, kb);
        for (p, m) in set.panels.iter().zip(&meshes) {
            check_pattern(&body, m, &params, &p.name);
        }
    }

    #[test]
    fn small_panel_gets_at_least_three_boundary_samples() {
        // A cap whose rim (≈ 1.5 m) is shorter than two target lengths still gets a triangle of samples.
        let body = icosphere(3, 1.0);
        let regions = vec![Region {
            label: "tiny cap".into(),
            half_spaces: vec![hs([0.0, 0.0, -1.0], -0.97)],
        }];
        let params = RemeshParams {
            target_edge_length: 1.0,
            ..Default::default()
        };
        let set = panels(&body, &regions, &PlaneCutParams::default()).unwrap();
        let samples = boundary_samples(&set, &params).unwrap();
        assert_eq!(samples[0][0].len(), 3);
        let (_, meshes) = remesh_all(&body, &regions, &params);
        check_pattern(&body, &meshes[0], &params, "tiny cap");
    }

    #[test]
    fn bad_inputs_are_reported() {
        let body = icosphere(2, 1.0);
        let set = panels(&body, &sphere_regions(), &PlaneCutParams::default()).unwrap();
        let params = RemeshParams::default();
        let bad = RemeshParams {
            target_edge_length: -1.0,
            ..params
        };
        assert!(matches!(
            boundary_samples(&set, &bad).unwrap_err(),
            RemeshError::BadParam {
                field: "target_edge_length",
                ..
            }
        ));
        let samples = boundary_samples(&set, &params).unwrap();
        let p = &set.panels[0];
        let err = pattern_remesh(p, &[Vec2::zeros(); 2], &samples[0], &params).unwrap_err();
        assert!(matches!(err, RemeshError::FlatteningSize { .. }), "{err}");
        // A flattening that folds the panel onto a line makes samples coincide or the boundary degenerate.
        let folded: Vec<Vec2> = p
            .mesh
            .positions
            .iter()
            .map(|q| Vec2::new(q.x, 0.0))
            .collect();
        assert!(pattern_remesh(p, &folded, &samples[0], &params).is_err());
        let mut nan = lscm(&p.mesh).unwrap().positions;
        nan[0].x = Real::NAN;
        assert!(pattern_remesh(p, &nan, &samples[0], &params).is_err());
    }

    #[test]
    fn body_torso_remesh() {
        let body = read_obj(&body_path("regular_1k.obj"));
        let (lo, hi) = body.bounding_box().unwrap();
        let y0 = lo.y + 0.55 * (hi.y - lo.y);
        let y1 = lo.y + 0.7 * (hi.y - lo.y);
        let side = |n: [Real; 3], d: Real| Region {
            label: format!("torso {n:?}"),
            half_spaces: vec![
                hs([0.0, -1.0, 0.0], -y0),
                hs([0.0, 1.0, 0.0], y1),
                hs([1.0, 0.0, 0.0], 0.2),
                hs([-1.0, 0.0, 0.0], 0.2),
                hs(n, d),
            ],
        };
        let regions = vec![side([0.0, 0.0, -1.0], -0.02), side([0.0, 0.0, 1.0], 0.02)];
        let params = RemeshParams {
            target_edge_length: 0.015,
            ..Default::default()
        };
        let start = std::time::Instant::now();
        let (set, meshes) = remesh_all(&body, &regions, &params);
        let elapsed = start.elapsed();
        // Front and back meet along two side seams.
        assert_eq!(set.seams.len(), 2);
        for (p, m) in set.panels.iter().zip(&meshes) {
            check_pattern(&body, m, &params, &p.name);
            eprintln!(
                "body {}: {} panel vertices → {} pattern vertices, {} faces, min angle {:.1}°",
                p.name,
                p.mesh.num_vertices(),
                m.positions.len(),
                m.faces.len(),
                m.min_angle.to_degrees()
            );
        }
        let matched = |a: usize, b: usize| -> usize {
            let kb: HashMap<SampleKey, usize> = meshes[b]
                .boundary_samples
                .iter()
                .enumerate()
                .map(|(i, s)| (sample_key(&set.panels[b], s), i))
                .collect();
            meshes[a]
                .boundary_samples
                .iter()
                .enumerate()
                .filter(|(_, s)| s.from != s.to && s.border == Border::Seam { panel: b })
                .map(|(i, s)| {
                    let j = kb[&sample_key(&set.panels[a], s)];
                    assert_eq!(meshes[a].positions3[i], meshes[b].positions3[j]);
                })
                .count()
        };
        assert!(matched(0, 1) > 0);
        assert_eq!(matched(0, 1), matched(1, 0));
        eprintln!("cut + flatten + remesh of two torso panels: {elapsed:?}");
    }

    #[test]
    fn boundary_sampling_stops_at_its_cap_before_allocating() {
        let body = icosphere(3, 1.0);
        let set = panels(&body, &sphere_regions(), &PlaneCutParams::default()).unwrap();
        // 1e-9 m on a unit sphere would be ~10¹⁰ samples.
        let params = RemeshParams {
            target_edge_length: 1e-9,
            max_added_vertices: 1000,
            ..Default::default()
        };
        assert_eq!(
            boundary_samples(&set, &params).unwrap_err(),
            RemeshError::TooManySamples { max: 1000 }
        );
        // Within the cap, nothing changes.
        let params = RemeshParams {
            target_edge_length: 0.1,
            max_added_vertices: 1000,
            ..Default::default()
        };
        assert!(boundary_samples(&set, &params).is_ok());
    }
}
