//! The honest comparison of issue 44 (deliverable 3): the projective-dynamics hang of a `stock_9` patch
//! (default 16 × 16 cells, the scene of part 1's yarn-level benchmark: the top band of a quarter cell
//! clamped, gravity `(0, −9.81, 0)` m/s², Δt = 1/150 s) with the global step solved by the direct sparse
//! Cholesky (factored once), plain Jacobi and Chebyshev-accelerated Jacobi. Each solver runs the same
//! steps from rest; printed per solver: set-up time, seconds per step (mean), PD iterations per step
//! (mean, most), the final residual `‖∇Ψ‖∞ / F`, unconverged steps, and the largest per-step difference
//! of its positions from Cholesky's. Uniform `γˢ = γᵛ` (Pa, argument 3), see docs/BENCHMARKS.md
//! "Projective dynamics (issue 44)" for why.
//!
//! `cargo run --release -p skintight-homogenize --example pd_hang_solvers [CELLS] [STEPS] [GAMMA_PA] [TOL] [SWEEPS] [all|cholesky]`

use std::path::PathBuf;
use std::time::Instant;

use skintight_homogenize::projective_dynamics::{
    GlobalSolver, JacobiParams, ProjectiveDynamics, ProjectiveDynamicsParams,
};
use skintight_homogenize::volumetric_mesh::{RestYarns, VolumetricMesh, VolumetricMeshParams};
use skintight_knit::PeriodicPattern;
use skintight_knit::tile::tile;
use skintight_knit::yarn_params::YarnParams;

fn arg<T: std::str::FromStr>(i: usize, default: T) -> T {
    std::env::args()
        .nth(i)
        .and_then(|a| a.parse().ok())
        .unwrap_or(default)
}

/// CPU seconds of this process, all threads (utime + stime of `/proc/self/stat`, at USER_HZ = 100);
/// 0 where it cannot be read.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the parenthesised command name; utime and stime are the 14th and 15th fields.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

fn main() {
    let cells: usize = arg(1, 16);
    let steps: usize = arg(2, 10);
    let gamma: f64 = arg(3, 2000.0);
    let tolerance: f64 = arg(4, 1e-3);
    let sweeps: usize = arg(5, 20);
    let only_direct = arg(6, String::from("all")) == "cholesky";
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/yarns");
    let pattern = match PeriodicPattern::read(&dir.join("stock_9").join("pattern.pyp")) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let patch = tile(&pattern, cells, cells).expect("a positive cell count");
    let yarns = RestYarns::from_patch(&patch, YarnParams::default().linear_density(patch.radius));
    let start = Instant::now();
    let mesh = match VolumetricMesh::build(&yarns, &VolumetricMeshParams::default()) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let ymax = mesh.rest.iter().fold(f64::MIN, |m, p| m.max(p[1]));
    let band = 0.25 * pattern.period[1];
    let clamped: Vec<usize> = (0..mesh.rest.len())
        .filter(|&v| mesh.rest[v][1] >= ymax - band)
        .collect();
    println!(
        "stock_9 {cells}x{cells}: {} nodes ({} DOFs), {} tets, {} clamped, mass {:.4} g, mesh built in {:.2} s; \
         γˢ = γᵛ = {gamma} Pa, Δt = 1/150 s, tolerance {tolerance:e}, {steps} steps, {} threads",
        mesh.rest.len(),
        3 * mesh.rest.len(),
        mesh.tets.len(),
        clamped.len(),
        1e3 * mesh.node_mass.iter().sum::<f64>(),
        start.elapsed().as_secs_f64(),
        ProjectiveDynamicsParams::default().threads,
    );
    println!(
        "| global step | set-up (s) | s / step (mean; wall, CPU) | PD iterations / step (mean, most) | local / global s a step | last residual | unconverged steps | max per-step diff vs Cholesky (m) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let solvers = [
        ("Cholesky (factored once)", GlobalSolver::Cholesky),
        (
            "plain Jacobi",
            GlobalSolver::Jacobi(JacobiParams {
                sweeps,
                chebyshev: false,
                ..Default::default()
            }),
        ),
        (
            "Chebyshev Jacobi",
            GlobalSolver::Jacobi(JacobiParams {
                sweeps,
                chebyshev: true,
                ..Default::default()
            }),
        ),
    ];
    let mut reference: Vec<Vec<[f64; 3]>> = Vec::new();
    for (name, solver) in solvers.into_iter().take(if only_direct { 1 } else { 3 }) {
        let params = ProjectiveDynamicsParams {
            solver,
            tolerance,
            max_iterations: 200,
            ..Default::default()
        };
        let setup = Instant::now();
        let mut pd = match ProjectiveDynamics::new(
            &mesh,
            vec![[gamma, gamma]; mesh.tets.len()],
            &clamped,
            params,
        ) {
            Ok(pd) => pd,
            Err(e) => {
                println!("| {name} | — | — | — | — | — | — | refused: {e} |");
                continue;
            }
        };
        let setup = setup.elapsed().as_secs_f64();
        let (mut local, mut global) = (0.0, 0.0);
        let (mut seconds, mut iterations, mut most, mut unconverged, mut residual) =
            (0.0, 0usize, 0usize, 0usize, 0.0);
        let mut diff = 0.0f64;
        let cpu = cpu_seconds();
        for s in 0..steps {
            let r = pd.step(None).expect("a step");
            seconds += r.seconds;
            local += r.local_seconds;
            global += r.global_seconds;
            iterations += r.iterations;
            most = most.max(r.iterations);
            unconverged += usize::from(!r.converged);
            residual = r.residual;
            if reference.len() < steps {
                reference.push(pd.positions().to_vec());
            } else {
                let d = pd
                    .positions()
                    .iter()
                    .flatten()
                    .zip(reference[s].iter().flatten())
                    .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                diff = diff.max(d);
            }
        }
        let cpu = (cpu_seconds() - cpu) / steps as f64;
        let rho = pd
            .jacobi_spectral_radius()
            .map_or(String::new(), |r| format!(" (ρ = {r:.5}, {sweeps} sweeps)"));
        println!(
            "| {name}{rho} | {setup:.2} | {:.3}, {cpu:.3} | {:.1}, {most} | {:.3} / {:.3} | {residual:.2e} | {unconverged} | {diff:.2e} |",
            seconds / steps as f64,
            iterations as f64 / steps as f64,
            local / steps as f64,
            global / steps as f64,
        );
    }
}
