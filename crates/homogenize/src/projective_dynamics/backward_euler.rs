//! One backward-Euler time step of the volumetric knit as projective dynamics (the knitwear paper
//! Eq. 25–28; Bouaziz et al. 2014). With `x*`, `v*` the positions (m) and velocities (m/s) at the start
//! of the step, `M` the lumped masses (kg), `g` gravity (m/s²) and `E` the material of Eq. 7 (J), the
//! step minimizes
//!
//! ```text
//! Ψ(x) = a/(2Δt²) ‖x − y‖²_M + E(x) − f · x,      y = x* + Δt v* / a,   a = 1 + α Δt,   f = M g
//! ```
//!
//! over the free nodes (the clamped ones sit at their prescribed positions of the step's end), and then
//! `v = (x − x*)/Δt`. The stationarity of `Ψ` is backward Euler `M (v − v*)/Δt = −∇E + f − α M v`:
//! **Rayleigh damping** is its mass-proportional part `α M v` (α in 1/s), which in PD is exact and free —
//! it scales the inertia weight by `a` and pulls the inertial target `y` back, leaving `K` constant.
//! The stiffness-proportional part `β K v` would need the Hessian of Eq. 7, which PD never forms (its PD
//! stand-in `β L v` with `L = Σ ω G_eᵀG_e` is not implemented).
//!
//! **Iterations.** From `x = y` (clamped nodes at their targets), repeat: the local step at `x` gives
//! the targets `P_e` and `E(x)`; by the envelope theorem ([`super::local_step`]) the global step's
//! gradient at `x` with these targets is `∇Ψ(x)` exactly, so the residual
//! `r = ‖∇Ψ(x)‖_∞ / F` over the free nodes (dimensionless; `F` the force scale below, N) costs nothing
//! more; stop when `r ≤ tolerance` or after `max_iterations` global steps; else the global step
//! (Cholesky factored once, or Jacobi sweeps) moves `x`. With the direct global step, `Ψ` does not
//! increase from one iterate to the next (each half-step minimizes the surrogate
//! `a/(2Δt²)‖x − y‖²_M + Σ V_e(γˢ‖F − R‖² + γᵛ‖F − V‖²) − f·x ≥ Ψ`, equal to `Ψ` after the local step),
//! which the tests assert. The force scale is `F = max_e (γˢ_e + γᵛ_e) V_e^{2/3} + max_v m_v |g|`: the
//! force a unit strain puts on an element's face plus the largest nodal weight.
//!
//! **Collisions** ([`ProjectiveDynamics::with_collision`]): `Ψ` gains the yarn-level constraints of
//! [`super::body_collision`], `Σ_j ½ w dist²(N_j x, admissible)` over the *active* yarn vertices: those
//! inside a collider's clearance at the step's first iterate `x = y`, and any that enter one during the
//! iterations (added, never removed within a step; at most [`MAX_CONTACT_CHANGES`] additions a step).
//! Their constraints enter `K` (a numeric refactorization at each change of the set, none while it
//! holds); the local step projects them. Between two changes the surrogate argument above still holds
//! (the projected targets are admissible points, so `½ w ‖N_j x − p_j‖² ≥ ½ w dist²` with equality at
//! the `x` they were projected from), so `Ψ` decreases; at a change it gains the new vertices' penalty.
//! A constraint that is active while its vertex is outside has `p_j = N_j x`: stiffness in `K`, no force
//! at a fixed point. Keeping every vertex near a collider active instead made PD crawl (930 iterations
//! where 1–30 do, on the tests' block): `K` then overestimates the Hessian by `w NᵀN` everywhere there.

use std::time::Instant;

use nalgebra::Matrix3;

use super::body_collision::{BodyCollision, BodyCollisionError};
use super::global_step::{GlobalStep, GlobalStepError};
use super::jacobi_global_step::{JacobiError, JacobiGlobalStep, JacobiParams};
use super::local_step::{LocalStepError, element_weights, local_step};
use crate::closest_volume_preserving::VolumePreservingParams;
use crate::knit_material::{KnitMaterial, KnitMaterialError};
use crate::volumetric_mesh::{Embedded, VolumetricMesh};

/// How the global step is solved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GlobalSolver {
    /// Sparse Cholesky of `K`, factored once ([`GlobalStep`]).
    Cholesky,
    /// Jacobi sweeps, warm-started ([`JacobiGlobalStep`]).
    Jacobi(JacobiParams),
}

/// Settings of [`ProjectiveDynamics`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectiveDynamicsParams {
    /// The time step `Δt` (s, > 0, finite).
    pub dt: f64,
    /// Gravity (m/s²), applied as the nodal forces `m_v g`.
    pub gravity: [f64; 3],
    /// Mass-proportional Rayleigh damping `α` (1/s, ≥ 0).
    pub mass_damping: f64,
    /// Converged when `‖∇Ψ‖_∞ / F ≤ tolerance` (dimensionless, > 0; see the module doc).
    pub tolerance: f64,
    /// Most global steps per time step (at least 1).
    pub max_iterations: usize,
    /// Threads of the local step (at least 1).
    pub threads: usize,
    /// The global step's solver.
    pub solver: GlobalSolver,
    /// The projection `V(F)`'s settings.
    pub projection: VolumePreservingParams,
}

impl Default for ProjectiveDynamicsParams {
    fn default() -> Self {
        Self {
            dt: 1.0 / 150.0,
            gravity: [0.0, -9.81, 0.0],
            mass_damping: 0.0,
            tolerance: 1e-3,
            max_iterations: 100,
            threads: 2,
            solver: GlobalSolver::Cholesky,
            projection: VolumePreservingParams::default(),
        }
    }
}

/// Why the simulation cannot be set up or stepped.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ProjectiveDynamicsError {
    /// A setting out of range.
    #[error("projective dynamics: {field} = {value} is out of range ({expected})")]
    Params {
        /// Which setting.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        expected: &'static str,
    },
    /// The material refused the mesh or `γ`.
    #[error(transparent)]
    Material(#[from] KnitMaterialError),
    /// The global step refused its inputs.
    #[error(transparent)]
    Global(#[from] GlobalStepError),
    /// The Jacobi solver cannot be used.
    #[error(transparent)]
    Jacobi(#[from] JacobiError),
    /// The local step failed.
    #[error(transparent)]
    Local(#[from] LocalStepError),
    /// A collider or the collision settings cannot be used.
    #[error(transparent)]
    Collision(#[from] BodyCollisionError),
    /// Colliders were given for a mesh without embedded yarns.
    #[error(
        "colliders act on the embedded yarn vertices, and this mesh has none; build it with \
         `VolumetricMesh::build` from the yarns"
    )]
    NoYarns,
    /// The prescribed positions do not match the clamped nodes.
    #[error(
        "{given} prescribed positions for {expected} clamped nodes; give one finite position (m) per clamped node, in the order of `clamped()`"
    )]
    Prescribed {
        /// Positions given (or the index of a non-finite one).
        given: usize,
        /// Clamped nodes.
        expected: usize,
    },
}

/// What one time step did.
#[derive(Clone, Debug, PartialEq)]
pub struct PdStepReport {
    /// Global steps taken.
    pub iterations: usize,
    /// The final residual `‖∇Ψ‖_∞ / F` (dimensionless).
    pub residual: f64,
    /// Whether it met the tolerance.
    pub converged: bool,
    /// `Ψ` at each local step, the first at the start `x = y` (J).
    pub objective: Vec<f64>,
    /// The elastic energy `E` at the end of the step (J).
    pub elastic_energy: f64,
    /// Wall time of the step (s).
    pub seconds: f64,
    /// Of which in the local steps (s).
    pub local_seconds: f64,
    /// Of which in the global steps (s).
    pub global_seconds: f64,
    /// Yarn vertices inside a collider's clearance at the end of the step (0 without colliders).
    pub contacts: usize,
    /// The deepest of them inside the clearance (m; 0 without contact).
    pub max_penetration_m: f64,
    /// Times the active contacts grew during the iterations (each a refactorization of `K`).
    pub contact_changes: usize,
}

/// The most times the active contacts may grow within one step (see the module doc); a vertex that
/// enters a collider after that is caught at the next step, and `max_penetration_m` shows it.
pub const MAX_CONTACT_CHANGES: usize = 8;

/// The volumetric knit in time (see the module doc).
#[derive(Debug)]
pub struct ProjectiveDynamics {
    material: KnitMaterial,
    global: GlobalStep,
    jacobi: Option<JacobiGlobalStep>,
    params: ProjectiveDynamicsParams,
    mass: Vec<f64>,
    forces: Vec<[f64; 3]>,
    force_scale: f64,
    targets: Vec<Matrix3<f64>>,
    collision: BodyCollision,
    /// The yarn vertices' embedding (empty without colliders).
    embedding: Vec<Embedded>,
    tets: Vec<[usize; 4]>,
    /// The collision targets `p_j` (`#Y × 3`, m; empty without colliders).
    point_targets: Vec<[f64; 3]>,
    /// Positions (`#V × 3`, m).
    x: Vec<[f64; 3]>,
    /// Velocities (`#V × 3`, m/s).
    v: Vec<[f64; 3]>,
    time: f64,
}

impl ProjectiveDynamics {
    /// The mesh at rest and still, with material `gamma` (`#T × 2`, Pa) and the nodes `clamped` held
    /// (at rest until [`Self::step`] is given other positions).
    pub fn new(
        mesh: &VolumetricMesh,
        gamma: Vec<[f64; 2]>,
        clamped: &[usize],
        params: ProjectiveDynamicsParams,
    ) -> Result<Self, ProjectiveDynamicsError> {
        Self::with_collision(mesh, gamma, clamped, params, BodyCollision::default())
    }

    /// As [`Self::new`], with the embedded yarns kept out of `collision`'s colliders (see the module
    /// doc); the yarns must start outside every collider's clearance.
    pub fn with_collision(
        mesh: &VolumetricMesh,
        gamma: Vec<[f64; 2]>,
        clamped: &[usize],
        params: ProjectiveDynamicsParams,
        collision: BodyCollision,
    ) -> Result<Self, ProjectiveDynamicsError> {
        let bad = |field, value, expected| {
            Err(ProjectiveDynamicsError::Params {
                field,
                value,
                expected,
            })
        };
        if !(params.dt.is_finite() && params.dt > 0.0) {
            return bad("dt", params.dt, "finite and > 0 (s)");
        }
        if let Some(&g) = params.gravity.iter().find(|g| !g.is_finite()) {
            return bad("gravity", g, "finite (m/s²)");
        }
        if !(params.mass_damping.is_finite() && params.mass_damping >= 0.0) {
            return bad("mass_damping", params.mass_damping, "finite and ≥ 0 (1/s)");
        }
        if !(params.tolerance.is_finite() && params.tolerance > 0.0) {
            return bad("tolerance", params.tolerance, "finite and > 0");
        }
        if params.max_iterations == 0 {
            return bad("max_iterations", 0.0, "at least 1");
        }
        if params.threads == 0 {
            return bad("threads", 0.0, "at least 1");
        }
        let material = KnitMaterial::new(mesh, gamma, params.projection)?;
        let weights = element_weights(&material);
        let a = 1.0 + params.mass_damping * params.dt;
        let scaled = VolumetricMesh {
            rest: mesh.rest.clone(),
            tets: mesh.tets.clone(),
            node_mass: mesh.node_mass.iter().map(|m| a * m).collect(),
            embedding: Vec::new(),
        };
        collision.validate()?;
        let (embedding, point_weight) = if collision.colliders.is_empty() {
            (Vec::new(), 0.0)
        } else {
            if mesh.embedding.is_empty() {
                return Err(ProjectiveDynamicsError::NoYarns);
            }
            let yarns = mesh
                .v2y(&mesh.rest)
                .map_err(|_| ProjectiveDynamicsError::NoYarns)?;
            collision.check_start(&yarns)?;
            // The default weight: a multiple of the mean diagonal of the elastic part of K (N/m).
            let mut diagonal = vec![0.0; mesh.rest.len()];
            for ((tet, rest), w) in mesh.tets.iter().zip(material.rest_tets()).zip(&weights) {
                for (a, g) in rest.corner_gradients().iter().enumerate() {
                    diagonal[tet[a]] += w * g.norm_squared();
                }
            }
            let mean = diagonal.iter().sum::<f64>() / diagonal.len().max(1) as f64;
            let w = collision
                .stiffness
                .unwrap_or(super::body_collision::DEFAULT_STIFFNESS_RATIO * mean);
            if !(w.is_finite() && w > 0.0) {
                return bad(
                    "collision stiffness",
                    w,
                    "finite and > 0 (N/m): give `stiffness`, the material has none",
                );
            }
            (mesh.embedding.clone(), w)
        };
        if !collision.colliders.is_empty() && params.solver != GlobalSolver::Cholesky {
            return bad(
                "solver",
                0.0,
                "the Cholesky global step with colliders (Jacobi's matrix is not refreshed when \
                 the contacts change)",
            );
        }
        let global = GlobalStep::with_points(
            &scaled,
            &weights,
            clamped,
            params.dt,
            &embedding,
            point_weight,
        )?;
        let jacobi = match params.solver {
            GlobalSolver::Cholesky => None,
            GlobalSolver::Jacobi(j) => Some(JacobiGlobalStep::new(&global, j)?),
        };
        let forces: Vec<[f64; 3]> = mesh
            .node_mass
            .iter()
            .map(|m| params.gravity.map(|g| m * g))
            .collect();
        let g = params.gravity.iter().map(|v| v * v).sum::<f64>().sqrt();
        let elastic = material
            .rest_tets()
            .iter()
            .zip(material.gamma())
            .map(|(r, g)| (g[0] + g[1]) * r.volume.powf(2.0 / 3.0))
            .fold(0.0, f64::max);
        let weight = mesh.node_mass.iter().fold(0.0f64, |m, v| m.max(v * g));
        let force_scale = elastic + weight;
        if !(force_scale > 0.0 && force_scale.is_finite()) {
            return bad(
                "gamma and gravity",
                force_scale,
                "some stiffness or some weight, so that forces have a scale",
            );
        }
        Ok(Self {
            targets: vec![Matrix3::identity(); mesh.tets.len()],
            point_targets: vec![[0.0; 3]; embedding.len()],
            embedding,
            collision,
            tets: mesh.tets.clone(),
            material,
            global,
            jacobi,
            params,
            mass: mesh.node_mass.clone(),
            forces,
            force_scale,
            x: mesh.rest.clone(),
            v: vec![[0.0; 3]; mesh.rest.len()],
            time: 0.0,
        })
    }

    /// Positions (`#V × 3`, m).
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.x
    }

    /// Velocities (`#V × 3`, m/s).
    pub fn velocities(&self) -> &[[f64; 3]] {
        &self.v
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// The clamped nodes, sorted (the order of the prescribed positions).
    pub fn clamped(&self) -> &[usize] {
        self.global.clamped()
    }

    /// The material.
    pub fn material(&self) -> &KnitMaterial {
        &self.material
    }

    /// The force scale `F` of the residual (N).
    pub fn force_scale(&self) -> f64 {
        self.force_scale
    }

    /// The Jacobi solver's estimated spectral radius, when Jacobi is the global solver.
    pub fn jacobi_spectral_radius(&self) -> Option<f64> {
        self.jacobi.as_ref().map(|j| j.spectral_radius())
    }

    /// Sets the state (`#V × 3` each; m, m/s), e.g. a stretched pose to release.
    pub fn set_state(
        &mut self,
        x: Vec<[f64; 3]>,
        v: Vec<[f64; 3]>,
    ) -> Result<(), ProjectiveDynamicsError> {
        let nodes = self.x.len();
        for (what, a) in [("positions", &x), ("velocities", &v)] {
            if a.len() != nodes {
                return Err(ProjectiveDynamicsError::Global(GlobalStepError::Length {
                    what,
                    given: a.len(),
                    expected: nodes,
                }));
            }
            if let Some(index) = a.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
                return Err(ProjectiveDynamicsError::Global(
                    GlobalStepError::NotFinite { what, index },
                ));
            }
        }
        self.x = x;
        self.v = v;
        Ok(())
    }

    /// The kinetic energy `½ vᵀ M v` (J).
    pub fn kinetic_energy(&self) -> f64 {
        self.v
            .iter()
            .zip(&self.mass)
            .map(|(v, m)| 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
            .sum()
    }

    /// The elastic energy `E(x)` of Eq. 7 at the current positions (J).
    pub fn elastic_energy(&self) -> Result<f64, ProjectiveDynamicsError> {
        let mut targets = vec![Matrix3::identity(); self.targets.len()];
        Ok(local_step(
            &self.material,
            &self.x,
            &self.params.projection,
            self.params.threads,
            &mut targets,
        )?)
    }

    /// The yarn vertex `j` at positions `x` (m).
    fn yarn(&self, x: &[[f64; 3]], j: usize) -> [f64; 3] {
        let e = &self.embedding[j];
        let tet = &self.tets[e.tet];
        [0, 1, 2].map(|i| (0..4).map(|a| e.weights[a] * x[tet[a]][i]).sum())
    }

    /// The collision targets `p_j = Π(N_j x)` into `point_targets`; returns the collision energy
    /// `Σ ½ w ‖N_j x − p_j‖²` over the candidates (J), and over every yarn vertex the number inside a
    /// clearance and the deepest (m).
    fn project_yarns(&mut self, x: &[[f64; 3]]) -> (f64, usize, f64) {
        let (mut energy, mut contacts, mut deepest) = (0.0, 0, 0.0f64);
        let w = self.global.point_weight();
        for j in 0..self.embedding.len() {
            let y = self.yarn(x, j);
            let p = self.collision.project(y);
            let d2 = (0..3).map(|i| (y[i] - p[i]).powi(2)).sum::<f64>();
            if d2 > 0.0 {
                contacts += 1;
                deepest = deepest.max(d2.sqrt());
            }
            if self.global.active_points()[j] {
                energy += 0.5 * w * d2;
            }
            self.point_targets[j] = p;
        }
        (energy, contacts, deepest)
    }

    /// Makes the yarn vertices inside a collider's clearance at `x` active constraints of `K`: only
    /// those (`reset`, at a step's start) or those added to the active ones. Returns whether the set
    /// changed.
    fn activate_contacts(
        &mut self,
        x: &[[f64; 3]],
        reset: bool,
    ) -> Result<bool, ProjectiveDynamicsError> {
        if self.embedding.is_empty() {
            return Ok(false);
        }
        let c = self.collision.clearance_m;
        let previous = self.global.active_points();
        let active: Vec<bool> = (0..self.embedding.len())
            .map(|j| {
                let y = self.yarn(x, j);
                let inside = self
                    .collision
                    .colliders
                    .iter()
                    .any(|k| k.signed_distance(y) < c);
                inside || (!reset && previous[j])
            })
            .collect();
        Ok(self.global.set_active_points(&active)?)
    }

    /// `Ψ(x)` (J) for the step with target `y`, given `E(x)` (with the collision energy in it).
    fn objective(&self, x: &[[f64; 3]], y: &[[f64; 3]], elastic: f64) -> f64 {
        let a = 1.0 + self.params.mass_damping * self.params.dt;
        let c = a / (2.0 * self.params.dt * self.params.dt);
        let mut value = elastic;
        for v in 0..x.len() {
            for i in 0..3 {
                let d = x[v][i] - y[v][i];
                value += c * self.mass[v] * d * d - self.forces[v][i] * x[v][i];
            }
        }
        value
    }

    /// One time step of `Δt`; `prescribed` gives the clamped nodes' positions at the step's end (m, in
    /// the order of [`Self::clamped`]), `None` keeps them where they are.
    pub fn step(
        &mut self,
        prescribed: Option<&[[f64; 3]]>,
    ) -> Result<PdStepReport, ProjectiveDynamicsError> {
        let start = Instant::now();
        let clamped = self.global.clamped().to_vec();
        if let Some(p) = prescribed {
            if p.len() != clamped.len() {
                return Err(ProjectiveDynamicsError::Prescribed {
                    given: p.len(),
                    expected: clamped.len(),
                });
            }
            if let Some(i) = p.iter().position(|q| !q.iter().all(|c| c.is_finite())) {
                return Err(ProjectiveDynamicsError::Prescribed {
                    given: i,
                    expected: clamped.len(),
                });
            }
        }
        let dt = self.params.dt;
        let a = 1.0 + self.params.mass_damping * dt;
        let y: Vec<[f64; 3]> = self
            .x
            .iter()
            .zip(&self.v)
            .map(|(x, v)| [0, 1, 2].map(|i| x[i] + dt * v[i] / a))
            .collect();
        let mut x = y.clone();
        for (k, &c) in clamped.iter().enumerate() {
            x[c] = prescribed.map_or(self.x[c], |p| p[k]);
        }
        self.activate_contacts(&x, true)?;
        let mut contact_changes = 0;
        let mut objective = Vec::new();
        let mut iterations = 0;
        let (mut local_seconds, mut global_seconds) = (0.0, 0.0);
        let (residual, elastic, contacts, max_penetration_m) = loop {
            let clock = Instant::now();
            let elastic = local_step(
                &self.material,
                &x,
                &self.params.projection,
                self.params.threads,
                &mut self.targets,
            )?;
            if contact_changes < MAX_CONTACT_CHANGES && self.activate_contacts(&x, false)? {
                contact_changes += 1;
            }
            let (collision, contacts, deepest) = self.project_yarns(&x);
            local_seconds += clock.elapsed().as_secs_f64();
            objective.push(self.objective(&x, &y, elastic + collision));
            let (_, gradient) =
                self.global
                    .objective(&y, &self.forces, &self.targets, &self.point_targets, &x);
            let residual = gradient
                .iter()
                .flatten()
                .fold(0.0f64, |m, g| m.max(g.abs()))
                / self.force_scale;
            if residual <= self.params.tolerance || iterations == self.params.max_iterations {
                break (residual, elastic, contacts, deepest);
            }
            let clock = Instant::now();
            let (f, t, p) = (&self.forces, &self.targets, &self.point_targets);
            match &self.jacobi {
                None => self.global.solve(&y, f, t, p, &mut x)?,
                Some(j) => j.solve(&self.global, &y, f, t, p, &mut x)?,
            }
            global_seconds += clock.elapsed().as_secs_f64();
            iterations += 1;
        };
        for (v, (xn, xo)) in self.v.iter_mut().zip(x.iter().zip(&self.x)) {
            *v = [0, 1, 2].map(|i| (xn[i] - xo[i]) / dt);
        }
        self.x = x;
        self.time += dt;
        Ok(PdStepReport {
            iterations,
            residual,
            converged: residual <= self.params.tolerance,
            objective,
            elastic_energy: elastic,
            seconds: start.elapsed().as_secs_f64(),
            local_seconds,
            global_seconds,
            contacts,
            max_penetration_m,
            contact_changes,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::knit_material::test_states::{block_mesh, rng};
    use crate::knit_material::{MaterialHessian, QuasiStaticParams, QuasiStaticProblem};
    use crate::projective_dynamics::body_collision::BodyCollider;
    use rand::Rng;
    use skintight_physics::newton::{NewtonParams, minimize};

    /// A block of `n` cubes of 1 cm with 1 g a node.
    fn block(n: [usize; 3]) -> VolumetricMesh {
        let mut mesh = block_mesh(n[0], n[1], n[2], 0.01);
        mesh.node_mass = vec![1e-3; mesh.rest.len()];
        mesh
    }

    fn top(mesh: &VolumetricMesh) -> Vec<usize> {
        let ymax = mesh.rest.iter().fold(f64::MIN, |m, p| m.max(p[1]));
        (0..mesh.rest.len())
            .filter(|&v| mesh.rest[v][1] == ymax)
            .collect()
    }

    #[test]
    fn the_objective_never_increases_and_the_converged_step_is_backward_euler() {
        let mesh = block([3, 2, 2]);
        let mut rng = rng(17);
        let gamma: Vec<[f64; 2]> = (0..mesh.tets.len())
            .map(|_| {
                [
                    rng.random_range(200.0..800.0),
                    rng.random_range(500.0..3000.0),
                ]
            })
            .collect();
        let clamped = top(&mesh);
        for damping in [0.0, 5.0] {
            let params = ProjectiveDynamicsParams {
                mass_damping: damping,
                tolerance: 1e-9,
                max_iterations: 2000,
                ..Default::default()
            };
            let mut pd = ProjectiveDynamics::new(&mesh, gamma.clone(), &clamped, params).unwrap();
            // A sheared, stretched start with random velocities; the clamped nodes move this step.
            let x0: Vec<[f64; 3]> = mesh
                .rest
                .iter()
                .map(|p| {
                    [
                        1.2 * p[0] + 0.3 * p[1] + rng.random_range(-5e-4..5e-4),
                        0.9 * p[1] + rng.random_range(-5e-4..5e-4),
                        p[2] + 0.1 * p[0],
                    ]
                })
                .collect();
            let v0: Vec<[f64; 3]> = (0..x0.len())
                .map(|_| [0, 1, 2].map(|_| rng.random_range(-0.2..0.2)))
                .collect();
            pd.set_state(x0.clone(), v0.clone()).unwrap();
            let prescribed: Vec<[f64; 3]> = clamped
                .iter()
                .map(|&c| [x0[c][0] + 1e-3, x0[c][1], x0[c][2]])
                .collect();
            let report = pd.step(Some(&prescribed)).unwrap();
            assert!(report.converged, "{report:?}");
            assert!(report.iterations > 3, "{report:?}");
            for w in report.objective.windows(2) {
                assert!(
                    w[1] <= w[0] + 1e-12 * w[0].abs(),
                    "Ψ rose from {} to {}",
                    w[0],
                    w[1]
                );
            }
            // Backward Euler's optimality through the knit material's own gradient.
            let dt = params.dt;
            let a = 1.0 + damping * dt;
            let x = pd.positions().to_vec();
            let flat: Vec<f64> = x.iter().flatten().copied().collect();
            let grad = pd
                .material()
                .evaluate(&flat, MaterialHessian::Skip)
                .unwrap()
                .gradient;
            let mut worst = 0.0f64;
            for v in 0..x.len() {
                if clamped.contains(&v) {
                    continue;
                }
                for i in 0..3 {
                    let y = x0[v][i] + dt * v0[v][i] / a;
                    let g = a * 1e-3 * (x[v][i] - y) / (dt * dt) + grad[3 * v + i]
                        - 1e-3 * params.gravity[i];
                    worst = worst.max(g.abs());
                }
            }
            assert!(
                worst <= 1e-8 * pd.force_scale(),
                "∇Ψ = {worst} N (scale {} N)",
                pd.force_scale()
            );
            for (k, &c) in clamped.iter().enumerate() {
                assert_eq!(x[c], prescribed[k]);
            }
            for v in 0..x.len() {
                for i in 0..3 {
                    let want = (x[v][i] - x0[v][i]) / dt;
                    assert!((pd.velocities()[v][i] - want).abs() <= 1e-9 * want.abs().max(1.0));
                }
            }
        }
    }

    #[test]
    fn a_released_stretch_neither_gains_energy_nor_explodes_over_1000_steps() {
        let mesh = block([2, 2, 2]);
        let params = ProjectiveDynamicsParams {
            gravity: [0.0; 3],
            tolerance: 1e-7,
            max_iterations: 500,
            ..Default::default()
        };
        let mut pd =
            ProjectiveDynamics::new(&mesh, vec![[500.0, 2000.0]; mesh.tets.len()], &[], params)
                .unwrap();
        let stretched: Vec<[f64; 3]> = mesh
            .rest
            .iter()
            .map(|p| [1.3 * p[0], 0.95 * p[1] + 0.1 * p[0], p[2]])
            .collect();
        pd.set_state(stretched, vec![[0.0; 3]; mesh.rest.len()])
            .unwrap();
        let initial = pd.elastic_energy().unwrap();
        assert!(initial > 0.0);
        let mut most_kinetic = 0.0f64;
        let mut unconverged = 0;
        for step in 0..1000 {
            let report = pd.step(None).unwrap();
            unconverged += usize::from(!report.converged);
            let total = report.elastic_energy + pd.kinetic_energy();
            assert!(total.is_finite(), "step {step}: not finite");
            assert!(
                total <= initial * (1.0 + 1e-6),
                "step {step}: total energy {total} J above the initial {initial} J"
            );
            most_kinetic = most_kinetic.max(pd.kinetic_energy());
            assert!(pd.positions().iter().flatten().all(|c| c.abs() < 1.0));
        }
        assert_eq!(unconverged, 0);
        // It moved: the stretch turned into motion (not frozen by over-damping or a no-op step).
        assert!(most_kinetic > 0.1 * initial, "{most_kinetic} vs {initial}");
    }

    #[test]
    fn a_hanging_block_settles_to_the_quasi_static_solution() {
        let mesh = block([1, 4, 1]);
        let gamma = vec![[300.0, 1500.0]; mesh.tets.len()];
        let clamped = top(&mesh);
        let params = ProjectiveDynamicsParams {
            dt: 0.02,
            mass_damping: 10.0,
            tolerance: 1e-10,
            max_iterations: 5000,
            ..Default::default()
        };
        let mut pd = ProjectiveDynamics::new(&mesh, gamma.clone(), &clamped, params).unwrap();
        let mut steps = 0;
        while steps < 2000 {
            let report = pd.step(None).unwrap();
            assert!(report.converged, "{report:?}");
            steps += 1;
            let speed = pd
                .velocities()
                .iter()
                .flatten()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            if speed < 1e-9 {
                break;
            }
        }
        assert!(steps < 2000, "did not settle");

        let material = KnitMaterial::new(&mesh, gamma, VolumePreservingParams::default()).unwrap();
        let force: Vec<f64> = mesh
            .node_mass
            .iter()
            .flat_map(|m| params.gravity.map(|g| m * g))
            .collect();
        let mut fixed = vec![false; 3 * mesh.rest.len()];
        for &c in &clamped {
            fixed[3 * c..3 * c + 3].fill(true);
        }
        let mut problem =
            QuasiStaticProblem::new(&material, force, fixed, &QuasiStaticParams::default())
                .unwrap();
        let mut x: Vec<f64> = mesh.rest.iter().flatten().copied().collect();
        minimize(&mut problem, &mut x, &NewtonParams::default()).unwrap();
        let sag = mesh
            .rest
            .iter()
            .flatten()
            .zip(&x)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let mut worst = 0.0f64;
        for (p, q) in pd.positions().iter().flatten().zip(&x) {
            worst = worst.max((p - q).abs());
        }
        assert!(sag > 1e-4, "no visible sag: {sag} m");
        assert!(
            worst <= 1e-6 * sag.max(1e-3),
            "PD settled {worst} m from Newton's equilibrium (sag {sag} m, {steps} steps)"
        );
    }

    #[test]
    fn jacobi_global_steps_reach_the_same_step() {
        let mesh = block([3, 2, 2]);
        let gamma = vec![[400.0, 1600.0]; mesh.tets.len()];
        let clamped = top(&mesh);
        let run = |solver| {
            let params = ProjectiveDynamicsParams {
                solver,
                tolerance: 1e-8,
                max_iterations: 5000,
                ..Default::default()
            };
            let mut pd = ProjectiveDynamics::new(&mesh, gamma.clone(), &clamped, params).unwrap();
            let mut iterations = 0;
            for _ in 0..5 {
                let r = pd.step(None).unwrap();
                assert!(r.converged, "{solver:?}: {r:?}");
                iterations += r.iterations;
            }
            (pd.positions().to_vec(), iterations)
        };
        let (direct, _) = run(GlobalSolver::Cholesky);
        for chebyshev in [false, true] {
            let (x, _) = run(GlobalSolver::Jacobi(JacobiParams {
                sweeps: 10,
                chebyshev,
                ..Default::default()
            }));
            let worst = x
                .iter()
                .flatten()
                .zip(direct.iter().flatten())
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                worst < 1e-7,
                "chebyshev {chebyshev}: {worst} m from Cholesky's"
            );
        }
    }

    /// The radius of the sphere the tests drop a block on (m): wide enough that the frictionless block
    /// rests on it rather than sliding off.
    const SPHERE_R: f64 = 0.5;

    /// A block of 4 × 1 × 4 cubes of 1 cm (1 g a node) with 200 "yarn" points embedded at random
    /// barycentric coordinates, its lowest point 1 mm above the top of a sphere of radius `SPHERE_R`.
    fn block_over(rng: &mut rand_chacha::ChaCha8Rng) -> (VolumetricMesh, [f64; 3]) {
        let mut mesh = block([4, 1, 4]);
        mesh.embedding = (0..200)
            .map(|_| {
                let b: [f64; 4] = [0, 1, 2, 3].map(|_| rng.random_range(0.01..1.0));
                let sum: f64 = b.iter().sum();
                Embedded {
                    tet: rng.random_range(0..mesh.tets.len()),
                    weights: b.map(|v| v / sum),
                }
            })
            .collect();
        let low = mesh
            .v2y(&mesh.rest)
            .unwrap()
            .iter()
            .fold(f64::MAX, |m, p| m.min(p[1]));
        // The sphere under the block's centre (x = z = 2 cm).
        (mesh, [0.02, low - 0.001 - SPHERE_R - 0.0005, 0.02])
    }

    #[test]
    fn a_block_dropped_on_a_sphere_rests_on_it_and_falls_through_without_it() {
        let mut rng = rng(23);
        let (mesh, center) = block_over(&mut rng);
        let gamma = vec![[3000.0, 3000.0]; mesh.tets.len()];
        let params = ProjectiveDynamicsParams {
            max_iterations: 1000,
            ..Default::default()
        };
        let clearance = 0.0005;
        let collision = BodyCollision {
            colliders: vec![BodyCollider::sphere(0, center, SPHERE_R).unwrap()],
            clearance_m: clearance,
            stiffness: None,
        };
        let mut with = ProjectiveDynamics::with_collision(
            &mesh,
            gamma.clone(),
            &[],
            params,
            collision.clone(),
        )
        .unwrap();
        let mut without = ProjectiveDynamics::new(&mesh, gamma, &[], params).unwrap();
        let steps = 40; // 0.27 s: a fall of 1 mm takes 14 ms, then it settles on the sphere.
        let mut touched = 0;
        for _ in 0..steps {
            let r = with.step(None).unwrap();
            assert!(
                r.converged,
                "{} iterations, residual {}",
                r.iterations, r.residual
            );
            if r.contact_changes == 0 {
                for w in r.objective.windows(2) {
                    assert!(w[1] <= w[0] + 1e-12 * w[0].abs(), "Ψ rose: {w:?}");
                }
            }
            // A penalty: the load (and at impact the momentum) over w, within half the clearance
            // (the yarn's surface reaches at most a quarter of its diameter into the sphere).
            assert!(
                r.max_penetration_m < 0.5 * clearance,
                "{} m deep",
                r.max_penetration_m
            );
            touched = touched.max(r.contacts);
            without.step(None).unwrap();
        }
        assert!(touched > 0, "the block never reached the sphere");
        let yarns = |pd: &ProjectiveDynamics| mesh.v2y(pd.positions()).unwrap();
        let collider = collision.colliders[0];
        let closest = yarns(&with)
            .iter()
            .map(|p| collider.signed_distance(*p))
            .fold(f64::MAX, f64::min);
        let lowest = |y: Vec<[f64; 3]>| y.iter().fold(f64::MAX, |m, p| m.min(p[1]));
        let top = center[1] + SPHERE_R;
        // On the sphere: no yarn point deeper than half the clearance, the block not below its top;
        // without it the block fell through the sphere's place.
        assert!(
            closest > 0.5 * clearance,
            "closest yarn point {closest} m from the sphere"
        );
        assert!(
            lowest(yarns(&with)) > top - 0.005,
            "the block slid off the sphere"
        );
        assert!(
            lowest(yarns(&without)) < top - 0.05,
            "without the sphere the block did not fall"
        );
    }

    #[test]
    fn an_untouched_collider_changes_the_iterations_but_not_the_step() {
        let mut rng = rng(29);
        let (mesh, _) = block_over(&mut rng);
        let gamma = vec![[3000.0, 3000.0]; mesh.tets.len()];
        let params = ProjectiveDynamicsParams {
            tolerance: 1e-8,
            max_iterations: 2000,
            ..Default::default()
        };
        let far = BodyCollision {
            colliders: vec![
                BodyCollider::cylinder(0, [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], 0.05).unwrap(),
            ],
            clearance_m: 0.0005,
            stiffness: None,
        };
        let top = top(&mesh);
        let mut a = ProjectiveDynamics::new(&mesh, gamma.clone(), &top, params).unwrap();
        let mut b = ProjectiveDynamics::with_collision(&mesh, gamma, &top, params, far).unwrap();
        let (mut ia, mut ib) = (0, 0);
        for _ in 0..5 {
            let (ra, rb) = (a.step(None).unwrap(), b.step(None).unwrap());
            assert!(ra.converged && rb.converged);
            assert_eq!(rb.contacts, 0);
            ia += ra.iterations;
            ib += rb.iterations;
        }
        let worst = a
            .positions()
            .iter()
            .zip(b.positions())
            .flat_map(|(p, q)| (0..3).map(move |i| (p[i] - q[i]).abs()))
            .fold(0.0f64, f64::max);
        assert!(worst < 1e-6, "positions differ by {worst} m");
        // What the constant-weight constraints cost in iterations (docs/BENCHMARKS.md, issue 44).
        eprintln!("PD iterations over 5 steps: {ia} without colliders, {ib} with an untouched one");
        assert!(ib >= ia && ib <= 4 * ia, "{ia} → {ib}");
    }

    #[test]
    fn bad_colliders_are_refused_by_name() {
        let mut rng = rng(31);
        let (mesh, center) = block_over(&mut rng);
        let gamma = vec![[3000.0, 3000.0]; mesh.tets.len()];
        let params = ProjectiveDynamicsParams::default();
        // A sphere that holds the patch at the start.
        let inside = BodyCollision {
            colliders: vec![BodyCollider::sphere(0, [0.02, 0.005, 0.02], 0.01).unwrap()],
            clearance_m: 0.0005,
            stiffness: None,
        };
        let err = ProjectiveDynamics::with_collision(&mesh, gamma.clone(), &[], params, inside)
            .unwrap_err();
        assert!(
            err.to_string().contains("collider 0 holds yarn vertex"),
            "{err}"
        );
        // Colliders on a mesh without yarns.
        let mut bare = mesh.clone();
        bare.embedding.clear();
        let ok = BodyCollision {
            colliders: vec![BodyCollider::sphere(0, center, SPHERE_R).unwrap()],
            clearance_m: 0.0005,
            stiffness: None,
        };
        let err = ProjectiveDynamics::with_collision(&bare, gamma.clone(), &[], params, ok.clone())
            .unwrap_err();
        assert!(err.to_string().contains("no"), "{err}");
        let err = ProjectiveDynamics::with_collision(
            &mesh,
            gamma,
            &[],
            params,
            BodyCollision {
                stiffness: Some(-1.0),
                ..ok
            },
        )
        .unwrap_err();
        assert!(err.to_string().contains("stiffness"), "{err}");
    }

    #[test]
    fn bad_settings_and_inputs_are_refused_by_name() {
        let mesh = block([1, 1, 1]);
        let gamma = vec![[1.0, 1.0]; 6];
        let new =
            |p: ProjectiveDynamicsParams| ProjectiveDynamics::new(&mesh, gamma.clone(), &[0], p);
        let d = ProjectiveDynamicsParams::default();
        for (p, field) in [
            (ProjectiveDynamicsParams { dt: 0.0, ..d }, "dt"),
            (ProjectiveDynamicsParams { dt: f64::NAN, ..d }, "dt"),
            (
                ProjectiveDynamicsParams {
                    gravity: [0.0, f64::INFINITY, 0.0],
                    ..d
                },
                "gravity",
            ),
            (
                ProjectiveDynamicsParams {
                    mass_damping: -1.0,
                    ..d
                },
                "mass_damping",
            ),
            (
                ProjectiveDynamicsParams {
                    tolerance: 0.0,
                    ..d
                },
                "tolerance",
            ),
            (
                ProjectiveDynamicsParams {
                    max_iterations: 0,
                    ..d
                },
                "max_iterations",
            ),
            (ProjectiveDynamicsParams { threads: 0, ..d }, "threads"),
        ] {
            match new(p) {
                Err(ProjectiveDynamicsError::Params { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
        assert!(matches!(
            ProjectiveDynamics::new(&mesh, vec![[1.0, -1.0]; 6], &[], d),
            Err(ProjectiveDynamicsError::Material(_))
        ));
        assert!(matches!(
            ProjectiveDynamics::new(&mesh, gamma.clone(), &[42], d),
            Err(ProjectiveDynamicsError::Global(GlobalStepError::Clamped {
                node: 42,
                ..
            }))
        ));
        let mut pd = new(d).unwrap();
        assert!(matches!(
            pd.step(Some(&[[0.0; 3], [0.0; 3]])),
            Err(ProjectiveDynamicsError::Prescribed {
                given: 2,
                expected: 1
            })
        ));
        assert!(matches!(
            pd.step(Some(&[[0.0, f64::NAN, 0.0]])),
            Err(ProjectiveDynamicsError::Prescribed { .. })
        ));
        let mut nan = mesh.rest.clone();
        nan[1][0] = f64::NAN;
        assert!(pd.set_state(nan, vec![[0.0; 3]; 8]).is_err());
        assert!(pd.set_state(mesh.rest.clone(), vec![[0.0; 3]; 7]).is_err());
        // A sane state still steps after the refusals.
        assert!(pd.step(None).unwrap().converged);
    }
}
