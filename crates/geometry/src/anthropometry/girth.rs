//! Tape-measure girth of a section loop: the perimeter of the convex hull of the loop in its plane.
//!
//! **Why the convex hull.** A tape measure pulled snug around a limb or the torso lies on the skin where the
//! skin is convex and bridges every concavity (between the calf muscles, the gluteal fold, the navel) in a
//! straight line: its length is the perimeter of the convex hull of the section (ISO 8559-1:2017 takes
//! girths with the tape in contact with the skin, without compressing the soft tissue).
//! The convex-hull perimeter is also far less sensitive to the mesh resolution than the loop's own length,
//! whose zig-zags on a coarse mesh add length.
//!
//! **Method.** The loop is projected on its plane (frame from [`plane_frame`]); the hull by Andrew's
//! monotone chain; the perimeter is the sum of the hull's edge lengths. Units: metres.

use crate::math::{Real, Vec2, Vec3};

use super::plane_section::SectionLoop;

/// Convex hull of 2D points, counter-clockwise, without collinear points (Andrew's monotone chain).
pub fn convex_hull(points: &[Vec2]) -> Vec<Vec2> {
    let mut p: Vec<Vec2> = points
        .iter()
        .copied()
        .filter(|q| q.x.is_finite() && q.y.is_finite())
        .collect();
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    let mut hull: Vec<Vec2> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &Vec2>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// Perimeter (m) of a closed 2D polygon.
pub fn perimeter(q: &[Vec2]) -> Real {
    (0..q.len())
        .map(|i| (q[(i + 1) % q.len()] - q[i]).norm())
        .sum()
}

/// Tape-measure girth (m) of `section`, a loop in the plane with normal `normal`: the perimeter of its
/// convex hull in that plane.
pub fn girth(section: &SectionLoop, normal: Vec3) -> Real {
    perimeter(&convex_hull(&section.project(normal)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hull_of_a_star_is_its_tips_and_its_perimeter_bridges_the_dents() {
        // A five-pointed star: tips on radius 1, dents on radius 0.4.
        let pts: Vec<Vec3> = (0..10)
            .map(|k| {
                let a = k as Real * std::f64::consts::PI / 5.0;
                let r = if k % 2 == 0 { 1.0 } else { 0.4 };
                Vec3::new(r * a.cos(), 0.0, r * a.sin())
            })
            .collect();
        let star = SectionLoop { points: pts };
        let g = girth(&star, Vec3::y());
        let pentagon = 10.0 * (std::f64::consts::PI / 5.0).sin();
        assert!((g - pentagon).abs() < 1e-12, "{g} vs {pentagon}");
        assert!(star.length() > g);
        let q = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.5, 0.0),
        ];
        assert_eq!(convex_hull(&q).len(), 2);
    }
}
