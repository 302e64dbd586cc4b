//! Figures of a state for the solver and the reports: the damping metric, the unbalanced-force residual,
//! the cloth force norm, the smallest body volume ratio, and per element or vertex the membrane states,
//! cloth forces, normal forces and interface pressures.

use super::{ClothOnBody, ClothOnBodyError, ClothOnBodyState, Frames};
use crate::math::{Real, Vec2, Vec3};
use crate::membrane_element::MembraneState;

impl ClothOnBody {
    /// The damping metric `D` (`#q`): 1 for body coordinates, `|∂x/∂s_a|²` (m²) for surface coordinates
    /// (floored at 10⁻³ of their median), so that `α D` (α in N/m) damps every unknown by about the same
    /// stiffness per metre of motion.
    pub fn damping_metric(&self, state: &ClothOnBodyState) -> Result<Vec<Real>, ClothOnBodyError> {
        Ok(self.damping_metric_with(&self.frames(state)?))
    }

    pub(super) fn damping_metric_with(&self, frames: &Frames) -> Vec<Real> {
        let mut d = vec![1.0; self.num_dofs];
        let mut s_entries = Vec::new();
        for (c, dof) in self.cloth_dof.iter().enumerate() {
            if let Some(k) = *dof {
                let t = &frames.points[c].tangents;
                d[k] = t.column(0).norm_squared();
                d[k + 1] = t.column(1).norm_squared();
                s_entries.extend([d[k], d[k + 1]]);
            }
        }
        // Next to an extraordinary vertex of valence < 6 the limit surface's tangents shrink to zero at the
        // vertex; floor the metric there at 10⁻³ of the median so such a coordinate is still damped.
        if !s_entries.is_empty() {
            let mid = s_entries.len() / 2;
            let median = *s_entries
                .select_nth_unstable_by(mid, |a, b| a.total_cmp(b))
                .1;
            let floor = 1e-3 * median;
            for dof in self.cloth_dof.iter().flatten() {
                d[*dof] = d[*dof].max(floor);
                d[dof + 1] = d[dof + 1].max(floor);
            }
        }
        d
    }

    /// Unbalanced forces (N): the body gradient entries as they are, and for each cloth vertex's `∂U/∂s`
    /// the tangential force it represents, `|T (TᵀT)⁻¹ ∂U/∂s|`. Returns `‖·‖₂` over all of them.
    pub fn force_residual(
        &self,
        state: &ClothOnBodyState,
        gradient: &[Real],
    ) -> Result<Real, ClothOnBodyError> {
        Ok(self.force_residual_with(&self.frames(state)?, gradient))
    }

    pub(super) fn force_residual_with(&self, frames: &Frames, gradient: &[Real]) -> Real {
        let mut sum = 0.0;
        for dof in &self.body_dof {
            if let Some(d) = *dof {
                sum += gradient[d] * gradient[d]
                    + gradient[d + 1] * gradient[d + 1]
                    + gradient[d + 2] * gradient[d + 2];
            }
        }
        for (c, dof) in self.cloth_dof.iter().enumerate() {
            if let Some(d) = *dof {
                let t = &frames.points[c].tangents;
                let gs = Vec2::new(gradient[d], gradient[d + 1]);
                let metric = t.transpose() * t;
                let f = match metric.try_inverse() {
                    Some(inv) => gs.dot(&(inv * gs)),
                    None => Real::INFINITY,
                };
                sum += f;
            }
        }
        sum.sqrt()
    }

    /// The smallest volume ratio `J = det F` over the body tetrahedra at `state`, and its tetrahedron
    /// (`(1, 0)` for a body without tetrahedra). `J ≤ 0` is an inverted element.
    pub fn min_volume_ratio(&self, state: &ClothOnBodyState) -> (Real, usize) {
        let mut best = (1.0, 0);
        for (t, tet) in self.tets.iter().enumerate() {
            let j = self.body.elements()[t]
                .deformation_gradient(&tet.map(|v| state.body[v]))
                .determinant();
            if !(j >= best.0) {
                best = (j, t);
            }
        }
        best
    }

    /// Cartesian cloth force norm `‖∂U_cloth/∂x‖₂` (N) over all cloth vertices: the forces the body must
    /// balance, used as the force scale of the convergence test.
    pub fn cloth_force_norm(&self, state: &ClothOnBodyState) -> Result<Real, ClothOnBodyError> {
        let g = self.cloth_vertex_forces(state)?;
        Ok(g.iter().map(|f| f.norm_squared()).sum::<Real>().sqrt())
    }

    /// `∂U_cloth/∂x_i` (N, `#Vc`): minus the force the cloth exerts at each cloth vertex.
    pub fn cloth_vertex_forces(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<Vec3>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        let mut out = vec![Vec3::zeros(); state.cloth.len()];
        for (t, element) in self.elements.iter().enumerate() {
            let (_, g) = element
                .energy_gradient(&self.law, &self.corners(t, &frames.points))
                .map_err(|source| ClothOnBodyError::Cloth {
                    triangle: t,
                    source,
                })?;
            for (i, &c) in self.triangles[t].iter().enumerate() {
                out[c] += Vec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2]);
            }
        }
        Ok(out)
    }

    /// Per cloth triangle: principal stretches, regime and stress.
    pub fn element_states(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<MembraneState>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        self.elements
            .iter()
            .enumerate()
            .map(|(t, e)| {
                e.state(&self.law, &self.corners(t, &frames.points))
                    .map_err(|source| ClothOnBodyError::Cloth {
                        triangle: t,
                        source,
                    })
            })
            .collect()
    }

    /// Per cloth vertex, the normal force the cloth presses onto the body, `∂U_cloth/∂x_i · n_i` (N;
    /// positive = pressing in, negative = pulling away), with `n_i` the outward surface normal.
    pub fn cloth_normal_forces(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<Real>, ClothOnBodyError> {
        let forces = self.cloth_vertex_forces(state)?;
        let points = self.cloth_surface_points(state)?;
        Ok(forces
            .iter()
            .zip(&points)
            .map(|(g, p)| p.normal().map_or(0.0, |n| g.dot(&n)))
            .collect())
    }

    /// Interface pressure per cloth triangle (Pa): the normal force of the triangle's own corner forces,
    /// `Σ_i ∂U_e/∂x_i · n_i`, over its deformed area. Positive presses onto the body; negative would lift off.
    pub fn element_pressures(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<Real>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        let mut out = Vec::with_capacity(self.elements.len());
        for (t, element) in self.elements.iter().enumerate() {
            let x = self.corners(t, &frames.points);
            let (_, g) = element.energy_gradient(&self.law, &x).map_err(|source| {
                ClothOnBodyError::Cloth {
                    triangle: t,
                    source,
                }
            })?;
            let mut normal_force = 0.0;
            for (i, &c) in self.triangles[t].iter().enumerate() {
                if let Some(n) = frames.points[c].normal() {
                    normal_force += Vec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2]).dot(&n);
                }
            }
            let area = 0.5 * (x[1] - x[0]).cross(&(x[2] - x[0])).norm();
            out.push(if area > 0.0 { normal_force / area } else { 0.0 });
        }
        Ok(out)
    }

    /// The floor of the convergence test's force scale, `10⁻³ E t ℓ √#Vc` (N): the force norm of a 0.1 %
    /// stretch of the fabric (Young's modulus `E`, thickness `t`, `ℓ` the square root of the mean pattern
    /// triangle area) over all cloth vertices, so that a slack garment has a scale (see
    /// [`mod@crate::equilibrium`]). `10⁻¹²` N for a system without cloth triangles.
    pub fn force_scale_floor(&self) -> Real {
        let elements = self.elements();
        if elements.is_empty() {
            return 1e-12;
        }
        let mean_area =
            elements.iter().map(|e| e.rest_area()).sum::<Real>() / elements.len() as Real;
        let t = elements[0].thickness();
        1e-3 * self.fabric_youngs_modulus()
            * t
            * mean_area.sqrt()
            * (self.num_cloth_vertices() as Real).sqrt()
    }
}
