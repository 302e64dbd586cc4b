//! Which matrix the Newton solver factors for `∂²U/∂q²`: the Hessian in the surface coordinates of the
//! current faces (thesis Eq. 156–157 as written), or the **covariant Hessian**, which leaves out the part of
//! Eq. 156's surface-curvature term that only the chart puts there.
//!
//! # The equation
//!
//! A cloth vertex `i` lies at `x_i(s_i)` on the body surface, with tangents `T_i = ∂x_i/∂s_i` (3 × 2, m),
//! unit normal `n_i` and second derivatives `x_{i,ab}` (m). Eq. 156's diagonal block carries the force term
//! `[g_i · x_{i,ab}]_ab` (N·m), `g_i = ∂U/∂x_i` (N) summed over the vertex's triangles. The Gauss formula
//! splits the second derivative into its tangential and normal parts,
//!
//! ```text
//! x_{i,ab} = Γ^c_ab T_i[:,c] + II_ab n_i        (Γ the Christoffel symbols of the chart, II the second
//!                                                 fundamental form, both per unit surface coordinate)
//! g_i · x_{i,ab} = Γ^c_ab ∂U/∂s_ic + II_ab (g_i · n_i)        (∂U/∂s_i = T_iᵀ g_i, Eq. 155)
//! ```
//!
//! The first part is the unbalanced tangential force of the vertex times the chart's Christoffel symbols: it
//! vanishes at every equilibrium (`∂U/∂s_i = 0`) and depends on how the face's coordinates are laid out, not
//! on the garment. The second is the physical geometric stiffness of a force pressing on a curved surface.
//! Dropping the first gives the Riemannian (covariant) Hessian of `U` restricted to the surface,
//! `T_iᵀ H_ii T_i + II (g_i · n_i)` (Absil, Mahony & Trumpf 2013, "An extrinsic look at the Riemannian
//! Hessian"). The mixed `s–y` block's force term `∂w_ui/∂s_a g_i` (the body moves the surface under the
//! vertex) splits the same way; its tangential part is `∂w_ui/∂s_a T_i (T_iᵀT_i)⁻¹ ∂U/∂s_i`, also zero at
//! every equilibrium. [`HessianForm::Covariant`] evaluates both force terms with the normal part of the
//! force only, per triangle: `g_i ↦ (g_i · n_i) n_i` (exact after the sum over the triangles, since the
//! split is linear in `g_i`).
//!
//! # Why
//!
//! Away from equilibrium the Christoffel part can be large and of either sign: it makes the coordinate
//! Hessian indefinite where every cloth triangle's own Hessian is positive semidefinite (the chart's doing,
//! not the garment's), so the solver climbs its damping to the median stiffness and spends Newton iterations
//! bringing it back down. The covariant form factors at once near the path to equilibrium and reaches the
//! same equilibria and designs in about half the Newton iterations, so [`HessianForm::Covariant`] is the
//! default; the job key `solver.hessian: "coordinate"` gives Eq. 156 as written. The measurements, and why
//! the coordinate form was the default until they were repeated, are in docs/BENCHMARKS.md ("Session 17:
//! Newton factors the covariant Hessian", "Session 24: the covariant Hessian is the default").
//!
//! # Convergence and exactness
//!
//! The two matrices differ by a term proportional to `∂U/∂s`, the residual: Newton's method with a matrix
//! whose error is bounded by a multiple of the residual keeps its quadratic convergence, and at an
//! equilibrium the covariant Hessian **is** the Hessian. The adjoint, the equilibrium predictor and the
//! Gauss–Newton directions of the design, which factor the solver's final matrix, are therefore unchanged at
//! an exact equilibrium, and at an inexactly solved one carry an error of the order of the residual — the
//! order the inexact-solve bounds already allow for. The coordinate form stays the finite-difference-tested
//! Hessian of `U` ([`super::ClothOnBody::hessian`]); `covariant_hessian_is_the_hessian_less_the_christoffel_term`
//! in the tests checks the difference against `Γ ∂U/∂s` computed from the surface frames.

use serde::{Deserialize, Serialize};

use crate::math::{Mat3x2, Vec3};

/// The matrix that stands for `∂²U/∂q²` in a Newton step (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HessianForm {
    /// Eq. 156–157 as written: the Hessian in the surface coordinates of the current faces.
    Coordinate,
    /// The Hessian less the chart's Christoffel term: the force terms of Eq. 156 and of the `s–y` blocks
    /// with the normal part of the force only. Equal to the Hessian at every equilibrium. The default.
    #[default]
    Covariant,
}

impl HessianForm {
    /// The force (N) that multiplies the surface's second derivatives in the Hessian blocks of a cloth
    /// corner with element force `g` (N, `∂U_e/∂x_i`) and surface tangents `tangents` (3 × 2, m): `g` itself
    /// for [`HessianForm::Coordinate`], its normal part `(g · n) n` for [`HessianForm::Covariant`].
    pub fn curvature_force(self, g: Vec3, tangents: &Mat3x2) -> Vec3 {
        match self {
            HessianForm::Coordinate => g,
            HessianForm::Covariant => {
                let normal = tangents.column(0).cross(&tangents.column(1));
                let n2 = normal.norm_squared();
                if n2 > 0.0 {
                    normal * (g.dot(&normal) / n2)
                } else {
                    g
                }
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::cloth_on_body::tests::{Kind, MIXED, sphere_system};
    use crate::cloth_on_body::{ClothOnBody, ClothOnBodyState};
    use crate::math::Real;
    use crate::node_block_assembly::{NodeBlockAssembler, NodeBlockRecorder};

    #[test]
    fn covariant_force_is_the_normal_part_and_coordinate_force_is_all_of_it() {
        let t = Mat3x2::new(2.0, 0.5, 0.0, 1.5, 0.3, -0.2);
        let g = Vec3::new(0.7, -1.1, 2.3);
        let n = t.column(0).cross(&t.column(1)).normalize();
        let c = HessianForm::Covariant.curvature_force(g, &t);
        // Along the normal, with the normal component of g.
        assert!((c - n * g.dot(&n)).norm() <= 1e-14 * g.norm());
        assert!(c.dot(&t.column(0)).abs() <= 1e-14 * g.norm());
        assert!(c.dot(&t.column(1)).abs() <= 1e-14 * g.norm());
        assert_eq!(HessianForm::Coordinate.curvature_force(g, &t), g);
        // Degenerate tangents: no normal, the force is kept.
        let flat = Mat3x2::new(1.0, 2.0, 0.0, 0.0, 0.0, 0.0);
        assert_eq!(HessianForm::Covariant.curvature_force(g, &flat), g);
    }

    /// The dense matrix of `form` at `state` (both triangles) from the parallel assembly, and the gradient.
    pub(crate) fn assembled_dense(
        system: &ClothOnBody,
        state: &ClothOnBodyState,
        form: HessianForm,
    ) -> (Vec<Real>, Vec<Real>) {
        let n = system.num_dofs();
        let mut recorder = NodeBlockRecorder::default();
        let mut g = vec![0.0; n];
        system.hessian(state, &mut g, &mut recorder).unwrap();
        let mut asm = NodeBlockAssembler::new(n, system.nodes(), &recorder);
        asm.begin();
        let frames = system.frames_at(state).unwrap();
        system
            .hessian_parallel(state, &frames, &mut g, &mut asm, 2, form)
            .unwrap();
        assert!(asm.finish().is_ok());
        (asm.to_dense(), g)
    }

    #[test]
    fn covariant_hessian_is_the_hessian_less_the_christoffel_term() {
        // Away from equilibrium (mixed stretches): coordinate − covariant must be, for every free cloth vertex
        // i with tangential force p_i = T (TᵀT)⁻¹ ∂U/∂s_i, the 2 × 2 block p_i · x_{i,ab} on (s_i, s_i) and
        // ∂w_ui/∂s_a p_i on (s_i, y_u), and zero everywhere else (hessian_form.rs, the Gauss formula).
        for kind in [Kind::Loop, Kind::Linear] {
            let (system, state) = sphere_system(kind, 5, &MIXED);
            let n = system.num_dofs();
            let (coordinate, g) = assembled_dense(&system, &state, HessianForm::Coordinate);
            let (covariant, _) = assembled_dense(&system, &state, HessianForm::Covariant);
            let frames = system.frames(&state).unwrap();
            let mut expected = vec![0.0; n * n];
            for (i, dof) in system.cloth_dof.iter().enumerate() {
                let Some(si) = *dof else { continue };
                let point = &frames.points[i];
                let t = point.tangents;
                let ds = nalgebra::Vector2::new(g[si], g[si + 1]);
                let p = t * (t.transpose() * t).try_inverse().unwrap() * ds;
                let sec = point.second;
                let block = [
                    [p.dot(&sec[0]), p.dot(&sec[1])],
                    [p.dot(&sec[1]), p.dot(&sec[2])],
                ];
                for a in 0..2 {
                    for b in 0..2 {
                        expected[(si + a) * n + si + b] += block[a][b];
                    }
                }
                for &(v, _, dw) in &frames.entries[frames.offsets[i]..frames.offsets[i + 1]] {
                    let Some(yu) = system.body_dof[v] else {
                        continue;
                    };
                    for a in 0..2 {
                        for k in 0..3 {
                            expected[(si + a) * n + yu + k] += dw[a] * p[k];
                            expected[(yu + k) * n + si + a] += dw[a] * p[k];
                        }
                    }
                }
            }
            let scale = coordinate.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            let largest = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            // The state is far enough from equilibrium for the term to matter (else the test proves nothing).
            assert!(
                largest > 1e-6 * scale,
                "{kind:?}: Christoffel term {largest} of {scale}"
            );
            for r in 0..n {
                for c in 0..n {
                    let d = coordinate[r * n + c] - covariant[r * n + c];
                    assert!(
                        (d - expected[r * n + c]).abs() <= 1e-9 * largest + 1e-12 * scale,
                        "{kind:?} ({r}, {c}): difference {d}, Christoffel term {}",
                        expected[r * n + c]
                    );
                }
            }
        }
    }
}
