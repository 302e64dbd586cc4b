//! The structure of the Hessian `∂²U/∂q²`: the node list of every block (per body tetrahedron, per cloth
//! triangle) and the reserve of node pairs a cloth vertex meets after sliding one face over, so that the
//! sparsity pattern and its symbolic factorization survive sliding.

use super::{
    ClothOnBody, ClothOnBodyError, ClothOnBodyState, ElementScratch, Frames, SurfaceFrames,
};
use crate::math::Vec2;
use crate::node_block_assembly::{Node, NodeBlockAssembler, NodeBlockRecorder};
use skintight_geometry::{LimitSurface, Stencil};

/// Per surface face, the free body vertices of the stencils of the face and of its edge-neighbours
/// (sorted), as offsets and entries.
pub(super) fn face_reach(
    surface: &(dyn LimitSurface + Send + Sync),
    surface_body_vertex: &[usize],
    body_dof: &[Option<usize>],
) -> Result<(Vec<usize>, Vec<usize>), ClothOnBodyError> {
    let nf = surface.num_faces();
    let mut support = Vec::with_capacity(nf);
    let mut stencil = Stencil::with_capacity(64);
    for f in 0..nf {
        surface.stencil(f, Vec2::new(1.0 / 3.0, 1.0 / 3.0), &mut stencil)?;
        let mut vs: Vec<usize> = stencil
            .entries
            .iter()
            .map(|e| surface_body_vertex[e.vertex])
            .filter(|&v| body_dof[v].is_some())
            .collect();
        vs.sort_unstable();
        vs.dedup();
        support.push(vs);
    }
    let topology = surface.topology();
    let mut offsets = Vec::with_capacity(nf + 1);
    let mut entries = Vec::new();
    offsets.push(0);
    let mut reach = Vec::new();
    for f in 0..nf {
        reach.clear();
        reach.extend_from_slice(&support[f]);
        for e in 0..3 {
            if let Some(twin) = topology.twin(f, e) {
                reach.extend_from_slice(&support[twin.face]);
            }
        }
        reach.sort_unstable();
        reach.dedup();
        entries.extend_from_slice(&reach);
        offsets.push(entries.len());
    }
    Ok((offsets, entries))
}

impl ClothOnBody {
    /// Node list of cloth triangle `t` into `scratch.nodes` (unpinned corners' `s`, then the free body
    /// vertices of the corners' stencils, sorted, in `scratch.union`). Returns each corner's local offset
    /// (`usize::MAX` if pinned) and the local offset of the first body node.
    pub(super) fn element_nodes(
        &self,
        t: usize,
        frames: &Frames,
        scratch: &mut ElementScratch,
    ) -> ([usize; 3], usize) {
        let corners = self.triangles[t];
        scratch.union.clear();
        for &c in &corners {
            for &(v, _, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                if self.body_dof[v].is_some() {
                    scratch.union.push(v);
                }
            }
        }
        scratch.union.sort_unstable();
        scratch.union.dedup();
        scratch.nodes.clear();
        let mut s_corner = [usize::MAX; 3];
        let mut off = 0;
        for (i, &c) in corners.iter().enumerate() {
            if let Some(d) = self.cloth_dof[c] {
                scratch.nodes.push(Node {
                    first_dof: d,
                    dim: 2,
                });
                s_corner[i] = off;
                off += 2;
            }
        }
        for &v in &scratch.union {
            scratch.nodes.push(Node {
                first_dof: self.body_dof[v].expect("union holds free vertices"),
                dim: 3,
            });
        }
        (s_corner, off)
    }

    /// The node lists of every Hessian block at `frames` — the same blocks, in the same order, as
    /// [`Self::hessian_at`] emits — without computing any value (to fit the sparsity pattern first).
    pub fn structure(&self, frames: &SurfaceFrames, recorder: &mut NodeBlockRecorder) {
        let mut nodes = Vec::with_capacity(4);
        for tet in &self.tets {
            nodes.clear();
            nodes.extend(tet.iter().filter_map(|&v| self.body_dof[v]).map(|d| Node {
                first_dof: d,
                dim: 3,
            }));
            if !nodes.is_empty() {
                recorder.record(&nodes);
            }
        }
        let mut scratch = ElementScratch::default();
        for t in 0..self.elements.len() {
            self.element_nodes(t, &frames.0, &mut scratch);
            recorder.record(&scratch.nodes);
        }
    }

    /// Node lists whose pairs the Hessian's sparsity pattern should hold beyond [`Self::structure`]'s:
    /// per cloth triangle, its free corners' `s` and every free body vertex within reach of its corners'
    /// faces (the stencils of each face and of its edge-neighbours). A pattern that holds them survives
    /// cloth vertices sliding one face over, so the symbolic factorization is reused (see
    /// [`NodeBlockAssembler::with_reserve`](crate::NodeBlockAssembler::with_reserve)).
    pub fn reserve_structure(&self, state: &ClothOnBodyState, recorder: &mut NodeBlockRecorder) {
        let all: Vec<usize> = (0..self.triangles.len()).collect();
        self.reserve_structure_of(state, &all, 1, recorder);
    }

    /// [`Self::reserve_structure`] for the cloth triangles `triangles` only (indices past the end are
    /// skipped), reaching `steps` edge-neighbour faces from each corner's face: 1 as
    /// [`Self::reserve_structure`] (and so does 0), 2 one face further (for triangles that have already
    /// slid out of a pattern once, where sliding goes on).
    pub fn reserve_structure_of(
        &self,
        state: &ClothOnBodyState,
        triangles: &[usize],
        steps: usize,
        recorder: &mut NodeBlockRecorder,
    ) {
        let topology = self.surface.topology();
        let support =
            |f: usize| &self.reach_entries[self.reach_offsets[f]..self.reach_offsets[f + 1]];
        let mut faces = Vec::new();
        let mut next = Vec::new();
        let mut union = Vec::new();
        let mut nodes = Vec::new();
        for &t in triangles {
            let Some(corners) = self.triangles.get(t) else {
                continue;
            };
            // Faces within `steps − 1` edge steps; each one's reach adds one more step.
            faces.clear();
            faces.extend(corners.iter().map(|&c| state.cloth[c].face));
            for _ in 1..steps {
                next.clear();
                for &f in &faces {
                    next.extend((0..3).filter_map(|e| topology.twin(f, e)).map(|tw| tw.face));
                }
                faces.append(&mut next);
                faces.sort_unstable();
                faces.dedup();
            }
            union.clear();
            for &f in &faces {
                union.extend_from_slice(support(f));
            }
            union.sort_unstable();
            union.dedup();
            nodes.clear();
            nodes.extend(
                corners
                    .iter()
                    .filter_map(|&c| self.cloth_dof[c])
                    .map(|d| Node {
                        first_dof: d,
                        dim: 2,
                    }),
            );
            nodes.extend(union.iter().map(|&v| Node {
                first_dof: self.body_dof[v].expect("reach holds free vertices"),
                dim: 3,
            }));
            recorder.record(&nodes);
        }
    }

    /// The cloth triangle whose Hessian block is block `b` of [`Self::structure`] (`None` for a body
    /// tetrahedron's block or an index past the end).
    pub fn cloth_triangle_of_block(&self, b: usize) -> Option<usize> {
        let body_blocks = self.tet_block.iter().flatten().count();
        b.checked_sub(body_blocks)
            .filter(|&t| t < self.triangles.len())
    }

    /// The assembler of the Hessian's node blocks at `state` (`frames` from [`Self::frames_at`]): the
    /// pattern holds the pairs of [`Self::structure`]'s blocks and those of [`Self::reserve_structure`], so
    /// that cloth vertices sliding one face over rarely change it.
    pub fn hessian_assembler(
        &self,
        state: &ClothOnBodyState,
        frames: &SurfaceFrames,
    ) -> NodeBlockAssembler {
        let mut recorder = NodeBlockRecorder::default();
        self.structure(frames, &mut recorder);
        let mut reserve = NodeBlockRecorder::default();
        self.reserve_structure(state, &mut reserve);
        NodeBlockAssembler::with_reserve(
            self.num_dofs(),
            self.nodes(),
            &recorder,
            Some(&reserve),
            None,
        )
    }

    /// Per cloth triangle, the surface faces its three corners lie in at `state`.
    pub fn triangle_faces(&self, state: &ClothOnBodyState) -> Vec<[usize; 3]> {
        self.triangles
            .iter()
            .map(|t| t.map(|c| state.cloth[c].face))
            .collect()
    }

    /// The reserve for a pattern that must grow at `state`: [`Self::reserve_structure_of`] two faces out
    /// for the cloth triangles whose corners changed faces since `reserved_faces` (per triangle, the faces
    /// when its reserve was last added; updated, and reset if its length is not `#Fc`), then for those
    /// whose blocks `outside_blocks` (indices of [`Self::structure`]'s blocks) fell outside the pattern.
    pub fn slide_reserve(
        &self,
        state: &ClothOnBodyState,
        outside_blocks: &[usize],
        reserved_faces: &mut Vec<[usize; 3]>,
    ) -> NodeBlockRecorder {
        // The triangles that slid onto other faces since their pairs were reserved get the reserve around
        // where they are now; those that moved out of the pattern one face further.
        let hot: Vec<usize> = outside_blocks
            .iter()
            .filter_map(|&b| self.cloth_triangle_of_block(b))
            .collect();
        let faces = |t: usize| self.triangles[t].map(|c| state.cloth[c].face);
        if reserved_faces.len() != self.triangles.len() {
            reserved_faces.clear();
            reserved_faces.extend((0..self.triangles.len()).map(|_| [usize::MAX; 3]));
        }
        let moved: Vec<usize> = (0..self.triangles.len())
            .filter(|&t| reserved_faces[t] != faces(t))
            .collect();
        let mut reserve = NodeBlockRecorder::default();
        self.reserve_structure_of(state, &moved, 2, &mut reserve);
        self.reserve_structure_of(state, &hot, 2, &mut reserve);
        for &t in &moved {
            reserved_faces[t] = faces(t);
        }
        reserve
    }
}
