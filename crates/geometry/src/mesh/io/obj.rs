//! Wavefront OBJ: `v` positions, `f` polygons (fan-triangulated), `g`/`o` groups as face labels.
//!
//! A small parser of our own, because vertex indices must stay exactly as in the file (general loaders
//! re-index vertices per object or per position/normal/texture triple). Texture coordinates, normals,
//! materials, smoothing groups, lines and the optional colour fields after `v x y z` are ignored.

use std::collections::HashMap;
use std::fmt::Write as _;

use super::{MeshFormat, MeshIoError, WriteParams, fan_triangulate};
use crate::math::Vec3;
use crate::mesh::TriMesh;

const FORMAT: MeshFormat = MeshFormat::Obj;

/// Reads an OBJ file. Errors name the line.
pub fn read_obj(bytes: &[u8]) -> Result<TriMesh, MeshIoError> {
    let text = String::from_utf8_lossy(bytes);
    let mut positions: Vec<Vec3> = Vec::new();
    let mut faces: Vec<[usize; 3]> = Vec::new();
    // Group of each face; `None` before the first `g`/`o`.
    let mut groups: Vec<Option<u32>> = Vec::new();
    let mut group_names: Vec<String> = Vec::new();
    let mut group_ids: HashMap<String, u32> = HashMap::new();
    let mut current: Option<u32> = None;
    let mut poly: Vec<usize> = Vec::with_capacity(8);

    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.split('#').next().unwrap_or("");
        let mut tokens = content.split_ascii_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        match keyword {
            "v" => {
                let mut xyz = [0.0; 3];
                for (k, c) in xyz.iter_mut().enumerate() {
                    let tok = tokens.next().ok_or_else(|| {
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
                positions.push(Vec3::new(xyz[0], xyz[1], xyz[2]));
            }
            "f" => {
                poly.clear();
                for tok in tokens {
                    poly.push(vertex_index(tok, positions.len(), line)?);
                }
                if poly.len() < 3 {
                    return Err(MeshIoError::syntax(
                        FORMAT,
                        line,
                        format!("face has {} vertices, needs at least 3", poly.len()),
                    ));
                }
                fan_triangulate(&poly, &mut faces);
                groups.resize(faces.len(), current);
            }
            "g" | "o" => {
                let name = tokens.collect::<Vec<_>>().join(" ");
                let name = if name.is_empty() {
                    "default".to_string()
                } else {
                    name
                };
                let next = group_names.len() as u32;
                let id = *group_ids.entry(name.clone()).or_insert_with(|| {
                    group_names.push(name);
                    next
                });
                current = Some(id);
            }
            _ => {} // vt, vn, s, usemtl, mtllib, l, … are not needed.
        }
    }

    let face_groups = if group_names.is_empty() {
        Vec::new()
    } else {
        // Faces before the first group statement go to a group named "default".
        let default = if groups.iter().any(Option::is_none) {
            match group_ids.get("default") {
                Some(&id) => id,
                None => {
                    group_names.push("default".into());
                    group_names.len() as u32 - 1
                }
            }
        } else {
            0
        };
        groups.iter().map(|g| g.unwrap_or(default)).collect()
    };
    Ok(TriMesh {
        positions,
        faces,
        face_groups,
        group_names,
    })
}

/// The 0-based vertex index of a face corner `v`, `v/vt`, `v//vn` or `v/vt/vn`, given the vertices so far.
fn vertex_index(tok: &str, count: usize, line: usize) -> Result<usize, MeshIoError> {
    let v = tok.split('/').next().unwrap_or("");
    let i: i64 = v.parse().map_err(|_| {
        MeshIoError::syntax(
            FORMAT,
            line,
            format!("face corner {tok:?} does not start with a vertex index"),
        )
    })?;
    let resolved = if i > 0 {
        (i - 1) as usize
    } else if i < 0 {
        // Relative: -1 is the last vertex defined so far.
        let back = i.unsigned_abs() as usize;
        if back > count {
            return Err(MeshIoError::syntax(
                FORMAT,
                line,
                format!(
                    "relative vertex index {i} reaches before the first vertex ({count} defined so far)"
                ),
            ));
        }
        count - back
    } else {
        return Err(MeshIoError::syntax(
            FORMAT,
            line,
            "vertex index 0 is invalid (OBJ indices start at 1)",
        ));
    };
    if resolved >= count {
        return Err(MeshIoError::syntax(
            FORMAT,
            line,
            format!("face refers to vertex {i}, but only {count} vertices are defined so far"),
        ));
    }
    Ok(resolved)
}

/// Writes an OBJ file: `v x y z [r g b]`, `vn`, `g` group lines where the group changes, `f` with 1-based
/// indices (`f a//a …` with normals). Coordinates are written in the shortest form that reads back exactly.
pub fn write_obj(mesh: &TriMesh, params: &WriteParams<'_>) -> Vec<u8> {
    let mut s = String::with_capacity(mesh.num_vertices() * 40 + mesh.num_faces() * 20);
    let _ = writeln!(
        s,
        "# skintight mesh: {} vertices, {} triangles, metres",
        mesh.num_vertices(),
        mesh.num_faces()
    );
    for (v, p) in mesh.positions.iter().enumerate() {
        let _ = write!(s, "v {} {} {}", p.x, p.y, p.z);
        if let Some(c) = params.colors {
            let _ = write!(s, " {} {} {}", c[v][0], c[v][1], c[v][2]);
        }
        s.push('\n');
    }
    if let Some(normals) = params.normals {
        for n in normals {
            let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
        }
    }
    let mut group: Option<u32> = None;
    for (f, face) in mesh.faces.iter().enumerate() {
        if let Some(&g) = mesh.face_groups.get(f)
            && group != Some(g)
        {
            let _ = writeln!(s, "g {}", mesh.group_names[g as usize]);
            group = Some(g);
        }
        let [a, b, c] = face.map(|v| v + 1);
        if params.normals.is_some() {
            let _ = writeln!(s, "f {a}//{a} {b}//{b} {c}//{c}");
        } else {
            let _ = writeln!(s, "f {a} {b} {c}");
        }
    }
    s.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::octahedron;

    #[test]
    fn polygons_groups_and_index_forms() {
        let text = "# a comment\n\
            mtllib x.mtl\n\
            v 0 0 0 1 0 0\n\
            v 1 0 0 0.5 0.5 0.5 # colour fields ignored\n\
            v 1 1 0\n\
            v 0 1 0\n\
            vt 0 0\n\
            vn 0 0 1\n\
            f 1/1/1 2/1/1 3/1/1 4/1/1\n\
            g left arm\n\
            v 0 0 1\n\
            f -5//1 -4//1 -1//1\n\
            o second\n\
            s off\n\
            f 2/1 3/1 5/1\n\
            g left arm\n\
            f 3 4 5\n";
        let m = read_obj(text.as_bytes()).unwrap();
        assert_eq!(m.num_vertices(), 5);
        assert_eq!(
            m.faces,
            vec![[0, 1, 2], [0, 2, 3], [0, 1, 4], [1, 2, 4], [2, 3, 4]]
        );
        assert_eq!(m.group_names, vec!["left arm", "second", "default"]);
        assert_eq!(m.face_groups, vec![2, 2, 0, 1, 0]);
        assert_eq!(m.positions[1], Vec3::new(1.0, 0.0, 0.0));
    }

    #[test]
    fn no_groups_means_no_labels() {
        let m = read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert!(m.face_groups.is_empty() && m.group_names.is_empty());
    }

    #[test]
    fn errors_name_the_line() {
        let cases: [(&str, &str); 6] = [
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "line 4"),
            ("v 0 0 0\nv 1 x 0\n", "line 2: \"x\" is not a number"),
            ("v 0 0\n", "line 1: vertex has 2 coordinates"),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", "line 3: face has 2 vertices"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
                "line 4: vertex index 0",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf -4 1 2\n",
                "line 5: relative vertex index -4",
            ),
        ];
        for (text, expected) in cases {
            let e = read_obj(text.as_bytes()).unwrap_err();
            assert!(e.to_string().contains(expected), "{e} lacks {expected}");
            assert!(e.to_string().starts_with("OBJ line"), "{e}");
        }
    }

    #[test]
    fn nan_coordinates_are_read_for_the_check_to_report() {
        let m = read_obj(b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert!(m.positions[0].x.is_nan());
    }

    #[test]
    fn write_then_read_keeps_everything() {
        let m = octahedron();
        let normals: Vec<Vec3> = m.positions.iter().map(|p| p.normalize()).collect();
        let colors: Vec<[f32; 3]> = (0..6).map(|i| [i as f32 / 5.0, 0.5, 1.0]).collect();
        let params = WriteParams {
            normals: Some(&normals),
            colors: Some(&colors),
            ..Default::default()
        };
        let back = read_obj(&write_obj(&m, &params)).unwrap();
        assert_eq!(back, m);
    }
}
