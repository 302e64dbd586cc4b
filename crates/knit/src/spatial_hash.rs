//! Candidate pairs of segments for contact by spatial hashing onto a uniform grid: cubic cells of side `h`
//! (m) over the segments' bounding box, a cell's hash its linear index in that grid (a perfect hash: no
//! collisions, no table). Each segment's bounding box, inflated by the contact distance, is entered in the
//! one cell holding its lower corner (a counting sort by cell), and each box looks for partners in the
//! cells whose lower corners it could meet: from its own lower corner less the largest box extent up to its
//! upper corner — with `h` at least the largest box extent, at most 3 cells per axis. Two segments are
//! candidates when their inflated boxes overlap. Every pair is found once (from its lower index), so the
//! pairs come out sorted without a sort or a deduplication, and the boxes are split into contiguous
//! ranges searched on separate threads. The work is linear in the number of segments for yarn densities of
//! real fabric; a grid that would have more than 8 cells a segment (a segment flung far from the rest) is
//! coarsened, which costs more overlap tests but finds the same pairs. (It replaced a hash map from cells
//! to the segments overlapping them, whose pairs needed a sort and a deduplication: 0.94× the 16 × 16
//! hang's time, docs/BENCHMARKS.md.)

/// Candidate pairs `(i, j)`, `i < j`, sorted, of segments `(a, b)` whose bounding boxes, inflated by
/// `margin / 2` on every side (`margin` in m), overlap. `cell` (m) is the grid spacing; values ≤ 0 or
/// non-finite are replaced by the largest inflated box's extent. A segment with a non-finite coordinate
/// has no partner.
pub fn candidate_pairs(
    segments: &[([f64; 3], [f64; 3])],
    margin: f64,
    cell: f64,
) -> Vec<(usize, usize)> {
    let boxes = inflated_boxes(segments, margin);
    let finite = |(lo, hi): &([f64; 3], [f64; 3])| lo.iter().chain(hi).all(|v| v.is_finite());
    let extent = boxes
        .iter()
        .filter(|b| finite(b))
        .map(|(lo, hi)| (0..3).map(|k| hi[k] - lo[k]).fold(0.0f64, f64::max))
        .fold(0.0f64, f64::max);
    let mut low = [f64::INFINITY; 3];
    let mut high = [f64::NEG_INFINITY; 3];
    for (lo, hi) in boxes.iter().filter(|b| finite(b)) {
        for k in 0..3 {
            low[k] = low[k].min(lo[k]);
            high[k] = high[k].max(hi[k]);
        }
    }
    if !low[0].is_finite() {
        return Vec::new();
    }
    let mut h = if cell.is_finite() && cell > 0.0 {
        cell
    } else {
        extent.max(1e-12)
    };
    let limit = (8 * boxes.len()).max(1024) as f64;
    let dims = loop {
        let dims: [f64; 3] = std::array::from_fn(|k| ((high[k] - low[k]) / h).floor() + 1.0);
        if dims[0] * dims[1] * dims[2] <= limit {
            break dims.map(|d| d as usize);
        }
        h *= 2.0;
    };
    let index = |p: &[f64; 3], k: usize| -> usize {
        // Saturating casts: NaN to 0, beyond the grid to its last cell.
        (((p[k] - low[k]) / h).floor().max(0.0) as usize).min(dims[k] - 1)
    };
    let cell_of = |p: &[f64; 3]| index(p, 0) + dims[0] * (index(p, 1) + dims[1] * index(p, 2));
    // Counting sort of the boxes by the cell of their lower corner.
    let cells = dims[0] * dims[1] * dims[2];
    let mut start = vec![0usize; cells + 1];
    let home: Vec<usize> = boxes.iter().map(|(lo, _)| cell_of(lo)).collect();
    for &c in &home {
        start[c + 1] += 1;
    }
    for c in 0..cells {
        start[c + 1] += start[c];
    }
    let mut members = vec![0usize; boxes.len()];
    let mut next = start.clone();
    for (i, &c) in home.iter().enumerate() {
        members[next[c]] = i;
        next[c] += 1;
    }
    let search = |range: std::ops::Range<usize>| {
        let mut pairs = Vec::new();
        let mut partners = Vec::new();
        for i in range {
            let (lo, hi) = &boxes[i];
            if !finite(&boxes[i]) {
                continue;
            }
            let from: [f64; 3] = std::array::from_fn(|k| lo[k] - extent);
            let (a, b): ([usize; 3], [usize; 3]) = (
                std::array::from_fn(|k| index(&from, k)),
                std::array::from_fn(|k| index(hi, k)),
            );
            partners.clear();
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    let row = dims[0] * (y + dims[1] * z);
                    for &j in &members[start[row + a[0]]..start[row + b[0] + 1]] {
                        let (lj, uj) = &boxes[j];
                        if j > i && (0..3).all(|k| lo[k] <= uj[k] && lj[k] <= hi[k]) {
                            partners.push(j);
                        }
                    }
                }
            }
            partners.sort_unstable();
            pairs.extend(partners.iter().map(|&j| (i, j)));
        }
        pairs
    };
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(16);
    if threads < 2 || boxes.len() < 4000 {
        return search(0..boxes.len());
    }
    let chunk = boxes.len().div_ceil(threads);
    let parts: Vec<Vec<(usize, usize)>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let range = (t * chunk).min(boxes.len())..((t + 1) * chunk).min(boxes.len());
                scope.spawn(|| search(range))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a candidate search thread panicked"))
            .collect()
    });
    parts.concat()
}

/// The segments' bounding boxes `(lower, upper)` (m), inflated by `margin / 2` on every side.
fn inflated_boxes(segments: &[([f64; 3], [f64; 3])], margin: f64) -> Vec<([f64; 3], [f64; 3])> {
    segments
        .iter()
        .map(|(a, b)| {
            (
                std::array::from_fn(|k| a[k].min(b[k]) - margin / 2.0),
                std::array::from_fn(|k| a[k].max(b[k]) + margin / 2.0),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::segment_distance::distance;
    use crate::test_support::random_point;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn finds_every_pair_closer_than_the_margin() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let segments: Vec<([f64; 3], [f64; 3])> = (0..400)
            .map(|_| {
                let a = random_point(&mut rng, 1e-2);
                let d = random_point(&mut rng, 1e-3);
                (a, [a[0] + d[0], a[1] + d[1], a[2] + d[2]])
            })
            .collect();
        let margin = 2e-3;
        let pairs = candidate_pairs(&segments, margin, 0.0);
        let mut close = 0;
        for i in 0..segments.len() {
            for j in i + 1..segments.len() {
                let d = distance(segments[i].0, segments[i].1, segments[j].0, segments[j].1);
                if d < margin {
                    close += 1;
                    assert!(
                        pairs.binary_search(&(i, j)).is_ok(),
                        "missed ({i}, {j}) at {d}"
                    );
                }
            }
        }
        assert!(close > 10, "the test needs close pairs: {close}");
        assert!(
            pairs.len() < segments.len() * segments.len() / 10,
            "{} candidates",
            pairs.len()
        );
    }

    /// The pairs whose inflated boxes overlap, by testing every pair.
    fn brute_force(segments: &[([f64; 3], [f64; 3])], margin: f64) -> Vec<(usize, usize)> {
        let boxes = inflated_boxes(segments, margin);
        let mut pairs = Vec::new();
        for i in 0..boxes.len() {
            for j in i + 1..boxes.len() {
                let ((li, ui), (lj, uj)) = (boxes[i], boxes[j]);
                if (0..3).all(|k| li[k] <= uj[k] && lj[k] <= ui[k]) {
                    pairs.push((i, j));
                }
            }
        }
        pairs
    }

    /// Exactly the overlapping pairs, sorted and once each: at the default spacing, at a fine and a coarse
    /// one, with a segment flung far away (the grid coarsened), a segment with a NaN (no partner), and
    /// enough segments for the threaded search.
    #[test]
    fn gives_exactly_the_overlapping_pairs_in_order() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let random = |rng: &mut ChaCha8Rng, count: usize, spread: f64| {
            (0..count)
                .map(|_| {
                    let a = random_point(rng, spread);
                    let d = random_point(rng, 1e-3);
                    (a, [a[0] + d[0], a[1] + d[1], a[2] + d[2]])
                })
                .collect::<Vec<([f64; 3], [f64; 3])>>()
        };
        let margin = 2e-3;
        let mut far = random(&mut rng, 300, 5e-3);
        far.push(([1e3, -2e3, 5e2], [1e3 + 1e-3, -2e3, 5e2]));
        let mut nan = random(&mut rng, 300, 5e-3);
        nan[17].1[1] = f64::NAN;
        for (segments, cell) in [
            (random(&mut rng, 500, 1e-2), 0.0),
            (random(&mut rng, 500, 1e-2), 1e-3),
            (random(&mut rng, 500, 1e-2), 0.5),
            (far, 0.0),
            (nan, 0.0),
            (random(&mut rng, 5000, 3e-2), 0.0),
        ] {
            let pairs = candidate_pairs(&segments, margin, cell);
            assert!(pairs.windows(2).all(|w| w[0] < w[1]), "sorted and unique");
            let expected = brute_force(&segments, margin);
            assert!(
                expected.len() > 100,
                "the test needs pairs: {}",
                expected.len()
            );
            assert_eq!(pairs, expected, "{} segments, cell {cell}", segments.len());
        }
        assert!(candidate_pairs(&[], margin, 0.0).is_empty());
    }
}
