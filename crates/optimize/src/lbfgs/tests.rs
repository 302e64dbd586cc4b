use super::*;
use std::cell::RefCell;
use std::convert::Infallible;

/// [`super::lbfgs`] on a closure, with a callback that does not need the problem.
fn lbfgs<E, F, C>(
    objective: F,
    x0: &[Real],
    params: &LbfgsParams,
    callback: C,
) -> Result<LbfgsResult, LbfgsError<E>>
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
    C: FnMut(&LbfgsIteration) -> ControlFlow<()>,
{
    lbfgs_from(objective, LbfgsStart::Point(x0), params, callback)
}

/// [`super::lbfgs_from`] as [`lbfgs`] above.
fn lbfgs_from<E, F, C>(
    mut objective: F,
    from: LbfgsStart<'_>,
    params: &LbfgsParams,
    mut callback: C,
) -> Result<LbfgsResult, LbfgsError<E>>
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
    C: FnMut(&LbfgsIteration) -> ControlFlow<()>,
{
    super::lbfgs_from(&mut objective, from, params, |_, it| callback(it))
}

/// Extended Rosenbrock (Moré, Garbow, Hillstrom #21): independent 2D Rosenbrock pairs, minimum 0 at
/// all ones, no other stationary point.
fn rosenbrock(x: &[Real]) -> (Real, Vec<Real>) {
    let mut f = 0.0;
    let mut g = vec![0.0; x.len()];
    for i in (0..x.len()).step_by(2) {
        let (a, b) = (x[i], x[i + 1]);
        let t = b - a * a;
        f += 100.0 * t * t + (1.0 - a) * (1.0 - a);
        g[i] = -400.0 * a * t - 2.0 * (1.0 - a);
        g[i + 1] = 200.0 * t;
    }
    (f, g)
}

fn ok(x: &[Real]) -> Result<(Real, Vec<Real>), Infallible> {
    Ok(rosenbrock(x))
}

fn start(n: usize) -> Vec<Real> {
    (0..n)
        .map(|i| if i % 2 == 0 { -1.2 } else { 1.0 })
        .collect()
}

fn tight() -> LbfgsParams {
    LbfgsParams {
        gradient_tolerance: 1e-9,
        min_relative_decrease: 0.0,
        ..LbfgsParams::default()
    }
}

fn continue_(_: &LbfgsIteration) -> ControlFlow<()> {
    ControlFlow::Continue(())
}

#[test]
fn default_parameters_are_valid_and_bad_ones_are_errors() {
    assert!(LbfgsParams::default().validate().is_ok());
    let bad = [
        LbfgsParams {
            memory: 0,
            ..Default::default()
        },
        LbfgsParams {
            c1: 0.95,
            ..Default::default()
        },
        LbfgsParams {
            c2: 1.0,
            ..Default::default()
        },
        LbfgsParams {
            gradient_tolerance: -1.0,
            ..Default::default()
        },
        LbfgsParams {
            time_limit_seconds: Some(0.0),
            ..Default::default()
        },
        LbfgsParams {
            initial_step_length: Real::NAN,
            ..Default::default()
        },
        LbfgsParams {
            no_progress_iterations: 0,
            ..Default::default()
        },
        LbfgsParams {
            max_line_search_evaluations: 0,
            ..Default::default()
        },
        LbfgsParams {
            min_relative_decrease: Real::INFINITY,
            ..Default::default()
        },
    ];
    for p in bad {
        assert!(matches!(
            lbfgs(ok, &[0.0, 0.0], &p, continue_),
            Err(LbfgsError::InvalidParameters(_))
        ));
    }
}

#[test]
fn rosenbrock_2d_converges() {
    let r = lbfgs(ok, &start(2), &tight(), continue_).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::GradientTolerance);
    for x in &r.x {
        assert!((x - 1.0).abs() < 1e-6, "{:?}", r.x);
    }
    assert!(r.value < 1e-12);
    assert!(r.iterations < 100, "{} iterations", r.iterations);
}

#[test]
fn rosenbrock_10d_converges() {
    let r = lbfgs(ok, &start(10), &tight(), continue_).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::GradientTolerance);
    for x in &r.x {
        assert!((x - 1.0).abs() < 1e-6, "{:?}", r.x);
    }
    assert_eq!(r.failed_evaluations, 0);
}

#[test]
fn wolfe_conditions_hold_at_every_accepted_step() {
    let params = tight();
    for n in [2, 10] {
        let mut previous: Option<(Vec<Real>, Real, Vec<Real>)> = None;
        let mut steps = 0;
        let check = |it: &LbfgsIteration| {
            if let Some((x0, f0, g0)) = &previous {
                // The search direction, recovered from the step: d = (x1 − x0) / α.
                let d: Vec<Real> =
                    it.x.iter()
                        .zip(x0)
                        .map(|(a, b)| (a - b) / it.step_length)
                        .collect();
                let slope0 = dot(g0, &d);
                let slope1 = dot(it.gradient, &d);
                assert!(slope0 < 0.0, "not a descent direction");
                assert!(
                    it.value <= f0 + params.c1 * it.step_length * slope0,
                    "sufficient decrease fails at iteration {}",
                    it.iteration
                );
                assert!(
                    slope1.abs() <= params.c2 * slope0.abs() * (1.0 + 1e-9),
                    "curvature fails at iteration {}",
                    it.iteration
                );
                steps += 1;
            }
            previous = Some((it.x.to_vec(), it.value, it.gradient.to_vec()));
            ControlFlow::Continue(())
        };
        let r = lbfgs(ok, &start(n), &params, check).unwrap();
        assert_eq!(steps, r.iterations);
        assert!(steps > 10);
    }
}

#[test]
fn convex_quadratic_converges_in_few_iterations() {
    // f = ½ xᵀ A x − bᵀ x with A = R diag(1..10) Rᵀ, R = I − 2 v vᵀ / vᵀv (orthogonal): n = 10,
    // condition number 10.
    let n = 10;
    let v: Vec<Real> = (0..n).map(|i| 1.0 + (i as Real * 0.7).sin()).collect();
    let vv = dot(&v, &v);
    let r = |i: usize, j: usize| (if i == j { 1.0 } else { 0.0 }) - 2.0 * v[i] * v[j] / vv;
    let a: Vec<Vec<Real>> = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| (0..n).map(|k| r(i, k) * (1.0 + k as Real) * r(j, k)).sum())
                .collect()
        })
        .collect();
    let b: Vec<Real> = (0..n).map(|i| (i as Real * 0.5).cos()).collect();
    let f = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
        let ax: Vec<Real> = (0..n).map(|i| dot(&a[i], x)).collect();
        let value = 0.5 * dot(x, &ax) - dot(&b, x);
        let grad = ax.iter().zip(&b).map(|(p, q)| p - q).collect();
        Ok((value, grad))
    };
    let params = LbfgsParams {
        memory: n,
        // f* ≈ −0.65: a gradient of 1e-6 leaves f − f* ≈ 1e-13, well above round-off.
        gradient_tolerance: 1e-6,
        min_relative_decrease: 0.0,
        ..LbfgsParams::default()
    };
    let result = lbfgs(f, &vec![0.0; n], &params, continue_).unwrap();
    assert_eq!(result.stop_reason, OptimizerStop::GradientTolerance);
    assert!(
        result.iterations <= n + 5,
        "{} iterations",
        result.iterations
    );
}

#[test]
fn failures_beyond_a_radius_are_shrunk_and_it_still_converges() {
    // f = ‖x − a‖² with ‖a‖ = 0.9, undefined (Err) outside the unit ball; a first trial step of 10
    // leaves the ball.
    let a = [0.6, -0.6, 0.3];
    let failures = RefCell::new(0);
    let f = |x: &[Real]| -> Result<(Real, Vec<Real>), String> {
        if norm(x) > 1.0 {
            *failures.borrow_mut() += 1;
            return Err("outside".into());
        }
        let d: Vec<Real> = x.iter().zip(&a).map(|(x, a)| x - a).collect();
        Ok((dot(&d, &d), d.iter().map(|d| 2.0 * d).collect()))
    };
    let params = LbfgsParams {
        initial_step_length: 10.0,
        gradient_tolerance: 1e-10,
        ..LbfgsParams::default()
    };
    let r = lbfgs(f, &[-0.5, 0.5, 0.0], &params, continue_).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::GradientTolerance);
    assert!(*failures.borrow() > 0);
    assert_eq!(r.failed_evaluations, *failures.borrow());
    for (x, a) in r.x.iter().zip(&a) {
        assert!((x - a).abs() < 1e-9);
    }
    // Non-finite values count as failures too.
    let g = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
        if norm(x) > 1.0 {
            return Ok((Real::NAN, vec![0.0; 3]));
        }
        let d: Vec<Real> = x.iter().zip(&a).map(|(x, a)| x - a).collect();
        Ok((dot(&d, &d), d.iter().map(|d| 2.0 * d).collect()))
    };
    let r = lbfgs(g, &[-0.5, 0.5, 0.0], &params, continue_).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::GradientTolerance);
    assert!(r.failed_evaluations > 0);
}

#[test]
fn failure_at_the_start_is_an_error() {
    let f = |_: &[Real]| -> Result<(Real, Vec<Real>), &str> { Err("no") };
    assert_eq!(
        lbfgs(f, &[1.0], &LbfgsParams::default(), continue_),
        Err(LbfgsError::InitialEvaluation("no"))
    );
    let g = |_: &[Real]| -> Result<(Real, Vec<Real>), &str> { Ok((Real::INFINITY, vec![0.0])) };
    assert!(matches!(
        lbfgs(g, &[1.0], &LbfgsParams::default(), continue_),
        Err(LbfgsError::InvalidStart(_))
    ));
    let h = |_: &[Real]| -> Result<(Real, Vec<Real>), &str> { Ok((1.0, vec![0.0, 1.0])) };
    assert!(matches!(
        lbfgs(h, &[1.0], &LbfgsParams::default(), continue_),
        Err(LbfgsError::InvalidStart(_))
    ));
    let k = |_: &[Real]| -> Result<(Real, Vec<Real>), &str> { Ok((1.0, vec![Real::NAN])) };
    assert!(matches!(
        lbfgs(k, &[1.0], &LbfgsParams::default(), continue_),
        Err(LbfgsError::InvalidStart(_))
    ));
}

#[test]
fn iteration_limit_returns_the_best_point() {
    let params = LbfgsParams {
        max_iterations: 3,
        ..tight()
    };
    let r = lbfgs(ok, &start(2), &params, continue_).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::MaxIterations);
    assert_eq!(r.iterations, 3);
    let (f0, _) = rosenbrock(&start(2));
    assert!(r.value < f0);
    let (f, g) = rosenbrock(&r.x);
    assert_eq!(f, r.value);
    assert_eq!(g, r.gradient);
    assert_eq!(r.gradient_norm, norm(&g));
}

#[test]
fn time_limit_returns_the_best_point() {
    let slow = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
        std::thread::sleep(std::time::Duration::from_millis(2));
        Ok(rosenbrock(x))
    };
    let params = LbfgsParams {
        time_limit_seconds: Some(0.03),
        ..tight()
    };
    let r = lbfgs(slow, &start(10), &params, continue_).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::TimeLimit);
    assert!(r.elapsed_seconds < 1.0);
    let (f0, _) = rosenbrock(&start(10));
    assert!(r.value <= f0);
    assert_eq!(rosenbrock(&r.x).0, r.value);
}

#[test]
fn callback_can_stop_the_run() {
    let mut seen = Vec::new();
    let stop = |it: &LbfgsIteration| {
        seen.push((it.iteration, it.evaluations, it.elapsed_seconds));
        if it.iteration == 2 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    };
    let r = lbfgs(ok, &start(2), &tight(), stop).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::Callback);
    assert_eq!(r.iterations, 2);
    assert_eq!(seen.iter().map(|s| s.0).collect::<Vec<_>>(), vec![0, 1, 2]);
    assert!(seen.windows(2).all(|w| w[0].1 < w[1].1 && w[0].2 <= w[1].2));
    // Stopping at the start returns the start.
    let r = lbfgs(ok, &start(2), &tight(), |_: &LbfgsIteration| {
        ControlFlow::Break(())
    })
    .unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::Callback);
    assert_eq!(r.x, start(2));
    assert_eq!(r.iterations, 0);
}

#[test]
fn no_progress_stops_the_run() {
    // A huge constant offset makes every decrease relatively tiny.
    // f = 1e8 + ½ Σ λ_i x_i² with λ_i = 1 + 11 i: at most 250 to gain from x = 1, relatively < 1e-5.
    let f = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
        let lambda = |i: usize| 1.0 + 11.0 * i as Real;
        let value = 1e8
            + 0.5
                * x.iter()
                    .enumerate()
                    .map(|(i, x)| lambda(i) * x * x)
                    .sum::<Real>();
        Ok((
            value,
            x.iter().enumerate().map(|(i, x)| lambda(i) * x).collect(),
        ))
    };
    let params = LbfgsParams {
        gradient_tolerance: 0.0,
        min_relative_decrease: 1e-5,
        no_progress_iterations: 3,
        ..LbfgsParams::default()
    };
    let r = lbfgs(f, &[1.0; 10], &params, continue_).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::NoProgress);
    assert_eq!(r.iterations, 3);
    assert!(r.value < 1e8 + 250.0);
}

#[test]
fn a_search_without_a_curvature_step_moves_to_its_lowest_sufficient_decrease() {
    // f = (x − 3)², but the reported slope is −6 everywhere (as at x = 0): no step meets the curvature
    // condition, several meet sufficient decrease. The search moves to the lowest of those instead of
    // failing (regression: the hourglass design stopped with LineSearchFailed at 17.5× reduction).
    let f = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
        Ok(((x[0] - 3.0).powi(2), vec![-6.0]))
    };
    let params = LbfgsParams {
        max_iterations: 1,
        max_line_search_evaluations: 12,
        ..LbfgsParams::default()
    };
    let r = lbfgs(f, &[0.0], &params, continue_).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::MaxIterations);
    assert_eq!(r.iterations, 1);
    assert!(r.value < 9.0 * 0.5, "value {} after one step", r.value);
    assert!(r.x[0] > 0.0 && r.x[0] < 6.0);
}

#[test]
fn a_wrong_gradient_fails_the_line_search() {
    // The reported gradient points uphill: no step satisfies sufficient decrease.
    let evaluations = RefCell::new(0);
    let f = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
        *evaluations.borrow_mut() += 1;
        Ok((dot(x, x), x.iter().map(|x| -2.0 * x).collect()))
    };
    let params = LbfgsParams {
        max_line_search_evaluations: 10,
        ..LbfgsParams::default()
    };
    let r = lbfgs(f, &[1.0, 2.0], &params, continue_).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::LineSearchFailed);
    assert_eq!(r.x, vec![1.0, 2.0]);
    assert_eq!(r.iterations, 0);
    // The first direction is already steepest descent: one search only (1 + 10 evaluations).
    assert_eq!(*evaluations.borrow(), 11);
}

#[test]
fn a_failed_quasi_newton_search_retries_steepest_descent() {
    // f = 5x² + 9xy + 5y² (eigenvalues ½ and 9½). Run once to learn the first iterate x1 and the
    // quasi-Newton direction d of the second iteration (its first trial is x1 + d); then make the
    // objective fail inside a thin cone around d with apex x1: every quasi-Newton trial fails, the
    // steepest-descent retry succeeds.
    let quadratic = |x: &[Real]| {
        (
            5.0 * x[0] * x[0] + 9.0 * x[0] * x[1] + 5.0 * x[1] * x[1],
            vec![10.0 * x[0] + 9.0 * x[1], 9.0 * x[0] + 10.0 * x[1]],
        )
    };
    let x0 = [1.0, 0.0];
    let log = RefCell::new(Vec::new());
    let logged = |x: &[Real]| -> Result<(Real, Vec<Real>), Infallible> {
        log.borrow_mut().push(x.to_vec());
        Ok(quadratic(x))
    };
    let mut x1 = Vec::new();
    let mut evals_at_x1 = 0;
    let params = LbfgsParams {
        max_iterations: 2,
        ..LbfgsParams::default()
    };
    lbfgs(logged, &x0, &params, |it: &LbfgsIteration| {
        if it.iteration == 1 {
            x1 = it.x.to_vec();
            evals_at_x1 = it.evaluations;
        }
        ControlFlow::Continue(())
    })
    .unwrap();
    let trial = log.borrow()[evals_at_x1].clone();
    let d = [trial[0] - x1[0], trial[1] - x1[1]];
    let g1 = quadratic(&x1).1;
    let cos_sd = -(g1[0] * d[0] + g1[1] * d[1]) / (norm(&g1) * norm(&d));
    assert!(
        cos_sd < 0.9999,
        "the directions must differ for this test ({cos_sd})"
    );
    let in_cone = |x: &[Real]| {
        let v = [x[0] - x1[0], x[1] - x1[1]];
        let nv = norm(&v);
        nv > 0.0 && (v[0] * d[0] + v[1] * d[1]) / (nv * norm(&d)) > 0.99999
    };
    let failing = |x: &[Real]| -> Result<(Real, Vec<Real>), &str> {
        if in_cone(x) {
            Err("in the cone")
        } else {
            Ok(quadratic(x))
        }
    };
    let mut steepest = Vec::new();
    let r = lbfgs(failing, &x0, &params, |it: &LbfgsIteration| {
        steepest.push(it.steepest_descent);
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(r.iterations, 2);
    assert_eq!(r.stop_reason, OptimizerStop::MaxIterations);
    // Iteration 2 was taken along steepest descent after the quasi-Newton search failed.
    assert_eq!(steepest, vec![true, true, true]);
    assert_eq!(r.failed_evaluations, params.max_line_search_evaluations);
    assert!(r.value < quadratic(&x1).0);
}

#[test]
fn empty_problem_stops_at_once() {
    let f = |_: &[Real]| -> Result<(Real, Vec<Real>), Infallible> { Ok((2.0, Vec::new())) };
    let r = lbfgs(f, &[], &LbfgsParams::default(), continue_).unwrap();
    assert_eq!(r.stop_reason, OptimizerStop::GradientTolerance);
    assert_eq!(r.value, 2.0);
}

/// Every accepted iterate of a run: its number, point and value.
type Path = Vec<(usize, Vec<Real>, Real)>;

#[test]
fn a_run_resumed_from_any_checkpoint_takes_the_same_steps() {
    // With failures beyond a radius, so that the best point, the failed count and memory restarts matter.
    let failing = |x: &[Real]| -> Result<(Real, Vec<Real>), String> {
        if x.iter().map(|v| v * v).sum::<Real>() > 9.0 {
            Err("no equilibrium".into())
        } else {
            Ok(rosenbrock(x))
        }
    };
    let params = LbfgsParams {
        memory: 3,
        ..tight()
    };
    let mut full: Path = Vec::new();
    let mut states = Vec::new();
    let whole = lbfgs(failing, &start(6), &params, |it: &LbfgsIteration| {
        full.push((it.iteration, it.x.to_vec(), it.value));
        states.push(it.state());
        ControlFlow::Continue(())
    })
    .unwrap();
    assert!(whole.iterations > 10, "{} iterations", whole.iterations);
    for k in [1, 4, whole.iterations / 2, whole.iterations - 1] {
        let mut rest: Path = Vec::new();
        let resumed = lbfgs_from(
            failing,
            LbfgsStart::Resume(states[k].clone()),
            &params,
            |it: &LbfgsIteration| {
                rest.push((it.iteration, it.x.to_vec(), it.value));
                ControlFlow::Continue(())
            },
        )
        .unwrap();
        assert_eq!(rest.as_slice(), &full[k + 1..], "resumed at {k}");
        assert_eq!(resumed.x, whole.x);
        assert_eq!(
            (
                resumed.iterations,
                resumed.evaluations,
                resumed.failed_evaluations
            ),
            (
                whole.iterations,
                whole.evaluations,
                whole.failed_evaluations
            )
        );
        assert_eq!(resumed.stop_reason, whole.stop_reason);
    }
    // A checkpoint of another problem size is refused.
    let mut wrong = states[2].clone();
    wrong.x.pop();
    assert!(matches!(
        lbfgs_from(ok, LbfgsStart::Resume(wrong), &params, continue_),
        Err(LbfgsError::InvalidStart(_))
    ));
}
