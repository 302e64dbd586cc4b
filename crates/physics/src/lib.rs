//! Physics for skintight: the body and cloth energies, their coupling through the body surface, and the
//! equilibrium solver.
//!
//! Units: SI throughout — positions in m, stiffnesses in Pa, energies in J, forces in N.
//!
//! Layout, from the element up to the solve:
//! - [`neo_hookean`]: the compressible Neo-Hookean body (thesis Eq. 134–136), per tetrahedron and over a
//!   whole tetrahedral mesh;
//! - [`tension_field_density`] and [`membrane_element`]: the C²-smoothed tension-field cloth membrane
//!   (Eq. 122–129, Sec. 6.1) and its triangle element;
//! - [`cloth_on_body`]: the cloth on the body's smooth surface over the unknowns `q = {s, y}` (Eq. 139–140,
//!   155–157) — its numbering of the unknowns, energy, Hessian structure and assembly, the sensitivities the
//!   design uses, and the figures of a state, one file each;
//! - [`node_block_assembly`]: sparse assembly of the Hessian by node blocks on a pattern that survives
//!   sliding, sequential or on several threads;
//! - [`sparse_cholesky`]: the sparse Cholesky factorization with AMD / METIS ordering;
//! - [`newton`]: the Newton toolkit both equilibrium solvers share — the pattern cache and its assembly
//!   from triplets, the shifted factorization, the damping policies, the stop reasons, and the
//!   Levenberg–Marquardt/Armijo minimizer the yarn solves of `skintight-knit` use;
//! - [`mod@equilibrium`]: the garment's damped Newton solve (Eq. 144–154, Sec. 2.1.2) and the workspace the
//!   design's adjoint solves reuse.

pub use skintight_geometry::math;

/// Pascals per millimetre of mercury (the unit fitters read pressures in: 1 mmHg = 133.322 Pa).
pub const PA_PER_MMHG: f64 = 133.322;

pub mod cloth_on_body;
pub mod equilibrium;
pub mod membrane_element;
pub mod membrane_law;
pub mod neo_hookean;
pub mod newton;
pub mod node_block_assembly;
pub mod orthotropic_density;
pub mod sparse_cholesky;
mod symmetric_permutation;
pub mod tension_curve;
pub mod tension_field_density;

pub use cloth_on_body::{
    BodySpec, ChartChange, ClothOnBody, ClothOnBodyError, ClothOnBodyState, ClothSpec,
    CoordinateCharts, HessianForm, SharedSurface,
};
pub use equilibrium::{
    EquilibriumError, EquilibriumFigures, EquilibriumParams, EquilibriumReport, EquilibriumTimings,
    EquilibriumWorkspace, IterationInfo, SolveProgress, StopReason, equilibrium, equilibrium_in,
    equilibrium_resumable,
};
pub use membrane_element::{MembraneDerivatives, MembraneElement, MembraneError, MembraneState};
pub use neo_hookean::{
    BodyStateError, NeoHookeanBody, NeoHookeanError, NeoHookeanMaterial, NeoHookeanParams,
};
pub use node_block_assembly::{
    AssemblyPart, AssemblyShare, Node, NodeBlockAssembler, NodeBlockRecorder, NodeHessianSink,
};
pub use sparse_cholesky::{
    CholeskyError, FillFigures, Ordering, SparseCholesky, SparseCholeskyParams,
};
pub use tension_field_density::{
    DensityDerivatives, MaterialError, Regime, TensionFieldDensity, TensionFieldParams,
};
