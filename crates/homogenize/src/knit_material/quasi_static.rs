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
                let c = [dm.column(0).into_owned(), dm.column(1).into_owned(), dm.column(2).into_owned()];
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
            g[k] = if self.fixed[k] { 0.0 } else { g[k] - self.force[k] };
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
