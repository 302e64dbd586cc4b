//! Reading and writing triangle meshes: Wavefront OBJ, PLY, STL and glTF 2.0 binary (`.glb`).
//!
//! Readers take the whole file as bytes (the HTTP service receives uploads that way; [`read_mesh`] reads a
//! file first) and return a [`TriMesh`] in the file's units, which skintight takes to be metres. Polygons
//! are fan-triangulated: polygon `(v0, v1, …, vk)` becomes `(v0, v1, v2), (v0, v2, v3), …`. Vertex order is
//! kept exactly as in the file for OBJ, PLY and glTF (body files of one resolution share connectivity); STL
//! has no shared vertices, so its corners are welded by identical coordinates in order of first appearance.
//!
//! Readers check syntax and index ranges but not geometry: a NaN coordinate or a non-manifold edge is read
//! as is, and [`crate::mesh::check`] reports it.

mod glb;
mod obj;
mod ply;
mod stl;

use std::fmt;
use std::path::Path;

pub use glb::{read_glb, write_glb};
pub use obj::{read_obj, write_obj};
pub use ply::{read_ply, write_ply};
pub use stl::{read_stl, write_stl};

use crate::math::Vec3;
use crate::mesh::TriMesh;

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MeshFormat {
    /// Wavefront OBJ (text).
    Obj,
    /// Stanford PLY (ASCII or binary).
    Ply,
    /// STL (ASCII or binary).
    Stl,
    /// glTF 2.0 binary container.
    Glb,
}

impl MeshFormat {
    /// Every format, in a fixed order.
    pub const ALL: [MeshFormat; 4] = [
        MeshFormat::Obj,
        MeshFormat::Ply,
        MeshFormat::Stl,
        MeshFormat::Glb,
    ];

    /// The format of a file extension (`"obj"`, `".PLY"`, …), case-insensitive.
    pub fn from_extension(ext: &str) -> Option<Self> {
        let ext = ext.trim().trim_start_matches('.').to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(Self::Obj),
            "ply" => Some(Self::Ply),
            "stl" => Some(Self::Stl),
            "glb" => Some(Self::Glb),
            _ => None,
        }
    }

    /// The format of a file path, by its extension.
    pub fn from_path(path: &Path) -> Option<Self> {
        path.extension()
            .and_then(|e| e.to_str())
            .and_then(Self::from_extension)
    }

    /// The format of an HTTP content type such as `model/obj` or `model/gltf-binary; charset=binary`.
    /// `application/octet-stream` and other generic types give `None` (use the file name then).
    pub fn from_content_type(content_type: &str) -> Option<Self> {
        let essence = content_type
            .split(';')
            .next()
            .unwrap_or("")
            .trim()
            .to_ascii_lowercase();
        match essence.as_str() {
            "model/obj" | "text/x-obj" | "application/x-tgif" | "model/x-obj" => Some(Self::Obj),
            "model/ply" | "application/ply" | "model/x-ply" | "application/x-ply" => {
                Some(Self::Ply)
            }
            "model/stl"
            | "model/x.stl-binary"
            | "model/x.stl-ascii"
            | "application/sla"
            | "application/vnd.ms-pki.stl"
            | "model/x-stl"
            | "application/x-stl" => Some(Self::Stl),
            "model/gltf-binary" => Some(Self::Glb),
            _ => None,
        }
    }

    /// The usual file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Self::Obj => "obj",
            Self::Ply => "ply",
            Self::Stl => "stl",
            Self::Glb => "glb",
        }
    }

    /// The registered (or customary) content type.
    pub fn content_type(self) -> &'static str {
        match self {
            Self::Obj => "model/obj",
            Self::Ply => "model/ply",
            Self::Stl => "model/stl",
            Self::Glb => "model/gltf-binary",
        }
    }
}

impl fmt::Display for MeshFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Obj => "OBJ",
            Self::Ply => "PLY",
            Self::Stl => "STL",
            Self::Glb => "glTF binary",
        })
    }
}

/// Why a mesh could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum MeshIoError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Read {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// The file could not be written.
    #[error("cannot write {path}: {source}")]
    Write {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// The format could not be told from the name or content type.
    #[error("cannot tell the mesh format of {name:?}: expected a .obj, .ply, .stl or .glb file")]
    UnknownFormat { name: String },
    /// A text file has a bad line.
    #[error("{format} line {line}: {message}")]
    Syntax {
        format: MeshFormat,
        line: usize,
        message: String,
    },
    /// The content is malformed (the message names the format and where).
    #[error("{message}")]
    Invalid { format: MeshFormat, message: String },
    /// The mesh (or its attributes) cannot be written as asked.
    #[error("cannot write {format}: {message}")]
    Unwritable { format: MeshFormat, message: String },
}

impl MeshIoError {
    pub(crate) fn invalid(format: MeshFormat, message: impl Into<String>) -> Self {
        Self::Invalid {
            format,
            message: message.into(),
        }
    }

    pub(crate) fn syntax(format: MeshFormat, line: usize, message: impl Into<String>) -> Self {
        Self::Syntax {
            format,
            line,
            message: message.into(),
        }
    }
}

/// Reads a mesh file, choosing the format by the file extension.
pub fn read_mesh(path: &Path) -> Result<TriMesh, MeshIoError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| MeshIoError::UnknownFormat {
        name: path.display().to_string(),
    })?;
    let bytes = std::fs::read(path).map_err(|source| MeshIoError::Read {
        path: path.display().to_string(),
        source,
    })?;
    read_mesh_bytes(&bytes, format)
}

/// Reads a mesh from the bytes of a file of the given format.
pub fn read_mesh_bytes(bytes: &[u8], format: MeshFormat) -> Result<TriMesh, MeshIoError> {
    match format {
        MeshFormat::Obj => read_obj(bytes),
        MeshFormat::Ply => read_ply(bytes),
        MeshFormat::Stl => read_stl(bytes),
        MeshFormat::Glb => read_glb(bytes),
    }
}

/// Encoding of a PLY file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PlyEncoding {
    /// Binary, little-endian (compact, exact).
    #[default]
    BinaryLittleEndian,
    /// Text.
    Ascii,
}

/// What to write besides positions and faces.
#[derive(Clone, Copy, Debug, Default)]
pub struct WriteParams<'a> {
    /// `#V` unit vertex normals (OBJ `vn`, PLY `nx ny nz`, glTF `NORMAL`; STL stores face normals only).
    pub normals: Option<&'a [Vec3]>,
    /// `#V` linear RGB colours in `[0, 1]` (OBJ `v x y z r g b`, PLY `red green blue` bytes, glTF `COLOR_0`;
    /// not stored in STL).
    pub colors: Option<&'a [[f32; 3]]>,
    /// PLY encoding.
    pub ply_encoding: PlyEncoding,
    /// glTF: the name of the node and the mesh (what a viewer lists).
    pub name: Option<&'a str>,
    /// glTF: application data on the mesh (`extras`), e.g. a colour legend with its units.
    pub extras: Option<&'a serde_json::Value>,
    /// glTF: draw both sides of each triangle (an open membrane such as a garment seen from inside).
    pub double_sided: bool,
}

/// Encodes a mesh in the given format.
pub fn write_mesh_bytes(
    mesh: &TriMesh,
    format: MeshFormat,
    params: &WriteParams<'_>,
) -> Result<Vec<u8>, MeshIoError> {
    validate_for_writing(mesh, format, params)?;
    Ok(match format {
        MeshFormat::Obj => write_obj(mesh, params),
        MeshFormat::Ply => write_ply(mesh, params),
        MeshFormat::Stl => write_stl(mesh),
        MeshFormat::Glb => write_glb(mesh, params)?,
    })
}

/// Writes a mesh file, choosing the format by the file extension.
pub fn write_mesh(
    path: &Path,
    mesh: &TriMesh,
    params: &WriteParams<'_>,
) -> Result<(), MeshIoError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| MeshIoError::UnknownFormat {
        name: path.display().to_string(),
    })?;
    let bytes = write_mesh_bytes(mesh, format, params)?;
    std::fs::write(path, bytes).map_err(|source| MeshIoError::Write {
        path: path.display().to_string(),
        source,
    })
}

/// Checks what every writer needs: indices in range, attribute lengths `#V`, finite numbers.
fn validate_for_writing(
    mesh: &TriMesh,
    format: MeshFormat,
    params: &WriteParams<'_>,
) -> Result<(), MeshIoError> {
    let nv = mesh.num_vertices();
    let fail = |message: String| MeshIoError::Unwritable { format, message };
    if let Some((f, v)) = mesh
        .faces
        .iter()
        .enumerate()
        .find_map(|(f, face)| face.iter().find(|&&v| v >= nv).map(|&v| (f, v)))
    {
        return Err(fail(format!(
            "face {f} names vertex {v}, but the mesh has {nv} vertices"
        )));
    }
    if let Some(v) = mesh
        .positions
        .iter()
        .position(|p| !p.iter().all(|x| x.is_finite()))
    {
        return Err(fail(format!("vertex {v} has a non-finite coordinate")));
    }
    if !mesh.face_groups.is_empty() {
        if mesh.face_groups.len() != mesh.num_faces() {
            return Err(fail(format!(
                "{} face group labels for {} faces",
                mesh.face_groups.len(),
                mesh.num_faces()
            )));
        }
        if let Some(f) = mesh
            .face_groups
            .iter()
            .position(|&g| g as usize >= mesh.group_names.len())
        {
            return Err(fail(format!(
                "face {f} has group {} but there are {} group names",
                mesh.face_groups[f],
                mesh.group_names.len()
            )));
        }
    }
    if let Some(n) = params.normals {
        if n.len() != nv {
            return Err(fail(format!("{} normals for {nv} vertices", n.len())));
        }
        if let Some(v) = n.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
            return Err(fail(format!("the normal of vertex {v} is not finite")));
        }
    }
    if let Some(c) = params.colors {
        if c.len() != nv {
            return Err(fail(format!("{} colours for {nv} vertices", c.len())));
        }
        if let Some(v) = c
            .iter()
            .position(|c| !c.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)))
        {
            return Err(fail(format!(
                "the colour of vertex {v} is outside [0, 1]: {:?}",
                c[v]
            )));
        }
    }
    Ok(())
}

/// Appends the fan triangulation of a polygon (`poly.len() ≥ 3`) to `faces`.
pub(crate) fn fan_triangulate(poly: &[usize], faces: &mut Vec<[usize; 3]>) {
    for k in 1..poly.len() - 1 {
        faces.push([poly[0], poly[k], poly[k + 1]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes;

    #[test]
    fn formats_from_extension_and_content_type() {
        assert_eq!(MeshFormat::from_extension(".OBJ"), Some(MeshFormat::Obj));
        assert_eq!(MeshFormat::from_extension("glb"), Some(MeshFormat::Glb));
        assert_eq!(MeshFormat::from_extension("gltf"), None);
        assert_eq!(
            MeshFormat::from_content_type("model/gltf-binary; charset=binary"),
            Some(MeshFormat::Glb)
        );
        assert_eq!(
            MeshFormat::from_content_type("Model/STL"),
            Some(MeshFormat::Stl)
        );
        assert_eq!(
            MeshFormat::from_content_type("application/octet-stream"),
            None
        );
        for f in MeshFormat::ALL {
            assert_eq!(MeshFormat::from_extension(f.extension()), Some(f));
            assert_eq!(MeshFormat::from_content_type(f.content_type()), Some(f));
        }
        assert_eq!(
            MeshFormat::from_path(Path::new("/a/b/body.Ply")),
            Some(MeshFormat::Ply)
        );
    }

    #[test]
    fn unknown_extension_is_named() {
        let e = read_mesh(Path::new("body.xyz")).unwrap_err();
        assert!(e.to_string().contains("body.xyz"), "{e}");
    }

    #[test]
    fn writers_reject_bad_meshes() {
        let mut m = test_meshes::octahedron();
        m.positions[3].y = Real::NAN;
        for f in MeshFormat::ALL {
            let e = write_mesh_bytes(&m, f, &WriteParams::default()).unwrap_err();
            assert!(e.to_string().contains("vertex 3"), "{e}");
        }
        let mut m = test_meshes::octahedron();
        m.faces[7][2] = 6;
        let e = write_mesh_bytes(&m, MeshFormat::Obj, &WriteParams::default()).unwrap_err();
        assert!(e.to_string().contains("face 7"), "{e}");
        let m = test_meshes::octahedron();
        let normals = vec![Vec3::x(); 5];
        let params = WriteParams {
            normals: Some(&normals),
            ..Default::default()
        };
        let e = write_mesh_bytes(&m, MeshFormat::Glb, &params).unwrap_err();
        assert!(e.to_string().contains("5 normals"), "{e}");
    }

    use crate::math::Real;

    #[test]
    fn regular_1k_keeps_file_indices() {
        let m = read_mesh(&test_meshes::body("regular_1k.obj")).unwrap();
        assert_eq!(m.num_vertices(), 1229);
        assert_eq!(m.num_faces(), 2030 + 2 * 212);
        // First lines of the file: "v -0.029247 0.671858 0.126338", "f 4 8 11".
        assert_eq!(m.positions[0], Vec3::new(-0.029247, 0.671858, 0.126338));
        assert_eq!(m.faces[0], [3, 7, 10]);
    }

    /// A body written in each format and read back keeps its connectivity (STL: up to welding order).
    #[test]
    fn body_round_trips_in_every_format() {
        let m = read_mesh(&test_meshes::body("kid_600.obj")).unwrap();
        for f in MeshFormat::ALL {
            let bytes = write_mesh_bytes(&m, f, &WriteParams::default()).unwrap();
            let back = read_mesh_bytes(&bytes, f).unwrap();
            assert_eq!(back.num_vertices(), m.num_vertices(), "{f}");
            assert_eq!(back.num_faces(), m.num_faces(), "{f}");
            if f != MeshFormat::Stl {
                assert_eq!(back.faces, m.faces, "{f}");
            }
            assert!(
                (back.signed_volume() - m.signed_volume()).abs() < 1e-6 * m.signed_volume().abs()
            );
        }
    }

    /// Every format written and read back gives the same faces and (to the format's precision) positions.
    #[test]
    fn round_trip_every_format() {
        let m = test_meshes::octahedron();
        for f in MeshFormat::ALL {
            for enc in [PlyEncoding::BinaryLittleEndian, PlyEncoding::Ascii] {
                let params = WriteParams {
                    ply_encoding: enc,
                    ..Default::default()
                };
                let bytes = write_mesh_bytes(&m, f, &params).unwrap();
                let back = read_mesh_bytes(&bytes, f).unwrap();
                assert_eq!(back.num_faces(), m.num_faces(), "{f}");
                assert_eq!(back.num_vertices(), m.num_vertices(), "{f}");
                // f32 formats (STL, glTF) keep ~7 digits.
                let tol = match f {
                    MeshFormat::Stl | MeshFormat::Glb => 1e-7,
                    _ => 0.0,
                };
                for (fa, fb) in m.faces.iter().zip(&back.faces) {
                    for k in 0..3 {
                        let d = (m.positions[fa[k]] - back.positions[fb[k]]).amax();
                        assert!(d <= tol, "{f}: corner differs by {d}");
                    }
                }
                if f != MeshFormat::Stl {
                    assert_eq!(back.faces, m.faces, "{f}");
                }
            }
        }
    }

    /// Truncated and corrupted files give errors or meshes, never a panic or a hang (seeded, several sizes).
    #[test]
    fn corrupted_files_never_panic() {
        use rand::{Rng, SeedableRng};
        let body = read_mesh(&test_meshes::body("regular_370.obj")).unwrap();
        let small = test_meshes::octahedron();
        for (seed, mesh) in [(1u64, &small), (2, &body)] {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            for f in MeshFormat::ALL {
                for enc in [PlyEncoding::BinaryLittleEndian, PlyEncoding::Ascii] {
                    let params = WriteParams {
                        ply_encoding: enc,
                        ..Default::default()
                    };
                    let good = write_mesh_bytes(mesh, f, &params).unwrap();
                    for _ in 0..40 {
                        let mut bad = good.clone();
                        if rng.random_bool(0.5) {
                            bad.truncate(rng.random_range(0..good.len()));
                        }
                        for _ in 0..rng.random_range(1..6) {
                            if bad.is_empty() {
                                break;
                            }
                            let i = rng.random_range(0..bad.len());
                            bad[i] = rng.random();
                        }
                        if let Ok(m) = read_mesh_bytes(&bad, f) {
                            // Whatever was read is fit for the checker.
                            let _ = crate::mesh::check::mesh_report(&m, &Default::default());
                        }
                    }
                }
            }
        }
    }
}
