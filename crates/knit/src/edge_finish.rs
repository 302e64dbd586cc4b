//! The finish of a patch's cut border: which cut yarn ends are bonded to the fabric, and where.
//!
//! A patch tiled from a periodic pattern ([`crate::tile`]) cuts every yarn that crosses its border. In the
//! periodic cell those yarns carry tension and bending moments across the cell boundary; cut, their ends
//! are free, and with frictionless contact nothing holds them: each cut course retracts through its loops
//! and the border unravels — a slow, large motion through thousands of contact changes that has no
//! equilibrium near the knitted state (issue 19: a hanging 4 × 4 stockinette patch with free ends does
//! not converge in 100 Newton iterations a step; with its 48 end vertices held, every step converges and
//! after the first, in about 3). A garment panel's edges are never left so: synthetic compression knits
//! are cut with a laser or ultrasound that fuses the yarn ends to the loops they pass through, or the
//! edge is overlocked or bonded.
//!
//! [`EdgeFinish::Bonded`] models such a fused edge: every end vertex `a` of a cut (open) yarn is tied to
//! the nearest vertex `b` of another yarn at the starting geometry by a link with the yarn's own axial
//! stiffness and the starting distance as its rest length —
//!
//! `E_bond = ½ k_s L̄ (|x_b − x_a|/L̄ − 1)²`,  `L̄ = |X_b − X_a|` (m), `k_s = E π r²` (N), `E_bond` in J —
//!
//! the stretching energy of one rod edge ([`crate::stretching::StretchingEdge`], whose derivatives are
//! derived and finite-difference tested there), so a bond costs nothing at the start and holds the end
//! where it was relative to the loop it passes through while the patch as a whole moves freely.
//! [`EdgeFinish::Cut`] leaves the ends free. The bonds enter the patch energy
//! ([`crate::patch::PatchModel::bond_cut_ends`]) counted with the stretching part.
//!
//! A yarn end with no other yarn in the patch (a patch of a single yarn) stays free.

use serde::{Deserialize, Serialize};

use crate::tile::Patch;

/// How the cut yarn ends at a patch's border are finished.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EdgeFinish {
    /// Every cut yarn end bonded to the nearest vertex of another yarn (a fused or overlocked edge).
    #[default]
    Bonded,
    /// Cut yarn ends left free: with frictionless contact the border unravels.
    Cut,
}

/// A link between two vertices of a patch with the stretching energy of a rod edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bond {
    /// Global vertex indices `(a, b)` in the patch (yarn after yarn): `a` the cut end, `b` its partner.
    pub vertices: [usize; 2],
    /// Rest length `L̄` (m): the starting distance.
    pub rest_length: f64,
}

/// The bonds of a fused edge ([`EdgeFinish::Bonded`]) at the patch's current positions: for each end
/// vertex of each open yarn (yarns in order, first end then last), the nearest vertex of any other yarn;
/// a pair already bonded the other way round is not bonded twice. Global vertex indices count the
/// patch's yarns in order, as [`crate::patch::PatchModel`] does for a patch without edgeless yarns.
pub fn cut_end_bonds(patch: &Patch) -> Vec<Bond> {
    let mut offset = Vec::with_capacity(patch.yarns.len());
    let mut total = 0;
    for y in &patch.yarns {
        offset.push(total);
        total += y.positions.len();
    }
    let mut bonds: Vec<Bond> = Vec::new();
    for (yi, y) in patch.yarns.iter().enumerate() {
        let n = y.positions.len();
        if y.closed || n < 2 {
            continue;
        }
        for local in [0, n - 1] {
            let p = y.positions[local];
            let mut best: Option<(f64, usize)> = None;
            for (yj, other) in patch.yarns.iter().enumerate() {
                if yj == yi {
                    continue;
                }
                for (k, q) in other.positions.iter().enumerate() {
                    let d2 = (0..3).map(|c| (q[c] - p[c]).powi(2)).sum::<f64>();
                    if best.is_none_or(|(b, _)| d2 < b) {
                        best = Some((d2, offset[yj] + k));
                    }
                }
            }
            let Some((d2, b)) = best else { continue };
            let a = offset[yi] + local;
            let rest_length = d2.sqrt();
            if rest_length <= 0.0 || bonds.iter().any(|q| q.vertices == [b, a]) {
                continue;
            }
            bonds.push(Bond {
                vertices: [a, b],
                rest_length,
            });
        }
    }
    bonds
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tile::Yarn;

    fn straight(y: f64, n: usize, closed: bool) -> Yarn {
        let positions: Vec<[f64; 3]> = (0..n).map(|i| [i as f64 * 1e-3, y, 0.0]).collect();
        let edges = if closed { n } else { n - 1 };
        Yarn {
            source: vec![(0, [0, 0]); n],
            closed,
            twist: vec![0.0; edges],
            rest_length: vec![1e-3; edges],
            reference_director: vec![[0.0, 0.0, 1.0]; edges],
            reference_twist: vec![None; n],
            rest_curvature: vec![None; n],
            rest_twist: vec![None; n],
            positions,
        }
    }

    #[test]
    fn each_cut_end_is_bonded_to_the_nearest_vertex_of_another_yarn() {
        // Three parallel yarns at y = 0, 2 and 4.5 mm, the middle one shifted by 0.4 mm along x; the last
        // closed.
        let mut middle = straight(2e-3, 5, false);
        for p in &mut middle.positions {
            p[0] += 0.4e-3;
        }
        let patch = Patch {
            cells: [1, 1],
            radius: 1e-3,
            yarns: vec![straight(0.0, 4, false), middle, straight(4.5e-3, 3, true)],
        };
        let bonds = cut_end_bonds(&patch);
        let d = |dx: f64, dy: f64| (dx * dx + dy * dy).sqrt();
        // Yarn 0 (vertices 0..4): its first end (x = 0) meets the middle yarn's vertex 0 at x = 0.4 mm
        // (global 4); its last end (x = 3 mm) the middle yarn's vertex 3 at x = 3.4 mm (global 7), not
        // vertex 2 at 2.4 mm (0.6 mm off in x).
        assert_eq!(bonds[0].vertices, [0, 4]);
        assert!((bonds[0].rest_length - d(0.4e-3, 2e-3)).abs() < 1e-15);
        assert_eq!(bonds[1].vertices, [3, 7]);
        // The middle yarn's first end (global 4) is already bonded to vertex 0: not twice.
        // Its last end (x = 4.4 mm, global 8): yarn 0's last vertex (1.4 mm off in x, 2 mm in y) is
        // nearer than the closed yarn's last (2.4 mm in x, 2.5 mm in y): global 3.
        assert_eq!(bonds[2].vertices, [8, 3]);
        // The closed yarn has no cut end.
        assert_eq!(bonds.len(), 3, "{bonds:?}");
    }

    #[test]
    fn a_single_yarn_has_no_partner() {
        let patch = Patch {
            cells: [1, 1],
            radius: 1e-3,
            yarns: vec![straight(0.0, 4, false)],
        };
        assert!(cut_end_bonds(&patch).is_empty());
    }
}
