//! Design checkpoints: a design stopped after an iteration and resumed from that iteration's checkpoint
//! (stored as bytes, set up afresh from the job) takes the steps the uninterrupted run took and ends with
//! its final objective — L-BFGS and Gauss-Newton, across a coarse-to-fine level change and across a
//! remesh — and reports only the iterations after the checkpoint.

use std::ops::ControlFlow;

use serde_json::{Value, json};
use skintight::design::{DesignJob, RunCheckpoint, prepare_design, run_design_from};
use skintight::scene::FileResolver;

/// A two-panel sleeve on a small cylinder, shaped towards a tapered revolution target
/// (`design_support/small_cylinder.json`), with the `optimizer` section given. The predictor and inexact
/// solves (on by default) are off unless the section turns them on: a resume of a design without the
/// predictor is exact to the bit, which these tests check; with it, to the equilibrium tolerance.
fn job(mut optimizer: Value) -> DesignJob {
    let mut doc: Value =
        serde_json::from_str(include_str!("design_support/small_cylinder.json")).unwrap();
    for key in ["predictor", "inexact_solves"] {
        if optimizer.get(key).is_none() {
            optimizer[key] = Value::Bool(false);
        }
    }
    doc["optimizer"] = optimizer;
    DesignJob::from_json(&doc.to_string()).unwrap()
}

/// What a run reported and where it ended.
struct Run {
    /// The iteration numbers reported, in order.
    reported: Vec<usize>,
    /// Every checkpoint, as stored.
    checkpoints: Vec<Vec<u8>>,
    final_objective: f64,
    parameters: Vec<f64>,
    /// Per entry: iteration, objective, evaluations and Newton iterations so far.
    history: Vec<(usize, f64, usize, usize)>,
    remeshes: usize,
}

fn run(job: &DesignJob, resume: Option<&[u8]>) -> Run {
    let mut design = prepare_design(job, &FileResolver::new(".")).unwrap();
    let resume = resume.map(|b| RunCheckpoint::decode(b).expect("a checkpoint reads back"));
    let mut reported = Vec::new();
    let mut checkpoints = Vec::new();
    let result = run_design_from(
        &mut design,
        resume,
        &mut |it, checkpoint| {
            reported.push(it.iteration);
            if it.iteration > 0 {
                assert_eq!(checkpoint.iteration(), it.iteration, "checkpoint numbering");
                checkpoints.push(checkpoint.encode());
            }
            ControlFlow::Continue(())
        },
        &|| false,
    )
    .unwrap();
    // The work counts of the history add up: each entry's step counts are the growth of the totals.
    for pair in result.history.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        assert!(b.step_evaluations >= 1, "iteration {}", b.iteration);
        assert_eq!(b.evaluations - a.evaluations, b.step_evaluations);
        assert_eq!(
            b.newton_iterations_total - a.newton_iterations_total,
            b.step_newton_iterations
        );
        assert_eq!(
            b.factorizations_total - a.factorizations_total,
            b.step_factorizations
        );
        assert!(b.step_newton_iterations >= b.newton_iterations);
    }
    Run {
        reported,
        checkpoints,
        final_objective: result.final_objective,
        parameters: result.parameters.clone(),
        history: result
            .history
            .iter()
            .map(|it| {
                (
                    it.iteration,
                    it.objective,
                    it.evaluations,
                    it.newton_iterations_total,
                )
            })
            .collect(),
        remeshes: result.remeshes,
    }
}

/// Resumes `full`'s run from its checkpoint at `iteration` and compares.
fn resumes_exactly(job: &DesignJob, full: &Run, iteration: usize) {
    resumes_within(job, full, iteration, 1e-9);
}

/// [`resumes_exactly`] with objectives and parameters agreeing to `tolerance` (relative; m).
fn resumes_within(job: &DesignJob, full: &Run, iteration: usize, tolerance: f64) {
    let bytes = &full.checkpoints[iteration - 1];
    assert_eq!(RunCheckpoint::decode(bytes).unwrap().iteration(), iteration);
    let resumed = run(job, Some(bytes));
    let expected: Vec<usize> = full
        .reported
        .iter()
        .copied()
        .filter(|&k| k > iteration)
        .collect();
    assert_eq!(
        resumed.reported, expected,
        "iterations reported after the resume"
    );
    let relative = (resumed.final_objective - full.final_objective).abs() / full.final_objective;
    println!(
        "resumed at {iteration}: final objective {:.12e} vs {:.12e} (relative difference {relative:.1e})",
        resumed.final_objective, full.final_objective
    );
    assert!(relative <= tolerance, "relative difference {relative:e}");
    assert_eq!(resumed.history.len(), full.history.len());
    for ((k, a, ea, na), (l, b, eb, nb)) in resumed.history.iter().zip(&full.history) {
        assert_eq!(k, l);
        assert!(
            (a - b).abs() <= tolerance * b.abs(),
            "iteration {k}: {a} vs {b}"
        );
        if tolerance <= 1e-9 {
            assert_eq!((ea, na), (eb, nb), "iteration {k}: the work counts");
        }
    }
    assert_eq!(resumed.remeshes, full.remeshes);
    let moved = resumed
        .parameters
        .iter()
        .zip(&full.parameters)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0_f64, f64::max);
    assert!(
        moved <= tolerance,
        "final boundary parameters differ by {moved:e} m"
    );
}

#[test]
fn lbfgs_resumes_across_a_level_change() {
    let job = job(json!({
        "method": "lbfgs", "max_iterations": 7, "mode_levels": [6], "level_iterations": 3
    }));
    let full = run(&job, None);
    assert_eq!(full.reported.first(), Some(&0));
    assert!(
        full.checkpoints.len() >= 5,
        "{} iterations",
        full.checkpoints.len()
    );
    // At the coarse level's last iteration, and inside the boundary-position level.
    for k in [3, 5] {
        resumes_exactly(&job, &full, k);
    }
}

/// With the predictor the replayed solve is the same, but the next prediction solves with the Hessian,
/// whose rounding (its sparsity pattern and ordering come from the solves before) a fresh problem does not
/// reproduce bit for bit, and a badly conditioned solve magnifies it: a resumed predictor–corrector design
/// agrees with the uninterrupted one to the equilibrium tolerance (measured 3·10⁻⁸), not to 10⁻⁹.
#[test]
fn a_predictor_corrector_design_resumes_to_the_solver_tolerance() {
    let job = job(json!({"method": "lbfgs", "max_iterations": 5, "predictor": true}));
    let full = run(&job, None);
    assert!(
        full.checkpoints.len() >= 4,
        "{} iterations",
        full.checkpoints.len()
    );
    resumes_within(&job, &full, 3, 1e-6);
}

/// Inexact solves: the replayed evaluation is solved to the tolerance it was, and the schedule goes on
/// from the checkpoint's gradient; without the predictor, the resumed design is the uninterrupted one.
#[test]
fn an_inexact_design_resumes_exactly() {
    let job = job(json!({"method": "gauss_newton", "max_iterations": 5, "inexact_solves": true}));
    let full = run(&job, None);
    assert!(
        full.checkpoints.len() >= 4,
        "{} iterations",
        full.checkpoints.len()
    );
    resumes_exactly(&job, &full, 3);
}

#[test]
fn gauss_newton_resumes() {
    let job = job(json!({
        "method": "gauss_newton", "max_iterations": 6, "mode_levels": [6], "level_iterations": 2
    }));
    let full = run(&job, None);
    assert!(
        full.checkpoints.len() >= 4,
        "{} iterations",
        full.checkpoints.len()
    );
    for k in [3] {
        resumes_exactly(&job, &full, k);
    }
}

#[test]
fn a_remeshed_design_resumes_at_the_remesh_and_after_it() {
    let job = job(json!({
        "method": "gauss_newton", "max_iterations": 6,
        "remesh": {"min_quality": 0.99, "max_edge_ratio": 1.01, "max_remeshes": 1}
    }));
    let full = run(&job, None);
    assert_eq!(full.remeshes, 1, "the settings must make the design remesh");
    // The checkpoint that asked for the remesh, and the first after it.
    let at_remesh = (1..=full.checkpoints.len())
        .find(|&k| {
            RunCheckpoint::decode(&full.checkpoints[k - 1])
                .unwrap()
                .design
                .remesh_requested
        })
        .expect("a checkpoint asked for the remesh");
    resumes_exactly(&job, &full, at_remesh);
    assert!(
        full.checkpoints.len() > at_remesh,
        "iterations after the remesh"
    );
    resumes_exactly(&job, &full, at_remesh + 1);
}

#[test]
fn bytes_that_are_not_a_checkpoint_read_as_none() {
    assert!(RunCheckpoint::decode(b"").is_none());
    assert!(RunCheckpoint::decode(b"STSIM\x001\x00rest").is_none());
    assert!(RunCheckpoint::decode(b"STDES\x001\x00\xff\xff\xff").is_none());
}

/// A stop asked for in the middle of an equilibrium solve is honoured within one Newton iteration: after
/// it, the design does at most one more Newton iteration (the final evaluation's first, which polls and
/// stops) — no solve runs on, and no line search goes on solving trials.
#[test]
fn a_stop_mid_solve_is_honoured_within_one_newton_iteration() {
    use std::cell::Cell;
    for method in ["lbfgs", "gauss_newton"] {
        let job = job(json!({"method": method, "max_iterations": 7, "mode_levels": [6]}));
        let mut design = prepare_design(&job, &FileResolver::new(".")).unwrap();
        let polls = Cell::new(0usize);
        // Set at iteration 2's report: the Newton iterations so far and the poll count then.
        let at_report = Cell::new(None::<(usize, usize)>);
        let flip_at = Cell::new(usize::MAX);
        let stop = || {
            polls.set(polls.get() + 1);
            polls.get() >= flip_at.get()
        };
        let outcome = run_design_from(
            &mut design,
            None,
            &mut |it, checkpoint| {
                if it.iteration == 2 {
                    let newton = checkpoint.design.totals.newton_iterations;
                    at_report.set(Some((newton, polls.get())));
                    // Three polls on: inside the next trial's solve.
                    flip_at.set(polls.get() + 3);
                }
                ControlFlow::Continue(())
            },
            &stop,
        );
        let (newton_then, polls_then) = at_report.get().expect("iteration 2 was reported");
        let newton_after = design.problem.equilibrium_totals().newton_iterations - newton_then;
        let polls_before_stop = flip_at.get() - polls_then;
        println!(
            "{method}: {newton_after} Newton iterations after iteration 2, the stop at poll {polls_before_stop} \
             after it; outcome ok: {}",
            outcome.is_ok()
        );
        assert!(
            newton_after <= polls_before_stop + 1,
            "{method}: {newton_after} Newton iterations for {polls_before_stop} polls before the stop"
        );
    }
}
