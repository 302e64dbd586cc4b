//! Geometry for skintight: triangle meshes and their connectivity, mesh formats and checks, the Loop limit
//! surface the garment slides on, and tetrahedral bodies.
//!
//! Units: positions in metres (m), areas in m², volumes in m³.

pub mod finite_difference;
pub mod io;
pub mod math;
pub mod mesh;
pub mod mesh_check;
pub mod topology;

pub use math::*;
pub use mesh::TriMesh;
pub use mesh_check::{
    BodySurface, MeshCheckParams, MeshIssue, MeshReport, body_surface, mesh_report,
};
pub use topology::{Corner, HalfEdgeTwin, Topology, TopologyError};
