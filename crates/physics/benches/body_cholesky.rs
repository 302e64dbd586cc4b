//! The sparse Cholesky solver alone, on a body-only matrix: the Neo-Hookean Hessian of a solid ball (radius
//! 0.1 m, bottom cap `z < −0.08 m` fixed, PSD projection on, randomly perturbed state, small diagonal shift),
//! assembled by node blocks; symbolic analysis and numeric factorization with AMD and with METIS nested
//! dissection, single-threaded. A scalable, regular 3D matrix for the solver's own figures — not the matrix
//! the equilibrium solve factors: that one (cloth on body, the pants) is timed by the app's
//! `cloth_on_body_cholesky` bench.
//!
//! Criterion (ball resolution 16, 14 k DOF):
//! `cargo bench -p skintight-physics --bench body_cholesky`
//!
//! One-shot table (one analysis and one factorization per ordering and size), sizes as ball resolutions:
//! `SPARSE_CHOLESKY_TABLE=16,29 cargo bench -p skintight-physics --bench body_cholesky`

use criterion::{Criterion, criterion_group};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::body::procedural_body::{SphereParams, solid_sphere};
use skintight_physics::math::{Real, Vec3};
use skintight_physics::{
    NeoHookeanBody, NeoHookeanParams, NodeBlockAssembler, Ordering, SparseCholesky,
    SparseCholeskyParams,
};
use std::hint::black_box;
use std::time::Instant;

/// The assembled Hessian (lower triangle, N/m) of the ball at `resolution`, plus `1e-3 · mean(diag)`.
fn ball_hessian(resolution: usize) -> NodeBlockAssembler {
    let radius = 0.1;
    let mesh = solid_sphere(&SphereParams { radius, resolution }).expect("ball");
    let fixed: Vec<bool> = mesh.positions.iter().map(|p| p.z < -0.8 * radius).collect();
    let params = NeoHookeanParams {
        project_psd: true,
        ..Default::default()
    };
    let body = NeoHookeanBody::new(&mesh.positions, &mesh.tets, &fixed, &params).expect("body");
    let h = 2.0 * radius / resolution as Real;
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let perturbed: Vec<Vec3> = mesh
        .positions
        .iter()
        .map(|p| {
            p + Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ) * 0.1
                * h
        })
        .collect();
    let x = body.dofs_from_positions(&perturbed);
    let mut assembler = body.hessian_assembler();
    body.assemble_hessian(&x, &mut assembler).expect("hessian");
    let n = body.num_dofs();
    let mean_diagonal = (0..n)
        .map(|i| assembler.matrix().val_of_col(i)[0])
        .sum::<Real>()
        / n as Real;
    assembler.add_diagonal(&vec![1e-3 * mean_diagonal; n]);
    assembler
}

fn params(ordering: Ordering) -> SparseCholeskyParams {
    SparseCholeskyParams {
        ordering,
        threads: None,
    }
}

/// Prints one Markdown table row per ordering: analysis and factorization time, fill, solve residual.
fn table(resolutions: &[usize]) {
    println!(
        "| resolution | DOF | nnz(A) lower | ordering | analyze (s) | factorize (s) | solve (s) | nnz(L) | flops Σc² | supernodal | ‖Ax−b‖/‖b‖ |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for &resolution in resolutions {
        let assembler = ball_hessian(resolution);
        let a = assembler.matrix();
        let n = a.nrows();
        for ordering in [Ordering::Amd, Ordering::Metis, Ordering::Auto] {
            let start = Instant::now();
            let mut chol = SparseCholesky::analyze(a.as_ref(), &params(ordering)).expect("analyze");
            let analyze = start.elapsed().as_secs_f64();
            let start = Instant::now();
            chol.factorize(a.as_ref()).expect("factorize");
            let factorize = start.elapsed().as_secs_f64();
            let b: Vec<Real> = (0..n).map(|i| ((i % 7) as Real) - 3.0).collect();
            let mut x = b.clone();
            let start = Instant::now();
            chol.solve_in_place(&mut x).expect("solve");
            let solve = start.elapsed().as_secs_f64();
            // Residual with the symmetric matrix whose lower triangle is stored.
            let mut ax = vec![0.0; n];
            for c in 0..n {
                for (r, &v) in a.row_idx_of_col(c).zip(a.val_of_col(c)) {
                    ax[r] += v * x[c];
                    if r != c {
                        ax[c] += v * x[r];
                    }
                }
            }
            let norm = |v: &[Real]| v.iter().map(|t| t * t).sum::<Real>().sqrt();
            let r: Vec<Real> = ax.iter().zip(&b).map(|(p, q)| p - q).collect();
            let fill = chol
                .fill(Ordering::Auto)
                .expect("fill of the ordering in use");
            let label = match ordering {
                Ordering::Auto => format!("auto → {:?}", chol.ordering_used()),
                o => format!("{o:?}"),
            };
            println!(
                "| {resolution} | {n} | {} | {label} | {analyze:.3} | {factorize:.3} | {solve:.4} | {} | {:.3e} | {} | {:.1e} |",
                a.val().len(),
                chol.factor_nnz(),
                fill.flops,
                chol.is_supernodal(),
                norm(&r) / norm(&b),
            );
        }
    }
}

fn bench(c: &mut Criterion) {
    let assembler = ball_hessian(16);
    let a = assembler.matrix();
    let mut group = c.benchmark_group("sparse_cholesky_ball16");
    group.sample_size(10);
    for ordering in [Ordering::Amd, Ordering::Metis] {
        group.bench_function(format!("analyze_{ordering:?}"), |bench| {
            bench.iter(|| SparseCholesky::analyze(black_box(a.as_ref()), &params(ordering)))
        });
        let mut chol = SparseCholesky::analyze(a.as_ref(), &params(ordering)).expect("analyze");
        group.bench_function(format!("factorize_{ordering:?}"), |bench| {
            bench.iter(|| chol.factorize(black_box(a.as_ref())).expect("factorize"))
        });
        let mut rhs = vec![1.0; a.nrows()];
        group.bench_function(format!("solve_{ordering:?}"), |bench| {
            bench.iter(|| chol.solve_in_place(black_box(&mut rhs)).expect("solve"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);

fn main() {
    if let Ok(sizes) = std::env::var("SPARSE_CHOLESKY_TABLE") {
        let resolutions: Vec<usize> = sizes
            .split(',')
            .map(|s| {
                s.trim()
                    .parse()
                    .expect("SPARSE_CHOLESKY_TABLE: comma-separated resolutions")
            })
            .collect();
        table(&resolutions);
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
