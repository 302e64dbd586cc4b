//! Reads Gmsh `.msh` ASCII files, format versions 2.x and 4.x (4.0 and 4.1).
//!
//! Only 4-node tetrahedra (element type 4) are read; every other element type (points, lines, triangles,
//! second-order tetrahedra, …) is skipped. Node tags may be arbitrary and non-contiguous; vertices are
//! numbered in the order the nodes appear. Unknown sections (`$PhysicalNames`, `$Entities`, `$NodeData`, …)
//! are skipped. Binary `.msh` files are refused.

use std::collections::HashMap;
use std::path::Path;

use super::{TetReadError, capacity, checked, parse_error, parse_real, parse_usize, read_text};
use crate::body::tet_mesh::TetMesh;
use crate::math::Vec3;

/// Gmsh element type of the 4-node tetrahedron.
const GMSH_TET4: usize = 4;

/// Reads a Gmsh `.msh` ASCII (v2 or v4) file.
pub fn read_msh(path: &Path) -> Result<TetMesh, TetReadError> {
    let text = read_text(path)?;
    msh_from_str(&text, &path.display().to_string())
}

/// Parses Gmsh `.msh` ASCII text; `name` is used in error messages.
pub fn msh_from_str(text: &str, name: &str) -> Result<TetMesh, TetReadError> {
    let mut lines = Lines::new(text, name);
    let mut version: Option<u32> = None;
    let mut nodes: Option<(Vec<Vec3>, HashMap<usize, usize>)> = None;
    let mut tets: Option<Vec<[usize; 4]>> = None;
    while let Some((line, head)) = lines.next_opt() {
        let Some(section) = head.strip_prefix('$') else {
            return Err(parse_error(
                name,
                line,
                format!("expected a section such as `$Nodes`, found `{head}`"),
            ));
        };
        match section {
            "MeshFormat" => {
                let (l, f) = lines.fields("the format line `version file-type data-size`")?;
                if f.len() < 2 {
                    return Err(parse_error(
                        name,
                        l,
                        "the format line needs `version file-type data-size`".into(),
                    ));
                }
                if f[1] != "0" {
                    return Err(parse_error(
                        name,
                        l,
                        "binary .msh is not supported; save as ASCII".into(),
                    ));
                }
                let major = f[0].split('.').next().unwrap_or("");
                version = Some(match major {
                    "2" => 2,
                    "4" => 4,
                    _ => {
                        return Err(parse_error(
                            name,
                            l,
                            format!("MSH version {} is not supported (use 2.2 or 4.1)", f[0]),
                        ));
                    }
                });
            }
            "Nodes" | "Elements" => {
                let v = version.ok_or_else(|| {
                    parse_error(name, line, "`$MeshFormat` must come first".into())
                })?;
                if section == "Nodes" {
                    nodes = Some(if v == 2 {
                        nodes_v2(&mut lines)?
                    } else {
                        nodes_v4(&mut lines)?
                    });
                } else {
                    let map = &nodes
                        .as_ref()
                        .ok_or_else(|| {
                            parse_error(name, line, "`$Elements` comes before `$Nodes`".into())
                        })?
                        .1;
                    tets = Some(if v == 2 {
                        elements_v2(&mut lines, map)?
                    } else {
                        elements_v4(&mut lines, map)?
                    });
                }
            }
            _ => {
                lines.skip_to_end(section)?;
                continue;
            }
        }
        // The parsed sections must end right after the records their counts announce.
        lines.expect_end(section)?;
    }
    let (positions, _) = nodes.ok_or_else(|| TetReadError::Format {
        path: name.into(),
        message: "no `$Nodes` section".into(),
    })?;
    let tets = tets.ok_or_else(|| TetReadError::Format {
        path: name.into(),
        message: "no `$Elements` section".into(),
    })?;
    if tets.is_empty() {
        return Err(TetReadError::Format {
            path: name.into(),
            message: "no 4-node tetrahedra (element type 4) in `$Elements`".into(),
        });
    }
    checked(TetMesh::new(positions, tets), name)
}

/// Non-blank lines with their 1-based numbers.
struct Lines<'a> {
    name: &'a str,
    len: usize,
    iter: std::iter::Enumerate<std::str::Lines<'a>>,
}

impl<'a> Lines<'a> {
    fn new(text: &'a str, name: &'a str) -> Self {
        Self {
            name,
            len: text.len(),
            iter: text.lines().enumerate(),
        }
    }
    fn next_opt(&mut self) -> Option<(usize, &'a str)> {
        for (i, l) in self.iter.by_ref() {
            let t = l.trim();
            if !t.is_empty() {
                return Some((i + 1, t));
            }
        }
        None
    }
    /// The next line split into fields, or a "file ends" error naming `what`.
    fn fields(&mut self, what: &str) -> Result<(usize, Vec<&'a str>), TetReadError> {
        let (l, t) = self.next_opt().ok_or_else(|| TetReadError::Format {
            path: self.name.into(),
            message: format!("file ends early: expected {what}"),
        })?;
        if t.starts_with('$') {
            return Err(parse_error(
                self.name,
                l,
                format!("section ends early: expected {what}, found `{t}`"),
            ));
        }
        Ok((l, t.split_whitespace().collect()))
    }
    /// Skips to `$End<section>`.
    fn skip_to_end(&mut self, section: &str) -> Result<(), TetReadError> {
        while let Some((_, t)) = self.next_opt() {
            if t.strip_prefix("$End") == Some(section) {
                return Ok(());
            }
        }
        Err(TetReadError::Format {
            path: self.name.into(),
            message: format!("file ends inside `${section}` (no `$End{section}`)"),
        })
    }
    /// The next line must be `$End<section>`.
    fn expect_end(&mut self, section: &str) -> Result<(), TetReadError> {
        match self.next_opt() {
            Some((_, t)) if t.strip_prefix("$End") == Some(section) => Ok(()),
            Some((l, t)) => Err(parse_error(
                self.name,
                l,
                format!(
                    "expected `$End{section}` after the records the count announces, found `{t}`"
                ),
            )),
            None => Err(TetReadError::Format {
                path: self.name.into(),
                message: format!("file ends inside `${section}` (no `$End{section}`)"),
            }),
        }
    }
    fn usize_at(&self, f: &[&str], i: usize, l: usize, what: &str) -> Result<usize, TetReadError> {
        let t = f.get(i).ok_or_else(|| {
            parse_error(self.name, l, format!("missing {what} (field {})", i + 1))
        })?;
        parse_usize(t, self.name, l, what)
    }
    fn point(&self, f: &[&str], at: usize, l: usize) -> Result<Vec3, TetReadError> {
        let mut p = [0.0; 3];
        for (k, c) in p.iter_mut().enumerate() {
            let what = ["x", "y", "z"][k];
            let t = f
                .get(at + k)
                .ok_or_else(|| parse_error(self.name, l, format!("missing coordinate {what}")))?;
            *c = parse_real(t, self.name, l, what)?;
        }
        Ok(Vec3::new(p[0], p[1], p[2]))
    }
}

fn add_node(
    lines: &Lines,
    tag: usize,
    p: Vec3,
    l: usize,
    positions: &mut Vec<Vec3>,
    map: &mut HashMap<usize, usize>,
) -> Result<(), TetReadError> {
    if map.insert(tag, positions.len()).is_some() {
        return Err(parse_error(
            lines.name,
            l,
            format!("node tag {tag} appears twice"),
        ));
    }
    positions.push(p);
    Ok(())
}

/// v2: `n`, then `n` lines `tag x y z`.
fn nodes_v2(lines: &mut Lines) -> Result<(Vec<Vec3>, HashMap<usize, usize>), TetReadError> {
    let (l, f) = lines.fields("the node count")?;
    let n = lines.usize_at(&f, 0, l, "node count")?;
    let mut positions = Vec::with_capacity(capacity(n, lines.len));
    let mut map = HashMap::with_capacity(capacity(n, lines.len));
    for _ in 0..n {
        let (l, f) = lines.fields("a node line `tag x y z`")?;
        let tag = lines.usize_at(&f, 0, l, "node tag")?;
        let p = lines.point(&f, 1, l)?;
        add_node(lines, tag, p, l, &mut positions, &mut map)?;
    }
    Ok((positions, map))
}

/// v4.1: `blocks n min max`, per block `dim entity parametric count`, `count` tag lines then `count`
/// coordinate lines. v4.0: `blocks n`, per block `entity dim parametric count`, then `count` lines `tag x y z`.
fn nodes_v4(lines: &mut Lines) -> Result<(Vec<Vec3>, HashMap<usize, usize>), TetReadError> {
    let (l, f) = lines.fields("the `$Nodes` header")?;
    let blocks = lines.usize_at(&f, 0, l, "entity block count")?;
    let n = lines.usize_at(&f, 1, l, "node count")?;
    let v41 = f.len() >= 4;
    let mut positions = Vec::with_capacity(capacity(n, lines.len));
    let mut map = HashMap::with_capacity(capacity(n, lines.len));
    let mut tags = Vec::new();
    for _ in 0..blocks {
        let (l, f) = lines.fields("a node block header `dim entity parametric count`")?;
        let count = lines.usize_at(&f, 3, l, "number of nodes in the block")?;
        if positions.len().saturating_add(count) > n {
            return Err(parse_error(
                lines.name,
                l,
                format!("node blocks hold more than the {n} nodes announced"),
            ));
        }
        if v41 {
            tags.clear();
            for _ in 0..count {
                let (l, f) = lines.fields("a node tag")?;
                tags.push((lines.usize_at(&f, 0, l, "node tag")?, l));
            }
            for &(tag, _) in &tags {
                let (l, f) = lines.fields("a node coordinate line `x y z`")?;
                let p = lines.point(&f, 0, l)?;
                add_node(lines, tag, p, l, &mut positions, &mut map)?;
            }
        } else {
            for _ in 0..count {
                let (l, f) = lines.fields("a node line `tag x y z`")?;
                let tag = lines.usize_at(&f, 0, l, "node tag")?;
                let p = lines.point(&f, 1, l)?;
                add_node(lines, tag, p, l, &mut positions, &mut map)?;
            }
        }
    }
    if positions.len() != n {
        return Err(parse_error(
            lines.name,
            l,
            format!(
                "header announces {n} nodes, blocks hold {}",
                positions.len()
            ),
        ));
    }
    Ok((positions, map))
}

/// Looks up the four node tags of a tetrahedron in fields `f[at..at + 4]`; exactly four must follow.
fn tet_nodes(
    lines: &Lines,
    f: &[&str],
    at: usize,
    l: usize,
    map: &HashMap<usize, usize>,
) -> Result<[usize; 4], TetReadError> {
    if f.len() != at + 4 {
        return Err(parse_error(
            lines.name,
            l,
            format!(
                "a 4-node tetrahedron needs 4 node tags, found {}",
                f.len().saturating_sub(at)
            ),
        ));
    }
    let mut t = [0; 4];
    for (k, v) in t.iter_mut().enumerate() {
        let tag = lines.usize_at(f, at + k, l, "node tag")?;
        *v = *map.get(&tag).ok_or_else(|| {
            parse_error(
                lines.name,
                l,
                format!("tetrahedron names node tag {tag}, which `$Nodes` does not define"),
            )
        })?;
    }
    Ok(t)
}

/// v2: `n`, then `n` lines `tag type ntags tags… nodes…`.
fn elements_v2(
    lines: &mut Lines,
    map: &HashMap<usize, usize>,
) -> Result<Vec<[usize; 4]>, TetReadError> {
    let (l, f) = lines.fields("the element count")?;
    let n = lines.usize_at(&f, 0, l, "element count")?;
    let mut tets = Vec::with_capacity(capacity(n, lines.len));
    for _ in 0..n {
        let (l, f) = lines.fields("an element line `tag type ntags tags… nodes…`")?;
        let ty = lines.usize_at(&f, 1, l, "element type")?;
        let ntags = lines.usize_at(&f, 2, l, "number of tags")?;
        if ty == GMSH_TET4 {
            let at = ntags
                .checked_add(3)
                .filter(|&a| a <= f.len())
                .ok_or_else(|| {
                    parse_error(
                        lines.name,
                        l,
                        format!("element announces {ntags} tags but the line is shorter"),
                    )
                })?;
            tets.push(tet_nodes(lines, &f, at, l, map)?);
        }
    }
    Ok(tets)
}

/// v4: `blocks n [min max]`, per block `dim entity type count` (4.1) or `entity dim type count` (4.0), then
/// `count` lines `tag nodes…`.
fn elements_v4(
    lines: &mut Lines,
    map: &HashMap<usize, usize>,
) -> Result<Vec<[usize; 4]>, TetReadError> {
    let (l, f) = lines.fields("the `$Elements` header")?;
    let blocks = lines.usize_at(&f, 0, l, "entity block count")?;
    let n = lines.usize_at(&f, 1, l, "element count")?;
    let mut tets = Vec::new();
    let mut seen = 0usize;
    for _ in 0..blocks {
        let (l, f) = lines.fields("an element block header `dim entity type count`")?;
        let ty = lines.usize_at(&f, 2, l, "element type")?;
        let count = lines.usize_at(&f, 3, l, "number of elements in the block")?;
        seen = seen.saturating_add(count);
        if seen > n {
            return Err(parse_error(
                lines.name,
                l,
                format!("element blocks hold more than the {n} elements announced"),
            ));
        }
        for _ in 0..count {
            let (l, f) = lines.fields("an element line `tag nodes…`")?;
            if ty == GMSH_TET4 {
                tets.push(tet_nodes(lines, &f, 1, l, map)?);
            }
        }
    }
    if seen != n {
        return Err(parse_error(
            lines.name,
            l,
            format!("header announces {n} elements, blocks hold {seen}"),
        ));
    }
    Ok(tets)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::body::tet_io::fixtures::{cube, truncations};
    use std::fmt::Write;

    /// The cube as MSH 2.2 with node tags 1..8, a triangle element to skip and a `$PhysicalNames` section.
    pub(crate) fn cube_v2() -> String {
        let (p, t) = cube();
        let mut s = String::from(
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"body\"\n$EndPhysicalNames\n",
        );
        writeln!(s, "$Nodes\n{}", p.len()).unwrap();
        for (i, q) in p.iter().enumerate() {
            writeln!(s, "{} {} {} {}", i + 1, q.x, q.y, q.z).unwrap();
        }
        writeln!(s, "$EndNodes\n$Elements\n{}", t.len() + 1).unwrap();
        writeln!(s, "1 2 2 0 1 1 2 4").unwrap();
        for (i, e) in t.iter().enumerate() {
            writeln!(
                s,
                "{} 4 2 1 1 {} {} {} {}",
                i + 2,
                e[0] + 1,
                e[1] + 1,
                e[2] + 1,
                e[3] + 1
            )
            .unwrap();
        }
        s.push_str("$EndElements\n");
        s
    }

    /// The cube as MSH 4.1 with node tags `100 + 7i` in two entity blocks and a triangle block.
    fn cube_v4() -> String {
        let (p, t) = cube();
        let tag = |i: usize| 100 + 7 * i;
        let mut s = String::from(
            "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 0 1\n1 0 0 0 1 1 1 0 0\n$EndEntities\n",
        );
        writeln!(s, "$Nodes\n2 8 {} {}", tag(0), tag(7)).unwrap();
        for (block, range) in [(0, 0..3), (1, 3..8)] {
            writeln!(s, "3 {} 0 {}", block + 1, range.len()).unwrap();
            for i in range.clone() {
                writeln!(s, "{}", tag(i)).unwrap();
            }
            for i in range {
                writeln!(s, "{} {} {}", p[i].x, p[i].y, p[i].z).unwrap();
            }
        }
        writeln!(
            s,
            "$EndNodes\n$Elements\n2 {} 1 {}",
            t.len() + 1,
            t.len() + 1
        )
        .unwrap();
        writeln!(s, "2 1 2 1\n1 {} {} {}", tag(0), tag(1), tag(3)).unwrap();
        writeln!(s, "3 1 4 {}", t.len()).unwrap();
        for (i, e) in t.iter().enumerate() {
            writeln!(
                s,
                "{} {} {} {} {}",
                i + 2,
                tag(e[0]),
                tag(e[1]),
                tag(e[2]),
                tag(e[3])
            )
            .unwrap();
        }
        s.push_str("$EndElements\n");
        s
    }

    fn err(text: &str) -> String {
        match msh_from_str(text, "t.msh") {
            Ok(_) => panic!("parsed:\n{text}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn tet_io_msh_v2_cube() {
        let (p, t) = cube();
        let m = msh_from_str(&cube_v2(), "cube.msh").unwrap();
        assert_eq!(m.positions, p);
        assert_eq!(m.tets, t);
        assert!((m.volume() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn tet_io_msh_v4_cube_with_non_contiguous_tags() {
        let (p, t) = cube();
        let m = msh_from_str(&cube_v4(), "cube.msh").unwrap();
        assert_eq!(m.positions, p);
        assert_eq!(m.tets, t);
    }

    #[test]
    fn tet_io_msh_v40_node_lines() {
        let text = "$MeshFormat\n4 0 8\n$EndMeshFormat\n$Nodes\n1 4\n1 3 0 4\n10 0 0 0\n20 1 0 0\n30 0 1 0\n40 0 0 1\n$EndNodes\n$Elements\n1 1\n1 3 4 1\n5 10 20 30 40\n$EndElements\n";
        let m = msh_from_str(text, "t.msh").unwrap();
        assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
    }

    #[test]
    fn tet_io_msh_binary_is_refused() {
        let e = err("$MeshFormat\n4.1 1 8\n\u{1}\0\0\0\n$EndMeshFormat\n");
        assert!(
            e.contains("binary .msh is not supported; save as ASCII") && e.contains("line 2"),
            "{e}"
        );
    }

    #[test]
    fn tet_io_msh_bad_inputs_name_line_and_problem() {
        let good = cube_v2();
        let cases: Vec<(String, &str)> = vec![
            (good.replace("2.2 0 8", "3.0 0 8"), "version 3.0"),
            (good.replace("1 0 0 0\n", "1 nan 0 0\n"), "x is not finite"),
            (good.replace("4 1 1 0\n", "4 1 1 zz\n"), "expected z"),
            (good.replace("\n8\n", "\n9\n"), "section ends early"),
            (
                good.replace("3 0 1 0\n", "3 0 1 0\n3 0 0 1\n"),
                "node tag 3 appears twice",
            ),
            (good.replace(" 1 1 1 ", " 1 1 99 "), "node tag 99"),
            (good.replace("$EndElements\n", ""), "no `$EndElements`"),
            (
                good.replace("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n", ""),
                "`$MeshFormat` must come first",
            ),
        ];
        for (text, want) in cases {
            let e = err(&text);
            assert!(e.contains(want), "expected `{want}` in: {e}");
        }
        // An element line with five nodes for type 4.
        let extra = good.replace("$EndElements", "8 4 0 1 2 3 4 5\n$EndElements");
        let e = err(&extra);
        assert!(e.contains("line 28: expected `$EndElements`"), "{e}");
        let e = err(&extra.replace("\n7\n", "\n8\n"));
        assert!(
            e.contains("line 28: a 4-node tetrahedron needs 4 node tags, found 5"),
            "{e}"
        );
    }

    #[test]
    fn tet_io_msh_inverted_tet_is_rejected_by_name() {
        let (_, t) = cube();
        let [a, b, c, d] = t[2].map(|v| v + 1);
        let line = format!("4 4 2 1 1 {a} {b} {c} {d}\n");
        let swapped = format!("4 4 2 1 1 {b} {a} {c} {d}\n");
        assert!(cube_v2().contains(&line));
        let e = msh_from_str(&cube_v2().replace(&line, &swapped), "t.msh").unwrap_err();
        assert!(
            matches!(
                e,
                TetReadError::Mesh {
                    source: crate::TetMeshError::Inverted { tet: 2, .. },
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("tetrahedron 2"), "{e}");
    }

    #[test]
    fn tet_io_msh_truncation_never_panics() {
        for (seed, text) in [(1, cube_v2()), (2, cube_v4())] {
            truncations(&text, seed, 300, |s| {
                let r = msh_from_str(s, "cut.msh");
                // A cut before the closing `$EndElements` must be an error.
                if !s.contains("$EndElements") {
                    assert!(r.is_err(), "prefix of {} bytes parsed", s.len());
                }
            });
        }
    }
}
