//! Least squares conformal map (Lévy, Petitjean, Ray, Maillot 2002) of a disk-topology mesh into the plane.
//!
//! For a piecewise-linear map `(u, v)` of a triangle `T` (3D, in its own orthonormal frame), the map is
//! conformal when `∇v = J ∇u` with `J` the rotation by +90°. The conformal energy
//!
//! `E(u, v) = Σ_T A_T |∇v − J ∇u|²`    (m² · dimensionless² per m² = m² for positions in m)
//!
//! is a quadratic form in the `2 · #V` pattern coordinates. It vanishes exactly for similarities of a planar
//! mesh and is minimized, with two pinned vertices (removing the similarity invariance), by solving the sparse
//! normal equations `H_ff x_f = −H_fp x_p` with a sparse Cholesky factorization (faer). The boundary is free.
//!
//! The result is then moved so that (1) its area-weighted centroid is at the origin, (2) its principal axis
//! (largest-variance direction of the area distribution) lies along +x, and (3) its total 2D area equals the
//! total 3D area of the panel. The last choice makes the flattening as close as a uniform scale can make it to
//! an isometry on average, so the elastic energy of the flat pattern sewn onto the body starts near rest.

use faer::prelude::Solve;
use faer::sparse::{SparseColMat, Triplet};

use crate::math::{Mat2, Real, Vec2, Vec3, VertexId};
use skintight_geometry::mesh::TriMesh;
use skintight_geometry::mesh::topology::{Topology, TopologyError};

/// Why a mesh could not be flattened.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LscmError {
    /// The mesh is not an oriented manifold.
    #[error("the panel mesh is not an oriented manifold: {0}")]
    Topology(TopologyError),
    /// The mesh has no faces.
    #[error("the panel mesh has no faces")]
    Empty,
    /// A vertex position is NaN or infinite.
    #[error("panel vertex {vertex} has a non-finite position")]
    NonFinitePosition { vertex: VertexId },
    /// A face has (nearly) zero area, so it has no conformal frame.
    #[error("panel face {face} is degenerate (area {area:.3e} m²)")]
    DegenerateFace { face: usize, area: Real },
    /// The mesh is not a topological disk.
    #[error(
        "the panel is not a topological disk: {components} connected piece(s), {loops} boundary loop(s), Euler characteristic {euler}"
    )]
    NotADisk {
        components: usize,
        loops: usize,
        euler: i64,
    },
    /// The linear system could not be factorized (should not happen for a valid disk).
    #[error("the LSCM normal equations could not be factorized: {0}")]
    Solver(String),
}

/// A flattened panel.
#[derive(Clone, Debug)]
pub struct Flattening {
    /// `#V` pattern positions (m), centred, principal axis along x, total area equal to the 3D area.
    pub positions: Vec<Vec2>,
    /// The two vertices pinned while solving.
    pub pinned: [VertexId; 2],
    /// Uniform scale applied after the solve so that 2D area equals 3D area (dimensionless; 1 for a
    /// developable panel).
    pub area_scale: Real,
    /// Number of faces whose 2D orientation is reversed or degenerate (0 for a valid pattern).
    pub flipped: usize,
    /// Largest difference between a 2D and the matching 3D corner angle (rad).
    pub max_angle_distortion: Real,
    /// Mean absolute corner angle difference (rad).
    pub mean_angle_distortion: Real,
    /// Conformal energy of the final positions (m²).
    pub conformal_energy: Real,
}

/// Per-face data: the area (m²) and the gradients of the three hat functions (1/m) in the face's own
/// orthonormal frame.
struct FaceFrame {
    area: Real,
    grad: [Vec2; 3],
}

fn face_frame(p: [Vec3; 3]) -> FaceFrame {
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let normal = e1.cross(&e2);
    let area = 0.5 * normal.norm();
    let x = e1.normalize();
    let y = normal.normalize().cross(&x);
    let q = [
        Vec2::zeros(),
        Vec2::new(e1.norm(), 0.0),
        Vec2::new(e2.dot(&x), e2.dot(&y)),
    ];
    // ∇φ_i = J (q_k − q_j) / (2A) for (i, j, k) counter-clockwise.
    let grad = [0, 1, 2].map(|i| {
        let d = q[(i + 2) % 3] - q[(i + 1) % 3];
        Vec2::new(-d.y, d.x) / (2.0 * area)
    });
    FaceFrame { area, grad }
}

/// The 2 × 6 residual matrix of a face: `r = ∇v − J∇u` as rows (x, y) over `(u0, v0, u1, v1, u2, v2)`.
fn residual_rows(fr: &FaceFrame) -> [[Real; 6]; 2] {
    let mut r = [[0.0; 6]; 2];
    for i in 0..3 {
        let g = fr.grad[i];
        // J∇u = (−∂u/∂y, ∂u/∂x).
        r[0][2 * i] = g.y;
        r[0][2 * i + 1] = g.x;
        r[1][2 * i] = -g.x;
        r[1][2 * i + 1] = g.y;
    }
    r
}

fn frames(mesh: &TriMesh) -> Result<Vec<FaceFrame>, LscmError> {
    let scale = mesh
        .bounding_box()
        .map(|(lo, hi)| (hi - lo).norm())
        .unwrap_or(0.0);
    (0..mesh.num_faces())
        .map(|f| {
            let fr = face_frame(mesh.corners(f));
            if fr.area.is_nan()
                || fr.area <= 1e-14 * scale * scale
                || !fr.grad.iter().all(|g| g.iter().all(|c| c.is_finite()))
            {
                Err(LscmError::DegenerateFace {
                    face: f,
                    area: fr.area,
                })
            } else {
                Ok(fr)
            }
        })
        .collect()
}

/// Conformal energy `E = Σ_T A_T |∇v − J∇u|²` (m²) of pattern positions `uv` (`#V`, m) for `mesh`.
pub fn conformal_energy(mesh: &TriMesh, uv: &[Vec2]) -> Result<Real, LscmError> {
    let fr = frames(mesh)?;
    Ok(energy_with(&fr, &mesh.faces, uv, None))
}

/// Gradient of [`conformal_energy`] with respect to `uv` (`#V`, m).
pub fn conformal_energy_gradient(mesh: &TriMesh, uv: &[Vec2]) -> Result<Vec<Vec2>, LscmError> {
    let fr = frames(mesh)?;
    let mut g = vec![Vec2::zeros(); uv.len()];
    energy_with(&fr, &mesh.faces, uv, Some(&mut g));
    Ok(g)
}

fn energy_with(
    frames: &[FaceFrame],
    faces: &[[usize; 3]],
    uv: &[Vec2],
    mut grad: Option<&mut [Vec2]>,
) -> Real {
    let mut e = 0.0;
    for (fr, face) in frames.iter().zip(faces) {
        let rows = residual_rows(fr);
        let x: [Real; 6] = [
            uv[face[0]].x,
            uv[face[0]].y,
            uv[face[1]].x,
            uv[face[1]].y,
            uv[face[2]].x,
            uv[face[2]].y,
        ];
        let r = rows.map(|row| (0..6).map(|k| row[k] * x[k]).sum::<Real>());
        e += fr.area * (r[0] * r[0] + r[1] * r[1]);
        if let Some(g) = grad.as_deref_mut() {
            for k in 0..6 {
                let d = 2.0 * fr.area * (rows[0][k] * r[0] + rows[1][k] * r[1]);
                g[face[k / 2]][k % 2] += d;
            }
        }
    }
    e
}

/// Calls `entry(i, j, h)` for every contribution to the (constant) Hessian of the conformal energy, with
/// unknowns interleaved as `(u0, v0, u1, v1, …)`; contributions to the same entry are to be summed.
fn hessian_entries(
    frames: &[FaceFrame],
    faces: &[[usize; 3]],
    mut entry: impl FnMut(usize, usize, Real),
) {
    for (fr, face) in frames.iter().zip(faces) {
        let rows = residual_rows(fr);
        for a in 0..6 {
            for b in 0..6 {
                let h = 2.0 * fr.area * (rows[0][a] * rows[0][b] + rows[1][a] * rows[1][b]);
                entry(2 * face[a / 2] + a % 2, 2 * face[b / 2] + b % 2, h);
            }
        }
    }
}

/// Hessian of [`conformal_energy`] (constant; dimensionless) as `(row, column, value)` triplets over the
/// `2 · #V` unknowns interleaved `(u0, v0, u1, v1, …)`. Entries repeat; their sum is the Hessian.
pub fn conformal_energy_hessian(mesh: &TriMesh) -> Result<Vec<(usize, usize, Real)>, LscmError> {
    let fr = frames(mesh)?;
    let mut out = Vec::with_capacity(mesh.num_faces() * 36);
    hessian_entries(&fr, &mesh.faces, |i, j, h| out.push((i, j, h)));
    Ok(out)
}

/// Two boundary vertices far apart: the farthest from boundary vertex 0, and the farthest from that one.
fn far_pair(positions: &[Vec3], boundary: &[VertexId]) -> [VertexId; 2] {
    let farthest = |from: VertexId| {
        *boundary
            .iter()
            .max_by(|&&a, &&b| {
                let da = (positions[a] - positions[from]).norm_squared();
                let db = (positions[b] - positions[from]).norm_squared();
                da.total_cmp(&db)
            })
            .expect("a disk has a boundary")
    };
    let a = farthest(boundary[0]);
    [a, farthest(a)]
}

/// Flattens a disk-topology `mesh` (positions in m) by the least squares conformal map; see the module
/// documentation for the normalization of the result.
pub fn lscm(mesh: &TriMesh) -> Result<Flattening, LscmError> {
    if mesh.faces.is_empty() {
        return Err(LscmError::Empty);
    }
    if let Some(v) = mesh
        .positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(LscmError::NonFinitePosition { vertex: v });
    }
    let topo = Topology::new(mesh.num_vertices(), &mesh.faces).map_err(LscmError::Topology)?;
    let frames = frames(mesh)?;

    // Topology: one component, one boundary loop, Euler characteristic 1 (isolated vertices excluded).
    let (_, components) = topo.face_components();
    let boundary_edges = topo.boundary_edges();
    let used: Vec<bool> = {
        let mut u = vec![false; mesh.num_vertices()];
        mesh.faces.iter().flatten().for_each(|&v| u[v] = true);
        u
    };
    let nv_used = used.iter().filter(|&&u| u).count() as i64;
    let euler = nv_used - topo.num_edges() as i64 + mesh.num_faces() as i64;
    let loops = count_loops(&boundary_edges);
    if components != 1 || loops != 1 || euler != 1 {
        return Err(LscmError::NotADisk {
            components,
            loops,
            euler,
        });
    }
    let mut boundary: Vec<VertexId> = boundary_edges.iter().map(|e| e.0).collect();
    boundary.sort_unstable();
    let pinned = far_pair(&mesh.positions, &boundary);
    let pin_pos = [
        Vec2::zeros(),
        Vec2::new(
            (mesh.positions[pinned[1]] - mesh.positions[pinned[0]]).norm(),
            0.0,
        ),
    ];

    // Numbering of the free unknowns (u, v interleaved).
    let n = mesh.num_vertices();
    let mut free_index = vec![usize::MAX; n];
    let mut nfree = 0;
    for v in 0..n {
        if used[v] && v != pinned[0] && v != pinned[1] {
            free_index[v] = nfree;
            nfree += 1;
        }
    }
    let pin_of = |v: VertexId| pinned.iter().position(|&p| p == v);

    // Stationarity of E in the free unknowns: H_ff x_f = −H_fp x_p.
    let mut triplets: Vec<Triplet<usize, usize, Real>> = Vec::with_capacity(mesh.num_faces() * 36);
    let mut rhs = vec![0.0; 2 * nfree];
    hessian_entries(&frames, &mesh.faces, |i, j, h| {
        let (vi, vj) = (i / 2, j / 2);
        if free_index[vi] == usize::MAX {
            return;
        }
        let ia = 2 * free_index[vi] + i % 2;
        if let Some(p) = pin_of(vj) {
            rhs[ia] -= h * pin_pos[p][j % 2];
        } else {
            triplets.push(Triplet::new(ia, 2 * free_index[vj] + j % 2, h));
        }
    });
    let mut uv = vec![Vec2::zeros(); n];
    uv[pinned[0]] = pin_pos[0];
    uv[pinned[1]] = pin_pos[1];
    if nfree > 0 {
        let h = SparseColMat::<usize, Real>::try_new_from_triplets(2 * nfree, 2 * nfree, &triplets)
            .map_err(|e| LscmError::Solver(format!("{e:?}")))?;
        let llt = h
            .sp_cholesky(faer::Side::Lower)
            .map_err(|e| LscmError::Solver(format!("{e:?}")))?;
        let b = faer::Col::<Real>::from_fn(2 * nfree, |i| rhs[i]);
        let x = llt.solve(&b);
        for v in 0..n {
            if free_index[v] != usize::MAX {
                uv[v] = Vec2::new(x[2 * free_index[v]], x[2 * free_index[v] + 1]);
            }
        }
    }
    if let Some(v) = uv.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(LscmError::Solver(format!(
            "the solution is not finite at vertex {v}"
        )));
    }

    // Normalize: centroid, principal axis, area.
    let area3: Real = frames.iter().map(|f| f.area).sum();
    let (area2, centroid, cov) = area_moments(&mesh.faces, &uv);
    if area2.is_nan() || area2 <= 0.0 {
        return Err(LscmError::Solver(format!(
            "the flattened area is {area2:.3e} m² (not positive)"
        )));
    }
    let area_scale = (area3 / area2).sqrt();
    let eig = cov.symmetric_eigen();
    let k = if eig.eigenvalues[0] >= eig.eigenvalues[1] {
        0
    } else {
        1
    };
    let axis: Vec2 = eig.eigenvectors.column(k).into_owned();
    // Rotation taking `axis` to +x.
    let rot = Mat2::new(axis.x, axis.y, -axis.y, axis.x);
    for p in &mut uv {
        *p = rot * (*p - centroid) * area_scale;
    }

    let (flipped, max_ad, mean_ad) = angle_report(mesh, &uv);
    let conformal_energy = energy_with(&frames, &mesh.faces, &uv, None);
    Ok(Flattening {
        positions: uv,
        pinned,
        area_scale,
        flipped,
        max_angle_distortion: max_ad,
        mean_angle_distortion: mean_ad,
        conformal_energy,
    })
}

fn count_loops(edges: &[(VertexId, VertexId)]) -> usize {
    use std::collections::HashMap;
    let next: HashMap<VertexId, VertexId> = edges.iter().copied().collect();
    let mut seen = std::collections::HashSet::new();
    let mut loops = 0;
    for &(a, _) in edges {
        if seen.contains(&a) {
            continue;
        }
        loops += 1;
        let mut v = a;
        while seen.insert(v) {
            v = next[&v];
        }
    }
    loops
}

/// Total signed area (m²), area-weighted centroid (m) and area-weighted second moment about the centroid
/// (m², 2 × 2) of a 2D triangulation, using triangle centroids.
pub(crate) fn area_moments(faces: &[[usize; 3]], uv: &[Vec2]) -> (Real, Vec2, Mat2) {
    let mut area = 0.0;
    let mut first = Vec2::zeros();
    for f in faces {
        let a = signed_area(uv[f[0]], uv[f[1]], uv[f[2]]);
        area += a;
        first += a * (uv[f[0]] + uv[f[1]] + uv[f[2]]) / 3.0;
    }
    let centroid = if area != 0.0 {
        first / area
    } else {
        Vec2::zeros()
    };
    let mut cov = Mat2::zeros();
    for f in faces {
        let a = signed_area(uv[f[0]], uv[f[1]], uv[f[2]]);
        let d = (uv[f[0]] + uv[f[1]] + uv[f[2]]) / 3.0 - centroid;
        cov += a * d * d.transpose();
    }
    (area, centroid, cov)
}

/// Signed area of the 2D triangle `(a, b, c)` (m²), positive when counter-clockwise.
pub fn signed_area(a: Vec2, b: Vec2, c: Vec2) -> Real {
    0.5 * ((b - a).x * (c - a).y - (b - a).y * (c - a).x)
}

fn corner_angles3(p: [Vec3; 3]) -> [Real; 3] {
    [0, 1, 2].map(|i| {
        let u = p[(i + 1) % 3] - p[i];
        let v = p[(i + 2) % 3] - p[i];
        u.cross(&v).norm().atan2(u.dot(&v))
    })
}

fn corner_angles2(p: [Vec2; 3]) -> [Real; 3] {
    [0, 1, 2].map(|i| {
        let u = p[(i + 1) % 3] - p[i];
        let v = p[(i + 2) % 3] - p[i];
        (u.x * v.y - u.y * v.x).abs().atan2(u.dot(&v))
    })
}

/// Count of flipped faces, largest and mean corner-angle difference (rad) between `mesh` and `uv`.
fn angle_report(mesh: &TriMesh, uv: &[Vec2]) -> (usize, Real, Real) {
    let mut flipped = 0;
    let mut max = 0.0_f64;
    let mut sum = 0.0;
    for (f, face) in mesh.faces.iter().enumerate() {
        let q = face.map(|v| uv[v]);
        if signed_area(q[0], q[1], q[2]) <= 0.0 {
            flipped += 1;
        }
        let a3 = corner_angles3(mesh.corners(f));
        let a2 = corner_angles2(q);
        for k in 0..3 {
            let d = (a3[k] - a2[k]).abs();
            max = max.max(d);
            sum += d;
        }
    }
    (flipped, max, sum / (3 * mesh.num_faces()) as Real)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plane_cut::{HalfSpace, PlaneCutParams, Region, panels};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::{FdParams, check_gradient};
    use skintight_geometry::test_meshes::{body_path, cylinder, grid, icosphere, read_obj};

    fn edge_lengths3(m: &TriMesh) -> Vec<Real> {
        m.faces
            .iter()
            .flat_map(|f| (0..3).map(move |e| (f[e], f[(e + 1) % 3])))
            .map(|(a, b)| (m.positions[a] - m.positions[b]).norm())
            .collect()
    }

    fn edge_lengths2(m: &TriMesh, uv: &[Vec2]) -> Vec<Real> {
        m.faces
            .iter()
            .flat_map(|f| (0..3).map(move |e| (f[e], f[(e + 1) % 3])))
            .map(|(a, b)| (uv[a] - uv[b]).norm())
            .collect()
    }

    #[test]
    fn energy_gradient_matches_central_differences() {
        for (seed, (nx, ny)) in [(1u64, (2, 2)), (2, (3, 4)), (3, (5, 3))] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            // A bent grid, so that the faces are not coplanar.
            let mut m = grid(nx, ny, 0.3, 0.2);
            for p in &mut m.positions {
                p.z = 0.2 * (3.0 * p.x).sin() * p.y + rng.random_range(-0.01..0.01);
            }
            let uv: Vec<Vec2> = (0..m.num_vertices())
                .map(|_| Vec2::new(rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3)))
                .collect();
            let g = conformal_energy_gradient(&m, &uv).unwrap();
            let flat: Vec<Real> = uv.iter().flat_map(|p| [p.x, p.y]).collect();
            let gflat: Vec<Real> = g.iter().flat_map(|p| [p.x, p.y]).collect();
            let f = |x: &[Real]| {
                let q: Vec<Vec2> = x.chunks(2).map(|c| Vec2::new(c[0], c[1])).collect();
                conformal_energy(&m, &q).unwrap()
            };
            check_gradient(f, &flat, &gflat, &FdParams::default())
                .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        }
    }

    #[test]
    fn energy_hessian_matches_central_differences() {
        for (seed, (nx, ny)) in [(4u64, (2, 2)), (5, (3, 2)), (6, (4, 3))] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut m = grid(nx, ny, 0.3, 0.2);
            for p in &mut m.positions {
                p.z = 0.1 * (2.0 * p.y).cos() * p.x + rng.random_range(-0.01..0.01);
            }
            let n = 2 * m.num_vertices();
            let x: Vec<Real> = (0..n).map(|_| rng.random_range(-0.3..0.3)).collect();
            let mut dense = vec![0.0; n * n];
            for (i, j, h) in conformal_energy_hessian(&m).unwrap() {
                dense[i * n + j] += h;
            }
            let g = |x: &[Real]| {
                let q: Vec<Vec2> = x.chunks(2).map(|c| Vec2::new(c[0], c[1])).collect();
                conformal_energy_gradient(&m, &q)
                    .unwrap()
                    .iter()
                    .flat_map(|v| [v.x, v.y])
                    .collect::<Vec<Real>>()
            };
            skintight_geometry::finite_difference::check_jacobian(
                g,
                &x,
                &dense,
                &FdParams::default(),
            )
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        }
    }

    #[test]
    fn planar_mesh_is_reproduced_up_to_a_rigid_motion() {
        for (nx, ny) in [(3, 2), (6, 5), (12, 9)] {
            let m = grid(nx, ny, 0.4, 0.25);
            let flat = lscm(&m).unwrap();
            assert_eq!(flat.flipped, 0);
            assert!((flat.area_scale - 1.0).abs() < 1e-10);
            // Rigid: every pairwise distance from two reference vertices is kept, orientation too.
            for (r, (l3, l2)) in edge_lengths3(&m)
                .iter()
                .zip(edge_lengths2(&m, &flat.positions))
                .enumerate()
            {
                assert!((l3 - l2).abs() < 1e-10 * l3, "edge {r}: {l3} vs {l2}");
            }
            for v in 0..m.num_vertices() {
                let d3 = (m.positions[v] - m.positions[0]).norm();
                let d2 = (flat.positions[v] - flat.positions[0]).norm();
                assert!((d3 - d2).abs() < 1e-10);
            }
            assert!(flat.max_angle_distortion < 1e-9);
            assert!(flat.conformal_energy < 1e-18);
        }
    }

    #[test]
    fn cylinder_strip_flattens_isometrically() {
        for (segments, rings, sweep) in [(8, 3, 2.0), (16, 6, 3.5), (30, 10, 5.5)] {
            let m = cylinder(0.15, 0.4, segments, rings, sweep);
            let flat = lscm(&m).unwrap();
            assert_eq!(flat.flipped, 0);
            for (l3, l2) in edge_lengths3(&m)
                .iter()
                .zip(edge_lengths2(&m, &flat.positions))
            {
                assert!((l3 - l2).abs() < 1e-6 * l3, "{l3} vs {l2}");
            }
            // The strip is long along the circumference: the principal axis is x.
            let (lo, hi) = flat.positions.iter().fold(
                (Vec2::repeat(Real::INFINITY), Vec2::repeat(-Real::INFINITY)),
                |(lo, hi), p| (lo.inf(p), hi.sup(p)),
            );
            if 0.15 * sweep > 0.4 {
                assert!(hi.x - lo.x > hi.y - lo.y);
            }
        }
    }

    #[test]
    fn hemisphere_flattens_without_flips() {
        for levels in [2, 3, 4] {
            let sphere = icosphere(levels, 0.2);
            let region = Region {
                label: "cap".into(),
                half_spaces: vec![HalfSpace {
                    normal: -Vec3::z(),
                    offset: -0.01,
                }],
            };
            let set = panels(&sphere, &[region], &PlaneCutParams::default()).unwrap();
            let cap = &set.panels[0].mesh;
            let flat = lscm(cap).unwrap();
            assert_eq!(flat.flipped, 0, "levels {levels}");
            let (area2, centroid, cov) = area_moments(&cap.faces, &flat.positions);
            assert!((area2 - cap.area()).abs() < 1e-12 * cap.area());
            assert!(centroid.norm() < 1e-12);
            assert!(cov[(0, 1)].abs() < 1e-12 && cov[(0, 0)] >= cov[(1, 1)] - 1e-15);
            // A sphere is not developable, but the discrete conformal map converges to the smooth one, which
            // keeps angles: the mean angle error halves with each subdivision (0.051, 0.026, 0.013 rad).
            let bound = 0.06 * 0.5f64.powi(levels as i32 - 2);
            assert!(
                flat.mean_angle_distortion < bound,
                "{}",
                flat.mean_angle_distortion
            );
            assert!(
                flat.max_angle_distortion < 0.2,
                "{}",
                flat.max_angle_distortion
            );
            eprintln!(
                "hemisphere level {levels}: area scale {:.4}, angle distortion mean {:.4} max {:.4} rad",
                flat.area_scale, flat.mean_angle_distortion, flat.max_angle_distortion
            );
        }
    }

    #[test]
    fn solution_is_stationary() {
        // The LSCM result minimizes the energy with two pins: the gradient vanishes at the free vertices.
        let sphere = icosphere(3, 0.2);
        let region = Region {
            label: "cap".into(),
            half_spaces: vec![HalfSpace {
                normal: -Vec3::new(0.2, 0.1, 1.0),
                offset: 0.03,
            }],
        };
        let set = panels(&sphere, &[region], &PlaneCutParams::default()).unwrap();
        let cap = &set.panels[0].mesh;
        let flat = lscm(cap).unwrap();
        let g = conformal_energy_gradient(cap, &flat.positions).unwrap();
        let scale = g.iter().map(|v| v.norm()).fold(0.0, Real::max);
        for (v, gv) in g.iter().enumerate() {
            if !flat.pinned.contains(&v) {
                assert!(gv.norm() < 1e-9 * scale.max(1e-3), "vertex {v}: {gv:?}");
            }
        }
    }

    #[test]
    fn body_panel_flattens() {
        let body = read_obj(&body_path("regular_1k.obj"));
        let (lo, hi) = body.bounding_box().unwrap();
        let y0 = lo.y + 0.55 * (hi.y - lo.y);
        let y1 = lo.y + 0.7 * (hi.y - lo.y);
        let region = Region {
            label: "front torso".into(),
            half_spaces: vec![
                HalfSpace {
                    normal: -Vec3::y(),
                    offset: -y0,
                },
                HalfSpace {
                    normal: Vec3::y(),
                    offset: y1,
                },
                HalfSpace {
                    normal: -Vec3::z(),
                    offset: -0.02,
                },
                HalfSpace {
                    normal: Vec3::x(),
                    offset: 0.12,
                },
                HalfSpace {
                    normal: -Vec3::x(),
                    offset: 0.12,
                },
            ],
        };
        let set = panels(&body, &[region], &PlaneCutParams::default()).unwrap();
        let p = &set.panels[0].mesh;
        let flat = lscm(p).unwrap();
        assert_eq!(flat.flipped, 0);
        eprintln!(
            "body front panel: {} faces, area scale {:.4}, angle distortion mean {:.4} max {:.4} rad",
            p.num_faces(),
            flat.area_scale,
            flat.mean_angle_distortion,
            flat.max_angle_distortion
        );
    }

    #[test]
    fn non_disk_is_rejected() {
        let closed = icosphere(1, 1.0);
        let err = lscm(&closed).unwrap_err();
        assert!(matches!(err, LscmError::NotADisk { loops: 0, .. }), "{err}");
        let tube = cylinder(0.1, 0.2, 8, 2, std::f64::consts::TAU);
        let err = lscm(&tube).unwrap_err();
        assert!(matches!(err, LscmError::NotADisk { loops: 2, .. }), "{err}");
        let mut degenerate = grid(2, 2, 1.0, 0.0);
        let v = degenerate.faces[0][2];
        degenerate.positions[v] = degenerate.positions[degenerate.faces[0][0]];
        assert!(matches!(
            lscm(&degenerate).unwrap_err(),
            LscmError::DegenerateFace { .. }
        ));
        let mut nan = grid(2, 2, 1.0, 0.0);
        nan.positions[3].x = Real::NAN;
        assert_eq!(
            lscm(&nan).unwrap_err(),
            LscmError::NonFinitePosition { vertex: 3 }
        );
    }
}
