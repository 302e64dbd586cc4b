//! Predictor–corrector evaluations ([`skintight_design::equilibrium_predictor`]): a design whose solves
//! start from the first-order prediction of the new equilibrium, and correct it with Newton, takes fewer
//! Newton iterations and factorizations than one whose solves start from the last equilibrium, and ends at
//! the same design; with chord steps (`optimizer.chord_steps`) the corrector reuses the factorization it
//! finds.

use std::ops::ControlFlow;

use serde_json::{Value, json};
use skintight::design::{DesignJob, prepare_design, run_design};
use skintight::scene::FileResolver;

fn job(optimizer: Value) -> DesignJob {
    let mut doc: Value =
        serde_json::from_str(include_str!("design_support/small_cylinder.json")).unwrap();
    doc["optimizer"] = optimizer;
    DesignJob::from_json(&doc.to_string()).unwrap()
}

/// (final objective, Newton iterations of every design solve, their factorizations, evaluations,
/// seconds, chord steps).
fn design(job: &DesignJob) -> (f64, usize, usize, usize, f64, usize) {
    let mut design = prepare_design(job, &FileResolver::new(".")).unwrap();
    let result = run_design(&mut design, &mut |_| ControlFlow::Continue(()), &|| false).unwrap();
    let totals = design.problem.equilibrium_totals();
    (
        result.final_objective,
        totals.newton_iterations,
        totals.factorizations,
        result.evaluations,
        result.seconds,
        totals.chord_steps,
    )
}

#[test]
fn the_predictor_saves_newton_iterations_and_reaches_the_same_design() {
    for optimizer in [
        json!({"method": "gauss_newton", "max_iterations": 6}),
        json!({"method": "lbfgs", "max_iterations": 6}),
    ] {
        let mut without = optimizer.clone();
        without["predictor"] = json!(false);
        without["inexact_solves"] = json!(false);
        let (t_plain, newton_plain, fact_plain, evals_plain, s_plain, _) =
            design(&job(without.clone()));
        let mut with = without.clone();
        with["predictor"] = json!(true);
        let (t_pred, newton_pred, fact_pred, evals_pred, s_pred, chords_pred) =
            design(&job(with.clone()));
        assert_eq!(chords_pred, 0, "chord steps are off by default");
        println!(
            "{}: without predictor T = {t_plain:.6e}, {newton_plain} Newton iterations, {fact_plain} \
             factorizations, {evals_plain} evaluations, {s_plain:.1} s; with: T = {t_pred:.6e}, \
             {newton_pred}, {fact_pred}, {evals_pred}, {s_pred:.1} s",
            optimizer["method"]
        );
        assert!(
            (t_pred - t_plain).abs() <= 1e-3 * t_plain,
            "the designs differ: {t_pred} vs {t_plain}"
        );
        assert!(
            (newton_pred as f64) < 0.8 * newton_plain as f64,
            "{newton_pred} Newton iterations with the predictor, {newton_plain} without"
        );
        assert!(
            (fact_pred as f64) < 0.8 * fact_plain as f64,
            "{fact_pred} factorizations with the predictor, {fact_plain} without"
        );
        // Chord steps on request: the same design, some Newton iterations without a factorization.
        with["chord_steps"] = json!(true);
        let (t_chord, newton_chord, fact_chord, _, _, chords) = design(&job(with));
        println!(
            "  with chord steps: T = {t_chord:.6e}, {newton_chord}, {fact_chord}, {chords} chord steps"
        );
        assert!(
            (t_chord - t_plain).abs() <= 1e-3 * t_plain,
            "the designs differ: {t_chord} vs {t_plain}"
        );
        assert!(chords > 0);
    }
}

/// Inexact solves ([`skintight_design::inexact_tolerance`]) on top of the predictor: fewer Newton
/// iterations, the same design, the final design's equilibrium at the job's own tolerance, and the
/// problem left at that tolerance.
#[test]
fn inexact_solves_save_newton_iterations_and_end_at_the_tight_tolerance() {
    for method in ["gauss_newton", "lbfgs"] {
        let exact_job = job(json!({
            "method": method, "max_iterations": 6, "predictor": true, "inexact_solves": false
        }));
        let tight = exact_job.solver.tolerance;
        let (t_exact, newton_exact, ..) = design(&exact_job);
        let inexact_job = job(json!({
            "method": method, "max_iterations": 6, "predictor": true, "inexact_solves": true
        }));
        let mut design_run = prepare_design(&inexact_job, &FileResolver::new(".")).unwrap();
        let result = run_design(&mut design_run, &mut |_| ControlFlow::Continue(()), &|| {
            false
        })
        .unwrap();
        let newton_inexact = design_run.problem.equilibrium_totals().newton_iterations;
        println!(
            "{method}: exact solves T = {t_exact:.6e}, {newton_exact} Newton iterations; inexact: T = {:.6e}, \
             {newton_inexact}",
            result.final_objective
        );
        assert!(
            (result.final_objective - t_exact).abs() <= 1e-2 * t_exact,
            "the designs differ: {} vs {t_exact}",
            result.final_objective
        );
        assert!(
            newton_inexact < newton_exact,
            "{newton_inexact} Newton iterations with inexact solves, {newton_exact} without"
        );
        assert!(result.evaluation.equilibrium.residual < tight);
        assert_eq!(design_run.problem.equilibrium_tolerance(), tight);
    }
}

/// With the predictor, a line-search trial after one whose objective is more than twice the best so far
/// (the anchor) starts from the anchor's equilibrium, its prediction the anchor's first one scaled along
/// the line; after a trial below that it starts from the trial's own equilibrium, as without the anchor.
/// And a trial that went far does not move the anchor: the anchor's pattern evaluated again after it gives
/// the anchor's objective (the solve comes back to the anchor's branch).
#[test]
fn a_trial_after_one_far_above_the_best_starts_from_the_best_equilibrium() {
    let job = job(json!({"method": "gauss_newton", "predictor": true, "inexact_solves": false}));
    let mut design = prepare_design(&job, &FileResolver::new(".")).unwrap();
    let x0 = design.map.initial_pattern().to_vec();
    let problem = &mut design.problem;
    let mut go = |_: &skintight_physics::IterationInfo| ControlFlow::Continue(());
    let e0 = problem.evaluate(&x0, true, &mut go).unwrap();
    let anchor_state = problem.state().clone();
    // Uphill along the gradient, scaled so that its largest vertex move is `a` metres.
    let g = e0.gradient.clone().unwrap();
    let gmax = g
        .iter()
        .map(|v| v.x.abs().max(v.y.abs()))
        .fold(0.0, f64::max);
    let along = |a: f64| -> Vec<_> { x0.iter().zip(&g).map(|(x, g)| x + g * (a / gmax)).collect() };

    // A small step first: not far above the anchor, so the next trial starts from it.
    let near = problem.evaluate(&along(1e-4), true, &mut go).unwrap();
    assert!(
        near.value > e0.value && near.value < 2.0 * e0.value,
        "{} against {}",
        near.value,
        e0.value
    );
    let near_state = problem.state().clone();
    problem.evaluate(&along(5e-5), true, &mut go).unwrap();
    let start = problem.last_evaluation().unwrap();
    assert_eq!(
        start.warm_start, near_state,
        "after a near trial: its own equilibrium"
    );

    // A far step: the next trial (half of it) starts from the anchor, predicted along the line.
    let mut a = 2e-3;
    let far = loop {
        let e = problem.evaluate(&along(a), true, &mut go);
        match e {
            Ok(e) if e.value > 2.0 * e0.value => break a,
            _ => {}
        }
        a *= 2.0;
        assert!(a < 0.05, "no step up to 5 cm doubles the objective");
    };
    let far_state = problem.state().clone();
    assert_ne!(far_state, anchor_state);
    let half = problem.evaluate(&along(far / 2.0), true, &mut go).unwrap();
    let start = problem.last_evaluation().unwrap();
    assert_eq!(
        start.warm_start, anchor_state,
        "after a far trial: the anchor's equilibrium"
    );
    assert!(
        start.solve_start.is_some(),
        "the trial is predicted along the anchor's line"
    );
    assert!(half.equilibrium.converged);

    // The anchor's pattern again: the anchor's objective.
    let again = problem.evaluate(&x0, true, &mut go).unwrap();
    assert!(
        (again.value - e0.value).abs() <= 1e-6 * e0.value,
        "{} against {}",
        again.value,
        e0.value
    );
}
