//! The sparse Cholesky of a yarn patch's Newton matrix under each fill-reducing ordering (and AMD's on two
//! faer threads), side by side:
//! the matrix of a run's checkpoint (`skintight knit simulate-yarn … --out DIR`, or the 16 × 16 hang of
//! `tools/knit_hang_acceptance.sh`), analyzed on the 4-unknown vertex groups as the time stepper does, then
//! factored and solved, the orderings taking turns so that the machine's load falls on both alike.
//!
//! The matrix: the patch Hessian at the checkpoint's state plus the step's mass term `M/h²` (kg/s², the
//! positions' lumped masses, the angles' inertias) plus the Levenberg–Marquardt shift `μ D`
//! ([`LevenbergMarquardt::scaling`]), `μ` raised ×10 from 10⁻² until it factors
//! ([`skintight_physics::newton::shifted_factorization`]) — the matrix one Newton iteration of a step factors. Units are the solver's (N/m, N, N·m). With `STEPS`, the stepper then takes that many time steps
//! and the matrix there is analyzed both afresh and under the first matrix's ordering
//! ([`SparseCholesky::reanalyze`]): what a stale ordering costs in fill and saves in analysis.
//!
//! ```text
//! cargo run --release --example factor_orderings -- out/hang16 [ROUNDS [STEPS]]
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use faer::sparse::{SparseColMat, Triplet};
use skintight::knit::{YarnRunCheckpoint, patch_model};
use skintight_knit::PeriodicPattern;
use skintight_knit::implicit_euler::ImplicitEuler;
use skintight_physics::newton::{
    LevenbergMarquardt, add_to_diagonal, indefinite, shifted_factorization,
};
use skintight_physics::{Ordering, SparseCholesky, SparseCholeskyParams};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(dir) = args.first().map(PathBuf::from) else {
        eprintln!("usage: factor_orderings RUN_DIR [ROUNDS] (RUN_DIR holds checkpoint.json)");
        std::process::exit(2);
    };
    let rounds: usize = args
        .get(1)
        .map_or(3, |r| r.parse().expect("ROUNDS: a count"));
    let steps: usize = args
        .get(2)
        .map_or(0, |r| r.parse().expect("STEPS: a count"));
    let checkpoint = match YarnRunCheckpoint::read(&dir) {
        Ok(Some(c)) => c,
        Ok(None) => {
            eprintln!("{}: no checkpoint.json", dir.display());
            std::process::exit(1);
        }
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let scene = &checkpoint.scene;
    let yarns = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/yarns");
    let pattern = PeriodicPattern::read(&scene.pattern_path(Path::new("."), Some(&yarns)))
        .expect("the scene's pattern");
    let (model, prescribed) = patch_model(scene, &pattern).expect("the scene sets up");
    let mut sim = ImplicitEuler::new(model, scene.time_stepping(), prescribed).expect("a stepper");
    sim.restore_state(checkpoint.state.clone())
        .expect("the checkpoint's state");
    let (a, diagonal, scaling, contacts) = newton_matrix(&sim, scene.dt_s);
    let groups: Vec<usize> = (0..=a.nrows() / 4).map(|k| 4 * k).collect();
    println!(
        "{} DOFs, {} entries in the lower triangle, {} contacts at t = {} s",
        a.nrows(),
        a.val().len(),
        contacts,
        checkpoint.state.time
    );
    let n = a.nrows();
    let b: Vec<f64> = (0..n)
        .map(|k| ((k * 7919) % 1000) as f64 / 1000.0 - 0.5)
        .collect();
    for round in 0..rounds {
        for (ordering, threads) in [
            (Ordering::Amd, None),
            (Ordering::Metis, None),
            (Ordering::Amd, Some(2)),
        ] {
            let clock = Instant::now();
            let chol = SparseCholesky::analyze_grouped(
                a.as_ref(),
                Some(&groups),
                &SparseCholeskyParams { ordering, threads },
            )
            .expect("an analysis");
            let analysis = clock.elapsed().as_secs_f64();
            let fill = chol.fill(ordering).expect("the ordering in use");
            let (factorization, shift, solve) = factor(chol, &a, &diagonal, &scaling, &b);
            println!(
                "round {round} {ordering:?}, {} thread(s): analysis {analysis:.3} s, factorization {factorization:.3} s (shift {shift:.0e}), solve {solve:.4} s, nnz(L) {}, flops {:.3e}",
                threads.unwrap_or(1),
                fill.factor_nnz,
                fill.flops
            );
        }
    }
    if steps == 0 {
        return;
    }
    // A stale ordering: the matrix `steps` time steps later, analyzed afresh and under the ordering of the
    // checkpoint's matrix.
    let clock = Instant::now();
    for _ in 0..steps {
        sim.step().expect("a step");
    }
    let (later, later_diagonal, later_scaling, later_contacts) = newton_matrix(&sim, scene.dt_s);
    println!(
        "{steps} steps later ({:.0} s): {} entries, {} contacts, t = {} s",
        clock.elapsed().as_secs_f64(),
        later.val().len(),
        later_contacts,
        sim.time()
    );
    let settings = |ordering| SparseCholeskyParams {
        ordering,
        threads: None,
    };
    for round in 0..rounds {
        for ordering in [Ordering::Amd, Ordering::Metis] {
            let old =
                SparseCholesky::analyze_grouped(a.as_ref(), Some(&groups), &settings(ordering))
                    .expect("an analysis");
            let clock = Instant::now();
            let fresh =
                SparseCholesky::analyze_grouped(later.as_ref(), Some(&groups), &settings(ordering))
                    .expect("an analysis");
            let fresh_analysis = clock.elapsed().as_secs_f64();
            let clock = Instant::now();
            let stale = old
                .reanalyze(later.as_ref(), &settings(ordering))
                .expect("a reanalysis");
            let stale_analysis = clock.elapsed().as_secs_f64();
            let (fresh_len, stale_len) = (fresh.factor_storage_len(), stale.factor_storage_len());
            let (f_fresh, _, _) = factor(fresh, &later, &later_diagonal, &later_scaling, &b);
            let (f_stale, _, _) = factor(stale, &later, &later_diagonal, &later_scaling, &b);
            println!(
                "round {round} {ordering:?}: fresh analysis {fresh_analysis:.3} s, factor storage {fresh_len}, factorization {f_fresh:.3} s; under the old ordering: analysis {stale_analysis:.3} s, factor storage {stale_len} ({:.3}×), factorization {f_stale:.3} s",
                stale_len as f64 / fresh_len as f64
            );
        }
    }
}

/// The Newton matrix of a step at the stepper's state: the lower triangle, its diagonal's positions, the
/// Levenberg–Marquardt scaling `D` of its diagonal, and the pairs in contact.
fn newton_matrix(
    sim: &ImplicitEuler,
    dt: f64,
) -> (SparseColMat<usize, f64>, Vec<usize>, Vec<f64>, usize) {
    let model = sim.model();
    let n = model.dof_count();
    let ev = model.evaluate(sim.state(), true);
    let h2 = dt * dt;
    let inertia = model.angular_inertia();
    let mut triplets = ev.hessian;
    for (v, (m, i)) in model.masses().iter().zip(&inertia).enumerate() {
        for k in 0..4 {
            let mass = if k == 3 { *i } else { *m };
            triplets.push(Triplet::new(4 * v + k, 4 * v + k, mass / h2));
        }
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).expect("a matrix");
    let diagonal: Vec<usize> = (0..n)
        .map(|c| {
            let rows = a.symbolic().row_idx_of_col_raw(c);
            a.symbolic().col_ptr()[c] + rows.iter().position(|&r| r == c).expect("a diagonal")
        })
        .collect();
    let values: Vec<f64> = diagonal.iter().map(|&p| a.val()[p]).collect();
    (
        a,
        diagonal,
        LevenbergMarquardt::scaling(&values),
        ev.contacts,
    )
}

/// Factors `a + μ D` with `μ` from 10⁻² up ×10 until it is positive definite, then solves for `b`: the
/// factorization's and the solve's seconds and the shift.
fn factor(
    mut chol: SparseCholesky,
    a: &SparseColMat<usize, f64>,
    diagonal: &[usize],
    scaling: &[f64],
    b: &[f64],
) -> (f64, f64, f64) {
    let mut values = a.val().to_vec();
    let mut factorization = 0.0;
    let shift = shifted_factorization(
        1e-2,
        |mu| (mu < 1e6).then_some(mu * 10.0),
        |mu| {
            values.copy_from_slice(a.val());
            add_to_diagonal(&mut values, diagonal, mu, scaling);
            let shifted = faer::sparse::SparseColMatRef::new(a.symbolic(), &values);
            let clock = Instant::now();
            let result = chol.factorize(shifted);
            factorization = clock.elapsed().as_secs_f64();
            result
        },
        indefinite,
    )
    .unwrap_or_else(|(mu, e)| panic!("at shift {mu:e}: {e}"));
    let clock = Instant::now();
    let mut x = b.to_vec();
    chol.solve_in_place(&mut x).expect("a solve");
    (factorization, shift, clock.elapsed().as_secs_f64())
}
