//! Repair of a triangle soup into an oriented 2-manifold with boundary: drops invalid, degenerate and
//! duplicated faces and every face on an edge shared by more than two faces, splits pinched ("bow-tie")
//! vertices into one vertex per fan, and orients the faces consistently.
//!
//! Units: positions in any unit (only zero areas and exact duplicates are judged).
//!
//! Method: the cutting approach of Guéziec, Taubin, Lazarus & Horn 2001, "Cutting and stitching:
//! converting sets of polygons to manifold surfaces" (IEEE TVCG 7(2)), simplified: faces at singular edges
//! are removed rather than cut apart (the holes they leave are filled afterwards, see
//! [`super::hole_filling`]); singular vertices are split per edge-connected fan; orientation is propagated
//! across manifold edges by breadth-first search, and a face that cannot agree with its neighbours
//! (a Möbius band) is dropped.

use std::collections::VecDeque;

use crate::math::Vec3;
use crate::mesh::TriMesh;

/// What the repair changed.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RepairSummary {
    /// Faces naming a vertex twice, a non-finite vertex, or of zero area.
    pub invalid_faces_removed: usize,
    /// Second and later copies of a face (same three vertices).
    pub duplicate_faces_removed: usize,
    /// Edges shared by more than two faces.
    pub non_manifold_edges: usize,
    /// Faces removed because they lie on such an edge.
    pub non_manifold_edge_faces_removed: usize,
    /// Pinched vertices split (one new vertex per extra fan).
    pub non_manifold_vertices_split: usize,
    /// Faces turned to agree with their neighbours.
    pub faces_reoriented: usize,
    /// Faces dropped because no consistent orientation exists.
    pub unorientable_faces_removed: usize,
}

/// Sorted directed-edge list: `(min, max, face, forward)` where `forward` means the face runs min → max.
fn edge_list(faces: &[[usize; 3]]) -> Vec<(usize, usize, usize, bool)> {
    let mut e = Vec::with_capacity(faces.len() * 3);
    for (fi, f) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            e.push((a.min(b), a.max(b), fi, a < b));
        }
    }
    e.sort_unstable();
    e
}

/// Repairs the mesh as described in the module documentation.
pub fn repair_non_manifold(mesh: &TriMesh) -> (TriMesh, RepairSummary) {
    let mut s = RepairSummary::default();
    let nv = mesh.num_vertices();
    let finite = |v: usize| mesh.positions[v].iter().all(|x| x.is_finite());
    // 1. Invalid and zero-area faces.
    let mut faces: Vec<[usize; 3]> = Vec::with_capacity(mesh.num_faces());
    for (fi, f) in mesh.faces.iter().enumerate() {
        let ok = f.iter().all(|&v| v < nv && finite(v))
            && f[0] != f[1]
            && f[1] != f[2]
            && f[0] != f[2]
            && mesh.face_area(fi) > 0.0;
        if ok {
            faces.push(*f);
        } else {
            s.invalid_faces_removed += 1;
        }
    }
    // 2. Duplicates (any order of the same three vertices).
    let mut keyed: Vec<([usize; 3], usize)> = faces
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let mut k = *f;
            k.sort_unstable();
            (k, i)
        })
        .collect();
    keyed.sort_unstable();
    let mut keep = vec![true; faces.len()];
    for w in keyed.windows(2) {
        if w[0].0 == w[1].0 {
            keep[w[1].1] = false;
            s.duplicate_faces_removed += 1;
        }
    }
    // 3. Faces on edges with more than two faces.
    let edges = edge_list(&faces);
    let mut i = 0;
    while i < edges.len() {
        let mut j = i;
        while j < edges.len() && edges[j].0 == edges[i].0 && edges[j].1 == edges[i].1 {
            j += 1;
        }
        let live: Vec<usize> = edges[i..j]
            .iter()
            .map(|e| e.2)
            .filter(|&f| keep[f])
            .collect();
        if live.len() > 2 {
            s.non_manifold_edges += 1;
            for f in live {
                keep[f] = false;
                s.non_manifold_edge_faces_removed += 1;
            }
        }
        i = j;
    }
    let mut faces: Vec<[usize; 3]> = faces
        .into_iter()
        .zip(&keep)
        .filter(|(_, k)| **k)
        .map(|(f, _)| f)
        .collect();
    // 4. Orientation by breadth-first search over manifold edges.
    let edges = edge_list(&faces);
    let mut adj: Vec<[Option<usize>; 3]> = vec![[None; 3]; faces.len()];
    let mut i = 0;
    while i < edges.len() {
        let mut j = i;
        while j < edges.len() && edges[j].0 == edges[i].0 && edges[j].1 == edges[i].1 {
            j += 1;
        }
        if j - i == 2 {
            let (f, g) = (edges[i].2, edges[i + 1].2);
            if let Some(slot) = adj[f].iter_mut().find(|x| x.is_none()) {
                *slot = Some(g);
            }
            if let Some(slot) = adj[g].iter_mut().find(|x| x.is_none()) {
                *slot = Some(f);
            }
        }
        i = j;
    }
    let mut state = vec![0u8; faces.len()]; // 0 unseen, 1 oriented, 2 dropped
    let mut queue = VecDeque::new();
    for start in 0..faces.len() {
        if state[start] != 0 {
            continue;
        }
        state[start] = 1;
        queue.push_back(start);
        while let Some(f) = queue.pop_front() {
            if state[f] != 1 {
                continue;
            }
            for nb in adj[f] {
                let Some(g) = nb else { continue };
                if state[g] == 2 {
                    continue;
                }
                // The shared edge, as f runs it: a → b; g must run b → a.
                let Some(e) = (0..3).find(|&e| {
                    faces[g].contains(&faces[f][e]) && faces[g].contains(&faces[f][(e + 1) % 3])
                }) else {
                    continue;
                };
                let (a, b) = (faces[f][e], faces[f][(e + 1) % 3]);
                let agrees = (0..3).any(|m| faces[g][m] == b && faces[g][(m + 1) % 3] == a);
                if state[g] == 0 {
                    if !agrees {
                        faces[g].swap(1, 2);
                        s.faces_reoriented += 1;
                    }
                    state[g] = 1;
                    queue.push_back(g);
                } else if !agrees {
                    state[g] = 2;
                    s.unorientable_faces_removed += 1;
                }
            }
        }
    }
    faces = faces
        .into_iter()
        .zip(&state)
        .filter(|(_, st)| **st == 1)
        .map(|(f, _)| f)
        .collect();
    // 5. Pinched vertices: one vertex per fan of faces connected through edges at the vertex.
    let mut positions: Vec<Vec3> = mesh.positions.clone();
    let mut incident: Vec<Vec<(usize, usize)>> = vec![Vec::new(); nv]; // (face, corner)
    for (fi, f) in faces.iter().enumerate() {
        for k in 0..3 {
            incident[f[k]].push((fi, k));
        }
    }
    for (v, inc) in incident.iter().enumerate() {
        if inc.len() < 2 {
            continue;
        }
        let n = inc.len();
        let mut parent: Vec<usize> = (0..n).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        // Faces around v sharing another vertex share an edge at v.
        let mut others: Vec<(usize, usize)> = Vec::with_capacity(2 * n);
        for (li, &(fi, k)) in inc.iter().enumerate() {
            others.push((faces[fi][(k + 1) % 3], li));
            others.push((faces[fi][(k + 2) % 3], li));
        }
        others.sort_unstable();
        for w in others.windows(2) {
            if w[0].0 == w[1].0 {
                let (a, b) = (root(&mut parent, w[0].1), root(&mut parent, w[1].1));
                if a != b {
                    parent[a] = b;
                }
            }
        }
        let mut fan_of_root: Vec<(usize, usize)> = Vec::new(); // (root, new vertex)
        let mut first_root = None;
        for (li, &(fi, k)) in inc.iter().enumerate() {
            let r = root(&mut parent, li);
            let first = *first_root.get_or_insert(r);
            if r == first {
                continue;
            }
            let nvx = match fan_of_root.iter().find(|x| x.0 == r) {
                Some(x) => x.1,
                None => {
                    positions.push(mesh.positions[v]);
                    s.non_manifold_vertices_split += 1;
                    fan_of_root.push((r, positions.len() - 1));
                    positions.len() - 1
                }
            };
            faces[fi][k] = nvx;
        }
    }
    (TriMesh::new(positions, faces), s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::check::{MeshCheckParams, mesh_report};
    use crate::test_meshes::icosphere;

    #[test]
    fn bow_tie_is_split_and_fin_removed() {
        let mut m = icosphere(2, 1.0);
        let nf = m.num_faces();
        // A fin on edge (f0.0, f0.1): a third face on that edge.
        let [a, b, _] = m.faces[0];
        m.positions.push(Vec3::new(3.0, 3.0, 3.0));
        let tip = m.positions.len() - 1;
        m.faces.push([a, b, tip]);
        // A bow-tie: a triangle touching vertex 5 only.
        m.positions
            .push(m.positions[5] * 1.5 + Vec3::new(0.1, 0.0, 0.0));
        m.positions
            .push(m.positions[5] * 1.5 + Vec3::new(0.0, 0.1, 0.0));
        let (p, q) = (m.positions.len() - 2, m.positions.len() - 1);
        m.faces.push([5, p, q]);
        // A duplicate, a flipped face, a degenerate one.
        m.faces.push(m.faces[3]);
        m.faces[7].swap(0, 1);
        m.faces.push([1, 1, 2]);
        let (r, s) = repair_non_manifold(&m);
        assert_eq!(s.invalid_faces_removed, 1);
        assert_eq!(s.duplicate_faces_removed, 1);
        assert_eq!(s.non_manifold_edges, 1);
        assert_eq!(s.non_manifold_edge_faces_removed, 3);
        assert_eq!(s.non_manifold_vertices_split, 1);
        assert_eq!(s.faces_reoriented, 1);
        let rep = mesh_report(&r, &MeshCheckParams::default());
        assert!(rep.manifold && rep.oriented, "{:?}", rep.problems);
        // The sphere minus two faces, plus the fin's leftover-free bow-tie triangle.
        assert_eq!(r.num_faces(), nf - 2 + 1);
    }
}
