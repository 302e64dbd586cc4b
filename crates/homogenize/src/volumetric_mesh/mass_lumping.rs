//! The yarn mass lumped onto the mesh nodes (the knitwear paper, Eq. 2–3):
//!
//! `m_i = Σ_j L_j ∫₀¹ N_i(x_j(t)) ρ_j dt`,   `x_j(t) = x̄₀ + t (x̄₁ − x̄₀)`,
//!
//! summed over the yarn segments `j` (rest length `L_j = ‖x̄₁ − x̄₀‖` in m, linear density `ρ_j` in kg/m),
//! with `N_i` the piecewise-linear shape function of node `i` (kg per node). The paper writes the point of
//! the segment in the element's natural coordinates, `J⁻¹ Δx^Y(t)` (Eq. 3); here those are the barycentric
//! weights of [`super::embedding`], the same thing.
//!
//! **Exact integration.** Along a segment, `N_i(x(t))` is piecewise linear in `t`: linear inside each
//! tetrahedron, with kinks where the segment crosses a face between tetrahedra. The faces of the Kuhn
//! split ([`super::tet_split`]) lie on the planes `u_a ∈ ℤ` (voxel faces) and `u_a − u_b ∈ ℤ` (the
//! diagonal planes inside a voxel) of the grid coordinates `u`, so the segment is cut at every parameter
//! where `u_a(t)` or `u_a(t) − u_b(t)` crosses an integer — at most `7 + ‖Δu‖₁ + Σ_{a<b} |Δu_a − Δu_b|`
//! pieces — and on each piece `[t_k, t_{k+1}]` the midpoint rule is exact for the linear integrand:
//! `∫ N_i dt = (t_{k+1} − t_k) N_i(x((t_k + t_{k+1}) / 2))`. The lumped masses are therefore exact up to
//! round-off, they are non-negative, and they sum to the yarn's mass `Σ_j ρ_j L_j` (the weights of each
//! point sum to 1), which the tests check. No derivatives: the masses are constants of the rest pose.

use super::embedding::TetLocator;
use super::error::VolumetricMeshError;

/// The parameters `t ∈ [0, 1]` cutting the segment from grid coordinates `a` to `b` into pieces that each lie
/// in one Kuhn tetrahedron, sorted, starting with 0 and ending with 1.
pub fn cuts(a: [f64; 3], b: [f64; 3]) -> Vec<f64> {
    let mut t = vec![0.0, 1.0];
    let mut crossings = |g0: f64, g1: f64| {
        if g0 == g1 {
            return;
        }
        let (lo, hi) = (g0.min(g1), g0.max(g1));
        let mut n = lo.ceil();
        while n <= hi {
            let s = (n - g0) / (g1 - g0);
            if s > 0.0 && s < 1.0 {
                t.push(s);
            }
            n += 1.0;
        }
    };
    for i in 0..3 {
        crossings(a[i], b[i]);
        for j in i + 1..3 {
            crossings(a[i] - a[j], b[i] - b[j]);
        }
    }
    t.sort_by(f64::total_cmp);
    t.dedup();
    t
}

/// The lumped masses (kg), one per node (`node_count`), of the polylines given in grid coordinates (with
/// whether each is closed), of linear density `linear_density` (kg/m), in the mesh of `tets` whose voxels the
/// locator knows.
pub fn node_mass(
    locator: &TetLocator<'_>,
    tets: &[[usize; 4]],
    node_count: usize,
    polylines: &[(&[[f64; 3]], bool)],
    linear_density: f64,
) -> Result<Vec<f64>, VolumetricMeshError> {
    let h = locator.grid.voxel_m;
    let mut mass = vec![0.0; node_count];
    let mut first = 0;
    for &(u, closed) in polylines {
        let n = u.len();
        let edges = match n {
            0 | 1 => 0,
            _ if closed => n,
            _ => n - 1,
        };
        for k in 0..edges {
            let (a, b) = (u[k], u[(k + 1) % n]);
            let d: [f64; 3] = std::array::from_fn(|i| b[i] - a[i]);
            let length = h * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if length == 0.0 {
                continue;
            }
            let t = cuts(a, b);
            for w in t.windows(2) {
                let mid = 0.5 * (w[0] + w[1]);
                let p: [f64; 3] = std::array::from_fn(|i| a[i] + mid * d[i]);
                let e = locator
                    .locate(p)
                    .ok_or_else(|| VolumetricMeshError::NotEnclosed {
                        vertex: first + k,
                        position: std::array::from_fn(|i| locator.grid.origin[i] + h * p[i]),
                    })?;
                // A midpoint on the mesh's boundary face can get weights off zero by round-off
                // (`TetLocator::locate`); clipped and renormalized, the masses stay non-negative.
                let clipped = e.weights.map(|x| x.max(0.0));
                let sum: f64 = clipped.iter().sum();
                let piece = linear_density * length * (w[1] - w[0]) / sum;
                let tet = tets[e.tet];
                for c in 0..4 {
                    mass[tet[c]] += piece * clipped[c];
                }
            }
        }
        first += n;
    }
    Ok(mass)
}

#[cfg(test)]
mod tests {
    use super::super::tet_split::tet_split;
    use super::super::voxelize::{VoxelGrid, voxelize};
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn every_piece_between_cuts_lies_in_one_tetrahedron() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let grid = VoxelGrid {
            origin: [0.0; 3],
            voxel_m: 1.0,
        };
        for _ in 0..100 {
            let a: [f64; 3] = std::array::from_fn(|_| rng.random_range(-3.0..3.0));
            let b: [f64; 3] = std::array::from_fn(|_| rng.random_range(-3.0..3.0));
            let voxels = voxelize(&[(&[a, b], false)], 0);
            let locator = TetLocator {
                grid,
                voxels: &voxels,
            };
            let t = cuts(a, b);
            for w in t.windows(2) {
                // Points at 1/4 and 3/4 of a piece fall in the same tetrahedron as its midpoint.
                let at = |s: f64| -> [f64; 3] {
                    std::array::from_fn(|i| a[i] + (w[0] + s * (w[1] - w[0])) * (b[i] - a[i]))
                };
                let tets: Vec<usize> = [0.25, 0.5, 0.75]
                    .iter()
                    .map(|&s| locator.locate(at(s)).expect("enclosed").tet)
                    .collect();
                assert!(tets.iter().all(|&x| x == tets[0]), "{tets:?}");
            }
        }
    }

    #[test]
    fn masses_sum_to_the_yarn_mass_and_match_a_fine_quadrature() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let grid = VoxelGrid {
            origin: [0.0; 3],
            voxel_m: 2e-3,
        };
        // A random closed polyline in grid coordinates.
        let u: Vec<[f64; 3]> = (0..12)
            .map(|_| std::array::from_fn(|_| rng.random_range(0.0..5.0)))
            .collect();
        let voxels = voxelize(&[(&u, true)], 0);
        let (nodes, tets) = tet_split(&voxels);
        let locator = TetLocator {
            grid,
            voxels: &voxels,
        };
        let rho = 3.6e-3;
        let mass = node_mass(&locator, &tets, nodes.len(), &[(&u, true)], rho).unwrap();
        let length: f64 = (0..u.len())
            .map(|k| {
                let (a, b) = (u[k], u[(k + 1) % u.len()]);
                grid.voxel_m * (0..3).map(|i| (b[i] - a[i]).powi(2)).sum::<f64>().sqrt()
            })
            .sum();
        let total: f64 = mass.iter().sum();
        assert!(
            (total - rho * length).abs() < 1e-14 * rho * length,
            "{total} vs {}",
            rho * length
        );
        assert!(mass.iter().all(|&m| m >= 0.0));
        // A brute-force midpoint quadrature with 20 000 points a segment converges to the same masses.
        let mut fine = vec![0.0; nodes.len()];
        let samples = 20_000;
        for k in 0..u.len() {
            let (a, b) = (u[k], u[(k + 1) % u.len()]);
            let l = grid.voxel_m * (0..3).map(|i| (b[i] - a[i]).powi(2)).sum::<f64>().sqrt();
            for s in 0..samples {
                let t = (s as f64 + 0.5) / samples as f64;
                let p: [f64; 3] = std::array::from_fn(|i| a[i] + t * (b[i] - a[i]));
                let e = locator.locate(p).unwrap();
                for c in 0..4 {
                    fine[tets[e.tet][c]] += rho * l / samples as f64 * e.weights[c];
                }
            }
        }
        let scale = mass.iter().copied().fold(0.0, f64::max);
        let worst = mass
            .iter()
            .zip(&fine)
            .map(|(m, f)| (m - f).abs())
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-4 * scale,
            "exact vs fine quadrature: {worst} of {scale}"
        );
    }

    #[test]
    fn a_segment_along_a_voxel_edge_splits_its_mass_between_the_edge_nodes() {
        // Along the x axis at u = (·, 0, 0): a grid edge. Every point is a convex combination of the two
        // end nodes of the edge it lies on, so the masses are those of a bar: ρ h / 2 at the ends, ρ h inside.
        let grid = VoxelGrid {
            origin: [0.0; 3],
            voxel_m: 1e-3,
        };
        let u = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
        let voxels = voxelize(&[(&u, false)], 0);
        let (nodes, tets) = tet_split(&voxels);
        let locator = TetLocator {
            grid,
            voxels: &voxels,
        };
        let mass = node_mass(&locator, &tets, nodes.len(), &[(&u, false)], 1.0).unwrap();
        for (g, m) in nodes.iter().zip(&mass) {
            let want = match g {
                [0 | 3, 0, 0] => 0.5e-3,
                [1 | 2, 0, 0] => 1e-3,
                _ => 0.0,
            };
            assert!((m - want).abs() < 1e-18, "{g:?}: {m}");
        }
    }
}
