//! Isotropic remeshing of a closed 2-manifold triangle surface to a target edge length, each vertex kept on
//! a reference surface (the scan).
//!
//! Units: positions and lengths in the mesh's unit (metres in skintight).
//!
//! Method: Botsch & Kobbelt 2004, "A remeshing approach to multiresolution modeling" (SGP): repeat
//! (1) split edges longer than 4/3 L at their midpoint, (2) collapse edges shorter than 4/5 L unless that
//! makes an edge longer than 4/3 L, (3) flip edges when that brings the four valences nearer to 6,
//! (4) move each vertex tangentially towards the centroid of its neighbours and project it onto the
//! reference surface. A first shortest-edge-first collapse pass (the collapse step of (2) with a priority
//! queue, as in incremental decimation, Hoppe 1996 "Progressive meshes") reduces a dense scan to the target
//! resolution before the loop, so the loop works on a mesh of the target size.
//!
//! A collapse places the merged vertex at the edge's midpoint or at one of its ends, whichever leaves the
//! two old positions nearest to the new triangles, and is refused when that distance exceeds a bound
//! (the one-sided local error of Garland & Heckbert 1997's framework, measured directly), so thin parts such
//! as fingers keep shorter edges rather than being shortened.
//!
//! [`adaptive_remesh`] runs the same loop with a target length per vertex instead of one (an edge's target
//! is the smaller of its ends'; the thresholds 4/5 and 4/3 apply to it), as in Dunyach, Vanderhaeghe,
//! Barthe & Botsch 2013, "Adaptive remeshing for real-time mesh deformation"; the lengths come from
//! [`super::curvature_sizing`].
//!
//! Every collapse checks the link condition (Dey, Edelsbrunner, Guha, Nekhayev 1999, "Topology preserving
//! edge contraction"), so the result stays a closed 2-manifold of the same genus; collapses and flips that
//! would turn a face over are refused. Projection uses the grid closest-point query of
//! [`super::surface_deviation`].
//!
//! Library choice: no mesh-processing crate is used. `meshopt` (meshoptimizer) decimates fast but does not
//! promise a manifold result of unchanged genus, which the body needs; this module's own link-condition
//! collapses do, and the few operations needed are short.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::surface_deviation::{ClosestPointGrid, closest_point_on_triangle};
use crate::math::{Real, Vec3};
use crate::mesh::TriMesh;

/// Settings of [`isotropic_remesh`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsotropicRemeshParams {
    /// Target edge length L.
    pub target_edge: Real,
    /// Split–collapse–flip–relax rounds after the first reduction (Botsch & Kobbelt use 5–10).
    pub iterations: usize,
    /// Largest distance a collapse may leave between the two old vertex positions and the new triangles
    /// around the merged vertex; keeps thin features (fingers) from being eaten.
    pub max_collapse_error: Real,
    /// Splitting stops at this many faces (a coarse input far from the target resolution cannot explode).
    pub max_faces: usize,
}

impl Default for IsotropicRemeshParams {
    fn default() -> Self {
        Self {
            target_edge: 0.012,
            iterations: 5,
            max_collapse_error: 0.0015,
            max_faces: 10_000_000,
        }
    }
}

/// A triangle mesh under local edits: faces may die, vertices may die.
struct DynMesh {
    p: Vec<Vec3>,
    f: Vec<[u32; 3]>,
    fdead: Vec<bool>,
    vf: Vec<Vec<u32>>,
    vdead: Vec<bool>,
    /// Target edge length at each vertex; an edge's target is the smaller of its ends'.
    size: Vec<Real>,
}

fn normal(a: &Vec3, b: &Vec3, c: &Vec3) -> Vec3 {
    (b - a).cross(&(c - a))
}

impl DynMesh {
    fn new(mesh: &TriMesh) -> Self {
        let nv = mesh.num_vertices();
        let mut vf = vec![Vec::new(); nv];
        let f: Vec<[u32; 3]> = mesh.faces.iter().map(|f| f.map(|v| v as u32)).collect();
        for (i, face) in f.iter().enumerate() {
            for &v in face {
                vf[v as usize].push(i as u32);
            }
        }
        Self {
            p: mesh.positions.clone(),
            fdead: vec![false; f.len()],
            f,
            vf,
            vdead: vec![false; nv],
            size: vec![0.0; nv],
        }
    }

    fn to_mesh(&self) -> TriMesh {
        let mut map = vec![usize::MAX; self.p.len()];
        let mut positions = Vec::new();
        for (v, slot) in map.iter_mut().enumerate() {
            if !self.vdead[v] && !self.vf[v].is_empty() {
                *slot = positions.len();
                positions.push(self.p[v]);
            }
        }
        let faces = self
            .f
            .iter()
            .zip(&self.fdead)
            .filter(|(_, d)| !**d)
            .map(|(f, _)| f.map(|v| map[v as usize]))
            .collect();
        TriMesh::new(positions, faces)
    }

    /// Faces containing edge (a, b).
    fn edge_faces(&self, a: u32, b: u32) -> Vec<u32> {
        self.vf[a as usize]
            .iter()
            .copied()
            .filter(|&g| self.f[g as usize].contains(&b))
            .collect()
    }

    fn ring(&self, v: u32) -> Vec<u32> {
        let mut r: Vec<u32> = self.vf[v as usize]
            .iter()
            .flat_map(|&g| self.f[g as usize])
            .filter(|&u| u != v)
            .collect();
        r.sort_unstable();
        r.dedup();
        r
    }

    fn len(&self, a: u32, b: u32) -> Real {
        (self.p[a as usize] - self.p[b as usize]).norm()
    }

    /// Target length of edge (a, b): the smaller of its ends' sizes.
    fn target(&self, a: u32, b: u32) -> Real {
        self.size[a as usize].min(self.size[b as usize])
    }

    /// The vertex of face g that is neither a nor b.
    fn opposite(&self, g: u32, a: u32, b: u32) -> u32 {
        self.f[g as usize]
            .into_iter()
            .find(|&v| v != a && v != b)
            .unwrap_or(a)
    }

    /// Collapses b into a, placing the merged vertex at the midpoint or at one of the two ends, whichever
    /// keeps the old positions of a and b nearest to the new triangles (at most `max_err` away). Refuses
    /// when the result would not be a manifold of the same genus, a face would turn over, or an edge would
    /// get longer than `hi` times its target length. The merged vertex takes the smaller size.
    fn collapse(&mut self, a: u32, b: u32, hi: Real, max_err: Real) -> bool {
        let size = self.size[a as usize].min(self.size[b as usize]);
        let max_len = hi * size;
        let ef = self.edge_faces(a, b);
        if ef.len() != 2 {
            return false;
        }
        let c = self.opposite(ef[0], a, b);
        let d = self.opposite(ef[1], a, b);
        if c == d || self.vf[c as usize].len() <= 3 || self.vf[d as usize].len() <= 3 {
            return false;
        }
        let ra = self.ring(a);
        let rb = self.ring(b);
        let common = ra.iter().filter(|v| rb.binary_search(v).is_ok()).count();
        if common != 2 || ra.len() + rb.len() > 4 + 16 {
            return false;
        }
        let (pa, pb) = (self.p[a as usize], self.p[b as usize]);
        let fan: Vec<[u32; 3]> = [a, b]
            .iter()
            .flat_map(|&v| self.vf[v as usize].iter())
            .filter(|g| !ef.contains(g))
            .map(|&g| self.f[g as usize])
            .collect();
        let error = |m: &Vec3| {
            let tri = |f: &[u32; 3]| {
                f.map(|u| {
                    if u == a || u == b {
                        *m
                    } else {
                        self.p[u as usize]
                    }
                })
            };
            [pa, pb]
                .iter()
                .map(|q| {
                    fan.iter()
                        .map(|f| {
                            let [x, y, z] = tri(f);
                            (closest_point_on_triangle(q, &x, &y, &z) - q).norm()
                        })
                        .fold(Real::INFINITY, Real::min)
                })
                .fold(0.0, Real::max)
        };
        let mut candidates: Vec<(Real, Vec3)> = [0.5 * (pa + pb), pa, pb]
            .into_iter()
            .map(|m| (error(&m), m))
            .filter(|(e, _)| *e <= max_err)
            .collect();
        // Prefer the midpoint (it averages noise) unless an end is clearly better.
        candidates.sort_by(|x, y| x.0.total_cmp(&y.0));
        let Some(&(_, m)) = candidates
            .iter()
            .find(|(e, m)| *m == 0.5 * (pa + pb) && *e <= 0.25 * max_err)
            .or(candidates.first())
        else {
            return false;
        };
        if ra.iter().chain(&rb).any(|&u| {
            u != a
                && u != b
                && (self.p[u as usize] - m).norm() > hi * size.min(self.size[u as usize])
        }) {
            return false;
        }
        for f in &fan {
            let old = f.map(|u| self.p[u as usize]);
            let new = f.map(|u| {
                if u == a || u == b {
                    m
                } else {
                    self.p[u as usize]
                }
            });
            let n0 = normal(&old[0], &old[1], &old[2]);
            let n1 = normal(&new[0], &new[1], &new[2]);
            let (l0, l1) = (n0.norm(), n1.norm());
            if l1 <= 1e-14 * max_len * max_len || n0.dot(&n1) <= 0.2 * l0 * l1 {
                return false;
            }
        }
        for &g in &ef {
            self.fdead[g as usize] = true;
            for v in self.f[g as usize] {
                self.vf[v as usize].retain(|&h| h != g);
            }
        }
        let moved = std::mem::take(&mut self.vf[b as usize]);
        for &g in &moved {
            for v in &mut self.f[g as usize] {
                if *v == b {
                    *v = a;
                }
            }
        }
        self.vf[a as usize].extend(moved);
        self.vdead[b as usize] = true;
        self.p[a as usize] = m;
        self.size[a as usize] = size;
        true
    }

    /// Splits edge (a, b) at its midpoint.
    fn split(&mut self, a: u32, b: u32) -> bool {
        let ef = self.edge_faces(a, b);
        if ef.len() != 2 {
            return false;
        }
        let m = self.p.len() as u32;
        self.p.push(0.5 * (self.p[a as usize] + self.p[b as usize]));
        self.size
            .push(0.5 * (self.size[a as usize] + self.size[b as usize]));
        self.vf.push(Vec::new());
        self.vdead.push(false);
        for g in ef {
            let f = self.f[g as usize];
            let k = (0..3)
                .find(|&k| {
                    let (x, y) = (f[k], f[(k + 1) % 3]);
                    (x == a && y == b) || (x == b && y == a)
                })
                .unwrap_or(0);
            let (x, y, z) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
            self.f[g as usize] = [x, m, z];
            let h = self.f.len() as u32;
            self.f.push([m, y, z]);
            self.fdead.push(false);
            for slot in self.vf[y as usize].iter_mut() {
                if *slot == g {
                    *slot = h;
                }
            }
            self.vf[z as usize].push(h);
            self.vf[m as usize].push(g);
            self.vf[m as usize].push(h);
        }
        true
    }

    /// Flips edge (a, b) when that brings the valences nearer to 6 and turns no face over.
    fn flip_if_better(&mut self, a: u32, b: u32) -> bool {
        let ef = self.edge_faces(a, b);
        if ef.len() != 2 {
            return false;
        }
        // Orient: g1 runs a → b.
        let runs = |g: u32| {
            let f = self.f[g as usize];
            (0..3).any(|k| f[k] == a && f[(k + 1) % 3] == b)
        };
        let (g1, g2) = if runs(ef[0]) {
            (ef[0], ef[1])
        } else {
            (ef[1], ef[0])
        };
        let c = self.opposite(g1, a, b);
        let d = self.opposite(g2, a, b);
        if c == d {
            return false;
        }
        let val = |v: u32| self.vf[v as usize].len() as i64;
        let (va, vb, vc, vd) = (val(a), val(b), val(c), val(d));
        if va <= 3 || vb <= 3 {
            return false;
        }
        let dev = |x: i64| (x - 6) * (x - 6);
        let before = dev(va) + dev(vb) + dev(vc) + dev(vd);
        let after = dev(va - 1) + dev(vb - 1) + dev(vc + 1) + dev(vd + 1);
        if after >= before {
            return false;
        }
        if self.vf[c as usize]
            .iter()
            .any(|&g| self.f[g as usize].contains(&d))
        {
            return false;
        }
        let p = |v: u32| self.p[v as usize];
        let old = normal(&p(a), &p(b), &p(c)).normalize() + normal(&p(b), &p(a), &p(d)).normalize();
        let n1 = normal(&p(c), &p(a), &p(d));
        let n2 = normal(&p(d), &p(b), &p(c));
        let ok = |n: &Vec3| {
            let l = n.norm();
            l > 0.0 && n.dot(&old) > 0.5 * l * old.norm()
        };
        if !old.iter().all(|x| x.is_finite()) || !ok(&n1) || !ok(&n2) {
            return false;
        }
        self.f[g1 as usize] = [c, a, d];
        self.f[g2 as usize] = [d, b, c];
        self.vf[b as usize].retain(|&h| h != g1);
        self.vf[d as usize].push(g1);
        self.vf[a as usize].retain(|&h| h != g2);
        self.vf[c as usize].push(g2);
        true
    }

    fn edges(&self) -> Vec<(u32, u32)> {
        let mut e = Vec::new();
        for (g, f) in self.f.iter().enumerate() {
            if self.fdead[g] {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                if a < b {
                    e.push((a, b));
                }
            }
        }
        e
    }

    /// Collapses edges shorter than `lo` times their target length, relatively shortest first, keeping every
    /// edge at most `hi` times its target and each collapse's error at most `max_err`.
    fn collapse_short(&mut self, lo: Real, hi: Real, max_err: Real) -> usize {
        let key = |l: Real| l.to_bits();
        let rel = |m: &Self, a: u32, b: u32| m.len(a, b) / m.target(a, b);
        let mut heap: BinaryHeap<Reverse<(u64, u32, u32)>> = self
            .edges()
            .into_iter()
            .filter_map(|(a, b)| {
                let l = rel(self, a, b);
                (l < lo).then(|| Reverse((key(l), a, b)))
            })
            .collect();
        let mut done = 0;
        while let Some(Reverse((k, a, b))) = heap.pop() {
            if self.vdead[a as usize] || self.vdead[b as usize] {
                continue;
            }
            let l = rel(self, a, b);
            if key(l) != k || l >= lo {
                continue;
            }
            if self.collapse(a, b, hi, max_err) {
                done += 1;
                for u in self.ring(a) {
                    let l = rel(self, a, u);
                    if l < lo {
                        heap.push(Reverse((key(l), a.min(u), a.max(u))));
                    }
                }
            }
        }
        done
    }

    /// Splits edges longer than `hi` times their target length, relatively longest first.
    fn split_long(&mut self, hi: Real, max_faces: usize) -> usize {
        let mut done = 0;
        let rel = |m: &Self, a: u32, b: u32| m.len(a, b) / m.target(a, b);
        for _ in 0..12 {
            let mut long: Vec<(u32, u32)> = self
                .edges()
                .into_iter()
                .filter(|&(a, b)| rel(self, a, b) > hi)
                .collect();
            if long.is_empty() {
                break;
            }
            long.sort_by(|x, y| rel(self, y.0, y.1).total_cmp(&rel(self, x.0, x.1)));
            for (a, b) in long {
                if self.f.len() >= max_faces {
                    return done;
                }
                if rel(self, a, b) > hi && self.split(a, b) {
                    done += 1;
                }
            }
        }
        done
    }

    fn equalize_valences(&mut self) -> usize {
        let mut done = 0;
        for (a, b) in self.edges() {
            if self.flip_if_better(a, b) {
                done += 1;
            }
        }
        done
    }

    fn vertex_normals(&self) -> Vec<Vec3> {
        let mut n = vec![Vec3::zeros(); self.p.len()];
        for (g, f) in self.f.iter().enumerate() {
            if self.fdead[g] {
                continue;
            }
            let fn_ = normal(
                &self.p[f[0] as usize],
                &self.p[f[1] as usize],
                &self.p[f[2] as usize],
            );
            for &v in f {
                n[v as usize] += fn_;
            }
        }
        for x in &mut n {
            let l = x.norm();
            if l > 0.0 {
                *x /= l;
            }
        }
        n
    }

    /// Tangential relaxation towards the neighbours' centroid, then projection onto the reference.
    /// Returns the reference face each vertex landed on (`u32::MAX` for dead vertices).
    fn relax_and_project(&mut self, reference: &ClosestPointGrid, relax: bool) -> Vec<u32> {
        let normals = self.vertex_normals();
        let old = self.p.clone();
        if relax {
            for v in 0..self.p.len() {
                if self.vdead[v] || self.vf[v].is_empty() {
                    continue;
                }
                let r = self.ring(v as u32);
                let q = r.iter().map(|&u| old[u as usize]).sum::<Vec3>() / r.len() as Real;
                let d = q - old[v];
                let n = normals[v];
                self.p[v] = old[v] + d - n * n.dot(&d);
            }
        }
        let mut landed = vec![u32::MAX; self.p.len()];
        let mut seen = Vec::new();
        let mut stamp = 0;
        for v in 0..self.p.len() {
            if self.vdead[v] || self.vf[v].is_empty() {
                continue;
            }
            if let Some(c) = reference.closest(&self.p[v], &mut seen, &mut stamp) {
                // A thin part's other side may be nearer: project only onto a face of the same side.
                if reference.face_normal(c.face).dot(&normals[v]) > 0.0 {
                    self.p[v] = c.point;
                }
                landed[v] = c.face as u32;
            }
        }
        landed
    }
}

/// What the remesher did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RemeshOutcome {
    /// The remeshed surface.
    pub mesh: TriMesh,
    /// For each output vertex, the reference face it was last projected onto.
    pub reference_face: Vec<usize>,
}

/// Remeshes a closed 2-manifold `mesh` to edge length about `params.target_edge`, keeping the vertices on
/// `reference` (usually the mesh itself at full resolution).
pub fn isotropic_remesh(
    mesh: &TriMesh,
    reference: &ClosestPointGrid,
    params: &IsotropicRemeshParams,
) -> RemeshOutcome {
    let sizes = vec![params.target_edge; mesh.num_vertices()];
    adaptive_remesh(mesh, reference, params, &sizes)
}

/// [`isotropic_remesh`] with a target edge length per vertex of `mesh` (`sizes`, finite and > 0; an
/// edge's target is the smaller of its ends', a vertex made by a split takes the mean of the two):
/// adaptive remeshing in the manner of Dunyach, Vanderhaeghe, Barthe & Botsch 2013 ("Adaptive remeshing
/// for real-time mesh deformation"). `params.target_edge` only scales the collapse error bound.
pub fn adaptive_remesh(
    mesh: &TriMesh,
    reference: &ClosestPointGrid,
    params: &IsotropicRemeshParams,
    sizes: &[Real],
) -> RemeshOutcome {
    let (lo, hi) = (0.8, 4.0 / 3.0);
    let max_err = params.max_collapse_error;
    let mut m = DynMesh::new(mesh);
    for (s, &x) in m.size.iter_mut().zip(sizes) {
        *s = if x.is_finite() && x > 0.0 {
            x
        } else {
            params.target_edge
        };
    }
    m.collapse_short(lo, hi, max_err);
    let mut landed = Vec::new();
    for _ in 0..params.iterations.max(1) {
        m.split_long(hi, params.max_faces);
        m.collapse_short(lo, hi, max_err);
        m.equalize_valences();
        landed = m.relax_and_project(reference, true);
    }
    // Compact, carrying the landing faces along.
    let out = m.to_mesh();
    let reference_face = (0..m.p.len())
        .filter(|&v| !m.vdead[v] && !m.vf[v].is_empty())
        .map(|v| landed.get(v).copied().unwrap_or(u32::MAX) as usize)
        .collect();
    RemeshOutcome {
        mesh: out,
        reference_face,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::check::{MeshCheckParams, mesh_report};
    use crate::mesh::self_intersection::mean_edge_length;
    use crate::test_meshes::icosphere;

    #[test]
    fn dense_sphere_is_coarsened_to_the_target_and_stays_a_sphere() {
        let m = icosphere(5, 1.0); // 20480 faces, edge ≈ 0.038
        let grid = ClosestPointGrid::new(&m.positions, &m.faces, 0.05);
        let out = isotropic_remesh(
            &m,
            &grid,
            &IsotropicRemeshParams {
                target_edge: 0.15,
                iterations: 5,
                max_collapse_error: 0.02,
                max_faces: 1_000_000,
            },
        );
        let r = mesh_report(&out.mesh, &MeshCheckParams::default());
        assert!(r.closed && r.manifold && r.oriented, "{:?}", r.problems);
        assert_eq!(r.genus, Some(0));
        let mean = mean_edge_length(&out.mesh.positions, &out.mesh.faces);
        assert!((mean - 0.15).abs() < 0.03, "{mean}");
        for p in &out.mesh.positions {
            assert!((p.norm() - 1.0).abs() < 2e-3);
        }
        assert!(out.mesh.signed_volume() > 0.0);
    }

    #[test]
    fn coarse_sphere_is_refined() {
        let m = icosphere(1, 1.0);
        let fine = icosphere(5, 1.0);
        let grid = ClosestPointGrid::new(&fine.positions, &fine.faces, 0.05);
        let out = isotropic_remesh(
            &m,
            &grid,
            &IsotropicRemeshParams {
                target_edge: 0.2,
                iterations: 4,
                max_collapse_error: 0.02,
                max_faces: 1_000_000,
            },
        );
        let r = mesh_report(&out.mesh, &MeshCheckParams::default());
        assert!(r.closed && r.manifold, "{:?}", r.problems);
        assert!(out.mesh.num_faces() > 300, "{}", out.mesh.num_faces());
        assert_eq!(out.reference_face.len(), out.mesh.num_vertices());
    }
}
