//! Unbiased fit of a coarse remeshed surface to the dense scan it was made from: each vertex moves along its
//! normal so that the coarse surface straddles the scan in the least-squares sense, instead of lying inside
//! it.
//!
//! **Why.** Isotropic remeshing leaves every vertex *on* the scan, so each coarse face is a chord of the
//! (curved) scan surface and lies inside it where the scan is convex: an equilateral triangle of edge `e`
//! with its corners on a sphere of radius `r` lies `(R_t² − |x|²) / (2r)` inside it at a point `x` from
//! its centre (`R_t = e/√3`), `e² / (8r)` on average over the triangle. On a limb of radius 40 mm remeshed
//! at 12 mm edges that is 0.45 mm, and every girth is short by a few millimetres: a systematic bias, not
//! noise. (A tape-measure girth — a convex-hull perimeter — of a polygon with its corners on a circle is
//! short by 2π/3 of the chords' sagitta; of a polygon straddling the circle, over by as much. A coarse
//! surface that straddles a surface of the same resolution — the 12k body the scans are made from — reads
//! that surface's girths.)
//!
//! **Equation.** Let the coarse surface have vertices `p_v`, unit vertex normals `n_v`, and let the vertex
//! `v` move to `p_v + d_v n_v`. On each face `f` (unit normal `n_f`, area `A_f`) take the sample points
//! `x_k` of the 7-point triangle rule exact for cubic polynomials (corners weight 1/20, edge midpoints 2/15,
//! centroid 9/20, each times `A_f`: the weights `w_k`), with hat-function values `φ_v(x_k)`. The signed
//! distance of a sample to the scan is
//!
//! ```text
//!     s_k = (x_k − q_k) · n_f,        q_k = the closest point of the scan to x_k,
//! ```
//!
//! positive outside the scan. The fit minimizes `E(d) = Σ_k w_k s_k(d)²`. Linearized,
//! `s_k(d + δ) ≈ s_k + Σ_v φ_v(x_k) c_kv δ_v` with `c_kv = n_f · n_v`; one Jacobi step on the normal
//! equations with the matrix lumped to its row sums (`Σ_u φ_u = 1`) is
//!
//! ```text
//!     δ_v = − Σ_k w_k φ_v(x_k) c_kv s_k  /  Σ_k w_k φ_v(x_k) c_kv²,
//! ```
//!
//! a weighted mean of minus the signed distances of the samples on the faces around `v`. The step is
//! clamped to `|δ_v| ≤ max_step` and the total displacement to `|d_v| ≤ max_offset`, and the closest points
//! are recomputed before the next step (Gauss–Newton with a lumped matrix; the lumped P1 mass matrix bounds
//! the consistent one, so the iteration does not overshoot). At the fixed point the area-weighted mean
//! signed distance of the coarse surface from the scan, around every vertex, is zero: the surface encloses
//! the volume the scan encloses, and a tape measure around it reads what it reads on the scan to within the
//! difference of the two surfaces' own chord effects.
//!
//! A sample is left out when its closest point is farther than `max_distance` (it lies over a hole of the
//! scan: the filled soles and crown, where the scan has no data) or on a scan face turned away from the
//! coarse face (the far side of a thin part). Fixed vertices (hole patches) do not move.
//!
//! Units: positions, distances and steps in the meshes' unit (metres in skintight).

use std::collections::HashMap;

use super::surface_deviation::ClosestPointGrid;
use crate::math::{Real, Vec3};
use crate::mesh::TriMesh;

/// Settings of [`unbiased_fit`] (lengths in the mesh's unit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitParams {
    /// Gauss–Newton steps.
    pub iterations: usize,
    /// Largest move of a vertex in one step.
    pub max_step: Real,
    /// Largest total move of a vertex.
    pub max_offset: Real,
    /// Samples farther than this from the scan are left out (holes of the scan).
    pub max_distance: Real,
}

impl FitParams {
    /// Settings for a surface of mean edge length `edge`: 3 steps of at most `edge / 20`, at most
    /// `edge / 8` in all, samples within `edge / 4` of the scan.
    pub fn for_edge_length(edge: Real) -> Self {
        Self {
            iterations: 3,
            max_step: edge / 20.0,
            max_offset: edge / 8.0,
            max_distance: edge / 4.0,
        }
    }
}

/// What [`unbiased_fit`] found and did (lengths in the mesh's unit).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FitSummary {
    /// Area-weighted mean signed distance of the surface from the scan before the fit (negative: inside).
    pub signed_mean_before: Real,
    /// The same after the fit.
    pub signed_mean_after: Real,
    /// Area-weighted root-mean-square distance before the fit.
    pub rms_before: Real,
    /// The same after the fit.
    pub rms_after: Real,
    /// Largest displacement of a vertex.
    pub max_displacement: Real,
    /// Fraction of the sample weight left out (over holes, across thin parts).
    pub excluded_fraction: Real,
}

/// Quadrature of one face: (corner weights, edge-midpoint weights, centroid weight); exact for cubics.
const W_CORNER: Real = 1.0 / 20.0;
const W_MIDPOINT: Real = 2.0 / 15.0;
const W_CENTROID: Real = 9.0 / 20.0;

/// Signed distances of the sample points of `mesh` (vertices, edge midpoints, centroids) to the scan.
struct Samples {
    /// Per vertex, per edge (index in `edges`), per face: `x − q` and whether the sample counts.
    vertex: Vec<Option<Vec3>>,
    edge: Vec<Option<Vec3>>,
    centroid: Vec<Option<Vec3>>,
}

fn unit_face_normals(mesh: &TriMesh) -> (Vec<Vec3>, Vec<Real>) {
    let mut normals = Vec::with_capacity(mesh.num_faces());
    let mut areas = Vec::with_capacity(mesh.num_faces());
    for f in 0..mesh.num_faces() {
        let n = mesh.face_area_normal(f);
        let l = n.norm();
        areas.push(0.5 * l);
        normals.push(if l > 0.0 { n / l } else { Vec3::zeros() });
    }
    (normals, areas)
}

/// The edges of `mesh` (sorted vertex pairs) and, per face, the index of its edge `k` → `k + 1`.
fn edges(mesh: &TriMesh) -> (Vec<[usize; 2]>, Vec<[usize; 3]>) {
    let mut index: HashMap<(usize, usize), usize> = HashMap::with_capacity(2 * mesh.num_faces());
    let mut list = Vec::new();
    let face_edges = mesh
        .faces
        .iter()
        .map(|f| {
            std::array::from_fn(|k| {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                *index.entry(key).or_insert_with(|| {
                    list.push([key.0, key.1]);
                    list.len() - 1
                })
            })
        })
        .collect();
    (list, face_edges)
}

impl Samples {
    /// Closest points of the scan to every sample point. A sample's offset `x − q` is kept when it is
    /// within `max_distance` and the scan face is turned towards the sample's side (`n_ref · n > 0` for the
    /// normal `n` of the coarse surface there).
    fn new(
        mesh: &TriMesh,
        edge_list: &[[usize; 2]],
        vnormal: &[Vec3],
        fnormal: &[Vec3],
        scan: &ClosestPointGrid,
        max_distance: Real,
    ) -> Self {
        let mut seen = Vec::new();
        let mut stamp = 0u32;
        let mut query = |x: Vec3, n: Vec3| -> Option<Vec3> {
            let c = scan.closest(&x, &mut seen, &mut stamp)?;
            (c.distance <= max_distance && scan.face_normal(c.face).dot(&n) > 0.0)
                .then_some(x - c.point)
        };
        let p = &mesh.positions;
        let vertex = (0..p.len()).map(|v| query(p[v], vnormal[v])).collect();
        let edge = edge_list
            .iter()
            .map(|&[a, b]| query(0.5 * (p[a] + p[b]), vnormal[a] + vnormal[b]))
            .collect();
        let centroid = mesh
            .faces
            .iter()
            .zip(fnormal)
            .map(|(f, n)| query((p[f[0]] + p[f[1]] + p[f[2]]) / 3.0, *n))
            .collect();
        Self {
            vertex,
            edge,
            centroid,
        }
    }
}

/// One evaluation: per vertex the numerator and denominator of the Jacobi step, and the surface's
/// weighted mean signed distance, RMS distance and excluded weight fraction.
struct Evaluation {
    num: Vec<Real>,
    den: Vec<Real>,
    mean: Real,
    rms: Real,
    excluded: Real,
}

fn evaluate(
    mesh: &TriMesh,
    face_edges: &[[usize; 3]],
    vnormal: &[Vec3],
    fnormal: &[Vec3],
    areas: &[Real],
    s: &Samples,
) -> Evaluation {
    let nv = mesh.num_vertices();
    let mut num = vec![0.0; nv];
    let mut den = vec![0.0; nv];
    let (mut sum, mut sum2, mut wsum, mut wall) = (0.0, 0.0, 0.0, 0.0);
    for (f, face) in mesh.faces.iter().enumerate() {
        let (n, area) = (fnormal[f], areas[f]);
        if area.is_nan() || area <= 0.0 {
            continue;
        }
        // Each sample: (offset, weight, [(vertex, φ)]).
        let mut add = |off: Option<Vec3>, w: Real, hats: &[(usize, Real)]| {
            let w = w * area;
            wall += w;
            let Some(off) = off else { return };
            let sd = off.dot(&n);
            sum += w * sd;
            sum2 += w * sd * sd;
            wsum += w;
            for &(v, phi) in hats {
                let c = n.dot(&vnormal[v]);
                num[v] += w * phi * c * sd;
                den[v] += w * phi * c * c;
            }
        };
        for k in 0..3 {
            add(s.vertex[face[k]], W_CORNER, &[(face[k], 1.0)]);
            add(
                s.edge[face_edges[f][k]],
                W_MIDPOINT,
                &[(face[k], 0.5), (face[(k + 1) % 3], 0.5)],
            );
        }
        let third = 1.0 / 3.0;
        add(
            s.centroid[f],
            W_CENTROID,
            &[(face[0], third), (face[1], third), (face[2], third)],
        );
    }
    Evaluation {
        num,
        den,
        mean: if wsum > 0.0 { sum / wsum } else { 0.0 },
        rms: if wsum > 0.0 {
            (sum2 / wsum).sqrt()
        } else {
            0.0
        },
        excluded: if wall > 0.0 { 1.0 - wsum / wall } else { 0.0 },
    }
}

/// Moves the vertices of `mesh` (closed or not; its connectivity is unchanged) along their normals so that
/// it straddles `scan` in the least-squares sense; vertices with `fixed[v]` stay. See the module
/// documentation for the equation.
pub fn unbiased_fit(
    mesh: &mut TriMesh,
    scan: &ClosestPointGrid,
    fixed: &[bool],
    params: &FitParams,
) -> FitSummary {
    let (edge_list, face_edges) = edges(mesh);
    let nv = mesh.num_vertices();
    let mut offset = vec![0.0; nv];
    let mut summary = FitSummary::default();
    for it in 0..=params.iterations {
        let (fnormal, areas) = unit_face_normals(mesh);
        let vnormal = mesh.vertex_normals();
        let samples = Samples::new(
            mesh,
            &edge_list,
            &vnormal,
            &fnormal,
            scan,
            params.max_distance,
        );
        let e = evaluate(mesh, &face_edges, &vnormal, &fnormal, &areas, &samples);
        if it == 0 {
            summary.signed_mean_before = e.mean;
            summary.rms_before = e.rms;
        }
        summary.signed_mean_after = e.mean;
        summary.rms_after = e.rms;
        summary.excluded_fraction = e.excluded;
        if it == params.iterations {
            break;
        }
        for v in 0..nv {
            if fixed.get(v).copied().unwrap_or(false) || e.den[v].is_nan() || e.den[v] <= 0.0 {
                continue;
            }
            let step = (-e.num[v] / e.den[v]).clamp(-params.max_step, params.max_step);
            let total = (offset[v] + step).clamp(-params.max_offset, params.max_offset);
            let step = total - offset[v];
            if step.is_finite() {
                offset[v] = total;
                mesh.positions[v] += step * vnormal[v];
            }
        }
    }
    summary.max_displacement = offset.iter().fold(0.0, |m: Real, d| m.max(d.abs()));
    summary
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anthropometry::girth::girth;
    use crate::anthropometry::plane_section::plane_section;
    use crate::test_meshes::icosphere;

    /// Tape-measure girth of `mesh` in the plane `z = h`.
    fn girth_at(mesh: &TriMesh, h: Real) -> Real {
        let loops = plane_section(mesh, Vec3::z(), h);
        assert_eq!(loops.len(), 1);
        girth(&loops[0], Vec3::z())
    }

    /// A coarse icosphere with its vertices on a sphere of radius r (chords inside it, as a remesh of a
    /// scan leaves them), fitted to a dense icosphere of the same radius standing for the scan.
    fn fitted_sphere(r: Real) -> (TriMesh, TriMesh, TriMesh, FitSummary) {
        let dense = icosphere(6, r);
        let scan = ClosestPointGrid::new(&dense.positions, &dense.faces, 0.04 * r);
        let coarse = icosphere(2, r);
        let mut fitted = coarse.clone();
        let edge =
            crate::mesh::self_intersection::mean_edge_length(&coarse.positions, &coarse.faces);
        let fixed = vec![false; fitted.num_vertices()];
        let s = unbiased_fit(
            &mut fitted,
            &scan,
            &fixed,
            &FitParams::for_edge_length(edge),
        );
        (dense, coarse, fitted, s)
    }

    /// The bias the fit removes: the chordal surface is inside the scan (mean signed distance ≈ −e²/(8r),
    /// volume short by 3.4 %, girths short by 0.6–1.1 %); the fitted one straddles it (mean signed
    /// distance 0, the scan's volume), and its girths are within 0.6 % of 2πr — over, as a polygon
    /// straddling a circle is.
    #[test]
    fn a_coarse_sphere_on_a_dense_one_is_moved_out_to_straddle_it() {
        let r = 0.05;
        let (dense, coarse, fitted, s) = fitted_sphere(r);
        let edge =
            crate::mesh::self_intersection::mean_edge_length(&coarse.positions, &coarse.faces);
        let sagitta = edge * edge / (8.0 * r);
        assert!(
            s.signed_mean_before < -0.8 * sagitta && s.signed_mean_before > -1.2 * sagitta,
            "{s:?}, sagitta {sagitta}"
        );
        assert!(s.signed_mean_after.abs() < 1e-3 * sagitta, "{s:?}");
        assert!(s.rms_after < 0.6 * s.rms_before, "{s:?}");
        assert!(s.max_displacement > 0.5 * sagitta && s.max_displacement < 1.5 * sagitta);
        assert_eq!(s.excluded_fraction, 0.0);
        let v_scan = dense.signed_volume();
        let dv = |m: &TriMesh| m.signed_volume() / v_scan - 1.0;
        assert!(dv(&coarse) < -0.03, "{}", dv(&coarse));
        assert!(dv(&fitted).abs() < 2e-4, "{}", dv(&fitted));
        for h in [0.0, 0.013, -0.021] {
            let g_true = std::f64::consts::TAU * (r * r - h * h).sqrt();
            let before = girth_at(&coarse, h) / g_true - 1.0;
            let after = girth_at(&fitted, h) / g_true - 1.0;
            assert!(before < -0.005, "h {h}: {before}");
            assert!(after > 0.0 && after < 0.006, "h {h}: {after}");
        }
    }

    /// Fixed vertices stay; samples over a hole of the scan are left out instead of pulling the surface
    /// into it.
    #[test]
    fn fixed_vertices_stay_and_holes_are_left_out() {
        let r = 0.05;
        let mut dense = icosphere(6, r);
        // A hole: the scan has no faces above z = 0.8 r.
        dense
            .faces
            .retain(|f| f.iter().all(|&v| dense.positions[v].z < 0.8 * r));
        let scan = ClosestPointGrid::new(&dense.positions, &dense.faces, 0.04 * r);
        let coarse = icosphere(2, r);
        let edge =
            crate::mesh::self_intersection::mean_edge_length(&coarse.positions, &coarse.faces);
        let fixed: Vec<bool> = coarse.positions.iter().map(|p| p.x > 0.5 * r).collect();
        let mut fitted = coarse.clone();
        let s = unbiased_fit(
            &mut fitted,
            &scan,
            &fixed,
            &FitParams::for_edge_length(edge),
        );
        assert!(s.excluded_fraction > 0.02, "{s:?}");
        // A quarter of the vertices is fixed, so a quarter of the bias stays.
        assert!(
            s.signed_mean_after.abs() < 0.35 * s.signed_mean_before.abs(),
            "{s:?}"
        );
        for (v, (a, b)) in coarse.positions.iter().zip(&fitted.positions).enumerate() {
            let moved = (a - b).norm();
            if fixed[v] {
                assert_eq!(moved, 0.0);
            }
            assert!(moved <= edge / 8.0 + 1e-12);
            // Far inside the hole nothing pulls: the vertex stays.
            if a.z > 0.97 * r {
                assert!(moved < 1e-12, "{v}: {moved}");
            }
        }
    }
}
