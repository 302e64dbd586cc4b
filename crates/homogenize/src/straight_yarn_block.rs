//! A block of voxels threaded by straight, parallel yarns: the hand-computable case of shape fitting
//! (issue 43: "a uniform stretch of a block whose yarns are straight lines gives `F` equal to the imposed
//! deformation") and the synthetic mesh of its benchmark. Not the mesh construction of Sec. 4 (that
//! voxelizes arbitrary yarns, [`crate::volumetric_mesh`]); this builds the same kind of mesh directly.
//!
//! `nx × ny × nz` cubic voxels of edge `voxel_m` (m) with a corner at the origin, split by
//! [`crate::volumetric_mesh::tet_split::voxel_block`] into six
//! tetrahedra around its diagonal from `(0, 0, 0)` to `(1, 1, 1)` (the Kuhn split: the same in every
//! voxel, so neighbouring voxels share their face triangulation). One yarn per voxel row along `x`,
//! at `y = (j + 0.37) voxel_m`, `z = (k + 0.61) voxel_m`, from `x = 0.05 voxel_m` to
//! `x = (nx − 0.05) voxel_m` with vertices `voxel_m / 2.5` apart (not aligned with the grid) and edge
//! angles `θ = 0`. Each yarn vertex is embedded by its barycentric weights in the tetrahedron that holds
//! it; the yarn mass (`linear_density_kg_per_m` times each vertex's Voronoi length) is lumped onto the
//! nodes with those weights (a point-mass version of Eq. 2, exact for the mass and its first moment).

use nalgebra::{Matrix3, Vector3};
use skintight_knit::frame_sequence::YarnRange;

use crate::volumetric_mesh::{Embedded, VolumetricMesh};

/// The block's mesh, yarn ranges and rest frame (`#Y` rows: x, y, z in m, θ = 0 rad).
#[derive(Clone, Debug)]
pub struct StraightYarnBlock {
    /// The mesh with its embedding and lumped masses.
    pub mesh: VolumetricMesh,
    /// One open yarn per voxel row along x.
    pub yarns: Vec<YarnRange>,
    /// The rest frame of the yarns.
    pub rest: Vec<[f64; 4]>,
}

/// Builds the block (`nx, ny, nz ≥ 1` voxels, `voxel_m > 0` m, `linear_density_kg_per_m > 0` kg/m).
pub fn straight_yarn_block(
    [nx, ny, nz]: [usize; 3],
    voxel_m: f64,
    linear_density_kg_per_m: f64,
) -> StraightYarnBlock {
    let (rest, tets) = crate::volumetric_mesh::tet_split::voxel_block([nx, ny, nz], voxel_m);
    let mut rows = Vec::new();
    let mut yarns = Vec::new();
    let spacing = voxel_m / 2.5;
    let (x0, x1) = (0.05 * voxel_m, (nx as f64 - 0.05) * voxel_m);
    let count = ((x1 - x0) / spacing).floor() as usize + 1;
    for k in 0..nz {
        for j in 0..ny {
            yarns.push(YarnRange {
                first_vertex: rows.len(),
                vertex_count: count,
                closed: false,
            });
            for v in 0..count {
                rows.push([
                    x0 + v as f64 * spacing,
                    (j as f64 + 0.37) * voxel_m,
                    (k as f64 + 0.61) * voxel_m,
                    0.0,
                ]);
            }
        }
    }
    let mut embedding = Vec::with_capacity(rows.len());
    let mut node_mass = vec![0.0; rest.len()];
    for (r, row) in rows.iter().enumerate() {
        let p = Vector3::new(row[0], row[1], row[2]);
        let cell: [usize; 3] = std::array::from_fn(|c| {
            let n = [nx, ny, nz][c];
            ((p[c] / voxel_m).floor().max(0.0) as usize).min(n - 1)
        });
        let first = 6 * ((cell[0] * ny + cell[1]) * nz + cell[2]);
        let mut best = (f64::NEG_INFINITY, first, [0.0; 4]);
        for e in first..first + 6 {
            let t = tets[e];
            let q = |c: usize| Vector3::from(rest[t[c]]);
            let d = Matrix3::from_columns(&[q(1) - q(0), q(2) - q(0), q(3) - q(0)]);
            let l = d
                .try_inverse()
                .expect("a voxel tetrahedron is not degenerate")
                * (p - q(0));
            let w = [1.0 - l.sum(), l.x, l.y, l.z];
            let worst = w.iter().copied().fold(f64::INFINITY, f64::min);
            if worst > best.0 {
                best = (worst, e, w);
            }
        }
        embedding.push(Embedded {
            tet: best.1,
            weights: best.2,
        });
        let open_end = yarns
            .iter()
            .any(|y| r == y.first_vertex || r + 1 == y.first_vertex + y.vertex_count);
        let mass = linear_density_kg_per_m * spacing * if open_end { 0.5 } else { 1.0 };
        for c in 0..4 {
            node_mass[tets[best.1][c]] += mass * best.2[c];
        }
    }
    StraightYarnBlock {
        mesh: VolumetricMesh {
            rest,
            tets,
            node_mass,
            embedding,
        },
        yarns,
        rest: rows,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_block_is_conforming_and_its_embedding_reproduces_the_yarn() {
        let b = straight_yarn_block([3, 2, 2], 2e-3, 1e-3);
        assert_eq!(b.mesh.tets.len(), 6 * 12);
        assert_eq!(b.mesh.rest.len(), 4 * 3 * 3);
        let mut volume = 0.0;
        for t in &b.mesh.tets {
            let q = |c: usize| Vector3::from(b.mesh.rest[t[c]]);
            let v = (q(1) - q(0)).cross(&(q(2) - q(0))).dot(&(q(3) - q(0))) / 6.0;
            assert!(v > 0.0);
            volume += v;
        }
        assert!((volume - 12.0 * 8e-9).abs() < 1e-20);
        // Every face is shared by two elements or lies on the boundary (conforming split).
        let mut faces = std::collections::HashMap::new();
        for t in &b.mesh.tets {
            for f in crate::volumetric_mesh::tet_split::sorted_faces(t) {
                *faces.entry(f).or_insert(0) += 1;
            }
        }
        assert!(faces.values().all(|&c| c <= 2));
        let boundary = faces.values().filter(|&&c| c == 1).count();
        assert_eq!(boundary, 2 * 2 * (3 * 2 + 2 * 2 + 3 * 2));
        for (row, em) in b.rest.iter().zip(&b.mesh.embedding) {
            assert!(em.weights.iter().all(|&w| w >= -1e-12));
            let t = b.mesh.tets[em.tet];
            let p: Vector3<f64> = (0..4)
                .map(|c| Vector3::from(b.mesh.rest[t[c]]) * em.weights[c])
                .sum();
            assert!((p - Vector3::new(row[0], row[1], row[2])).norm() < 1e-15);
        }
        let yarn_mass: f64 = b
            .yarns
            .iter()
            .map(|y| (y.vertex_count - 1) as f64 * 2e-3 / 2.5 * 1e-3)
            .sum();
        let lumped: f64 = b.mesh.node_mass.iter().sum();
        assert!((lumped - yarn_mass).abs() < 1e-15);
    }
}
