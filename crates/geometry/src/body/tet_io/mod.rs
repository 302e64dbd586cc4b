//! Tetrahedral mesh formats: readers for Gmsh `.msh` (ASCII v2 and v4), MEDIT `.mesh` and TetGen
//! `.node`/`.ele`, and the `.vtu` writer.
//!
//! Every reader returns a [`TetMesh`] that passed [`TetMesh::validate`] (with minimum quality 0): inverted
//! (negative signed volume) or flat tetrahedra in a file are rejected with an error naming the tetrahedron,
//! never silently reoriented. All vertices of the file are kept, in file order, including ones no
//! tetrahedron uses. No vertex is marked fixed. Coordinates are taken as metres.

pub mod medit;
pub mod msh;
pub mod tetgen;
pub mod vtu;

use std::path::Path;

pub use medit::{medit_from_str, read_medit};
pub use msh::{msh_from_str, read_msh};
pub use tetgen::{read_tetgen, tetgen_from_str};
pub use vtu::{VtuArray, VtuError, body_arrays, vtu_string, write_vtu};

use crate::body::tet_mesh::{TetMesh, TetMeshError};
use crate::math::Real;

/// Why a tetrahedral mesh file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum TetReadError {
    /// The file could not be opened or read.
    #[error("cannot read {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    /// A line of the file is malformed (bad number, wrong count, unknown index, …).
    #[error("{path}, line {line}: {message}")]
    Parse {
        path: String,
        line: usize,
        message: String,
    },
    /// The file as a whole cannot be used (truncated, missing section, unsupported variant).
    #[error("{path}: {message}")]
    Format { path: String, message: String },
    /// The mesh was read but is not usable (inverted or flat tetrahedron, …).
    #[error("{path}: {source}")]
    Mesh { path: String, source: TetMeshError },
}

/// Reads a tetrahedral mesh, choosing the format by extension: `.msh` (Gmsh ASCII v2/v4), `.mesh` (MEDIT),
/// `.node` or `.ele` (TetGen pair; the sibling file is found next to it).
pub fn read_tet_mesh(path: &Path) -> Result<TetMesh, TetReadError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "msh" => read_msh(path),
        "mesh" => read_medit(path),
        "node" | "ele" => read_tetgen(path),
        _ => Err(TetReadError::Format {
            path: path.display().to_string(),
            message: format!(
                "unknown tetrahedral mesh extension `.{ext}` (expected .msh, .mesh, .node or .ele)"
            ),
        }),
    }
}

/// Reads a whole file as text (invalid UTF-8 replaced, so binary content fails later with a parse error).
pub(crate) fn read_text(path: &Path) -> Result<String, TetReadError> {
    let bytes = std::fs::read(path).map_err(|source| TetReadError::Io {
        path: path.display().to_string(),
        source,
    })?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

/// Validates a mesh just read, attaching the file name to the error.
pub(crate) fn checked(mesh: TetMesh, name: &str) -> Result<TetMesh, TetReadError> {
    mesh.validate(0.0).map_err(|source| TetReadError::Mesh {
        path: name.to_string(),
        source,
    })?;
    Ok(mesh)
}

/// Whitespace-separated tokens with their 1-based line numbers; `comment` starts a comment to end of line.
pub(crate) struct Tokens<'a> {
    name: &'a str,
    tokens: Vec<(usize, &'a str)>,
    pos: usize,
}

impl<'a> Tokens<'a> {
    pub(crate) fn new(text: &'a str, name: &'a str, comment: Option<char>) -> Self {
        let mut tokens = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = match comment.and_then(|c| line.find(c)) {
                Some(k) => &line[..k],
                None => line,
            };
            tokens.extend(line.split_whitespace().map(|t| (i + 1, t)));
        }
        Self {
            name,
            tokens,
            pos: 0,
        }
    }

    /// The next token, or a "file ends" error saying what was expected.
    pub(crate) fn next(&mut self, what: &str) -> Result<(usize, &'a str), TetReadError> {
        let t = self
            .tokens
            .get(self.pos)
            .copied()
            .ok_or_else(|| TetReadError::Format {
                path: self.name.to_string(),
                message: format!("file ends early: expected {what}"),
            })?;
        self.pos += 1;
        Ok(t)
    }

    pub(crate) fn peek(&self) -> Option<(usize, &'a str)> {
        self.tokens.get(self.pos).copied()
    }

    pub(crate) fn usize(&mut self, what: &str) -> Result<usize, TetReadError> {
        let (line, t) = self.next(what)?;
        parse_usize(t, self.name, line, what)
    }

    pub(crate) fn real(&mut self, what: &str) -> Result<Real, TetReadError> {
        let (line, t) = self.next(what)?;
        parse_real(t, self.name, line, what)
    }

    pub(crate) fn error(&self, line: usize, message: String) -> TetReadError {
        parse_error(self.name, line, message)
    }
}

pub(crate) fn parse_error(name: &str, line: usize, message: String) -> TetReadError {
    TetReadError::Parse {
        path: name.to_string(),
        line,
        message,
    }
}

/// A non-negative integer field.
pub(crate) fn parse_usize(
    t: &str,
    name: &str,
    line: usize,
    what: &str,
) -> Result<usize, TetReadError> {
    t.parse::<usize>().map_err(|_| {
        parse_error(
            name,
            line,
            format!("expected {what} (a non-negative integer), found `{t}`"),
        )
    })
}

/// A finite real field.
pub(crate) fn parse_real(
    t: &str,
    name: &str,
    line: usize,
    what: &str,
) -> Result<Real, TetReadError> {
    match t.parse::<Real>() {
        Ok(x) if x.is_finite() => Ok(x),
        Ok(_) => Err(parse_error(
            name,
            line,
            format!("{what} is not finite (`{t}`)"),
        )),
        Err(_) => Err(parse_error(
            name,
            line,
            format!("expected {what} (a number), found `{t}`"),
        )),
    }
}

/// Caps a count read from a file before it is used to reserve memory (a corrupt count must not allocate
/// terabytes): no more entries than the file has tokens.
pub(crate) fn capacity(count: usize, text_len: usize) -> usize {
    count.min(text_len / 2 + 1)
}

#[cfg(test)]
pub(crate) mod fixtures {
    use crate::body::tet_mesh::tet_signed_volume;
    use crate::math::Vec3;

    /// The unit cube (vertex `x + 2y + 4z` at `(x, y, z)`) split into the six Kuhn tetrahedra along the
    /// diagonal 0 → 7, each positively oriented.
    pub(crate) fn cube() -> (Vec<Vec3>, Vec<[usize; 4]>) {
        let p: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
            .collect();
        let mut tets = Vec::new();
        for perm in [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ] {
            let a = 1 << perm[0];
            let b = a | (1 << perm[1]);
            let mut t = [0, a, b, 7];
            if tet_signed_volume(&p[t[0]], &p[t[1]], &p[t[2]], &p[t[3]]) < 0.0 {
                t.swap(2, 3);
            }
            tets.push(t);
        }
        (p, tets)
    }

    /// Cuts `text` at `n` seeded random byte positions (on char boundaries) and hands each prefix to `read`,
    /// which must return (Ok or Err), never panic.
    pub(crate) fn truncations(text: &str, seed: u64, n: usize, mut read: impl FnMut(&str)) {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..n {
            let mut cut = rng.random_range(0..=text.len());
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            read(&text[..cut]);
        }
        for cut in 0..text.len().min(400) {
            read(&text[..cut]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tet_io_dispatch_rejects_unknown_extension_and_missing_file() {
        let e = read_tet_mesh(Path::new("/nonexistent/body.stl")).unwrap_err();
        assert!(
            e.to_string().contains("unknown tetrahedral mesh extension"),
            "{e}"
        );
        let e = read_tet_mesh(Path::new("/nonexistent/body.msh")).unwrap_err();
        assert!(matches!(e, TetReadError::Io { .. }), "{e}");
    }

    #[test]
    fn tet_io_dispatch_reads_each_format_from_disk() {
        let (p, t) = fixtures::cube();
        let dir = std::env::temp_dir().join(format!("skintight_tet_io_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files = [
            ("cube.msh", msh::tests::cube_v2()),
            ("cube.mesh", medit::tests::cube_medit()),
        ];
        for (name, text) in files {
            let path = dir.join(name);
            std::fs::write(&path, text).unwrap();
            let m = read_tet_mesh(&path).unwrap();
            assert_eq!(m.positions, p, "{name}");
            assert_eq!(m.tets, t, "{name}");
        }
        let (node, ele) = tetgen::tests::cube_tetgen(1);
        std::fs::write(dir.join("cube.1.node"), node).unwrap();
        std::fs::write(dir.join("cube.1.ele"), ele).unwrap();
        for name in ["cube.1.node", "cube.1.ele"] {
            let m = read_tet_mesh(&dir.join(name)).unwrap();
            assert_eq!(m.tets, t, "{name}");
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
