use super::*;
use crate::term::Fabric;
use crate::test_support::*;
use crate::young_laplace_pressure::tests::{bent_strip, regimes};
use crate::young_laplace_pressure::young_laplace_pressures;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::finite_difference::FdParams;
use skintight_physics::Regime;

fn fd() -> FdParams {
    FdParams {
        step: 1e-7,
        rel_tol: 2e-5,
        abs_tol: 1e-9,
    }
}

fn input<'a>(
    s: &'a Strip,
    cloth: &'a [Vec3],
    pattern: &'a [Vec2],
    fabric: &'a Fabric,
) -> TermInput<'a> {
    TermInput {
        mesh: &s.mesh,
        cloth,
        pattern,
        fabric,
    }
}

#[test]
fn gradient_with_the_phi_chain_rule_and_residuals_match_finite_differences_in_every_regime() {
    // `check_term_gradient` compares with central differences of T(x, X̄) that re-solve φ* every time.
    let s = strip(3, 2, 0.05);
    let fabric = fabric();
    let terms = [
        Pressure::new(1e-3, PressureTarget::Value(150.0), 0.0)
            .unwrap()
            .with_boundary_ring(true),
        Pressure::new(
            2e-3,
            PressureTarget::Range {
                min: 100.0,
                max: 120.0,
            },
            5e-3,
        )
        .unwrap()
        .with_boundary(BoundaryEdges::FaceNormal)
        .with_boundary_ring(true),
        // The default leaves the boundary ring out (the strip has two interior vertices).
        Pressure::new(1e-3, PressureTarget::Value(150.0), 1e-3).unwrap(),
    ];
    for seed in [1, 2] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for (regime, m1, m2, noise) in regimes() {
            let (cloth, pattern) = bent_strip(&mut rng, &s, 0.4, m1, m2, noise);
            for term in &terms {
                let v = check_term_gradient(term, &s.mesh, &fabric, &cloth, &pattern, &fd());
                assert!(v > 0.0, "{regime:?}");
                let n = check_term_residuals(term, &s.mesh, &fabric, &cloth, &pattern, &fd());
                let nf = s.mesh.num_triangles();
                assert_eq!(
                    n,
                    if term.negative_weight() > 0.0 {
                        2 * nf
                    } else {
                        nf
                    }
                );
            }
            if regime == Regime::Slack {
                let p = young_laplace_pressures(
                    &input(&s, &cloth, &pattern, &fabric),
                    BoundaryEdges::Free,
                )
                .unwrap();
                assert!(p.iter().all(|&p| p == 0.0));
            }
        }
    }
}

#[test]
fn lift_off_over_a_concave_region_is_penalised_and_reported() {
    // A saddle-like wavy sheet, stretched taut: some triangles are concave (negative pressure).
    let s = strip(4, 3, 0.04);
    let fabric = fabric();
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let cloth: Vec<Vec3> = s
        .cloth_layout
        .iter()
        .map(|p| {
            let z = 0.01 * (p.x * 40.0).sin() * (p.y * 30.0).cos();
            Vec3::new(1.2 * p.x, 1.15 * p.y, z)
                + Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ) * 1e-4
        })
        .collect();
    let pattern = s.pattern_layout.clone();
    let inp = input(&s, &cloth, &pattern, &fabric);
    let p = young_laplace_pressures(&inp, BoundaryEdges::Free).unwrap();
    assert!(
        p.iter().any(|&p| p < 0.0) && p.iter().any(|&p| p > 0.0),
        "{p:?}"
    );
    let plain = Pressure::new(
        1e-3,
        PressureTarget::Range {
            min: -1e6,
            max: 1e6,
        },
        0.0,
    )
    .unwrap()
    .with_boundary_ring(true);
    let lift = Pressure::new(
        1e-3,
        PressureTarget::Range {
            min: -1e6,
            max: 1e6,
        },
        2e-3,
    )
    .unwrap()
    .with_boundary_ring(true);
    assert_eq!(plain.evaluate(&inp, None).unwrap().value, 0.0);
    let e = lift.evaluate(&inp, None).unwrap();
    // Exactly the negative triangles contribute, 2e-3 Ā p².
    for (f, (&v, &pf)) in e.per_element.iter().zip(&p).enumerate() {
        let area = s.mesh.pattern_area(&pattern, f);
        let expect = if pf < 0.0 { 2e-3 * area * pf * pf } else { 0.0 };
        assert!(
            (v - expect).abs() <= 1e-12 * expect.abs() + 1e-300,
            "{v} {expect}"
        );
    }
    check_term_gradient(&lift, &s.mesh, &fabric, &cloth, &pattern, &fd());
    check_term_residuals(&lift, &s.mesh, &fabric, &cloth, &pattern, &fd());
}

#[test]
fn value_is_the_area_weighted_squared_deviation() {
    // Isotropically stretched sphere soup: every triangle has the same pressure p0 (within the
    // discretization), so T = w Σ Ā (p − T)² is checked against the pressures themselves.
    let fabric = fabric();
    let (faces, x) = icosphere(0.1, 2);
    let (mesh, pattern) = soup_design_mesh(&faces, &x, 1.1);
    let inp = TermInput {
        mesh: &mesh,
        cloth: &x,
        pattern: &pattern,
        fabric: &fabric,
    };
    let p = young_laplace_pressures(&inp, BoundaryEdges::Free).unwrap();
    let t = Pressure::new(0.5, PressureTarget::Value(300.0), 1.0).unwrap();
    let e = t.evaluate(&inp, None).unwrap();
    let expect: Real = (0..mesh.num_triangles())
        .map(|f| 0.5 * mesh.pattern_area(&pattern, f) * (p[f] - 300.0).powi(2))
        .sum();
    assert!((e.value - expect).abs() <= 1e-12 * expect);
    assert_eq!(e.per_element.len(), mesh.num_triangles());
    let r = t.residuals(&inp).unwrap().unwrap();
    // No negative pressure on a sphere, but the lift-off residuals are there (zero).
    assert_eq!(r.values.len(), 2 * mesh.num_triangles());
    let sq: Real = r.values.iter().map(|v| v * v).sum();
    assert!((sq - e.value).abs() <= 1e-12 * e.value);
    // Inside a range containing every pressure: zero.
    let lo = p.iter().copied().fold(Real::INFINITY, Real::min);
    let hi = p.iter().copied().fold(0.0, Real::max);
    let inside = Pressure::new(
        1.0,
        PressureTarget::Range {
            min: lo - 1.0,
            max: hi + 1.0,
        },
        1.0,
    )
    .unwrap();
    assert_eq!(inside.evaluate(&inp, None).unwrap().value, 0.0);
}

#[test]
fn bad_parameters_and_inputs_are_errors() {
    for (w, t, n) in [
        (-1.0, PressureTarget::Value(1.0), 0.0),
        (Real::NAN, PressureTarget::Value(1.0), 0.0),
        (1.0, PressureTarget::Value(Real::INFINITY), 0.0),
        (1.0, PressureTarget::Value(1.0), -1.0),
        (1.0, PressureTarget::Range { min: 2.0, max: 1.0 }, 0.0),
        (
            1.0,
            PressureTarget::Range {
                min: Real::NAN,
                max: 1.0,
            },
            0.0,
        ),
    ] {
        assert!(matches!(
            Pressure::new(w, t, n),
            Err(TermError::Parameter { .. })
        ));
    }
    let s = strip(2, 1, 0.1);
    let fabric = fabric();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let (cloth, pattern) = bent_strip(&mut rng, &s, 0.5, 1.2, 1.1, 0.0);
    let t = Pressure::new(1.0, PressureTarget::Value(10.0), 1.0).unwrap();
    let thin = Fabric {
        thickness: 0.0,
        ..fabric.clone()
    };
    assert!(matches!(
        t.evaluate(&input(&s, &cloth, &pattern, &thin), None),
        Err(TermError::Invalid { .. })
    ));
    let mut nan = cloth.clone();
    nan[2].y = Real::NAN;
    assert!(
        t.evaluate(&input(&s, &nan, &pattern, &fabric), None)
            .is_err()
    );
    assert!(
        t.residuals(&input(&s, &nan, &pattern, &fabric))
            .unwrap()
            .is_err()
    );
    let flat = vec![Vec3::zeros(); cloth.len()];
    assert!(matches!(
        t.evaluate(&input(&s, &flat, &pattern, &fabric), None),
        Err(TermError::Collapsed { .. })
    ));
    let mut inverted = pattern.clone();
    let [a, b, _] = s.mesh.pattern_triangles[0];
    inverted.swap(a, b);
    assert!(matches!(
        t.evaluate(&input(&s, &cloth, &inverted, &fabric), None),
        Err(TermError::Collapsed { .. })
    ));
}

#[test]
#[allow(clippy::needless_range_loop)] // parallel per-triangle arrays
fn the_boundary_ring_is_left_out_by_default() {
    let s = strip(4, 3, 0.04);
    let fabric = fabric();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (cloth, pattern) = bent_strip(&mut rng, &s, 0.3, 1.3, 1.2, 1e-4);
    let inp = input(&s, &cloth, &pattern, &fabric);
    let all = Pressure::new(1.0, PressureTarget::Value(0.0), 0.0)
        .unwrap()
        .with_boundary_ring(true);
    let inner = Pressure::new(1.0, PressureTarget::Value(0.0), 0.0).unwrap();
    assert!(!inner.includes_boundary_ring() && all.includes_boundary_ring());
    let (ea, ei) = (
        all.evaluate(&inp, None).unwrap(),
        inner.evaluate(&inp, None).unwrap(),
    );
    let op = crate::mid_edge_shape_operator::MidEdgeShapeOperator::new(
        &s.mesh.cloth_triangles,
        s.mesh.num_cloth_vertices,
        BoundaryEdges::Free,
    )
    .unwrap();
    let ring = op.boundary_ring();
    assert!(ring.iter().any(|r| *r) && ring.iter().any(|r| !*r));
    for f in 0..ring.len() {
        if ring[f] {
            assert_eq!(ei.per_element[f], 0.0);
        } else {
            assert_eq!(ei.per_element[f], ea.per_element[f]);
            assert!(ei.per_element[f] > 0.0);
        }
    }
    check_term_gradient(&inner, &s.mesh, &fabric, &cloth, &pattern, &fd());
    check_term_residuals(&inner, &s.mesh, &fabric, &cloth, &pattern, &fd());
}
