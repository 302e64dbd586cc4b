//! The Loop subdivision limit surface of a closed triangle mesh (thesis appendix A; Stam 1998).
//!
//! Faces whose three vertices are regular (valence 6) use the 12 box-spline basis functions of Eq. 189
//! ([`crate::surface::loop_regular_patch`]); faces with exactly one extraordinary vertex use Stam's exact evaluation
//! ([`crate::surface::loop_irregular_patch`]). Faces with two or three extraordinary vertices have no such
//! evaluation: [`LoopSurface::new`] rejects them, naming the face, and
//! [`LoopSurface::with_preprocessing_subdivision`] subdivides the mesh once (after which every face has at
//! most one extraordinary vertex) and composes every stencil with the subdivision map `S`, so stencils stay
//! in the ORIGINAL control vertices while the surface faces are the refined ones.
//!
//! Coordinates follow [`crate::surface`]: in face `[v0, v1, v2]`, `s1` weighs `v0`, `s2` weighs `v1`,
//! `s3 = 1 − s1 − s2` weighs `v2`.

use crate::math::{FaceId, Real, Vec2, VertexId};
use crate::mesh::topology::Topology;
use crate::surface::loop_irregular_patch::{IrregularPatch, LocalWeights, chain};
use crate::surface::loop_regular_patch::regular_basis;
use crate::surface::loop_subdivision::{LoopRefinement, child_coords, loop_subdivision};
use crate::surface::{LimitSurface, Stencil, SurfaceCoord, SurfaceError, checked_coords};

/// Largest supported valence.
pub const MAX_VALENCE: usize = 32;

/// Per-face evaluation data.
#[derive(Clone, Copy, Debug)]
struct Patch {
    /// Offset of the local control ids in `LoopSurface::ids`.
    offset: usize,
    /// Valence of the extraordinary vertex; 6 for a regular face.
    valence: usize,
    /// Local corner (0..3) of the extraordinary vertex: the face is evaluated as `[A, B, C]` =
    /// `[f[r+1], f[r+2], f[r]]`. Regular faces use `r = 2` (no rotation).
    rotation: usize,
}

/// Regular-patch label order (Eq. 189, 0-based) → index in the valence-6 local layout of
/// [`crate::surface::loop_irregular_patch`].
const REGULAR_FROM_LAYOUT: [usize; 12] = [3, 4, 2, 0, 5, 7, 1, 6, 11, 8, 9, 10];

/// The Loop limit surface; see the module docs.
#[derive(Clone, Debug)]
pub struct LoopSurface {
    /// Connectivity of the surface faces (refined ones after preprocessing).
    topology: Topology,
    /// Number of control vertices of the stencils (the original mesh's).
    num_control: usize,
    patches: Vec<Patch>,
    /// Local control vertex ids (in `topology`'s vertex numbering) of all patches.
    ids: Vec<VertexId>,
    /// Evaluation tables indexed by valence.
    tables: Vec<Option<IrregularPatch>>,
    /// The preprocessing subdivision, if any.
    refinement: Option<LoopRefinement>,
}

impl LoopSurface {
    /// The limit surface of the closed mesh `faces` over `num_vertices` control vertices. Errors if the mesh
    /// is not a closed oriented manifold, has a vertex of valence outside `3..=MAX_VALENCE`, or has a face
    /// with more than one extraordinary vertex (naming it).
    pub fn new(num_vertices: usize, faces: &[[VertexId; 3]]) -> Result<Self, SurfaceError> {
        let topology = closed_topology(num_vertices, faces)?;
        Self::build(topology, num_vertices, None)
    }

    /// Like [`LoopSurface::new`], but first subdivides the mesh once so that every face has at most one
    /// extraordinary vertex. Surface faces are the `4 #F` refined faces (children of face `f` are `4f..4f+4`,
    /// see [`crate::surface::loop_subdivision`]); stencils are expressed in the original `num_vertices` control
    /// vertices.
    pub fn with_preprocessing_subdivision(
        num_vertices: usize,
        faces: &[[VertexId; 3]],
    ) -> Result<Self, SurfaceError> {
        let coarse = closed_topology(num_vertices, faces)?;
        let refinement = loop_subdivision(&coarse)?;
        let topology = Topology::new(refinement.num_vertices, &refinement.faces)?;
        Self::build(topology, num_vertices, Some(refinement))
    }

    fn build(
        topology: Topology,
        num_control: usize,
        refinement: Option<LoopRefinement>,
    ) -> Result<Self, SurfaceError> {
        let mut tables: Vec<Option<IrregularPatch>> = (0..=MAX_VALENCE).map(|_| None).collect();
        let mut patches = Vec::with_capacity(topology.num_faces());
        let mut ids = Vec::with_capacity(topology.num_faces() * 12);
        let mut local = Vec::with_capacity(MAX_VALENCE + 6);
        for (f, face) in topology.faces().iter().enumerate() {
            let irregular: Vec<usize> =
                (0..3).filter(|&c| topology.valence(face[c]) != 6).collect();
            if irregular.len() > 1 {
                return Err(SurfaceError::TooManyIrregular {
                    face: f,
                    count: irregular.len(),
                });
            }
            let rotation = irregular.first().copied().unwrap_or(2);
            let valence = topology.valence(face[rotation]);
            gather_patch(&topology, f, rotation, valence, &mut local);
            let offset = ids.len();
            if valence == 6 {
                ids.extend(REGULAR_FROM_LAYOUT.iter().map(|&i| local[i]));
            } else {
                ids.extend_from_slice(&local);
                if tables[valence].is_none() {
                    tables[valence] = Some(IrregularPatch::new(valence));
                }
            }
            patches.push(Patch {
                offset,
                valence,
                rotation,
            });
        }
        Ok(Self {
            topology,
            num_control,
            patches,
            ids,
            tables,
            refinement,
        })
    }

    /// The preprocessing subdivision (map `S` and refined faces), if the surface was built with one.
    pub fn refinement(&self) -> Option<&LoopRefinement> {
        self.refinement.as_ref()
    }

    /// The original mesh face that surface face `face` lies in (itself without preprocessing).
    pub fn parent_face(&self, face: FaceId) -> FaceId {
        match &self.refinement {
            Some(r) => r.parent_face(face),
            None => face,
        }
    }

    /// The surface location of coordinates `s` in ORIGINAL mesh face `face` (itself without preprocessing;
    /// with it, the refined child face containing the point and its coordinates there).
    pub fn coord_in_original_face(
        &self,
        face: FaceId,
        s: Vec2,
    ) -> Result<SurfaceCoord, SurfaceError> {
        let num_original = match &self.refinement {
            Some(_) => self.patches.len() / 4,
            None => self.patches.len(),
        };
        let [s1, s2] = checked_coords(face, num_original, s)?;
        let s = Vec2::new(s1, s2);
        Ok(match &self.refinement {
            Some(_) => {
                let (f, t) = child_coords(face, s);
                SurfaceCoord { face: f, s: t }
            }
            None => SurfaceCoord { face, s },
        })
    }

    /// Whether surface face `face` has an extraordinary vertex (`false` for a face id out of range).
    pub fn is_irregular(&self, face: FaceId) -> bool {
        self.patches.get(face).is_some_and(|p| p.valence != 6)
    }

    /// Weights of the local control vertices of `face` at clamped coordinates `(s1, s2)` into `w`; returns
    /// the local ids.
    fn local_weights(
        &self,
        face: FaceId,
        s1: Real,
        s2: Real,
        w: &mut [LocalWeights],
    ) -> &[VertexId] {
        let patch = self.patches[face];
        if patch.valence == 6 {
            let basis = regular_basis(s1, s2);
            w[..12].copy_from_slice(&basis);
            return &self.ids[patch.offset..patch.offset + 12];
        }
        // Rotate so that the extraordinary vertex is at s3 = 1: u = (weight of f[r+1], weight of f[r+2]).
        let s3 = 1.0 - s1 - s2;
        let (u1, u2, jac) = match patch.rotation {
            0 => (s2, s3, [[0.0, 1.0], [-1.0, -1.0]]),
            1 => (s3, s1, [[-1.0, -1.0], [1.0, 0.0]]),
            _ => (s1, s2, [[1.0, 0.0], [0.0, 1.0]]),
        };
        let table = self.tables[patch.valence]
            .as_ref()
            .expect("tables exist for every valence in the mesh");
        let k = table.num_control();
        table.weights(u1, u2, &mut w[..k]);
        if patch.rotation != 2 {
            for x in w[..k].iter_mut() {
                *x = chain(x, &jac);
            }
        }
        &self.ids[patch.offset..patch.offset + k]
    }
}

impl LimitSurface for LoopSurface {
    fn num_faces(&self) -> usize {
        self.patches.len()
    }

    fn num_control_vertices(&self) -> usize {
        self.num_control
    }

    fn topology(&self) -> &Topology {
        &self.topology
    }

    fn stencil(&self, face: FaceId, s: Vec2, out: &mut Stencil) -> Result<(), SurfaceError> {
        let [s1, s2] = checked_coords(face, self.num_faces(), s)?;
        let mut w = [[0.0; 6]; MAX_VALENCE + 6];
        let ids = self.local_weights(face, s1, s2, &mut w);
        out.clear();
        match &self.refinement {
            None => {
                for (&v, x) in ids.iter().zip(&w) {
                    out.add(v, 1.0, x[0], [x[1], x[2]], [x[3], x[4], x[5]]);
                }
            }
            Some(r) => {
                for (&v, x) in ids.iter().zip(&w) {
                    for (orig, sw) in r.subdivision.row(v) {
                        out.add(orig, sw, x[0], [x[1], x[2]], [x[3], x[4], x[5]]);
                    }
                }
            }
        }
        Ok(())
    }
}

/// Topology of a closed mesh with valences in `3..=MAX_VALENCE`.
fn closed_topology(num_vertices: usize, faces: &[[VertexId; 3]]) -> Result<Topology, SurfaceError> {
    let topology = Topology::new(num_vertices, faces)?;
    if let Some(&(a, b)) = topology.boundary_edges().first() {
        return Err(SurfaceError::Boundary { a, b });
    }
    for v in 0..num_vertices {
        let n = topology.valence(v);
        if n == 0 {
            continue; // isolated vertex: not part of the surface
        }
        if !(3..=MAX_VALENCE).contains(&n) {
            return Err(SurfaceError::Valence {
                vertex: v,
                valence: n,
                max: MAX_VALENCE,
            });
        }
    }
    Ok(topology)
}

/// The third vertex of the face across local edge `e` of face `f`, with that face and its edge index.
fn across(t: &Topology, f: FaceId, e: usize) -> (VertexId, FaceId, usize) {
    let tw = t.twin(f, e).expect("closed mesh: every edge has a twin");
    (t.faces()[tw.face][(tw.edge + 2) % 3], tw.face, tw.edge)
}

/// Collects the `N + 6` local control vertices of face `f` with the extraordinary (or, if regular, the
/// chosen) vertex at local corner `r` into `out`, in the layout of [`crate::surface::loop_irregular_patch`].
fn gather_patch(t: &Topology, f: FaceId, r: usize, n: usize, out: &mut Vec<VertexId>) {
    let face = t.faces()[f];
    let (a, b, c) = (face[(r + 1) % 3], face[(r + 2) % 3], face[r]);
    out.clear();
    out.push(c);
    // Ring of C from A away from B: across the edge C → (current ring vertex) lies the next one.
    out.push(a);
    let (mut g, mut corner) = (f, r);
    for _ in 1..n {
        let tw = t.twin(g, corner).expect("closed mesh");
        let h = t.faces()[tw.face];
        out.push(h[(tw.edge + 2) % 3]);
        g = tw.face;
        corner = (tw.edge + 1) % 3;
    }
    debug_assert_eq!(out[n], b, "the ring of C ends at B");
    // H_A = [A, C, r2] across C → A; X6 across its edge r2 → A.
    let (_, ha, ea) = across(t, f, r);
    let (x6, _, _) = across(t, ha, (ea + 2) % 3);
    // H_AB = [B, A, X11] across A → B; X10 across A → X11, X12 across X11 → B.
    let (x11, hab, eab) = across(t, f, (r + 1) % 3);
    let (x10, _, _) = across(t, hab, (eab + 1) % 3);
    let (x12, _, _) = across(t, hab, (eab + 2) % 3);
    // H_B = [C, B, r_{N−1}] across B → C; X9 across B → r_{N−1}.
    let (_, hb, eb) = across(t, f, (r + 2) % 3);
    let (x9, _, _) = across(t, hb, (eb + 1) % 3);
    out.extend_from_slice(&[x6, x10, x11, x12, x9]);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The subdivision-based evaluator on a valence-6 configuration agrees with the box-spline formula
    /// (Eq. 189) — pins the local layout, the extended matrix and the picking of the three sub-patches.
    #[test]
    fn regular_formula_agrees_with_irregular_evaluator_at_valence_six() {
        let table = IrregularPatch::new(6);
        let mut w = vec![[0.0; 6]; 12];
        for &(s1, s2) in &[
            (0.2, 0.3),
            (0.7, 0.1),
            (0.1, 0.75),
            (0.3, 0.3),
            (0.01, 0.02),
            (1e-6, 3e-7),
            (0.5, 0.5),
            (0.0, 1.0),
        ] {
            table.weights(s1, s2, &mut w);
            let basis = regular_basis(s1, s2);
            for (label, &layout) in REGULAR_FROM_LAYOUT.iter().enumerate() {
                for c in 0..6 {
                    let (a, b) = (w[layout][c], basis[label][c]);
                    assert!(
                        (a - b).abs() < 1e-9 * (1.0 + b.abs()),
                        "({s1}, {s2}) label {} component {c}: {a} vs {b}",
                        label + 1
                    );
                }
            }
        }
    }
}
