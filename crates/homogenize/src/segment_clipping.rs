//! The length of each rest-pose yarn segment inside each tetrahedron: the weights `Lⱼ` of the element
//! average of Eq. 5 (the knitwear paper, Sec. 5), where a segment that crosses several elements counts in
//! each with the part of its length that lies there.
//!
//! Along a segment `p(s) = p₀ + s (p₁ − p₀)`, `s ∈ [0, 1]`, the barycentric coordinates `λₖ(s)` of a
//! tetrahedron are affine in `s`; the segment is inside where all four are non-negative, an interval
//! `[s₀, s₁]` found by clipping against each `λₖ ≥ 0` (Liang–Barsky in barycentric coordinates). Its length
//! in the element is `(s₁ − s₀) |p₁ − p₀|` (m). A segment lying on a face shared by two elements (a
//! tolerance of 1e-10 in `λ`) counts in both: the weights are normalized per element, so this only lets
//! both elements see it.
//!
//! Candidate elements come from a uniform grid of the elements' bounding boxes (cell = the mean element
//! size), so the cost is linear in segments and elements for a voxel mesh.

use std::collections::HashMap;

use nalgebra::{Matrix3, Vector3};

/// Per tetrahedron, the segments that pass through it and their lengths inside it (m): `#T` lists of
/// `(segment, length)`, in increasing segment order. `nodes`: `#V × 3` (m); `tets`: `#T × 4`, positively
/// oriented and non-degenerate; `segments`: `#S` pairs of end points (m).
pub fn segment_lengths_in_tets(
    nodes: &[[f64; 3]],
    tets: &[[usize; 4]],
    segments: &[[[f64; 3]; 2]],
) -> Vec<Vec<(usize, f64)>> {
    let mut out = vec![Vec::new(); tets.len()];
    if tets.is_empty() || segments.is_empty() {
        return out;
    }
    let p = |i: usize| Vector3::from(nodes[i]);
    // Barycentric maps: λ₁..₃ = D⁻¹ (x − x₀), λ₀ = 1 − Σ.
    let maps: Vec<Option<(Vector3<f64>, Matrix3<f64>)>> = tets
        .iter()
        .map(|t| {
            let d =
                Matrix3::from_columns(&[p(t[1]) - p(t[0]), p(t[2]) - p(t[0]), p(t[3]) - p(t[0])]);
            d.try_inverse().map(|inv| (p(t[0]), inv))
        })
        .collect();
    let boxes: Vec<([f64; 3], [f64; 3])> = tets
        .iter()
        .map(|t| {
            let mut lo = [f64::INFINITY; 3];
            let mut hi = [f64::NEG_INFINITY; 3];
            for &v in t {
                for k in 0..3 {
                    lo[k] = lo[k].min(nodes[v][k]);
                    hi[k] = hi[k].max(nodes[v][k]);
                }
            }
            (lo, hi)
        })
        .collect();
    let mean_size = boxes
        .iter()
        .map(|(lo, hi)| (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max))
        .sum::<f64>()
        / tets.len() as f64;
    let cell = if mean_size > 0.0 && mean_size.is_finite() {
        mean_size
    } else {
        1.0
    };
    let key = |x: &[f64; 3]| -> [i64; 3] { std::array::from_fn(|k| (x[k] / cell).floor() as i64) };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (e, (lo, hi)) in boxes.iter().enumerate() {
        let (a, b) = (key(lo), key(hi));
        for i in a[0]..=b[0] {
            for j in a[1]..=b[1] {
                for k in a[2]..=b[2] {
                    grid.entry([i, j, k]).or_default().push(e);
                }
            }
        }
    }
    let mut stamp = vec![usize::MAX; tets.len()];
    const TOL: f64 = 1e-12;
    for (s, [a, b]) in segments.iter().enumerate() {
        let (pa, pb) = (Vector3::from(*a), Vector3::from(*b));
        let length = (pb - pa).norm();
        if length.is_nan() || length <= 0.0 {
            continue;
        }
        let lo: [f64; 3] = std::array::from_fn(|k| a[k].min(b[k]));
        let hi: [f64; 3] = std::array::from_fn(|k| a[k].max(b[k]));
        let (ka, kb) = (key(&lo), key(&hi));
        for i in ka[0]..=kb[0] {
            for j in ka[1]..=kb[1] {
                for k in ka[2]..=kb[2] {
                    let Some(list) = grid.get(&[i, j, k]) else {
                        continue;
                    };
                    for &e in list {
                        if stamp[e] == s {
                            continue;
                        }
                        stamp[e] = s;
                        let Some((origin, inv)) = &maps[e] else {
                            continue;
                        };
                        let la = inv * (pa - origin);
                        let lb = inv * (pb - origin);
                        let l0a = 1.0 - la.sum();
                        let l0b = 1.0 - lb.sum();
                        let (mut s0, mut s1) = (0.0_f64, 1.0_f64);
                        for (va, vb) in [(l0a, l0b), (la.x, lb.x), (la.y, lb.y), (la.z, lb.z)] {
                            // va + s (vb − va) ≥ −TOL.
                            let d = vb - va;
                            if d.abs() < 1e-300 {
                                if va < -TOL {
                                    s1 = -1.0;
                                }
                            } else {
                                let root = (-TOL - va) / d;
                                if d > 0.0 {
                                    s0 = s0.max(root);
                                } else {
                                    s1 = s1.min(root);
                                }
                            }
                        }
                        if s1 > s0 {
                            out[e].push((s, (s1 - s0) * length));
                        }
                    }
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cube `[0, 1]³` split into six tetrahedra around its diagonal 0 → 7 (node k at the corner with
    /// bits (x, y, z) = (k & 1, k >> 1 & 1, k >> 2 & 1)).
    fn cube() -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
        crate::volumetric_mesh::tet_split::voxel_block([1, 1, 1], 1.0)
    }

    #[test]
    fn a_segment_through_the_cube_is_split_into_its_full_length() {
        let (nodes, tets) = cube();
        // Generic segments strictly inside and crossing the cube: the lengths inside sum to the length
        // of the part inside the cube.
        let segments = [
            [[0.1, 0.2, 0.3], [0.9, 0.7, 0.4]],
            [[-0.5, 0.31, 0.62], [1.5, 0.33, 0.61]],
            [[0.45, 0.55, -1.0], [0.45, 0.55, 0.5]],
        ];
        let inside = [
            (Vector3::new(0.8, 0.5, 0.1)).norm(),
            (Vector3::new(2.0, 0.02, -0.01)).norm() * 0.5,
            0.5,
        ];
        let out = segment_lengths_in_tets(&nodes, &tets, &segments);
        for s in 0..3 {
            let total: f64 = out
                .iter()
                .flatten()
                .filter(|(j, _)| *j == s)
                .map(|(_, l)| l)
                .sum();
            assert!(
                (total - inside[s]).abs() < 1e-10,
                "segment {s}: {total} vs {}",
                inside[s]
            );
            // More than one element is crossed by each.
            assert!(
                out.iter()
                    .filter(|l| l.iter().any(|(j, _)| *j == s))
                    .count()
                    >= 2
            );
        }
        // A segment outside touches nothing.
        let far = segment_lengths_in_tets(&nodes, &tets, &[[[2.0, 2.0, 2.0], [3.0, 2.0, 2.0]]]);
        assert!(far.iter().all(|l| l.is_empty()));
    }

    #[test]
    fn a_segment_along_the_diagonal_counts_in_all_six() {
        let (nodes, tets) = cube();
        let out = segment_lengths_in_tets(&nodes, &tets, &[[[0.2; 3], [0.6; 3]]]);
        let l = 0.4 * 3f64.sqrt();
        for list in &out {
            assert_eq!(list.len(), 1);
            assert!((list[0].1 - l).abs() < 1e-9);
        }
    }
}
