//! Reader of periodic yarn patterns (`.pyp`, the text format of HYLC/MADYPG; Sperl et al. 2020, 2021).
//!
//! A `.pyp` file describes one period of a yarn pattern as discrete elastic rods at rest, in sections that
//! start with a `*name` header line; `#` starts a comment, blank lines are ignored:
//!
//! - `*pattern`: one line `px py radius n`: the period in x and y (m), the yarn radius (m), the vertex count;
//! - `*Q`: `n` lines `x y z t`: vertex positions (m) and the twist (material frame angle, rad) of the edge
//!   that starts at the vertex;
//! - `*E`: `n` lines `v0 v1 dx dy`: the edge from vertex `v0` to vertex `v1` shifted by `dx` periods in x and
//!   `dy` in y. The lines come in any order; the edge is identified by `v0` (every vertex starts exactly one
//!   edge, and ends exactly one: the yarns are closed loops of the periodic cell);
//! - `*RL` (rest length, m), `*RK` (rest curvature, 2 material components, dimensionless: the integrated
//!   curvature `2 tan(φ/2)` of Bergou et al. 2008), `*RT` (rest twist, rad), `*RefD1` (reference director
//!   `d1` of the edge, unit 3-vector), `*RefT` (reference twist, rad): one line per vertex `i`, for vertex `i`
//!   or for the edge that **starts** at vertex `i` (matched through `*E`'s `v0`, not by line order: see
//!   `shared/data/yarns/README.md`).
//!
//! Every problem is a [`PypError`] naming the file, the line and how to fix it; nothing panics on bad input.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// An error reading a `.pyp` file: the file, the 1-based line (0 when the problem is not on one line) and
/// what is wrong.
#[derive(Clone, Debug, Error, PartialEq)]
#[error("{}:{line}: {problem}", path.display())]
pub struct PypError {
    /// The file read.
    pub path: PathBuf,
    /// 1-based line of the problem; 0 for the file as a whole.
    pub line: usize,
    /// What is wrong, and how to fix it.
    pub problem: String,
}

/// One edge of the periodic cell: from `start` to the periodic image of `end` shifted by `shift` periods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PeriodicEdge {
    /// Vertex the edge starts at (also the edge's index: edge `i` starts at vertex `i`).
    pub start: usize,
    /// Vertex the edge ends at (in the cell shifted by `shift`).
    pub end: usize,
    /// Periodic shift of `end`, in periods `(x, y)`.
    pub shift: [i32; 2],
}

/// A periodic yarn pattern at rest. Edge `i` starts at vertex `i`; per-vertex rest data (`rest_curvature`,
/// `rest_twist`, `reference_twist`) belong to the vertex `i` joining the edge that ends there
/// ([`PeriodicPattern::previous_edge`]) and edge `i`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PeriodicPattern {
    /// Period `[px, py]` (m).
    pub period: [f64; 2],
    /// Yarn radius (m).
    pub radius: f64,
    /// Vertex positions (m).
    pub positions: Vec<[f64; 3]>,
    /// Material frame angle of edge `i` relative to its reference frame (rad).
    pub twist: Vec<f64>,
    /// Edge `i`, from vertex `i`.
    pub edges: Vec<PeriodicEdge>,
    /// Rest length of edge `i` (m).
    pub rest_length: Vec<f64>,
    /// Rest material curvature `(κ₁, κ₂)` at vertex `i` (dimensionless integrated curvature).
    pub rest_curvature: Vec<[f64; 2]>,
    /// Rest twist at vertex `i` (rad).
    pub rest_twist: Vec<f64>,
    /// Reference director `d1` of edge `i` (unit, perpendicular to the edge).
    pub reference_director: Vec<[f64; 3]>,
    /// Reference twist at vertex `i` (rad): the angle from the space-parallel transport of the previous
    /// edge's reference director to edge `i`'s, about edge `i`'s tangent.
    pub reference_twist: Vec<f64>,
}

/// A section's lines: (1-based line number, numbers).
type Rows = Vec<(usize, Vec<f64>)>;

impl PeriodicPattern {
    /// Reads and checks a `.pyp` file.
    pub fn read(path: &Path) -> Result<Self, PypError> {
        let text = std::fs::read_to_string(path).map_err(|e| PypError {
            path: path.to_path_buf(),
            line: 0,
            problem: format!("cannot read the file ({e}); check the path of the pattern"),
        })?;
        Self::parse(&text, path)
    }

    /// Parses `.pyp` text; `path` only names the source in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, PypError> {
        let err = |line: usize, problem: String| PypError {
            path: path.to_path_buf(),
            line,
            problem,
        };
        // Split into sections.
        let mut sections: Vec<(String, usize, Rows)> = Vec::new();
        for (k, raw) in text.lines().enumerate() {
            let line_no = k + 1;
            let content = raw.split('#').next().unwrap_or("").trim();
            if content.is_empty() {
                continue;
            }
            if let Some(name) = content.strip_prefix('*') {
                let name = name.split_whitespace().next().unwrap_or("").to_string();
                if sections.iter().any(|(n, _, _)| *n == name) {
                    return Err(err(
                        line_no,
                        format!("section *{name} appears twice; keep one"),
                    ));
                }
                sections.push((name, line_no, Vec::new()));
                continue;
            }
            let Some((name, _, rows)) = sections.last_mut() else {
                return Err(err(
                    line_no,
                    "numbers before the first section header; start the file with `*pattern`"
                        .into(),
                ));
            };
            let mut numbers = Vec::new();
            for token in content.split_whitespace() {
                let value: f64 = token.parse().map_err(|_| {
                    err(
                        line_no,
                        format!("`{token}` in section *{name} is not a number"),
                    )
                })?;
                if !value.is_finite() {
                    return Err(err(
                        line_no,
                        format!("`{token}` in section *{name} is not a finite number"),
                    ));
                }
                numbers.push(value);
            }
            rows.push((line_no, numbers));
        }
        let section = |name: &str| -> Result<(usize, &Rows), PypError> {
            sections
                .iter()
                .find(|(n, _, _)| n == name)
                .map(|(_, l, r)| (*l, r))
                .ok_or_else(|| {
                    err(
                        0,
                        format!(
                            "missing section *{name}; a pattern needs *pattern, *Q, *E, *RL, *RK, *RT, \
                             *RefD1 and *RefT"
                        ),
                    )
                })
        };
        // Columns and row counts of a data section.
        let table = |name: &str, columns: usize, n: usize| -> Result<&Rows, PypError> {
            let (header, rows) = section(name)?;
            for (line, numbers) in rows {
                if numbers.len() != columns {
                    return Err(err(
                        *line,
                        format!(
                            "section *{name} needs {columns} numbers per line, this line has {}",
                            numbers.len()
                        ),
                    ));
                }
            }
            if rows.len() != n {
                return Err(err(
                    header,
                    format!(
                        "section *{name} has {} lines but *pattern declares {n} vertices; the counts \
                         must agree",
                        rows.len()
                    ),
                ));
            }
            Ok(rows)
        };

        let (pattern_line, pattern_rows) = section("pattern")?;
        let Some((line, header)) = pattern_rows.first() else {
            return Err(err(
                pattern_line,
                "section *pattern is empty; it needs one line `px py radius n`".into(),
            ));
        };
        if header.len() != 4 || pattern_rows.len() != 1 {
            return Err(err(
                *line,
                format!(
                    "section *pattern needs exactly one line of 4 numbers `px py radius n`, found {} \
                     line(s), the first with {} numbers",
                    pattern_rows.len(),
                    header.len()
                ),
            ));
        }
        let (px, py, radius, n_raw) = (header[0], header[1], header[2], header[3]);
        for (what, v) in [("period px", px), ("period py", py), ("radius", radius)] {
            if v <= 0.0 {
                return Err(err(
                    *line,
                    format!("the {what} is {v} m; it must be positive"),
                ));
            }
        }
        if n_raw < 2.0 || n_raw.fract() != 0.0 || n_raw > 1e8 {
            return Err(err(
                *line,
                format!("the vertex count is {n_raw}; it must be a whole number ≥ 2"),
            ));
        }
        let n = n_raw as usize;

        let q = table("Q", 4, n)?;
        let e = table("E", 4, n)?;
        let rl = table("RL", 1, n)?;
        let rk = table("RK", 2, n)?;
        let rt = table("RT", 1, n)?;
        let d1 = table("RefD1", 3, n)?;
        let reft = table("RefT", 1, n)?;

        let as_index = |line: usize, v: f64, what: &str, limit: Option<usize>| {
            if v.fract() != 0.0 || !(-1e9..=1e9).contains(&v) {
                return Err(err(line, format!("the {what} {v} is not a whole number")));
            }
            if let Some(limit) = limit
                && (v < 0.0 || v as usize >= limit)
            {
                return Err(err(
                    line,
                    format!(
                        "the {what} {v} names a vertex that does not exist (vertices are 0..{}); fix the \
                         edge or the vertex count",
                        limit - 1
                    ),
                ));
            }
            Ok(v as i64)
        };
        let mut edges: Vec<Option<(PeriodicEdge, usize)>> = vec![None; n];
        let mut ends = vec![None::<usize>; n];
        for (line, row) in e {
            let start = as_index(*line, row[0], "edge start v0", Some(n))? as usize;
            let end = as_index(*line, row[1], "edge end v1", Some(n))? as usize;
            let sx = as_index(*line, row[2], "periodic shift dx", None)?;
            let sy = as_index(*line, row[3], "periodic shift dy", None)?;
            if let Some((_, first)) = edges[start] {
                return Err(err(
                    *line,
                    format!(
                        "vertex {start} starts a second edge (the first is on line {first}); every vertex \
                         starts exactly one edge"
                    ),
                ));
            }
            if let Some(first) = ends[end] {
                return Err(err(
                    *line,
                    format!(
                        "vertex {end} ends a second edge (the first is on line {first}); every vertex ends \
                         exactly one edge"
                    ),
                ));
            }
            if start == end && sx == 0 && sy == 0 {
                return Err(err(
                    *line,
                    format!(
                        "edge from vertex {start} to itself without a periodic shift has zero length"
                    ),
                ));
            }
            ends[end] = Some(*line);
            edges[start] = Some((
                PeriodicEdge {
                    start,
                    end,
                    shift: [sx as i32, sy as i32],
                },
                *line,
            ));
        }
        // n lines, no vertex starts two edges ⇒ every vertex starts one.
        let edges: Vec<PeriodicEdge> = edges.into_iter().flatten().map(|(e, _)| e).collect();

        let positions: Vec<[f64; 3]> = q.iter().map(|(_, r)| [r[0], r[1], r[2]]).collect();
        let twist = q.iter().map(|(_, r)| r[3]).collect();
        let mut rest_length = Vec::with_capacity(n);
        for (line, r) in rl {
            if r[0] <= 0.0 {
                return Err(err(
                    *line,
                    format!("rest length {} m is not positive", r[0]),
                ));
            }
            rest_length.push(r[0]);
        }
        let mut reference_director = Vec::with_capacity(n);
        for (line, r) in d1 {
            let norm = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
            if (norm - 1.0).abs() > 1e-3 {
                return Err(err(
                    *line,
                    format!("reference director has length {norm}; it must be a unit vector"),
                ));
            }
            reference_director.push([r[0] / norm, r[1] / norm, r[2] / norm]);
        }
        let pattern = PeriodicPattern {
            period: [px, py],
            radius,
            positions,
            twist,
            edges,
            rest_length,
            rest_curvature: rk.iter().map(|(_, r)| [r[0], r[1]]).collect(),
            rest_twist: rt.iter().map(|(_, r)| r[0]).collect(),
            reference_director,
            reference_twist: reft.iter().map(|(_, r)| r[0]).collect(),
        };
        // Zero-length edges make tangents undefined.
        for i in 0..n {
            let len = pattern.edge_length(i);
            if len <= 1e-12 * (px + py) {
                return Err(err(
                    0,
                    format!("edge {i} (from vertex {i}) has zero length; two vertices coincide"),
                ));
            }
        }
        Ok(pattern)
    }

    /// Number of vertices (= number of edges).
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether the pattern has no vertices (never true for a parsed pattern).
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The in-plane offset (m) of the periodic shift `s` (periods): `(s_x px, s_y py, 0)`.
    pub fn shift_offset(&self, s: [i32; 2]) -> [f64; 3] {
        [
            s[0] as f64 * self.period[0],
            s[1] as f64 * self.period[1],
            0.0,
        ]
    }

    /// Position (m) of the end of edge `i` (its end vertex in the shifted cell).
    pub fn edge_end_position(&self, i: usize) -> [f64; 3] {
        let e = self.edges[i];
        let o = self.shift_offset(e.shift);
        let p = self.positions[e.end];
        [p[0] + o[0], p[1] + o[1], p[2] + o[2]]
    }

    /// Current geometric length (m) of edge `i`.
    pub fn edge_length(&self, i: usize) -> f64 {
        let a = self.positions[i];
        let b = self.edge_end_position(i);
        ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
    }

    /// The edge ending at vertex `i` (the previous edge along the yarn).
    pub fn previous_edge(&self, i: usize) -> usize {
        self.previous_edges()[i]
    }

    /// For every vertex, the edge that ends there.
    pub fn previous_edges(&self) -> Vec<usize> {
        let mut prev = vec![0; self.len()];
        for e in &self.edges {
            prev[e.end] = e.start;
        }
        prev
    }

    /// The yarns of the cell: each a closed cycle of vertex indices following the edges, together with the
    /// total periodic shift accumulated around the cycle (the yarn's period in cells; `[0, 0]` for a closed
    /// loop inside the cell).
    pub fn yarn_cycles(&self) -> Vec<(Vec<usize>, [i32; 2])> {
        let n = self.len();
        let mut seen = vec![false; n];
        let mut cycles = Vec::new();
        for first in 0..n {
            if seen[first] {
                continue;
            }
            let mut cycle = Vec::new();
            let mut shift = [0, 0];
            let mut v = first;
            while !seen[v] {
                seen[v] = true;
                cycle.push(v);
                let e = self.edges[v];
                shift[0] += e.shift[0];
                shift[1] += e.shift[1];
                v = e.end;
            }
            cycles.push((cycle, shift));
        }
        cycles
    }
}

#[cfg(test)]
mod tests;
