//! Arc-length resampling of pattern boundaries for a remesh, seam sides kept sewable.
//!
//! A panel boundary loop is cut at its corners into pieces (a seam side or a free stretch). Each piece is
//! resampled at equal arc length into a given number of segments; the two sides of a seam must get the same
//! count, which [`seam_segment_count`] computes from both sides' lengths, so that vertex `k` of one side is
//! sewn to vertex `k` (or `n − k` when reversed) of the other. Corners (piece endpoints) are kept exactly.
//! Positions in m.

use crate::math::{Real, Vec2};

/// Number of segments `max(1, round(L / h))` for pieces of lengths `lengths` (m) sewn together, `L` their
/// mean length and `h` (m, > 0) the target edge length; 1 for non-finite input.
pub fn seam_segment_count(lengths: &[Real], edge_length: Real) -> usize {
    if lengths.is_empty() {
        return 1;
    }
    let mean = lengths.iter().sum::<Real>() / lengths.len() as Real;
    let n = (mean / edge_length).round();
    if n.is_finite() && n >= 1.0 {
        n as usize
    } else {
        1
    }
}

/// Length (m) of the open polyline `points`.
pub fn polyline_length(points: &[Vec2]) -> Real {
    points.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

/// The open polyline `points` (≥ 2 points, m) resampled into `segments` (≥ 1) pieces of equal arc length:
/// `segments + 1` points, the first and last equal to those of `points`. A zero-length polyline gives
/// copies of its first point.
pub fn resample_polyline(points: &[Vec2], segments: usize) -> Vec<Vec2> {
    let segments = segments.max(1);
    let first = points[0];
    let last = *points.last().unwrap_or(&first);
    let total = polyline_length(points);
    let mut out = Vec::with_capacity(segments + 1);
    out.push(first);
    if !(total > 0.0 && total.is_finite()) {
        out.extend(std::iter::repeat_n(first, segments - 1));
        out.push(last);
        return out;
    }
    let mut edge = 0;
    let mut edge_start = 0.0;
    for k in 1..segments {
        let s = total * k as Real / segments as Real;
        while edge + 2 < points.len() && edge_start + (points[edge + 1] - points[edge]).norm() < s {
            edge_start += (points[edge + 1] - points[edge]).norm();
            edge += 1;
        }
        let l = (points[edge + 1] - points[edge]).norm();
        let t = if l > 0.0 {
            ((s - edge_start) / l).clamp(0.0, 1.0)
        } else {
            0.0
        };
        out.push(points[edge] + (points[edge + 1] - points[edge]) * t);
    }
    out.push(last);
    out
}

/// The closed boundary loop `points` (m) cut at the loop indices `corners` (strictly increasing, ≥ 1 of
/// them) and piece `i` (from `corners[i]` to `corners[i + 1]`, the last wrapping around) resampled into
/// `segments[i]` pieces; returns the new loop (not repeated at the end) and the new loop index of each
/// corner.
pub fn resample_loop(
    points: &[Vec2],
    corners: &[usize],
    segments: &[usize],
) -> Result<(Vec<Vec2>, Vec<usize>), String> {
    let n = points.len();
    if n < 3 {
        return Err(format!("a boundary loop needs at least 3 points, got {n}"));
    }
    if corners.is_empty() || corners.len() != segments.len() {
        return Err(format!(
            "{} corners and {} segment counts: need as many, at least one",
            corners.len(),
            segments.len()
        ));
    }
    if corners.windows(2).any(|w| w[0] >= w[1]) || corners.iter().any(|&c| c >= n) {
        return Err("corner indices must be increasing and inside the loop".into());
    }
    let mut out = Vec::new();
    let mut new_corners = Vec::with_capacity(corners.len());
    for (i, &c) in corners.iter().enumerate() {
        let end = if i + 1 < corners.len() {
            corners[i + 1]
        } else {
            corners[0] + n
        };
        let piece: Vec<Vec2> = (c..=end).map(|j| points[j % n]).collect();
        let resampled = resample_polyline(&piece, segments[i]);
        new_corners.push(out.len());
        out.extend_from_slice(&resampled[..resampled.len() - 1]);
    }
    Ok((out, new_corners))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn polygon_area(p: &[Vec2]) -> Real {
        let n = p.len();
        0.5 * (0..n)
            .map(|i| p[i].x * p[(i + 1) % n].y - p[(i + 1) % n].x * p[i].y)
            .sum::<Real>()
    }

    /// A rounded panel: unevenly sampled circle of radius `r` (m) with `n` points.
    fn uneven_circle(n: usize, r: Real) -> Vec<Vec2> {
        (0..n)
            .map(|i| {
                let u = i as Real / n as Real;
                let tau = std::f64::consts::TAU;
                let a = tau * (u + 0.05 * (4.0 * u * tau).sin() / tau);
                Vec2::new(r * a.cos(), r * a.sin())
            })
            .collect()
    }

    #[test]
    fn polyline_resampling_keeps_ends_and_equalizes_edges() {
        let pts = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(0.03, 0.0),
            Vec2::new(0.03, 0.01),
        ];
        for segs in [1, 2, 4, 7, 20] {
            let r = resample_polyline(&pts, segs);
            assert_eq!(r.len(), segs + 1);
            assert_eq!(r[0], pts[0]);
            assert_eq!(r[segs], pts[2]);
            // Equal arc length: each piece is 0.04/segs along the polyline (chords ≤ that).
            for w in r.windows(2) {
                assert!((w[1] - w[0]).norm() <= 0.04 / segs as Real + 1e-12);
            }
            assert!((polyline_length(&r) - 0.04).abs() < 0.04 * 0.3);
        }
        let degenerate = resample_polyline(&[Vec2::zeros(), Vec2::zeros()], 3);
        assert_eq!(degenerate.len(), 4);
        assert!(degenerate.iter().all(|p| p.norm() == 0.0));
    }

    #[test]
    fn seam_sides_get_equal_counts_and_corners_are_kept() {
        let h = 0.005;
        // Two sides of a seam of slightly different lengths, sampled differently.
        let a: Vec<Vec2> = (0..=7)
            .map(|i| Vec2::new(i as Real * 0.1 / 7.0, 0.0))
            .collect();
        let b: Vec<Vec2> = (0..=3)
            .map(|i| Vec2::new(0.0, i as Real * 0.104 / 3.0))
            .collect();
        let n = seam_segment_count(&[polyline_length(&a), polyline_length(&b)], h);
        assert_eq!(n, 20);
        assert_eq!(
            resample_polyline(&a, n).len(),
            resample_polyline(&b, n).len()
        );
        assert_eq!(seam_segment_count(&[Real::NAN], h), 1);
        assert_eq!(seam_segment_count(&[0.001], h), 1);
    }

    #[test]
    fn loop_resampling_preserves_area_and_corners_at_several_sizes() {
        for (n, h) in [(17, 0.02), (40, 0.01), (90, 0.004)] {
            let r = 0.1;
            let pts = uneven_circle(n, r);
            let corners = vec![0, n / 3, 2 * n / 3];
            let segments: Vec<usize> = (0..3)
                .map(|i| {
                    let end = if i < 2 { corners[i + 1] } else { n };
                    let piece: Vec<Vec2> = (corners[i]..=end).map(|j| pts[j % n]).collect();
                    seam_segment_count(&[polyline_length(&piece)], h)
                })
                .collect();
            let (new, new_corners) = resample_loop(&pts, &corners, &segments).unwrap();
            assert_eq!(new.len(), segments.iter().sum::<usize>());
            for (c, nc) in corners.iter().zip(&new_corners) {
                assert_eq!(pts[*c], new[*nc]);
            }
            let a0 = polygon_area(&pts);
            let a1 = polygon_area(&new);
            assert!(a1 > 0.0, "orientation kept");
            assert!((a1 - a0).abs() < 0.03 * a0, "n {n}: area {a0} → {a1}");
            // Edges near the target length.
            let m = new.len();
            for i in 0..m {
                let l = (new[(i + 1) % m] - new[i]).norm();
                assert!(l > 0.5 * h && l < 1.5 * h, "n {n}: edge {l} vs {h}");
            }
        }
        assert!(resample_loop(&uneven_circle(5, 0.1), &[3, 1], &[2, 2]).is_err());
        assert!(resample_loop(&uneven_circle(5, 0.1), &[0], &[]).is_err());
    }
}
