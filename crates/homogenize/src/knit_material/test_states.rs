//! Seeded states for the material's tests: deformation gradients in every regime and a block mesh.

use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::volumetric_mesh::VolumetricMesh;

/// A seeded generator.
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// A random rotation.
pub fn rotation(rng: &mut ChaCha8Rng) -> Matrix3<f64> {
    let axis = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
    *Rotation3::new(axis * rng.random_range(0.0..3.1)).matrix()
}

/// `Q₁ diag(σ) Q₂ᵀ` with random rotations.
pub fn with_singular_values(sigma: Vector3<f64>, rng: &mut ChaCha8Rng) -> Matrix3<f64> {
    rotation(rng) * Matrix3::from_diagonal(&sigma) * rotation(rng).transpose()
}

/// Deformation gradients of every regime, named: near identity, isotropic (equal singular values),
/// large stretch, compression, near-degenerate (`σ₃ ≈ 10⁻³`), inverted, the clamping of Eq. 26 active
/// (`σ₃` far below the others), crossing `det F = 0` (`σ₃ = ±10⁻⁸`).
pub fn regimes(rng: &mut ChaCha8Rng) -> Vec<(&'static str, Matrix3<f64>)> {
    let mut out = Vec::new();
    let r = |rng: &mut ChaCha8Rng, a: f64, b: f64| rng.random_range(a..b);
    let sigmas = [
        (
            "near identity",
            Vector3::new(
                1.0 + r(rng, -0.05, 0.05),
                1.0 + r(rng, -0.05, 0.05),
                1.0 + r(rng, -0.05, 0.05),
            ),
        ),
        ("isotropic", Vector3::repeat(r(rng, 0.6, 1.6))),
        (
            "large stretch",
            Vector3::new(r(rng, 1.5, 3.0), r(rng, 1.2, 2.0), r(rng, 1.0, 1.5)),
        ),
        (
            "compression",
            Vector3::new(r(rng, 0.5, 0.9), r(rng, 0.3, 0.6), r(rng, 0.1, 0.4)),
        ),
        (
            "near-degenerate",
            Vector3::new(r(rng, 0.8, 1.5), r(rng, 0.5, 1.0), 1e-3 * r(rng, 0.5, 1.5)),
        ),
        (
            "inverted",
            Vector3::new(r(rng, 0.8, 1.5), r(rng, 0.5, 1.0), -r(rng, 0.05, 0.45)),
        ),
        (
            "clamped",
            Vector3::new(r(rng, 60.0, 120.0), r(rng, 20.0, 50.0), r(rng, 0.5, 2.0)),
        ),
        (
            "det crossing 0",
            Vector3::new(r(rng, 0.8, 1.5), r(rng, 0.5, 1.0), 1e-8 * r(rng, -1.0, 1.0)),
        ),
    ];
    for (name, sigma) in sigmas {
        out.push((name, with_singular_values(sigma, rng)));
    }
    out
}

/// A random positively oriented rest tetrahedron of size about 1 m.
pub fn rest_tet(rng: &mut ChaCha8Rng) -> [[f64; 3]; 4] {
    loop {
        let p: [[f64; 3]; 4] = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            .map(|c| c.map(|v| v + rng.random_range(-0.3..0.3)));
        let e = |i: usize| Vector3::from(p[i]) - Vector3::from(p[0]);
        if Matrix3::from_columns(&[e(1), e(2), e(3)]).determinant() > 0.2 {
            return p;
        }
    }
}

/// `nx × ny × nz` cubes of edge `h` (m), six positively oriented tetrahedra a cube around its main
/// diagonal; unit nodal masses, no yarn embedded.
pub fn block_mesh(nx: usize, ny: usize, nz: usize, h: f64) -> VolumetricMesh {
    let id = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    let mut rest = Vec::new();
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                rest.push([i as f64 * h, j as f64 * h, k as f64 * h]);
            }
        }
    }
    let mut tets = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                // Each order of the three axes is a monotone path from corner (0,0,0) to (1,1,1).
                for order in [
                    [0, 1, 2],
                    [0, 2, 1],
                    [1, 0, 2],
                    [1, 2, 0],
                    [2, 0, 1],
                    [2, 1, 0],
                ] {
                    let mut c = [i, j, k];
                    let mut tet = [id(i, j, k); 4];
                    for (step, &axis) in order.iter().enumerate() {
                        c[axis] += 1;
                        tet[step + 1] = id(c[0], c[1], c[2]);
                    }
                    let p = tet.map(|v| Vector3::from(rest[v]));
                    let det = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]])
                        .determinant();
                    if det < 0.0 {
                        tet.swap(2, 3);
                    }
                    tets.push(tet);
                }
            }
        }
    }
    VolumetricMesh {
        node_mass: vec![1.0; rest.len()],
        rest,
        tets,
        embedding: Vec::new(),
    }
}
