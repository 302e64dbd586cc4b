//! The cut line: a piece's sewing line offset outwards by each run's seam allowance, with the corners a
//! pattern maker draws.
//!
//! The sewing line `p_0 … p_{n−1}` is closed and counter-clockwise, so the outward normal of segment
//! `i` (`p_i → p_{i+1}`, unit direction `d_i`) is `n_i = (d_i.y, −d_i.x)`. Segment `i` has the allowance
//! `a_i` (m) of the run it belongs to, and its offset line is `p_i + a_i n_i + t d_i`. At vertex `i`, where
//! segment `i − 1` meets segment `i`, the cut line takes:
//! * inside a run (a smooth curve) and at every concave vertex: the **mitre**, the intersection of the two
//!   offset lines; where the turn is so sharp that the mitre would reach further than `MITRE_LIMIT` times
//!   the allowance, a bevel (the two offset ends joined);
//! * where two runs meet at a convex corner ([`CornerStyle`]): the mitre, or, at a corner sharper than a
//!   right angle, the **squared** corner: each offset line runs on past the corner by the other run's
//!   allowance, and the two ends are joined — the allowance of a hem folds back flat along the seam
//!   allowance instead of ending in a long point. At a right angle both are the same point.
//!
//! Where the sewing line curves inwards more tightly than the allowance, the raw offset crosses itself in a
//! small loop; the loop is cut off at the crossing ("local loop removal"). A loop that spans more than
//! `LOCAL_LOOP` allowances of sewing line is no longer a local artefact but two parts of the piece whose
//! allowances overlap: that is refused ([`OffsetError::SelfIntersects`]), as is any crossing left over.

use crate::math::{Real, Vec2};

/// Mitre length beyond which a join is bevelled, in allowances (a turn of about 150°).
const MITRE_LIMIT: Real = 4.0;
/// Longest sewing-line arc (in largest allowances) whose offset may be cut off as a local loop.
const LOCAL_LOOP: Real = 6.0;

/// How a convex corner between two runs of the outline is drawn in the cut line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CornerStyle {
    /// The two allowance lines meet at their intersection.
    #[default]
    Mitre,
    /// At corners sharper than a right angle, each allowance line runs on past the corner by the other's
    /// allowance, and the ends are joined; elsewhere the mitre.
    Square,
}

/// Why a cut line could not be drawn.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OffsetError {
    /// Fewer than three points, a zero-length segment, or a non-finite value.
    #[error("the sewing line is degenerate: {0}")]
    Degenerate(String),
    /// A negative or non-finite allowance.
    #[error("seam allowance {0} m is invalid: it must be a finite length ≥ 0")]
    BadAllowance(Real),
    /// The allowances of two parts of the outline overlap, so the cut line would cross itself.
    #[error(
        "the cut line crosses itself near sewing-line vertices {first} and {second}: the allowance there is wider than the piece leaves room for"
    )]
    SelfIntersects { first: usize, second: usize },
}

/// Intersection parameter of `a + t (b − a)` with `c + s (d − c)`: `Some((t, s))` for a proper crossing of
/// the two segments (both in [0, 1]), `None` for parallel ones.
pub(crate) fn segment_crossing(a: Vec2, b: Vec2, c: Vec2, d: Vec2) -> Option<(Real, Real)> {
    let r = b - a;
    let q = d - c;
    let den = r.x * q.y - r.y * q.x;
    if den.abs() <= 1e-300 {
        return None;
    }
    let w = c - a;
    let t = (w.x * q.y - w.y * q.x) / den;
    let s = (w.x * r.y - w.y * r.x) / den;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&s)).then_some((t, s))
}

/// Intersection of the lines `p + t u` and `q + s v` (`None` when parallel).
fn line_intersection(p: Vec2, u: Vec2, q: Vec2, v: Vec2) -> Option<Vec2> {
    let den = u.x * v.y - u.y * v.x;
    if den.abs() < 1e-12 {
        return None;
    }
    let w = q - p;
    let t = (w.x * v.y - w.y * v.x) / den;
    Some(p + u * t)
}

/// The cut line of the closed counter-clockwise `sewing` line (m): segment `i` (`sewing[i] → sewing[i+1]`)
/// offset by `allowance[i]` (m, ≥ 0); `corner[i]` marks vertex `i` as the meeting of two runs, drawn with
/// `style` when convex. Returns the closed counter-clockwise cut line (m), not repeated at the end.
pub fn cut_line(
    sewing: &[Vec2],
    allowance: &[Real],
    corner: &[bool],
    style: CornerStyle,
) -> Result<Vec<Vec2>, OffsetError> {
    let n = sewing.len();
    if n < 3 {
        return Err(OffsetError::Degenerate(format!("{n} points")));
    }
    if allowance.len() != n || corner.len() != n {
        return Err(OffsetError::Degenerate(format!(
            "{} allowances and {} corner flags for {n} segments",
            allowance.len(),
            corner.len()
        )));
    }
    if let Some(&a) = allowance.iter().find(|a| !(a.is_finite() && **a >= 0.0)) {
        return Err(OffsetError::BadAllowance(a));
    }
    let mut dir = Vec::with_capacity(n);
    for i in 0..n {
        let e = sewing[(i + 1) % n] - sewing[i];
        let len = e.norm();
        if !(len > 0.0 && len.is_finite()) {
            return Err(OffsetError::Degenerate(format!(
                "segment {i} has length {len:e} m"
            )));
        }
        dir.push(e / len);
    }
    let normal = |i: usize| Vec2::new(dir[i].y, -dir[i].x);
    let a_max = allowance.iter().copied().fold(0.0, Real::max);

    // Raw offset: one or two points per sewing vertex, each tagged with its sewing vertex.
    let mut raw: Vec<(Vec2, usize)> = Vec::with_capacity(n + 8);
    for i in 0..n {
        let h = (i + n - 1) % n;
        let p = sewing[i];
        let (a0, a1) = (allowance[h], allowance[i]);
        let (n0, n1) = (normal(h), normal(i));
        let (d0, d1) = (dir[h], dir[i]);
        let turn = d0.x * d1.y - d0.y * d1.x;
        let convex = turn > 0.0;
        let bevel = || [(p + n0 * a0, i), (p + n1 * a1, i)];
        // Squared only where the corner is sharper than a right angle (a turn of more than 90°); at a right
        // angle the squared corner is the mitre, and at a blunter one it would cross itself.
        if corner[i] && convex && style == CornerStyle::Square && d0.dot(&d1) < 0.0 {
            raw.push((p + n0 * a0 + d0 * a1, i));
            raw.push((p + n1 * a1 - d1 * a0, i));
            continue;
        }
        match line_intersection(p + n0 * a0, d0, p + n1 * a1, d1) {
            Some(x) if !convex || (x - p).norm() <= MITRE_LIMIT * a0.max(a1) + 1e-12 => {
                raw.push((x, i))
            }
            Some(_) => raw.extend(bevel()),
            // Parallel: straight on (one point when the allowances agree) or a step between allowances.
            None if (a0 - a1).abs() <= 1e-12 && d0.dot(&d1) > 0.0 => raw.push((p + n1 * a1, i)),
            None => raw.extend(bevel()),
        }
    }

    // Local loop removal.
    let arc = |from: usize, to: usize| -> Real {
        // Sewing-line length from vertex `from` forward to vertex `to`.
        let mut s = 0.0;
        let mut k = from;
        while k != to {
            s += (sewing[(k + 1) % n] - sewing[k]).norm();
            k = (k + 1) % n;
        }
        s
    };
    let mut guard = 0;
    'outer: loop {
        guard += 1;
        let m = raw.len();
        if m < 3 || guard > 4 * n + 16 {
            return Err(OffsetError::Degenerate(
                "the cut line collapsed while removing its loops".into(),
            ));
        }
        for i in 0..m {
            for j in i + 2..m {
                if i == 0 && j == m - 1 {
                    continue;
                }
                let (a, b) = (raw[i].0, raw[(i + 1) % m].0);
                let (c, d) = (raw[j].0, raw[(j + 1) % m].0);
                let Some((t, _)) = segment_crossing(a, b, c, d) else {
                    continue;
                };
                let x = a + (b - a) * t;
                // The loop is raw[i+1 ..= j] (inner side) or raw[j+1 ..= i] (around the end).
                let inner_len = j - i;
                let (from, to) = if inner_len <= m - inner_len {
                    (raw[i].1, raw[(j + 1) % m].1)
                } else {
                    (raw[j].1, raw[(i + 1) % m].1)
                };
                if arc(from, to).min(arc(to, from)) > LOCAL_LOOP * a_max {
                    return Err(OffsetError::SelfIntersects {
                        first: raw[i].1,
                        second: raw[j].1,
                    });
                }
                let tag = raw[i].1;
                if inner_len <= m - inner_len {
                    raw.splice(i + 1..=j, [(x, tag)]);
                } else {
                    raw.truncate(j + 1);
                    raw.drain(..=i);
                    raw.insert(0, (x, tag));
                }
                continue 'outer;
            }
        }
        break;
    }
    let out: Vec<Vec2> = raw.into_iter().map(|(p, _)| p).collect();
    // Drop consecutive duplicates (zero allowances repeat points).
    let mut cut: Vec<Vec2> = Vec::with_capacity(out.len());
    for p in out {
        if cut.last().is_none_or(|q| (p - q).norm() > 1e-12) {
            cut.push(p);
        }
    }
    while cut.len() > 1 && (cut[0] - cut[cut.len() - 1]).norm() <= 1e-12 {
        cut.pop();
    }
    if cut.len() < 3 {
        return Err(OffsetError::Degenerate(
            "the cut line has fewer than 3 points".into(),
        ));
    }
    Ok(cut)
}

/// Whether `p` lies inside the closed polygon `points` (even–odd rule; points on the outline may go
/// either way).
pub fn polygon_contains(points: &[Vec2], p: Vec2) -> bool {
    let n = points.len();
    let mut inside = false;
    for i in 0..n {
        let (a, b) = (points[i], points[(i + 1) % n]);
        if (a.y > p.y) != (b.y > p.y) {
            let x = a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x);
            if p.x < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// The first pair of crossing non-adjacent segments of the closed polygon `points`, if any.
pub fn first_self_crossing(points: &[Vec2]) -> Option<(usize, usize)> {
    let m = points.len();
    for i in 0..m {
        for j in i + 2..m {
            if i == 0 && j == m - 1 {
                continue;
            }
            if segment_crossing(
                points[i],
                points[(i + 1) % m],
                points[j],
                points[(j + 1) % m],
            )
            .is_some()
            {
                return Some((i, j));
            }
        }
    }
    None
}
