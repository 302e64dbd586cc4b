//! Hole filling: the boundary loops of an oriented 2-manifold, each closed by a patch, and the fairing that
//! makes a patch (once remeshed finer) continue the surrounding surface smoothly.
//!
//! Units: positions in any unit; hole perimeters are reported in that unit.
//!
//! Method: after Liepa 2003, "Filling holes in meshes" (SGP), in three steps: (1) each boundary loop is
//! closed by a fan of triangles around its centroid (Liepa triangulates by a minimum-weight dynamic
//! program; a fan is enough here because the patch is refined by the isotropic remesher that follows,
//! [`super::isotropic_remeshing`]); (2) the patch is refined to the surrounding edge length by that remesher;
//! (3) the patch's vertices are faired to a thin-plate surface with the rest of the mesh held fixed: the
//! squared uniform umbrella operator `U` of Kobbelt, Campagna, Vorsatz & Seidel 1998, "Interactive
//! multi-resolution modeling on arbitrary meshes" (SIGGRAPH), is minimized (its minimizer solves the
//! discrete bi-Laplace equation `U²x = 0` on the patch), which gives tangent continuity across the rim.
//! The least-squares problem is solved by conjugate gradients on the normal equations (CGLS).

use std::collections::HashMap;

use crate::math::{Real, Vec3};
use crate::mesh::TriMesh;

/// One hole that was closed.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FilledHole {
    /// Boundary edges of the hole.
    pub edges: usize,
    /// Length of its rim.
    pub perimeter: Real,
}

/// The boundary loops of an oriented manifold mesh, each as its vertices in the order of its faces'
/// boundary half-edges.
pub fn boundary_loops(mesh: &TriMesh) -> Vec<Vec<usize>> {
    let mut directed: HashMap<(usize, usize), u32> = HashMap::with_capacity(mesh.num_faces() * 3);
    for f in &mesh.faces {
        for k in 0..3 {
            *directed.entry((f[k], f[(k + 1) % 3])).or_default() += 1;
        }
    }
    let mut next: HashMap<usize, Vec<usize>> = HashMap::new();
    for &(a, b) in directed.keys() {
        if !directed.contains_key(&(b, a)) {
            next.entry(a).or_default().push(b);
        }
    }
    let mut starts: Vec<usize> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut loops = Vec::new();
    for s in starts {
        while next.get(&s).is_some_and(|v| !v.is_empty()) {
            let mut lp = vec![s];
            let mut cur = s;
            while let Some(n) = next.get_mut(&cur).and_then(|v| v.pop()) {
                if n == s {
                    break;
                }
                lp.push(n);
                cur = n;
                if lp.len() > mesh.num_vertices() {
                    break;
                }
            }
            if lp.len() >= 3 {
                loops.push(lp);
            }
        }
    }
    loops
}

/// Closes every boundary loop by a fan around its centroid (a triangle for a three-edge hole). Returns the
/// holes and the index of the first patch face (patch faces are the last ones).
pub fn fill_holes_with_fans(mesh: &mut TriMesh) -> (Vec<FilledHole>, usize) {
    let first_patch_face = mesh.num_faces();
    let mut holes = Vec::new();
    for lp in boundary_loops(mesh) {
        let n = lp.len();
        let perimeter: Real = (0..n)
            .map(|i| (mesh.positions[lp[(i + 1) % n]] - mesh.positions[lp[i]]).norm())
            .sum();
        holes.push(FilledHole {
            edges: n,
            perimeter,
        });
        if n == 3 {
            mesh.faces.push([lp[2], lp[1], lp[0]]);
            continue;
        }
        let c = lp.iter().map(|&v| mesh.positions[v]).sum::<Vec3>() / n as Real;
        mesh.positions.push(c);
        let ci = mesh.positions.len() - 1;
        for i in 0..n {
            // The boundary half-edge runs lp[i] → lp[i+1]; the patch runs it backwards.
            mesh.faces.push([lp[(i + 1) % n], lp[i], ci]);
        }
    }
    (holes, first_patch_face)
}

/// Fairs the vertices marked `free` towards a thin-plate surface, the others fixed: minimizes
/// `Σ_i |U(x)_i|²` over the free positions, `U` the uniform umbrella operator (Kobbelt et al. 1998), the sum
/// over every vertex whose umbrella involves a free one. Solved per coordinate by CGLS (conjugate gradients
/// on the normal equations, Hestenes & Stiefel 1952), at most `iterations` steps.
pub fn fair(positions: &mut [Vec3], faces: &[[usize; 3]], free: &[bool], iterations: usize) {
    let nv = positions.len();
    let mut ring: Vec<Vec<usize>> = vec![Vec::new(); nv];
    for f in faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            ring[a].push(b);
            ring[b].push(a);
        }
    }
    for r in &mut ring {
        r.sort_unstable();
        r.dedup();
    }
    let free_list: Vec<usize> = (0..nv)
        .filter(|&v| free[v] && !ring[v].is_empty())
        .collect();
    if free_list.is_empty() {
        return;
    }
    let mut col = vec![usize::MAX; nv];
    for (i, &v) in free_list.iter().enumerate() {
        col[v] = i;
    }
    // Rows: free vertices and their neighbours.
    let mut is_row = vec![false; nv];
    for &v in &free_list {
        is_row[v] = true;
        for &u in &ring[v] {
            is_row[u] = true;
        }
    }
    let rows: Vec<usize> = (0..nv)
        .filter(|&v| is_row[v] && !ring[v].is_empty())
        .collect();
    // U_i = (1/n) Σ_j x_j − x_i as sparse rows over the free columns, plus the fixed part.
    let mut a_rows: Vec<Vec<(usize, Real)>> = Vec::with_capacity(rows.len());
    let mut fixed: Vec<Vec3> = Vec::with_capacity(rows.len());
    for &i in &rows {
        let w = 1.0 / ring[i].len() as Real;
        let mut row = Vec::new();
        let mut c = Vec3::zeros();
        for &j in &ring[i] {
            if col[j] != usize::MAX {
                row.push((col[j], w));
            } else {
                c += w * positions[j];
            }
        }
        if col[i] != usize::MAX {
            row.push((col[i], -1.0));
        } else {
            c -= positions[i];
        }
        a_rows.push(row);
        fixed.push(c);
    }
    let n = free_list.len();
    let apply = |x: &[Real], out: &mut Vec<Real>| {
        out.clear();
        out.extend(
            a_rows
                .iter()
                .map(|r| r.iter().map(|&(j, w)| w * x[j]).sum::<Real>()),
        );
    };
    let apply_t = |y: &[Real], out: &mut Vec<Real>| {
        out.clear();
        out.resize(n, 0.0);
        for (r, &yi) in a_rows.iter().zip(y) {
            for &(j, w) in r {
                out[j] += w * yi;
            }
        }
    };
    for d in 0..3 {
        let mut x: Vec<Real> = free_list.iter().map(|&v| positions[v][d]).collect();
        let b: Vec<Real> = fixed.iter().map(|c| -c[d]).collect();
        let mut ax = Vec::new();
        apply(&x, &mut ax);
        let mut r: Vec<Real> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
        let mut s = Vec::new();
        apply_t(&r, &mut s);
        let mut p = s.clone();
        let mut gamma: Real = s.iter().map(|v| v * v).sum();
        let gamma0 = gamma;
        let mut q = Vec::new();
        for _ in 0..iterations {
            if gamma <= 1e-24 * gamma0.max(Real::MIN_POSITIVE) || gamma == 0.0 {
                break;
            }
            apply(&p, &mut q);
            let qq: Real = q.iter().map(|v| v * v).sum();
            if qq <= 0.0 || !qq.is_finite() {
                break;
            }
            let alpha = gamma / qq;
            for (xi, pi) in x.iter_mut().zip(&p) {
                *xi += alpha * pi;
            }
            for (ri, qi) in r.iter_mut().zip(&q) {
                *ri -= alpha * qi;
            }
            apply_t(&r, &mut s);
            let g: Real = s.iter().map(|v| v * v).sum();
            let beta = g / gamma;
            gamma = g;
            for (pi, si) in p.iter_mut().zip(&s) {
                *pi = si + beta * *pi;
            }
        }
        if x.iter().all(|v| v.is_finite()) {
            for (&v, xi) in free_list.iter().zip(&x) {
                positions[v][d] = *xi;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::check::{MeshCheckParams, mesh_report};
    use crate::test_meshes::icosphere;

    #[test]
    fn holes_in_a_sphere_are_closed() {
        let mut m = icosphere(3, 1.0);
        // Two holes: the faces near the poles ±y.
        let keep: Vec<[usize; 3]> = m
            .faces
            .iter()
            .copied()
            .filter(|f| f.iter().all(|&v| m.positions[v].y.abs() < 0.9))
            .collect();
        m.faces = keep;
        assert_eq!(boundary_loops(&m).len(), 2);
        let (holes, first) = fill_holes_with_fans(&mut m);
        assert_eq!(holes.len(), 2);
        assert!(first < m.num_faces());
        let r = mesh_report(&m, &MeshCheckParams::default());
        assert!(r.closed && r.manifold && r.oriented, "{:?}", r.problems);
        assert_eq!(r.genus, Some(0));
        assert!(m.signed_volume() > 0.0);
    }

    #[test]
    fn fairing_lifts_a_flat_cap_towards_the_sphere() {
        let mut m = icosphere(4, 1.0);
        let free: Vec<bool> = m.positions.iter().map(|p| p.y > 0.8).collect();
        for (p, &f) in m.positions.iter_mut().zip(&free) {
            if f {
                p.y = 0.8;
            }
        }
        let top = |m: &TriMesh| m.positions.iter().map(|p| p.y).fold(Real::MIN, Real::max);
        fair(&mut m.positions, &m.faces, &free, 300);
        assert!(top(&m) > 0.95, "{}", top(&m));
    }
}
