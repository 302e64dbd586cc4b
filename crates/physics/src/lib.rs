//! Physics for skintight: the body and cloth energies, their coupling through the body surface, and the
//! equilibrium solver.
//!
//! Units: SI throughout — positions in m, stiffnesses in Pa, energies in J, forces in N.

pub use skintight_geometry::math;

pub mod form;
pub mod sparse_assembly;

pub use form::{Form, FormError, HessianSink, HessianTriplets};
pub use sparse_assembly::FixedPatternAssembler;
pub mod neo_hookean;

pub use neo_hookean::{NeoHookeanBody, NeoHookeanError, NeoHookeanMaterial, NeoHookeanParams};
pub mod tension_field_density;
pub mod membrane_element;

pub use membrane_element::{MembraneDerivatives, MembraneElement, MembraneError, MembraneState};
pub use tension_field_density::{
    DensityDerivatives, MaterialError, Regime, TensionFieldDensity, TensionFieldParams,
};
