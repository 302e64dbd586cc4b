//! Reads a TetGen `.node` + `.ele` pair.
//!
//! `.node`: header `#points 3 #attributes boundary-marker(0|1)`, then `index x y z [attributes] [marker]`.
//! `.ele`: header `#tets nodes-per-tet(4) #attributes`, then `index a b c d [attributes]`. `#` starts a
//! comment. Points are numbered from 0 or 1, as the first point record says, consecutively; `.ele` indices use
//! the same base. Attributes and boundary markers are ignored. Second-order (10-node) tetrahedra are refused.

use std::path::{Path, PathBuf};

use super::{TetReadError, Tokens, capacity, checked, read_text};
use crate::body::tet_mesh::TetMesh;
use crate::math::Vec3;

/// Reads a TetGen pair given either the `.node` or the `.ele` path; the other file is its sibling with the
/// same stem.
pub fn read_tetgen(path: &Path) -> Result<TetMesh, TetReadError> {
    let sibling = |ext: &str| -> PathBuf { path.with_extension(ext) };
    let (node, ele) = (sibling("node"), sibling("ele"));
    let node_text = read_text(&node)?;
    let ele_text = read_text(&ele)?;
    tetgen_from_str(
        &node_text,
        &ele_text,
        &node.display().to_string(),
        &ele.display().to_string(),
    )
}

/// Parses TetGen `.node` and `.ele` text; the names are used in error messages.
pub fn tetgen_from_str(
    node_text: &str,
    ele_text: &str,
    node_name: &str,
    ele_name: &str,
) -> Result<TetMesh, TetReadError> {
    // .node
    let mut tok = Tokens::new(node_text, node_name, Some('#'));
    let n = tok.usize("the point count")?;
    let (l, _) = tok.peek().unwrap_or((1, ""));
    let dim = tok.usize("the dimension")?;
    if dim != 3 {
        return Err(tok.error(
            l,
            format!("dimension {dim} is not supported (a tetrahedral mesh needs 3)"),
        ));
    }
    let attributes = tok.usize("the number of point attributes")?;
    let markers = tok.usize("the boundary-marker flag (0 or 1)")?;
    if markers > 1 {
        return Err(tok.error(
            l,
            format!("boundary-marker flag must be 0 or 1, found {markers}"),
        ));
    }
    let extra = attributes.saturating_add(markers);
    let mut positions = Vec::with_capacity(capacity(n, node_text.len()));
    let mut base = 0;
    for i in 0..n {
        let (l, s) = tok.peek().unwrap_or((0, ""));
        let index = tok.usize("a point index")?;
        if i == 0 {
            if index > 1 {
                return Err(tok.error(
                    l,
                    format!("the first point is numbered {index}; TetGen numbers from 0 or 1"),
                ));
            }
            base = index;
        } else if index != base + i {
            return Err(tok.error(
                l,
                format!("point `{s}` is out of sequence: expected {}", base + i),
            ));
        }
        let x = tok.real("point x")?;
        let y = tok.real("point y")?;
        let z = tok.real("point z")?;
        for _ in 0..extra {
            tok.next("a point attribute or boundary marker")?;
        }
        positions.push(Vec3::new(x, y, z));
    }

    // .ele
    let mut tok = Tokens::new(ele_text, ele_name, Some('#'));
    let m = tok.usize("the tetrahedron count")?;
    let (l, _) = tok.peek().unwrap_or((1, ""));
    let per = tok.usize("the number of nodes per tetrahedron")?;
    if per != 4 {
        return Err(tok.error(
            l,
            format!(
                "{per}-node tetrahedra are not supported (only 4-node; run TetGen without -o2)"
            ),
        ));
    }
    let attributes = tok.usize("the number of tetrahedron attributes")?;
    let nv = positions.len();
    let mut tets = Vec::with_capacity(capacity(m, ele_text.len()));
    for k in 0..m {
        tok.usize("a tetrahedron index")?;
        let mut tet = [0; 4];
        for v in tet.iter_mut() {
            let (l, s) = tok.peek().unwrap_or((0, ""));
            let i = tok.usize("a corner index of a tetrahedron")?;
            if i < base || i - base >= nv {
                return Err(tok.error(
                    l,
                    format!(
                        "tetrahedron {k} names point `{s}`, but points are numbered {base}..{}",
                        base + nv
                    ),
                ));
            }
            *v = i - base;
        }
        for _ in 0..attributes {
            tok.next("a tetrahedron attribute")?;
        }
        tets.push(tet);
    }
    if let Some((l, s)) = tok.peek() {
        return Err(tok.error(
            l,
            format!("unexpected `{s}` after the {m} tetrahedra the header announces"),
        ));
    }
    if tets.is_empty() {
        return Err(TetReadError::Format {
            path: ele_name.into(),
            message: "no tetrahedra".into(),
        });
    }
    checked(TetMesh::new(positions, tets), ele_name)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::body::tet_io::fixtures::{cube, truncations};
    use std::fmt::Write;

    /// The cube as a TetGen pair numbered from `base`, with one point attribute, boundary markers, a comment
    /// and one region attribute per tetrahedron.
    pub(crate) fn cube_tetgen(base: usize) -> (String, String) {
        let (p, t) = cube();
        let mut node = String::from("# cube\n8 3 1 1\n");
        for (i, q) in p.iter().enumerate() {
            writeln!(node, "{} {} {} {} 0.5 1", i + base, q.x, q.y, q.z).unwrap();
        }
        let mut ele = String::from("6 4 1\n");
        for (k, e) in t.iter().enumerate() {
            let [a, b, c, d] = e.map(|v| v + base);
            writeln!(ele, "{} {a} {b} {c} {d} 2 # region", k + base).unwrap();
        }
        (node, ele)
    }

    #[test]
    fn tet_io_tetgen_cube_zero_and_one_based() {
        let (p, t) = cube();
        for base in [0, 1] {
            let (node, ele) = cube_tetgen(base);
            let m = tetgen_from_str(&node, &ele, "c.node", "c.ele").unwrap();
            assert_eq!(m.positions, p, "base {base}");
            assert_eq!(m.tets, t, "base {base}");
        }
    }

    #[test]
    fn tet_io_tetgen_bad_inputs_name_line_and_problem() {
        let (node, ele) = cube_tetgen(1);
        let cases: Vec<(String, String, &str)> = vec![
            (
                node.replace("8 3 1 1", "8 2 1 1"),
                ele.clone(),
                "c.node, line 2: dimension 2",
            ),
            (
                node.replace("\n2 1 0 0", "\n2 nan 0 0"),
                ele.clone(),
                "line 4: point x is not finite",
            ),
            (
                node.replace("\n3 ", "\n4 "),
                ele.clone(),
                "out of sequence: expected 3",
            ),
            (
                node.replace("8 3 1 1", "9 3 1 1"),
                ele.clone(),
                "file ends early",
            ),
            (
                node.clone(),
                ele.replace("6 4 1", "6 10 1"),
                "10-node tetrahedra are not supported",
            ),
            (
                node.clone(),
                ele.replace("6 4 1", "7 4 1"),
                "c.ele: file ends early",
            ),
            (
                node.clone(),
                ele.replace("6 4 1", "5 4 1"),
                "after the 5 tetrahedra",
            ),
            (
                node.clone(),
                ele.replace("1 1 ", "1 9 "),
                "c.ele, line 2: tetrahedron 0 names point `9`",
            ),
            (
                node.clone(),
                ele.replace("1 1 ", "1 0 "),
                "names point `0`, but points are numbered 1..9",
            ),
        ];
        for (n, e, want) in cases {
            let msg = match tetgen_from_str(&n, &e, "c.node", "c.ele") {
                Ok(_) => panic!("case `{want}` parsed"),
                Err(e) => e.to_string(),
            };
            assert!(msg.contains(want), "expected `{want}` in: {msg}");
        }
    }

    #[test]
    fn tet_io_tetgen_inverted_tet_is_rejected_by_name() {
        let node = "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";
        assert!(tetgen_from_str(node, "1 4 0\n0 0 1 2 3\n", "t.node", "t.ele").is_ok());
        let e = tetgen_from_str(node, "1 4 0\n0 1 0 2 3\n", "t.node", "t.ele").unwrap_err();
        assert!(
            matches!(
                e,
                TetReadError::Mesh {
                    source: crate::TetMeshError::Inverted { tet: 0, .. },
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string()
                .contains("tetrahedron 0 [1, 0, 2, 3] is inverted"),
            "{e}"
        );
    }

    #[test]
    fn tet_io_tetgen_truncation_never_panics() {
        let (node, ele) = cube_tetgen(0);
        truncations(&node, 4, 200, |s| {
            let r = tetgen_from_str(s, &ele, "cut.node", "c.ele");
            if s.len() + 10 < node.len() {
                assert!(r.is_err(), "node prefix of {} bytes parsed", s.len());
            }
        });
        truncations(&ele, 5, 200, |s| {
            let _ = tetgen_from_str(&node, s, "c.node", "cut.ele");
        });
    }
}
