//! The volumetric knit of skintight (the knitwear paper, `../shared/seeds/001_4106da78f66b8d80.txt`,
//! Sec. 4–7): yarn-level knits homogenized into a tetrahedral mesh with two material parameters per
//! element, fitted to yarn-level frame sequences, and simulated at run time.
//!
//! Units: SI throughout — positions and lengths in m, masses in kg, energies in J, the material
//! parameters `γˢ`, `γᵛ` in Pa (energy per volume per unit squared strain).
//!
//! Layout (one equation a file; docs/ARCHITECTURE.md, "Where the knitwear parts go"):
//! - [`volumetric_mesh`]: the mesh around the rest-pose yarns (Sec. 4), its shared types in `mod.rs` and
//!   one step a file: `voxelize` (the exact grid walk along the centrelines, 6-connected, optional
//!   dilation), `tet_split` (six Kuhn tetrahedra a voxel, shared nodes), `mass_lumping` (Eq. 2–3,
//!   integrated exactly), `embedding` (the located yarn vertices and V2Y, Eq. 4, with its transpose and
//!   sparse matrix), `build` (the validating constructor `VolumetricMesh::build`, the admission
//!   `estimate` and the `report`), `mesh_vtu` (the `.vtu` file) and `error`;
//! - [`polar_decomposition`]: `F = R S` with `R` a proper rotation, through the rotation-variant SVD.
//! - [`harmonic_basis`]: the smoothest per-element fields of the mesh (Sec. 6.5, Eq. 23–24), the
//!   low-rank material spaces the elasticity fit starts in.
//! - [`projective_dynamics`]: the mesh in time (Sec. 7.1, Eq. 25–28), one step a file: `local_step`
//!   (per element `R(F)`, `V(F)`, the target `P_e` and `E(x)`, threaded), `global_step` (`K x = b`, one
//!   Cholesky factorization), `jacobi_global_step` (the same system by plain or Chebyshev Jacobi sweeps)
//!   and `backward_euler` (`ProjectiveDynamics`: the time step with gravity, clamped and moving nodes,
//!   mass-proportional damping and a residual on the true step objective's gradient).
//! - [`closest_volume_preserving`]: `V(F)`, the closest matrix with `det V = 1` (Eq. 8, the KKT problem of Eq. 26).
//! - [`knit_material`]: the material `γˢ V ‖F − R‖² + γᵛ V ‖F − V‖²` (Eq. 7): density, element, assembly,
//!   `∂g/∂γ`, and the quasi-static equilibrium as a Newton toolkit problem (Eq. 14).
//! - [`material_frame`]: the rods' material normals of a frame sequence, directors carried by parallel
//!   transport from frame to frame;
//! - [`segment_deformation`]: the deformation gradient of one yarn segment from its edge and normals (Sec. 5);
//! - [`rotation_average`]: rotations averaged through the matrix logarithm (Eq. 5), refined to the Karcher mean;
//! - [`segment_clipping`]: the length of each rest yarn segment inside each tetrahedron (the weights of Eq. 5);
//! - [`element_deformation`]: each element's target deformation gradient (Eq. 5), empty elements filled;
//! - [`shape_fit`]: Y2V, the mesh shape of a yarn pose (Eq. 6), factored once per mesh, and its error;
//! - [`shape_fit_error`]: the errors of the shape-fitting modules;
//! - [`inertia_force`]: the inertia forces of a sequence from the fitted shapes (Eq. 12–14).
//! - [`elasticity_fit`]: the fit of `γ` to the poses (Sec. 6): `adjoint_loss` (the loss of Eq. 9–10 over the
//!   poses' quasi-static equilibria, its adjoint gradient of Eq. 15–17 and the linearization of Eq. 18–21
//!   as an `AdjointProblem` of the shared Gauss-Newton).
//! - [`homogenization`]: the pipeline end to end — poses from sequences (targets, gravity and inertia
//!   loads, held nodes), the sample-by-sample fit through the harmonic schedule (Eq. 22–24) and the
//!   error on training and held-out frames.
//! - [`straight_yarn_block`]: a voxel block threaded by straight yarns, the hand-computable shape-fit case.

// Index loops over small fixed-size arrays (3-vectors, tetrahedron corners) read like the equations.
#![allow(clippy::needless_range_loop)]

pub mod closest_volume_preserving;
pub mod elasticity_fit;
pub mod element_deformation;
pub mod harmonic_basis;
pub mod homogenization;
pub mod inertia_force;
pub mod knit_material;
pub mod material_frame;
pub mod polar_decomposition;
pub mod projective_dynamics;
pub mod rotation_average;
pub mod segment_clipping;
pub mod segment_deformation;
pub mod shape_fit;
pub mod shape_fit_error;
pub mod straight_yarn_block;
pub mod volumetric_mesh;
