//! Writes a tetrahedral mesh as a VTK XML unstructured grid (`.vtu`, ASCII), readable by ParaView.
//!
//! Cells are VTK type 10 (tetrahedron) with the mesh's vertex order (VTK uses the same positive-orientation
//! convention). Point data arrays have one value (scalars) or three (vectors) per vertex; cell data arrays one
//! value per tetrahedron.

use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

use crate::body::tet_mesh::TetMesh;
use crate::math::{Real, Vec3};

/// A named data array attached to points or cells.
#[derive(Clone, Debug, PartialEq)]
pub enum VtuArray {
    /// One number per entry (e.g. the fixed flag as 0/1, the quality).
    Scalars(String, Vec<Real>),
    /// One 3-vector per entry (e.g. a displacement in m).
    Vectors(String, Vec<Vec3>),
}

impl VtuArray {
    fn len(&self) -> usize {
        match self {
            VtuArray::Scalars(_, v) => v.len(),
            VtuArray::Vectors(_, v) => v.len(),
        }
    }
    fn name(&self) -> &str {
        match self {
            VtuArray::Scalars(n, _) | VtuArray::Vectors(n, _) => n,
        }
    }
}

/// Why a `.vtu` file could not be written.
#[derive(Debug, thiserror::Error)]
pub enum VtuError {
    /// A data array has the wrong length.
    #[error("{kind} data array `{name}` has {len} entries, expected {expected}")]
    Length {
        kind: &'static str,
        name: String,
        len: usize,
        expected: usize,
    },
    /// The file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
}

/// The `.vtu` document as a string.
pub fn vtu_string(
    mesh: &TetMesh,
    point_data: &[VtuArray],
    cell_data: &[VtuArray],
) -> Result<String, VtuError> {
    for (kind, arrays, expected) in [
        ("point", point_data, mesh.num_vertices()),
        ("cell", cell_data, mesh.num_tets()),
    ] {
        for a in arrays {
            if a.len() != expected {
                return Err(VtuError::Length {
                    kind,
                    name: a.name().to_string(),
                    len: a.len(),
                    expected,
                });
            }
        }
    }
    let mut s = String::with_capacity(64 * (mesh.num_vertices() + mesh.num_tets()) + 1024);
    let _ = writeln!(s, "<?xml version=\"1.0\"?>");
    let _ = writeln!(
        s,
        "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">"
    );
    let _ = writeln!(s, "  <UnstructuredGrid>");
    let _ = writeln!(
        s,
        "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
        mesh.num_vertices(),
        mesh.num_tets()
    );
    let _ = writeln!(s, "      <Points>");
    let _ = writeln!(
        s,
        "        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">"
    );
    for p in &mesh.positions {
        let _ = writeln!(s, "          {:e} {:e} {:e}", p.x, p.y, p.z);
    }
    let _ = writeln!(s, "        </DataArray>");
    let _ = writeln!(s, "      </Points>");
    let _ = writeln!(s, "      <Cells>");
    let _ = writeln!(
        s,
        "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">"
    );
    for t in &mesh.tets {
        let _ = writeln!(s, "          {} {} {} {}", t[0], t[1], t[2], t[3]);
    }
    let _ = writeln!(s, "        </DataArray>");
    let _ = writeln!(
        s,
        "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">"
    );
    for i in 0..mesh.num_tets() {
        let _ = writeln!(s, "          {}", 4 * (i + 1));
    }
    let _ = writeln!(s, "        </DataArray>");
    let _ = writeln!(
        s,
        "        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">"
    );
    for _ in 0..mesh.num_tets() {
        let _ = writeln!(s, "          10");
    }
    let _ = writeln!(s, "        </DataArray>");
    let _ = writeln!(s, "      </Cells>");
    for (tag, arrays) in [("PointData", point_data), ("CellData", cell_data)] {
        if arrays.is_empty() {
            continue;
        }
        let _ = writeln!(s, "      <{tag}>");
        for a in arrays {
            match a {
                VtuArray::Scalars(name, v) => {
                    let _ = writeln!(
                        s,
                        "        <DataArray type=\"Float64\" Name=\"{}\" format=\"ascii\">",
                        xml_escape(name)
                    );
                    for x in v {
                        let _ = writeln!(s, "          {x:e}");
                    }
                }
                VtuArray::Vectors(name, v) => {
                    let _ = writeln!(
                        s,
                        "        <DataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"3\" format=\"ascii\">",
                        xml_escape(name)
                    );
                    for x in v {
                        let _ = writeln!(s, "          {:e} {:e} {:e}", x.x, x.y, x.z);
                    }
                }
            }
            let _ = writeln!(s, "        </DataArray>");
        }
        let _ = writeln!(s, "      </{tag}>");
    }
    let _ = writeln!(s, "    </Piece>");
    let _ = writeln!(s, "  </UnstructuredGrid>");
    let _ = writeln!(s, "</VTKFile>");
    Ok(s)
}

/// Writes the mesh with the given data arrays to `path`.
pub fn write_vtu(
    path: &Path,
    mesh: &TetMesh,
    point_data: &[VtuArray],
    cell_data: &[VtuArray],
) -> Result<(), VtuError> {
    let text = vtu_string(mesh, point_data, cell_data)?;
    let io = |source| VtuError::Io {
        path: path.display().to_string(),
        source,
    };
    let mut file = std::fs::File::create(path).map_err(io)?;
    file.write_all(text.as_bytes()).map_err(io)?;
    Ok(())
}

/// The usual arrays of a body: point data `fixed` (0/1), cell data `quality` (signed mean ratio).
pub fn body_arrays(mesh: &TetMesh) -> (Vec<VtuArray>, Vec<VtuArray>) {
    (
        vec![VtuArray::Scalars(
            "fixed".into(),
            mesh.fixed
                .iter()
                .map(|&f| if f { 1.0 } else { 0.0 })
                .collect(),
        )],
        vec![VtuArray::Scalars("quality".into(), mesh.qualities())],
    )
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reads back the numbers of one `<DataArray … Name="name">` block (a rough parser for the round trip).
    fn numbers_after(text: &str, marker: &str) -> Vec<f64> {
        let start = text.find(marker).expect(marker);
        let body = &text[start..];
        let open = body.find('>').unwrap() + 1;
        let close = body.find("</DataArray>").unwrap();
        body[open..close]
            .split_whitespace()
            .map(|t| t.parse().unwrap())
            .collect()
    }

    #[test]
    fn round_trip_counts_positions_and_arrays() {
        let mut m = TetMesh::new(
            vec![
                Vec3::zeros(),
                Vec3::x(),
                Vec3::y(),
                Vec3::z(),
                Vec3::new(1.0, 1.0, 1.0),
            ],
            vec![[0, 1, 2, 3], [1, 3, 2, 4]],
        );
        m.fixed[4] = true;
        let (mut pd, cd) = body_arrays(&m);
        pd.push(VtuArray::Vectors(
            "displacement".into(),
            vec![Vec3::new(0.5, -0.25, 1e-3); 5],
        ));
        let text = vtu_string(&m, &pd, &cd).unwrap();
        assert!(text.contains("NumberOfPoints=\"5\" NumberOfCells=\"2\""));
        let pts = numbers_after(
            &text,
            "<DataArray type=\"Float64\" NumberOfComponents=\"3\"",
        );
        assert_eq!(pts.len(), 15);
        assert_eq!(pts[12..15], [1.0, 1.0, 1.0]);
        let conn = numbers_after(&text, "Name=\"connectivity\"");
        assert_eq!(conn, vec![0.0, 1.0, 2.0, 3.0, 1.0, 3.0, 2.0, 4.0]);
        assert_eq!(numbers_after(&text, "Name=\"offsets\""), vec![4.0, 8.0]);
        assert_eq!(numbers_after(&text, "Name=\"types\""), vec![10.0, 10.0]);
        assert_eq!(
            numbers_after(&text, "Name=\"fixed\""),
            vec![0.0, 0.0, 0.0, 0.0, 1.0]
        );
        let q = numbers_after(&text, "Name=\"quality\"");
        assert_eq!(q.len(), 2);
        assert!((q[0] - m.quality(0)).abs() < 1e-12);
        let d = numbers_after(&text, "Name=\"displacement\"");
        assert_eq!(d.len(), 15);
        assert_eq!(d[0..3], [0.5, -0.25, 1e-3]);
    }

    #[test]
    fn wrong_array_length_names_the_array() {
        let m = TetMesh::new(vec![Vec3::zeros(); 4], vec![[0, 1, 2, 3]]);
        let err =
            vtu_string(&m, &[VtuArray::Scalars("fixed".into(), vec![0.0; 3])], &[]).unwrap_err();
        assert!(
            err.to_string()
                .contains("`fixed` has 3 entries, expected 4")
        );
    }

    #[test]
    fn unwritable_path_names_the_path() {
        let m = TetMesh::new(vec![Vec3::zeros(); 4], vec![[0, 1, 2, 3]]);
        let err = write_vtu(Path::new("/nonexistent-dir/x.vtu"), &m, &[], &[]).unwrap_err();
        assert!(err.to_string().contains("/nonexistent-dir/x.vtu"));
    }
}
