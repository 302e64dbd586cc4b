//! Physics for skintight: the body and cloth energies, their coupling through the body surface, and the
//! equilibrium solver.
//!
//! Units: SI throughout — positions in m, stiffnesses in Pa, energies in J, forces in N.

pub use skintight_geometry::math;

pub mod membrane_element;
pub mod tension_field_density;

pub use membrane_element::{MembraneDerivatives, MembraneElement, MembraneError, MembraneState};
pub use tension_field_density::{
    DensityDerivatives, MaterialError, Regime, TensionFieldDensity, TensionFieldParams,
};
