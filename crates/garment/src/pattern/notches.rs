//! Notches (match marks): where the two sides of a seam are to meet, at the same arc length from the seam's
//! start on both pieces.
//!
//! A seam of length `L` (m; both sides equally long once trued, see [`crate::seam_truing`]) gets notches at
//! arc lengths `s = 0` and `s = L` (its ends; a closed seam has none) and at `s = j · spacing` for
//! `j = 1, 2, …` up to `L − spacing / 2`, so none crowds an end; plus the ones the user asks for. Arc length
//! runs from the seam's start: forward along side 0's run, backward from the end of side 1's run (the
//! sides face each other). Because truing makes corresponding seam edges equally long, `s` falls on the same
//! seam edge at the same fraction on both sides.
//!
//! A notch is a slit `depth` long cut into the seam allowance: from the cut line, where the outward normal
//! at the mark meets it, towards the mark.

use crate::math::{Real, Vec2};
use crate::pattern::Notch;
use crate::pattern::seam_allowance::segment_crossing;

/// A run of a closed sewing line: vertices `start` forward to `end` (wrapping; `start == end` is the whole
/// line).
#[derive(Clone, Copy, Debug)]
pub struct Run<'a> {
    /// The closed sewing line (m).
    pub sewing: &'a [Vec2],
    /// First vertex.
    pub start: usize,
    /// Last vertex.
    pub end: usize,
}

impl Run<'_> {
    /// Number of segments in the run.
    pub fn segments(&self) -> usize {
        let n = self.sewing.len();
        match (self.end + n - self.start) % n {
            0 => n,
            k => k,
        }
    }

    /// Segment `k` of the run as its two end points.
    fn segment(&self, k: usize) -> (Vec2, Vec2) {
        let n = self.sewing.len();
        let i = (self.start + k) % n;
        (self.sewing[i], self.sewing[(i + 1) % n])
    }

    /// Length of the run (m).
    pub fn length(&self) -> Real {
        (0..self.segments())
            .map(|k| {
                let (a, b) = self.segment(k);
                (b - a).norm()
            })
            .sum()
    }

    /// The point at arc length `s` (m, clamped to the run) and the outward unit normal of its segment.
    pub fn point_at(&self, s: Real) -> (Vec2, Vec2) {
        let segs = self.segments();
        let mut left = s.max(0.0);
        for k in 0..segs {
            let (a, b) = self.segment(k);
            let len = (b - a).norm();
            if left <= len || k + 1 == segs {
                let t = if len > 0.0 {
                    (left / len).min(1.0)
                } else {
                    0.0
                };
                let d = if len > 0.0 { (b - a) / len } else { Vec2::x() };
                return (a + (b - a) * t, Vec2::new(d.y, -d.x));
            }
            left -= len;
        }
        (self.sewing[self.start], Vec2::x())
    }
}

/// Arc lengths (m) of the automatic notches on a seam of length `length` (see the module documentation).
pub fn notch_arc_lengths(length: Real, spacing: Real, closed: bool) -> Vec<Real> {
    let mut s = Vec::new();
    if !closed {
        s.push(0.0);
    }
    if spacing > 0.0 && spacing.is_finite() {
        let mut j = if closed { 0.0 } else { 1.0 };
        while j * spacing <= length - 0.5 * spacing {
            s.push(j * spacing);
            j += 1.0;
        }
    }
    if !closed {
        s.push(length);
    }
    s
}

/// A notch at the sewing-line point `at` with outward normal `normal`, cut `depth` into an allowance
/// `allowance` wide from the `cut` line (closed, m).
pub fn notch(
    at: Vec2,
    normal: Vec2,
    allowance: Real,
    depth: Real,
    cut: &[Vec2],
    seam: Option<usize>,
    arc_length: Real,
    user: bool,
) -> Notch {
    // Nearest crossing of the ray at + t·normal (0 ≤ t ≤ 3 allowance + 1 mm) with the cut line.
    let reach = 3.0 * allowance + 1e-3;
    let far = at + normal * reach;
    let n = cut.len();
    let hit = (0..n)
        .filter_map(|i| segment_crossing(at, far, cut[i], cut[(i + 1) % n]).map(|(t, _)| t))
        .fold(Real::INFINITY, Real::min);
    let on_cut_line = if hit.is_finite() {
        at + (far - at) * hit
    } else {
        at + normal * allowance
    };
    Notch {
        at,
        on_cut_line,
        depth: depth.min((on_cut_line - at).norm()),
        seam,
        arc_length,
        user,
    }
}
