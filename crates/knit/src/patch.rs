//! The mechanics of a finite (non-periodic) patch of yarns ([`crate::tile`]: the yarns of `nx × ny` cells,
//! cut at the patch border):
//!
//! `E(x) = Σ_edges E_s + Σ_interior vertices (E_b + E_t) + Σ_segment pairs E_c + Σ_vertices (E_g + E_sphere)
//! + Σ_bonds E_bond`
//!
//! - `E_s` stretching ([`crate::stretching`]), `E_b` bending with the rest curvatures ([`crate::bending`]),
//!   `E_t` twisting with the rest twists ([`crate::twisting`]) — at every vertex joining two edges of one
//!   yarn (not at the two ends of a cut yarn);
//! - `E_c` yarn–yarn contact ([`crate::contact`]) between every pair of segments closer than the contact
//!   distance, except pairs of one yarn within the exclusion arclength ([`crate::yarn_params`]); candidates
//!   from the spatial hash ([`crate::spatial_hash`]);
//! - `E_g` gravity on lumped vertex masses ([`crate::gravity`]; mass from the yarn's linear density);
//! - `E_sphere` an optional rigid sphere obstacle ([`crate::sphere_contact`]);
//! - bonds of a fused edge ([`crate::edge_finish`], [`PatchModel::bond_cut_ends`]): the stretching energy
//!   of a rod edge between a cut yarn end and its partner vertex, counted with the stretching part.
//!
//! All in J. **Unknowns**: 4 per vertex, yarn after yarn: the position (m) and the material angle (rad) of
//! the edge starting at the vertex. The last vertex of an open yarn starts no edge: its angle is unused
//! ([`PatchModel::unused_dofs`]; zero gradient, no Hessian entries). Gradients are in N (positions) and
//! N·m (angles), the Hessian's lower triangle as sparse triplets; each term's derivatives are derived and
//! tested in its own module, and [`PatchModel::evaluate`] only scatters them (tested here against central
//! differences of the assembled energy along random directions). [`PatchModel::evaluate_order`] evaluates
//! to a chosen [`Order`]: the energy alone (plain numbers, for the line search), with the gradient, or with
//! the Hessian; bending and twisting of a vertex come from one evaluation of its strains
//! ([`crate::rod_vertex`]).
//!
//! **Frames**: each edge carries a time-parallel-transported reference frame ([`crate::frames`]) built
//! from the pattern's reference director at the starting geometry; [`PatchModel::rebase_frames`] re-bases
//! frames whose tangent turned, which leaves the energy unchanged.

use faer::sparse::Triplet;
use serde::{Deserialize, Serialize};

use crate::bending::{BendingVertex, STENCIL_DOFS};
use crate::contact::{CONTACT_DOFS, ContactPair};
use crate::edge_finish::{Bond, cut_end_bonds};
use crate::frames::{EdgeFrame, dot, norm, scale, sub, vertex_strains};
use crate::gravity::{GravityVertex, lumped_masses};
use crate::rod_vertex::RodVertex;
use crate::spatial_hash::candidate_pairs;
use crate::sphere_contact::SphereObstacle;
use crate::stretching::StretchingEdge;
use crate::tile::Patch;
use crate::twisting::TwistingVertex;
use crate::yarn_params::{RodStiffness, YarnParams};

/// Unknowns per vertex: position (3) and the angle of the edge starting there (1).
pub const DOFS_PER_VERTEX: usize = 4;

/// What an evaluation computes ([`PatchModel::evaluate_order`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Order {
    /// The energy and its parts alone (no derivatives; the gradient is left empty): the line search.
    Energy,
    /// The energy and the gradient.
    Gradient,
    /// The energy, the gradient and the Hessian.
    Hessian,
}

/// External loads and obstacles of a patch.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PatchLoads {
    /// Gravitational acceleration (m/s²); skintight is +y up, so `(0, −9.81, 0)` pulls down.
    pub gravity: [f64; 3],
    /// A rigid sphere obstacle, if any.
    pub sphere: Option<SphereObstacle>,
}

impl Default for PatchLoads {
    fn default() -> Self {
        Self {
            gravity: [0.0, -crate::gravity::STANDARD_GRAVITY, 0.0],
            sphere: None,
        }
    }
}

/// Energy, gradient and (optionally) Hessian of a patch state.
#[derive(Clone, Debug, Default)]
pub struct PatchEvaluation {
    /// Total energy (J).
    pub energy: f64,
    /// Energy parts (J): stretching (with the bonds of a fused edge), bending, twisting, contact, gravity,
    /// sphere.
    pub parts: [f64; 6],
    /// Gradient (N for positions, N·m for angles).
    pub gradient: Vec<f64>,
    /// Hessian entries of the lower triangle (row ≥ column); duplicates add up.
    pub hessian: Vec<Triplet<usize, usize, f64>>,
    /// Segment pairs in contact (energy > 0).
    pub contacts: usize,
    /// Candidate segment pairs (not excluded) examined.
    pub candidates: usize,
    /// Smallest centreline distance (m) between non-excluded candidate segment pairs; infinite when there
    /// is no candidate.
    pub min_distance: f64,
    /// Vertices touching the sphere.
    pub sphere_contacts: usize,
}

/// A patch of yarns with its stiffnesses, masses, loads and rod frames.
#[derive(Clone, Debug)]
pub struct PatchModel {
    patch: Patch,
    stiffness: RodStiffness,
    linear_density: f64,
    loads: PatchLoads,
    /// First global vertex of each yarn (and the total at the end).
    vertex_offset: Vec<usize>,
    /// First global edge of each yarn (and the total at the end).
    edge_offset: Vec<usize>,
    /// Cumulative rest length along each yarn's edges: `arclength[edge_offset[y] + k]` is the rest length
    /// of the edges before edge `k` of yarn `y` (m); one extra entry per yarn holds the yarn's length.
    arclength: Vec<f64>,
    frames: Vec<EdgeFrame>,
    twist_hints: Vec<f64>,
    masses: Vec<f64>,
    voronoi: Vec<f64>,
    /// Bonds of a fused edge, by the yarn of their cut end (empty: ends free).
    bonds: Vec<Vec<Bond>>,
    /// Emptied Hessian triplet vectors handed back ([`Self::recycle`]) for the next evaluations to fill:
    /// a cache of allocations only (clones share it), never read for values.
    triplet_pool: std::sync::Arc<std::sync::Mutex<Vec<Vec<Triplet<usize, usize, f64>>>>>,
}

/// Most emptied triplet vectors a [`PatchModel`] keeps (one per evaluation thread, and the one the Newton
/// solver holds).
const TRIPLET_POOL: usize = 17;

/// A patch model's rod frames and reference-twist hints ([`PatchModel::frames_snapshot`]): per edge its
/// reference director and tangent (unit vectors), per vertex the reference twist its last strains were
/// measured with (rad). Serializable, so that a run can be checkpointed and resumed
/// (the yarn run checkpoint, the app crate's `src/knit/checkpoint.rs`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FramesSnapshot {
    frames: Vec<EdgeFrame>,
    twist_hints: Vec<f64>,
}

impl FramesSnapshot {
    /// Edges with a frame.
    pub fn edge_count(&self) -> usize {
        self.frames.len()
    }

    /// Vertices with a reference-twist hint.
    pub fn vertex_count(&self) -> usize {
        self.twist_hints.len()
    }

    /// Whether every director, tangent and hint is finite and every director and tangent a unit vector
    /// (to 10⁻⁶).
    pub fn is_valid(&self) -> bool {
        let unit = |v: [f64; 3]| v.iter().all(|c| c.is_finite()) && (norm(v) - 1.0).abs() <= 1e-6;
        self.frames
            .iter()
            .all(|f| unit(f.director) && unit(f.tangent))
            && self.twist_hints.iter().all(|h| h.is_finite())
    }
}

/// Errors setting up a patch.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum PatchError {
    /// A parameter is out of range.
    #[error("{0}")]
    Params(String),
    /// The patch has no yarn with an edge.
    #[error("the patch has no yarn with at least one edge")]
    Empty,
    /// A state has the wrong size.
    #[error("a state of {got} unknowns given for a patch of {expected}")]
    StateSize {
        /// Unknowns given.
        got: usize,
        /// Unknowns of the patch.
        expected: usize,
    },
}

impl PatchModel {
    /// The model of `patch` (yarns with fewer than 2 vertices — no edge — are dropped), with its rest
    /// data, the frames at its positions and the given loads.
    pub fn new(patch: &Patch, params: &YarnParams, loads: PatchLoads) -> Result<Self, PatchError> {
        params.validate().map_err(PatchError::Params)?;
        if loads.gravity.iter().any(|g| !g.is_finite()) {
            return Err(PatchError::Params(format!(
                "gravity {:?} must be finite (m/s²)",
                loads.gravity
            )));
        }
        if let Some(s) = &loads.sphere {
            s.validate().map_err(PatchError::Params)?;
        }
        let mut patch = patch.clone();
        patch.yarns.retain(|y| y.positions.len() >= 2);
        if patch.yarns.is_empty() {
            return Err(PatchError::Empty);
        }
        let stiffness = params.stiffness(patch.radius);
        let linear_density = params.linear_density(patch.radius);
        let mut vertex_offset = vec![0];
        let mut edge_offset = vec![0];
        let mut arclength = Vec::new();
        let mut frames = Vec::new();
        let mut twist_hints = Vec::new();
        let mut masses = Vec::new();
        for y in &patch.yarns {
            vertex_offset.push(vertex_offset.last().unwrap() + y.positions.len());
            edge_offset.push(edge_offset.last().unwrap() + y.edge_count());
            let mut s = 0.0;
            for k in 0..y.edge_count() {
                arclength.push(s);
                s += y.rest_length[k];
                let (a, b) = y.edge(k);
                let t = unit(sub(y.positions[b], y.positions[a]));
                let d = y.reference_director[k];
                let u = sub(d, scale(t, dot(d, t)));
                frames.push(EdgeFrame {
                    director: scale(u, 1.0 / norm(u)),
                    tangent: t,
                });
            }
            arclength.push(s);
            twist_hints.extend(y.reference_twist.iter().map(|t| t.unwrap_or(0.0)));
            masses.extend(lumped_masses(
                &y.rest_length,
                y.positions.len(),
                y.closed,
                linear_density,
            ));
        }
        let voronoi = masses.iter().map(|m| m / linear_density).collect();
        let mut model = Self {
            patch,
            stiffness,
            linear_density,
            loads,
            vertex_offset,
            edge_offset,
            arclength,
            frames,
            twist_hints,
            masses,
            voronoi,
            bonds: Vec::new(),
            triplet_pool: Default::default(),
        };
        // Pick the reference twist's 2π branch at the starting geometry.
        let x = model.initial_state();
        model.rebase_frames(&x, 0.0);
        Ok(model)
    }

    /// Bonds every cut yarn end to the nearest vertex of another yarn at the model's starting geometry
    /// ([`crate::edge_finish::cut_end_bonds`]; stiffness: the yarn's axial stiffness `k_s`), replacing any
    /// bonds before; returns how many.
    pub fn bond_cut_ends(&mut self) -> usize {
        let mut by_yarn = vec![Vec::new(); self.patch.yarns.len()];
        let bonds = cut_end_bonds(&self.patch);
        let count = bonds.len();
        for b in bonds {
            let yi = self.vertex_offset.partition_point(|&o| o <= b.vertices[0]) - 1;
            by_yarn[yi].push(b);
        }
        self.bonds = by_yarn;
        count
    }

    /// The bonds of a fused edge ([`Self::bond_cut_ends`]).
    pub fn bonds(&self) -> impl Iterator<Item = &Bond> {
        self.bonds.iter().flatten()
    }

    /// The patch (yarns without edges dropped).
    pub fn patch(&self) -> &Patch {
        &self.patch
    }

    /// The stiffnesses in use.
    pub fn stiffness(&self) -> &RodStiffness {
        &self.stiffness
    }

    /// The loads.
    pub fn loads(&self) -> &PatchLoads {
        &self.loads
    }

    /// Replaces the loads (checked as in [`Self::new`] by the caller).
    pub fn set_loads(&mut self, loads: PatchLoads) {
        self.loads = loads;
    }

    /// Yarn radius (m).
    pub fn radius(&self) -> f64 {
        self.patch.radius
    }

    /// Mass per unit yarn length (kg/m).
    pub fn linear_density(&self) -> f64 {
        self.linear_density
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        *self.vertex_offset.last().unwrap()
    }

    /// Number of edges (segments).
    pub fn edge_count(&self) -> usize {
        *self.edge_offset.last().unwrap()
    }

    /// Number of unknowns (4 per vertex).
    pub fn dof_count(&self) -> usize {
        self.vertex_count() * DOFS_PER_VERTEX
    }

    /// The global vertex range of each yarn.
    pub fn yarn_ranges(&self) -> Vec<std::ops::Range<usize>> {
        self.vertex_offset.windows(2).map(|w| w[0]..w[1]).collect()
    }

    /// Lumped vertex masses (kg).
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }

    /// Moment of inertia (kg·m²) of every angle unknown about its edge: `μ r²/2 · L̄` (a solid circular
    /// cross-section); 0 for the unused angle at the end of an open yarn.
    pub fn angular_inertia(&self) -> Vec<f64> {
        let r = self.patch.radius;
        let mut out = vec![0.0; self.vertex_count()];
        for (yi, y) in self.patch.yarns.iter().enumerate() {
            for k in 0..y.edge_count() {
                out[self.vertex_offset[yi] + k] =
                    self.linear_density * r * r / 2.0 * y.rest_length[k];
            }
        }
        out
    }

    /// The angle unknowns no energy depends on (the last vertex of each open yarn).
    pub fn unused_dofs(&self) -> Vec<usize> {
        self.patch
            .yarns
            .iter()
            .enumerate()
            .filter(|(_, y)| !y.closed)
            .map(|(yi, _)| DOFS_PER_VERTEX * (self.vertex_offset[yi + 1] - 1) + 3)
            .collect()
    }

    /// The patch's own positions and angles as an unknown vector.
    pub fn initial_state(&self) -> Vec<f64> {
        let mut x = Vec::with_capacity(self.dof_count());
        for y in &self.patch.yarns {
            for (i, p) in y.positions.iter().enumerate() {
                let t = if i < y.edge_count() { y.twist[i] } else { 0.0 };
                x.extend_from_slice(&[p[0], p[1], p[2], t]);
            }
        }
        x
    }

    /// Vertex positions (m) of an unknown vector.
    pub fn positions(x: &[f64]) -> Vec<[f64; 3]> {
        x.chunks_exact(DOFS_PER_VERTEX)
            .map(|c| [c[0], c[1], c[2]])
            .collect()
    }

    /// Checks the size of a state.
    pub fn check_state(&self, x: &[f64]) -> Result<(), PatchError> {
        if x.len() != self.dof_count() {
            return Err(PatchError::StateSize {
                got: x.len(),
                expected: self.dof_count(),
            });
        }
        Ok(())
    }

    fn pos(x: &[f64], v: usize) -> [f64; 3] {
        [x[4 * v], x[4 * v + 1], x[4 * v + 2]]
    }

    /// Global vertices `(a, b)` of global edge `e` (of yarn `yi`, local index `k`).
    fn edge_vertices(&self, yi: usize, k: usize) -> (usize, usize) {
        let (a, b) = self.patch.yarns[yi].edge(k);
        (self.vertex_offset[yi] + a, self.vertex_offset[yi] + b)
    }

    /// The yarn of global edge `e` and its local index.
    fn edge_owner(&self, e: usize) -> (usize, usize) {
        let yi = self.edge_offset.partition_point(|&o| o <= e) - 1;
        (yi, e - self.edge_offset[yi])
    }

    /// The stencil of interior vertex `i` of yarn `yi`: global unknowns `x_prev, x_i, x_next, θ_prev, θ_i`
    /// and the two global edges.
    fn stencil(&self, yi: usize, i: usize) -> ([usize; STENCIL_DOFS], [usize; 2]) {
        let y = &self.patch.yarns[yi];
        let n = y.positions.len();
        let o = self.vertex_offset[yi];
        let prev = (i + n - 1) % n;
        let next = (i + 1) % n;
        let mut s = [0; STENCIL_DOFS];
        for k in 0..3 {
            s[k] = 4 * (o + prev) + k;
            s[3 + k] = 4 * (o + i) + k;
            s[6 + k] = 4 * (o + next) + k;
        }
        s[9] = 4 * (o + prev) + 3;
        s[10] = 4 * (o + i) + 3;
        let eo = self.edge_offset[yi];
        (s, [eo + prev, eo + i])
    }

    /// Re-bases every edge frame whose tangent turned more than `angle` (rad) since its last base (all when
    /// `angle ≤ 0`) and updates the reference-twist hints. The energy at `x` is unchanged.
    pub fn rebase_frames(&mut self, x: &[f64], angle: f64) {
        for (yi, y) in self.patch.yarns.iter().enumerate() {
            for k in 0..y.edge_count() {
                let (a, b) = self.edge_vertices(yi, k);
                let t = unit(sub(Self::pos(x, b), Self::pos(x, a)));
                let f = &mut self.frames[self.edge_offset[yi] + k];
                if angle <= 0.0 || dot(t, f.tangent) < angle.cos() {
                    f.rebase(t);
                }
            }
        }
        for yi in 0..self.patch.yarns.len() {
            for i in 0..self.patch.yarns[yi].positions.len() {
                if self.patch.yarns[yi].rest_twist[i].is_none() {
                    continue;
                }
                let (s, e) = self.stencil(yi, i);
                let q: [f64; STENCIL_DOFS] = std::array::from_fn(|k| x[s[k]]);
                let (xs, th) = crate::bending::split_stencil(&q);
                let v = self.vertex_offset[yi] + i;
                let strains = vertex_strains(
                    xs,
                    th,
                    [&self.frames[e[0]], &self.frames[e[1]]],
                    self.twist_hints[v],
                );
                self.twist_hints[v] = strains.reference_twist;
            }
        }
    }

    /// The rod frames and reference-twist hints ([`Self::rebase_frames`] changes them), to put back with
    /// [`Self::restore_frames`] when a trial state is abandoned.
    pub fn frames_snapshot(&self) -> FramesSnapshot {
        FramesSnapshot {
            frames: self.frames.clone(),
            twist_hints: self.twist_hints.clone(),
        }
    }

    /// Puts back frames saved by [`Self::frames_snapshot`] of this model.
    pub fn restore_frames(&mut self, saved: &FramesSnapshot) {
        self.frames.clone_from(&saved.frames);
        self.twist_hints.clone_from(&saved.twist_hints);
    }

    /// Whether two global edges never contact: the same edge, or edges of one yarn whose arclength gap
    /// (rest lengths of the edges strictly between, either way round a closed yarn) is below the exclusion
    /// arclength, or which share a vertex.
    pub fn excluded(&self, e1: usize, e2: usize) -> bool {
        let (y1, k1) = self.edge_owner(e1);
        let (y2, k2) = self.edge_owner(e2);
        if y1 != y2 {
            return false;
        }
        if k1 == k2 {
            return true;
        }
        let (a, b) = (k1.min(k2), k1.max(k2));
        let yarn = &self.patch.yarns[y1];
        let base = self.edge_offset[y1] + y1; // arclength has one extra entry per yarn before this one
        let cum = |k: usize| self.arclength[base + k];
        let forward = cum(b) - cum(a + 1);
        let cutoff = self.stiffness.contact_exclusion;
        if b == a + 1 || forward < cutoff {
            return true;
        }
        if yarn.closed {
            let m = yarn.edge_count();
            let backward = cum(m) - cum(b + 1) + cum(a);
            if (a == 0 && b == m - 1) || backward < cutoff {
                return true;
            }
        }
        false
    }

    /// Candidate contact pairs `(e1, e2)` of global edges, `e1 < e2`, sorted, exclusions removed.
    pub fn contact_candidates(&self, x: &[f64]) -> Vec<(usize, usize)> {
        let mut segments = Vec::with_capacity(self.edge_count());
        for (yi, y) in self.patch.yarns.iter().enumerate() {
            for k in 0..y.edge_count() {
                let (a, b) = self.edge_vertices(yi, k);
                segments.push((Self::pos(x, a), Self::pos(x, b)));
            }
        }
        let mut pairs = candidate_pairs(&segments, self.stiffness.contact_distance, 0.0);
        pairs.retain(|&(a, b)| !self.excluded(a, b));
        pairs
    }

    /// The 12 global unknowns (the positions of `p₀, p₁, q₀, q₁`) and the rest lengths (m) of the segment
    /// pair of global edges `e1, e2`.
    pub(crate) fn contact_dofs(&self, e1: usize, e2: usize) -> ([usize; CONTACT_DOFS], [f64; 2]) {
        let (y1, k1) = self.edge_owner(e1);
        let (y2, k2) = self.edge_owner(e2);
        let (a0, a1) = self.edge_vertices(y1, k1);
        let (b0, b1) = self.edge_vertices(y2, k2);
        let verts = [a0, a1, b0, b1];
        (
            std::array::from_fn(|i| 4 * verts[i / 3] + i % 3),
            [
                self.patch.yarns[y1].rest_length[k1],
                self.patch.yarns[y2].rest_length[k2],
            ],
        )
    }

    /// The smallest centreline distance (m) that any pair of non-excluded segments can reach while every
    /// vertex moves on a straight line from `x0` to `x1`, bounded from below: the distance between two
    /// segments changes by at most the largest relative displacement of an end of one against an end of the
    /// other (the closest points are convex combinations of the ends), so along the motion it stays above
    /// `d(x0) − max_ij |Δa_i − Δb_j|`. Pairs are the candidates of the swept segments (boxes covering both
    /// positions, inflated by the contact distance); infinite when there is none. A motion with a bound
    /// above zero carries no yarn through another.
    pub fn swept_clearance(&self, x0: &[f64], x1: &[f64]) -> f64 {
        let mut boxes = Vec::with_capacity(self.edge_count());
        for (yi, y) in self.patch.yarns.iter().enumerate() {
            for k in 0..y.edge_count() {
                let (a, b) = self.edge_vertices(yi, k);
                let pts = [
                    Self::pos(x0, a),
                    Self::pos(x0, b),
                    Self::pos(x1, a),
                    Self::pos(x1, b),
                ];
                let lo: [f64; 3] =
                    std::array::from_fn(|c| pts.iter().map(|p| p[c]).fold(f64::INFINITY, f64::min));
                let hi: [f64; 3] = std::array::from_fn(|c| {
                    pts.iter().map(|p| p[c]).fold(f64::NEG_INFINITY, f64::max)
                });
                boxes.push((lo, hi));
            }
        }
        let mut bound = f64::INFINITY;
        for (e1, e2) in candidate_pairs(&boxes, self.stiffness.contact_distance, 0.0) {
            if self.excluded(e1, e2) {
                continue;
            }
            let (d, _) = self.contact_dofs(e1, e2);
            let p = |x: &[f64], i: usize| [x[d[3 * i]], x[d[3 * i + 1]], x[d[3 * i + 2]]];
            let dist = crate::segment_distance::distance(p(x0, 0), p(x0, 1), p(x0, 2), p(x0, 3));
            let delta = |i: usize| sub(p(x1, i), p(x0, i));
            let mut rel = 0.0f64;
            for i in 0..2 {
                for j in 2..4 {
                    rel = rel.max(norm(sub(delta(i), delta(j))));
                }
            }
            bound = bound.min(dist - rel);
        }
        bound
    }

    /// The smallest centreline distance (m) between non-excluded segment pairs within the contact distance
    /// of each other at `x`; infinite when none is.
    pub fn min_distance(&self, x: &[f64]) -> f64 {
        self.contact_candidates(x)
            .into_iter()
            .map(|(e1, e2)| {
                let (d, _) = self.contact_dofs(e1, e2);
                let p = |i: usize| [x[d[3 * i]], x[d[3 * i + 1]], x[d[3 * i + 2]]];
                crate::segment_distance::distance(p(0), p(1), p(2), p(3))
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Energy (J), gradient and, if `hessian`, the Hessian's lower triangle at `x` (4 unknowns per vertex).
    ///
    /// The terms are split into chunks (yarns and their vertices, contact pairs) evaluated on up to
    /// [`std::thread::available_parallelism`] threads and summed in chunk order, so the result does not
    /// depend on timing.
    pub fn evaluate(&self, x: &[f64], hessian: bool) -> PatchEvaluation {
        self.evaluate_order(
            x,
            if hessian {
                Order::Hessian
            } else {
                Order::Gradient
            },
        )
    }

    /// [`Self::evaluate`] to the given order: with [`Order::Energy`] every term is evaluated on plain numbers
    /// (no jets), the gradient is empty and the energy, its parts and the contact counts are those of the
    /// full evaluation (to rounding).
    pub fn evaluate_order(&self, x: &[f64], order: Order) -> PatchEvaluation {
        let pairs = self.contact_candidates(x);
        let threads = std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
            .min(16);
        let yarns = self.patch.yarns.len();
        let chunks = if self.vertex_count() + pairs.len() < 4000 {
            1
        } else {
            threads
        };
        let yarn_chunk = yarns.div_ceil(chunks);
        let pair_chunk = pairs.len().div_ceil(chunks).max(1);
        // Recycled triplet vectors, the largest for the first part (the others are appended to it).
        let mut buffers: Vec<Vec<Triplet<usize, usize, f64>>> = (0..chunks)
            .map(|_| {
                if order == Order::Hessian {
                    self.pooled_triplets()
                } else {
                    Vec::new()
                }
            })
            .collect();
        let parts: Vec<PatchEvaluation> = if chunks == 1 {
            vec![self.evaluate_part(
                x,
                order,
                0..yarns,
                &pairs,
                buffers.pop().unwrap_or_default(),
            )]
        } else {
            std::thread::scope(|scope| {
                let handles: Vec<_> = (0..chunks)
                    .zip(buffers)
                    .map(|(c, buffer)| {
                        let ys = (c * yarn_chunk).min(yarns)..((c + 1) * yarn_chunk).min(yarns);
                        let ps = &pairs[(c * pair_chunk).min(pairs.len())
                            ..((c + 1) * pair_chunk).min(pairs.len())];
                        scope.spawn(move || self.evaluate_part(x, order, ys, ps, buffer))
                    })
                    .collect();
                handles
                    .into_iter()
                    .map(|h| h.join().expect("an evaluation thread panicked"))
                    .collect()
            })
        };
        let mut parts = parts.into_iter();
        let mut ev = parts.next().unwrap_or_default();
        if order == Order::Hessian {
            // Room for the other parts and one entry per unknown (a caller's diagonal terms), so that
            // neither reallocates the ~100 MB vector.
            let total: usize = parts.as_slice().iter().map(|p| p.hessian.len()).sum();
            ev.hessian.reserve_exact(total + self.dof_count());
        }
        for p in parts {
            ev.energy += p.energy;
            for k in 0..ev.parts.len() {
                ev.parts[k] += p.parts[k];
            }
            for (a, b) in ev.gradient.iter_mut().zip(&p.gradient) {
                *a += b;
            }
            ev.hessian.extend_from_slice(&p.hessian);
            self.recycle(p.hessian);
            ev.contacts += p.contacts;
            ev.candidates += p.candidates;
            ev.sphere_contacts += p.sphere_contacts;
            ev.min_distance = ev.min_distance.min(p.min_distance);
        }
        ev
    }

    /// Hands back the Hessian triplets of an evaluation (e.g. once a Newton iteration has assembled them):
    /// later evaluations fill the emptied vector instead of allocating — on a 16 × 16 patch ~100 MB, whose
    /// fresh pages cost page faults and zeroing in every iteration.
    pub fn recycle(&self, mut triplets: Vec<Triplet<usize, usize, f64>>) {
        triplets.clear();
        let mut pool = self.triplet_pool.lock().unwrap_or_else(|e| e.into_inner());
        if pool.len() < TRIPLET_POOL {
            pool.push(triplets);
        }
    }

    /// An empty triplet vector, with the capacity of a recycled one when there is one (the largest).
    fn pooled_triplets(&self) -> Vec<Triplet<usize, usize, f64>> {
        let mut pool = self.triplet_pool.lock().unwrap_or_else(|e| e.into_inner());
        let largest = (0..pool.len()).max_by_key(|&i| pool[i].capacity());
        largest.map_or_else(Vec::new, |i| pool.swap_remove(i))
    }

    /// The terms of the yarns `yarns` (their edges, interior vertices, gravity and sphere) and of the contact
    /// pairs `pairs`, with a full-length gradient (empty for [`Order::Energy`]); the Hessian triplets (for
    /// [`Order::Hessian`]) fill the emptied vector `hessian`.
    fn evaluate_part(
        &self,
        x: &[f64],
        order: Order,
        yarns: std::ops::Range<usize>,
        pairs: &[(usize, usize)],
        hessian: Vec<Triplet<usize, usize, f64>>,
    ) -> PatchEvaluation {
        let mut ev = PatchEvaluation {
            gradient: if order >= Order::Gradient {
                vec![0.0; self.dof_count()]
            } else {
                Vec::new()
            },
            min_distance: f64::INFINITY,
            ..Default::default()
        };
        if order == Order::Hessian {
            // Upper bound of the triplets: 21 per edge, 66 per rod vertex, 6 per sphere contact, 78 per
            // contact pair (lower triangles with diagonals); one allocation instead of doublings.
            let mut edges = 0;
            let mut vertices = 0;
            for yi in yarns.clone() {
                edges += self.patch.yarns[yi].edge_count();
                vertices += self.patch.yarns[yi].positions.len();
            }
            let sphere = if self.loads.sphere.is_some() { 6 } else { 0 };
            let bonds: usize = yarns
                .clone()
                .map(|yi| self.bonds.get(yi).map_or(0, Vec::len))
                .sum();
            ev.hessian = hessian;
            ev.hessian
                .reserve(21 * (edges + bonds) + (66 + sphere) * vertices + 78 * pairs.len() / 4);
        }
        fn scatter<const N: usize>(
            ev: &mut PatchEvaluation,
            order: Order,
            part: usize,
            dofs: &[usize; N],
            e: f64,
            g: &[f64; N],
            h: &[[f64; N]; N],
        ) {
            ev.energy += e;
            ev.parts[part] += e;
            if order >= Order::Gradient {
                for k in 0..N {
                    ev.gradient[dofs[k]] += g[k];
                }
            }
            if order == Order::Hessian {
                for a in 0..N {
                    for b in 0..N {
                        let (r, c) = (dofs[a], dofs[b]);
                        if r >= c && h[a][b] != 0.0 {
                            ev.hessian.push(Triplet::new(r, c, h[a][b]));
                        }
                    }
                }
            }
        }
        fn add_energy(ev: &mut PatchEvaluation, part: usize, e: f64) {
            ev.energy += e;
            ev.parts[part] += e;
        }
        let r = self.patch.radius;
        for yi in yarns {
            let y = &self.patch.yarns[yi];
            // The yarn's edges, then the bonds of its cut ends: the same stretching energy.
            let edges = (0..y.edge_count()).map(|k| {
                let (a, b) = self.edge_vertices(yi, k);
                (a, b, y.rest_length[k])
            });
            let bonds = self.bonds.get(yi).into_iter().flatten();
            let bonds = bonds.map(|b| (b.vertices[0], b.vertices[1], b.rest_length));
            for (a, b, rest_length) in edges.chain(bonds) {
                let edge = StretchingEdge {
                    rest_length,
                    stiffness: self.stiffness.stretching,
                };
                if order == Order::Energy {
                    add_energy(&mut ev, 0, edge.energy(Self::pos(x, a), Self::pos(x, b)));
                    continue;
                }
                let (e, g, h) = edge.derivatives(Self::pos(x, a), Self::pos(x, b));
                let dofs = [4 * a, 4 * a + 1, 4 * a + 2, 4 * b, 4 * b + 1, 4 * b + 2];
                scatter(&mut ev, order, 0, &dofs, e, &g, &h);
            }
            for i in 0..y.positions.len() {
                let (Some(kappa), Some(twist)) = (y.rest_curvature[i], y.rest_twist[i]) else {
                    continue;
                };
                let (s, edges) = self.stencil(yi, i);
                let q: [f64; STENCIL_DOFS] = std::array::from_fn(|k| x[s[k]]);
                let n = y.positions.len();
                let prev = (i + n - 1) % n;
                let voronoi = 0.5 * (y.rest_length[prev] + y.rest_length[i]);
                let frames = [self.frames[edges[0]], self.frames[edges[1]]];
                let vertex = RodVertex {
                    bending: BendingVertex {
                        frames,
                        rest_curvature: kappa,
                        voronoi_length: voronoi,
                        stiffness: self.stiffness.bending,
                    },
                    twisting: TwistingVertex {
                        frames,
                        rest_twist: twist,
                        reference_twist_hint: self.twist_hints[self.vertex_offset[yi] + i],
                        voronoi_length: voronoi,
                        stiffness: self.stiffness.twisting,
                    },
                };
                if order == Order::Energy {
                    let [eb, et] = vertex.energies(&q);
                    add_energy(&mut ev, 1, eb);
                    add_energy(&mut ev, 2, et);
                    continue;
                }
                // Bending and twisting share the vertex strains: one jet evaluation for both.
                let ([eb, et], g, h) = vertex.derivatives(&q);
                scatter(&mut ev, order, 1, &s, eb, &g, &h);
                ev.energy += et;
                ev.parts[2] += et;
            }
            for v in self.vertex_offset[yi]..self.vertex_offset[yi + 1] {
                let p = Self::pos(x, v);
                let dofs = [4 * v, 4 * v + 1, 4 * v + 2];
                let grav = GravityVertex {
                    mass: self.masses[v],
                    acceleration: self.loads.gravity,
                };
                let (e, g) = grav.derivatives(p);
                scatter(
                    &mut ev,
                    order.min(Order::Gradient),
                    4,
                    &dofs,
                    e,
                    &g,
                    &[[0.0; 3]; 3],
                );
                if let Some(sphere) = &self.loads.sphere
                    && let Some((e, g, h)) = sphere.derivatives(p, r, self.voronoi[v])
                {
                    ev.sphere_contacts += 1;
                    scatter(&mut ev, order, 5, &dofs, e, &g, &h);
                }
            }
        }
        for &(e1, e2) in pairs {
            let (dofs, rest_lengths) = self.contact_dofs(e1, e2);
            let q: [f64; CONTACT_DOFS] = std::array::from_fn(|k| x[dofs[k]]);
            let pair = ContactPair {
                rest_lengths,
                contact_distance: self.stiffness.contact_distance,
                stiffness: self.stiffness.contact,
                kernel: self.stiffness.contact_kernel,
            };
            ev.candidates += 1;
            let (d, _) = pair.distance(&q);
            ev.min_distance = ev.min_distance.min(d);
            if d >= pair.contact_distance {
                continue;
            }
            if order == Order::Energy {
                let e = pair.energy_within(&q);
                if e > 0.0 {
                    ev.contacts += 1;
                    add_energy(&mut ev, 3, e);
                }
                continue;
            }
            if let Some((e, g, h)) = pair.derivatives_within(&q, order == Order::Hessian) {
                ev.contacts += 1;
                scatter(&mut ev, order, 3, &dofs, e, &g, &h);
            }
        }
        ev
    }
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    scale(v, 1.0 / norm(v))
}

/// A rigid motion of a patch: every position `p ↦ R p + t` and every reference director `d ↦ R d`, with
/// `R` a rotation (row-major) and `t` in m. The rest data (lengths, material curvatures, twists) are
/// invariant, so the rotated patch has the same energy at the rotated state.
pub fn transform_patch(patch: &Patch, rotation: [[f64; 3]; 3], translation: [f64; 3]) -> Patch {
    let rot = |p: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|i| (0..3).map(|j| rotation[i][j] * p[j]).sum::<f64>())
    };
    let mut out = patch.clone();
    for y in &mut out.yarns {
        for p in &mut y.positions {
            let q = rot(*p);
            *p = std::array::from_fn(|k| q[k] + translation[k]);
        }
        for d in &mut y.reference_director {
            *d = rot(*d);
        }
    }
    out
}

#[cfg(test)]
mod tests;
