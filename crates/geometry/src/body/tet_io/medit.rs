//! Reads MEDIT `.mesh` ASCII files (INRIA format, as written by TetGen `-g`, MMG, CGAL, fTetWild).
//!
//! Reads `MeshVersionFormatted`, `Dimension 3`, `Vertices` (`n`, then `n × (x y z ref)`) and `Tetrahedra`
//! (`n`, then `n × (a b c d ref)`, 1-based) up to `End`. Keywords are case-insensitive; `#` starts a comment.
//! Other sections (`Triangles`, `Edges`, `Corners`, …) are skipped. Vertex and tetrahedron references
//! (labels) are ignored.

use std::path::Path;

use super::{TetReadError, Tokens, capacity, checked, read_text};
use crate::body::tet_mesh::TetMesh;
use crate::math::Vec3;

/// Reads a MEDIT `.mesh` ASCII file.
pub fn read_medit(path: &Path) -> Result<TetMesh, TetReadError> {
    let text = read_text(path)?;
    medit_from_str(&text, &path.display().to_string())
}

/// Whether a token is a keyword: it starts with a letter and is not a number (`nan`, `inf` are numbers, so
/// a non-finite coordinate is reported as such rather than taken for a section name).
fn is_keyword(t: &str) -> bool {
    t.starts_with(|c: char| c.is_ascii_alphabetic()) && t.parse::<f64>().is_err()
}

/// Parses MEDIT `.mesh` ASCII text; `name` is used in error messages.
pub fn medit_from_str(text: &str, name: &str) -> Result<TetMesh, TetReadError> {
    let mut tok = Tokens::new(text, name, Some('#'));
    let mut positions: Option<Vec<Vec3>> = None;
    let mut tets: Option<Vec<[usize; 4]>> = None;
    let mut dimension = None;
    let mut ended = false;
    while let Some((line, word)) = tok.peek() {
        tok.next("a keyword")?;
        if !is_keyword(word) {
            return Err(tok.error(
                line,
                format!("expected a keyword such as `Vertices`, found `{word}`"),
            ));
        }
        match word.to_ascii_lowercase().as_str() {
            "meshversionformatted" => {
                let (l, v) = tok.next("the format version")?;
                if v == "0" {
                    return Err(tok.error(
                        l,
                        "binary MEDIT files (.meshb) are not supported; save as ASCII".into(),
                    ));
                }
            }
            "dimension" => {
                let (l, _) = tok.peek().unwrap_or((line, ""));
                let d = tok.usize("the dimension")?;
                if d != 3 {
                    return Err(tok.error(
                        l,
                        format!("dimension {d} is not supported (a tetrahedral mesh needs 3)"),
                    ));
                }
                dimension = Some(d);
            }
            "vertices" => {
                if dimension.is_none() {
                    return Err(tok.error(line, "`Dimension 3` must come before `Vertices`".into()));
                }
                let n = tok.usize("the vertex count")?;
                let mut p = Vec::with_capacity(capacity(n, text.len()));
                for _ in 0..n {
                    let x = tok.real("vertex x")?;
                    let y = tok.real("vertex y")?;
                    let z = tok.real("vertex z")?;
                    tok.next("the vertex reference")?;
                    p.push(Vec3::new(x, y, z));
                }
                positions = Some(p);
            }
            "tetrahedra" => {
                let nv = positions
                    .as_ref()
                    .ok_or_else(|| tok.error(line, "`Tetrahedra` comes before `Vertices`".into()))?
                    .len();
                let n = tok.usize("the tetrahedron count")?;
                let mut t = Vec::with_capacity(capacity(n, text.len()));
                for k in 0..n {
                    let mut tet = [0; 4];
                    for v in tet.iter_mut() {
                        let (l, s) = tok.peek().unwrap_or((line, ""));
                        let i = tok.usize("a vertex index of a tetrahedron")?;
                        if i == 0 || i > nv {
                            return Err(tok.error(
                                l,
                                format!("tetrahedron {} names vertex `{s}`, but vertices are numbered 1..={nv}", k + 1),
                            ));
                        }
                        *v = i - 1;
                    }
                    tok.next("the tetrahedron reference")?;
                    t.push(tet);
                }
                tets = Some(t);
            }
            "end" => {
                ended = true;
                break;
            }
            _ => {
                // Unknown section: skip its count and records up to the next keyword.
                while tok.peek().is_some_and(|(_, t)| !is_keyword(t)) {
                    tok.next("a record")?;
                }
            }
        }
    }
    let fail = |message: &str| TetReadError::Format {
        path: name.into(),
        message: message.into(),
    };
    if !ended {
        return Err(fail("file ends without `End` (truncated?)"));
    }
    let positions = positions.ok_or_else(|| fail("no `Vertices` section"))?;
    let tets = tets.ok_or_else(|| fail("no `Tetrahedra` section"))?;
    if tets.is_empty() {
        return Err(fail("`Tetrahedra` is empty"));
    }
    checked(TetMesh::new(positions, tets), name)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::body::tet_io::fixtures::{cube, truncations};
    use std::fmt::Write;

    /// The cube as MEDIT text with mixed-case keywords, a comment and a `Triangles` section to skip.
    pub(crate) fn cube_medit() -> String {
        let (p, t) = cube();
        let mut s =
            String::from("MeshVersionFormatted 2\n# unit cube\nDimension\n3\nVertices\n8\n");
        for q in &p {
            writeln!(s, "{} {} {} 0", q.x, q.y, q.z).unwrap();
        }
        s.push_str("triangles\n2\n1 2 4 1\n1 4 3 1\nTETRAHEDRA\n6\n");
        for e in &t {
            writeln!(s, "{} {} {} {} 1", e[0] + 1, e[1] + 1, e[2] + 1, e[3] + 1).unwrap();
        }
        s.push_str("Corners\n1\n1\nEnd\n");
        s
    }

    fn err(text: &str) -> String {
        medit_from_str(text, "t.mesh").unwrap_err().to_string()
    }

    #[test]
    fn tet_io_medit_cube() {
        let (p, t) = cube();
        let m = medit_from_str(&cube_medit(), "cube.mesh").unwrap();
        assert_eq!(m.positions, p);
        assert_eq!(m.tets, t);
    }

    #[test]
    fn tet_io_medit_bad_inputs_name_line_and_problem() {
        let good = cube_medit();
        let cases: Vec<(String, &str)> = vec![
            (
                good.replace("Dimension\n3", "Dimension\n2"),
                "line 4: dimension 2",
            ),
            (
                good.replace("1 1 0 0", "1 NaN 0 0"),
                "vertex y is not finite",
            ),
            (
                good.replace("1 1 0 0", "1 inf 0 0"),
                "vertex y is not finite",
            ),
            (
                good.replace("TETRAHEDRA\n6", "TETRAHEDRA\n7"),
                "expected a vertex index",
            ),
            (
                good.replace("TETRAHEDRA\n6\n1 ", "TETRAHEDRA\n6\n9 "),
                "line 21: tetrahedron 1 names vertex `9`",
            ),
            (
                good.replace("TETRAHEDRA\n6\n1 ", "TETRAHEDRA\n6\n0 "),
                "names vertex `0`",
            ),
            (good.replace("End\n", ""), "without `End`"),
            (
                good.replace("Dimension\n3\n", ""),
                "must come before `Vertices`",
            ),
            (
                good.replace("MeshVersionFormatted 2", "MeshVersionFormatted 0"),
                "binary MEDIT",
            ),
        ];
        for (text, want) in cases {
            let e = err(&text);
            assert!(e.contains(want), "expected `{want}` in: {e}");
        }
    }

    #[test]
    fn tet_io_medit_flat_tet_is_rejected_by_name() {
        let text = "Dimension 3\nVertices 4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n1 1 0 0\nTetrahedra 1\n1 2 3 4 0\nEnd\n";
        let e = medit_from_str(text, "flat.mesh").unwrap_err();
        assert!(
            matches!(
                e,
                TetReadError::Mesh {
                    source: crate::TetMeshError::Degenerate { tet: 0, .. },
                    ..
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn tet_io_medit_truncation_never_panics() {
        truncations(&cube_medit(), 3, 300, |s| {
            let r = medit_from_str(s, "cut.mesh");
            if !s.contains("End") {
                assert!(r.is_err(), "prefix of {} bytes parsed", s.len());
            }
        });
    }
}
