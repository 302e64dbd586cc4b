//! The multi-pose sliding objective (thesis Eq. 182–183) on a tube worn on a cylinder, both cuffs pinned,
//! with two poses (the cylinder bent, and sheared): its partial derivatives with respect to the neutral
//! surface coordinates and the pattern against central differences (none with respect to the body), the
//! friction regimes, and bad poses. The full design gradient through the simulation is checked in
//! `tests/design_gradient.rs`.

mod design_support;
use design_support::{BOTH_CUFFS, sleeve_scene};

use std::ops::ControlFlow;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight::scene::{FileResolver, Scene};
use skintight::simulate::{equilibrium_params, prepare};
use skintight_design::{
    DesignMesh, DesignProblem, Sliding, StateInput, Term, TermGradient, TermInput,
};
use skintight_geometry::math::{Real, Vec2, Vec3};
use skintight_physics::ClothOnBodyState;

fn scene(pinned: &str) -> String {
    sleeve_scene(pinned, 0.02, 1e-10)
}

fn problem(pinned: &str) -> (DesignProblem, Vec<Vec2>) {
    let scene = Scene::from_json(&scene(pinned)).unwrap();
    let mut sim = prepare(&scene, &FileResolver::new(".")).unwrap();
    let params = equilibrium_params(&scene);
    skintight::simulate::run(&mut sim, &mut |_| ControlFlow::Continue(())).unwrap();
    let (mesh, pattern) = DesignMesh::from_garment(&sim.garment);
    let problem = DesignProblem::new(sim.system, sim.state, mesh, vec![], params).unwrap();
    (problem, pattern)
}

/// Two poses of the cylinder's surface: bent in x along its axis (y), and sheared in z.
fn poses(problem: &DesignProblem) -> Vec<Vec<Vec3>> {
    let system = problem.system();
    let rest = system.control_positions(system.rest_positions());
    let bent = rest
        .iter()
        .map(|p| p + Vec3::new(4.0 * p.y * p.y, 0.0, 0.0))
        .collect();
    let sheared = rest
        .iter()
        .map(|p| p + Vec3::new(0.0, 0.0, 0.3 * p.y))
        .collect();
    vec![bent, sheared]
}

struct Eval {
    value: Real,
    per_element: Vec<Real>,
    cloth: Vec<Vec3>,
    pattern: Vec<Vec2>,
    state: Vec<Real>,
}

fn eval(
    problem: &DesignProblem,
    term: &Sliding,
    state: &ClothOnBodyState,
    pattern: &[Vec2],
) -> Eval {
    let system = problem.system();
    let cloth = system.cloth_positions(state).unwrap();
    let input = TermInput {
        mesh: problem.mesh(),
        cloth: &cloth,
        pattern,
        fabric: problem.fabric(),
    };
    let mut g = TermGradient::zeros(problem.mesh());
    let mut sg = vec![0.0; system.num_dofs()];
    let e = term
        .evaluate_with_state(
            &input,
            &StateInput { system, state },
            Some(&mut g),
            Some(&mut sg),
        )
        .unwrap();
    let plain = term
        .evaluate_with_state(&input, &StateInput { system, state }, None, None)
        .unwrap();
    assert_eq!(
        plain.value, e.value,
        "the value does not depend on asking for the gradient"
    );
    Eval {
        value: e.value,
        per_element: e.per_element,
        cloth: g.cloth,
        pattern: g.pattern,
        state: sg,
    }
}

fn direction(problem: &DesignProblem, rng: &mut ChaCha8Rng, ds: Real, dy: Real) -> Vec<Real> {
    let system = problem.system();
    let mut d = vec![0.0; system.num_dofs()];
    for c in 0..system.num_cloth_vertices() {
        if let Some(k) = system.cloth_dof(c) {
            d[k] = rng.random_range(-1.0..1.0) * ds;
            d[k + 1] = rng.random_range(-1.0..1.0) * ds;
        }
    }
    for v in 0..system.num_body_vertices() {
        if let Some(k) = system.body_dof(v) {
            for j in 0..3 {
                d[k + j] = rng.random_range(-1.0..1.0) * dy;
            }
        }
    }
    d
}

#[test]
fn sliding_partials_match_central_differences_in_every_friction_regime() {
    let (problem, pattern) = problem(BOTH_CUFFS);
    let system = problem.system();
    let state = problem.state().clone();
    let q0 = system.dofs(&state);
    let poses = poses(&problem);
    let unpinned = (0..system.num_cloth_vertices())
        .filter(|&c| system.cloth_dof(c).is_some())
        .count();
    for friction in [0.0, 0.3, 1.0] {
        let term = Sliding::new(2.0, friction, poses.clone()).unwrap();
        let base = eval(&problem, &term, &state, &pattern);
        let active = base.per_element.iter().filter(|&&v| v > 0.0).count();
        assert!(active > 0, "μ {friction}: some vertices slide");
        if friction > 0.0 {
            assert!(
                active < unpinned,
                "μ {friction}: friction holds some vertices"
            );
        }
        assert!(base.cloth.iter().all(|v| *v == Vec3::zeros()), "no ∂T/∂x");
        for seed in 0..3 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let at_q = |d: &[Real], t: Real| {
                let q: Vec<Real> = q0.iter().zip(d).map(|(q, d)| q + t * d).collect();
                eval(&problem, &term, &system.with_dofs(&state, &q), &pattern).value
            };
            // Surface coordinates.
            let d = direction(&problem, &mut rng, 1e-3, 0.0);
            let analytic: Real = base.state.iter().zip(&d).map(|(g, v)| g * v).sum();
            let h = 1e-4;
            let numeric = (at_q(&d, h) - at_q(&d, -h)) / (2.0 * h);
            let scale = analytic.abs().max(numeric.abs());
            assert!(scale > 0.0);
            assert!(
                (analytic - numeric).abs() <= 1e-5 * scale,
                "μ {friction} seed {seed} ds: {analytic:e} vs {numeric:e}"
            );
            // The body positions do not matter.
            let dy = direction(&problem, &mut rng, 0.0, 1e-3);
            assert_eq!(at_q(&dy, h), base.value);
            // The pattern.
            let dp: Vec<Vec2> = pattern
                .iter()
                .map(|_| Vec2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)) * 1e-4)
                .collect();
            let analytic: Real = base.pattern.iter().zip(&dp).map(|(g, v)| g.dot(v)).sum();
            let h = 1e-3;
            let at_p = |t: Real| {
                let p: Vec<Vec2> = pattern.iter().zip(&dp).map(|(p, v)| p + v * t).collect();
                eval(&problem, &term, &state, &p).value
            };
            let numeric = (at_p(h) - at_p(-h)) / (2.0 * h);
            let scale = analytic.abs().max(numeric.abs());
            assert!(
                (analytic - numeric).abs() <= 1e-5 * scale,
                "μ {friction} seed {seed} dX̄: {analytic:e} vs {numeric:e}"
            );
        }
    }
    // Friction strong enough holds everything.
    let held = eval(
        &problem,
        &Sliding::new(2.0, 1e6, poses).unwrap(),
        &state,
        &pattern,
    );
    assert_eq!(held.value, 0.0);
    assert!(held.state.iter().all(|&v| v == 0.0));
}

#[test]
fn a_pose_of_the_wrong_size_or_no_state_is_an_error() {
    let (problem, pattern) = problem(BOTH_CUFFS);
    let mut poses = poses(&problem);
    poses[1].pop();
    let term = Sliding::new(1.0, 0.5, poses).unwrap();
    let system = problem.system();
    let cloth = system.cloth_positions(problem.state()).unwrap();
    let input = TermInput {
        mesh: problem.mesh(),
        cloth: &cloth,
        pattern: &pattern,
        fabric: problem.fabric(),
    };
    let err = term
        .evaluate_with_state(
            &input,
            &StateInput {
                system,
                state: problem.state(),
            },
            None,
            None,
        )
        .unwrap_err();
    assert!(err.to_string().contains("pose 1"), "{err}");
    assert!(term.evaluate(&input, None).is_err());
}

fn residuals(
    problem: &DesignProblem,
    term: &Sliding,
    state: &ClothOnBodyState,
    pattern: &[Vec2],
) -> skintight_design::Residuals {
    let system = problem.system();
    let cloth = system.cloth_positions(state).unwrap();
    let input = TermInput {
        mesh: problem.mesh(),
        cloth: &cloth,
        pattern,
        fabric: problem.fabric(),
    };
    term.residuals_with_state(&input, &StateInput { system, state })
        .expect("sliding has residuals")
        .unwrap()
}

/// The Gauss-Newton residuals `√w T_kj`: their squares sum to the value, `2 Jᵀ r` is the gradient
/// (pattern and surface coordinates), and `J d` matches central differences of `r` along random
/// directions of the state and of the pattern, in every friction regime.
#[test]
fn sliding_residuals_square_to_the_value_and_their_jacobian_matches_central_differences() {
    let (problem, pattern) = problem(BOTH_CUFFS);
    let system = problem.system();
    let state = problem.state().clone();
    let q0 = system.dofs(&state);
    let poses = poses(&problem);
    for friction in [0.0, 0.3, 1.0] {
        let term = Sliding::new(2.0, friction, poses.clone()).unwrap();
        let base = eval(&problem, &term, &state, &pattern);
        let r = residuals(&problem, &term, &state, &pattern);
        let squares: Real = r.values.iter().map(|v| v * v).sum();
        assert!(
            (squares - base.value).abs() <= 1e-12 * base.value,
            "μ {friction}: Σ r² {squares:e} vs T {:e}",
            base.value
        );
        assert!(r.cloth_jacobian.is_empty(), "no ∂r/∂x");
        // 2 Jᵀ r against the gradient.
        let mut gp = vec![Vec2::zeros(); pattern.len()];
        for &(k, v, d) in &r.pattern_jacobian {
            gp[v] += d * (2.0 * r.values[k]);
        }
        let mut gq = vec![0.0; system.num_dofs()];
        for &(k, q, d) in &r.state_jacobian {
            gq[q] += 2.0 * r.values[k] * d;
        }
        let scale_p = base.pattern.iter().map(|g| g.norm()).fold(0.0, Real::max);
        for (a, b) in gp.iter().zip(&base.pattern) {
            assert!((a - b).norm() <= 1e-9 * scale_p, "μ {friction}: {a} vs {b}");
        }
        let scale_q = base.state.iter().map(|g| g.abs()).fold(0.0, Real::max);
        for (a, b) in gq.iter().zip(&base.state) {
            assert!((a - b).abs() <= 1e-9 * scale_q, "μ {friction}: {a} vs {b}");
        }
        // J d against central differences (where the set of slipping vertices stays the same).
        let mut compared = 0;
        for seed in 0..3 {
            let mut rng = ChaCha8Rng::seed_from_u64(10 + seed);
            let dq = direction(&problem, &mut rng, 1e-3, 0.0);
            let dp: Vec<Vec2> = pattern
                .iter()
                .map(|_| Vec2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)) * 1e-4)
                .collect();
            let mut jd = vec![0.0; r.values.len()];
            for &(k, q, d) in &r.state_jacobian {
                jd[k] += d * dq[q];
            }
            for &(k, v, d) in &r.pattern_jacobian {
                jd[k] += d.dot(&dp[v]);
            }
            let h = 1e-4;
            let at = |t: Real| {
                let q: Vec<Real> = q0.iter().zip(&dq).map(|(q, d)| q + t * d).collect();
                let p: Vec<Vec2> = pattern.iter().zip(&dp).map(|(p, v)| p + v * t).collect();
                residuals(&problem, &term, &system.with_dofs(&state, &q), &p).values
            };
            let (plus, minus) = (at(h), at(-h));
            if plus.len() != jd.len() || minus.len() != jd.len() {
                continue;
            }
            compared += 1;
            let scale = jd.iter().map(|v| v.abs()).fold(0.0, Real::max);
            assert!(scale > 0.0);
            for (k, a) in jd.iter().enumerate() {
                let numeric = (plus[k] - minus[k]) / (2.0 * h);
                assert!(
                    (a - numeric).abs() <= 1e-5 * scale,
                    "μ {friction} seed {seed} residual {k}: {a:e} vs {numeric:e}"
                );
            }
        }
        assert!(
            compared >= 2,
            "μ {friction}: the active set changed under the step"
        );
    }
}
