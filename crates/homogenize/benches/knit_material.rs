//! The volumetric knit's material (knitwear paper Eq. 7, issue 43): per element, `V(F)` alone (the
//! projection of Eq. 26), the energy with its gradient, and the energy with gradient and the exact or
//! PSD-projected 12 × 12 Hessian, at seeded states of three regimes (moderate stretch, compression,
//! the clamping of Eq. 26 active); and the assembly over a 6 × 6 × 6-cube block (1 296 tets).
//!
//! Run: `cargo bench -p skintight-homogenize --bench knit_material`

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Matrix3, Rotation3, Vector3};
use skintight_homogenize::closest_volume_preserving::{
    VolumePreservingParams, closest_volume_preserving,
};
use skintight_homogenize::knit_material::{KnitMaterial, MaterialHessian, RestTet, knit_element};
use skintight_homogenize::volumetric_mesh::VolumetricMesh;
use std::hint::black_box;

fn state(sigma: [f64; 3]) -> Matrix3<f64> {
    let q1 = *Rotation3::new(Vector3::new(0.3, -0.7, 0.4)).matrix();
    let q2 = *Rotation3::new(Vector3::new(-0.2, 0.5, 0.9)).matrix();
    q1 * Matrix3::from_diagonal(&Vector3::from(sigma)) * q2.transpose()
}

/// `n³` cubes of edge `h` (m), split as the mesh construction splits voxels; unit nodal masses.
fn block(n: usize, h: f64) -> VolumetricMesh {
    let (rest, tets) = skintight_homogenize::volumetric_mesh::tet_split::voxel_block([n, n, n], h);
    VolumetricMesh {
        node_mass: vec![1.0; rest.len()],
        rest,
        tets,
        embedding: Vec::new(),
    }
}

fn bench(c: &mut Criterion) {
    let params = VolumePreservingParams::default();
    let h = 0.002;
    let rest_x = [[0.0; 3], [h, 0.0, 0.0], [0.0, h, 0.0], [0.0, 0.0, h]];
    let rest = RestTet::new(&rest_x).unwrap();
    let gamma = [1.0e3, 3.0e3];
    for (name, sigma) in [
        ("stretch", [1.4, 1.1, 0.9]),
        ("compression", [0.8, 0.5, 0.3]),
        ("clamped", [90.0, 40.0, 1.0]),
    ] {
        let f = state(sigma);
        let x = rest_x.map(|p| {
            let y = f * Vector3::from(p);
            [y[0], y[1], y[2]]
        });
        c.bench_function(&format!("knit_material/V(F)/{name}"), |b| {
            b.iter(|| closest_volume_preserving(black_box(&f), &params).unwrap())
        });
        for (tag, form) in [
            ("energy_gradient", MaterialHessian::Skip),
            ("energy_gradient_exact_hessian", MaterialHessian::Exact),
            (
                "energy_gradient_projected_hessian",
                MaterialHessian::Projected,
            ),
        ] {
            c.bench_function(&format!("knit_material/element/{tag}/{name}"), |b| {
                b.iter(|| knit_element(&rest, black_box(&x), gamma, form, &params).unwrap())
            });
        }
    }
    let mesh = block(6, h);
    let material = KnitMaterial::new(&mesh, vec![gamma; mesh.tets.len()], params).unwrap();
    let x: Vec<f64> = mesh
        .rest
        .iter()
        .flat_map(|p| [1.2 * p[0], 0.95 * p[1], 0.9 * p[2] + 0.1 * p[0]])
        .collect();
    println!("block: {} tets, {} nodes", mesh.tets.len(), mesh.rest.len());
    c.bench_function("knit_material/assembly_1296_tets/projected_hessian", |b| {
        b.iter(|| {
            material
                .evaluate(black_box(&x), MaterialHessian::Projected)
                .unwrap()
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(std::time::Duration::from_secs(2)).warm_up_time(std::time::Duration::from_millis(500));
    targets = bench
}
criterion_main!(benches);
