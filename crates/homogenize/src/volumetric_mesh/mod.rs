//! The volumetric mesh around the rest-pose yarns (the knitwear paper, Sec. 4): the yarn centrelines are
//! voxelized, each voxel is split into six tetrahedra, the yarn mass is lumped onto the nodes (Eq. 2–3) and
//! every yarn vertex is embedded in one tetrahedron with barycentric weights, so the mesh-to-yarn map
//! V2Y (Eq. 4) is one sparse `3n^Y × 3n^V` matrix `N`.
//!
//! Shapes: `#V` mesh nodes, `#T` tetrahedra, `#Y` yarn vertices. Units: m, kg.
//!
//! One step a file: [`voxelize`] (the grid walk along the centrelines), [`tet_split`] (six tetrahedra a
//! voxel, shared nodes), [`mass_lumping`] (Eq. 2–3), [`embedding`] (the located yarn vertices and V2Y,
//! Eq. 4), [`build`] (the validating constructor [`VolumetricMesh::build`], its admission
//! [`VolumetricMesh::estimate`] and [`VolumetricMesh::report`]), [`mesh_vtu`] (the `.vtu` output) and
//! [`error`].

pub mod build;
pub mod embedding;
pub mod error;
pub mod mass_lumping;
pub mod mesh_vtu;
pub mod tet_split;
pub mod voxelize;

pub use build::{RestYarns, VolumetricMeshEstimate, VolumetricMeshParams, VolumetricMeshReport};
pub use error::VolumetricMeshError;

use serde::{Deserialize, Serialize};

/// Where one yarn vertex lies in the mesh: its tetrahedron and the barycentric weights of that
/// tetrahedron's four nodes (non-negative up to round-off, summing to 1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Embedded {
    /// Index of the tetrahedron, `< #T`.
    pub tet: usize,
    /// Barycentric weights of `tets[tet]`'s nodes, in their order.
    pub weights: [f64; 4],
}

/// A tetrahedral mesh around a knit's yarns, with nodal masses and the yarn vertices embedded in it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VolumetricMesh {
    /// Rest positions of the nodes, `#V × 3` (m).
    pub rest: Vec<[f64; 3]>,
    /// Tetrahedra as node indices, `#T × 4`, positively oriented at rest (signed volume > 0).
    pub tets: Vec<[usize; 4]>,
    /// Lumped nodal masses `M^V` (Eq. 2), `#V` (kg).
    pub node_mass: Vec<f64>,
    /// The embedding of each yarn vertex (V2Y, Eq. 4), `#Y`.
    pub embedding: Vec<Embedded>,
}
