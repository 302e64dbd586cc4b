//! The pinned-traction regularizer (thesis Eq. 188) on a garment at equilibrium, both cuffs pinned: its
//! partial derivatives with respect to the state `q` (through the cloth positions and, directly, through
//! the body surface's tangents) and the pattern `X̄` against central differences, its residuals and their
//! Jacobians, and that a zero weight gives zero. The full design gradient through
//! the simulation is checked in `tests/design_gradient.rs`.

mod design_support;
use design_support::{BOTH_CUFFS, sleeve_scene};

use std::ops::ControlFlow;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight::scene::{FileResolver, Scene};
use skintight::simulate::{equilibrium_params, prepare};
use skintight_design::{
    DesignMesh, DesignProblem, PinnedTraction, StateInput, Term, TermGradient, TermInput,
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

struct Eval {
    value: Real,
    cloth: Vec<Vec3>,
    pattern: Vec<Vec2>,
    state: Vec<Real>,
}

fn eval(
    problem: &DesignProblem,
    term: &PinnedTraction,
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
    Eval {
        value: e.value,
        cloth: g.cloth,
        pattern: g.pattern,
        state: sg,
    }
}

fn value(
    problem: &DesignProblem,
    term: &PinnedTraction,
    state: &ClothOnBodyState,
    pattern: &[Vec2],
) -> Real {
    let system = problem.system();
    let cloth = system.cloth_positions(state).unwrap();
    let input = TermInput {
        mesh: problem.mesh(),
        cloth: &cloth,
        pattern,
        fabric: problem.fabric(),
    };
    term.evaluate_with_state(&input, &StateInput { system, state }, None, None)
        .unwrap()
        .value
}

/// A random direction of the unknowns: surface coordinates by up to `ds`, body positions by up to `dy` m.
fn state_direction(problem: &DesignProblem, rng: &mut ChaCha8Rng, ds: Real, dy: Real) -> Vec<Real> {
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

fn close(name: &str, analytic: Real, numeric: Real, rel: Real) {
    let scale = analytic.abs().max(numeric.abs());
    assert!(scale > 0.0, "{name}: no change along the direction");
    assert!(
        (analytic - numeric).abs() <= rel * scale,
        "{name}: analytic {analytic:e} vs central difference {numeric:e}"
    );
}

#[test]
fn pinned_traction_partials_match_central_differences() {
    let (problem, pattern) = problem(BOTH_CUFFS);
    let system = problem.system();
    let state = problem.state().clone();
    let q0 = system.dofs(&state);
    for weight in [1.0, 250.0] {
        let term = PinnedTraction::new(weight).unwrap();
        let base = eval(&problem, &term, &state, &pattern);
        assert!(base.value > 0.0, "the cuffs carry tangential force");
        let total_q = {
            let mut t = system
                .cloth_jacobian_transpose(&state, &base.cloth)
                .unwrap();
            for (a, b) in t.iter_mut().zip(&base.state) {
                *a += b;
            }
            t
        };
        assert!(
            base.state.iter().any(|&v| v != 0.0),
            "the tangents move with the body"
        );
        for seed in 0..3 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            // Along the state: surface coordinates and body positions together, then the body alone (the
            // direct tangent term).
            for (what, ds) in [("q", 1e-3), ("y", 0.0)] {
                let d = state_direction(&problem, &mut rng, ds, 1e-3);
                let analytic: Real = total_q.iter().zip(&d).map(|(g, v)| g * v).sum();
                let h = 1e-4;
                let at = |t: Real| {
                    let q: Vec<Real> = q0.iter().zip(&d).map(|(q, d)| q + t * d).collect();
                    value(&problem, &term, &system.with_dofs(&state, &q), &pattern)
                };
                let numeric = (at(h) - at(-h)) / (2.0 * h);
                close(
                    &format!("w {weight} seed {seed} d{what}"),
                    analytic,
                    numeric,
                    1e-5,
                );
            }
            // Along the pattern, the state fixed.
            let dp: Vec<Vec2> = pattern
                .iter()
                .map(|_| Vec2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)) * 1e-4)
                .collect();
            let analytic: Real = base.pattern.iter().zip(&dp).map(|(g, v)| g.dot(v)).sum();
            let h = 1e-3;
            let at = |t: Real| {
                let p: Vec<Vec2> = pattern.iter().zip(&dp).map(|(p, v)| p + v * t).collect();
                value(&problem, &term, &state, &p)
            };
            close(
                &format!("w {weight} seed {seed} dX̄"),
                analytic,
                (at(h) - at(-h)) / (2.0 * h),
                1e-5,
            );
        }
    }
}

#[test]
fn pinned_traction_residuals_square_to_the_value_and_their_jacobians_match() {
    let (problem, pattern) = problem(BOTH_CUFFS);
    let system = problem.system();
    let state = problem.state().clone();
    let term = PinnedTraction::new(3.0).unwrap();
    let residuals_at = |state: &ClothOnBodyState, pattern: &[Vec2]| {
        let cloth = system.cloth_positions(state).unwrap();
        let input = TermInput {
            mesh: problem.mesh(),
            cloth: &cloth,
            pattern,
            fabric: problem.fabric(),
        };
        term.residuals_with_state(&input, &StateInput { system, state })
            .unwrap()
            .unwrap()
    };
    let r = residuals_at(&state, &pattern);
    let v = value(&problem, &term, &state, &pattern);
    let sum: Real = r.values.iter().map(|r| r * r).sum();
    assert!((sum - v).abs() <= 1e-12 * v, "Σ r² = {sum}, T = {v}");
    assert!(
        !r.state_jacobian.is_empty(),
        "the tangents move with the body"
    );
    let q0 = system.dofs(&state);
    for seed in 0..3 {
        let mut rng = ChaCha8Rng::seed_from_u64(10 + seed);
        let dq = state_direction(&problem, &mut rng, 1e-3, 1e-3);
        let dx = system.cloth_jacobian(&state, &dq).unwrap();
        let dp: Vec<Vec2> = pattern
            .iter()
            .map(|_| Vec2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)) * 1e-4)
            .collect();
        // R_x J dq + R_q dq + R_X dX̄ against central differences of r along (dq, dX̄).
        let mut analytic = vec![0.0; r.values.len()];
        for &(k, c, d) in &r.cloth_jacobian {
            analytic[k] += d.dot(&dx[c]);
        }
        for &(k, j, d) in &r.state_jacobian {
            analytic[k] += d * dq[j];
        }
        for &(k, p, d) in &r.pattern_jacobian {
            analytic[k] += d.dot(&dp[p]);
        }
        let h = 1e-4;
        let at = |t: Real| {
            let q: Vec<Real> = q0.iter().zip(&dq).map(|(q, d)| q + t * d).collect();
            let p: Vec<Vec2> = pattern.iter().zip(&dp).map(|(p, v)| p + v * t).collect();
            residuals_at(&system.with_dofs(&state, &q), &p).values
        };
        let (plus, minus) = (at(h), at(-h));
        let scale = analytic.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        assert!(scale > 0.0);
        for k in 0..analytic.len() {
            let numeric = (plus[k] - minus[k]) / (2.0 * h);
            assert!(
                (analytic[k] - numeric).abs() <= 1e-5 * scale,
                "seed {seed} residual {k}: {} vs {numeric}",
                analytic[k]
            );
        }
    }
}

#[test]
fn zero_weight_gives_zero_and_no_state_is_an_error() {
    let (problem, pattern) = problem(BOTH_CUFFS);
    let zero = eval(
        &problem,
        &PinnedTraction::new(0.0).unwrap(),
        problem.state(),
        &pattern,
    );
    assert_eq!(zero.value, 0.0);
    assert!(zero.state.iter().all(|&v| v == 0.0));
    assert!(zero.cloth.iter().all(|v| *v == Vec3::zeros()));
    // Without the state the term cannot say anything.
    let cloth = problem.system().cloth_positions(problem.state()).unwrap();
    let input = TermInput {
        mesh: problem.mesh(),
        cloth: &cloth,
        pattern: &pattern,
        fabric: problem.fabric(),
    };
    assert!(
        PinnedTraction::new(1.0)
            .unwrap()
            .evaluate(&input, None)
            .is_err()
    );
}
