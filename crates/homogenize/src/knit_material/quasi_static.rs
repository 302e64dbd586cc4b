//! The quasi-static equilibrium of the volumetric knit under dead loads, as a problem of the Newton
//! toolkit ([`skintight_physics::newton::NewtonProblem`]): the per-pose solve of the elasticity fit
//! (the knitwear paper Eq. 14, where the loads are the pose's inertia and gravity forces):
//!
//! ```text
//! min_x  Σ_e E_e(x) − f · x        over the free coordinates, the fixed ones held where they start
//! ```
//!
//! (J; `f` the nodal forces, `3#V`, N). The gradient is `∂E/∂x − f` with the fixed coordinates' entries
//! zeroed; the Hessian is the material's PSD-filtered one ([`MaterialHessian::Projected`]) with the
//! fixed rows and columns replaced by a positive diagonal (their step is then zero). The residual is
//! `‖g_free‖∞` over a force scale (N; by default `max_e (γˢ_e + γᵛ_e) V_e^{2/3}`, the force of a unit
//! strain on an element's face), and a step moves no node by more than a fraction of the shortest rest
//! edge (no element is inverted in one step).

use faer::sparse::Triplet;
use skintight_physics::newton::NewtonProblem;

use super::assembly::KnitMaterial;
use super::density::MaterialHessian;

/// Settings of [`QuasiStaticProblem`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuasiStaticParams {
    /// The most a node may move in one Newton step, as a fraction of the shortest rest edge
    /// (dimensionless, in `(0, 10]`).
    pub step_fraction: f64,
    /// The force the residual is measured against (N); `None`: `max_e (γˢ_e + γᵛ_e) V_e^{2/3}`.
    pub force_scale: Option<f64>,
}

impl Default for QuasiStaticParams {
    fn default() -> Self {
        Self {
            step_fraction: 0.5,
            force_scale: None,
        }
    }
}

/// Why a [`QuasiStaticProblem`] cannot be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum QuasiStaticError {
    /// The loads or the fixed flags do not have `3#V` entries.
    #[error("{what} has {got} entries, expected 3 × #V = {expected}")]
    Length {
        /// `force` or `fixed`.
        what: &'static str,
        /// Entries given.
        got: usize,
        /// `3#V`.
        expected: usize,
    },
    /// A load is not finite.
    #[error("force[{index}] = {value} N: loads must be finite")]
    Force {
        /// Its index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A setting is out of range.
    #[error("quasi-static solve: {field} = {value} is out of range ({expected})")]
    Params {
        /// Which setting.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        expected: &'static str,
    },
    /// The material has no stiffness to measure forces against (all `γ = 0`) and no force scale was
    /// given.
    #[error("all material parameters are 0: give QuasiStaticParams::force_scale")]
    NoStiffness,
}

/// The quasi-static problem of one pose (see the module doc).
#[derive(Clone, Debug)]
pub struct QuasiStaticProblem<'a> {
    material: &'a KnitMaterial,
    force: Vec<f64>,
    fixed: Vec<bool>,
    max_step: f64,
    force_scale: f64,
}

impl<'a> QuasiStaticProblem<'a> {
    /// `material` under nodal loads `force` (`3#V`, N) with the coordinates flagged in `fixed` (`3#V`)
    /// held at their starting values.
    pub fn new(
        material: &'a KnitMaterial,
        force: Vec<f64>,
        fixed: Vec<bool>,
        params: &QuasiStaticParams,
    ) -> Result<Self, QuasiStaticError> {
        let n = material.dof_count();
        for (what, got) in [("force", force.len()), ("fixed", fixed.len())] {
            if got != n {
                return Err(QuasiStaticError::Length {
                    what,
                    got,
                    expected: n,
                });
            }
        }
        if let Some((index, &value)) = force.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(QuasiStaticError::Force { index, value });
        }
        if !(params.step_fraction > 0.0 && params.step_fraction <= 10.0) {
            return Err(QuasiStaticError::Params {
                field: "step_fraction",
                value: params.step_fraction,
                expected: "0 < step_fraction ≤ 10",
            });
        }
        let force_scale = match params.force_scale {
            Some(s) if s.is_finite() && s > 0.0 => s,
            Some(s) => {
                return Err(QuasiStaticError::Params {
                    field: "force_scale",
                    value: s,
                    expected: "finite and > 0 (N)",
                });
            }
            None => {
                let s = material
                    .rest_tets()
                    .iter()
                    .zip(material.gamma())
                    .map(|(r, g)| (g[0] + g[1]) * r.volume.powf(2.0 / 3.0))
                    .fold(0.0, f64::max);
                if s > 0.0 {
                    s
                } else {
                    return Err(QuasiStaticError::NoStiffness);
                }
            }
        };
        // The shortest rest edge, from D_m = (D_m⁻¹)⁻¹.
        let shortest = material
            .rest_tets()
            .iter()
            .filter_map(|r| r.dm_inverse.try_inverse())
            .flat_map(|dm| {
                let c = [
                    dm.column(0).into_owned(),
                    dm.column(1).into_owned(),
                    dm.column(2).into_owned(),
                ];
                [
                    c[0].norm(),
                    c[1].norm(),
                    c[2].norm(),
                    (c[0] - c[1]).norm(),
                    (c[0] - c[2]).norm(),
                    (c[1] - c[2]).norm(),
                ]
            })
            .fold(f64::INFINITY, f64::min);
        let max_step = if shortest.is_finite() {
            params.step_fraction * shortest
        } else {
            f64::INFINITY
        };
        Ok(Self {
            material,
            force,
            fixed,
            max_step,
            force_scale,
        })
    }

    /// The force scale of the residual (N).
    pub fn force_scale(&self) -> f64 {
        self.force_scale
    }
}

impl NewtonProblem for QuasiStaticProblem<'_> {
    fn dof_count(&self) -> usize {
        self.material.dof_count()
    }

    fn evaluate(
        &self,
        x: &[f64],
        hessian: bool,
    ) -> (f64, Vec<f64>, Vec<Triplet<usize, usize, f64>>) {
        let form = if hessian {
            MaterialHessian::Projected
        } else {
            MaterialHessian::Skip
        };
        let Ok(ev) = self.material.evaluate(x, form) else {
            // Not finite positions: an infinite energy makes the line search reject the point.
            return (f64::INFINITY, vec![0.0; x.len()], Vec::new());
        };
        let mut energy = ev.energy;
        let mut g = ev.gradient;
        for k in 0..x.len() {
            energy -= self.force[k] * x[k];
            g[k] = if self.fixed[k] {
                0.0
            } else {
                g[k] - self.force[k]
            };
        }
        let mut triplets = ev.hessian;
        if hessian {
            triplets.retain(|t| !self.fixed[t.row] && !self.fixed[t.col]);
            // Any positive value on a held coordinate: its gradient is zero, so its step is zero.
            let diagonal = self.force_scale / self.max_step.min(1.0);
            for (k, &f) in self.fixed.iter().enumerate() {
                if f {
                    triplets.push(Triplet::new(k, k, diagonal));
                }
            }
        }
        (energy, g, triplets)
    }

    fn energy(&self, x: &[f64]) -> f64 {
        match self.material.energy(x) {
            Ok(e) => e - self.force.iter().zip(x).map(|(f, v)| f * v).sum::<f64>(),
            Err(_) => f64::INFINITY,
        }
    }

    fn group_size(&self) -> usize {
        3
    }

    /// `‖g‖∞ / force scale` (the fixed coordinates' entries are zero).
    fn residual(&self, g: &[f64]) -> f64 {
        g.iter().fold(0.0_f64, |m, v| m.max(v.abs())) / self.force_scale
    }

    /// Brings the largest node displacement of `h` within the step limit.
    fn step_scale(&self, h: &[f64]) -> f64 {
        let largest = h
            .chunks_exact(3)
            .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
            .fold(0.0, f64::max);
        if largest > self.max_step {
            self.max_step / largest
        } else {
            1.0
        }
    }

    fn accepted(&mut self, _x: &[f64]) {}
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::closest_volume_preserving::VolumePreservingParams;
    use crate::knit_material::density::knit_density;
    use crate::knit_material::test_states::block_mesh;
    use crate::volumetric_mesh::VolumetricMesh;
    use nalgebra::{Matrix3, Vector3};
    use skintight_physics::newton::{NewtonParams, minimize};

    /// Roller supports on the faces x = 0, y = 0, z = 0 (each holds its normal coordinate) and the
    /// nodal loads of a uniform nominal traction `t` (Pa) along +x on the face x = `length`: each
    /// boundary triangle there gives `t A / 3` to each of its nodes.
    fn uniaxial_setup(mesh: &VolumetricMesh, length: f64, t: f64) -> (Vec<f64>, Vec<bool>) {
        let n = mesh.rest.len();
        let eps = 1e-9 * length;
        let mut fixed = vec![false; 3 * n];
        for (v, p) in mesh.rest.iter().enumerate() {
            for c in 0..3 {
                fixed[3 * v + c] = p[c].abs() < eps;
            }
        }
        let mut force = vec![0.0; 3 * n];
        let on_face = |v: usize| (mesh.rest[v][0] - length).abs() < eps;
        for tet in &mesh.tets {
            for skip in 0..4 {
                let face: Vec<usize> = (0..4).filter(|&k| k != skip).map(|k| tet[k]).collect();
                if face.iter().all(|&v| on_face(v)) {
                    let p = face
                        .iter()
                        .map(|&v| Vector3::from(mesh.rest[v]))
                        .collect::<Vec<_>>();
                    let area = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
                    for &v in &face {
                        force[3 * v] += t * area / 3.0;
                    }
                }
            }
        }
        (force, fixed)
    }

    /// Solves the block and returns the largest distance of a node from `F X`.
    fn solve_and_compare(gamma: [f64; 2], t: f64, expected: Matrix3<f64>) -> (f64, usize) {
        let h = 0.01;
        let mesh = block_mesh(3, 2, 2, h);
        let material = KnitMaterial::new(
            &mesh,
            vec![gamma; mesh.tets.len()],
            VolumePreservingParams::default(),
        )
        .unwrap();
        let (force, fixed) = uniaxial_setup(&mesh, 3.0 * h, t);
        let mut problem =
            QuasiStaticProblem::new(&material, force, fixed, &QuasiStaticParams::default())
                .unwrap();
        let mut x: Vec<f64> = mesh.rest.iter().flatten().copied().collect();
        let report = minimize(&mut problem, &mut x, &NewtonParams::default()).unwrap();
        assert!(report.converged, "{report:?}");
        eprintln!(
            "quasi-static block: {} Newton iterations",
            report.iterations
        );
        let error = mesh
            .rest
            .iter()
            .enumerate()
            .map(|(v, p)| {
                let want = expected * Vector3::from(*p);
                (Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]) - want).norm()
            })
            .fold(0.0, f64::max);
        (error, report.iterations)
    }

    #[test]
    fn shape_term_alone_stretches_by_the_closed_form() {
        // γᵛ = 0: ψ = γˢ Σ (σ_i − 1)², so a uniaxial nominal stress t gives λ = 1 + t / (2γˢ) along x
        // and no lateral contraction.
        let gs = 2.0e3;
        let t = 800.0;
        let lambda = 1.0 + t / (2.0 * gs);
        let (error, iterations) = solve_and_compare(
            [gs, 0.0],
            t,
            Matrix3::from_diagonal(&Vector3::new(lambda, 1.0, 1.0)),
        );
        assert!(
            error < 1e-9 * 0.03,
            "error {error} m after {iterations} iterations"
        );
    }

    #[test]
    fn block_under_uniaxial_stress_reaches_the_uniform_stretch() {
        // With both terms: the uniform state F = diag(λ, μ, μ) with P₂₂ = P₃₃ = 0 (μ by bisection) is the
        // equilibrium under the traction t = P₁₁, and the Newton toolkit must find it.
        let gamma = [1.0e3, 3.0e3];
        let params = VolumePreservingParams::default();
        let lambda = 1.3;
        let stress = |mu: f64| {
            knit_density(
                &Matrix3::from_diagonal(&Vector3::new(lambda, mu, mu)),
                gamma,
                MaterialHessian::Skip,
                &params,
            )
            .unwrap()
            .stress
        };
        let (mut lo, mut hi) = (0.5, 1.2);
        assert!(stress(lo)[(1, 1)] < 0.0 && stress(hi)[(1, 1)] > 0.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if stress(mid)[(1, 1)] < 0.0 {
                lo = mid
            } else {
                hi = mid
            }
        }
        let mu = 0.5 * (lo + hi);
        assert!(mu < 0.99, "the volume term contracts laterally: μ = {mu}");
        let t = stress(mu)[(0, 0)];
        let (error, iterations) = solve_and_compare(
            gamma,
            t,
            Matrix3::from_diagonal(&Vector3::new(lambda, mu, mu)),
        );
        assert!(
            error < 1e-8 * 0.03,
            "error {error} m after {iterations} iterations"
        );
    }

    #[test]
    fn bad_setup_is_an_error() {
        let mesh = block_mesh(1, 1, 1, 0.01);
        let material = KnitMaterial::new(
            &mesh,
            vec![[1.0, 1.0]; 6],
            VolumePreservingParams::default(),
        )
        .unwrap();
        let n = material.dof_count();
        let p = QuasiStaticParams::default();
        let e = QuasiStaticProblem::new(&material, vec![0.0; 3], vec![false; n], &p).unwrap_err();
        assert!(e.to_string().contains("force has 3 entries"), "{e}");
        let mut f = vec![0.0; n];
        f[2] = f64::INFINITY;
        let e = QuasiStaticProblem::new(&material, f, vec![false; n], &p).unwrap_err();
        assert!(e.to_string().contains("force[2]"), "{e}");
        let zero = KnitMaterial::new(
            &mesh,
            vec![[0.0, 0.0]; 6],
            VolumePreservingParams::default(),
        )
        .unwrap();
        let e = QuasiStaticProblem::new(&zero, vec![0.0; n], vec![false; n], &p).unwrap_err();
        assert!(e.to_string().contains("force_scale"), "{e}");
    }
}
