//! Sliding over several body poses with Coulomb friction (thesis Eq. 182–183): the garment, worn in the
//! neutral pose, should not slide when the body moves.
//!
//! The neutral equilibrium gives every unpinned cloth vertex `j` its place on the body surface, `s_j`
//! (face and coordinates). A pose `k` is a deformed copy of the body surface — the same control mesh
//! with other control positions (`#Vs × 3`, m) — so the cloth carried along sits at `x_kj = S_k(s_j)`,
//! generally not in equilibrium. With the cloth's elastic force `f_kj = −∂U/∂x_j (x_k, X̄)` (N), the
//! pose's unit normal `n_kj` at `s_j`, the pressing force `N_kj = max(0, −f_kj·n_kj)` and the tangential
//! force `f^t_kj = ‖f_kj − (f_kj·n_kj) n_kj‖`, friction holds the vertex while `f^t ≤ μ N` (isotropic
//! Coulomb friction, coefficient `μ`). The term penalizes the excess:
//!
//! ```text
//! T = w Σ_k Σ_j T_kj²,     T_kj = max(0, f^t_kj − μ N_kj)     (N² × w).
//! ```
//!
//! (Eq. 182 writes `f^c = μ f·n` with `f` the force on the body; here `f` is the force on the cloth, so the
//! pressing force is `−f·n`, and a vertex pulled off the body has `N = 0`.) Pinned cloth vertices are held
//! by their pins and left out. `per_element` has one entry per cloth vertex (`#Vc`): its sum over poses.
//!
//! # Derivatives (Eq. 183)
//!
//! `T` depends on the pattern `X̄` (through the elements' rest shapes) and on the neutral pose's surface
//! coordinates `s` (through `x_kj` and `n_kj`), not on the neutral cloth positions or the body positions:
//! a state term ([`Term::evaluate_with_state`]) whose `∂T/∂q` holds only `s` entries. For an active
//! vertex, with `t = (f − (f·n)n)/f^t` and `[·]` = 1 while the vertex is pressed (`f·n < 0`):
//!
//! ```text
//! ∂T_kj²/∂f = 2T (t + μ n [·]),    ∂T_kj²/∂n = 2T (−(f·n) t + μ f [·]),
//! ```
//!
//! `∂f_j/∂x_m = −Σ_e H_e[j, m]`, `∂f_j/∂X̄ = −Σ_e M_e[j, :]` (element Hessians and mixed Hessians),
//! `∂x_kj/∂s_j` the pose's tangents and `∂n/∂s` from its second derivatives. `T_kj²` is C¹ across the
//! friction limit (`T → 0` there) and across `N = 0`.
//!
//! # Residuals (Gauss-Newton)
//!
//! `T` is a sum of squares: one residual `r_kj = √w T_kj` per pose and slipping vertex
//! ([`Term::residuals_with_state`]), with `∂r_kj/∂θ = √w (∂T_kj/∂f · ∂f_j/∂θ + ∂T_kj/∂n · ∂n_kj/∂θ)` —
//! the chain of the gradient with the seed `√w` instead of `2 w T_kj`. `r` is continuous (zero at the
//! friction limit) but its Jacobian jumps there, as for every `max(0, ·)` residual.

use crate::math::{Real, Vec2, Vec3};
use crate::term::{
    Residuals, StateInput, Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight,
};
use skintight_geometry::surface::Stencil;

const NAME: &str = "sliding";

/// The multi-pose sliding objective of Eq. 182–183; see the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct Sliding {
    weight: Real,
    friction: Real,
    /// Control positions of each pose (`#Vs × 3`, m).
    poses: Vec<Vec<Vec3>>,
}

/// Cloth vertex `j` in one pose.
struct PosedVertex {
    position: Vec3,
    tangents: crate::math::Mat3x2,
    second: [Vec3; 3],
}

impl Sliding {
    /// The term with weight `w` (≥ 0, per N²), friction coefficient `μ` (≥ 0, dimensionless) and the
    /// poses' control positions (each `#Vs × 3`, m, finite; at least one pose). The sizes are checked
    /// against the system when the term is evaluated.
    pub fn new(weight: Real, friction: Real, poses: Vec<Vec<Vec3>>) -> Result<Self, TermError> {
        let bad = |message: String| {
            Err(TermError::Parameter {
                term: NAME,
                message,
            })
        };
        check_weight(NAME, "weight", weight)?;
        if !(friction.is_finite() && friction >= 0.0) {
            return bad(format!(
                "the friction coefficient must be finite and ≥ 0, got {friction}"
            ));
        }
        if poses.is_empty() {
            return bad("at least one pose is needed".into());
        }
        if let Some((k, v)) = poses.iter().enumerate().find_map(|(k, p)| {
            p.iter()
                .position(|x| !x.iter().all(|c| c.is_finite()))
                .map(|v| (k, v))
        }) {
            return bad(format!("pose {k}: vertex {v} is not finite"));
        }
        Ok(Self {
            weight,
            friction,
            poses,
        })
    }

    /// The number of poses.
    pub fn num_poses(&self) -> usize {
        self.poses.len()
    }

    fn posed(&self, state: &StateInput, pose: usize) -> Result<Vec<PosedVertex>, TermError> {
        let surface = state.system.surface();
        let control = &self.poses[pose];
        if control.len() != surface.num_control_vertices() {
            return Err(TermError::Invalid {
                term: NAME,
                message: format!(
                    "pose {pose} has {} surface vertices, the body {}",
                    control.len(),
                    surface.num_control_vertices()
                ),
            });
        }
        let mut stencil = Stencil::with_capacity(64);
        state
            .state
            .cloth
            .iter()
            .map(|c| {
                let p = surface
                    .point_with(control, c.face, c.s, &mut stencil)
                    .map_err(|e| TermError::Invalid {
                        term: NAME,
                        message: format!("pose {pose}: {e}"),
                    })?;
                Ok(PosedVertex {
                    position: p.position,
                    tangents: p.tangents,
                    second: p.second,
                })
            })
            .collect()
    }
}

/// One pose's evaluation: the carried cloth, the elastic forces, the element derivatives (when asked for)
/// and every vertex's excess with its unit seeds.
struct PoseEvaluation {
    posed: Vec<PosedVertex>,
    /// Per cloth triangle: the element Hessian (9 × 9) and mixed Hessian (9 × 6), when asked for.
    blocks: Vec<(nalgebra::SMatrix<Real, 9, 9>, nalgebra::SMatrix<Real, 9, 6>)>,
    /// Per cloth vertex: `(excess T_kj, ∂T_kj/∂f, ∂T_kj/∂n)` for the active ones (`T_kj > 0`).
    active: Vec<Option<(Real, Vec3, Vec3)>>,
}

/// `∂n/∂s_a` (a = 1, 2) of the unit normal `n = (t1 × t2)/‖t1 × t2‖` at a posed vertex: with
/// `∂t1/∂s1 = x11`, `∂t1/∂s2 = ∂t2/∂s1 = x12`, `∂t2/∂s2 = x22`.
fn normal_derivatives(p: &PosedVertex) -> [Vec3; 2] {
    let (t1, t2) = (
        p.tangents.column(0).into_owned(),
        p.tangents.column(1).into_owned(),
    );
    let cross = t1.cross(&t2);
    let area = cross.norm();
    let n = cross / area;
    let [x11, x12, x22] = p.second;
    [(x11, x12), (x12, x22)].map(|(dt1, dt2)| {
        let dc = dt1.cross(&t2) + t1.cross(&dt2);
        (dc - n * n.dot(&dc)) / area
    })
}

impl Sliding {
    fn pose_evaluation(
        &self,
        input: &TermInput,
        state: &StateInput,
        pose: usize,
        derivatives: bool,
    ) -> Result<PoseEvaluation, TermError> {
        let system = state.system;
        let nc = input.mesh.num_cloth_vertices;
        let density = input.fabric.law();
        let posed = self.posed(state, pose)?;
        // Forces on the cloth vertices in this pose, and the elements' derivatives when needed.
        let mut force = vec![Vec3::zeros(); nc];
        let mut blocks = Vec::new();
        for (t, tri) in input.mesh.cloth_triangles.iter().enumerate() {
            let rest = input.mesh.pattern_triangles[t].map(|v| input.pattern[v]);
            let x = tri.map(|c| posed[c].position);
            let collapsed = |_| TermError::Collapsed {
                term: NAME,
                triangle: t,
            };
            let element = input.fabric.element(t, rest).map_err(collapsed)?;
            let g = if derivatives {
                let d = element.derivatives(density, &x).map_err(collapsed)?;
                let m = element.mixed_hessian(density, &x).map_err(collapsed)?;
                blocks.push((d.hessian, m));
                d.gradient
            } else {
                element.energy_gradient(density, &x).map_err(collapsed)?.1
            };
            for (k, &c) in tri.iter().enumerate() {
                force[c] -= Vec3::new(g[3 * k], g[3 * k + 1], g[3 * k + 2]);
            }
        }
        // Per vertex: the excess and its derivatives with respect to the force and the normal.
        let mut active = vec![None; nc];
        for j in 0..nc {
            if system.cloth_dof(j).is_none() {
                continue;
            }
            let tangents = posed[j].tangents;
            let cross = tangents.column(0).cross(&tangents.column(1));
            let area = cross.norm();
            if !(area > 0.0) {
                return Err(TermError::Invalid {
                    term: NAME,
                    message: format!(
                        "pose {pose}: the surface has no normal under cloth vertex {j}"
                    ),
                });
            }
            let n = cross / area;
            let f = force[j];
            let fn_ = f.dot(&n);
            let tangential = f - n * fn_;
            let ft = tangential.norm();
            let pressed = fn_ < 0.0;
            let excess = ft - self.friction * (-fn_).max(0.0);
            if excess <= 0.0 || ft == 0.0 {
                continue;
            }
            let t = tangential / ft;
            let (by_force, by_normal) = if pressed {
                (t + n * self.friction, t * (-fn_) + f * self.friction)
            } else {
                (t, t * (-fn_))
            };
            active[j] = Some((excess, by_force, by_normal));
        }
        Ok(PoseEvaluation {
            posed,
            blocks,
            active,
        })
    }
}

impl Term for Sliding {
    fn name(&self) -> &'static str {
        NAME
    }

    fn evaluate(
        &self,
        _input: &TermInput,
        _gradient: Option<&mut TermGradient>,
    ) -> Result<TermEvaluation, TermError> {
        Err(TermError::Invalid {
            term: NAME,
            message: "sliding needs the coupled state (the cloth's surface coordinates)".into(),
        })
    }

    fn evaluate_with_state(
        &self,
        input: &TermInput,
        state: &StateInput,
        mut gradient: Option<&mut TermGradient>,
        mut state_gradient: Option<&mut [Real]>,
    ) -> Result<TermEvaluation, TermError> {
        input.validate(NAME, gradient.as_deref())?;
        state.validate(NAME, input, state_gradient.as_deref())?;
        let system = state.system;
        let nc = input.mesh.num_cloth_vertices;
        let wanted = gradient.is_some() || state_gradient.is_some();
        let mut per_element = vec![0.0; nc];
        for pose in 0..self.poses.len() {
            let eval = self.pose_evaluation(input, state, pose, wanted)?;
            // dT/df and dT/dn per vertex: 2 w T_kj times the unit seeds.
            let mut d_force = vec![Vec3::zeros(); nc];
            let mut d_normal = vec![Vec3::zeros(); nc];
            for (j, a) in eval.active.iter().enumerate() {
                if let Some((excess, by_force, by_normal)) = a {
                    per_element[j] += self.weight * excess * excess;
                    let two = 2.0 * self.weight * excess;
                    d_force[j] = by_force * two;
                    d_normal[j] = by_normal * two;
                }
            }
            if !wanted {
                continue;
            }
            // dT/dx_k (per cloth vertex) and dT/dX̄ through the forces: f_j = −Σ_e ∂U_e/∂x_j.
            let mut d_position = vec![Vec3::zeros(); nc];
            for (t, tri) in input.mesh.cloth_triangles.iter().enumerate() {
                if tri.iter().all(|&c| d_force[c] == Vec3::zeros()) {
                    continue;
                }
                let (h, m) = &eval.blocks[t];
                for (k, &c) in tri.iter().enumerate() {
                    let u = d_force[c];
                    if u == Vec3::zeros() {
                        continue;
                    }
                    for (i, &ci) in tri.iter().enumerate() {
                        d_position[ci] -= h.fixed_view::<3, 3>(3 * k, 3 * i).transpose() * u;
                    }
                    if let Some(g) = gradient.as_deref_mut() {
                        let ptri = input.mesh.pattern_triangles[t];
                        for (i, &p) in ptri.iter().enumerate() {
                            g.pattern[p] -= m.fixed_view::<3, 2>(3 * k, 2 * i).transpose() * u;
                        }
                    }
                }
            }
            // To the neutral surface coordinates: x_kj = S_k(s_j), n_kj = n_k(s_j).
            if let Some(sg) = state_gradient.as_deref_mut() {
                for j in 0..nc {
                    let Some(d) = system.cloth_dof(j) else {
                        continue;
                    };
                    let p = &eval.posed[j];
                    let mut ds: Vec2 = p.tangents.transpose() * d_position[j];
                    if d_normal[j] != Vec3::zeros() {
                        let dn = normal_derivatives(p);
                        ds.x += d_normal[j].dot(&dn[0]);
                        ds.y += d_normal[j].dot(&dn[1]);
                    }
                    sg[d] += ds.x;
                    sg[d + 1] += ds.y;
                }
            }
        }
        TermEvaluation::from_per_element(NAME, per_element)
    }

    /// One residual `√w T_kj` per pose and active (slipping) unpinned cloth vertex, pose by pose in vertex
    /// order: its Jacobian has pattern entries (through the rest shapes of the vertex's triangles) and
    /// state entries on the surface coordinates of the vertex's one-ring (through the posed positions) and
    /// of the vertex itself (through the normal); none on the neutral cloth positions.
    fn residuals_with_state(
        &self,
        input: &TermInput,
        state: &StateInput,
    ) -> Option<Result<Residuals, TermError>> {
        Some((|| {
            input.validate(NAME, None)?;
            state.validate(NAME, input, None)?;
            let system = state.system;
            let nc = input.mesh.num_cloth_vertices;
            let root = self.weight.sqrt();
            // The triangles around each cloth vertex, with the vertex's corner.
            let mut around: Vec<Vec<(usize, usize)>> = vec![Vec::new(); nc];
            for (t, tri) in input.mesh.cloth_triangles.iter().enumerate() {
                for (k, &c) in tri.iter().enumerate() {
                    around[c].push((t, k));
                }
            }
            let mut res = Residuals::default();
            for pose in 0..self.poses.len() {
                let eval = self.pose_evaluation(input, state, pose, true)?;
                for (j, a) in eval.active.iter().enumerate() {
                    let Some((excess, by_force, by_normal)) = a else {
                        continue;
                    };
                    let row = res.values.len();
                    res.values.push(root * excess);
                    let u = by_force * root;
                    for &(t, k) in &around[j] {
                        let (h, m) = &eval.blocks[t];
                        let tri = input.mesh.cloth_triangles[t];
                        let ptri = input.mesh.pattern_triangles[t];
                        for i in 0..3 {
                            let dp = -(m.fixed_view::<3, 2>(3 * k, 2 * i).transpose() * u);
                            res.pattern_jacobian.push((row, ptri[i], dp));
                            if let Some(d) = system.cloth_dof(tri[i]) {
                                let dx = -(h.fixed_view::<3, 3>(3 * k, 3 * i).transpose() * u);
                                let ds = eval.posed[tri[i]].tangents.transpose() * dx;
                                res.state_jacobian.push((row, d, ds.x));
                                res.state_jacobian.push((row, d + 1, ds.y));
                            }
                        }
                    }
                    let d = system.cloth_dof(j).expect("active vertices are unpinned");
                    let dn = normal_derivatives(&eval.posed[j]);
                    for (a, dn) in dn.iter().enumerate() {
                        res.state_jacobian
                            .push((row, d + a, root * by_normal.dot(dn)));
                    }
                }
            }
            Ok(res)
        })())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_parameters_are_refused() {
        let pose = vec![vec![Vec3::zeros(); 3]];
        assert!(Sliding::new(-1.0, 0.5, pose.clone()).is_err());
        assert!(Sliding::new(1.0, Real::NAN, pose.clone()).is_err());
        assert!(Sliding::new(1.0, 0.5, vec![]).is_err());
        assert!(Sliding::new(1.0, 0.5, vec![vec![Vec3::new(Real::NAN, 0.0, 0.0)]]).is_err());
        assert_eq!(Sliding::new(1.0, 0.5, pose).unwrap().num_poses(), 1);
    }
}
