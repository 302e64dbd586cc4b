//! Geometry for skintight: the math types, triangle meshes ([`mesh`]), the smooth limit surface the
//! garment slides on ([`surface`]), tetrahedral bodies ([`body`]), regions bounded by planes
//! ([`region`]) and the preparation of raw body scans ([`scan`]). Turning a body region into sewn 2D patterns is the `skintight-garment` crate's.
//!
//! Units: positions in metres (m), areas in m², volumes in m³.

pub mod anthropometry;
pub mod body;
pub mod finite_difference;
pub mod math;
pub mod mesh;
pub mod polygon_area;
pub mod region;
pub mod scan;
pub mod surface;
/// Meshes for tests (icosphere, open cylinder, planar grid, the sample bodies), shared by the workspace's
/// tests through the `test-support` feature.
#[cfg(any(test, feature = "test-support"))]
pub mod test_meshes;

pub use body::shell_tetrahedralization::{
    ShellBody, ShellError, ShellParams, ShellReport, shell_tetrahedralization,
};
pub use body::tet_boundary::{
    BoundaryError, BoundarySurface, boundary_surface, outer_boundary_surface,
};
pub use body::tet_mesh::{TetMesh, TetMeshError};
pub use math::*;
pub use mesh::TriMesh;
pub use mesh::check::{
    BodySurface, MeshCheckParams, MeshIssue, MeshReport, body_surface, mesh_report,
};
pub use mesh::topology::{Corner, HalfEdgeTwin, Topology, TopologyError};
pub use surface::{
    LimitSurface, LinearSurface, LoopSurface, Stencil, StencilEntry, SurfaceCoord, SurfaceError,
    SurfacePoint,
};
