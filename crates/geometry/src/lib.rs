//! Geometry for skintight: triangle meshes and their connectivity, mesh formats and checks, the Loop limit
//! surface the garment slides on, and tetrahedral bodies.
//!
//! Units: positions in metres (m), areas in m², volumes in m³.

pub mod ease;
pub mod finite_difference;
pub mod lscm;
pub mod math;
pub mod mesh;
pub mod pattern_remesh;
pub mod plane_cut;
pub mod topology;

#[cfg(test)]
pub(crate) mod test_meshes;

pub use math::*;
pub use mesh::TriMesh;
pub use topology::{Corner, HalfEdgeTwin, Topology, TopologyError};
