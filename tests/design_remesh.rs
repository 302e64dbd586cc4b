//! Remeshing a design (`skintight_design::design_remesh`): the remeshed garment on a cylinder starts where
//! the previous one was worn (re-embedding), reaches its equilibrium in a few Newton iterations, keeps the
//! objective to within the change of discretization, keeps the pinned cuffs pinned, and leaves the
//! problem untouched when it fails.

mod design_support;
use design_support::{BOTH_CUFFS, sleeve_scene};

use std::ops::ControlFlow;

use skintight::scene::{FileResolver, Scene};
use skintight::simulate::{Simulation, equilibrium_params, prepare};
use skintight_design::{
    DesignMesh, DesignProblem, StretchWindow, Term, design_remesh, pattern_quality,
};
use skintight_geometry::math::{Real, Vec2};

fn scene(pinned: bool) -> Scene {
    let pinned = if pinned { BOTH_CUFFS } else { "" };
    Scene::from_json(&sleeve_scene(pinned, 0.015, 1e-9)).unwrap()
}

fn setup(pinned: bool) -> (Simulation, DesignProblem, Vec<Vec2>) {
    let scene = scene(pinned);
    let mut sim = prepare(&scene, &FileResolver::new(".")).unwrap();
    skintight::simulate::run(&mut sim, &mut |_| ControlFlow::Continue(())).unwrap();
    let (mesh, pattern) = DesignMesh::from_garment(&sim.garment);
    let terms: Vec<Box<dyn Term>> = vec![Box::new(StretchWindow::new(100.0, 1.0, 1.1).unwrap())];
    let problem = DesignProblem::new(
        sim.system.clone(),
        sim.state.clone(),
        mesh,
        terms,
        equilibrium_params(&scene),
    )
    .unwrap();
    (sim, problem, pattern)
}

const TARGET: Real = 0.015 * 0.9;

#[test]
fn remeshed_design_starts_where_the_worn_garment_was_and_keeps_its_objective() {
    let (sim, mut problem, pattern0) = setup(false);
    // A design step: each panel's pattern widened by 8 % and sheared, so the garment is worn differently.
    let pattern: Vec<Vec2> = pattern0
        .iter()
        .map(|p| Vec2::new(1.08 * p.x + 0.15 * p.y, p.y))
        .collect();
    let before = problem
        .evaluate(&pattern, false, &mut |_| ControlFlow::Continue(()))
        .unwrap();
    let worn_before = problem.system().cloth_positions(problem.state()).unwrap();
    let quality_before = pattern_quality(problem.mesh(), &pattern, TARGET).min_quality;
    let remeshed = design_remesh(&mut problem, &sim.garment, &pattern, TARGET).unwrap();
    assert_eq!(
        problem.mesh().num_pattern_vertices(),
        remeshed.pattern.len()
    );
    assert_eq!(remeshed.map.initial_pattern(), remeshed.pattern.as_slice());
    let quality_after = pattern_quality(problem.mesh(), &remeshed.pattern, TARGET).min_quality;
    // Re-embedding: every new cloth vertex starts at its interpolated worn position (projected onto the
    // smooth surface: the cloth triangles are flat chords of it, ≤ 1 mm off at this edge length).
    let start = problem.system().cloth_positions(problem.state()).unwrap();
    for (c, x) in start.iter().enumerate() {
        let d = (x - remeshed.garment.positions[c]).norm();
        assert!(d < 1e-3, "cloth vertex {c} re-embedded {d:.2e} m off");
    }
    let after = problem
        .evaluate(&remeshed.pattern, false, &mut |_| ControlFlow::Continue(()))
        .unwrap();
    let worn_after = problem.system().cloth_positions(problem.state()).unwrap();
    println!(
        "objective {:.4e} → {:.4e}; Newton {} → {}; quality {:.3} → {:.3}; {} → {} cloth vertices",
        before.value,
        after.value,
        before.equilibrium.iterations,
        after.equilibrium.iterations,
        quality_before,
        quality_after,
        worn_before.len(),
        worn_after.len()
    );
    assert!(after.equilibrium.converged);
    // The equilibrium moved little from where the old cloth was, up to a turn about the cylinder's axis
    // (y): an unpinned garment on a cylinder turns at no cost, so the solve may land anywhere along it.
    let polar = |x: &skintight_geometry::math::Vec3| (x.x.hypot(x.z), x.z.atan2(x.x), x.y);
    let turns: Vec<Real> = worn_after
        .iter()
        .zip(&remeshed.garment.positions)
        .map(|(x, y)| {
            let d = polar(x).1 - polar(y).1;
            (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
        })
        .collect();
    let turn = turns.iter().sum::<Real>() / turns.len() as Real;
    println!("turn about the axis {turn:.3e} rad");
    let moved: Vec<Real> = worn_after
        .iter()
        .zip(&remeshed.garment.positions)
        .zip(&turns)
        .map(|((x, y), t)| {
            let ((rx, _, yx), (ry, _, yy)) = (polar(x), polar(y));
            ((rx - ry).powi(2) + (yx - yy).powi(2) + (ry * (t - turn)).powi(2)).sqrt()
        })
        .collect();
    let mean = moved.iter().sum::<Real>() / moved.len() as Real;
    let max = moved.iter().copied().fold(0.0, Real::max);
    println!("moved after the remesh: mean {mean:.2e} m, max {max:.2e} m");
    assert!(
        mean < 5e-4 && max < 2e-3,
        "mean {mean:.2e} m, max {max:.2e} m"
    );
    let rel = (after.value - before.value).abs() / before.value;
    assert!(rel < 0.15, "objective changed by {:.1} %", rel * 100.0);
    assert!(quality_after > quality_before);
    assert!(quality_after > 0.5, "{quality_after}");
}

#[test]
fn pinned_cuffs_stay_pinned_after_a_remesh() {
    let (sim, mut problem, pattern) = setup(true);
    problem
        .evaluate(&pattern, false, &mut |_| ControlFlow::Continue(()))
        .unwrap();
    let old_coords = problem.state().cloth.clone();
    let remeshed = design_remesh(&mut problem, &sim.garment, &pattern, TARGET).unwrap();
    let system = problem.system();
    let pinned_count = remeshed.pinned.iter().filter(|&&p| p).count();
    let free_count = remeshed
        .garment
        .free_boundary
        .iter()
        .filter(|&&p| p)
        .count();
    // Both hems are free boundary and all pinned: every free-boundary vertex is pinned.
    assert!(pinned_count > 0);
    assert_eq!(pinned_count, free_count);
    for (c, &p) in remeshed.pinned.iter().enumerate() {
        assert_eq!(system.cloth_dof(c).is_none(), p);
    }
    // The previous pinned vertices that are still vertices keep their exact surface coordinates.
    let kept = remeshed
        .garment
        .vertex_body
        .iter()
        .enumerate()
        .filter(|(_, sp)| sp.bary.iter().any(|&b| b >= 1.0 - 1e-12))
        .filter(|(c, _)| remeshed.pinned[*c])
        .count();
    assert!(kept > 0);
    let with_old = remeshed
        .garment
        .vertex_body
        .iter()
        .enumerate()
        .filter(|(c, _)| remeshed.pinned[*c])
        .filter_map(|(c, sp)| {
            let k = (0..3).find(|&k| sp.bary[k] >= 1.0 - 1e-12)?;
            Some((c, sim.garment.faces[sp.face][k]))
        });
    for (c, old) in with_old {
        assert_eq!(problem.state().cloth[c], old_coords[old]);
    }
    let eval = problem
        .evaluate(&remeshed.pattern, false, &mut |_| ControlFlow::Continue(()))
        .unwrap();
    assert!(eval.equilibrium.converged);
}

#[test]
fn a_failed_remesh_leaves_the_problem_as_it_was() {
    let (sim, mut problem, pattern) = setup(false);
    problem
        .evaluate(&pattern, false, &mut |_| ControlFlow::Continue(()))
        .unwrap();
    let state = problem.state().clone();
    let n = problem.mesh().num_pattern_vertices();
    assert!(design_remesh(&mut problem, &sim.garment, &pattern[1..], TARGET).is_err());
    // A pattern boundary folded over itself cannot be triangulated.
    let folded: Vec<Vec2> = pattern
        .iter()
        .enumerate()
        .map(|(i, p)| if i % 2 == 0 { Vec2::new(-p.x, p.y) } else { *p })
        .collect();
    assert!(design_remesh(&mut problem, &sim.garment, &folded, TARGET).is_err());
    assert_eq!(problem.mesh().num_pattern_vertices(), n);
    assert_eq!(problem.state(), &state);
}
