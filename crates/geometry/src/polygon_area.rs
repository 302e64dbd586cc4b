//! The signed area of a closed plane polygon by the shoelace formula:
//! `A = ½ Σᵢ (xᵢ yᵢ₊₁ − xᵢ₊₁ yᵢ)` over the vertices `p_0 … p_{n−1}` with `p_n = p_0`.
//!
//! The sign gives the orientation (positive counter-clockwise), which the pattern code uses to tell a
//! piece's outline from a hole and the girth code ignores (it takes the absolute value). One function for
//! both so the two always agree to the bit.
//!
//! Units: the square of the points' unit (m² for points in metres).

use crate::math::{Real, Vec2};

/// Signed area of the closed polygon `points` (m² for points in m): positive when counter-clockwise.
pub fn polygon_area(points: &[Vec2]) -> Real {
    let n = points.len();
    0.5 * (0..n)
        .map(|i| {
            let (a, b) = (points[i], points[(i + 1) % n]);
            a.x * b.y - a.y * b.x
        })
        .sum::<Real>()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_square_both_ways() {
        let square = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ];
        assert_eq!(polygon_area(&square), 1.0);
        let mut reversed = square;
        reversed.reverse();
        assert_eq!(polygon_area(&reversed), -1.0);
        assert_eq!(polygon_area(&[]), 0.0);
    }
}
