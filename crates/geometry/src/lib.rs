//! Geometry for skintight: triangle meshes and their connectivity, mesh formats and checks, the Loop limit
//! surface the garment slides on, and tetrahedral bodies.
//!
//! Units: positions in metres (m), areas in m², volumes in m³.

pub mod closest_point;
pub mod ease;
pub mod finite_difference;
pub mod garment;
pub mod garment_remesh;
pub mod io;
pub mod leg_pose;
pub mod linear_surface;
pub mod loop_irregular_patch;
pub mod loop_regular_patch;
pub mod loop_subdivision;
pub mod loop_surface;
pub mod math;
pub mod mesh;
pub mod mesh_check;
pub mod pattern_remesh;
pub mod pattern_svg;
pub mod plane_cut;
pub mod procedural_body;
pub mod self_intersection;
pub mod shell_tetrahedralization;
pub mod surface;
pub mod surface_walk;
pub mod tet_boundary;
pub mod tet_io;
pub mod tet_mesh;
pub mod topology;
pub mod triangle_grid;
pub mod triangle_intersection;

pub use linear_surface::LinearSurface;
pub use loop_surface::LoopSurface;
pub mod lscm;
#[cfg(test)]
pub(crate) mod test_meshes;
pub use math::*;
pub use mesh::TriMesh;
pub use mesh_check::{
    BodySurface, MeshCheckParams, MeshIssue, MeshReport, body_surface, mesh_report,
};
pub use shell_tetrahedralization::{
    ShellBody, ShellError, ShellParams, ShellReport, shell_tetrahedralization,
};
pub use surface::{LimitSurface, Stencil, StencilEntry, SurfaceCoord, SurfaceError, SurfacePoint};
pub use tet_boundary::{BoundaryError, BoundarySurface, boundary_surface, outer_boundary_surface};
pub use tet_mesh::{TetMesh, TetMeshError};
pub use topology::{Corner, HalfEdgeTwin, Topology, TopologyError};
