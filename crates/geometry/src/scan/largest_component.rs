//! Connected components of a triangle soup (faces linked through shared vertices), their areas, and the
//! mesh reduced to its largest component with unused vertices removed.
//!
//! Units: areas in the square of the positions' unit.
//!
//! Method: union–find with path halving over the vertices of each face (Tarjan 1975, "Efficiency of a good
//! but not linear set union algorithm"); the largest component is the one of largest surface area (a scan's
//! noise islands are small however densely they are sampled).

use crate::math::{Real, Vec3};
use crate::mesh::TriMesh;

/// Components of a mesh, largest area first.
#[derive(Clone, Debug, PartialEq)]
pub struct Components {
    /// `#F`: the component of each face (0 = largest area).
    pub face_component: Vec<usize>,
    /// Area of each component, in decreasing order.
    pub areas: Vec<Real>,
    /// Faces of each component.
    pub faces: Vec<usize>,
}

fn root(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// The components of the faces (indices must be in range).
pub fn components(mesh: &TriMesh) -> Components {
    let nv = mesh.num_vertices();
    let mut parent: Vec<usize> = (0..nv).collect();
    for f in &mesh.faces {
        let r0 = root(&mut parent, f[0]);
        for &v in &f[1..] {
            let r = root(&mut parent, v);
            if r != r0 {
                parent[r] = r0;
            }
        }
    }
    let mut id = vec![usize::MAX; nv];
    let mut areas: Vec<Real> = Vec::new();
    let mut counts: Vec<usize> = Vec::new();
    let mut raw = Vec::with_capacity(mesh.num_faces());
    for (fi, f) in mesh.faces.iter().enumerate() {
        let r = root(&mut parent, f[0]);
        if id[r] == usize::MAX {
            id[r] = areas.len();
            areas.push(0.0);
            counts.push(0);
        }
        let c = id[r];
        let a = mesh.face_area(fi);
        if a.is_finite() {
            areas[c] += a;
        }
        counts[c] += 1;
        raw.push(c);
    }
    let mut order: Vec<usize> = (0..areas.len()).collect();
    order.sort_by(|&a, &b| {
        areas[b]
            .total_cmp(&areas[a])
            .then(counts[b].cmp(&counts[a]))
    });
    let mut rank = vec![0; areas.len()];
    for (r, &c) in order.iter().enumerate() {
        rank[c] = r;
    }
    Components {
        face_component: raw.iter().map(|&c| rank[c]).collect(),
        areas: order.iter().map(|&c| areas[c]).collect(),
        faces: order.iter().map(|&c| counts[c]).collect(),
    }
}

/// The faces for which `keep` is true, with unused vertices removed (vertex order kept).
pub fn keep_faces(mesh: &TriMesh, keep: impl Fn(usize) -> bool) -> TriMesh {
    let nv = mesh.num_vertices();
    let mut map = vec![usize::MAX; nv];
    let mut positions: Vec<Vec3> = Vec::new();
    let mut faces = Vec::new();
    let kept: Vec<usize> = (0..mesh.num_faces()).filter(|&f| keep(f)).collect();
    let mut used = vec![false; nv];
    for &f in &kept {
        for &v in &mesh.faces[f] {
            used[v] = true;
        }
    }
    for v in 0..nv {
        if used[v] {
            map[v] = positions.len();
            positions.push(mesh.positions[v]);
        }
    }
    for &f in &kept {
        faces.push(mesh.faces[f].map(|v| map[v]));
    }
    TriMesh::new(positions, faces)
}

/// The largest-area component alone, and the components found.
pub fn largest_component(mesh: &TriMesh) -> (TriMesh, Components) {
    let c = components(mesh);
    let kept = keep_faces(mesh, |f| c.face_component[f] == 0);
    (kept, c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::icosphere;

    #[test]
    fn two_spheres_and_a_speck() {
        let a = icosphere(2, 1.0);
        let b = icosphere(1, 0.5);
        let c = icosphere(0, 0.01);
        let mut m = TriMesh::default();
        for (s, off) in [(&b, 0.0), (&a, 5.0), (&c, 10.0)] {
            let base = m.positions.len();
            m.positions
                .extend(s.positions.iter().map(|p| p + Vec3::new(off, 0.0, 0.0)));
            m.faces.extend(s.faces.iter().map(|f| f.map(|v| v + base)));
        }
        let (big, comps) = largest_component(&m);
        assert_eq!(comps.areas.len(), 3);
        assert_eq!(
            comps.faces,
            vec![a.num_faces(), b.num_faces(), c.num_faces()]
        );
        assert_eq!(big.num_faces(), a.num_faces());
        assert_eq!(big.num_vertices(), a.num_vertices());
        assert!((big.area() - a.area()).abs() < 1e-12);
    }
}
