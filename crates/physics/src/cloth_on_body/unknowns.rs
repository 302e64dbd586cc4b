//! The unknowns `q = {s, y}`: their numbering (free cloth vertices' `(s1, s2)` first, then free body
//! vertices' positions), the conversion between DOF vectors and states, and the Newton step that walks `s`
//! across faces (thesis Eq. 146–154).

use super::{ClothOnBody, ClothOnBodyState};
use crate::math::{Real, Vec2, Vec3};
use crate::node_block_assembly::Node;
use skintight_geometry::surface::walk::{WalkError, WalkParams, surface_walk};

/// Numbers the vertices whose flag is `false` with `dim` consecutive DOFs each, after those already in
/// `nodes` (one node each, appended); `None` for flagged (pinned or fixed) vertices.
fn number_free(flags: &[bool], dim: usize, nodes: &mut Vec<Node>) -> Vec<Option<usize>> {
    let mut next = nodes.last().map_or(0, |n| n.first_dof + n.dim);
    flags
        .iter()
        .map(|&flagged| {
            (!flagged).then(|| {
                nodes.push(Node {
                    first_dof: next,
                    dim,
                });
                next += dim;
                next - dim
            })
        })
        .collect()
}

/// The numbering of the unknowns: the free cloth vertices' `(s1, s2)` first, then the free body vertices'
/// positions (see the fields of [`ClothOnBody`] of the same names).
pub(super) struct Unknowns {
    pub(super) cloth_dof: Vec<Option<usize>>,
    pub(super) body_dof: Vec<Option<usize>>,
    pub(super) nodes: Vec<Node>,
    pub(super) num_dofs: usize,
}

impl Unknowns {
    pub(super) fn new(pinned: &[bool], fixed: &[bool]) -> Self {
        let mut nodes = Vec::new();
        let cloth_dof = number_free(pinned, 2, &mut nodes);
        let body_dof = number_free(fixed, 3, &mut nodes);
        let num_dofs = nodes.last().map_or(0, |n: &Node| n.first_dof + n.dim);
        Self {
            cloth_dof,
            body_dof,
            nodes,
            num_dofs,
        }
    }
}

impl ClothOnBody {
    /// The DOF vector of `state` (`#q`): `s` of unpinned cloth vertices, positions of free body vertices.
    pub fn dofs(&self, state: &ClothOnBodyState) -> Vec<Real> {
        let mut q = vec![0.0; self.num_dofs];
        for (c, dof) in self.cloth_dof.iter().enumerate() {
            if let Some(d) = *dof {
                q[d] = state.cloth[c].s.x;
                q[d + 1] = state.cloth[c].s.y;
            }
        }
        for (v, dof) in self.body_dof.iter().enumerate() {
            if let Some(d) = *dof {
                q[d..d + 3].copy_from_slice(state.body[v].as_slice());
            }
        }
        q
    }

    /// The state with the DOFs `q` in the faces of `template` (no walking: the coordinates are taken as
    /// they are, even outside the face — the surface clamps them). For derivative tests and small steps.
    pub fn with_dofs(&self, template: &ClothOnBodyState, q: &[Real]) -> ClothOnBodyState {
        let mut state = template.clone();
        for (c, dof) in self.cloth_dof.iter().enumerate() {
            if let Some(d) = *dof {
                state.cloth[c].s = Vec2::new(q[d], q[d + 1]);
            }
        }
        for (v, dof) in self.body_dof.iter().enumerate() {
            if let Some(d) = *dof {
                state.body[v] = Vec3::new(q[d], q[d + 1], q[d + 2]);
            }
        }
        state
    }

    /// Applies the step `dq` (`#q`): body positions are added (Eq. 146), each cloth vertex walks its `Δs`
    /// across faces on the surface of the new body positions (Eq. 147–154).
    pub fn step(
        &self,
        state: &ClothOnBodyState,
        dq: &[Real],
        walk: &WalkParams,
    ) -> Result<ClothOnBodyState, WalkError> {
        let mut next = state.clone();
        for (v, dof) in self.body_dof.iter().enumerate() {
            if let Some(d) = *dof {
                next.body[v] += Vec3::new(dq[d], dq[d + 1], dq[d + 2]);
            }
        }
        let control = self.control_positions(&next.body);
        for (c, dof) in self.cloth_dof.iter().enumerate() {
            if let Some(d) = *dof {
                let ds = Vec2::new(dq[d], dq[d + 1]);
                if ds.x != 0.0 || ds.y != 0.0 {
                    next.cloth[c] =
                        surface_walk(&*self.surface, &control, state.cloth[c], ds, walk, None)?
                            .coord;
                }
            }
        }
        Ok(next)
    }

    /// The unknowns grouped by node (a cloth vertex's 2 surface coordinates, a body vertex's 3
    /// coordinates) as group starts followed by `#q`, as
    /// [`SparseCholesky::analyze_grouped`](crate::SparseCholesky::analyze_grouped) takes them; `None` if
    /// the nodes do not tile the unknowns (then each unknown is its own group).
    pub fn dof_groups(&self) -> Option<Vec<usize>> {
        let mut starts: Vec<(usize, usize)> =
            self.nodes().iter().map(|n| (n.first_dof, n.dim)).collect();
        starts.sort_unstable();
        let mut out = Vec::with_capacity(starts.len() + 1);
        let mut next = 0;
        for (first, dim) in starts {
            if first != next || dim == 0 {
                return None;
            }
            out.push(first);
            next = first + dim;
        }
        (next == self.num_dofs()).then(|| {
            out.push(next);
            out
        })
    }
}
