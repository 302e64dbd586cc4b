//! The full design gradient by the adjoint method against central differences through the whole
//! simulation (each side a new equilibrium), for every objective and regularizer, on a small cylinder:
//! `dT/dX̄` along random pattern directions, and `dT/dp` through the design map (boundary parameters,
//! bi-harmonic interior) along random parameter directions. The seams are left as flattened
//! (`patterns.true_seams: false`), so that the seam-length term is not zero.

use std::ops::ControlFlow;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight::scene::{FileResolver, Scene};
use skintight::simulate::{equilibrium_params, prepare};
use skintight_design::{
    BoundarySmoothness, Compactness, DesignMesh, DesignProblem, EdgeLengthUniformity, PatternMap,
    PinnedTraction, SeamLength, SeamTraction, SeamTractionForm, ShapeImls, Sliding, StretchWindow,
    Term, cylinder_target,
};
use skintight_geometry::math::{Real, Vec2};

/// The small two-panel cylinder scene of the design-gradient tests (`design_support/gradient_cylinder.json`).
const SCENE: &str = include_str!("design_support/gradient_cylinder.json");

fn problem(terms: Vec<Box<dyn Term>>) -> (DesignProblem, Vec<Vec2>) {
    let scene = Scene::from_json(SCENE).unwrap();
    let mut sim = prepare(&scene, &FileResolver::new(".")).unwrap();
    let params = equilibrium_params(&scene);
    skintight::simulate::run(&mut sim, &mut |_| ControlFlow::Continue(())).unwrap();
    let (mesh, pattern) = DesignMesh::from_garment(&sim.garment);
    let problem = DesignProblem::new(sim.system, sim.state, mesh, terms, params).unwrap();
    (problem, pattern)
}

/// `dT/dX̄ · d` against `(T(X̄ + h d) − T(X̄ − h d)) / 2h` along seeded random directions.
fn check(name: &str, terms: Vec<Box<dyn Term>>, rel_tol: Real) {
    let (mut problem, pattern) = problem(terms);
    let mut none = |_: &_| ControlFlow::Continue(());
    let base = problem.evaluate(&pattern, true, &mut none).unwrap();
    assert!(base.value > 0.0, "{name}: the term is active");
    let gradient = base.gradient.clone().unwrap();
    let state = problem.state().clone();
    for seed in 0..3 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // A smooth-ish direction: random per vertex, 1 mm at most.
        let d: Vec<Vec2> = pattern
            .iter()
            .map(|_| Vec2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)) * 1e-3)
            .collect();
        let analytic: Real = gradient.iter().zip(&d).map(|(g, v)| g.dot(v)).sum();
        let h = 1e-3;
        let mut at = |t: Real| -> Real {
            problem.set_state(state.clone());
            let p: Vec<Vec2> = pattern.iter().zip(&d).map(|(p, v)| p + v * t).collect();
            problem.evaluate(&p, false, &mut none).unwrap().value
        };
        let numeric = (at(h) - at(-h)) / (2.0 * h);
        let scale = analytic.abs().max(numeric.abs());
        assert!(
            (analytic - numeric).abs() <= rel_tol * scale,
            "{name} seed {seed}: adjoint {analytic:e} vs central difference {numeric:e}"
        );
        assert!(scale > 0.0, "{name}: direction with no change");
    }
}

#[test]
fn stretch_window_gradient_matches_central_differences_through_the_simulation() {
    check(
        "stretch",
        vec![Box::new(StretchWindow::new(1.0, 0.95, 1.04).unwrap())],
        1e-4,
    );
}

#[test]
fn shape_gradient_matches_central_differences_through_the_simulation() {
    // The target is about z from z = 0; the body about y, centred: turn it (x, y, z) → (x, z − 0.1, −y).
    let mut target = cylinder_target(0.048, 0.2, 24, 8).unwrap();
    for p in &mut target.positions {
        *p = skintight_geometry::math::Vec3::new(p.x, p.z - 0.1, -p.y);
    }
    check(
        "shape",
        vec![Box::new(ShapeImls::from_mesh(1.0, &target, None).unwrap())],
        1e-4,
    );
}

#[test]
fn seam_traction_gradient_matches_central_differences_through_the_simulation() {
    check(
        "seam_traction",
        vec![Box::new(
            SeamTraction::new(1.0, SeamTractionForm::Squared).unwrap(),
        )],
        1e-4,
    );
}

#[test]
fn seam_length_gradient_matches_central_differences_through_the_simulation() {
    check(
        "seam_length",
        vec![Box::new(SeamLength::new(1.0).unwrap())],
        1e-4,
    );
}

#[test]
fn boundary_smoothness_gradient_matches_central_differences_through_the_simulation() {
    check(
        "boundary_smoothness",
        vec![Box::new(BoundarySmoothness::new(1.0).unwrap())],
        1e-4,
    );
}

#[test]
fn edge_length_gradient_matches_central_differences_through_the_simulation() {
    check(
        "edge_length",
        vec![Box::new(EdgeLengthUniformity::new(1.0).unwrap())],
        1e-4,
    );
}

#[test]
fn compactness_gradient_matches_central_differences_through_the_simulation() {
    // A high threshold, so that many boundary pairs of the cylinder's panels are penalized.
    check(
        "compactness",
        vec![Box::new(Compactness::new(1.0, 0.9).unwrap())],
        1e-4,
    );
}

/// `dT/dp` (the pattern gradient through `PatternMap::apply_jacobian_transpose`) against central
/// differences of `T(P(p ± h d))` along random boundary-parameter directions, every objective and
/// regularizer together.
#[test]
fn pinned_traction_gradient_matches_central_differences_through_the_simulation() {
    check(
        "pinned_traction",
        vec![Box::new(PinnedTraction::new(100.0).unwrap())],
        1e-4,
    );
}

#[test]
fn sliding_gradient_matches_central_differences_through_the_simulation() {
    // The poses: the neutral body's surface bent along its axis, and sheared.
    let (probe, _) = problem(vec![]);
    let system = probe.system();
    let rest = system.control_positions(system.rest_positions());
    let poses = vec![
        rest.iter()
            .map(|p| p + skintight_geometry::math::Vec3::new(4.0 * p.y * p.y, 0.0, 0.0))
            .collect(),
        rest.iter()
            .map(|p| p + skintight_geometry::math::Vec3::new(0.0, 0.0, 0.3 * p.y))
            .collect(),
    ];
    check(
        "sliding",
        vec![Box::new(Sliding::new(2.0, 0.3, poses).unwrap())],
        1e-4,
    );
}

#[test]
fn design_gradient_through_the_pattern_map_matches_central_differences() {
    let mut target = cylinder_target(0.048, 0.2, 24, 8).unwrap();
    for p in &mut target.positions {
        *p = skintight_geometry::math::Vec3::new(p.x, p.z - 0.1, -p.y);
    }
    let terms: Vec<Box<dyn Term>> = vec![
        Box::new(StretchWindow::new(1.0, 0.95, 1.04).unwrap()),
        Box::new(ShapeImls::from_mesh(1.0, &target, None).unwrap()),
        Box::new(SeamTraction::new(1.0, SeamTractionForm::Squared).unwrap()),
        Box::new(SeamLength::new(1.0).unwrap()),
        Box::new(BoundarySmoothness::new(1e-6).unwrap()),
        Box::new(EdgeLengthUniformity::new(1.0).unwrap()),
        Box::new(Compactness::new(1.0, 0.9).unwrap()),
    ];
    let (mut problem, pattern) = problem(terms);
    let map = PatternMap::new(problem.mesh(), &pattern).unwrap();
    let p0 = map.initial_parameters();
    let mut none = |_: &_| ControlFlow::Continue(());
    let base = problem.evaluate(&pattern, true, &mut none).unwrap();
    assert!(
        base.terms.iter().all(|t| t.value > 0.0),
        "every term is active: {:?}",
        base.terms
            .iter()
            .map(|t| (t.name, t.value))
            .collect::<Vec<_>>()
    );
    let gp = map
        .apply_jacobian_transpose(base.gradient.as_ref().unwrap())
        .unwrap();
    let state = problem.state().clone();
    for seed in 10..13 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let d: Vec<Real> = p0
            .iter()
            .map(|_| rng.random_range(-1.0..1.0) * 1e-3)
            .collect();
        let analytic: Real = gp.iter().zip(&d).map(|(g, v)| g * v).sum();
        let h = 1e-3;
        let mut at = |t: Real| -> Real {
            problem.set_state(state.clone());
            let p: Vec<Real> = p0.iter().zip(&d).map(|(p, v)| p + v * t).collect();
            let pattern = map.apply(&p).unwrap();
            problem.evaluate(&pattern, false, &mut none).unwrap().value
        };
        let numeric = (at(h) - at(-h)) / (2.0 * h);
        let scale = analytic.abs().max(numeric.abs());
        assert!(scale > 0.0, "direction with no change");
        assert!(
            (analytic - numeric).abs() <= 1e-4 * scale,
            "seed {seed}: adjoint {analytic:e} vs central difference {numeric:e}"
        );
    }
}
