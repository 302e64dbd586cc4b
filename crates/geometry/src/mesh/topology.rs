//! Connectivity of an oriented manifold triangle mesh: neighbours across edges and ordered vertex fans.
//!
//! Local edge `e` of face `f = [v0, v1, v2]` runs from `f[e]` to `f[(e + 1) % 3]`; it lies opposite corner
//! `(e + 2) % 3`. Around a vertex, faces are listed counter-clockwise about the outward normal.

use std::collections::HashMap;

use crate::math::{FaceId, VertexId};

/// The face across an edge, and that edge's local index in it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HalfEdgeTwin {
    /// Neighbouring face.
    pub face: FaceId,
    /// Local index (0..3) of the shared edge in `face`.
    pub edge: usize,
}

/// One face around a vertex: the face and the corner (0..3) at which the vertex stands in it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Corner {
    /// The face.
    pub face: FaceId,
    /// Local index of the vertex in the face.
    pub corner: usize,
}

/// Why a face list is not an oriented 2-manifold.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TopologyError {
    /// A face names a vertex index that does not exist.
    #[error("face {face} names vertex {vertex}, but the mesh has {num_vertices} vertices")]
    BadIndex {
        face: FaceId,
        vertex: usize,
        num_vertices: usize,
    },
    /// A face uses the same vertex twice.
    #[error("face {face} repeats vertex {vertex}")]
    RepeatedVertex { face: FaceId, vertex: VertexId },
    /// More than two faces share an edge.
    #[error("edge ({a}, {b}) is shared by more than two faces (non-manifold edge)")]
    NonManifoldEdge { a: VertexId, b: VertexId },
    /// Two faces traverse a shared edge in the same direction.
    #[error(
        "faces {f} and {g} traverse edge ({a}, {b}) in the same direction (inconsistent orientation)"
    )]
    InconsistentOrientation {
        a: VertexId,
        b: VertexId,
        f: FaceId,
        g: FaceId,
    },
    /// The faces around a vertex form more than one fan (pinched, non-manifold vertex).
    #[error("vertex {vertex} is non-manifold: its faces form {fans} separate fans")]
    NonManifoldVertex { vertex: VertexId, fans: usize },
}

/// Connectivity of an oriented manifold triangle mesh (with or without boundary).
#[derive(Clone, Debug)]
pub struct Topology {
    num_vertices: usize,
    faces: Vec<[VertexId; 3]>,
    /// `twins[f][e]`: the face across local edge `e` of `f`, `None` on the boundary.
    twins: Vec<[Option<HalfEdgeTwin>; 3]>,
    /// CSR offsets into `fan` per vertex (`#V + 1`).
    fan_offsets: Vec<usize>,
    /// Faces around each vertex, counter-clockwise; for a boundary vertex the fan starts at a boundary edge.
    fan: Vec<Corner>,
    /// Whether each vertex lies on the boundary.
    on_boundary: Vec<bool>,
}

impl Topology {
    /// Builds the connectivity, or reports the first violation of oriented manifoldness.
    /// Isolated vertices (used by no face) are allowed and have empty fans.
    pub fn new(num_vertices: usize, faces: &[[VertexId; 3]]) -> Result<Self, TopologyError> {
        let mut directed: HashMap<(VertexId, VertexId), (FaceId, usize)> =
            HashMap::with_capacity(faces.len() * 3);
        for (f, face) in faces.iter().enumerate() {
            for (k, &v) in face.iter().enumerate() {
                if v >= num_vertices {
                    return Err(TopologyError::BadIndex {
                        face: f,
                        vertex: v,
                        num_vertices,
                    });
                }
                if face[(k + 1) % 3] == v {
                    return Err(TopologyError::RepeatedVertex { face: f, vertex: v });
                }
            }
            if face[0] == face[2] {
                return Err(TopologyError::RepeatedVertex {
                    face: f,
                    vertex: face[0],
                });
            }
            for e in 0..3 {
                let key = (face[e], face[(e + 1) % 3]);
                if let Some(&(g, _)) = directed.get(&key) {
                    let undirected_count = faces_on_edge(faces, key.0, key.1, f);
                    if undirected_count > 2 {
                        return Err(TopologyError::NonManifoldEdge { a: key.0, b: key.1 });
                    }
                    return Err(TopologyError::InconsistentOrientation {
                        a: key.0,
                        b: key.1,
                        f: g,
                        g: f,
                    });
                }
                directed.insert(key, (f, e));
            }
        }
        let mut twins = vec![[None; 3]; faces.len()];
        for (f, face) in faces.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (face[e], face[(e + 1) % 3]);
                if let Some(&(g, eg)) = directed.get(&(b, a)) {
                    twins[f][e] = Some(HalfEdgeTwin { face: g, edge: eg });
                }
            }
        }

        // Vertex fans, counter-clockwise. In face f with v at corner c, the next face counter-clockwise is the
        // one across the incoming edge (local edge (c + 2) % 3); the previous one is across edge c.
        let mut incident: Vec<Vec<Corner>> = vec![Vec::new(); num_vertices];
        for (f, face) in faces.iter().enumerate() {
            for (c, &v) in face.iter().enumerate() {
                incident[v].push(Corner { face: f, corner: c });
            }
        }
        let mut fan_offsets = Vec::with_capacity(num_vertices + 1);
        let mut fan = Vec::with_capacity(faces.len() * 3);
        let mut on_boundary = vec![false; num_vertices];
        fan_offsets.push(0);
        for (v, corners) in incident.iter().enumerate() {
            if let Some(&first) = corners.first() {
                // Walk clockwise to the fan's start (a face with no neighbour across its outgoing edge).
                let mut start = first;
                loop {
                    match twins[start.face][start.corner] {
                        None => {
                            on_boundary[v] = true;
                            break;
                        }
                        Some(t) => {
                            let prev = Corner {
                                face: t.face,
                                corner: (t.edge + 1) % 3,
                            };
                            debug_assert_eq!(faces[prev.face][prev.corner], v);
                            if prev == first {
                                break;
                            }
                            start = prev;
                        }
                    }
                }
                let begin = fan.len();
                let mut cur = start;
                loop {
                    fan.push(cur);
                    match twins[cur.face][(cur.corner + 2) % 3] {
                        None => break,
                        Some(t) => {
                            let next = Corner {
                                face: t.face,
                                corner: t.edge,
                            };
                            debug_assert_eq!(faces[next.face][next.corner], v);
                            if next == start {
                                break;
                            }
                            cur = next;
                        }
                    }
                    if fan.len() - begin > corners.len() {
                        break;
                    }
                }
                let walked = fan.len() - begin;
                if walked != corners.len() {
                    let fans = count_fans(corners, &twins);
                    return Err(TopologyError::NonManifoldVertex { vertex: v, fans });
                }
            }
            fan_offsets.push(fan.len());
        }
        Ok(Self {
            num_vertices,
            faces: faces.to_vec(),
            twins,
            fan_offsets,
            fan,
            on_boundary,
        })
    }

    /// Number of vertices `#V`.
    pub fn num_vertices(&self) -> usize {
        self.num_vertices
    }

    /// Number of faces `#F`.
    pub fn num_faces(&self) -> usize {
        self.faces.len()
    }

    /// The faces, as given.
    pub fn faces(&self) -> &[[VertexId; 3]] {
        &self.faces
    }

    /// The face across local edge `e` of face `f` (`None` on the boundary).
    pub fn twin(&self, f: FaceId, e: usize) -> Option<HalfEdgeTwin> {
        self.twins[f][e]
    }

    /// The faces around vertex `v`, counter-clockwise about the outward normal.
    pub fn fan(&self, v: VertexId) -> &[Corner] {
        &self.fan[self.fan_offsets[v]..self.fan_offsets[v + 1]]
    }

    /// Number of edges at `v` (the valence): fan size, plus one on the boundary.
    pub fn valence(&self, v: VertexId) -> usize {
        let n = self.fan(v).len();
        if self.on_boundary[v] { n + 1 } else { n }
    }

    /// Whether `v` lies on the boundary.
    pub fn is_boundary_vertex(&self, v: VertexId) -> bool {
        self.on_boundary[v]
    }

    /// The neighbours of `v`, counter-clockwise: for each fan face, the vertex after `v`; on the boundary the
    /// last fan face's third vertex closes the list.
    pub fn one_ring(&self, v: VertexId) -> Vec<VertexId> {
        let fan = self.fan(v);
        let mut ring: Vec<VertexId> = fan
            .iter()
            .map(|c| self.faces[c.face][(c.corner + 1) % 3])
            .collect();
        if self.on_boundary[v] {
            if let Some(last) = fan.last() {
                ring.push(self.faces[last.face][(last.corner + 2) % 3]);
            }
        }
        ring
    }

    /// Whether every edge has two faces.
    pub fn is_closed(&self) -> bool {
        self.twins.iter().all(|t| t.iter().all(Option::is_some))
    }

    /// Boundary edges as directed vertex pairs `(a, b)` following the faces' orientation.
    pub fn boundary_edges(&self) -> Vec<(VertexId, VertexId)> {
        let mut out = Vec::new();
        for (f, t) in self.twins.iter().enumerate() {
            for e in 0..3 {
                if t[e].is_none() {
                    out.push((self.faces[f][e], self.faces[f][(e + 1) % 3]));
                }
            }
        }
        out
    }

    /// Number of undirected edges.
    pub fn num_edges(&self) -> usize {
        let interior: usize = self.twins.iter().flatten().filter(|t| t.is_some()).count();
        let boundary: usize = self.twins.iter().flatten().filter(|t| t.is_none()).count();
        interior / 2 + boundary
    }

    /// Connected components of faces (sharing an edge): a component id per face, and the count.
    pub fn face_components(&self) -> (Vec<usize>, usize) {
        let mut comp = vec![usize::MAX; self.num_faces()];
        let mut count = 0;
        let mut stack = Vec::new();
        for seed in 0..self.num_faces() {
            if comp[seed] != usize::MAX {
                continue;
            }
            comp[seed] = count;
            stack.push(seed);
            while let Some(f) = stack.pop() {
                for t in self.twins[f].iter().flatten() {
                    if comp[t.face] == usize::MAX {
                        comp[t.face] = count;
                        stack.push(t.face);
                    }
                }
            }
            count += 1;
        }
        (comp, count)
    }
}

fn faces_on_edge(faces: &[[VertexId; 3]], a: VertexId, b: VertexId, upto: FaceId) -> usize {
    faces[..=upto]
        .iter()
        .filter(|f| f.contains(&a) && f.contains(&b))
        .count()
}

fn count_fans(corners: &[Corner], twins: &[[Option<HalfEdgeTwin>; 3]]) -> usize {
    // Union the corners that are joined across an edge at this vertex.
    let index = |c: &Corner| corners.iter().position(|d| d == c);
    let mut parent: Vec<usize> = (0..corners.len()).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for (i, c) in corners.iter().enumerate() {
        if let Some(t) = twins[c.face][(c.corner + 2) % 3] {
            if let Some(j) = index(&Corner {
                face: t.face,
                corner: t.edge,
            }) {
                let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                parent[ri] = rj;
            }
        }
    }
    (0..corners.len())
        .filter(|&i| root(&mut parent, i) == i)
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Octahedron: 6 vertices of valence 4, outward oriented.
    fn octahedron() -> Vec<[usize; 3]> {
        // 0:+x 1:-x 2:+y 3:-y 4:+z 5:-z
        vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ]
    }

    #[test]
    fn octahedron_is_closed_with_valence_four() {
        let t = Topology::new(6, &octahedron()).unwrap();
        assert!(t.is_closed());
        assert_eq!(t.num_edges(), 12);
        for v in 0..6 {
            assert_eq!(t.valence(v), 4);
            assert_eq!(t.one_ring(v).len(), 4);
        }
        // Counter-clockwise about +z at the top vertex: +x, +y, −x, −y.
        assert_eq!(
            t.one_ring(4),
            vec![0, 2, 1, 3]
                .into_iter()
                .cycle()
                .skip_while(|&v| v != t.one_ring(4)[0])
                .take(4)
                .collect::<Vec<_>>()
        );
        let (_, n) = t.face_components();
        assert_eq!(n, 1);
    }

    #[test]
    fn twins_are_mutual() {
        let t = Topology::new(6, &octahedron()).unwrap();
        for f in 0..t.num_faces() {
            for e in 0..3 {
                let tw = t.twin(f, e).unwrap();
                assert_eq!(
                    t.twin(tw.face, tw.edge),
                    Some(HalfEdgeTwin { face: f, edge: e })
                );
            }
        }
    }

    #[test]
    fn open_fan_has_boundary() {
        let faces = vec![[0, 1, 2], [0, 2, 3]];
        let t = Topology::new(4, &faces).unwrap();
        assert!(!t.is_closed());
        assert!(t.is_boundary_vertex(0));
        assert_eq!(t.one_ring(0), vec![1, 2, 3]);
        assert_eq!(t.valence(0), 3);
        assert_eq!(t.boundary_edges().len(), 4);
    }

    #[test]
    fn flipped_face_is_inconsistent() {
        let mut faces = octahedron();
        faces[3].swap(1, 2);
        assert!(matches!(
            Topology::new(6, &faces),
            Err(TopologyError::InconsistentOrientation { .. })
        ));
    }

    #[test]
    fn three_faces_on_an_edge_are_non_manifold() {
        let faces = vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]];
        assert!(matches!(
            Topology::new(5, &faces),
            Err(TopologyError::NonManifoldEdge { .. })
        ));
    }

    #[test]
    fn bow_tie_vertex_is_non_manifold() {
        let faces = vec![[0, 1, 2], [0, 3, 4]];
        assert_eq!(
            Topology::new(5, &faces).unwrap_err(),
            TopologyError::NonManifoldVertex { vertex: 0, fans: 2 }
        );
    }
}
