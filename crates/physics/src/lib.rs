//! Physics for skintight: the body and cloth energies, their coupling through the body surface, and the
//! equilibrium solver.
//!
//! Units: SI throughout — positions in m, stiffnesses in Pa, energies in J, forces in N.

pub use skintight_geometry::math;

pub mod cloth_on_body;
pub mod equilibrium;
pub mod form;
pub mod membrane_element;
pub mod neo_hookean;
pub mod node_block_assembly;
pub mod sparse_assembly;
pub mod sparse_cholesky;
pub mod tension_field_density;

pub use cloth_on_body::{
    BodySpec, ClothOnBody, ClothOnBodyError, ClothOnBodyState, ClothSpec, SharedSurface,
};
pub use equilibrium::{
    EquilibriumError, EquilibriumParams, EquilibriumReport, EquilibriumTimings,
    EquilibriumWorkspace, IterationInfo, StopReason, equilibrium, equilibrium_in,
};
pub use form::{Form, FormError, HessianSink, HessianTriplets};
pub use membrane_element::{MembraneDerivatives, MembraneElement, MembraneError, MembraneState};
pub use neo_hookean::{NeoHookeanBody, NeoHookeanError, NeoHookeanMaterial, NeoHookeanParams};
pub use node_block_assembly::{
    AssemblyPart, AssemblyShare, Node, NodeBlockAssembler, NodeBlockRecorder, NodeHessianSink,
};
pub use sparse_assembly::FixedPatternAssembler;
pub use sparse_cholesky::{
    CholeskyError, FillFigures, Ordering, SparseCholesky, SparseCholeskyParams,
};
pub use tension_field_density::{
    DensityDerivatives, MaterialError, Regime, TensionFieldDensity, TensionFieldParams,
};
