//! Candidate pairs of segments for contact by spatial hashing: a uniform grid of cubic cells of side `h`
//! (m) in a hash map; each segment is entered in every cell its bounding box, inflated by the contact
//! distance, overlaps; two segments are candidates when they share a cell. With `h` at least the longest
//! segment plus the contact distance each segment touches at most 8 cells, so the work is linear in the
//! number of segments for yarn densities of real fabric.

use std::collections::HashMap;

/// Candidate pairs `(i, j)`, `i < j`, of segments `(a, b)` whose bounding boxes, inflated by `margin`
/// (m), overlap. `cell` (m) is the grid spacing; values ≤ 0 or non-finite are replaced by the longest
/// segment plus `margin`.
pub fn candidate_pairs(
    segments: &[([f64; 3], [f64; 3])],
    margin: f64,
    cell: f64,
) -> Vec<(usize, usize)> {
    let longest = segments
        .iter()
        .map(|(a, b)| {
            ((b[0] - a[0]).abs())
                .max((b[1] - a[1]).abs())
                .max((b[2] - a[2]).abs())
        })
        .fold(0.0f64, f64::max);
    let h = if cell.is_finite() && cell > 0.0 {
        cell
    } else {
        (longest + margin).max(1e-12)
    };
    let boxes: Vec<([f64; 3], [f64; 3])> = segments
        .iter()
        .map(|(a, b)| {
            (
                std::array::from_fn(|k| a[k].min(b[k]) - margin / 2.0),
                std::array::from_fn(|k| a[k].max(b[k]) + margin / 2.0),
            )
        })
        .collect();
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, (lo, hi)) in boxes.iter().enumerate() {
        let l: [i64; 3] = std::array::from_fn(|k| (lo[k] / h).floor() as i64);
        let u: [i64; 3] = std::array::from_fn(|k| (hi[k] / h).floor() as i64);
        for x in l[0]..=u[0] {
            for y in l[1]..=u[1] {
                for z in l[2]..=u[2] {
                    grid.entry([x, y, z]).or_default().push(i);
                }
            }
        }
    }
    let mut pairs = Vec::new();
    for members in grid.values() {
        for (k, &i) in members.iter().enumerate() {
            for &j in &members[k + 1..] {
                let (a, b) = (i.min(j), i.max(j));
                let (la, ua) = boxes[a];
                let (lb, ub) = boxes[b];
                if (0..3).all(|k| la[k] <= ub[k] && lb[k] <= ua[k]) {
                    pairs.push((a, b));
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
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
}
