use super::*;
use crate::problem::Objective;
use std::convert::Infallible;

/// A problem made of two closures: the objective and the direction.
struct Pair<F, D>(F, D);

impl<F, D, E> Objective for Pair<F, D>
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
{
    type Error = E;

    fn evaluate(&mut self, x: &[Real]) -> Result<(Real, Vec<Real>), E> {
        (self.0)(x)
    }
}

impl<F, D, E> GaussNewtonProblem for Pair<F, D>
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
    D: FnMut(&[Real], &[Real], Real) -> Result<Vec<Real>, E>,
{
    fn direction(&mut self, x: &[Real], g: &[Real], kappa: Real) -> Result<Vec<Real>, E> {
        (self.1)(x, g, kappa)
    }
}

/// [`super::gauss_newton`] on the [`Pair`] of `objective` and `direction`, with a callback that does not
/// need the problem.
fn gauss_newton<E, F, D, C>(
    objective: F,
    direction: D,
    x0: &[Real],
    params: &GaussNewtonParams,
    callback: C,
) -> Result<GaussNewtonOutcome, GaussNewtonRunError<E>>
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
    D: FnMut(&[Real], &[Real], Real) -> Result<Vec<Real>, E>,
    C: FnMut(&GaussNewtonIteration) -> ControlFlow<()>,
{
    gauss_newton_from(
        objective,
        direction,
        GaussNewtonStart::Point(x0),
        params,
        callback,
    )
}

/// [`super::gauss_newton_from`] as [`gauss_newton`] above.
fn gauss_newton_from<E, F, D, C>(
    objective: F,
    direction: D,
    from: GaussNewtonStart<'_>,
    params: &GaussNewtonParams,
    mut callback: C,
) -> Result<GaussNewtonOutcome, GaussNewtonRunError<E>>
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
    D: FnMut(&[Real], &[Real], Real) -> Result<Vec<Real>, E>,
    C: FnMut(&GaussNewtonIteration) -> ControlFlow<()>,
{
    super::gauss_newton_from(&mut Pair(objective, direction), from, params, |_, it| {
        callback(it)
    })
}

/// Residuals of a small nonlinear least-squares problem (Rosenbrock as `r = (10 (y − x²), 1 − x)`),
/// `T = Σ r²`, minimum 0 at (1, 1).
fn residuals(x: &[Real]) -> ([Real; 2], [[Real; 2]; 2]) {
    (
        [10.0 * (x[1] - x[0] * x[0]), 1.0 - x[0]],
        [[-20.0 * x[0], 10.0], [-1.0, 0.0]],
    )
}

fn objective(x: &[Real]) -> Result<(Real, Vec<Real>), Infallible> {
    let (r, j) = residuals(x);
    let v = r[0] * r[0] + r[1] * r[1];
    let g = (0..2)
        .map(|i| 2.0 * (j[0][i] * r[0] + j[1][i] * r[1]))
        .collect();
    Ok((v, g))
}

/// `−(2 JᵀJ + κI)⁻¹ g`.
fn direction(x: &[Real], g: &[Real], kappa: Real) -> Result<Vec<Real>, Infallible> {
    let (_, j) = residuals(x);
    let m = |a: usize, b: usize| {
        2.0 * (j[0][a] * j[0][b] + j[1][a] * j[1][b]) + if a == b { kappa } else { 0.0 }
    };
    let det = m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0);
    Ok(vec![
        -(m(1, 1) * g[0] - m(0, 1) * g[1]) / det,
        -(-m(1, 0) * g[0] + m(0, 0) * g[1]) / det,
    ])
}

#[test]
fn solves_rosenbrock_in_few_iterations_and_reports_every_step() {
    let mut seen = Vec::new();
    let out = gauss_newton(
        objective,
        direction,
        &[-1.2, 1.0],
        &GaussNewtonParams {
            gradient_tolerance: 1e-10,
            ..Default::default()
        },
        |it: &GaussNewtonIteration| {
            seen.push((it.iteration, it.value));
            ControlFlow::Continue(())
        },
    )
    .unwrap();
    assert_eq!(out.stop_reason, OptimizerStop::GradientTolerance);
    assert!((out.x[0] - 1.0).abs() < 1e-6 && (out.x[1] - 1.0).abs() < 1e-6);
    assert!(out.iterations < 40, "{} iterations", out.iterations);
    assert_eq!(seen.len(), out.iterations + 1);
    assert!(
        seen.windows(2).all(|w| w[1].1 < w[0].1),
        "monotone decrease"
    );
}

#[test]
fn a_run_resumed_from_any_checkpoint_takes_the_same_steps() {
    let mut full = Vec::new();
    let mut states = Vec::new();
    let params = GaussNewtonParams {
        gradient_tolerance: 1e-10,
        ..Default::default()
    };
    let whole = gauss_newton(
        objective,
        direction,
        &[-1.2, 1.0],
        &params,
        |it: &GaussNewtonIteration| {
            full.push((it.iteration, it.x.to_vec(), it.value, it.damping));
            states.push(it.state());
            ControlFlow::Continue(())
        },
    )
    .unwrap();
    assert!(whole.iterations > 4, "{} iterations", whole.iterations);
    for k in 1..whole.iterations {
        let mut rest = Vec::new();
        let resumed = gauss_newton_from(
            objective,
            direction,
            GaussNewtonStart::Resume(states[k].clone()),
            &params,
            |it: &GaussNewtonIteration| {
                rest.push((it.iteration, it.x.to_vec(), it.value, it.damping));
                ControlFlow::Continue(())
            },
        )
        .unwrap();
        assert_eq!(rest.as_slice(), &full[k + 1..], "resumed at {k}");
        assert_eq!(
            (resumed.x, resumed.iterations, resumed.evaluations),
            (whole.x.clone(), whole.iterations, whole.evaluations)
        );
    }
}

/// `T = x²` from `x = 1` with a fixed direction `d` (too long): the trial steps the line search takes.
fn trial_steps(d: Real) -> (Vec<Real>, GaussNewtonOutcome) {
    let mut trials = Vec::new();
    let out = gauss_newton(
        |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
            trials.push((1.0 - x[0]) / -d);
            Ok((x[0] * x[0], vec![2.0 * x[0]]))
        },
        |_: &[Real], _: &[Real], _: Real| -> Result<Vec<Real>, Infallible> { Ok(vec![d]) },
        &[1.0],
        &GaussNewtonParams {
            max_iterations: 1,
            ..Default::default()
        },
        |_: &GaussNewtonIteration| ControlFlow::Continue(()),
    )
    .unwrap();
    (trials[1..].to_vec(), out)
}

#[test]
fn backtracking_steps_to_the_minimizer_of_the_quadratic_model_kept_within_a_tenth_and_a_half() {
    // d = −4: φ(t) = (1 − 4t)², φ(1) = 9, φ'(0) = −8; the model is exact, its minimizer t = ¼ (x = 0).
    let (trials, out) = trial_steps(-4.0);
    assert_eq!(trials, vec![1.0, 0.25]);
    assert_eq!(out.x, vec![0.0]);
    // Accepted at ¼: the damping grew by 1/α = 4 (from the default 1).
    assert!((out.damping - 4.0).abs() < 1e-12, "{}", out.damping);
    // d = −100: the minimizer 0.01 is below a tenth of the step: 0.1; from there 0.01 is allowed.
    let (trials, out) = trial_steps(-100.0);
    assert_eq!(trials.len(), 3, "{trials:?}");
    assert_eq!(trials[..2], [1.0, 0.1]);
    assert!((trials[2] - 0.01).abs() < 1e-15, "{trials:?}");
    assert!(out.x[0].abs() < 1e-12);
    // The halving rule would have tried 1, ½, ¼, …, 1/64 (x = −0.5625) first: seven trials.
    assert_eq!(backtrack(1.0, 1.0, -8.0, 9.0), 0.25);
    assert_eq!(backtrack(1.0, 1.0, -1.0, 1.0), 0.5);
    assert_eq!(backtrack(0.5, 1.0, -8.0, 1e9), 0.05);
    assert_eq!(backtrack(0.5, 1.0, -8.0, Real::INFINITY), 0.25);
}

#[test]
fn the_line_search_gives_up_below_the_shortest_halving_step() {
    // A direction along which the loss only rises (numerically): no step decreases it, so the
    // attempt's trials stop at 2^−h, and (no retries) the run stops where it started.
    let mut trials = Vec::new();
    let out = gauss_newton(
        |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
            trials.push(x[0] - 1.0);
            Ok((1.0 + (x[0] - 1.0).abs(), vec![-1e-3]))
        },
        |_: &[Real], _: &[Real], _: Real| -> Result<Vec<Real>, Infallible> { Ok(vec![1.0]) },
        &[1.0],
        &GaussNewtonParams {
            max_halvings: 4,
            max_retries: 0,
            ..Default::default()
        },
        |_: &GaussNewtonIteration| ControlFlow::Continue(()),
    )
    .unwrap();
    assert_eq!(out.stop_reason, OptimizerStop::LineSearchFailed);
    assert_eq!(out.x, vec![1.0]);
    let steps = &trials[1..];
    assert!(steps.len() <= 5, "{steps:?}");
    assert!(
        steps.iter().all(|&t| t >= 1.0 / 16.0 * (1.0 - 1e-12)),
        "{steps:?}"
    );
    assert!(
        steps
            .windows(2)
            .all(|w| w[1] <= 0.5 * w[0] && w[1] >= 0.1 * w[0])
    );
}

#[test]
fn a_jump_at_the_current_point_stops_the_run_without_retries() {
    // T = (x − 1)² + J at every x but the start x0 = 0 (T(0) = 1: an equilibrium the trials do not
    // reach), g(0) = −2, d = 8 whatever the damping. Trials x = 8α: α = 1 (excess 48 + J), then the
    // quadratic model's α = 0.122 (x = 0.977, excess J − 1 + 0.0005), then α = 0.0485 (x = 0.388,
    // excess J − 0.63), whose secant slope is 4.4 × the one before: a jump, the run stops there
    // instead of shrinking the step to 2⁻⁸ and retrying three times (up to 36 trials).
    let run = |jump: Real| {
        let mut trials = Vec::new();
        let out = gauss_newton(
            |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
                trials.push(x[0]);
                let off = if x[0] == 0.0 { 0.0 } else { jump };
                Ok(((x[0] - 1.0).powi(2) + off, vec![2.0 * (x[0] - 1.0)]))
            },
            |_: &[Real], g: &[Real], _: Real| -> Result<Vec<Real>, Infallible> {
                Ok(vec![-4.0 * g[0]])
            },
            &[0.0],
            &GaussNewtonParams::default(),
            |_: &GaussNewtonIteration| ControlFlow::Continue(()),
        )
        .unwrap();
        (trials[1..].to_vec(), out)
    };
    let (trials, out) = run(1.5);
    assert_eq!(out.stop_reason, OptimizerStop::LineSearchFailed);
    assert_eq!(out.x, vec![0.0]);
    assert_eq!(trials.len(), 3, "{trials:?}");
    assert!((trials[2] - 0.388).abs() < 1e-3, "{trials:?}");
    // Without the jump the model is exact and its second trial is the minimum; a kink (the excess
    // shrinking as fast as the step) is not a jump either:
    // `the_line_search_gives_up_below_the_shortest_halving_step` tries down to 2⁻ʰ.
    let (trials, out) = run(0.0);
    assert_eq!(trials[..2], [8.0, 1.0]);
    assert_eq!(out.value, 0.0);
}

/// `T = (x − 100)²` and its gradient: every step towards 100 decreases it.
fn towards_100(x: &[Real]) -> (Real, Vec<Real>) {
    ((x[0] - 100.0).powi(2), vec![2.0 * (x[0] - 100.0)])
}

#[test]
fn the_first_trial_moves_at_most_the_growth_factor_times_the_last_accepted_step() {
    // T = (x − 100)² (`towards_100`). Scripted direction lengths 1, 10, 1, 3:
    // with growth 2 the second iteration's first trial is bounded to 2 × 1 (α = 0.2) and accepted
    // there (damping × 5); the third is not bounded (1 ≤ 2 × 2); the fourth is bounded to 2 × 1.
    let run = |growth: Real| {
        let mut trials = Vec::new();
        let mut lengths = [1.0, 10.0, 1.0, 3.0].into_iter();
        let mut dampings = Vec::new();
        let out = gauss_newton(
            |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
                trials.push(x[0]);
                Ok(towards_100(x))
            },
            |_: &[Real], _: &[Real], _: Real| -> Result<Vec<Real>, Infallible> {
                Ok(vec![lengths.next().unwrap_or(1.0)])
            },
            &[0.0],
            &GaussNewtonParams {
                max_iterations: 4,
                max_step_growth: growth,
                ..Default::default()
            },
            |it: &GaussNewtonIteration| {
                dampings.push(it.damping);
                ControlFlow::Continue(())
            },
        )
        .unwrap();
        (trials, dampings, out)
    };
    let (trials, dampings, out) = run(2.0);
    assert_eq!(trials, vec![0.0, 1.0, 3.0, 4.0, 6.0], "{trials:?}");
    assert_eq!(out.iterations, 4);
    // The bounded acceptance at α = 0.2 raised the damping by 1/α = 5 (after the first step's
    // Nielsen factor).
    assert!(
        (dampings[2] / dampings[1] - 5.0).abs() < 1e-9,
        "{dampings:?}"
    );
    // Without the bound the full steps are taken.
    let (trials, _, _) = run(Real::INFINITY);
    assert_eq!(trials, vec![0.0, 1.0, 11.0, 12.0, 15.0], "{trials:?}");
    // A resumed run keeps the bound of the step before its checkpoint.
    let mut states = Vec::new();
    let mut lengths = [1.0, 10.0].into_iter();
    gauss_newton(
        |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> { Ok(towards_100(x)) },
        |_: &[Real], _: &[Real], _: Real| -> Result<Vec<Real>, Infallible> {
            Ok(vec![lengths.next().unwrap_or(1.0)])
        },
        &[0.0],
        &GaussNewtonParams {
            max_iterations: 1,
            ..Default::default()
        },
        |it: &GaussNewtonIteration| {
            states.push(it.state());
            ControlFlow::Continue(())
        },
    )
    .unwrap();
    let resumed = states.pop().unwrap();
    assert_eq!(resumed.last_step, Some(1.0));
    let mut trials = Vec::new();
    gauss_newton_from(
        |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
            trials.push(x[0]);
            Ok(towards_100(x))
        },
        |_: &[Real], _: &[Real], _: Real| -> Result<Vec<Real>, Infallible> { Ok(vec![10.0]) },
        GaussNewtonStart::Resume(resumed),
        &GaussNewtonParams {
            max_iterations: 2,
            ..Default::default()
        },
        |_: &GaussNewtonIteration| ControlFlow::Continue(()),
    )
    .unwrap();
    assert_eq!(trials, vec![3.0], "{trials:?}");
    // Settings below 1 (or not a number) are refused.
    for growth in [0.5, Real::NAN] {
        let params = GaussNewtonParams {
            max_step_growth: growth,
            ..Default::default()
        };
        assert!(params.validate().unwrap_err().contains("max_step_growth"));
    }
}

#[test]
fn failures_are_long_steps_and_limits_stop_the_run_with_the_best_point() {
    // A region x0 > 0.5 fails: the run must still decrease and never accept a failed point.
    let failing = |x: &[Real]| -> Result<(Real, Vec<Real>), String> {
        if x[0] > 0.5 {
            Err("no equilibrium".into())
        } else {
            Ok(objective(x).unwrap())
        }
    };
    let out = gauss_newton(
        failing,
        |x: &[Real], g: &[Real], k: Real| Ok(direction(x, g, k).unwrap()),
        &[-1.2, 1.0],
        &GaussNewtonParams {
            max_iterations: 30,
            ..Default::default()
        },
        |_: &GaussNewtonIteration| ControlFlow::Continue(()),
    )
    .unwrap();
    assert!(out.x[0] <= 0.5 && out.value < objective(&[-1.2, 1.0]).unwrap().0);
    assert!(out.failed_evaluations > 0);
    // A direction that is never a descent direction: stops after the retries, at the start.
    let out = gauss_newton(
        objective,
        |_: &[Real], _: &[Real], _: Real| -> Result<Vec<Real>, Infallible> { Ok(vec![-1.0, 0.0]) },
        &[-1.2, 1.0],
        &GaussNewtonParams::default(),
        |_: &GaussNewtonIteration| ControlFlow::Continue(()),
    )
    .unwrap();
    assert_eq!(out.stop_reason, OptimizerStop::LineSearchFailed);
    assert_eq!(out.x, vec![-1.2, 1.0]);
    // The callback and the iteration limit.
    let out = gauss_newton(
        objective,
        direction,
        &[-1.2, 1.0],
        &GaussNewtonParams::default(),
        |it: &GaussNewtonIteration| {
            if it.iteration == 2 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        },
    )
    .unwrap();
    assert_eq!(
        (out.stop_reason, out.iterations),
        (OptimizerStop::Callback, 2)
    );
    let bad = GaussNewtonParams {
        initial_damping: 0.0,
        ..Default::default()
    };
    assert!(matches!(
        gauss_newton(
            objective,
            direction,
            &[0.0, 0.0],
            &bad,
            |_: &GaussNewtonIteration| { ControlFlow::Continue(()) }
        ),
        Err(GaussNewtonRunError::InvalidParameters(_))
    ));
}

/// `T = (x + 1)²` over `x ≥ 0`: the projected line search stops at the bound, never evaluating a
/// negative point.
#[test]
fn projected_trials_stay_in_the_feasible_set() {
    struct Bounded(usize);
    impl Objective for Bounded {
        type Error = String;
        fn evaluate(&mut self, x: &[Real]) -> Result<(Real, Vec<Real>), String> {
            self.0 += 1;
            if x[0] < 0.0 {
                return Err(format!("x = {} < 0 evaluated", x[0]));
            }
            Ok(((x[0] + 1.0).powi(2), vec![2.0 * (x[0] + 1.0)]))
        }
    }
    impl GaussNewtonProblem for Bounded {
        fn direction(&mut self, _x: &[Real], g: &[Real], kappa: Real) -> Result<Vec<Real>, String> {
            Ok(vec![-g[0] / (2.0 + kappa)])
        }
        fn project(&self, x: &mut [Real]) {
            x[0] = x[0].max(0.0);
        }
    }
    let mut problem = Bounded(0);
    let out = super::gauss_newton(
        &mut problem,
        &[3.0],
        &GaussNewtonParams::default(),
        |p: &mut Bounded, _| {
            assert!(p.0 > 0);
            ControlFlow::Continue(())
        },
    )
    .unwrap();
    assert_eq!(out.x, vec![0.0], "{out:?}");
    assert_eq!(out.value, 1.0);
}
