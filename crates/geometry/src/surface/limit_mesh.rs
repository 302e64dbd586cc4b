//! A triangle mesh of a limit surface: every surface face split into `n²` triangles whose vertices lie on
//! the limit surface, shared between neighbouring faces, so the mesh is as closed as the surface.
//!
//! For face `f` with corners `(c₀, c₁, c₂)` and the sample `(i, j, k)`, `i + j + k = n`, the vertex is the
//! surface point at barycentric weights `(i, j, k) / n` — surface coordinates `s = (i/n, j/n)`
//! ([`crate::surface::SurfaceCoord::barycentric`]). A sample on an edge is keyed by the edge's two vertices
//! and its distance from the smaller one, a sample at a corner by the vertex, so neighbouring faces share it
//! (evaluated once, from the first face that reaches it). The sub-triangles keep the face's orientation.
//!
//! Why: a coarse body mesh lies inside its own smooth limit surface wherever the body is convex, by up to
//! the chord error (millimetres on the 1k bodies), and the garment rests on the limit surface; drawn over
//! the coarse triangles, most of a worn garment would sink into the body in a viewer. With `n = 3` the
//! sub-triangles' chord error is about 1/9 of the coarse one.
//!
//! Units: positions in the control positions' units (m).

use std::collections::HashMap;

use crate::math::{Vec2, Vec3};
use crate::mesh::TriMesh;
use crate::surface::{LimitSurface, Stencil, SurfaceError};

/// The limit surface of `surface` at control positions `control` (`#V × 3`, m) as a triangle mesh with
/// `n²` triangles per surface face (`n ≥ 1`; `n = 1` samples only the corners), `#F·n²` faces in face
/// order (face `f`'s sub-triangles are `f·n² … (f+1)·n² − 1`).
pub fn limit_mesh<S: LimitSurface + ?Sized>(
    surface: &S,
    control: &[Vec3],
    n: usize,
) -> Result<TriMesh, SurfaceError> {
    let n = n.max(1);
    let faces = surface.topology().faces();
    let mut positions: Vec<Vec3> = Vec::new();
    let mut corner_id: HashMap<usize, usize> = HashMap::new();
    let mut edge_id: HashMap<(usize, usize, usize), usize> = HashMap::new();
    let mut scratch = Stencil::with_capacity(64);
    let mut out_faces = Vec::with_capacity(faces.len() * n * n);
    let mut local = vec![0usize; (n + 1) * (n + 2) / 2];
    // Index of sample (i, j) (weights of corners 0 and 1) in `local`.
    let at = |i: usize, j: usize| i * (n + 1) - i * i.saturating_sub(1) / 2 + j;
    for (f, face) in faces.iter().enumerate() {
        let mut eval = |i: usize, j: usize| -> Result<Vec3, SurfaceError> {
            let s = Vec2::new(i as f64 / n as f64, j as f64 / n as f64);
            Ok(surface.point_with(control, f, s, &mut scratch)?.position)
        };
        for i in 0..=n {
            for j in 0..=(n - i) {
                let k = n - i - j;
                // Which corners carry weight: a corner sample, an edge sample or an interior one.
                let weights = [i, j, k];
                let nonzero: Vec<usize> = (0..3).filter(|&c| weights[c] > 0).collect();
                let id = match nonzero.as_slice() {
                    [c] => {
                        let v = face[*c];
                        match corner_id.get(&v) {
                            Some(&id) => id,
                            None => {
                                positions.push(eval(i, j)?);
                                corner_id.insert(v, positions.len() - 1);
                                positions.len() - 1
                            }
                        }
                    }
                    [a, b] => {
                        let (va, vb) = (face[*a], face[*b]);
                        // Distance from the smaller vertex, in steps of 1/n.
                        let key = if va < vb {
                            (va, vb, weights[*b])
                        } else {
                            (vb, va, weights[*a])
                        };
                        match edge_id.get(&key) {
                            Some(&id) => id,
                            None => {
                                positions.push(eval(i, j)?);
                                edge_id.insert(key, positions.len() - 1);
                                positions.len() - 1
                            }
                        }
                    }
                    _ => {
                        positions.push(eval(i, j)?);
                        positions.len() - 1
                    }
                };
                local[at(i, j)] = id;
            }
        }
        // Sub-triangles in the face's orientation: the face (c₀, c₁, c₂) maps to the samples
        // (n,0) → (0,n) → (0,0) in (i, j), and each cell keeps that cyclic order.
        for i in 0..n {
            for j in 0..(n - i) {
                out_faces.push([local[at(i + 1, j)], local[at(i, j + 1)], local[at(i, j)]]);
                if i + j + 1 < n {
                    out_faces.push([
                        local[at(i + 1, j)],
                        local[at(i + 1, j + 1)],
                        local[at(i, j + 1)],
                    ]);
                }
            }
        }
    }
    Ok(TriMesh::new(positions, out_faces))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::topology::Topology;
    use crate::surface::LoopSurface;
    use crate::test_meshes::icosphere;

    /// On a Loop sphere: closed and manifold, as many faces as asked, outward (positive volume), every
    /// vertex on the limit surface, and the volume closer to the sphere's than the control mesh's.
    #[test]
    fn tessellates_the_limit_surface_closed_and_oriented() {
        let control = icosphere(1, 1.0);
        let surface = LoopSurface::new(control.num_vertices(), &control.faces).unwrap();
        for n in [1, 2, 3, 4] {
            let mesh = limit_mesh(&surface, &control.positions, n).unwrap();
            assert_eq!(mesh.num_faces(), control.num_faces() * n * n);
            let topo = Topology::new(mesh.num_vertices(), &mesh.faces).unwrap();
            assert!(topo.is_closed(), "n = {n}");
            // Euler characteristic of a sphere.
            let chi =
                mesh.num_vertices() as i64 - topo.num_edges() as i64 + mesh.num_faces() as i64;
            assert_eq!(chi, 2, "n = {n}");
            assert!(mesh.signed_volume() > 0.0);
        }
        // Finer samples of the same limit surface: the volume converges (the chord error shrinks).
        let v: Vec<f64> = [1, 2, 4, 8]
            .iter()
            .map(|&n| {
                limit_mesh(&surface, &control.positions, n)
                    .unwrap()
                    .signed_volume()
            })
            .collect();
        assert!((v[3] - v[2]).abs() < (v[1] - v[0]).abs() / 4.0, "{v:?}");
        assert!(
            v[0] < v[1] && v[1] < v[2],
            "a convex limit surface grows as it is sampled finer: {v:?}"
        );
    }
}
