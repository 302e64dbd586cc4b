//! Which faces of the body's limit surface `body.glb` tessellates finely: those the worn garment may
//! touch.
//!
//! The garment lies on the body's limit surface; a viewer draws the body as triangles through limit-surface
//! samples, which lie inside the smooth surface where it is convex by the chord error (millimetres for a
//! whole surface face of a 1k body, about a ninth of that for `n = 3` samples per edge). So only where the
//! garment is must the body be sampled finely; elsewhere the corner samples show the body's shape
//! ([`skintight_geometry::surface::limit_mesh::limit_mesh_graded`], crack-free between the two).
//!
//! Face `f` is fine when a ball around its centre sample `c_f` (radius `r_f`: the largest distance from
//! `c_f` to the face's corner samples, so the ball holds the face's chord triangle, widened by 10 % for
//! the surface's bulge) meets a ball of radius `e` (the longest worn cloth edge) around a cloth vertex:
//! `min_i ‖x_i − c_f‖ ≤ r_f + e`. A cloth triangle lies within `e` of each of its vertices, so every face
//! that a cloth triangle crosses is fine. Nearest cloth vertices come from a uniform grid of cell
//! `max_f r_f + e` (each query looks at the 27 cells around its own). Units: metres.

use std::collections::HashMap;

use skintight_geometry::Vec3;
use skintight_geometry::math::Vec2;
use skintight_geometry::surface::{LimitSurface, Stencil, SurfaceError};

/// `#F` flags of the surface faces within reach of the garment (see the module notes): `surface` at control
/// positions `control` (`#V × 3`, m), the worn cloth at `cloth` (`#Vc × 3`, m) with triangles
/// `triangles`.
pub fn faces_under_garment<S: LimitSurface + ?Sized>(
    surface: &S,
    control: &[Vec3],
    cloth: &[Vec3],
    triangles: &[[usize; 3]],
) -> Result<Vec<bool>, SurfaceError> {
    let nf = surface.num_faces();
    let mut scratch = Stencil::with_capacity(64);
    let mut centre = Vec::with_capacity(nf);
    let mut radius = Vec::with_capacity(nf);
    for f in 0..nf {
        let mut at = |s1: f64, s2: f64| -> Result<Vec3, SurfaceError> {
            Ok(surface
                .point_with(control, f, Vec2::new(s1, s2), &mut scratch)?
                .position)
        };
        let c = at(1.0 / 3.0, 1.0 / 3.0)?;
        let r = [at(1.0, 0.0)?, at(0.0, 1.0)?, at(0.0, 0.0)?]
            .iter()
            .map(|p| (p - c).norm())
            .fold(0.0, f64::max);
        centre.push(c);
        radius.push(1.1 * r);
    }
    let edge = triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| (cloth[t[k]] - cloth[t[(k + 1) % 3]]).norm()))
        .fold(0.0, f64::max);
    if cloth.is_empty() {
        return Ok(vec![false; nf]);
    }
    let cell = radius.iter().copied().fold(0.0, f64::max) + edge;
    if !(cell.is_finite() && cell > 0.0) {
        return Ok(vec![true; nf]);
    }
    let key = |p: &Vec3| [p.x, p.y, p.z].map(|x| (x / cell).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in cloth.iter().enumerate() {
        grid.entry(key(p)).or_default().push(i);
    }
    Ok((0..nf)
        .map(|f| {
            let k = key(&centre[f]);
            let reach = radius[f] + edge;
            (-1..=1).any(|dx| {
                (-1..=1).any(|dy| {
                    (-1..=1).any(|dz| {
                        grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz])
                            .is_some_and(|ids| {
                                ids.iter().any(|&i| (cloth[i] - centre[f]).norm() <= reach)
                            })
                    })
                })
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use skintight_geometry::surface::LoopSurface;
    use skintight_geometry::test_meshes::icosphere;

    /// A cloth patch over one cap of a Loop sphere: the faces near it are fine, those on the far side are
    /// not, and every face a cloth triangle's points lie in is fine (checked by the closest face of points
    /// sampled on the cloth triangles).
    #[test]
    fn the_faces_a_garment_patch_touches_are_fine_and_the_far_side_is_not() {
        let control = icosphere(3, 1.0);
        let surface = LoopSurface::new(control.num_vertices(), &control.faces).unwrap();
        // Cloth: the limit points of the control vertices above y = 0.6, with the control mesh's triangles
        // among them.
        let keep: Vec<usize> = (0..control.num_vertices())
            .filter(|&v| control.positions[v].y > 0.6)
            .collect();
        let index: HashMap<usize, usize> = keep.iter().enumerate().map(|(i, &v)| (v, i)).collect();
        let limit =
            skintight_geometry::surface::limit_mesh::limit_mesh(&surface, &control.positions, 1)
                .unwrap();
        // limit_mesh with n = 1 numbers the corner samples in first-seen order: map by nearest position.
        let cloth: Vec<Vec3> = keep
            .iter()
            .map(|&v| {
                let p = control.positions[v];
                *limit
                    .positions
                    .iter()
                    .min_by(|a, b| (*a - p).norm().total_cmp(&(*b - p).norm()))
                    .unwrap()
            })
            .collect();
        let triangles: Vec<[usize; 3]> = control
            .faces
            .iter()
            .filter(|f| f.iter().all(|v| index.contains_key(v)))
            .map(|f| f.map(|v| index[&v]))
            .collect();
        assert!(triangles.len() > 4);
        let fine = faces_under_garment(&surface, &control.positions, &cloth, &triangles).unwrap();
        let faces = surface.topology().faces();
        let mut scratch = Stencil::with_capacity(64);
        let centres: Vec<Vec3> = (0..faces.len())
            .map(|f| {
                surface
                    .point_with(
                        &control.positions,
                        f,
                        Vec2::new(1.0 / 3.0, 1.0 / 3.0),
                        &mut scratch,
                    )
                    .unwrap()
                    .position
            })
            .collect();
        for t in &triangles {
            for (a, b) in [(1.0 / 3.0, 1.0 / 3.0), (0.5, 0.5), (0.8, 0.1)] {
                let p = cloth[t[0]] * a + cloth[t[1]] * b + cloth[t[2]] * (1.0 - a - b);
                let nearest = (0..faces.len())
                    .min_by(|&f, &g| (centres[f] - p).norm().total_cmp(&(centres[g] - p).norm()))
                    .unwrap();
                assert!(fine[nearest], "face {nearest} under the cloth is coarse");
            }
        }
        let far = (0..faces.len()).filter(|&f| centres[f].y < -0.3).count();
        assert!(far > 0);
        assert!(
            (0..faces.len()).all(|f| centres[f].y >= -0.3 || !fine[f]),
            "a face on the far side is fine"
        );
        assert!(fine.iter().filter(|&&f| f).count() < faces.len() / 2);
        // No cloth: nothing fine.
        let none = faces_under_garment(&surface, &control.positions, &[], &[]).unwrap();
        assert!(none.iter().all(|&f| !f));
    }
}
