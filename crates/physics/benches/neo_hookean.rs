//! Neo-Hookean body energy on a structured grid of 10 368 tets (12³ cubes × 6), bottom layer fixed:
//! energy, gradient, Hessian assembly (the node-block pattern once, then numeric-only assembly into it, with
//! and without PSD projection), and one supernodal sparse Cholesky factorization of the Hessian
//! (single-threaded).
//!
//! Run: `cargo bench -p skintight-physics --bench neo_hookean`

use criterion::{Criterion, criterion_group, criterion_main};
use faer::Side;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_physics::math::{Mat3, Real, Vec3};
use skintight_physics::{NeoHookeanBody, NeoHookeanParams};
use std::hint::black_box;

/// `n³` cubes of edge `h` (m), each split into 6 positively oriented tets around its main diagonal.
fn tet_grid(n: usize, h: Real) -> (Vec<Vec3>, Vec<[usize; 4]>) {
    let m = n + 1;
    let id = |i: usize, j: usize, k: usize| i + m * (j + m * k);
    let mut positions = Vec::with_capacity(m * m * m);
    for k in 0..m {
        for j in 0..m {
            for i in 0..m {
                positions.push(Vec3::new(i as Real, j as Real, k as Real) * h);
            }
        }
    }
    let mut tets = Vec::with_capacity(6 * n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                for perm in [
                    [0, 1, 2],
                    [0, 2, 1],
                    [1, 0, 2],
                    [1, 2, 0],
                    [2, 0, 1],
                    [2, 1, 0],
                ] {
                    let mut c = [i, j, k];
                    let mut tet = [id(i, j, k); 4];
                    for (s, &axis) in perm.iter().enumerate() {
                        c[axis] += 1;
                        tet[s + 1] = id(c[0], c[1], c[2]);
                    }
                    let p = tet.map(|v| positions[v]);
                    if Mat3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]).determinant()
                        < 0.0
                    {
                        tet.swap(2, 3);
                    }
                    tets.push(tet);
                }
            }
        }
    }
    (positions, tets)
}

fn bench(c: &mut Criterion) {
    faer::set_global_parallelism(faer::Par::Seq);
    let n = 12;
    let h = 0.01;
    let (rest, tets) = tet_grid(n, h);
    let fixed: Vec<bool> = (0..rest.len()).map(|v| v < (n + 1) * (n + 1)).collect();
    let mut body = NeoHookeanBody::new(&rest, &tets, &fixed, &NeoHookeanParams::default()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    // 8 % vertical compression plus noise: a state where some element Hessians are indefinite.
    let deformed: Vec<Vec3> = rest
        .iter()
        .map(|p| {
            Vec3::new(p.x, p.y, 0.92 * p.z)
                + Vec3::from_fn(|_, _| rng.random_range(-0.05..0.05) * h)
        })
        .collect();
    let x = body.dofs_from_positions(&deformed);
    let ndof = body.num_dofs();
    println!(
        "grid: {} tets, {} vertices, {} DOFs",
        tets.len(),
        rest.len(),
        ndof
    );

    c.bench_function("neo_hookean_10k/energy", |b| {
        b.iter(|| body.value(black_box(&x)).unwrap())
    });
    let mut g = vec![0.0; ndof];
    c.bench_function("neo_hookean_10k/gradient", |b| {
        b.iter(|| body.gradient(black_box(&x), &mut g).unwrap())
    });

    let mut asm = body.hessian_assembler();
    println!(
        "Hessian pattern: {} × {}, {} stored (lower) entries",
        ndof,
        ndof,
        asm.nnz()
    );
    c.bench_function("neo_hookean_10k/pattern_symbolic", |b| {
        b.iter(|| black_box(&body).hessian_assembler())
    });
    for project in [false, true] {
        body.set_project_psd(project);
        let tag = if project { "psd" } else { "raw" };
        c.bench_function(&format!("neo_hookean_10k/hessian_node_blocks_{tag}"), |b| {
            b.iter(|| {
                body.assemble_hessian(black_box(&x), &mut asm).unwrap();
            })
        });
    }

    // Cholesky of the projected Hessian + a small diagonal regularization (fixed bottom layer ⇒ SPD).
    body.set_project_psd(true);
    body.assemble_hessian(&x, &mut asm).unwrap();
    let max_diag = asm
        .diagonal_slots()
        .iter()
        .map(|&s| asm.matrix().val()[s])
        .fold(0.0, Real::max);
    asm.add_diagonal(&vec![1e-8 * max_diag; ndof]);
    let matrix = asm.matrix();
    c.bench_function("neo_hookean_10k/cholesky_symbolic", |b| {
        b.iter(|| SymbolicLlt::try_new(black_box(matrix.symbolic()), Side::Lower).unwrap())
    });
    let symbolic = SymbolicLlt::try_new(matrix.symbolic(), Side::Lower).unwrap();
    c.bench_function("neo_hookean_10k/cholesky_numeric", |b| {
        b.iter(|| {
            Llt::try_new_with_symbolic(symbolic.clone(), black_box(matrix.as_ref()), Side::Lower)
                .unwrap()
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench
}
criterion_main!(benches);
