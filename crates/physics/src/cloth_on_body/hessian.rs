//! Assembly of the Hessian `∂²U/∂q²` as node blocks (thesis Eq. 156–157; see the parent module for the
//! formulas and units), sequential into any [`NodeHessianSink`] or on several threads straight into a
//! [`NodeBlockAssembler`], with the gradient, energy and residual figures of the same evaluation.

use super::{
    ClothOnBody, ClothOnBodyError, ClothOnBodyState, ElementScratch, Frames, HessianForm,
    SurfaceFrames,
};
use crate::math::{Mat3, Mat3x2, Real, Vec3};
use crate::membrane_element::{Matrix9, Vector9};
use crate::node_block_assembly::{AssemblyPart, Node, NodeBlockAssembler, NodeHessianSink};

/// What [`ClothOnBody::hessian`] evaluates besides the Hessian.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// `U` (J).
    pub energy: Real,
    /// Unbalanced force norm (N), as [`ClothOnBody::force_residual`].
    pub force_residual: Real,
    /// `‖∂U_cloth/∂x‖₂` (N), as [`ClothOnBody::cloth_force_norm`].
    pub cloth_force_norm: Real,
    /// The damping metric `D` (`#q`), as [`ClothOnBody::damping_metric`].
    pub damping_metric: Vec<Real>,
}

impl ClothOnBody {
    /// Hands the Hessian `∂²U/∂q²` (`#q × #q`) to `sink` as node blocks: one per body tetrahedron (its free
    /// corners), then one per cloth triangle (its unpinned corners' `s`, then the free body vertices of its
    /// corners' stencils in increasing order). Writes `∂U/∂q` into `gradient` and returns `U` with the force
    /// residual, cloth force norm and damping metric, all from the one evaluation of the surface.
    ///
    /// The node lists depend on the faces the cloth vertices lie in (their stencils), not on the
    /// coordinates within a face. This is the exact Hessian ([`HessianForm::Coordinate`]); the solver's
    /// assembly can use the covariant form instead ([`Self::hessian_parallel`]).
    pub fn hessian(
        &self,
        state: &ClothOnBodyState,
        gradient: &mut [Real],
        sink: &mut dyn NodeHessianSink,
    ) -> Result<Evaluation, ClothOnBodyError> {
        self.check_dofs(gradient, "gradient buffer")?;
        let frames = self.frames(state)?;
        self.hessian_at(state, &SurfaceFrames(frames), gradient, sink)
    }

    /// [`Self::hessian`] with the surface already evaluated at `state` (`frames` from [`Self::frames_at`]).
    pub fn hessian_at(
        &self,
        state: &ClothOnBodyState,
        frames: &SurfaceFrames,
        gradient: &mut [Real],
        sink: &mut dyn NodeHessianSink,
    ) -> Result<Evaluation, ClothOnBodyError> {
        self.check_dofs(gradient, "gradient buffer")?;
        let frames = &frames.0;
        gradient.fill(0.0);
        let mut energy = self.body_gradient(state, gradient)?;
        self.body_hessian(state, sink)?;
        let mut scratch = ElementScratch::default();
        let mut cloth_forces = vec![Vec3::zeros(); state.cloth.len()];
        for t in 0..self.elements.len() {
            energy += self.cloth_element(t, frames, &mut scratch, gradient, &mut cloth_forces)?;
            sink.add_node_block(&scratch.nodes, &scratch.block);
        }
        Ok(self.evaluation(frames, energy, gradient, &cloth_forces))
    }

    /// [`Self::hessian_at`] into a [`NodeBlockAssembler`] (after its `begin`) on `threads` threads (at least
    /// one): the same blocks with the same indices, each thread scattering into its own copy of the values,
    /// merged at the end. Sums are taken in another order than the sequential pass, so results agree to
    /// rounding. `form` chooses the matrix ([`HessianForm`]; `Coordinate` is [`Self::hessian_at`]'s).
    pub fn hessian_parallel(
        &self,
        state: &ClothOnBodyState,
        frames: &SurfaceFrames,
        gradient: &mut [Real],
        assembler: &mut NodeBlockAssembler,
        threads: usize,
        form: HessianForm,
    ) -> Result<Evaluation, ClothOnBodyError> {
        self.check_dofs(gradient, "gradient buffer")?;
        self.check_state(state)?;
        let frames = &frames.0;
        let threads = threads.max(1);
        let (nt, ne) = (self.tets.len(), self.elements.len());
        let num_body_blocks = self.tet_block.iter().flatten().count();
        let split = |len: usize, k: usize| (len * k / threads, len * (k + 1) / threads);
        let mut buffers = assembler.lend_buffers(threads);
        let shared: &NodeBlockAssembler = assembler;
        let run = |k: usize,
                   values: Vec<Real>|
         -> Result<(Real, Vec<Real>, Vec<Vec3>, AssemblyPart), ClothOnBodyError> {
            let mut share = shared.share_in(values);
            let mut g = vec![0.0; self.num_dofs];
            let mut forces = vec![Vec3::zeros(); state.cloth.len()];
            let mut energy = 0.0;
            let mut nodes = Vec::with_capacity(4);
            let mut block = Vec::with_capacity(144);
            let (t0, t1) = split(nt, k);
            for t in t0..t1 {
                energy += self.tet_gradient(t, state, &mut g)?;
                if let Some(b) = self.tet_block[t] {
                    self.tet_hessian_block(t, state, &mut nodes, &mut block)?;
                    share.add(b, &nodes, &block);
                }
            }
            let mut scratch = ElementScratch::default();
            let (e0, e1) = split(ne, k);
            for t in e0..e1 {
                // The node-pair blocks go straight into the values when the triangle's node list is
                // the recorded one (the usual case); the dense block otherwise.
                let (e, d) = self.cloth_element_derivatives(t, frames, &mut g, &mut forces)?;
                energy += e;
                let (s_node, _) = self.cloth_block_weights(t, frames, &mut scratch);
                let nodes = std::mem::take(&mut scratch.nodes);
                let direct = share.add_direct(num_body_blocks + t, &nodes, |slots| {
                    self.cloth_pair_blocks(
                        t,
                        frames,
                        (&d.gradient, &d.hessian),
                        &mut scratch,
                        s_node,
                        form,
                        |a, b, h| slots.add(a, b, h),
                    );
                });
                scratch.nodes = nodes;
                if !direct {
                    self.cloth_block(t, frames, &d.gradient, &d.hessian, &mut scratch, form);
                    share.add(num_body_blocks + t, &scratch.nodes, &scratch.block);
                }
            }
            Ok((energy, g, forces, share.into_part()))
        };
        let first = buffers.remove(0);
        let results: Vec<_> = if threads == 1 {
            vec![run(0, first)]
        } else {
            std::thread::scope(|scope| {
                let handles: Vec<_> = buffers
                    .into_iter()
                    .enumerate()
                    .map(|(k, values)| scope.spawn(move || run(k + 1, values)))
                    .collect();
                let mut results = vec![run(0, first)];
                results.extend(
                    handles
                        .into_iter()
                        .map(|h| h.join().expect("assembly thread panicked")),
                );
                results
            })
        };
        gradient.fill(0.0);
        let mut energy = 0.0;
        let mut cloth_forces = vec![Vec3::zeros(); state.cloth.len()];
        let mut parts = Vec::with_capacity(threads);
        for result in results {
            let (e, g, forces, part) = result?;
            energy += e;
            for (a, b) in gradient.iter_mut().zip(&g) {
                *a += b;
            }
            for (a, b) in cloth_forces.iter_mut().zip(&forces) {
                *a += b;
            }
            parts.push(part);
        }
        assembler.merge(parts);
        Ok(self.evaluation(frames, energy, gradient, &cloth_forces))
    }

    pub(super) fn evaluation(
        &self,
        frames: &Frames,
        energy: Real,
        gradient: &[Real],
        cloth_forces: &[Vec3],
    ) -> Evaluation {
        Evaluation {
            energy,
            force_residual: self.force_residual_with(frames, gradient),
            cloth_force_norm: cloth_forces
                .iter()
                .map(|f| f.norm_squared())
                .sum::<Real>()
                .sqrt(),
            damping_metric: self.damping_metric_with(frames),
        }
    }

    /// Cloth triangle `t`: adds its `∂U/∂q` into `gradient` and its Cartesian corner forces into
    /// `cloth_forces`, leaves its Hessian block in `scratch` and returns its energy.
    pub(super) fn cloth_element(
        &self,
        t: usize,
        frames: &Frames,
        scratch: &mut ElementScratch,
        gradient: &mut [Real],
        cloth_forces: &mut [Vec3],
    ) -> Result<Real, ClothOnBodyError> {
        let (energy, d) = self.cloth_element_derivatives(t, frames, gradient, cloth_forces)?;
        self.cloth_block(
            t,
            frames,
            &d.gradient,
            &d.hessian,
            scratch,
            HessianForm::Coordinate,
        );
        Ok(energy)
    }

    /// Cloth triangle `t`: adds its `∂U/∂q` into `gradient` and its Cartesian corner forces into
    /// `cloth_forces`; returns its energy and its Cartesian derivatives.
    pub(super) fn cloth_element_derivatives(
        &self,
        t: usize,
        frames: &Frames,
        gradient: &mut [Real],
        cloth_forces: &mut [Vec3],
    ) -> Result<(Real, crate::MembraneDerivatives), ClothOnBodyError> {
        let x = self.corners(t, &frames.points);
        let d = self.elements[t]
            .derivatives(&self.law, &x)
            .map_err(|source| ClothOnBodyError::Cloth {
                triangle: t,
                source,
            })?;
        self.scatter_cloth_gradient(t, frames, &d.gradient, gradient);
        for (i, &c) in self.triangles[t].iter().enumerate() {
            cloth_forces[c] += Vec3::new(
                d.gradient[3 * i],
                d.gradient[3 * i + 1],
                d.gradient[3 * i + 2],
            );
        }
        Ok((d.energy, d))
    }

    /// The Hessian block of body tetrahedron `t` over its free corners into `nodes` and `block` (empty
    /// `nodes` when all four are fixed).
    pub(super) fn tet_hessian_block(
        &self,
        t: usize,
        state: &ClothOnBodyState,
        nodes: &mut Vec<Node>,
        block: &mut Vec<Real>,
    ) -> Result<(), ClothOnBodyError> {
        let tet = &self.tets[t];
        nodes.clear();
        let mut local = [0usize; 4];
        for (a, &v) in tet.iter().enumerate() {
            if let Some(d) = self.body_dof[v] {
                local[nodes.len()] = a;
                nodes.push(Node {
                    first_dof: d,
                    dim: 3,
                });
            }
        }
        if nodes.is_empty() {
            return Ok(());
        }
        let h = self.body.elements()[t]
            .hessian(self.body.material(), &tet.map(|v| state.body[v]), false)
            .map_err(|det| ClothOnBodyError::InvertedBody { tet: t, det })?;
        let m = 3 * nodes.len();
        block.clear();
        block.resize(m * m, 0.0);
        for (i, &a) in local[..nodes.len()].iter().enumerate() {
            for (j, &b) in local[..nodes.len()].iter().enumerate() {
                for r in 0..3 {
                    for c in 0..3 {
                        block[(3 * i + r) * m + 3 * j + c] = h[(3 * a + r, 3 * b + c)];
                    }
                }
            }
        }
        Ok(())
    }

    pub(super) fn body_hessian(
        &self,
        state: &ClothOnBodyState,
        sink: &mut dyn NodeHessianSink,
    ) -> Result<(), ClothOnBodyError> {
        let mut nodes = Vec::with_capacity(4);
        let mut block = Vec::with_capacity(144);
        for t in 0..self.tets.len() {
            self.tet_hessian_block(t, state, &mut nodes, &mut block)?;
            if !nodes.is_empty() {
                sink.add_node_block(&nodes, &block);
            }
        }
        Ok(())
    }

    /// Dense Hessian block of cloth triangle `t` over its nodes (Eq. 156–157, in `form`) into
    /// `scratch.block`, the nodes into `scratch.nodes`.
    pub(super) fn cloth_block(
        &self,
        t: usize,
        frames: &Frames,
        g: &Vector9,
        h: &Matrix9,
        scratch: &mut ElementScratch,
        form: HessianForm,
    ) {
        let (s_node, y_start) = self.cloth_block_weights(t, frames, scratch);
        let ns = scratch.nodes.len() - scratch.union.len();
        let m = y_start + 3 * scratch.union.len();
        // Every entry is written (all node pairs, both triangles), so the block is not zeroed first.
        let mut block = std::mem::take(&mut scratch.block);
        block.resize(m * m, 0.0);
        let offset = |a: usize| {
            if a < ns {
                2 * a
            } else {
                y_start + 3 * (a - ns)
            }
        };
        let dim = |a: usize| if a < ns { 2 } else { 3 };
        self.cloth_pair_blocks(t, frames, (g, h), scratch, s_node, form, |a, b, hb| {
            let (oa, ob, da, db) = (offset(a), offset(b), dim(a), dim(b));
            for r in 0..da {
                for c in 0..db {
                    block[(oa + r) * m + ob + c] = hb[r * db + c];
                    block[(ob + c) * m + oa + r] = hb[r * db + c];
                }
            }
        });
        scratch.block = block;
    }

    /// Node list of cloth triangle `t` into `scratch.nodes` and the stencil weights of the free body
    /// vertices (`scratch.union`) at its corners into `scratch.w`, `scratch.dw`. Returns each corner's
    /// position in the node list (`usize::MAX` if pinned) and the local offset of the first body DOF.
    pub(super) fn cloth_block_weights(
        &self,
        t: usize,
        frames: &Frames,
        scratch: &mut ElementScratch,
    ) -> ([usize; 3], usize) {
        let corners = self.triangles[t];
        let (s_corner, y_start) = self.element_nodes(t, frames, scratch);
        let nu = scratch.union.len();
        scratch.w.clear();
        scratch.w.resize(nu, [0.0; 3]);
        scratch.dw.clear();
        scratch.dw.resize(nu, [[0.0; 2]; 3]);
        for (i, &c) in corners.iter().enumerate() {
            for &(v, w, dw) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                if let Ok(u) = scratch.union.binary_search(&v) {
                    scratch.w[u][i] += w;
                    scratch.dw[u][i][0] += dw[0];
                    scratch.dw[u][i][1] += dw[1];
                }
            }
        }
        // The s nodes come first, two DOFs each.
        (
            s_corner.map(|o| if o == usize::MAX { o } else { o / 2 }),
            y_start,
        )
    }

    /// The node-pair blocks of cloth triangle `t`'s Hessian (Eq. 156–157) from its Cartesian derivatives
    /// `(g, h)`, each pair `(a, b)`, `a ≤ b` positions in `scratch.nodes`, once, to `emit(a, b, block)`
    /// (row-major, `dim_a × dim_b`); after [`Self::cloth_block_weights`] (`s_node` is what it returned). The
    /// force terms (the second derivatives of the surface times the corner force) take the force
    /// [`HessianForm::curvature_force`] gives.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn cloth_pair_blocks(
        &self,
        t: usize,
        frames: &Frames,
        (g, h): (&Vector9, &Matrix9),
        scratch: &mut ElementScratch,
        s_node: [usize; 3],
        form: HessianForm,
        mut emit: impl FnMut(usize, usize, &[Real]),
    ) {
        let corners = self.triangles[t];
        let nu = scratch.union.len();
        let ns = s_node.iter().filter(|&&a| a != usize::MAX).count();
        let hik = |i: usize, k: usize| -> Mat3 { h.fixed_view::<3, 3>(3 * i, 3 * k).into_owned() };
        let tan: [Mat3x2; 3] = corners.map(|c| frames.points[c].tangents);
        // The corner forces of the force terms (all of `g_i`, or its normal part).
        let gi: [Vec3; 3] = [0, 1, 2].map(|i| {
            form.curvature_force(Vec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2]), &tan[i])
        });

        // s–s blocks.
        for i in 0..3 {
            if s_node[i] == usize::MAX {
                continue;
            }
            for k in i..3 {
                if s_node[k] == usize::MAX {
                    continue;
                }
                let mut b = tan[i].transpose() * hik(i, k) * tan[k];
                if i == k {
                    let sec = &frames.points[corners[i]].second;
                    b[(0, 0)] += gi[i].dot(&sec[0]);
                    b[(0, 1)] += gi[i].dot(&sec[1]);
                    b[(1, 0)] += gi[i].dot(&sec[1]);
                    b[(1, 1)] += gi[i].dot(&sec[2]);
                }
                emit(
                    s_node[i],
                    s_node[k],
                    &[b[(0, 0)], b[(0, 1)], b[(1, 0)], b[(1, 1)]],
                );
            }
        }
        // HW_u[i] = Σ_k H_ik w_uk.
        scratch.hw.clear();
        let h_blocks: [[Mat3; 3]; 3] = [0, 1, 2].map(|i| [0, 1, 2].map(|k| hik(i, k)));
        for u in 0..nu {
            let w = scratch.w[u];
            scratch
                .hw
                .push([0, 1, 2].map(|i| {
                    h_blocks[i][0] * w[0] + h_blocks[i][1] * w[1] + h_blocks[i][2] * w[2]
                }));
        }
        // s–y blocks.
        let mut sy = [0.0; 6];
        for i in 0..3 {
            if s_node[i] == usize::MAX {
                continue;
            }
            for u in 0..nu {
                let b = tan[i].transpose() * scratch.hw[u][i]; // 2 × 3
                for a in 0..2 {
                    let dw = scratch.dw[u][i][a];
                    for k in 0..3 {
                        sy[3 * a + k] = b[(a, k)] + dw * gi[i][k];
                    }
                }
                emit(s_node[i], ns + u, &sy);
            }
        }
        // y–y blocks.
        let mut yy = [0.0; 9];
        for u in 0..nu {
            let wu = scratch.w[u];
            for v in u..nu {
                let hv = &scratch.hw[v];
                let b = hv[0] * wu[0] + hv[1] * wu[1] + hv[2] * wu[2];
                for r in 0..3 {
                    for c in 0..3 {
                        yy[3 * r + c] = b[(r, c)];
                    }
                }
                emit(ns + u, ns + v, &yy);
            }
        }
    }
}
