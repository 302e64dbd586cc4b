//! Six tetrahedra a voxel (the knitwear paper, Sec. 4: "to prevent numerical locking of the hexahedral
//! element, each voxel is further split into six tetrahedrons").
//!
//! **The split.** The Kuhn (Freudenthal) split of the unit cube along its main diagonal from corner
//! `(0,0,0)` to `(1,1,1)`: for each permutation `π` of the axes, the tetrahedron
//! `[0, e_π₀, e_π₀ + e_π₁, 1]` is the set of points whose local coordinates are ordered
//! `f_π₀ ≥ f_π₁ ≥ f_π₂`. The six orderings tile the cube. Every voxel uses the same diagonal direction, and
//! the split of each face is then the same seen from both voxels sharing it (the face `f_i = 0` is split by
//! its diagonal between its corners `0` and `1 − e_i`, and the face `f_i = 1` of the voxel below is split by
//! the same diagonal), so the mesh is conforming: neighbouring tetrahedra share whole faces, no hanging
//! nodes. The faces between tetrahedra lie on the planes `u_i ∈ ℤ` and `u_i − u_j ∈ ℤ` of the grid
//! coordinates `u`, which is what [`super::mass_lumping`] splits the yarn segments at.
//!
//! **Orientation.** The signed volume of `[0, e_π₀, e_π₀ + e_π₁, 1]` is `det[e_π₀, e_π₁, e_π₂] / 6 =
//! sign(π) h³ / 6`; for the three odd permutations the corners 1 and 2 are swapped, so every tetrahedron is
//! positively oriented with volume `h³ / 6` (m³).
//!
//! **Nodes** are the voxels' corners, shared between neighbouring voxels: each is identified by its integer
//! grid coordinates, sorted, and numbered in that order, so the same voxels always give the same mesh.
//! Tetrahedron `6 v + k` is the `k`-th Kuhn tetrahedron ([`KUHN`]) of the `v`-th voxel (in sorted order).

/// The axis permutations `π` of the six Kuhn tetrahedra, in the order of the tetrahedra of a voxel.
pub const KUHN: [[usize; 3]; 6] = [
    [0, 1, 2],
    [0, 2, 1],
    [1, 0, 2],
    [1, 2, 0],
    [2, 0, 1],
    [2, 1, 0],
];

/// Whether the permutation `KUHN[k]` is odd (its tetrahedron's corners 1 and 2 are then swapped).
pub fn odd(k: usize) -> bool {
    matches!(k, 1 | 2 | 5)
}

/// The corner offsets (0 or 1 on each axis) of the `k`-th Kuhn tetrahedron of a voxel, positively oriented.
pub fn kuhn_corners(k: usize) -> [[i64; 3]; 4] {
    let p = KUHN[k];
    let mut corners = [[0i64; 3]; 4];
    corners[1][p[0]] = 1;
    corners[2][p[0]] = 1;
    corners[2][p[1]] = 1;
    corners[3] = [1, 1, 1];
    if odd(k) {
        corners.swap(1, 2);
    }
    corners
}

/// The nodes (sorted integer grid coordinates) and the tetrahedra (indices into the nodes, `6 #voxels × 4`)
/// of the sorted, distinct `voxels`.
pub fn tet_split(voxels: &[[i64; 3]]) -> (Vec<[i64; 3]>, Vec<[usize; 4]>) {
    let mut nodes = Vec::with_capacity(8 * voxels.len());
    for c in voxels {
        for dz in 0..2 {
            for dy in 0..2 {
                for dx in 0..2 {
                    nodes.push([c[0] + dx, c[1] + dy, c[2] + dz]);
                }
            }
        }
    }
    nodes.sort_unstable();
    nodes.dedup();
    let index = |g: [i64; 3]| {
        nodes
            .binary_search(&g)
            .expect("every voxel corner is among the nodes")
    };
    let corners: [[[i64; 3]; 4]; 6] = std::array::from_fn(kuhn_corners);
    let mut tets = Vec::with_capacity(6 * voxels.len());
    for c in voxels {
        for tet in &corners {
            tets.push(std::array::from_fn(|j| {
                index([c[0] + tet[j][0], c[1] + tet[j][1], c[2] + tet[j][2]])
            }));
        }
    }
    (nodes, tets)
}

/// The four faces of a tetrahedron as sorted node triples, face `k` opposite corner `k`: the key under
/// which two tetrahedra sharing a face meet.
pub fn sorted_faces(tet: &[usize; 4]) -> [[usize; 3]; 4] {
    std::array::from_fn(|skip| {
        let mut face = [0usize; 3];
        for (k, c) in (0..4).filter(|&c| c != skip).enumerate() {
            face[k] = tet[c];
        }
        face.sort_unstable();
        face
    })
}

/// A box of `cells[0] × cells[1] × cells[2]` voxels of edge `voxel_m` (m) with a corner at the origin,
/// split by [`tet_split`]: the node positions (`#V × 3`, m) and the tetrahedra (`6 #voxels × 4`).
/// Tetrahedron `6 v + k` lies in voxel `v = (i · cells[1] + j) · cells[2] + l` at `(i, j, l)`. The
/// hand-made meshes of tests and benchmarks: the same split the mesh construction uses.
pub fn voxel_block(cells: [usize; 3], voxel_m: f64) -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
    let mut voxels = Vec::with_capacity(cells.iter().product());
    for i in 0..cells[0] as i64 {
        for j in 0..cells[1] as i64 {
            for l in 0..cells[2] as i64 {
                voxels.push([i, j, l]);
            }
        }
    }
    let (nodes, tets) = tet_split(&voxels);
    let rest = nodes
        .iter()
        .map(|g| g.map(|c| c as f64 * voxel_m))
        .collect();
    (rest, tets)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn signed_volume(p: [[f64; 3]; 4]) -> f64 {
        let d = |a: usize| -> [f64; 3] { std::array::from_fn(|i| p[a][i] - p[0][i]) };
        let (a, b, c) = (d(1), d(2), d(3));
        (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]))
            / 6.0
    }

    #[test]
    fn six_positive_tetrahedra_fill_the_cube() {
        let mut total = 0.0;
        for k in 0..6 {
            let c = kuhn_corners(k);
            let v = signed_volume(std::array::from_fn(|j| c[j].map(|x| x as f64)));
            assert!((v - 1.0 / 6.0).abs() < 1e-15, "tet {k}: {v}");
            total += v;
        }
        assert!((total - 1.0).abs() < 1e-15);
    }

    #[test]
    fn neighbouring_voxels_share_nodes_and_whole_faces() {
        // A 2 × 2 × 2 block of voxels: 27 nodes, and every interior triangle has exactly two tetrahedra,
        // every boundary triangle one — a conforming mesh (a non-conforming split would leave triangles of
        // the shared faces with one tetrahedron each).
        let mut voxels = Vec::new();
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..2 {
                    voxels.push([x, y, z]);
                }
            }
        }
        voxels.sort_unstable();
        let (nodes, tets) = tet_split(&voxels);
        assert_eq!(nodes.len(), 27);
        assert_eq!(tets.len(), 48);
        let mut faces: HashMap<[usize; 3], usize> = HashMap::new();
        for t in &tets {
            for f in sorted_faces(t) {
                *faces.entry(f).or_default() += 1;
            }
        }
        let boundary = faces.values().filter(|&&n| n == 1).count();
        assert!(faces.values().all(|&n| n == 1 || n == 2));
        // The block's surface: 6 faces of 2 × 2 squares, two triangles each.
        assert_eq!(boundary, 6 * 4 * 2);
        for t in &tets {
            let p = t.map(|i| nodes[i].map(|x| x as f64));
            assert!(signed_volume(p) > 0.0);
        }
    }
}
