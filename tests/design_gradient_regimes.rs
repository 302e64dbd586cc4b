//! The design gradient by the adjoint method against central differences through the whole simulation,
//! for the prescription objective ([`BandPressure`]) and the fabric's stretch limits
//! ([`FabricStretchLimit`]), each alone and summed with [`Pressure`] and [`StretchWindow`], on a garment
//! whose equilibrium mixes the tension-field regimes (taut, wrinkled, transition and a few slack
//! triangles): `dT/dX̄` along seeded random pattern directions, along seeded random directions that
//! move only the vertices of one regime's triangles (taut, wrinkled, transition, slack: each regime's
//! part of the gradient on its own), and `dT/dp` through the design map ([`PatternMap`]) along seeded
//! random boundary-parameter directions. The scene of `tests/design_gradient.rs` is all taut.
//!
//! # The scene
//!
//! The two-panel sleeve of `tests/design_support` (procedural cylinder along `y`, radius 5 cm; both cuffs
//! pinned; cloth edge length 2 cm, 329 triangles) on a warped pattern:
//!
//! - in each panel, about the panel's centroid, the course (pattern coordinate `t` across the grain
//!   line) is scaled by `k(ξ) = COURSE_SCALE + COURSE_SLOPE ξ`, `ξ ∈ [−1, 1]` the wale coordinate
//!   (along the grain line, i.e. the body's axis) over the panel's half-length; the wales keep the
//!   scene's ease (−10 %: wale stretch ≈ 1.1 between the pinned cuffs). Near the lower cuff
//!   (`y = −5 cm`) the course is stretched round the body (≈ 1.08): **taut**. Near the upper cuff the
//!   pattern is wider than the body (course stretch ≈ 0.94 at wale stretch ≈ 1.1, below the wrinkling
//!   threshold `λ̄2 = 1 − ν(λ1 − 1)`): **wrinkled**, tension along the wales only, hardly any interface
//!   pressure. In between, the wrinkled→taut band of the smoothed tension field
//!   (`skintight_physics::tension_field_density`: `0 < λ2 − λ̄2(λ1) < (1 + ν) w`, `w = 0.01`) crosses
//!   the sleeve: **transition**. The wrinkled part is made to carry the wales' tension, not the
//!   course's: with the wales slack, rings of vertices are nearly free to slide along the axis (tried:
//!   wale scale 1.3, all triangles wrinkled round the body; the equilibrium Hessian's smallest
//!   eigenvalue, by inverse iteration, fell from 4e-3 on the taut and the mixed sleeves to 7e-6).
//! - a pocket of excess fabric in the first panel, in the wrinkled part (`ξ = POCKET_AT`): the pattern
//!   magnified about that point by `1 + POCKET_SCALE (1 − ρ²)²`, `ρ` = distance / `POCKET_RADIUS`
//!   (3 cm). The fabric round it carries the wale tension past its middle, which goes **slack**.
//!
//! [`mixed_scene_has_taut_wrinkled_and_transition_triangles`] asserts the counts (measured: taut 229,
//! wrinkled 74, transition 24, slack 2), that the taut, transition and wrinkled triangles lie in that
//! order up the sleeve, and that both stretch limits are exceeded somewhere (wale > 1.08: 116
//! triangles, course > 1.05: 68): the test fails if the scene drifts to one regime.
//!
//! # Band edges of the tension field
//!
//! The smoothed density is C² but not C³ at the edges of its bands (`λ1 − 1 ∈ {0, w}`,
//! `λ2 − λ̄2 ∈ {0, (1 + ν) w}`: the ramp's third derivative jumps, by `9/w` on the wrinkled edge). A
//! difference stencil that carries a triangle across an edge is not smooth in the step, and Richardson
//! extrapolation does not hold. Measured on an earlier version of this scene (course scale
//! `1.1 ± 0.1`, no pocket), where a triangle sat `8e-5` (in `λ`) on the wrinkled side of the wrinkled→transition edge: it crossed the edge at 0.8 µm
//! of pattern motion along seed 1, and the central difference of the band pressure then erred by 10 %
//! at `h = 1e-3`, by 1.6e-4 at `h = 5e-4`, while the extrapolated difference at `h ≤ 2.4e-4` agreed with
//! the adjoint to 1e-7: the adjoint was right, the stencil was not smooth. Hence: the warp's parameters
//! keep every triangle at least `3.9e-4` from an edge (asserted ≥ `5e-5`); every evaluation of a
//! stencil asserts that no triangle changes regime; and the step is small.
//!
//! # Step-size control
//!
//! A direction `d` is random per pattern vertex (or per boundary parameter), each coordinate uniform in
//! ±1 mm (±4 mm on the slack patch's few vertices, see [`check_regime_directions`]), seeded. The
//! central difference `D(h) = (T(X̄ + h d) − T(X̄ − h d)) / 2h` (units of `T`, `h` dimensionless) has
//! truncation error `c h² + O(h⁴)`, estimated from the half step as `E(h) = (D(h) − D(h/2)) · 4/3`
//! (Richardson); the extrapolated `R = (4 D(h/2) − D(h)) / 3` has error `O(h⁴)`. Each check asserts,
//! with the scale `s = max(|dT · d|, |R|)`,
//!
//! - `|E(STEP)| ≤ s · REL_TOL / FD_MARGIN` (`1e-6 s`): the difference itself is ten times more accurate
//!   than the tolerance, and
//! - `|dT · d − R| ≤ s · REL_TOL` (`1e-5 s`).
//!
//! The mixed regimes curve the objective sharply at small scales (inside the transition band a
//! triangle's stiffness across its wrinkles rises from 0 to the taut one over `Δλ = 0.013`): `c` is
//! 10 to 10⁴ times larger than on the all-taut sleeve (`D(1e-3)` off by 6e-9 to 7e-7 relative there,
//! by 1e-6 to 4e-4 here, per term and direction; [`step_size_sweep`] prints the table for the sum).
//! Hence `STEP = 3.2e-5`, a pattern motion of at most 32 nm per coordinate, where `c h²` is about 1e-8
//! to 2e-7 of `s`.
//!
//! Its partner is the noise of the equilibrium: each side is solved to the relative residual
//! `SOLVER_TOLERANCE = 5e-13` (this scene's floor is about 2e-13; at 1e-13 the solver stops with no
//! progress), which leaves an error of about that relative size in `T`, i.e. about `5e-13 |T| / h` in
//! `D`: 1e-8 to 4e-7 of `s` at this step. At the 1e-11 of `tests/design_gradient.rs` it is twenty times
//! larger, and the first assertion above fails (tried: `|E|/s` up to 3.3e-6).
//!
//! Measured over the 30 checks: `|E|/s ≤ 1.9e-7` and `|dT · d − R|/s ≤ 1.9e-7` (up to 3.9e-7 and
//! 4.2e-7 with the checks in another order: the noise depends on the solves' history, as each solve
//! starts with the damping the previous one ended with). `REL_TOL = 1e-5` stands 25 to 50 times above
//! the worst agreement, and an error of 1e-4 in a term's gradient fails the test (tried: scaling
//! [`FabricStretchLimit`]'s `G = ∂Φ/∂C` by `1 + 1e-4` gives 9.5e-5 relative; dropping the `∂D_X/∂s_f`
//! part of the band kernel's derivative in [`BandPressure`] gives 1.1e-1).
//!
//! The four tests together take about 11 s (test profile; two test threads on a shared 2-core machine).
//!
//! Units: pattern and cloth positions in m; pressures in Pa; stretches and `λ` (squared stretches)
//! dimensionless; `T` in each term's units (m² Pa² × weight for the pressure terms, m² × weight for the
//! stretch terms; the weights below make each term's gradient of the same order in the sum).

use std::ops::ControlFlow;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight::scene::{FileResolver, Scene};
use skintight::simulate::admissibility::wale_directions;
use skintight::simulate::{equilibrium_params, prepare};
use skintight_design::{
    BandPressure, DesignEvaluation, DesignMesh, DesignProblem, FabricStretchLimit, PatternMap,
    Pressure, PressureBand, PressureTarget, StretchWindow, Term, TermInput,
};
use skintight_geometry::math::{Real, Vec2, Vec3};
use skintight_physics::Regime;

mod design_support;

/// Relative residual of every equilibrium solve (dimensionless).
const SOLVER_TOLERANCE: Real = 5e-13;
/// Course scale of the pattern at the panel's middle, and its slope over the half-length (see the module
/// documentation).
const COURSE_SCALE: Real = 1.115;
const COURSE_SLOPE: Real = 0.08;
/// The pocket of excess fabric: its magnification at the centre, radius (m) and centre on the first
/// panel's grain line (wale coordinate `ξ`).
const POCKET_SCALE: Real = 0.8;
const POCKET_RADIUS: Real = 0.03;
const POCKET_AT: Real = 0.7;
/// The difference step `h` (dimensionless; directions are ≤ 1 mm per coordinate, so ≤ 32 nm).
const STEP: Real = 3.2e-5;
/// Tolerance of the adjoint against the extrapolated difference, relative to the directional derivative.
const REL_TOL: Real = 1e-5;
/// How much more accurate than `REL_TOL` the difference at `STEP` must be (its Richardson estimate).
const FD_MARGIN: Real = 10.0;

/// The band-pressure objective's axis: the body's, `+y` through the origin (m).
fn axis() -> (Vec3, Vec3) {
    (Vec3::zeros(), Vec3::y())
}

/// Four bands 2.4 cm wide (half-width 1.2 cm) along the sleeve, overlapping the next by 4 mm: below its
/// window (`A`, taut: 0.90 kPa against 1.5–2 kPa), above (`B`: 0.57 kPa against 0.3–0.45 kPa), inside
/// (`C`, across the transition: 0.25 kPa in 0.15–0.5 kPa) and below (`D`, mostly wrinkled: 59 Pa against
/// 0.5–0.8 kPa). Pa; the test asserts these sides, with 50 Pa or more to every window edge.
fn bands() -> Vec<PressureBand> {
    let band = |name: &str, center: Real, min: Real, max: Real| PressureBand {
        name: name.into(),
        center,
        half_width: 0.012,
        taper: 0.006,
        min,
        max,
    };
    vec![
        band("A", -0.03, 1500.0, 2000.0),
        band("B", -0.01, 300.0, 450.0),
        band("C", 0.01, 150.0, 500.0),
        band("D", 0.03, 500.0, 800.0),
    ]
}

fn band_pressure(weight: Real) -> BandPressure {
    let (origin, direction) = axis();
    BandPressure::new(weight, origin, direction, bands()).unwrap()
}

/// Wale and course bounds of the stretch-limit penalty (dimensionless): 116 of the 329 triangles exceed
/// the wale bound and 68 the course bound (asserted: at least 10 above and 10 below each).
const LIMITS: [Real; 2] = [1.08, 1.05];

/// The prescription, the limits, the per-triangle pressure window and the stretch window together, with
/// weights that put each one's directional derivatives along the test directions within 1e-4 to 1e-2.
fn sum_terms(wale: &[Vec2]) -> Vec<Box<dyn Term>> {
    vec![
        Box::new(band_pressure(1e-4)),
        Box::new(FabricStretchLimit::new(1e4, LIMITS, wale.to_vec()).unwrap()),
        Box::new(
            Pressure::new(
                1e-4,
                PressureTarget::Range {
                    min: 300.0,
                    max: 900.0,
                },
                0.0,
            )
            .unwrap(),
        ),
        Box::new(StretchWindow::new(1e3, 0.95, 1.04).unwrap()),
    ]
}

/// The garment at its equilibrium on the warped pattern, with the terms `terms(wale directions)`.
struct Mixed {
    problem: DesignProblem,
    /// The warped pattern (`#Vp`, m): the point the gradient is checked at.
    pattern: Vec<Vec2>,
    /// Each panel's unit wale direction in the pattern plane.
    wale: Vec<Vec2>,
    /// The evaluation at `pattern`, with the gradient.
    base: DesignEvaluation,
    /// The regime of every cloth triangle at `pattern`.
    regimes: Vec<Regime>,
}

fn mixed(terms: impl FnOnce(&[Vec2]) -> Vec<Box<dyn Term>>) -> Mixed {
    let json = design_support::sleeve_scene(design_support::BOTH_CUFFS, 0.02, SOLVER_TOLERANCE);
    let scene = Scene::from_json(&json).unwrap();
    let mut sim = prepare(&scene, &FileResolver::new(".")).unwrap();
    let params = equilibrium_params(&scene);
    skintight::simulate::run(&mut sim, &mut |_| ControlFlow::Continue(())).unwrap();
    let wale = wale_directions(&sim);
    let (mesh, flat) = DesignMesh::from_garment(&sim.garment);
    let pattern = warp(&mesh, &flat, &wale);
    let terms = terms(&wale);
    let mut problem = DesignProblem::new(sim.system, sim.state, mesh, terms, params).unwrap();
    let mut none = |_: &_| ControlFlow::Continue(());
    // From the scene's equilibrium to the warped pattern's, then the base evaluation from there.
    problem.evaluate(&pattern, false, &mut none).unwrap();
    let base = problem.evaluate(&pattern, true, &mut none).unwrap();
    assert!(
        base.equilibrium.converged && base.equilibrium.residual <= SOLVER_TOLERANCE,
        "the base equilibrium: {:?}",
        base.equilibrium
    );
    assert_eq!(
        base.adjoint_damping, 0.0,
        "the adjoint solve needed damping: the gradient would not be exact"
    );
    let regimes = regimes(&problem);
    Mixed {
        problem,
        pattern,
        wale,
        base,
        regimes,
    }
}

/// The pattern `flat` with each panel's course scaled by `k(ξ)` about the panel's centroid, and the
/// pocket in the first panel (see the module documentation).
fn warp(mesh: &DesignMesh, flat: &[Vec2], wale: &[Vec2]) -> Vec<Vec2> {
    let n = wale.len();
    let mut centre = vec![Vec2::zeros(); n];
    let mut count = vec![0.0; n];
    for (v, p) in flat.iter().enumerate() {
        centre[mesh.pattern_panel[v]] += p;
        count[mesh.pattern_panel[v]] += 1.0;
    }
    for (c, k) in centre.iter_mut().zip(&count) {
        *c /= *k;
    }
    let mut half_length = vec![0.0_f64; n];
    for (v, p) in flat.iter().enumerate() {
        let panel = mesh.pattern_panel[v];
        half_length[panel] = half_length[panel].max(wale[panel].dot(&(p - centre[panel])).abs());
    }
    flat.iter()
        .enumerate()
        .map(|(v, p)| {
            let panel = mesh.pattern_panel[v];
            let g = wale[panel];
            let course = Vec2::new(-g.y, g.x);
            let d = p - centre[panel];
            let (s, t) = (g.dot(&d), course.dot(&d));
            let k = COURSE_SCALE + COURSE_SLOPE * s / half_length[panel];
            let q = g * s + course * (t * k);
            let pocket = g * (POCKET_AT * half_length[panel]);
            let rho = (q - pocket).norm() / POCKET_RADIUS;
            let bump = if panel == 0 && rho < 1.0 {
                (1.0 - rho * rho).powi(2)
            } else {
                0.0
            };
            centre[panel] + q + (q - pocket) * (POCKET_SCALE * bump)
        })
        .collect()
}

/// The smallest distance, over the cloth triangles, of `λ1 − 1` from the edges `0`, `w` and of
/// `λ2 − λ̄2(λ1)` from the edges `0`, `(1 + ν) w` of the smoothed tension field's bands (in `λ`, squared
/// stretch, dimensionless).
fn band_edge_margin(problem: &DesignProblem) -> Real {
    let density = *problem.system().density();
    let w = density.transition_width();
    // λ̄2(λ1) = 1 − ν(λ1 − 1): ν from λ1 = 2.
    let nu = 1.0 - density.wrinkling_threshold(2.0);
    let mut margin = Real::INFINITY;
    for s in problem.system().element_states(problem.state()).unwrap() {
        let [s1, s2] = s.principal_stretches;
        let (l1, l2) = (s1 * s1, s2 * s2);
        let a = l1 - 1.0;
        let g = l2 - density.wrinkling_threshold(l1);
        for e in [a, a - w, g, g - (1.0 + nu) * w] {
            margin = margin.min(e.abs());
        }
    }
    margin
}

fn regimes(problem: &DesignProblem) -> Vec<Regime> {
    problem
        .system()
        .element_states(problem.state())
        .unwrap()
        .iter()
        .map(|s| s.regime)
        .collect()
}

/// `[wale, course]` stretch `|F g|` of every cloth triangle (dimensionless), as
/// [`FabricStretchLimit`] measures it.
fn directional_stretches(
    mesh: &DesignMesh,
    wale: &[Vec2],
    cloth: &[Vec3],
    pattern: &[Vec2],
) -> Vec<[Real; 2]> {
    (0..mesh.num_triangles())
        .map(|f| {
            let u = mesh.pattern_triangles[f].map(|v| pattern[v]);
            let x = mesh.cloth_triangles[f].map(|v| cloth[v]);
            let (e1, e2) = (u[1] - u[0], u[2] - u[0]);
            let det = e1.x * e2.y - e1.y * e2.x;
            let image = |d: Vec2| {
                let alpha = (e2.y * d.x - e2.x * d.y) / det;
                let beta = (-e1.y * d.x + e1.x * d.y) / det;
                ((x[1] - x[0]) * alpha + (x[2] - x[0]) * beta).norm()
            };
            let g = wale[mesh.pattern_panel[mesh.pattern_triangles[f][0]]];
            [image(g), image(Vec2::new(-g.y, g.x))]
        })
        .collect()
}

/// Checks `analytic` against the differences of `value_at(t) = T(base + t d)` at `STEP` and `STEP/2`
/// (see the module documentation).
fn richardson(label: &str, analytic: Real, mut value_at: impl FnMut(Real) -> Real) {
    let h = STEP;
    let d_h = (value_at(h) - value_at(-h)) / (2.0 * h);
    let d_half = (value_at(0.5 * h) - value_at(-0.5 * h)) / h;
    let fd_error = (d_h - d_half) * 4.0 / 3.0;
    let extrapolated = (4.0 * d_half - d_h) / 3.0;
    let scale = analytic.abs().max(extrapolated.abs());
    assert!(scale > 0.0, "{label}: a direction with no change");
    let relative_error = (analytic - extrapolated).abs() / scale;
    let fd_error = fd_error.abs() / scale;
    println!(
        "{label}: adjoint {analytic:.12e}, extrapolated difference {extrapolated:.12e}, relative error \
         {:.2e}, Richardson estimate of the difference's error {:.2e}",
        relative_error, fd_error
    );
    assert!(
        FD_MARGIN * fd_error <= REL_TOL,
        "{label}: the central difference at h = {h:e} is not accurate enough to test with: estimated \
         error {:.2e} of the derivative (D(h) = {d_h:e}, D(h/2) = {d_half:e})",
        fd_error
    );
    assert!(
        relative_error <= REL_TOL,
        "{label}: adjoint {analytic:e} vs extrapolated central difference {extrapolated:e} (relative \
         {:.2e}; D(h) = {d_h:e}, D(h/2) = {d_half:e})",
        relative_error
    );
}

/// Asserts that the equilibrium the problem holds has the regimes of the base, triangle by triangle.
fn assert_same_regimes(label: &str, problem: &DesignProblem, base: &[Regime], t: Real) {
    let now = regimes(problem);
    let changed: Vec<String> = base
        .iter()
        .zip(&now)
        .enumerate()
        .filter(|(_, (a, b))| a != b)
        .map(|(f, (a, b))| format!("triangle {f}: {a:?} → {b:?}"))
        .collect();
    assert!(
        changed.is_empty(),
        "{label}: the difference stencil at t = {t:e} carries triangles across a regime boundary, where \
         the density is only C²: {changed:?}"
    );
}

/// `dT/dX̄ · d` against differences along three seeded random pattern directions.
fn check_pattern_directions(name: &str, m: &mut Mixed) {
    let gradient = m.base.gradient.clone().unwrap();
    let state = m.problem.state().clone();
    for seed in 0..3 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let d: Vec<Vec2> = m
            .pattern
            .iter()
            .map(|_| Vec2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)) * 1e-3)
            .collect();
        let analytic: Real = gradient.iter().zip(&d).map(|(g, v)| g.dot(v)).sum();
        let label = format!("{name} dT/dX̄ seed {seed}");
        let (problem, pattern, base) = (&mut m.problem, &m.pattern, &m.regimes);
        richardson(&label, analytic, |t| {
            problem.set_state(state.clone());
            let p: Vec<Vec2> = pattern.iter().zip(&d).map(|(p, v)| p + v * t).collect();
            let value = problem
                .evaluate(&p, false, &mut |_| ControlFlow::Continue(()))
                .unwrap()
                .value;
            assert_same_regimes(&label, problem, base, t);
            value
        });
    }
}

/// `dT/dX̄ · d` along seeded random pattern directions that move only the pattern vertices of the
/// triangles of one regime (taut, wrinkled, transition; slack too, with slack triangles), so that each
/// regime's part of the gradient is checked on its own.
fn check_regime_directions(name: &str, m: &mut Mixed) {
    let gradient = m.base.gradient.clone().unwrap();
    let state = m.problem.state().clone();
    let mesh = m.problem.mesh().clone();
    // The slack patch is a handful of vertices whose derivative is 5 to 20 times smaller than the
    // others' (m² Pa² or m² per m): they move 4 times farther, so that the equilibrium's noise stays
    // small beside it.
    for (seed, regime, amplitude) in [
        (20, Regime::Taut, 1e-3),
        (21, Regime::Wrinkled, 1e-3),
        (22, Regime::Transition, 1e-3),
        (23, Regime::Slack, 4e-3),
    ] {
        let mut moved = vec![false; m.pattern.len()];
        for (f, tri) in mesh.pattern_triangles.iter().enumerate() {
            if m.regimes[f] == regime {
                for &v in tri {
                    moved[v] = true;
                }
            }
        }
        if !moved.contains(&true) {
            continue;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let d: Vec<Vec2> = moved
            .iter()
            .map(|&on| {
                let r =
                    Vec2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)) * amplitude;
                if on { r } else { Vec2::zeros() }
            })
            .collect();
        let analytic: Real = gradient.iter().zip(&d).map(|(g, v)| g.dot(v)).sum();
        let label = format!("{name} dT/dX̄ on the {regime:?} triangles, seed {seed}");
        let (problem, pattern, base) = (&mut m.problem, &m.pattern, &m.regimes);
        richardson(&label, analytic, |t| {
            problem.set_state(state.clone());
            let p: Vec<Vec2> = pattern.iter().zip(&d).map(|(p, v)| p + v * t).collect();
            let value = problem
                .evaluate(&p, false, &mut |_| ControlFlow::Continue(()))
                .unwrap()
                .value;
            assert_same_regimes(&label, problem, base, t);
            value
        });
    }
}

/// `dT/dp · d` (through [`PatternMap::apply_jacobian_transpose`]) against differences of `T(P(p0 + t d))`
/// along three seeded random boundary-parameter directions (±1 mm per coordinate).
fn check_parameter_directions(name: &str, m: &mut Mixed) {
    let map = PatternMap::new(m.problem.mesh(), &m.pattern).unwrap();
    let p0 = map.initial_parameters();
    let gp = map
        .apply_jacobian_transpose(m.base.gradient.as_ref().unwrap())
        .unwrap();
    let state = m.problem.state().clone();
    for seed in 10..13 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let d: Vec<Real> = p0
            .iter()
            .map(|_| rng.random_range(-1.0..1.0) * 1e-3)
            .collect();
        let analytic: Real = gp.iter().zip(&d).map(|(g, v)| g * v).sum();
        let label = format!("{name} dT/dp seed {seed}");
        let (problem, base) = (&mut m.problem, &m.regimes);
        richardson(&label, analytic, |t| {
            problem.set_state(state.clone());
            let p: Vec<Real> = p0.iter().zip(&d).map(|(p, v)| p + v * t).collect();
            let value = problem
                .evaluate(&map.apply(&p).unwrap(), false, &mut |_| {
                    ControlFlow::Continue(())
                })
                .unwrap()
                .value;
            assert_same_regimes(&label, problem, base, t);
            value
        });
    }
}

#[test]
fn mixed_scene_has_taut_wrinkled_and_transition_triangles() {
    let m = mixed(|_| vec![]);
    let count = |r: Regime| m.regimes.iter().filter(|&&x| x == r).count();
    let (taut, wrinkled, transition, slack) = (
        count(Regime::Taut),
        count(Regime::Wrinkled),
        count(Regime::Transition),
        count(Regime::Slack),
    );
    println!(
        "{} triangles: taut {taut}, wrinkled {wrinkled}, transition {transition}, slack {slack}",
        m.regimes.len()
    );
    assert!(
        taut >= 100 && wrinkled >= 40 && transition >= 12 && slack >= 1,
        "the scene must mix the regimes: taut {taut}, wrinkled {wrinkled}, transition {transition}, \
         slack {slack}"
    );
    // No triangle on an edge of a smoothing band, where the density is only C² (the differences' stencil
    // moves `λ` by about 1e-5 at most).
    let margin = band_edge_margin(&m.problem);
    println!("closest approach to a smoothing band's edge (in λ): {margin:.2e}");
    assert!(
        margin >= 5e-5,
        "a triangle is {margin:e} (in λ) from an edge of a tension-field smoothing band"
    );
    // Each regime's triangles where the warp puts them: taut near the lower cuff, wrinkled near the upper.
    let cloth = &m.base.cloth;
    let mesh = m.problem.mesh();
    let mean_height = |r: Regime| {
        let ys: Vec<Real> = (0..mesh.num_triangles())
            .filter(|&f| m.regimes[f] == r)
            .map(|f| {
                mesh.cloth_triangles[f]
                    .iter()
                    .map(|&v| cloth[v].y)
                    .sum::<Real>()
                    / 3.0
            })
            .collect();
        ys.iter().sum::<Real>() / ys.len() as Real
    };
    let (yt, yr, yw) = (
        mean_height(Regime::Taut),
        mean_height(Regime::Transition),
        mean_height(Regime::Wrinkled),
    );
    println!("mean heights (m): taut {yt:.4}, transition {yr:.4}, wrinkled {yw:.4}");
    assert!(
        yt < yr && yr < yw,
        "taut {yt}, transition {yr}, wrinkled {yw}"
    );
    // Both stretch limits exceeded somewhere, and not everywhere.
    let stretches = directional_stretches(mesh, &m.wale, cloth, &m.pattern);
    for (d, name) in ["wale", "course"].iter().enumerate() {
        let above = stretches.iter().filter(|s| s[d] > LIMITS[d]).count();
        println!("{name} stretch above {}: {above} triangles", LIMITS[d]);
        assert!(
            above >= 10 && above + 10 <= stretches.len(),
            "{name}: {above} triangles above the limit {}",
            LIMITS[d]
        );
    }
}

#[test]
fn band_pressure_gradient_in_mixed_regimes() {
    let mut m = mixed(|_| vec![Box::new(band_pressure(1e-2))]);
    // Each band's pressure against its window, with a margin (no window edge within reach of the
    // differences), and each band edge cutting through cloth triangles.
    let term = band_pressure(1e-2);
    let mesh = m.problem.mesh();
    let input = TermInput {
        mesh,
        cloth: &m.base.cloth,
        pattern: &m.pattern,
        fabric: m.problem.fabric(),
    };
    let measured = term.band_pressures(&input).unwrap();
    let mut sides = Vec::new();
    for (band, p) in bands().iter().zip(&measured) {
        let (pressure, area) = p.expect("every band holds triangles");
        println!(
            "band {}: pressure {pressure:.1} Pa over {area:.3e} m², window [{}, {}] Pa",
            band.name, band.min, band.max
        );
    }
    for (band, p) in bands().iter().zip(&measured) {
        let (pressure, _) = p.unwrap();
        let side = if pressure < band.min {
            -1
        } else if pressure > band.max {
            1
        } else {
            0
        };
        let margin = (pressure - band.min).abs().min((pressure - band.max).abs());
        assert!(
            margin >= 50.0,
            "band {}: {pressure} Pa is within 50 Pa of its window",
            band.name
        );
        sides.push(side);
        let (origin, direction) = axis();
        for edge in [band.center - band.half_width, band.center + band.half_width] {
            let cut = mesh.cloth_triangles.iter().any(|t| {
                let s = t.map(|v| direction.dot(&(m.base.cloth[v] - origin)));
                s.iter().any(|&x| x < edge) && s.iter().any(|&x| x > edge)
            });
            assert!(
                cut,
                "band {}: no triangle straddles its edge {edge}",
                band.name
            );
        }
    }
    assert!(
        sides.contains(&-1) && sides.contains(&1) && sides.contains(&0),
        "bands below, above and inside their windows: {sides:?}"
    );
    assert!(m.base.value > 0.0);
    check_pattern_directions("band_pressure", &mut m);
    check_regime_directions("band_pressure", &mut m);
    check_parameter_directions("band_pressure", &mut m);
}

#[test]
fn fabric_stretch_limit_gradient_in_mixed_regimes() {
    let mut m = mixed(|wale| {
        vec![Box::new(
            FabricStretchLimit::new(1e4, LIMITS, wale.to_vec()).unwrap(),
        )]
    });
    assert!(m.base.value > 0.0);
    check_pattern_directions("fabric_stretch_limit", &mut m);
    check_regime_directions("fabric_stretch_limit", &mut m);
    check_parameter_directions("fabric_stretch_limit", &mut m);
}

#[test]
fn prescription_limits_pressure_and_stretch_gradient_in_mixed_regimes() {
    let mut m = mixed(sum_terms);
    assert!(
        m.base.terms.iter().all(|t| t.value > 0.0),
        "every term is active: {:?}",
        m.base
            .terms
            .iter()
            .map(|t| (t.name, t.value))
            .collect::<Vec<_>>()
    );
    check_pattern_directions("sum", &mut m);
    check_regime_directions("sum", &mut m);
    check_parameter_directions("sum", &mut m);
}

/// The central difference `D(h)` and its Richardson estimate `E(h)` over steps `2⁻¹ … 2⁻¹⁶` for the sum of
/// the terms, along the pattern directions of the checks: the measurements behind `STEP` (module
/// documentation).
#[test]
#[ignore = "a step-size sweep for the documentation, about 10 s; run with --nocapture"]
fn step_size_sweep() {
    let mut m = mixed(sum_terms);
    let gradient = m.base.gradient.clone().unwrap();
    let state = m.problem.state().clone();
    for seed in 0..3 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let d: Vec<Vec2> = m
            .pattern
            .iter()
            .map(|_| Vec2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)) * 1e-3)
            .collect();
        let analytic: Real = gradient.iter().zip(&d).map(|(g, v)| g.dot(v)).sum();
        let mut at = |t: Real| {
            m.problem.set_state(state.clone());
            let p: Vec<Vec2> = m.pattern.iter().zip(&d).map(|(p, v)| p + v * t).collect();
            m.problem
                .evaluate(&p, false, &mut |_| ControlFlow::Continue(()))
                .unwrap()
                .value
        };
        println!("seed {seed}: adjoint {analytic:.12e}");
        let mut previous: Option<Real> = None;
        for k in 1..=16 {
            let h = 0.5_f64.powi(k);
            let d_h = (at(h) - at(-h)) / (2.0 * h);
            let richardson = previous.map_or(String::new(), |p| {
                format!(
                    ", E(2h) {:.2e}, (4D(h) − D(2h))/3 − adjoint {:.2e}",
                    ((p - d_h) * 4.0 / 3.0 / analytic).abs(),
                    (((4.0 * d_h - p) / 3.0 - analytic) / analytic).abs()
                )
            });
            println!(
                "  h {h:.3e}: D(h) − adjoint {:.2e}{richardson} (relative)",
                ((d_h - analytic) / analytic).abs()
            );
            previous = Some(d_h);
        }
    }
}
