//! The volumetric mesh as a ParaView-readable `.vtu` file, through the workspace's one VTU writer
//! (`skintight_geometry::body::tet_io::vtu`): the rest nodes (m), the tetrahedra (VTK type 10, the mesh's
//! positive orientation), the lumped nodal mass `node_mass_kg` (kg) as point data, and whatever per-element
//! arrays the caller adds as cell data (e.g. the fitted `gamma_s`, `gamma_v` in Pa).

use std::path::Path;

use skintight_geometry::Vec3;
use skintight_geometry::body::tet_io::{VtuArray, VtuError, vtu_string, write_vtu};
use skintight_geometry::body::tet_mesh::TetMesh;

use super::VolumetricMesh;

impl VolumetricMesh {
    /// The mesh's rest shape as the geometry crate's tetrahedral mesh (no fixed nodes).
    pub fn tet_mesh(&self) -> TetMesh {
        TetMesh::new(
            self.rest
                .iter()
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect(),
            self.tets.clone(),
        )
    }

    /// The point data every file of the mesh carries: `node_mass_kg`.
    fn point_data(&self) -> Vec<VtuArray> {
        vec![VtuArray::Scalars(
            "node_mass_kg".into(),
            self.node_mass.clone(),
        )]
    }

    /// The `.vtu` document, with `cell_data` (one value or 3-vector per tetrahedron each).
    pub fn vtu(&self, cell_data: &[VtuArray]) -> Result<String, VtuError> {
        vtu_string(&self.tet_mesh(), &self.point_data(), cell_data)
    }

    /// Writes the `.vtu` file to `path`, with `cell_data` (one value or 3-vector per tetrahedron each).
    pub fn write_vtu(&self, path: &Path, cell_data: &[VtuArray]) -> Result<(), VtuError> {
        write_vtu(path, &self.tet_mesh(), &self.point_data(), cell_data)
    }
}

#[cfg(test)]
mod tests {
    use super::super::Embedded;
    use super::*;

    fn one_tet() -> VolumetricMesh {
        VolumetricMesh {
            rest: vec![
                [0.0; 3],
                [1e-3, 0.0, 0.0],
                [0.0, 1e-3, 0.0],
                [0.0, 0.0, 1e-3],
            ],
            tets: vec![[0, 1, 2, 3]],
            node_mass: vec![1e-6, 2e-6, 3e-6, 4e-6],
            embedding: vec![Embedded {
                tet: 0,
                weights: [0.25; 4],
            }],
        }
    }

    #[test]
    fn vtu_has_the_mesh_its_masses_and_the_cell_data() {
        let m = one_tet();
        let text = m
            .vtu(&[
                VtuArray::Scalars("gamma_s".into(), vec![12.5]),
                VtuArray::Scalars("gamma_v".into(), vec![7.0]),
            ])
            .unwrap();
        assert!(text.contains("NumberOfPoints=\"4\" NumberOfCells=\"1\""));
        assert!(text.contains("Name=\"node_mass_kg\""));
        assert!(text.contains("<CellData>"));
        assert!(text.contains("Name=\"gamma_s\""));
        assert!(text.contains("1.25e1"));
        assert!(text.contains("Name=\"gamma_v\""));
        // A cell array of the wrong length is named in the error.
        let err = m
            .vtu(&[VtuArray::Scalars("gamma_s".into(), vec![1.0, 2.0])])
            .unwrap_err();
        assert!(err.to_string().contains("gamma_s"));
        let dir = std::env::temp_dir().join(format!("homogenize-vtu-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("mesh.vtu");
        m.write_vtu(&path, &[]).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), m.vtu(&[]).unwrap());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
