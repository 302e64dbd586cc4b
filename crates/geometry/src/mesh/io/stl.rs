//! STL, ASCII and binary. STL stores each triangle with its own three corners, so corners with identical
//! coordinates are welded into one vertex (in order of first appearance) to give a connected mesh.
//!
//! Binary layout: 80-byte header, `u32` triangle count, then per triangle 12 `f32` (normal, three corners)
//! and a `u16` attribute — 50 bytes. A file is taken as ASCII when it starts with `solid`, is text, and is not
//! exactly the size its binary header announces.

use std::collections::HashMap;

use super::{MeshFormat, MeshIoError};
use crate::math::Vec3;
use crate::mesh::TriMesh;

const FORMAT: MeshFormat = MeshFormat::Stl;
const HEADER: usize = 84;
const RECORD: usize = 50;

/// Reads an STL file (ASCII or binary).
pub fn read_stl(bytes: &[u8]) -> Result<TriMesh, MeshIoError> {
    let binary_size_matches = bytes.len() >= HEADER
        && HEADER as u64 + RECORD as u64 * binary_count(bytes) as u64 == bytes.len() as u64;
    let looks_ascii = bytes.trim_ascii_start().starts_with(b"solid")
        && !bytes.contains(&0)
        && std::str::from_utf8(bytes).is_ok();
    if looks_ascii && !binary_size_matches {
        read_ascii(std::str::from_utf8(bytes).unwrap_or(""))
    } else {
        read_binary(bytes)
    }
}

fn binary_count(bytes: &[u8]) -> u32 {
    u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]])
}

fn read_binary(bytes: &[u8]) -> Result<TriMesh, MeshIoError> {
    if bytes.len() < HEADER {
        return Err(MeshIoError::invalid(
            FORMAT,
            format!(
                "binary STL truncated: file has {} bytes, fewer than the 84-byte header",
                bytes.len()
            ),
        ));
    }
    let n = binary_count(bytes) as usize;
    let needed = HEADER as u64 + RECORD as u64 * n as u64;
    if (bytes.len() as u64) < needed {
        return Err(MeshIoError::invalid(
            FORMAT,
            format!(
                "binary STL truncated: header says {n} triangles (needs {needed} bytes) but file has {} bytes",
                bytes.len()
            ),
        ));
    }
    let mut welder = Welder::with_capacity(n / 2 + 3);
    let mut faces = Vec::with_capacity(n);
    for record in bytes[HEADER..].chunks_exact(RECORD).take(n) {
        let f = |k: usize| {
            let o = 12 + 4 * k;
            f32::from_le_bytes([record[o], record[o + 1], record[o + 2], record[o + 3]]) as f64
        };
        let mut face = [0; 3];
        for (c, v) in face.iter_mut().enumerate() {
            *v = welder.vertex(Vec3::new(f(3 * c), f(3 * c + 1), f(3 * c + 2)));
        }
        faces.push(face);
    }
    Ok(TriMesh::new(welder.positions, faces))
}

fn read_ascii(text: &str) -> Result<TriMesh, MeshIoError> {
    let mut welder = Welder::with_capacity(text.len() / 200);
    let mut faces = Vec::new();
    let mut corners: Vec<usize> = Vec::with_capacity(3);
    let mut facet_line: Option<usize> = None;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let mut t = raw.split_ascii_whitespace();
        match t.next() {
            Some("facet") => {
                if facet_line.is_some() {
                    return Err(MeshIoError::syntax(
                        FORMAT,
                        line,
                        "facet inside a facet (missing endfacet)",
                    ));
                }
                facet_line = Some(line);
                corners.clear();
            }
            Some("vertex") => {
                if facet_line.is_none() {
                    return Err(MeshIoError::syntax(FORMAT, line, "vertex outside a facet"));
                }
                let mut p = [0.0; 3];
                for (k, c) in p.iter_mut().enumerate() {
                    let tok = t.next().ok_or_else(|| {
                        MeshIoError::syntax(
                            FORMAT,
                            line,
                            format!("vertex has {k} coordinates, needs 3"),
                        )
                    })?;
                    *c = tok.parse().map_err(|_| {
                        MeshIoError::syntax(FORMAT, line, format!("{tok:?} is not a number"))
                    })?;
                }
                corners.push(welder.vertex(Vec3::new(p[0], p[1], p[2])));
            }
            Some("endfacet") => {
                if corners.len() != 3 {
                    return Err(MeshIoError::syntax(
                        FORMAT,
                        line,
                        format!("facet has {} vertices, needs 3", corners.len()),
                    ));
                }
                faces.push([corners[0], corners[1], corners[2]]);
                facet_line = None;
            }
            _ => {} // solid, outer loop, endloop, endsolid, blank lines
        }
    }
    if let Some(line) = facet_line {
        return Err(MeshIoError::syntax(
            FORMAT,
            line,
            "ASCII STL ends inside the facet that starts here",
        ));
    }
    Ok(TriMesh::new(welder.positions, faces))
}

/// Merges corners with bit-identical coordinates (−0 and +0 count as equal).
struct Welder {
    positions: Vec<Vec3>,
    index: HashMap<[u64; 3], usize>,
}

impl Welder {
    fn with_capacity(n: usize) -> Self {
        Self {
            positions: Vec::with_capacity(n),
            index: HashMap::with_capacity(n),
        }
    }

    fn vertex(&mut self, p: Vec3) -> usize {
        let key = [p.x, p.y, p.z].map(|x| if x == 0.0 { 0u64 } else { x.to_bits() });
        let next = self.positions.len();
        *self.index.entry(key).or_insert_with(|| {
            self.positions.push(p);
            next
        })
    }
}

/// Writes a binary STL with unit face normals (zero for a degenerate face). Coordinates become `f32`.
pub fn write_stl(mesh: &TriMesh) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER + RECORD * mesh.num_faces());
    let mut header = [b' '; 80];
    let title = b"skintight binary STL, metres";
    header[..title.len()].copy_from_slice(title);
    out.extend_from_slice(&header);
    out.extend_from_slice(&(mesh.num_faces() as u32).to_le_bytes());
    for f in 0..mesh.num_faces() {
        let n = mesh.face_area_normal(f);
        let len = n.norm();
        let n = if len > 0.0 { n / len } else { Vec3::zeros() };
        for x in n
            .iter()
            .chain(mesh.corners(f).iter().flat_map(|p| p.iter()))
        {
            out.extend_from_slice(&(*x as f32).to_le_bytes());
        }
        out.extend_from_slice(&0u16.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::octahedron;

    #[test]
    fn binary_welds_into_a_closed_mesh() {
        let m = octahedron();
        let back = read_stl(&write_stl(&m)).unwrap();
        assert_eq!(back.num_vertices(), 6);
        assert_eq!(back.num_faces(), 8);
        assert!(crate::Topology::new(6, &back.faces).unwrap().is_closed());
        assert!((back.signed_volume() - m.signed_volume()).abs() < 1e-8);
    }

    #[test]
    fn ascii_is_read_and_welded() {
        let text = "solid two\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n\
            vertex 0 1 0\n  endloop\n endfacet\n facet normal 0 0 1\n  outer loop\n   vertex 1 0 0\n\
            vertex 1 1 0\n   vertex 0 1 0\n  endloop\n endfacet\nendsolid two\n";
        let m = read_stl(text.as_bytes()).unwrap();
        assert_eq!(m.num_vertices(), 4);
        assert_eq!(m.faces, vec![[0, 1, 2], [1, 3, 2]]);
    }

    #[test]
    fn ascii_errors_name_the_line() {
        let text = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\n";
        let e = read_stl(text.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("STL line 7: facet has 2 vertices"), "{e}");
        let text = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 q 0\n";
        let e = read_stl(text.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("STL line 5: \"q\" is not a number"), "{e}");
        let text = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n";
        let e = read_stl(text.as_bytes()).unwrap_err().to_string();
        assert!(
            e.contains("line 2") && e.contains("ends inside the facet"),
            "{e}"
        );
    }

    #[test]
    fn truncated_binary_is_a_clear_error() {
        let mut b = write_stl(&octahedron());
        b.truncate(300);
        let e = read_stl(&b).unwrap_err().to_string();
        assert_eq!(
            e,
            "binary STL truncated: header says 8 triangles (needs 484 bytes) but file has 300 bytes"
        );
        let e = read_stl(&b[..50]).unwrap_err().to_string();
        assert!(e.contains("fewer than the 84-byte header"), "{e}");
    }

    #[test]
    fn binary_whose_header_starts_with_solid_is_binary() {
        let mut b = write_stl(&octahedron());
        b[..5].copy_from_slice(b"solid");
        assert_eq!(read_stl(&b).unwrap().num_vertices(), 6);
    }

    #[test]
    fn huge_announced_count_is_truncation_not_allocation() {
        let mut b = vec![0u8; 84];
        b[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = read_stl(&b).unwrap_err().to_string();
        assert!(e.contains("header says 4294967295 triangles"), "{e}");
    }
}
