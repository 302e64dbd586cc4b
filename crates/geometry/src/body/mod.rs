//! Tetrahedral bodies: the tet mesh ([`tet_mesh`]) and its file formats ([`tet_io`]: VTU, MEDIT, Gmsh,
//! TetGen), its boundary surface ([`tet_boundary`]), the soft-tissue shell filled under a body surface
//! ([`shell_tetrahedralization`]), procedural test bodies and fixed regions ([`procedural_body`]), and leg
//! poses of a body surface ([`leg_pose`]).
//!
//! Units: positions in metres (m), volumes in m³.

pub mod leg_pose;
pub mod procedural_body;
pub mod shell_tetrahedralization;
pub mod tet_boundary;
pub mod tet_io;
pub mod tet_mesh;
