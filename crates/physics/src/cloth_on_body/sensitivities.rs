//! What the design differentiates through the equilibrium: the cloth Jacobian `J = ∂x/∂q` (matrix-free and
//! explicit), how the surface tangents move with the body, and the energy's derivatives with respect to the
//! pattern (rest) corners `X̄`: `∂U/∂X̄` and the mixed `∂²U/∂q∂X̄` (thesis Eq. 164).

use faer::sparse::{SparseColMat, Triplet};

use super::{ClothOnBody, ClothOnBodyError, ClothOnBodyState};
use crate::math::{Real, Vec2, Vec3};
use crate::membrane_element::{MembraneElement, MembraneError, Vector9};

impl ClothOnBody {
    /// `J δq`: the motion of the cloth vertices (`#Vc × 3`, m) under a change `dq` (`#q`) of the unknowns,
    /// with `J = ∂x/∂q` at `state` (`δx_c = ∂x/∂s δs_c + Σ_v w_v δy_v`).
    pub fn cloth_jacobian(
        &self,
        state: &ClothOnBodyState,
        dq: &[Real],
    ) -> Result<Vec<Vec3>, ClothOnBodyError> {
        self.check_dofs(dq, "the change of unknowns")?;
        let frames = self.frames(state)?;
        Ok((0..state.cloth.len())
            .map(|c| {
                let mut dx = Vec3::zeros();
                if let Some(d) = self.cloth_dof[c] {
                    dx += frames.points[c].tangents * Vec2::new(dq[d], dq[d + 1]);
                }
                for &(v, w, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                    if let Some(d) = self.body_dof[v] {
                        dx += Vec3::new(dq[d], dq[d + 1], dq[d + 2]) * w;
                    }
                }
                dx
            })
            .collect())
    }

    /// `Jᵀ g`: a derivative with respect to the cloth vertex positions (`#Vc × 3`, units per m) carried to
    /// the unknowns (`#q`), the transpose of [`Self::cloth_jacobian`].
    pub fn cloth_jacobian_transpose(
        &self,
        state: &ClothOnBodyState,
        g: &[Vec3],
    ) -> Result<Vec<Real>, ClothOnBodyError> {
        if g.len() != self.cloth_dof.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "{} cloth vertex derivatives for {} cloth vertices",
                g.len(),
                self.cloth_dof.len()
            )));
        }
        let frames = self.frames(state)?;
        let mut out = vec![0.0; self.num_dofs];
        for (c, gc) in g.iter().enumerate() {
            self.scatter_vertex_gradient(c, &frames, gc, &mut out);
        }
        Ok(out)
    }

    /// How the surface tangents under each cloth vertex move with the body: for cloth vertex `c`, the
    /// pairs `(d, ∂w_v/∂s)` of the free body vertices `v` of its stencil (`d` = the first of `y_v`'s three
    /// unknowns; `∂w_v/∂s`, dimensionless, one entry per surface coordinate), so that a change `δy` of the
    /// body positions changes the tangents `T_c = ∂x_c/∂s_c` (`3 × 2`, m) by `δT_c = Σ_v δy_v (∂w_v/∂s)ᵀ`
    /// — the surface is linear in its control positions. Entries of one body vertex met twice are summed.
    /// `#Vc` lists, the cloth vertices' stencils at `state`.
    pub fn tangent_body_derivatives(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<Vec<(usize, Vec2)>>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        Ok((0..state.cloth.len())
            .map(|c| {
                let mut out: Vec<(usize, Vec2)> = Vec::new();
                for &(v, _, dw) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                    if let Some(d) = self.body_dof[v] {
                        let dw = Vec2::new(dw[0], dw[1]);
                        match out.iter_mut().find(|(e, _)| *e == d) {
                            Some((_, sum)) => *sum += dw,
                            None => out.push((d, dw)),
                        }
                    }
                }
                out
            })
            .collect())
    }

    /// `(∂²U/∂x∂X̄)ᵀ δx` per cloth triangle (`#Fc`, three pattern corners each, N): how the energy's
    /// derivative along the cloth motion `dx` (`#Vc × 3`, m) changes with each triangle's pattern corners —
    /// the design term `λᵀ ∂²U/∂q∂X̄` of the adjoint (Eq. 164) with `dx = J λ`.
    pub fn rest_mixed_product(
        &self,
        state: &ClothOnBodyState,
        dx: &[Vec3],
    ) -> Result<Vec<[Vec2; 3]>, ClothOnBodyError> {
        if dx.len() != self.cloth_dof.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "{} cloth vertex motions for {} cloth vertices",
                dx.len(),
                self.cloth_dof.len()
            )));
        }
        self.per_triangle(state, |t, element, x| {
            let m = element.mixed_hessian(&self.law, x)?;
            let v = Vector9::from_iterator(
                self.triangles[t]
                    .iter()
                    .flat_map(|&c| [dx[c].x, dx[c].y, dx[c].z]),
            );
            let r = m.transpose() * v;
            Ok([0, 1, 2].map(|k| Vec2::new(r[2 * k], r[2 * k + 1])))
        })
    }

    /// The cloth Jacobian `J = ∂x/∂q` at `state` as an explicit sparse matrix, `3#Vc × #q`
    /// (dimensionless: m of cloth motion per m of unknown — surface coordinates are measured so that
    /// `∂x/∂s` are the surface tangents). Row `3c + i` is coordinate `i` of cloth vertex `c`; its entries are
    /// the tangents `∂x_c/∂s_c` (columns of the vertex's surface coordinates, absent for a pinned vertex)
    /// and the stencil weights `w_v` of the free body vertices `v` under it (columns of `y_v`, one per
    /// coordinate). The same matrix as the matrix-free [`Self::cloth_jacobian`] and
    /// [`Self::cloth_jacobian_transpose`]; entries of one stencil vertex met twice are summed.
    pub fn cloth_jacobian_matrix(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<SparseColMat<usize, Real>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        let mut triplets = Vec::new();
        for c in 0..state.cloth.len() {
            if let Some(d) = self.cloth_dof[c] {
                let t = frames.points[c].tangents;
                for a in 0..2 {
                    for i in 0..3 {
                        triplets.push(Triplet::new(3 * c + i, d + a, t[(i, a)]));
                    }
                }
            }
            for &(v, w, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                if let Some(d) = self.body_dof[v] {
                    for i in 0..3 {
                        triplets.push(Triplet::new(3 * c + i, d + i, w));
                    }
                }
            }
        }
        SparseColMat::try_new_from_triplets(3 * state.cloth.len(), self.num_dofs, &triplets)
            .map_err(|e| ClothOnBodyError::Shape(format!("the cloth Jacobian: {e:?}")))
    }

    /// The mixed second derivative `K = ∂²U/∂q∂X̄` at `state` as an explicit sparse matrix,
    /// `#q × 2#Vp` (N/m: change of the generalized force per metre of pattern motion), with
    /// `K = Jᵀ M P`: `M` the cloth elements' `∂²U_e/∂x∂X̄` blocks (9 × 6 each, see
    /// [`MembraneElement::mixed_hessian`]) and `P` the scatter of each triangle's pattern corners to the
    /// pattern vertices `pattern_triangles` (`#Fc`, ids below `num_pattern_vertices`; column `2v + i` is
    /// coordinate `i` of pattern vertex `v`). The body energy does not depend on the pattern. `Kᵀ λ`
    /// equals [`Self::rest_mixed_product`] of `J λ` scattered to the pattern vertices.
    pub fn rest_mixed_matrix(
        &self,
        state: &ClothOnBodyState,
        pattern_triangles: &[[usize; 3]],
        num_pattern_vertices: usize,
    ) -> Result<SparseColMat<usize, Real>, ClothOnBodyError> {
        if pattern_triangles.len() != self.triangles.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "{} pattern triangles for {} cloth triangles",
                pattern_triangles.len(),
                self.triangles.len()
            )));
        }
        if let Some(t) = pattern_triangles
            .iter()
            .position(|t| t.iter().any(|&v| v >= num_pattern_vertices))
        {
            return Err(ClothOnBodyError::Shape(format!(
                "pattern triangle {t} names a vertex beyond the {num_pattern_vertices} pattern vertices"
            )));
        }
        let frames = self.frames(state)?;
        let blocks =
            self.per_triangle(state, |_, element, x| element.mixed_hessian(&self.law, x))?;
        let mut triplets = Vec::new();
        for (t, m) in blocks.iter().enumerate() {
            for (a, &c) in self.triangles[t].iter().enumerate() {
                // Rows of corner a (3 × 6) carried to the unknowns by J_cᵀ.
                let rows = m.fixed_rows::<3>(3 * a);
                let mut push = |dof: usize, coefficient: &dyn Fn(usize) -> Real| {
                    for (b, &v) in pattern_triangles[t].iter().enumerate() {
                        for i in 0..2 {
                            let col = 2 * b + i;
                            let value = coefficient(col);
                            triplets.push(Triplet::new(dof, 2 * v + i, value));
                        }
                    }
                };
                if let Some(d) = self.cloth_dof[c] {
                    let tg = frames.points[c].tangents;
                    for s in 0..2 {
                        push(d + s, &|col| {
                            (0..3).map(|i| tg[(i, s)] * rows[(i, col)]).sum()
                        });
                    }
                }
                for &(v, w, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                    if let Some(d) = self.body_dof[v] {
                        for i in 0..3 {
                            push(d + i, &|col| w * rows[(i, col)]);
                        }
                    }
                }
            }
        }
        SparseColMat::try_new_from_triplets(self.num_dofs, 2 * num_pattern_vertices, &triplets)
            .map_err(|e| ClothOnBodyError::Shape(format!("the mixed derivative: {e:?}")))
    }

    /// `K δX̄` (`#q`, N per unit of the unknowns), with `K = ∂²U/∂q∂X̄` at `state`, for a change `rest_change`
    /// of each cloth triangle's three pattern corners (`#Fc`, m): the product [`Self::rest_mixed_matrix`]
    /// would give, matrix-free — `Jᵀ Σ_e (∂²U_e/∂x∂X̄_e) δX̄_e`, element by element, then carried to the
    /// unknowns as a gradient is. What a first-order prediction of the equilibrium of a changed pattern
    /// needs (one product per prediction), without building the `#q × 2#Vp` matrix.
    pub fn rest_mixed_apply(
        &self,
        state: &ClothOnBodyState,
        rest_change: &[[Vec2; 3]],
    ) -> Result<Vec<Real>, ClothOnBodyError> {
        if rest_change.len() != self.triangles.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "{} triangles' pattern changes for {} cloth triangles",
                rest_change.len(),
                self.triangles.len()
            )));
        }
        let forces = self.per_triangle(state, |t, element, x| {
            let m = element.mixed_hessian(&self.law, x)?;
            let d = &rest_change[t];
            let v = nalgebra::Vector6::new(d[0].x, d[0].y, d[1].x, d[1].y, d[2].x, d[2].y);
            Ok(m * v)
        })?;
        let mut per_vertex = vec![Vec3::zeros(); self.cloth_dof.len()];
        for (t, f) in forces.iter().enumerate() {
            for (a, &c) in self.triangles[t].iter().enumerate() {
                per_vertex[c] += Vec3::new(f[3 * a], f[3 * a + 1], f[3 * a + 2]);
            }
        }
        self.cloth_jacobian_transpose(state, &per_vertex)
    }

    /// `K A` (`#q × #c`, returned column-major), with `K = ∂²U/∂q∂X̄` at `state` and a map `A` from `#c`
    /// parameters to the pattern coordinates given **by rows**: `a_rows` is `2#Vp × #c` row-major (row
    /// `2v + i` = coordinate `i` of pattern vertex `v`). Matrix-free, element by element —
    /// `Jᵀ Σ_e (∂²U_e/∂x∂X̄_e) A_e` with `A_e` the six rows of the triangle's pattern corners — the product
    /// [`Self::rest_mixed_matrix`] times `A` would give, without building `K` (whose assembly from
    /// triplets costs more than this product). What the reduced Gauss-Newton direction's sensitivity
    /// `H⁻¹ K A` needs.
    pub fn rest_mixed_times(
        &self,
        state: &ClothOnBodyState,
        pattern_triangles: &[[usize; 3]],
        a_rows: &[Real],
        columns: usize,
    ) -> Result<Vec<Real>, ClothOnBodyError> {
        if pattern_triangles.len() != self.triangles.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "{} pattern triangles for {} cloth triangles",
                pattern_triangles.len(),
                self.triangles.len()
            )));
        }
        if columns == 0 || a_rows.len() % columns != 0 {
            return Err(ClothOnBodyError::Shape(format!(
                "{} map entries are not whole rows of {columns} columns",
                a_rows.len()
            )));
        }
        let nx = a_rows.len() / columns;
        if let Some(t) = pattern_triangles
            .iter()
            .position(|t| t.iter().any(|&v| 2 * v + 1 >= nx))
        {
            return Err(ClothOnBodyError::Shape(format!(
                "pattern triangle {t} names a vertex beyond the map's {nx} rows"
            )));
        }
        let nc = columns;
        let frames = self.frames(state)?;
        let blocks =
            self.per_triangle(state, |_, element, x| element.mixed_hessian(&self.law, x))?;
        let axpy = |dst: &mut [Real], w: Real, src: &[Real]| {
            for (d, s) in dst.iter_mut().zip(src) {
                *d += w * s;
            }
        };
        // Rows of K A, one per unknown (`#q × #c` row-major), then transposed.
        let mut out = vec![0.0; self.num_dofs * nc];
        let mut tri = vec![0.0; 9 * nc];
        for (t, m) in blocks.iter().enumerate() {
            tri.fill(0.0);
            for r in 0..9 {
                let dst = &mut tri[r * nc..(r + 1) * nc];
                for (k, &v) in pattern_triangles[t].iter().enumerate() {
                    for i in 0..2 {
                        let w = m[(r, 2 * k + i)];
                        if w != 0.0 {
                            let row = 2 * v + i;
                            axpy(dst, w, &a_rows[row * nc..(row + 1) * nc]);
                        }
                    }
                }
            }
            for (a, &c) in self.triangles[t].iter().enumerate() {
                let corner = &tri[3 * a * nc..(3 * a + 3) * nc];
                if let Some(d) = self.cloth_dof[c] {
                    let tg = frames.points[c].tangents;
                    for s in 0..2 {
                        let dst = &mut out[(d + s) * nc..(d + s + 1) * nc];
                        for i in 0..3 {
                            axpy(dst, tg[(i, s)], &corner[i * nc..(i + 1) * nc]);
                        }
                    }
                }
                for &(v, w, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                    if let Some(d) = self.body_dof[v] {
                        for i in 0..3 {
                            let dst = &mut out[(d + i) * nc..(d + i + 1) * nc];
                            axpy(dst, w, &corner[i * nc..(i + 1) * nc]);
                        }
                    }
                }
            }
        }
        let nq = self.num_dofs;
        let mut column_major = vec![0.0; nq * nc];
        for q in 0..nq {
            for c in 0..nc {
                column_major[c * nq + q] = out[q * nc + c];
            }
        }
        Ok(column_major)
    }

    /// `∂U/∂X̄` per cloth triangle (`#Fc`, three pattern corners each, N) at fixed `state`.
    pub fn rest_gradient(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<[Vec2; 3]>, ClothOnBodyError> {
        self.per_triangle(state, |_, element, x| {
            let g = element.rest_gradient(&self.law, x)?;
            Ok([0, 1, 2].map(|k| Vec2::new(g[2 * k], g[2 * k + 1])))
        })
    }

    /// `f(t, element, corners)` for every cloth triangle at `state`, the surface evaluated once; an element
    /// error names its triangle.
    pub(super) fn per_triangle<T>(
        &self,
        state: &ClothOnBodyState,
        f: impl Fn(usize, &MembraneElement, &[Vec3; 3]) -> Result<T, MembraneError>,
    ) -> Result<Vec<T>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        self.elements
            .iter()
            .enumerate()
            .map(|(t, element)| {
                f(t, element, &self.corners(t, &frames.points)).map_err(|source| {
                    ClothOnBodyError::Cloth {
                        triangle: t,
                        source,
                    }
                })
            })
            .collect()
    }
}
