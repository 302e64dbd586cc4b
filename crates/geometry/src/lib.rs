//! Geometry for skintight: triangle meshes and their connectivity, mesh formats and checks, the Loop limit
//! surface the garment slides on, and tetrahedral bodies.
//!
//! Units: positions in metres (m), areas in m², volumes in m³.

pub mod finite_difference;
pub mod math;
pub mod mesh;
pub mod self_intersection;
pub mod shell_tetrahedralization;
pub mod tet_boundary;
pub mod tet_io;
pub mod tet_mesh;
pub mod topology;
pub mod triangle_grid;
pub mod triangle_intersection;

pub use math::*;
pub use mesh::TriMesh;
pub use shell_tetrahedralization::{
    ShellBody, ShellError, ShellParams, ShellReport, shell_tetrahedralization,
};
pub use tet_boundary::{BoundaryError, BoundarySurface, boundary_surface, outer_boundary_surface};
pub use tet_mesh::{TetMesh, TetMeshError};
pub use topology::{Corner, HalfEdgeTwin, Topology, TopologyError};
