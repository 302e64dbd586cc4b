//! The energy of one periodic cell of a yarn pattern under a prescribed in-plane macro deformation.
//!
//! **Macro deformation** (`shared/data/yarns/README.md`, MADYPG's strain parametrisation): `sx`, `sy` are
//! the stretches of the material x and y directions minus one and `sa` the cosine of the angle between
//! them, i.e. the first fundamental form `I = [[(1+sx)², sa(1+sx)(1+sy)], [sa(1+sx)(1+sy), (1+sy)²]]`. Any
//! `F` with `FᵀF = I` gives the same yarn up to a rotation; this crate takes the upper-triangular one
//! `F = [[1+sx, sa(1+sy)], [0, (1+sy)√(1−sa²)]]` ([`deformation_gradient`]).
//!
//! **Unknowns**: per pattern vertex `v` its deformed position `y_v` (m) and the material angle `θ_v` of the
//! edge starting there (rad), 4 per vertex, in that order. The periodic image of vertex `v` shifted by
//! `s` periods is `y_v + (F (s_x px, s_y py), 0)`: edges that wrap across the cell reach their end through
//! the macro deformation. A vertex of the reference cell at `X` with displacement `d` in the reference cell
//! deforms to `(F (X_xy + d_xy), X_z + d_z)` (README), so the displacement of a solution is
//! `d = (F⁻¹ y_xy − X_xy, y_z − X_z)` ([`PeriodicCell::displacements`]).
//!
//! **Energy**: stretching of every edge, bending and twisting at every vertex (each vertex joins the edge
//! ending there and the one starting there), and contact between every pair of segments — with their
//! periodic images — closer than the contact distance, except pairs close along one yarn
//! ([`crate::yarn_params`]). Candidates come from the spatial hash over the segments and their images in
//! the 3 × 3 neighbouring cells.

use std::collections::HashSet;

use faer::sparse::Triplet;
use thiserror::Error;

use crate::bending::{BendingVertex, STENCIL_DOFS};
use crate::contact::{CONTACT_DOFS, ContactPair};
use crate::frames::{EdgeFrame, vertex_strains};
use crate::pyp::PeriodicPattern;
use crate::spatial_hash::candidate_pairs;
use crate::stencil_energy::StencilEnergy;
use crate::stretching::StretchingEdge;
use crate::twisting::TwistingVertex;
use crate::yarn_params::{RodStiffness, YarnParams};

/// Unknowns per vertex: position (3) and edge angle (1).
pub const DOFS_PER_VERTEX: usize = 4;

/// Errors setting up a periodic cell.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum CellError {
    /// The strain has no deformation gradient.
    #[error(
        "strain (sx, sa, sy) = ({sx}, {sa}, {sy}) is not a deformation: it needs 1 + sx > 0, 1 + sy > 0 and \
         |sa| < 1"
    )]
    InvalidStrain {
        /// Stretch x − 1.
        sx: f64,
        /// Cosine of the angle between the material axes.
        sa: f64,
        /// Stretch y − 1.
        sy: f64,
    },
    /// A parameter is out of range.
    #[error("{0}")]
    Params(String),
}

/// `F` (2 × 2, row-major) for strain `[sx, sa, sy]`; see the module documentation.
pub fn deformation_gradient(strain: [f64; 3]) -> Result<[[f64; 2]; 2], CellError> {
    let [sx, sa, sy] = strain;
    if !(1.0 + sx > 0.0 && 1.0 + sy > 0.0 && sa.abs() < 1.0) {
        return Err(CellError::InvalidStrain { sx, sa, sy });
    }
    Ok([
        [1.0 + sx, sa * (1.0 + sy)],
        [0.0, (1.0 + sy) * (1.0 - sa * sa).sqrt()],
    ])
}

/// A state of the cell: deformed positions (m) and edge angles (rad).
#[derive(Clone, Debug, PartialEq)]
pub struct CellState {
    /// Deformed position of every vertex (m).
    pub positions: Vec<[f64; 3]>,
    /// Material angle of every edge (rad).
    pub twist: Vec<f64>,
}

impl CellState {
    /// The unknowns as one vector (4 per vertex).
    pub fn to_vector(&self) -> Vec<f64> {
        let mut x = Vec::with_capacity(self.positions.len() * DOFS_PER_VERTEX);
        for (p, t) in self.positions.iter().zip(&self.twist) {
            x.extend_from_slice(&[p[0], p[1], p[2], *t]);
        }
        x
    }

    /// The state from an unknown vector.
    pub fn from_vector(x: &[f64]) -> Self {
        let n = x.len() / DOFS_PER_VERTEX;
        Self {
            positions: (0..n)
                .map(|v| [x[4 * v], x[4 * v + 1], x[4 * v + 2]])
                .collect(),
            twist: (0..n).map(|v| x[4 * v + 3]).collect(),
        }
    }
}

/// Energy, gradient and (optionally) Hessian of a cell state.
#[derive(Clone, Debug, Default)]
pub struct CellEvaluation {
    /// Total energy (J).
    pub energy: f64,
    /// Energy parts: stretching, bending, twisting, contact (J).
    pub parts: [f64; 4],
    /// Gradient (N for positions, N·m for angles).
    pub gradient: Vec<f64>,
    /// Hessian entries of the lower triangle (row ≥ column); duplicates add up.
    pub hessian: Vec<Triplet<usize, usize, f64>>,
    /// Segment pairs in contact.
    pub contacts: usize,
    /// Smallest distance between non-excluded segment pairs among the candidates (m).
    pub min_distance: f64,
}

/// One periodic cell: the pattern, its stiffnesses, the macro deformation and the rod frames.
#[derive(Clone, Debug)]
pub struct PeriodicCell {
    pattern: PeriodicPattern,
    stiffness: RodStiffness,
    f: [[f64; 2]; 2],
    prev: Vec<usize>,
    frames: Vec<EdgeFrame>,
    twist_hints: Vec<f64>,
    voronoi: Vec<f64>,
    excluded: HashSet<(usize, usize, [i32; 2])>,
}

/// A stencil coordinate: the unknown it reads and the constant offset added (m).
type Slot = (usize, f64);

impl PeriodicCell {
    /// The cell of `pattern` under strain `[sx, sa, sy]`, with frames transported to the affinely deformed
    /// pattern ([`Self::affine_state`]).
    pub fn new(
        pattern: &PeriodicPattern,
        params: &YarnParams,
        strain: [f64; 3],
    ) -> Result<Self, CellError> {
        params.validate().map_err(CellError::Params)?;
        let f = deformation_gradient(strain)?;
        let n = pattern.len();
        let prev = pattern.previous_edges();
        let stiffness = params.stiffness(pattern.radius);
        let voronoi = (0..n)
            .map(|i| 0.5 * (pattern.rest_length[prev[i]] + pattern.rest_length[i]))
            .collect();
        let mut cell = Self {
            pattern: pattern.clone(),
            stiffness,
            f,
            prev,
            frames: Vec::with_capacity(n),
            twist_hints: pattern.reference_twist.clone(),
            voronoi,
            excluded: HashSet::new(),
        };
        // Frames: the stored directors at the rest tangents (made exactly perpendicular), transported to the
        // affinely deformed tangents.
        let rest = CellState {
            positions: pattern.positions.clone(),
            twist: pattern.twist.clone(),
        };
        let rest_cell_f = cell.f;
        cell.f = [[1.0, 0.0], [0.0, 1.0]];
        for i in 0..n {
            let t = cell.tangent(&rest, i);
            let d = pattern.reference_director[i];
            let dn = crate::frames::dot(d, t);
            let mut frame = EdgeFrame {
                director: d,
                tangent: t,
            };
            frame.director = {
                let u = crate::frames::sub(d, crate::frames::scale(t, dn));
                crate::frames::scale(u, 1.0 / crate::frames::norm(u))
            };
            cell.frames.push(frame);
        }
        cell.f = rest_cell_f;
        let start = cell.affine_state();
        cell.rebase_frames(&start, 0.0);
        cell.excluded = cell.exclusions();
        Ok(cell)
    }

    /// The edge reference frames and the reference-twist hints (the 2π branch per vertex).
    pub fn frames(&self) -> (&[EdgeFrame], &[f64]) {
        (&self.frames, &self.twist_hints)
    }

    /// Replaces the edge frames and reference-twist hints (one per edge / vertex), e.g. to carry a
    /// solution's frames to a tiling of it.
    pub fn set_frames(&mut self, frames: Vec<EdgeFrame>, hints: Vec<f64>) -> Result<(), CellError> {
        let n = self.pattern.len();
        if frames.len() != n || hints.len() != n {
            return Err(CellError::Params(format!(
                "{} frames and {} twist hints given for {n} edges",
                frames.len(),
                hints.len()
            )));
        }
        self.frames = frames;
        self.twist_hints = hints;
        Ok(())
    }

    /// The pattern.
    pub fn pattern(&self) -> &PeriodicPattern {
        &self.pattern
    }

    /// The stiffnesses in use.
    pub fn stiffness(&self) -> &RodStiffness {
        &self.stiffness
    }

    /// The deformation gradient `F`.
    pub fn deformation(&self) -> [[f64; 2]; 2] {
        self.f
    }

    /// Number of unknowns.
    pub fn dof_count(&self) -> usize {
        self.pattern.len() * DOFS_PER_VERTEX
    }

    /// The pattern deformed affinely by `F` (positions `(F X_xy, X_z)`, angles as stored).
    pub fn affine_state(&self) -> CellState {
        CellState {
            positions: self
                .pattern
                .positions
                .iter()
                .map(|p| {
                    [
                        self.f[0][0] * p[0] + self.f[0][1] * p[1],
                        self.f[1][0] * p[0] + self.f[1][1] * p[1],
                        p[2],
                    ]
                })
                .collect(),
            twist: self.pattern.twist.clone(),
        }
    }

    /// The deformed offset (m) of the periodic shift `s`: `(F (s_x px, s_y py), 0)`.
    pub fn offset(&self, s: [i32; 2]) -> [f64; 3] {
        let a = s[0] as f64 * self.pattern.period[0];
        let b = s[1] as f64 * self.pattern.period[1];
        [
            self.f[0][0] * a + self.f[0][1] * b,
            self.f[1][0] * a + self.f[1][1] * b,
            0.0,
        ]
    }

    /// Displacements `(dx, dy, dz)` (m) of a state in the reference cell: `(F⁻¹ y_xy − X_xy, y_z − X_z)`.
    pub fn displacements(&self, state: &CellState) -> Vec<[f64; 3]> {
        let [[a, b], [c, d]] = self.f;
        let det = a * d - b * c;
        state
            .positions
            .iter()
            .zip(&self.pattern.positions)
            .map(|(y, x)| {
                let u = (d * y[0] - b * y[1]) / det;
                let v = (-c * y[0] + a * y[1]) / det;
                [u - x[0], v - x[1], y[2] - x[2]]
            })
            .collect()
    }

    fn edge_slots(&self, i: usize) -> [[Slot; 3]; 2] {
        let e = self.pattern.edges[i];
        let o = self.offset(e.shift);
        [
            std::array::from_fn(|k| (4 * i + k, 0.0)),
            std::array::from_fn(|k| (4 * e.end + k, o[k])),
        ]
    }

    fn tangent(&self, state: &CellState, i: usize) -> [f64; 3] {
        let e = self.pattern.edges[i];
        let o = self.offset(e.shift);
        let a = state.positions[i];
        let b = state.positions[e.end];
        let d = [b[0] + o[0] - a[0], b[1] + o[1] - a[1], b[2] + o[2] - a[2]];
        crate::frames::scale(d, 1.0 / crate::frames::norm(d))
    }

    /// The 11 stencil slots of vertex `i`: `x_prev`, `x_i`, `x_next` (positions relative to the previous
    /// edge's cell copy) and the two angles.
    fn vertex_slots(&self, i: usize) -> [Slot; STENCIL_DOFS] {
        let p = self.prev[i];
        let ep = self.pattern.edges[p];
        let ei = self.pattern.edges[i];
        let o1 = self.offset(ep.shift);
        let o2 = self.offset([ep.shift[0] + ei.shift[0], ep.shift[1] + ei.shift[1]]);
        let mut s = [(0, 0.0); STENCIL_DOFS];
        for k in 0..3 {
            s[k] = (4 * p + k, 0.0);
            s[3 + k] = (4 * i + k, o1[k]);
            s[6 + k] = (4 * ei.end + k, o2[k]);
        }
        s[9] = (4 * p + 3, 0.0);
        s[10] = (4 * i + 3, 0.0);
        s
    }

    /// Re-bases every edge frame whose tangent turned more than `angle` (rad, cos-threshold) since its last
    /// base, and updates the reference-twist hints; `angle = 0` re-bases all. The energy at `state` is
    /// unchanged.
    pub fn rebase_frames(&mut self, state: &CellState, angle: f64) {
        let n = self.pattern.len();
        for i in 0..n {
            let t = self.tangent(state, i);
            if angle <= 0.0 || crate::frames::dot(t, self.frames[i].tangent) < angle.cos() {
                self.frames[i].rebase(t);
            }
        }
        for i in 0..n {
            let (q, _) = self.vertex_q(state, i);
            let (x, th) = crate::bending::split_stencil(&q);
            let s = vertex_strains(
                x,
                th,
                [&self.frames[self.prev[i]], &self.frames[i]],
                self.twist_hints[i],
            );
            self.twist_hints[i] = s.reference_twist;
        }
    }

    fn vertex_q(&self, state: &CellState, i: usize) -> ([f64; STENCIL_DOFS], [Slot; STENCIL_DOFS]) {
        let slots = self.vertex_slots(i);
        let x = state.to_vector_ref();
        (std::array::from_fn(|k| x(slots[k])), slots)
    }

    /// Pairs `(i, j, s)` that never contact: `j` (shifted by `s`) within the exclusion arclength of `i`
    /// along the yarn, both ways, and every edge with itself.
    fn exclusions(&self) -> HashSet<(usize, usize, [i32; 2])> {
        let mut set = HashSet::new();
        let cutoff = self.stiffness.contact_exclusion;
        let n = self.pattern.len();
        for i in 0..n {
            set.insert((i, i, [0, 0]));
            let mut gap = 0.0;
            let mut shift = [0, 0];
            let mut j = i;
            for _ in 0..n {
                let e = self.pattern.edges[j];
                shift = [shift[0] + e.shift[0], shift[1] + e.shift[1]];
                let next = e.end;
                if next == i && shift == [0, 0] {
                    break;
                }
                set.insert((i, next, shift));
                set.insert((next, i, [-shift[0], -shift[1]]));
                gap += self.pattern.rest_length[next];
                j = next;
                if gap >= cutoff {
                    break;
                }
            }
        }
        set
    }

    /// Candidate contact pairs `(i, j, s)`: segment `i` against segment `j` shifted by `s`, each unordered
    /// pair once, exclusions removed.
    pub fn contact_candidates(&self, state: &CellState) -> Vec<(usize, usize, [i32; 2])> {
        let n = self.pattern.len();
        let mut segments = Vec::with_capacity(9 * n);
        let mut ids = Vec::with_capacity(9 * n);
        for sy in -1..=1 {
            for sx in -1..=1 {
                let o = self.offset([sx, sy]);
                for i in 0..n {
                    let [a, b] = self.edge_slots(i);
                    let x = state.to_vector_ref();
                    let pa: [f64; 3] = std::array::from_fn(|k| x(a[k]) + o[k]);
                    let pb: [f64; 3] = std::array::from_fn(|k| x(b[k]) + o[k]);
                    segments.push((pa, pb));
                    ids.push((i, [sx, sy]));
                }
            }
        }
        let margin = self.stiffness.contact_distance;
        let mut out = Vec::new();
        for (a, b) in candidate_pairs(&segments, margin, 0.0) {
            let (ia, sa) = ids[a];
            let (ib, sb) = ids[b];
            // Keep pairs with one segment in the cell itself; express as (i, j, s) relative to it.
            let (i, j, s) = if sa == [0, 0] {
                (ia, ib, sb)
            } else if sb == [0, 0] {
                (ib, ia, sa)
            } else {
                continue;
            };
            // Canonical orientation of the unordered pair {(i, 0), (j, s)} ~ {(j, 0), (i, −s)}.
            let alt = (j, i, [-s[0], -s[1]]);
            let (i, j, s) = if alt < (i, j, s) { alt } else { (i, j, s) };
            if self.excluded.contains(&(i, j, s)) {
                continue;
            }
            out.push((i, j, s));
        }
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Axial strain `|e|/L̄ − 1` of every edge at `state` (dimensionless).
    pub fn edge_strains(&self, state: &CellState) -> Vec<f64> {
        let x = state.to_vector_ref();
        (0..self.pattern.len())
            .map(|i| {
                let [a, b] = self.edge_slots(i);
                let d: [f64; 3] = std::array::from_fn(|k| x(b[k]) - x(a[k]));
                crate::frames::norm(d) / self.pattern.rest_length[i] - 1.0
            })
            .collect()
    }

    /// The closest non-excluded segment pair `(i, j, s, distance)` (distance in m) at `state`, if any
    /// candidate lies within the contact distance.
    pub fn closest_pair(&self, state: &CellState) -> Option<(usize, usize, [i32; 2], f64)> {
        let x = state.to_vector_ref();
        self.contact_candidates(state)
            .into_iter()
            .map(|(i, j, s)| {
                let slots = self.contact_slots(i, j, s);
                let q: [f64; CONTACT_DOFS] = std::array::from_fn(|k| x(slots[k]));
                let p = |k: usize| [q[3 * k], q[3 * k + 1], q[3 * k + 2]];
                (
                    i,
                    j,
                    s,
                    crate::segment_distance::distance(p(0), p(1), p(2), p(3)),
                )
            })
            .min_by(|a, b| a.3.total_cmp(&b.3))
    }

    /// Arclength gap (m, rest lengths of the edges strictly between) from edge `i` forward along its yarn
    /// to edge `j` shifted by `s`, if `j` is reached within one turn of the cell's yarn cycles.
    pub fn arclength_gap(&self, i: usize, j: usize, s: [i32; 2]) -> Option<f64> {
        let n = self.pattern.len();
        let (mut k, mut shift, mut gap) = (i, [0, 0], 0.0);
        for _ in 0..2 * n {
            let e = self.pattern.edges[k];
            shift = [shift[0] + e.shift[0], shift[1] + e.shift[1]];
            k = e.end;
            if k == j && shift == s {
                return Some(gap);
            }
            gap += self.pattern.rest_length[k];
        }
        None
    }

    fn contact_slots(&self, i: usize, j: usize, s: [i32; 2]) -> [Slot; CONTACT_DOFS] {
        let [a0, a1] = self.edge_slots(i);
        let [b0, b1] = self.edge_slots(j);
        let o = self.offset(s);
        let mut slots = [(0, 0.0); CONTACT_DOFS];
        for k in 0..3 {
            slots[k] = a0[k];
            slots[3 + k] = a1[k];
            slots[6 + k] = (b0[k].0, b0[k].1 + o[k]);
            slots[9 + k] = (b1[k].0, b1[k].1 + o[k]);
        }
        slots
    }

    /// Energy (J), gradient and, if `hessian`, the Hessian's lower triangle at `state`.
    pub fn evaluate(&self, state: &CellState, hessian: bool) -> CellEvaluation {
        let n = self.pattern.len();
        let x = state.to_vector_ref();
        let mut ev = CellEvaluation {
            gradient: vec![0.0; self.dof_count()],
            min_distance: f64::INFINITY,
            ..Default::default()
        };
        let scatter = |part: usize,
                       e: f64,
                       slots: &[Slot],
                       g: &[f64],
                       h: &dyn Fn(usize, usize) -> f64,
                       ev: &mut CellEvaluation| {
            ev.energy += e;
            ev.parts[part] += e;
            for (k, &(dof, _)) in slots.iter().enumerate() {
                ev.gradient[dof] += g[k];
            }
            if hessian {
                for a in 0..slots.len() {
                    for b in 0..slots.len() {
                        let (r, c) = (slots[a].0, slots[b].0);
                        if r >= c {
                            let v = h(a, b);
                            if v != 0.0 {
                                ev.hessian.push(Triplet::new(r, c, v));
                            }
                        }
                    }
                }
            }
        };
        for i in 0..n {
            let [a, b] = self.edge_slots(i);
            let edge = StretchingEdge {
                rest_length: self.pattern.rest_length[i],
                stiffness: self.stiffness.stretching,
            };
            let p0 = std::array::from_fn(|k| x(a[k]));
            let p1 = std::array::from_fn(|k| x(b[k]));
            let (e, g, h) = edge.derivatives(p0, p1);
            let slots: Vec<Slot> = a.iter().chain(b.iter()).copied().collect();
            scatter(0, e, &slots, &g, &|r, c| h[r][c], &mut ev);
        }
        for i in 0..n {
            let (q, slots) = self.vertex_q(state, i);
            let frames = [self.frames[self.prev[i]], self.frames[i]];
            let bend = BendingVertex {
                frames,
                rest_curvature: self.pattern.rest_curvature[i],
                voronoi_length: self.voronoi[i],
                stiffness: self.stiffness.bending,
            };
            let (e, g, h) = bend.derivatives(&q);
            scatter(1, e, &slots, &g, &|r, c| h[r][c], &mut ev);
            let twist = TwistingVertex {
                frames,
                rest_twist: self.pattern.rest_twist[i],
                reference_twist_hint: self.twist_hints[i],
                voronoi_length: self.voronoi[i],
                stiffness: self.stiffness.twisting,
            };
            let (e, g, h) = twist.derivatives(&q);
            scatter(2, e, &slots, &g, &|r, c| h[r][c], &mut ev);
        }
        for (i, j, s) in self.contact_candidates(state) {
            let slots = self.contact_slots(i, j, s);
            let q: [f64; CONTACT_DOFS] = std::array::from_fn(|k| x(slots[k]));
            let pair = ContactPair {
                rest_lengths: [self.pattern.rest_length[i], self.pattern.rest_length[j]],
                contact_distance: self.stiffness.contact_distance,
                stiffness: self.stiffness.contact,
                kernel: self.stiffness.contact_kernel,
            };
            let (d, _) = pair.distance(&q);
            ev.min_distance = ev.min_distance.min(d);
            if let Some((e, g, h)) = pair.derivatives(&q) {
                ev.contacts += 1;
                scatter(3, e, &slots, &g, &|r, c| h[r][c], &mut ev);
            }
        }
        ev
    }
}

impl crate::newton::NewtonProblem for PeriodicCell {
    fn dof_count(&self) -> usize {
        PeriodicCell::dof_count(self)
    }

    fn evaluate(
        &self,
        x: &[f64],
        hessian: bool,
    ) -> (f64, Vec<f64>, Vec<Triplet<usize, usize, f64>>) {
        let ev = PeriodicCell::evaluate(self, &CellState::from_vector(x), hessian);
        (ev.energy, ev.gradient, ev.hessian)
    }

    /// `max(‖f‖∞ / k_s, ‖τ‖∞ / (k_s r))`: forces over the axial stiffness (the force of a 100 % yarn strain),
    /// torques over that force times the radius.
    fn residual(&self, g: &[f64]) -> f64 {
        let ks = self.stiffness.stretching;
        let r = self.pattern.radius;
        g.iter()
            .enumerate()
            .map(|(k, v)| {
                if k % DOFS_PER_VERTEX == 3 {
                    v.abs() / (ks * r)
                } else {
                    v.abs() / ks
                }
            })
            .fold(0.0, f64::max)
    }

    /// At most a quarter radius of motion per coordinate and half a radian per angle.
    fn step_scale(&self, h: &[f64]) -> f64 {
        let r = self.pattern.radius;
        let mut scale = 1.0f64;
        for (k, v) in h.iter().enumerate() {
            let limit = if k % DOFS_PER_VERTEX == 3 {
                0.5
            } else {
                0.25 * r
            };
            if v.abs() > limit {
                scale = scale.min(limit / v.abs());
            }
        }
        scale
    }

    fn accepted(&mut self, x: &[f64]) {
        self.rebase_frames(&CellState::from_vector(x), 0.3);
    }
}

impl CellState {
    /// Reads a stencil slot: the unknown plus its offset.
    fn to_vector_ref(&self) -> impl Fn(Slot) -> f64 + '_ {
        move |(dof, offset): Slot| {
            let v = dof / DOFS_PER_VERTEX;
            let k = dof % DOFS_PER_VERTEX;
            if k < 3 {
                self.positions[v][k] + offset
            } else {
                self.twist[v] + offset
            }
        }
    }
}

#[cfg(test)]
mod tests;
