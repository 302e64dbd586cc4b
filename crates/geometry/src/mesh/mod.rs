//! Triangle surface meshes: the mesh itself ([`TriMesh`]), its connectivity ([`topology`]), the checks a
//! body surface must pass ([`check`]), file formats ([`io`]: OBJ, PLY, STL, glTF binary), and the
//! triangle–triangle intersection tests behind the self-intersection check ([`triangle_grid`],
//! [`triangle_intersection`], [`self_intersection`]).
//!
//! Units: positions in metres (m), areas in m², volumes in m³.

pub mod check;
pub mod io;
pub mod self_intersection;
pub mod topology;
mod tri_mesh;
pub mod triangle_grid;
pub mod triangle_intersection;

pub use tri_mesh::TriMesh;
