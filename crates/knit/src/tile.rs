//! Tiling a periodic pattern into a finite patch of `nx × ny` cells: every cell holds a copy of the
//! pattern's vertices shifted by whole periods; the periodic edges join the copies into continuous yarns,
//! and edges that would leave the patch are cut, so each yarn ends at the patch border (or closes on
//! itself when it lies inside the patch). Yarns are written as OBJ `l` polylines.

use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::pyp::PeriodicPattern;

/// One continuous yarn of a patch: a polyline with the rod rest data of its edges and interior vertices.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Yarn {
    /// Vertex positions (m).
    pub positions: Vec<[f64; 3]>,
    /// For every vertex: the pattern vertex and the cell `[cx, cy]` it is a copy of.
    pub source: Vec<(usize, [i32; 2])>,
    /// Whether the last vertex joins the first (a loop inside the patch); then there are as many edges as
    /// vertices, otherwise one fewer.
    pub closed: bool,
    /// Material angle of each edge (rad).
    pub twist: Vec<f64>,
    /// Rest length of each edge (m).
    pub rest_length: Vec<f64>,
    /// Reference director of each edge (unit).
    pub reference_director: Vec<[f64; 3]>,
    /// Rest curvature at each vertex joining two edges of this yarn (dimensionless), indexed by the vertex;
    /// `None` at the two ends of an open yarn.
    pub rest_curvature: Vec<Option<[f64; 2]>>,
    /// Rest twist at each vertex joining two edges (rad); `None` at the ends.
    pub rest_twist: Vec<Option<f64>>,
    /// Reference twist at each vertex joining two edges (rad); `None` at the ends.
    pub reference_twist: Vec<Option<f64>>,
}

impl Yarn {
    /// Number of edges.
    pub fn edge_count(&self) -> usize {
        if self.closed {
            self.positions.len()
        } else {
            self.positions.len().saturating_sub(1)
        }
    }

    /// The vertices `(a, b)` of edge `k`.
    pub fn edge(&self, k: usize) -> (usize, usize) {
        (k, (k + 1) % self.positions.len())
    }

    /// Geometric length (m) of edge `k`.
    pub fn edge_length(&self, k: usize) -> f64 {
        let (a, b) = self.edge(k);
        let (p, q) = (self.positions[a], self.positions[b]);
        ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2)).sqrt()
    }
}

/// A patch of yarns.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Patch {
    /// Cells in x and y.
    pub cells: [usize; 2],
    /// Yarn radius (m).
    pub radius: f64,
    /// The yarns.
    pub yarns: Vec<Yarn>,
}

/// Errors of tiling.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum TileError {
    /// A patch needs at least one cell each way.
    #[error("a patch needs at least 1 × 1 cells, got {nx} × {ny}")]
    EmptyPatch {
        /// Cells in x.
        nx: usize,
        /// Cells in y.
        ny: usize,
    },
    /// Too many cells.
    #[error("{nx} × {ny} cells are too many (at most 10⁶ cells)")]
    TooLarge {
        /// Cells in x.
        nx: usize,
        /// Cells in y.
        ny: usize,
    },
}

/// Tiles `pattern` into `nx × ny` cells (cell `[cx, cy]` is the pattern shifted by `(cx px, cy py)`).
pub fn tile(pattern: &PeriodicPattern, nx: usize, ny: usize) -> Result<Patch, TileError> {
    if nx == 0 || ny == 0 {
        return Err(TileError::EmptyPatch { nx, ny });
    }
    if nx.saturating_mul(ny) > 1_000_000 {
        return Err(TileError::TooLarge { nx, ny });
    }
    let n = pattern.len();
    let id = |v: usize, cx: usize, cy: usize| v + n * (cx + nx * cy);
    let total = n * nx * ny;
    // Outgoing in-patch edge of every patch vertex (the pattern edge starting at its pattern vertex).
    let mut next = vec![None::<usize>; total];
    let mut has_prev = vec![false; total];
    for cy in 0..ny {
        for cx in 0..nx {
            for v in 0..n {
                let e = pattern.edges[v];
                let tx = cx as i64 + e.shift[0] as i64;
                let ty = cy as i64 + e.shift[1] as i64;
                if tx >= 0 && ty >= 0 && (tx as usize) < nx && (ty as usize) < ny {
                    let to = id(e.end, tx as usize, ty as usize);
                    next[id(v, cx, cy)] = Some(to);
                    has_prev[to] = true;
                }
            }
        }
    }
    let decode = |k: usize| (k % n, [((k / n) % nx) as i32, (k / (n * nx)) as i32]);
    let mut used = vec![false; total];
    let mut yarns = Vec::new();
    let follow = |start: usize, used: &mut Vec<bool>| -> (Vec<usize>, bool) {
        let mut chain = vec![start];
        used[start] = true;
        let mut k = start;
        while let Some(to) = next[k] {
            if to == start {
                return (chain, true);
            }
            if used[to] {
                break;
            }
            used[to] = true;
            chain.push(to);
            k = to;
        }
        (chain, false)
    };
    // Open yarns start where no in-patch edge arrives; what is left are loops.
    for k in 0..total {
        if !has_prev[k] && !used[k] {
            let (chain, closed) = follow(k, &mut used);
            yarns.push(build_yarn(pattern, &chain, closed, &decode));
        }
    }
    for k in 0..total {
        if !used[k] {
            let (chain, closed) = follow(k, &mut used);
            yarns.push(build_yarn(pattern, &chain, closed, &decode));
        }
    }
    Ok(Patch {
        cells: [nx, ny],
        radius: pattern.radius,
        yarns,
    })
}

fn build_yarn(
    pattern: &PeriodicPattern,
    chain: &[usize],
    closed: bool,
    decode: &impl Fn(usize) -> (usize, [i32; 2]),
) -> Yarn {
    let source: Vec<(usize, [i32; 2])> = chain.iter().map(|&k| decode(k)).collect();
    let positions = source
        .iter()
        .map(|&(v, c)| {
            let o = pattern.shift_offset(c);
            let p = pattern.positions[v];
            [p[0] + o[0], p[1] + o[1], p[2] + o[2]]
        })
        .collect();
    let edges = if closed {
        source.len()
    } else {
        source.len() - 1
    };
    let edge_sources = &source[..edges];
    let interior = |i: usize| closed || (i > 0 && i + 1 < source.len());
    Yarn {
        positions,
        closed,
        twist: edge_sources
            .iter()
            .map(|&(v, _)| pattern.twist[v])
            .collect(),
        rest_length: edge_sources
            .iter()
            .map(|&(v, _)| pattern.rest_length[v])
            .collect(),
        reference_director: edge_sources
            .iter()
            .map(|&(v, _)| pattern.reference_director[v])
            .collect(),
        rest_curvature: (0..source.len())
            .map(|i| interior(i).then(|| pattern.rest_curvature[source[i].0]))
            .collect(),
        rest_twist: (0..source.len())
            .map(|i| interior(i).then(|| pattern.rest_twist[source[i].0]))
            .collect(),
        reference_twist: (0..source.len())
            .map(|i| interior(i).then(|| pattern.reference_twist[source[i].0]))
            .collect(),
        source,
    }
}

/// The `nx × ny` tiling of `pattern` as one larger periodic pattern (a supercell): vertex `v` of cell
/// `[cx, cy]` becomes vertex `v + n (cx + nx cy)`, edges that leave the block wrap around it with the
/// supercell's periodic shifts, the period is `(nx px, ny py)`, and all rest data are copied. Equilibria of
/// the cell tile into equilibria of the supercell.
pub fn supercell(
    pattern: &PeriodicPattern,
    nx: usize,
    ny: usize,
) -> Result<PeriodicPattern, TileError> {
    if nx == 0 || ny == 0 {
        return Err(TileError::EmptyPatch { nx, ny });
    }
    if nx.saturating_mul(ny) > 1_000_000 {
        return Err(TileError::TooLarge { nx, ny });
    }
    let n = pattern.len();
    let mut out = PeriodicPattern {
        period: [pattern.period[0] * nx as f64, pattern.period[1] * ny as f64],
        radius: pattern.radius,
        positions: Vec::with_capacity(n * nx * ny),
        twist: Vec::new(),
        edges: Vec::new(),
        rest_length: Vec::new(),
        rest_curvature: Vec::new(),
        rest_twist: Vec::new(),
        reference_director: Vec::new(),
        reference_twist: Vec::new(),
    };
    for cy in 0..ny {
        for cx in 0..nx {
            let o = pattern.shift_offset([cx as i32, cy as i32]);
            for v in 0..n {
                let p = pattern.positions[v];
                out.positions.push([p[0] + o[0], p[1] + o[1], p[2] + o[2]]);
                let e = pattern.edges[v];
                let tx = cx as i64 + e.shift[0] as i64;
                let ty = cy as i64 + e.shift[1] as i64;
                let (wx, wy) = (tx.rem_euclid(nx as i64), ty.rem_euclid(ny as i64));
                out.edges.push(crate::pyp::PeriodicEdge {
                    start: v + n * (cx + nx * cy),
                    end: e.end + n * (wx as usize + nx * wy as usize),
                    shift: [
                        tx.div_euclid(nx as i64) as i32,
                        ty.div_euclid(ny as i64) as i32,
                    ],
                });
            }
            out.twist.extend_from_slice(&pattern.twist);
            out.rest_length.extend_from_slice(&pattern.rest_length);
            out.rest_curvature
                .extend_from_slice(&pattern.rest_curvature);
            out.rest_twist.extend_from_slice(&pattern.rest_twist);
            out.reference_director
                .extend_from_slice(&pattern.reference_director);
            out.reference_twist
                .extend_from_slice(&pattern.reference_twist);
        }
    }
    Ok(out)
}

impl Patch {
    /// Total number of yarn vertices.
    pub fn vertex_count(&self) -> usize {
        self.yarns.iter().map(|y| y.positions.len()).sum()
    }

    /// The patch as Wavefront OBJ text: `v x y z` lines (m) and one `l` polyline per yarn (a closed yarn
    /// repeats its first vertex at the end).
    pub fn to_obj(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "# skintight knit patch: {} x {} cells, {} yarns, yarn radius {} m",
            self.cells[0],
            self.cells[1],
            self.yarns.len(),
            self.radius
        );
        for y in &self.yarns {
            for p in &y.positions {
                let _ = writeln!(out, "v {} {} {}", p[0], p[1], p[2]);
            }
        }
        let mut base = 1;
        for y in &self.yarns {
            let mut line = String::from("l");
            for k in 0..y.positions.len() {
                let _ = write!(line, " {}", base + k);
            }
            if y.closed {
                let _ = write!(line, " {base}");
            }
            let _ = writeln!(out, "{line}");
            base += y.positions.len();
        }
        out
    }

    /// Writes [`Patch::to_obj`] to `path`.
    pub fn write_obj(&self, path: &Path) -> std::io::Result<()> {
        std::fs::write(path, self.to_obj())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{PATTERNS, shared_yarns_dir};

    fn pattern(name: &str) -> PeriodicPattern {
        PeriodicPattern::read(&shared_yarns_dir().join(name).join("pattern.pyp")).unwrap()
    }

    /// Open yarns of a patch, counted from the other direction: patch vertices whose incoming pattern edge
    /// starts outside the patch.
    fn expected_open_yarns(p: &PeriodicPattern, nx: usize, ny: usize) -> usize {
        let prev = p.previous_edges();
        let mut count = 0;
        for cy in 0..ny as i32 {
            for cx in 0..nx as i32 {
                for v in 0..p.len() {
                    let s = p.edges[prev[v]].shift;
                    let (fx, fy) = (cx - s[0], cy - s[1]);
                    if fx < 0 || fy < 0 || fx >= nx as i32 || fy >= ny as i32 {
                        count += 1;
                    }
                }
            }
        }
        count
    }

    #[test]
    fn tiles_every_pattern_into_continuous_yarns() {
        for name in PATTERNS {
            let p = pattern(name);
            let (nx, ny) = (3, 2);
            let patch = tile(&p, nx, ny).unwrap();
            assert_eq!(patch.vertex_count(), p.len() * nx * ny, "{name}");
            let open = patch.yarns.iter().filter(|y| !y.closed).count();
            assert_eq!(open, expected_open_yarns(&p, nx, ny), "{name}");
            // Loops only come from cycles that close inside one cell.
            let in_cell_loops = p.yarn_cycles().iter().filter(|(_, s)| *s == [0, 0]).count();
            let closed = patch.yarns.len() - open;
            assert!(closed <= in_cell_loops * nx * ny, "{name}: {closed} loops");
            // Cutting only happens at the border: a 1 × 1 patch has at least as many pieces as a 3 × 2 one has
            // per cell on its border, and the interior of a large patch holds long yarns.
            let longest = patch.yarns.iter().map(|y| y.positions.len()).max().unwrap();
            assert!(
                longest >= p.len() / p.yarn_cycles().len().max(1),
                "{name}: longest yarn {longest}"
            );
            for y in &patch.yarns {
                assert_eq!(y.twist.len(), y.edge_count());
                assert_eq!(y.rest_length.len(), y.edge_count());
                for k in 0..y.edge_count() {
                    // Every patch edge is a pattern edge: same geometric length, same rest length.
                    let v = y.source[k].0;
                    assert!((y.edge_length(k) - p.edge_length(v)).abs() < 1e-12 * p.edge_length(v));
                    assert_eq!(y.rest_length[k], p.rest_length[v]);
                }
                if !y.closed {
                    assert!(
                        y.rest_curvature[0].is_none() && y.rest_curvature.last().unwrap().is_none()
                    );
                }
            }
        }
    }

    #[test]
    fn rest_lengths_match_geometric_lengths_of_the_tiled_yarns() {
        for name in ["stock_9", "rib_9", "satin_9"] {
            let patch = tile(&pattern(name), 2, 2).unwrap();
            for y in &patch.yarns {
                for k in 0..y.edge_count() {
                    let rel = y.edge_length(k) / y.rest_length[k] - 1.0;
                    assert!(rel.abs() < 0.003, "{name}: {rel}");
                }
            }
        }
    }

    #[test]
    fn supercell_keeps_edge_geometry_and_yarn_count() {
        for name in PATTERNS {
            let p = pattern(name);
            let s = supercell(&p, 3, 2).unwrap();
            assert_eq!(s.len(), 6 * p.len());
            for i in 0..s.len() {
                let v = i % p.len();
                assert!(
                    (s.edge_length(i) - p.edge_length(v)).abs() < 1e-12 * p.edge_length(v),
                    "{name} edge {i}"
                );
                assert_eq!(s.edges[i].start, i);
            }
            let ends: std::collections::HashSet<usize> = s.edges.iter().map(|e| e.end).collect();
            assert_eq!(ends.len(), s.len());
        }
    }

    #[test]
    fn obj_has_one_polyline_per_yarn_and_bad_sizes_are_errors() {
        let patch = tile(&pattern("stocktiniest_9"), 2, 3).unwrap();
        let obj = patch.to_obj();
        assert_eq!(
            obj.lines().filter(|l| l.starts_with("v ")).count(),
            patch.vertex_count()
        );
        assert_eq!(
            obj.lines().filter(|l| l.starts_with("l ")).count(),
            patch.yarns.len()
        );
        let max_index: usize = obj
            .lines()
            .filter(|l| l.starts_with("l "))
            .flat_map(|l| {
                l[2..]
                    .split_whitespace()
                    .map(|t| t.parse::<usize>().unwrap())
            })
            .max()
            .unwrap();
        assert_eq!(max_index, patch.vertex_count());
        assert_eq!(
            tile(&pattern("stocktiniest_9"), 0, 3).unwrap_err(),
            TileError::EmptyPatch { nx: 0, ny: 3 }
        );
    }
}
