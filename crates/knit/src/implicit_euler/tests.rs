use super::*;
use crate::PeriodicPattern;
use crate::patch::PatchLoads;
use crate::patch_friction::tests::GROOVE_TOP;
use crate::test_support::shared_yarns_dir;
use crate::tile::tile;
use crate::yarn_params::YarnParams;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn model(name: &str, nx: usize, ny: usize, gravity: [f64; 3]) -> PatchModel {
    let p = PeriodicPattern::read(&shared_yarns_dir().join(name).join("pattern.pyp")).unwrap();
    let patch = tile(&p, nx, ny).unwrap();
    let loads = PatchLoads {
        gravity,
        sphere: None,
    };
    PatchModel::new(&patch, &YarnParams::default(), loads).unwrap()
}

fn tight() -> ImplicitEulerParams {
    let mut p = ImplicitEulerParams::default();
    p.newton.tolerance = 1e-11;
    p.newton.max_iterations = 600;
    p.newton.max_factorizations = 3000;
    p
}

/// The centre of mass (m) of the positions in `x`.
fn centre_of_mass(m: &PatchModel, x: &[f64]) -> [f64; 3] {
    let total: f64 = m.masses().iter().sum();
    std::array::from_fn(|k| {
        m.masses()
            .iter()
            .zip(x.chunks(4))
            .map(|(mi, c)| mi * c[k])
            .sum::<f64>()
            / total
    })
}

#[test]
fn a_free_patch_falls_like_backward_euler_of_a_point_mass() {
    // Internal forces sum to zero, so the centre of mass obeys backward Euler for one particle:
    // v_{n+1} = (v_n + h g) / (1 + c h), x_{n+1} = x_n + h v_{n+1}.
    for damping in [0.0, 3.0] {
        let g = [0.0, -9.81, 2.0];
        let m = model("stocktiniest_9", 2, 2, g);
        let params = ImplicitEulerParams {
            mass_damping: damping,
            ..tight()
        };
        let mut sim = ImplicitEuler::new(m, params, vec![]).unwrap();
        let relax = sim.relax(&params.newton).unwrap();
        assert!(relax.converged, "{relax:?}");
        let h = params.dt;
        let mut c = centre_of_mass(sim.model(), sim.state());
        let mut v = [0.0; 3];
        for _ in 0..4 {
            let report = sim.step().unwrap();
            assert!(report.newton.converged, "{report:?}");
            for k in 0..3 {
                v[k] = (v[k] + h * g[k]) / (1.0 + damping * h);
                c[k] += h * v[k];
            }
        }
        let got = centre_of_mass(sim.model(), sim.state());
        let fall = (v[1] * v[1]).sqrt() * h;
        for k in 0..3 {
            assert!(
                (got[k] - c[k]).abs() < 1e-4 * fall,
                "damping {damping}, axis {k}: {} vs {} (fall per step {fall})",
                got[k],
                c[k]
            );
        }
        assert!((sim.time() - 4.0 * h).abs() < 1e-15);
    }
}

#[test]
fn clamped_and_moving_vertices_follow_their_paths_and_yarns_stay_apart() {
    let m = model("stocktiniest_9", 3, 2, [0.0, -9.81, 0.0]);
    let x0 = m.initial_state();
    let r = m.radius();
    let ymax = x0.chunks(4).map(|c| c[1]).fold(f64::NEG_INFINITY, f64::max);
    let ymin = x0.chunks(4).map(|c| c[1]).fold(f64::INFINITY, f64::min);
    let mut prescribed = Vec::new();
    for (v, c) in x0.chunks(4).enumerate() {
        let p = [c[0], c[1], c[2]];
        if c[1] > ymax - 2.0 * r {
            prescribed.push(Prescribed {
                vertex: v,
                start: p,
                end: p,
                ramp_time: 0.0,
            });
        } else if c[1] < ymin + 2.0 * r {
            // Pulled down by 0.5 r over 0.01 s.
            prescribed.push(Prescribed {
                vertex: v,
                start: p,
                end: [p[0], p[1] - 0.5 * r, p[2]],
                ramp_time: 0.01,
            });
        }
    }
    assert!(prescribed.len() >= 4);
    let params = ImplicitEulerParams {
        dt: 0.005,
        ..tight()
    };
    let mut sim = ImplicitEuler::new(m, params, prescribed.clone()).unwrap();
    sim.relax(&params.newton).unwrap();
    let d0 = sim.model().min_distance(sim.state());
    for _ in 0..3 {
        let report = sim.step().unwrap();
        assert!(report.newton.converged, "{report:?}");
        assert!(
            report.min_distance >= 0.5 * 2.0 * r,
            "min distance {} (start {d0})",
            report.min_distance
        );
        let t = sim.time();
        for p in &prescribed {
            let q = p.position(t);
            for k in 0..3 {
                assert_eq!(sim.state()[4 * p.vertex + k], q[k]);
            }
        }
    }
    // Past the ramp the moving vertices rest at their ends.
    let end = prescribed.iter().find(|p| p.start != p.end).unwrap();
    assert_eq!(end.position(1.0), end.end);
    assert!((end.position(0.005)[1] - (end.start[1] - 0.25 * r)).abs() < 1e-15);
    // The free vertices moved (gravity and the published rest state's own forces act on them).
    let moved = sim
        .state()
        .iter()
        .zip(&x0)
        .enumerate()
        .filter(|(k, _)| !sim.fixed()[*k])
        .any(|(_, (a, b))| (a - b).abs() > 1e-9);
    assert!(moved);
}

#[test]
fn bad_settings_are_named() {
    let m = model("stocktiniest_9", 1, 1, [0.0; 3]);
    let e = ImplicitEuler::new(
        m.clone(),
        ImplicitEulerParams {
            dt: 0.0,
            ..ImplicitEulerParams::default()
        },
        vec![],
    )
    .unwrap_err();
    assert!(e.to_string().contains("dt = 0"), "{e}");
    let e = ImplicitEuler::new(
        m,
        ImplicitEulerParams::default(),
        vec![Prescribed {
            vertex: 10_000,
            start: [0.0; 3],
            end: [0.0; 3],
            ramp_time: 0.0,
        }],
    )
    .unwrap_err();
    assert!(e.to_string().contains("vertex 10000 does not exist"), "{e}");
}

#[test]
fn the_reused_analysis_warm_shift_and_energy_line_search_converge_as_the_legacy_solver() {
    // The same hanging patch stepped with the solver's speed-ups (energy-only line search, symbolic
    // analysis kept across iterations and steps in the workspace, warm shift) and without: both reach the
    // tolerance at every step with the yarns apart, and the fast one reuses analyses. (The states are not
    // compared: the relaxed cut ends have no unique equilibrium, so two solvers' paths may settle them
    // differently.)
    let top = |m: &PatchModel| {
        let x = m.initial_state();
        let ymax = x.chunks(4).map(|c| c[1]).fold(f64::NEG_INFINITY, f64::max);
        x.chunks(4)
            .enumerate()
            .filter(|(_, c)| c[1] > ymax - 0.5 * m.radius())
            .map(|(v, c)| Prescribed {
                vertex: v,
                start: [c[0], c[1], c[2]],
                end: [c[0], c[1], c[2]],
                ramp_time: 0.0,
            })
            .collect::<Vec<_>>()
    };
    for fast in [false, true] {
        let m = model("stocktiniest_9", 2, 2, [0.0, -9.81, 0.0]);
        let held = top(&m);
        let mut params = tight();
        params.newton.energy_line_search = fast;
        params.newton.reuse_analysis = fast;
        params.newton.warm_shift = fast;
        let mut sim = ImplicitEuler::new(m, params, held).unwrap();
        assert!(sim.relax(&params.newton).unwrap().converged);
        let (mut analyses, mut iterations) = (0, 0);
        for _ in 0..4 {
            let r = sim.step().unwrap();
            assert!(r.newton.converged, "fast {fast}: {r:?}");
            assert!(r.newton.residual <= params.newton.tolerance);
            assert!(r.min_distance > 0.5 * sim.model().stiffness().contact_distance);
            analyses += r.newton.figures.timings.analyses;
            iterations += r.newton.iterations;
        }
        if fast {
            assert!(
                analyses < iterations / 4,
                "{analyses} analyses for {iterations} iterations"
            );
        } else {
            assert_eq!(analyses, iterations, "legacy: one analysis per iteration");
        }
    }
}

#[test]
fn a_step_whose_newton_solve_does_not_converge_is_halved_and_ends_where_the_halves_do() {
    // A relaxed patch set falling under gravity, its top corner vertices moving down fast: with a Newton
    // budget of 2 iterations the whole step stops short of the tolerance; halved, each substep is nearer
    // its start and converges.
    let m = model("stocktiniest_9", 2, 2, [0.0, -9.81, 0.0]);
    let budget = |max_halvings: usize, iterations: usize| {
        let mut p = tight();
        p.newton.tolerance = 1e-9;
        p.newton.max_iterations = iterations;
        p.max_halvings = max_halvings;
        p
    };
    let mut start = ImplicitEuler::new(m.clone(), budget(0, 600), vec![]).unwrap();
    assert!(start.relax(&budget(0, 600).newton).unwrap().converged);
    let relaxed = start.model().clone();
    let x0 = start.state().to_vec();
    let sim = |params: ImplicitEulerParams| {
        let mut model = relaxed.clone();
        // The relaxed state as the model's start.
        let mut s = ImplicitEuler::new(model.clone(), params, vec![]).unwrap();
        s.x.copy_from_slice(&x0);
        model.rebase_frames(&x0, 0.0);
        s.model = model;
        s
    };
    let mut whole = sim(budget(0, 2));
    let r = whole.step().unwrap();
    assert!(
        !r.newton.converged,
        "the whole step should stop short: {r:?}"
    );
    assert_eq!((r.substeps, r.rejected_substeps), (1, 0));

    let mut halved = sim(budget(6, 2));
    let r = halved.step().unwrap();
    assert!(r.newton.converged, "{r:?}");
    assert_eq!((r.substeps, r.rejected_substeps), (2, 1), "{r:?}");
    assert!((halved.time() - budget(0, 2).dt).abs() < 1e-18);
    // The abandoned attempt left nothing behind: the state is that of two backward Euler steps of dt/2
    // from the start, replayed from scratch with a generous budget.
    let mut half = budget(0, 600);
    half.dt /= 2.0;
    let mut replay = sim(half);
    for _ in 0..2 {
        assert!(replay.step().unwrap().newton.converged);
    }
    // Within `tol` rad for angles and `tol` radii for positions (per second for velocities).
    let close = |what: &str, a: &[f64], b: &[f64], tol: f64| {
        for (k, (p, q)) in a.iter().zip(b).enumerate() {
            let t = if k % DOFS_PER_VERTEX == 3 {
                tol
            } else {
                tol * relaxed.radius()
            };
            assert!((p - q).abs() <= t, "{what} {k}: {p} against {q}");
        }
    };
    close("unknown", halved.state(), replay.state(), 1e-6);
    close("velocity", halved.velocity(), replay.velocity(), 1e-3);
    // The next step keeps the halved length (its substeps were not easy) and converges.
    let r2 = halved.step().unwrap();
    assert!(r2.newton.converged && r2.substeps >= 2, "{r2:?}");
}

/// The groove of [`crate::patch_friction::tests::groove`] with its base yarns clamped.
fn groove(gravity: [f64; 3]) -> (PatchModel, Vec<Prescribed>) {
    let (model, clamped) = crate::patch_friction::tests::groove(gravity);
    let x = model.initial_state();
    let clamps = clamped
        .map(|v| {
            let p = [x[4 * v], x[4 * v + 1], x[4 * v + 2]];
            Prescribed {
                vertex: v,
                start: p,
                end: p,
                ramp_time: 0.0,
            }
        })
        .collect();
    (model, clamps)
}

/// The friction's share of a step's incremental potential (with friction less without) at `x`: energy
/// (J, by the line search's [`NewtonProblem::energy`]), gradient (N) and the dense Hessian (N/m) of
/// [`NewtonProblem::evaluate`].
fn friction_share(
    with: &StepProblem<'_>,
    without: &StepProblem<'_>,
    x: &[f64],
) -> (f64, Vec<f64>, Vec<Vec<f64>>) {
    let n = x.len();
    let (_, g1, t1) = with.evaluate(x, true);
    let (_, g0, t0) = without.evaluate(x, true);
    let mut h = vec![vec![0.0; n]; n];
    for (t, sign) in t1
        .iter()
        .map(|t| (t, 1.0))
        .chain(t0.iter().map(|t| (t, -1.0)))
    {
        h[t.row][t.col] += sign * t.val;
        if t.row != t.col {
            h[t.col][t.row] += sign * t.val;
        }
    }
    let g = g1.iter().zip(&g0).map(|(a, b)| a - b).collect();
    (with.energy(x) - without.energy(x), g, h)
}

#[test]
fn the_friction_term_of_the_step_energy_matches_central_differences_sticking_sliding_and_across() {
    // A yarn lying in a groove between two clamped yarns; the step's friction lagged at the start, the
    // top yarn moved along the groove by `size` with a seeded random spread.
    let (model, clamps) = groove([0.0, 0.0, -9.81]);
    let params = ImplicitEulerParams {
        friction_coefficient: 0.6,
        ..tight()
    };
    let sim = ImplicitEuler::new(model, params, clamps).unwrap();
    let x_n = sim.state().to_vec();
    let eps = params.friction_slip;
    let friction = PatchFriction::new(sim.model(), &x_n, 0.6, eps).unwrap();
    assert!(!friction.is_empty());
    let none = PatchFriction::default();
    let (mut m1, mut m0) = (sim.model().clone(), sim.model().clone());
    let x_hat: Vec<f64> = x_n.clone();
    let problem = |model, friction| StepProblem {
        model,
        x_hat: &x_hat,
        x_n: &x_n,
        mass: &sim.mass,
        fixed: &sim.fixed,
        h: params.dt,
        damping: params.mass_damping,
        friction,
        observer: None,
        interrupted: false,
    };
    let with = problem(&mut m1, &friction);
    let without = problem(&mut m0, &none);
    let free: Vec<usize> = GROOVE_TOP.flat_map(|v| 4 * v..4 * v + 3).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(4503);
    for trial in 0..3 {
        let dir = [
            1.0,
            0.3 * rng.random_range(-1.0..1.0),
            0.3 * rng.random_range(-1.0..1.0),
        ];
        let spread: Vec<f64> = (0..x_n.len())
            .map(|_| rng.random_range(-0.3..0.3))
            .collect();
        let at = |size: f64| -> Vec<f64> {
            let mut x = x_n.clone();
            for &k in &free {
                x[k] += size * (dir[k % 4] + spread[k]);
            }
            x
        };
        let mut probe = friction.slips(&at(eps));
        probe.sort_by(f64::total_cmp);
        for (regime, size) in [
            ("sticking", 0.1 * eps),
            ("sliding", 30.0 * eps),
            ("across ε", eps * eps / probe[probe.len() / 2]),
        ] {
            let x = at(size);
            let slips = friction.slips(&x);
            match regime {
                "sticking" => assert!(slips.iter().all(|y| *y < eps), "{slips:?}"),
                "sliding" => assert!(slips.iter().all(|y| *y > eps), "{slips:?}"),
                _ => assert!(
                    slips.iter().any(|y| *y < eps) && slips.iter().any(|y| *y > eps),
                    "{slips:?}"
                ),
            }
            let (e, g, h) = friction_share(&with, &without, &x);
            let d = friction.energy(&x);
            assert!((e - d).abs() <= 1e-9 * d, "{regime}: {e} vs {d}");
            let gmax = free.iter().fold(0.0f64, |m, &k| m.max(g[k].abs()));
            let hmax = h.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(gmax > 0.0 && hmax > 0.0);
            // Central differences with steps of 10⁻⁵ ε (the Hessian's kink at y = ε errs by the step over
            // ε; module documentation of `yarn_friction`).
            let step = 1e-5 * eps;
            for &k in &free {
                let (mut xp, mut xm) = (x.clone(), x.clone());
                xp[k] += step;
                xm[k] -= step;
                let (ep, gp, _) = friction_share(&with, &without, &xp);
                let (em, gm, _) = friction_share(&with, &without, &xm);
                let fd = (ep - em) / (2.0 * step);
                assert!(
                    (fd - g[k]).abs() <= 1e-5 * gmax,
                    "{regime} {trial}: gradient {k}: {} vs {fd}",
                    g[k]
                );
                for &j in &free {
                    let fdh = (gp[j] - gm[j]) / (2.0 * step);
                    assert!(
                        (fdh - h[j][k]).abs() <= 1e-4 * hmax,
                        "{regime} {trial}: hessian {j},{k}: {} vs {fdh}",
                        h[j][k]
                    );
                }
            }
            // The held unknowns' rows meet no friction.
            assert!(sim.fixed.iter().zip(&g).all(|(f, v)| !*f || *v == 0.0));
        }
    }
}

/// The mean x of the groove's top yarn (m).
fn top_x(x: &[f64]) -> f64 {
    let top = GROOVE_TOP;
    let n = top.len() as f64;
    top.map(|v| x[4 * v]).sum::<f64>() / n
}

#[test]
fn a_yarn_in_a_groove_sticks_at_high_friction_and_slides_without() {
    // Settled in the groove under vertical gravity (frictionless, damped), then the groove tilted by
    // θ = atan 0.3 along its axis: without friction the yarn slides down like a point mass on the incline
    // (backward Euler with the mass damping); with μ = 1 (> tan θ) it stays put but for the smoothed
    // static friction's creep, at most ε a step.
    let g = 9.81;
    let (model, clamps) = groove([0.0, 0.0, -g]);
    let settle_params = ImplicitEulerParams {
        mass_damping: 30.0,
        ..tight()
    };
    let mut settle = ImplicitEuler::new(model, settle_params, clamps).unwrap();
    for _ in 0..30 {
        assert!(settle.step().unwrap().newton.converged);
    }
    let mut settled = settle.save_state();
    settled.v.iter_mut().for_each(|v| *v = 0.0);
    let theta = 0.3f64.atan();
    let along = g * theta.sin();
    let steps = 12;
    let mut moved = Vec::new();
    for mu in [0.0, 1.0] {
        let (model, clamps) = groove([along, 0.0, -g * theta.cos()]);
        let params = ImplicitEulerParams {
            friction_coefficient: mu,
            ..tight()
        };
        let mut sim = ImplicitEuler::new(model, params, clamps).unwrap();
        sim.restore_state(settled.clone()).unwrap();
        let x0 = top_x(sim.state());
        for _ in 0..steps {
            let r = sim.step().unwrap();
            assert!(r.newton.converged, "μ = {mu}: {r:?}");
            assert_eq!(r.friction_pairs > 0, mu > 0.0, "{r:?}");
            assert!(r.min_distance > 0.9 * sim.model().stiffness().contact_distance);
        }
        moved.push(top_x(sim.state()) - x0);
    }
    let params = tight();
    let (h, c) = (params.dt, params.mass_damping);
    let (mut v, mut expected) = (0.0, 0.0);
    for _ in 0..steps {
        v = (v + h * along) / (1.0 + c * h);
        expected += h * v;
    }
    println!(
        "groove: slid {:.4e} m without friction (point mass {expected:.4e} m), {:.3e} m at μ = 1 \
         (creep bound {:.1e} m)",
        moved[0],
        moved[1],
        steps as f64 * params.friction_slip
    );
    assert!(
        (moved[0] - expected).abs() <= 0.05 * expected,
        "{moved:?} vs {expected}"
    );
    assert!(
        moved[1].abs() <= steps as f64 * params.friction_slip,
        "{moved:?}"
    );
}

#[test]
fn frictionless_settings_step_exactly_as_before_and_bad_friction_settings_are_named() {
    // μ = 0 assembles nothing, whatever the slip: the steps are those of the default settings, to the bit.
    let run = |params: ImplicitEulerParams| {
        let m = model("stocktiniest_9", 2, 1, [0.0, -9.81, 0.0]);
        let mut sim = ImplicitEuler::new(m, params, vec![]).unwrap();
        for _ in 0..2 {
            let r = sim.step().unwrap();
            assert_eq!(r.friction_pairs, 0);
        }
        (sim.state().to_vec(), sim.velocity().to_vec())
    };
    let base = run(ImplicitEulerParams::default());
    let zero = run(ImplicitEulerParams {
        friction_coefficient: 0.0,
        friction_slip: 0.37,
        ..ImplicitEulerParams::default()
    });
    assert_eq!(base, zero);
    let m = model("stocktiniest_9", 1, 1, [0.0; 3]);
    for (mu, eps, name) in [
        (-1.0, 1e-6, "friction_coefficient"),
        (f64::NAN, 1e-6, "friction_coefficient"),
        (0.3, 0.0, "friction_slip"),
        (0.3, f64::NAN, "friction_slip"),
    ] {
        let e = ImplicitEuler::new(
            m.clone(),
            ImplicitEulerParams {
                friction_coefficient: mu,
                friction_slip: eps,
                ..ImplicitEulerParams::default()
            },
            vec![],
        )
        .unwrap_err();
        assert!(e.to_string().starts_with(name), "{e}");
    }
}

/// The mean displacement (m) of the vertices from `x0` to `x1`.
fn mean_displacement(x0: &[f64], x1: &[f64]) -> f64 {
    x1.chunks(4)
        .zip(x0.chunks(4))
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt())
        .sum::<f64>()
        / (x0.len() / 4) as f64
}

/// `nx × nx` cells of the stockinette `stock_9`, cut and free, no gravity, started unrelaxed from the
/// published rest geometry (whose rest curvatures differ from its shape's: the cut edges curl), stepped
/// `steps` times with friction coefficient `mu`: the mean vertex displacement (m) after each step, and the
/// seconds, Newton iterations and friction pairs of the steps.
fn curl(nx: usize, steps: usize, mu: f64) -> (Vec<f64>, f64, usize, usize) {
    let m = model("stock_9", nx, nx, [0.0; 3]);
    let params = ImplicitEulerParams {
        friction_coefficient: mu,
        ..ImplicitEulerParams::default()
    };
    let mut sim = ImplicitEuler::new(m, params, vec![]).unwrap();
    let x0 = sim.state().to_vec();
    let (mut motion, mut iterations, mut pairs) = (Vec::new(), 0, 0);
    let t = std::time::Instant::now();
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.newton.converged, "μ = {mu}: {r:?}");
        assert!(r.min_distance > 0.5 * sim.model().stiffness().contact_distance);
        assert_eq!(r.friction_pairs > 0, mu > 0.0, "{r:?}");
        iterations += r.newton.iterations;
        pairs += r.friction_pairs;
        motion.push(mean_displacement(&x0, sim.state()));
    }
    (motion, t.elapsed().as_secs_f64(), iterations, pairs)
}

#[test]
fn a_curling_cut_edge_holds_with_friction() {
    // One cell of stockinette, its cut border curling from the unrelaxed rest geometry: the yarns slide
    // on each other where they cross; friction (μ = 0.5) holds the crossings, so the patch moves less than
    // half as far in 4 steps (1/60 s).
    let (free, ..) = curl(1, 4, 0.0);
    let (held, ..) = curl(1, 4, 0.5);
    println!(
        "curl: mean displacement without friction {:.3e} m, at μ = 0.5 {:.3e} m",
        free[3], held[3]
    );
    assert!(held[3] < 0.5 * free[3], "{free:?} vs {held:?}");
}

/// The longer curl (`KNIT_CURL_CELLS`, default 2; `KNIT_CURL_STEPS`, default 24 = 0.1 s) at μ = 0 and
/// 0.5, and the cost of a step with and without friction (docs/BENCHMARKS.md, issue 45, friction):
/// `cargo test --release -p skintight-knit --lib curl_benchmark -- --ignored --nocapture`.
#[test]
#[ignore]
fn curl_benchmark() {
    let var = |name: &str, default: usize| -> usize {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let (nx, steps) = (var("KNIT_CURL_CELLS", 2), var("KNIT_CURL_STEPS", 24));
    let mut last = Vec::new();
    for mu in [0.0, 0.5] {
        let (motion, seconds, iterations, pairs) = curl(nx, steps, mu);
        println!(
            "{nx} × {nx} stock_9, μ = {mu}: mean displacement after each step (mm) {:?}; {steps} steps in \
             {seconds:.2} s ({:.3} s a step), {iterations} Newton iterations ({:.1} ms each), {:.0} friction pairs a step",
            motion
                .iter()
                .map(|m| (m * 1e4).round() / 10.0)
                .collect::<Vec<_>>(),
            seconds / steps as f64,
            1e3 * seconds / iterations as f64,
            pairs as f64 / steps as f64
        );
        last.push(motion[steps - 1]);
    }
    assert!(last[1] < 0.5 * last[0], "{last:?}");
}

#[test]
#[ignore]
fn friction_step_cost_benchmark() {
    // The cost of a step with and without friction on a small hang (2 × 2 tiny stockinette relaxed, top
    // row held), side by side: `cargo test --release -p skintight-knit --lib friction_step_cost -- \
    // --ignored --nocapture`.
    for mu in [0.0, 0.5, 0.0, 0.5] {
        let m = model("stocktiniest_9", 2, 2, [0.0, -9.81, 0.0]);
        let x = m.initial_state();
        let ymax = x.chunks(4).map(|c| c[1]).fold(f64::NEG_INFINITY, f64::max);
        let held: Vec<Prescribed> = x
            .chunks(4)
            .enumerate()
            .filter(|(_, c)| c[1] > ymax - 0.5 * m.radius())
            .map(|(v, c)| Prescribed {
                vertex: v,
                start: [c[0], c[1], c[2]],
                end: [c[0], c[1], c[2]],
                ramp_time: 0.0,
            })
            .collect();
        let params = ImplicitEulerParams {
            friction_coefficient: mu,
            ..ImplicitEulerParams::default()
        };
        let mut sim = ImplicitEuler::new(m, params, held).unwrap();
        assert!(sim.relax(&tight().newton).unwrap().converged);
        let steps = 24;
        let (mut iterations, mut pairs) = (0, 0);
        let t = std::time::Instant::now();
        for _ in 0..steps {
            let r = sim.step().unwrap();
            assert!(r.newton.converged, "{r:?}");
            iterations += r.newton.iterations;
            pairs += r.friction_pairs;
        }
        let seconds = t.elapsed().as_secs_f64();
        println!(
            "2 × 2 stocktiniest_9 hang, μ = {mu}: {steps} steps in {seconds:.3} s ({:.1} ms a step), \
             {iterations} Newton iterations ({:.2} ms each), {:.1} friction pairs a step",
            1e3 * seconds / steps as f64,
            1e3 * seconds / iterations as f64,
            pairs as f64 / steps as f64
        );
    }
}
