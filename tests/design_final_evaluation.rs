//! The evaluation a design ends with ([`skintight_design::DesignProblem::final_evaluation`]) is not lost to
//! a solve that stops short of the tolerance: it goes on from where the solve stopped, and when even that
//! falls short it measures the state reached and says so (`equilibrium.converged` false), which the
//! design's outputs report as a `not_converged` violation.

use std::ops::ControlFlow;

use serde_json::{Value, json};
use skintight::design::{Design, DesignJob, prepare_design};
use skintight::scene::FileResolver;
use skintight_design::math::Vec2;
use skintight_design::{DesignError, FINAL_ROUNDS};

fn prepared() -> Design {
    let mut doc: Value =
        serde_json::from_str(include_str!("design_support/small_cylinder.json")).unwrap();
    doc["optimizer"] =
        json!({"method": "gauss_newton", "predictor": false, "inexact_solves": false});
    let job = DesignJob::from_json(&doc.to_string()).unwrap();
    prepare_design(&job, &FileResolver::new(".")).unwrap()
}

/// The initial pattern with every vertex moved 4 % towards its panel's centroid: a tighter garment whose
/// equilibrium is some Newton iterations away from the initial one.
fn tighter(design: &Design) -> Vec<Vec2> {
    let x0 = design.map.initial_pattern().to_vec();
    let mesh = design.problem.mesh();
    let mut x = x0.clone();
    for panel in &mesh.panels {
        let range = panel.first_vertex..panel.first_vertex + panel.num_vertices;
        let c = x0[range.clone()].iter().fold(Vec2::zeros(), |a, v| a + v) / range.len() as f64;
        for v in range {
            x[v] = c + (x0[v] - c) * 0.96;
        }
    }
    x
}

fn go(_: &skintight_physics::IterationInfo) -> ControlFlow<()> {
    ControlFlow::Continue(())
}

#[test]
fn a_final_solve_that_stops_short_goes_on_from_where_it_stopped() {
    // How many Newton iterations the tighter garment takes in one solve.
    let mut reference = prepared();
    let x1 = tighter(&reference);
    let full = reference.problem.evaluate(&x1, true, &mut go).unwrap();
    let n = full.equilibrium.iterations;
    assert!(
        n >= 4,
        "the tighter garment solves in {n} Newton iterations"
    );

    // Half of them per solve: one solve stops short, the final evaluation goes on and converges.
    let limit = n.div_ceil(2);
    let mut short = prepared();
    short
        .problem
        .set_equilibrium_iteration_limit(limit)
        .unwrap();
    match short.problem.evaluate(&x1, true, &mut go) {
        Err(DesignError::NotConverged { stop, .. }) => assert_eq!(stop, "IterationLimit"),
        other => panic!("{limit} iterations solved it: {:?}", other.map(|e| e.value)),
    }
    let mut patient = prepared();
    patient
        .problem
        .set_equilibrium_iteration_limit(limit)
        .unwrap();
    let before = patient.problem.equilibrium_totals().newton_iterations;
    let last = patient
        .problem
        .final_evaluation(&x1, true, &mut go)
        .unwrap();
    let used = patient.problem.equilibrium_totals().newton_iterations - before;
    println!(
        "one solve: {n} Newton iterations; limit {limit}: {used} over the final evaluation's solves, \
         T = {:.6e} (one solve {:.6e})",
        last.value, full.value
    );
    assert!(last.equilibrium.converged);
    assert!(used > limit, "{used} Newton iterations");
    assert!(
        (last.value - full.value).abs() <= 1e-6 * full.value,
        "{} against {}",
        last.value,
        full.value
    );
    let g = last.gradient.as_ref().unwrap();
    let g_full = full.gradient.as_ref().unwrap();
    let diff: f64 = g
        .iter()
        .zip(g_full)
        .map(|(a, b)| (a - b).norm_squared())
        .sum();
    let norm: f64 = g_full.iter().map(|a| a.norm_squared()).sum();
    assert!(
        diff.sqrt() <= 1e-4 * norm.sqrt(),
        "gradients {} apart",
        diff.sqrt()
    );
}

#[test]
fn a_final_solve_that_never_converges_is_measured_and_says_so() {
    let mut design = prepared();
    let x1 = tighter(&design);
    // One Newton iteration per solve: the first and the added rounds all stop short.
    design.problem.set_equilibrium_iteration_limit(1).unwrap();
    let before = design.problem.equilibrium_totals().newton_iterations;
    let e = design.problem.final_evaluation(&x1, true, &mut go).unwrap();
    let used = design.problem.equilibrium_totals().newton_iterations - before;
    assert!(!e.equilibrium.converged);
    assert_eq!(used, FINAL_ROUNDS + 1);
    let tolerance = design.problem.equilibrium_tolerance();
    assert!(
        e.equilibrium.residual.is_finite() && e.equilibrium.residual >= tolerance,
        "residual {}",
        e.equilibrium.residual
    );
    assert!(e.value.is_finite() && e.value > 0.0);
    assert!(
        e.gradient
            .unwrap()
            .iter()
            .all(|g| g.x.is_finite() && g.y.is_finite())
    );
    // The state reached is the warm start of what follows: one more solve, with the limit lifted,
    // converges from it.
    design.problem.set_equilibrium_iteration_limit(200).unwrap();
    let again = design.problem.evaluate(&x1, true, &mut go).unwrap();
    assert!(again.equilibrium.converged);

    // Cancelled is not "stopped short": the final evaluation does not go on.
    let mut cancelled = prepared();
    let err = cancelled
        .problem
        .final_evaluation(&x1, true, &mut |_| ControlFlow::Break(()))
        .unwrap_err();
    assert_eq!(err, DesignError::Cancelled);
}
