//! Seams held during the design (`PatternDesignParams::hold_seams`, `crates/design/src/seam_projection.rs`):
//! on a small two-panel cylinder fitted to a narrower target, every pair of sewn edges of the designed
//! pattern is equally long (to the projection's 10⁻⁹ m), with Gauss-Newton coarse to fine and with L-BFGS,
//! and the objective still falls; with the seams free, the same run leaves them unequal by far more (the
//! check can fail). And the objective's gradient through the projection against central differences.

use std::ops::ControlFlow;

use skintight::scene::{FileResolver, Scene};
use skintight::simulate::{equilibrium_params, prepare};
use skintight_design::{
    DesignMesh, DesignProblem, Optimizer, PatternDesignParams, PatternMap, SeamProjection,
    ShapeImls, Term, cylinder_target, pattern_design,
};
use skintight_geometry::math::{Real, Vec2, Vec3};

/// A shape target only (no seam-length term): nothing but the projection keeps the seams sewable.
fn terms() -> Vec<Box<dyn Term>> {
    // The target is about z from z = 0; the body about y, centred: turn it (x, y, z) → (x, z − 0.1, −y).
    let mut target = cylinder_target(0.047, 0.2, 24, 8).unwrap();
    for p in &mut target.positions {
        *p = Vec3::new(p.x, p.z - 0.1, -p.y);
    }
    vec![Box::new(ShapeImls::from_mesh(1.0, &target, None).unwrap())]
}

fn setup() -> (DesignProblem, PatternMap, Vec<Vec2>) {
    let scene = Scene::from_json(&scene_json()).unwrap();
    let mut sim = prepare(&scene, &FileResolver::new(".")).unwrap();
    let params = equilibrium_params(&scene);
    skintight::simulate::run(&mut sim, &mut |_| ControlFlow::Continue(())).unwrap();
    let (mesh, pattern) = DesignMesh::from_garment(&sim.garment);
    let map = PatternMap::new(&mesh, &pattern).unwrap();
    let problem = DesignProblem::new(sim.system, sim.state, mesh, terms(), params).unwrap();
    (problem, map, pattern)
}

/// Largest `|‖a_{k+1} − a_k‖ − ‖b_{k+1} − b_k‖|` over the seams of `mesh` at `pattern` (m), and the largest
/// difference of a seam's two side lengths (m).
fn mismatch(mesh: &DesignMesh, pattern: &[Vec2]) -> (Real, Real) {
    let (mut per_edge, mut per_seam) = (0.0_f64, 0.0_f64);
    for seam in &mesh.seams {
        let [a, b] = &seam.vertices;
        let m = a.len();
        let edges = if seam.closed { m } else { m - 1 };
        let mut total = 0.0;
        for k in 0..edges {
            let k1 = (k + 1) % m;
            let d =
                (pattern[a[k1]] - pattern[a[k]]).norm() - (pattern[b[k1]] - pattern[b[k]]).norm();
            per_edge = per_edge.max(d.abs());
            total += d;
        }
        per_seam = per_seam.max(total.abs());
    }
    (per_edge, per_seam)
}

fn design(hold_seams: bool, method: Optimizer) -> (Real, Real, Real, Real) {
    let (mut problem, map, _) = setup();
    let mut params = PatternDesignParams {
        method,
        hold_seams,
        ..PatternDesignParams::default()
    };
    params.lbfgs.max_iterations = 5;
    params.gauss_newton.max_iterations = 5;
    if method == Optimizer::GaussNewton {
        params.mode_levels = vec![5];
        params.level_max_iterations = Some(2);
    }
    let result = pattern_design(
        &mut problem,
        &map,
        0.02,
        &params,
        &mut |_| ControlFlow::Continue(()),
        &|| false,
    )
    .unwrap();
    let (per_edge, per_seam) = mismatch(problem.mesh(), &result.pattern);
    (
        per_edge,
        per_seam,
        result.initial_objective,
        result.final_objective,
    )
}

#[test]
fn held_seams_stay_sewable_through_a_gauss_newton_and_an_lbfgs_design() {
    for method in [Optimizer::GaussNewton, Optimizer::Lbfgs] {
        let (per_edge, per_seam, t0, t) = design(true, method);
        assert!(
            per_edge <= 1e-8 && per_seam <= 1e-7,
            "{method:?}: edge pairs {per_edge:e} m, seams {per_seam:e} m apart"
        );
        assert!(
            t < 0.7 * t0,
            "{method:?}: the objective fell only from {t0:e} to {t:e}"
        );
    }
    // Free seams: the same Gauss-Newton run moves the sides apart (the check above can fail).
    let (per_edge, _, _, _) = design(false, Optimizer::GaussNewton);
    assert!(per_edge > 1e-5, "free seams stayed sewable: {per_edge:e}");
}

#[test]
fn the_design_gradient_through_the_seam_projection_matches_central_differences() {
    let (mut problem, map, pattern) = setup();
    let seams = SeamProjection::new(problem.mesh(), &map)
        .unwrap()
        .with_tolerance(1e-13);
    assert!(seams.num_pairs() > 0);
    // A point off the sewable set: one panel's boundary scaled by 1 % (its seam sides 1 % longer).
    let mut p = map.initial_parameters();
    let range = map.panel_parameters(0).unwrap();
    for k in range {
        p[k] *= 1.01;
    }
    assert!(
        mismatch(problem.mesh(), &pattern).0 < 1e-6,
        "the start is trued"
    );
    let objective = |problem: &mut DesignProblem, p: &[Real], gradient: bool| {
        let q = seams.project(p).unwrap();
        let x = map.apply(&q.parameters).unwrap();
        let eval = problem
            .evaluate(&x, gradient, &mut |_| ControlFlow::Continue(()))
            .unwrap();
        let g = eval.gradient.map(|g| {
            q.pull_back(&map.apply_jacobian_transpose(&g).unwrap())
                .unwrap()
        });
        (eval.value, g)
    };
    let (_, g) = objective(&mut problem, &p, true);
    let g = g.unwrap();
    // Directional derivatives along three seeded random directions, central differences of 10 µm.
    let h = 1e-5;
    let mut state = 12345_u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as Real / (1u64 << 53) as Real) * 2.0 - 1.0
    };
    for _ in 0..3 {
        let d: Vec<Real> = (0..p.len()).map(|_| uniform()).collect();
        let norm = d.iter().map(|v| v * v).sum::<Real>().sqrt();
        let d: Vec<Real> = d.iter().map(|v| v / norm).collect();
        let at = |s: Real| -> Vec<Real> { p.iter().zip(&d).map(|(p, d)| p + s * d).collect() };
        let (fp, _) = objective(&mut problem, &at(h), false);
        let (fm, _) = objective(&mut problem, &at(-h), false);
        let numeric = (fp - fm) / (2.0 * h);
        let analytic: Real = g.iter().zip(&d).map(|(g, d)| g * d).sum();
        let scale = g.iter().map(|v| v * v).sum::<Real>().sqrt();
        assert!(
            (numeric - analytic).abs() <= 1e-3 * scale + 1e-4 * analytic.abs(),
            "directional derivative {analytic:e} vs central difference {numeric:e} (‖g‖ {scale:e})"
        );
    }
}

#[allow(dead_code)]
mod design_support;

/// The leggings order (`examples/order_leggings_class1.json`) on every shared 1k body: the issue's
/// acceptance (exit 0, admissible, prescription passed; the final truing moves no vertex more than 1 mm and
/// the seams differ by at most 1 mm before it). Prints one table row per body. 14 minutes per body in a
/// debug build on 2 cores: run with `cargo test --release --test design_hold_seams -- --ignored --nocapture`.
#[test]
#[ignore = "the issue's acceptance on every shared 1k body: minutes per body (release), ~14 min (debug)"]
fn leggings_orders_on_every_shared_body_hold_their_seams_and_meet_their_prescription() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut failures = Vec::new();
    for body in [
        "regular_1k",
        "athletic_1k",
        "kid_1k",
        "male_1k",
        "overweight_1k",
    ] {
        let mut job: serde_json::Value = serde_json::from_slice(
            &std::fs::read(root.join("examples/order_leggings_class1.json")).unwrap(),
        )
        .unwrap();
        job["body"]["source"]["path"] = root
            .join(format!("../shared/data/bodies/{body}.obj"))
            .to_string_lossy()
            .into_owned()
            .into();
        let dir = tempfile::tempdir().unwrap();
        let t = std::time::Instant::now();
        let out = design_support::design_cli(env!("CARGO_BIN_EXE_skintight"), &job, dir.path());
        let r = design_support::read_json(&dir.path().join("out/result.json"));
        let truing = &r["seam_truing"];
        let before = truing["max_seam_mismatch_before_mm"].as_f64().unwrap();
        let moved = truing["max_displacement_mm"].as_f64().unwrap();
        println!(
            "| {body} | {:?} | {before:.2e} | {}, {moved:.3} | {:.4} | {} | {:.0} s |",
            out.status.code(),
            truing["iterations"],
            r["final_objective"].as_f64().unwrap_or(f64::NAN),
            r["prescription"]["pass"],
            t.elapsed().as_secs_f64()
        );
        assert!(before <= 1.0 && moved <= 1.0, "{body}: {truing}");
        if !(out.status.success() && r["admissible"] == true && r["prescription"]["pass"] == true) {
            failures.push(body);
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// The two-panel sleeve on the small cylinder, both cuffs pinned, 2 cm edges, tolerance 10⁻¹⁰.
fn scene_json() -> String {
    design_support::sleeve_scene(design_support::BOTH_CUFFS, 0.02, 1e-10)
}
