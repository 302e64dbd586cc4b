//! Sparse Cholesky of the matrix the equilibrium solve factors, on the pants: `examples/pants.json` (body
//! `regular_1k.obj` tetrahedralized as a shell, four panels) built through the app's own scene code
//! ([`skintight::simulate::prepare`]), solved to equilibrium once ([`equilibrium_in`], about 12 s in a
//! release build), then the final cloth-on-body Hessian `H + αD` the solver's adjoint factors
//! ([`EquilibriumWorkspace::adjoint_hessian`]: `α` the smallest damping that factors, 0 when `H` does) is
//! analysed with the ordering computed on the graph of the nodes as the solver does
//! ([`SparseCholesky::analyze_grouped`] with [`ClothOnBody::dof_groups`]), factored and solved, with AMD and
//! with METIS nested dissection, the solver's thread settings otherwise; and 570 right-hand sides at once
//! (a reduced Gauss-Newton direction's, [`SparseCholesky::solve_columns_in_place_on`]) in one sweep and
//! split across the machine's threads.
//!
//! `cargo bench --bench cloth_on_body_cholesky` (Criterion, 10 samples each);
//! `cargo bench --bench cloth_on_body_cholesky -- --quick` for one short run. The figures of the matrix and
//! one timed analysis, factorization and solve per ordering are printed first.
//!
//! [`ClothOnBody::dof_groups`]: skintight_physics::ClothOnBody::dof_groups

use std::hint::black_box;
use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use criterion::{Criterion, criterion_group};
use faer::sparse::SparseColMat;
use skintight::scene::{FileResolver, Scene};
use skintight::simulate::{equilibrium_params, prepare};
use skintight_physics::{
    EquilibriumWorkspace, Ordering, SparseCholesky, SparseCholeskyParams, equilibrium_in,
};

const SCENE: &str = "examples/pants.json";

/// The pants at equilibrium: the damped final Hessian (lower triangle, N/m for body coordinates), its
/// damping `α` (N/m), the node groups of the unknowns and the solver's Cholesky settings.
struct PantsHessian {
    matrix: SparseColMat<usize, f64>,
    alpha: f64,
    groups: Option<Vec<usize>>,
    cholesky: SparseCholeskyParams,
}

fn pants_hessian() -> PantsHessian {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(SCENE);
    let scene = Scene::from_file(&path).expect("the pants scene");
    let mut sim = prepare(&scene, &FileResolver::for_scene_file(&path)).expect("the pants set up");
    let params = equilibrium_params(&scene);
    let mut workspace = EquilibriumWorkspace::default();
    let start = Instant::now();
    let report = equilibrium_in(
        &sim.system,
        &mut sim.state,
        &params,
        &mut |_| ControlFlow::Continue(()),
        &mut workspace,
    )
    .expect("the pants solve");
    println!(
        "pants: {} unknowns, equilibrium in {} Newton iterations, {:.1} s ({:?})",
        report.figures.unknowns,
        report.iterations,
        start.elapsed().as_secs_f64(),
        report.stop
    );
    let (matrix, alpha) = workspace.adjoint_hessian().expect("the final Hessian");
    PantsHessian {
        matrix,
        alpha,
        groups: sim.system.dof_groups(),
        cholesky: params.cholesky,
    }
}

fn settings(pants: &PantsHessian, ordering: Ordering) -> SparseCholeskyParams {
    SparseCholeskyParams {
        ordering,
        ..pants.cholesky
    }
}

fn analyze(pants: &PantsHessian, ordering: Ordering) -> SparseCholesky {
    SparseCholesky::analyze_grouped(
        pants.matrix.as_ref(),
        pants.groups.as_deref(),
        &settings(pants, ordering),
    )
    .expect("analyze")
}

/// One timed analysis, factorization and solve per ordering, with the fill and the solve's residual.
fn figures(pants: &PantsHessian) {
    let a = &pants.matrix;
    let n = a.nrows();
    println!(
        "H + αD: {n} × {n}, {} stored (lower) entries, α = {:.3e} N/m",
        a.val().len(),
        pants.alpha
    );
    println!("| ordering | analyze (s) | factorize (s) | solve (s) | nnz(L) | ‖Ax−b‖/‖b‖ |");
    println!("|---|---|---|---|---|---|");
    for ordering in [Ordering::Amd, Ordering::Metis] {
        let start = Instant::now();
        let mut chol = analyze(pants, ordering);
        let analyze_s = start.elapsed().as_secs_f64();
        let start = Instant::now();
        chol.factorize(a.as_ref()).expect("factorize");
        let factorize_s = start.elapsed().as_secs_f64();
        let b: Vec<f64> = (0..n).map(|i| ((i % 7) as f64) - 3.0).collect();
        let mut x = b.clone();
        let start = Instant::now();
        chol.solve_in_place(&mut x).expect("solve");
        let solve_s = start.elapsed().as_secs_f64();
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
        let norm = |v: &[f64]| v.iter().map(|t| t * t).sum::<f64>().sqrt();
        let r: Vec<f64> = ax.iter().zip(&b).map(|(p, q)| p - q).collect();
        println!(
            "| {ordering:?} | {analyze_s:.3} | {factorize_s:.3} | {solve_s:.4} | {} | {:.1e} |",
            chol.factor_nnz(),
            norm(&r) / norm(&b)
        );
    }
}

/// The right-hand sides of a reduced Gauss-Newton direction on the tapered cylinder's finest level (one
/// per design parameter): [`SparseCholesky::solve_columns_in_place_on`] in one sweep and split across
/// the machine's threads, alternated three times, best of each.
const DIRECTION_COLUMNS: usize = 570;

fn column_figures(pants: &PantsHessian) {
    let a = pants.matrix.as_ref();
    let n = a.nrows();
    let mut chol = analyze(pants, pants.cholesky.ordering);
    chol.factorize(a).expect("factorize");
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let b: Vec<f64> = (0..n * DIRECTION_COLUMNS)
        .map(|i| ((i % 11) as f64) - 5.0)
        .collect();
    let mut best = [f64::INFINITY; 2];
    for _ in 0..3 {
        for (k, t) in [1, threads].into_iter().enumerate() {
            let mut x = b.clone();
            let start = Instant::now();
            chol.solve_columns_in_place_on(&mut x, DIRECTION_COLUMNS, t)
                .expect("solve");
            best[k] = best[k].min(start.elapsed().as_secs_f64());
        }
    }
    println!(
        "{DIRECTION_COLUMNS} right-hand sides: one sweep {:.3} s, split across {threads} threads {:.3} s \
         (ratio {:.2})",
        best[0],
        best[1],
        best[1] / best[0]
    );
}

fn bench(c: &mut Criterion) {
    let pants = pants_hessian();
    figures(&pants);
    column_figures(&pants);
    let a = pants.matrix.as_ref();
    let mut group = c.benchmark_group("cloth_on_body_cholesky_pants");
    group.sample_size(10);
    for ordering in [Ordering::Amd, Ordering::Metis] {
        group.bench_function(format!("analyze_{ordering:?}"), |bench| {
            bench.iter(|| analyze(black_box(&pants), ordering))
        });
        let mut chol = analyze(&pants, ordering);
        group.bench_function(format!("factorize_{ordering:?}"), |bench| {
            bench.iter(|| chol.factorize(black_box(a)).expect("factorize"))
        });
        let mut rhs = vec![1.0; a.nrows()];
        group.bench_function(format!("solve_{ordering:?}"), |bench| {
            bench.iter(|| chol.solve_in_place(black_box(&mut rhs)).expect("solve"))
        });
    }
    let mut chol = analyze(&pants, pants.cholesky.ordering);
    chol.factorize(a).expect("factorize");
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let mut block = vec![1.0; a.nrows() * DIRECTION_COLUMNS];
    for t in [1, threads] {
        group.bench_function(
            format!("solve_{DIRECTION_COLUMNS}_columns_{t}_threads"),
            |bench| {
                bench.iter(|| {
                    chol.solve_columns_in_place_on(black_box(&mut block), DIRECTION_COLUMNS, t)
                        .expect("solve")
                })
            },
        );
    }
    group.finish();
}

criterion_group!(benches, bench);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
}
