use super::*;
use crate::math::Vec3;
use crate::term::Fabric;
use crate::test_support::*;
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
fn value_matches_hand_computed_equibiaxial_and_uniaxial_cases() {
    // Dyadic layout: F is exact. Seam along x: 2 edges of l0 = 0.5 m on each side, Σ l0 = 2 m.
    let s = strip(2, 1, 0.5);
    let fabric = fabric();
    let t = SeamTraction::new(3.0, SeamTractionForm::Squared).unwrap();
    let lin = SeamTraction::new(3.0, SeamTractionForm::Linear).unwrap();
    // Equibiaxial μ = 1.5625: S = (λ + μ)(μ − 1) I = E (μ − 1) / (2 (1 − ν)) I.
    let cloth: Vec<Vec3> = s
        .cloth_layout
        .iter()
        .map(|p| Vec3::new(1.25 * p.x, 1.25 * p.y, 0.0))
        .collect();
    let tau = E * 0.5625 / (2.0 * (1.0 - NU));
    let e = t
        .evaluate(&input(&s, &cloth, &s.pattern_layout, &fabric), None)
        .unwrap();
    let expect = 3.0 * THICKNESS * 2.0 * tau * tau;
    assert!(
        (e.value - expect).abs() <= 1e-12 * expect,
        "{} {expect}",
        e.value
    );
    assert_eq!(e.per_element.len(), 4);
    let e = lin
        .evaluate(&input(&s, &cloth, &s.pattern_layout, &fabric), None)
        .unwrap();
    let expect = 3.0 * THICKNESS * 2.0 * tau;
    assert!((e.value - expect).abs() <= 1e-12 * expect);
    // Uniaxial pull across the seam, cloth compressed along it (wrinkled): S_yy = E (μ1 − 1)/2.
    let cloth: Vec<Vec3> = s
        .cloth_layout
        .iter()
        .map(|p| Vec3::new(0.75 * p.x, 0.0, 1.25 * p.y))
        .collect();
    let tri = s.mesh.cloth_triangles[0].map(|v| cloth[v]);
    let rest = s.mesh.pattern_triangles[0].map(|v| s.pattern_layout[v]);
    let strain = TriangleStrain::new(&tri, &rest).unwrap();
    assert_eq!(
        fabric.density.regime(strain.mu[0], strain.mu[1]),
        Regime::Wrinkled
    );
    let tau = E * 0.5625 / 2.0;
    let e = t
        .evaluate(&input(&s, &cloth, &s.pattern_layout, &fabric), None)
        .unwrap();
    let expect = 3.0 * THICKNESS * 2.0 * tau * tau;
    assert!(
        (e.value - expect).abs() <= 1e-12 * expect,
        "{} {expect}",
        e.value
    );
    // The same pull along the seam (cross direction wrinkled) puts no stress across it.
    let cloth: Vec<Vec3> = s
        .cloth_layout
        .iter()
        .map(|p| Vec3::new(1.25 * p.x, 0.0, 0.75 * p.y))
        .collect();
    let e = t
        .evaluate(&input(&s, &cloth, &s.pattern_layout, &fabric), None)
        .unwrap();
    assert!(e.value.abs() <= 1e-20);
    let r = t
        .residuals(&input(&s, &cloth, &s.pattern_layout, &fabric))
        .unwrap()
        .unwrap();
    assert_eq!(r.values.len(), 4);
    assert!(
        lin.residuals(&input(&s, &cloth, &s.pattern_layout, &fabric))
            .is_none()
    );
}

/// Squared stretches `(μ1, μ2)` of each regime of the density (w = 0.01, ν = 0.3).
fn regimes() -> Vec<(Regime, Real, Real, Real)> {
    // (regime, μ1, μ2, noise in m)
    vec![
        (Regime::Taut, 1.3, 1.2, 2e-5),
        (Regime::Taut, 1.25, 1.25, 0.0),
        (Regime::Wrinkled, 1.3, 0.8, 2e-5),
        (Regime::Slack, 0.95, 0.85, 2e-5),
        (Regime::Slack, 0.9, 0.9, 0.0),
        // Slack → wrinkled band 1 ≤ μ1 ≤ 1.01.
        (Regime::Transition, 1.005, 0.9, 0.0),
        // Wrinkled → taut band 0 ≤ μ2 − (1 − ν(μ1 − 1)) ≤ 0.013.
        (Regime::Transition, 1.2, 0.947, 0.0),
        // Both bands at once, at equal stretches next to the triple point.
        (Regime::Transition, 1.004, 1.004, 0.0),
    ]
}

#[test]
fn gradient_matches_finite_differences_in_every_regime() {
    let s = strip(2, 1, 0.1);
    let fabric = fabric();
    for form in [SeamTractionForm::Squared, SeamTractionForm::Linear] {
        let t = SeamTraction::new(2.0, form).unwrap();
        for seed in [1, 2, 3] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            for (regime, m1, m2, noise) in regimes() {
                let f = deformation(&mut rng, m1.sqrt(), m2.sqrt());
                let angle = rng.random_range(-3.0..3.0);
                let (cloth, pattern) = place(&mut rng, &s, &f, angle, noise);
                for tri in 0..s.mesh.num_triangles() {
                    let x = s.mesh.cloth_triangles[tri].map(|v| cloth[v]);
                    let r = s.mesh.pattern_triangles[tri].map(|v| pattern[v]);
                    let st = TriangleStrain::new(&x, &r).unwrap();
                    assert_eq!(
                        fabric.density.regime(st.mu[0], st.mu[1]),
                        regime,
                        "({m1}, {m2})"
                    );
                }
                let v = check_term_gradient(&t, &s.mesh, &fabric, &cloth, &pattern, &fd());
                if regime == Regime::Slack {
                    assert_eq!(v, 0.0);
                } else {
                    assert!(v > 0.0, "{regime:?} ({m1}, {m2})");
                }
                if form == SeamTractionForm::Squared {
                    let n = check_term_residuals(&t, &s.mesh, &fabric, &cloth, &pattern, &fd());
                    assert_eq!(n, 4);
                }
            }
        }
    }
}

#[test]
fn gradient_is_exact_at_exactly_equal_stretches() {
    let s = strip(2, 2, 0.25);
    let fabric = fabric();
    let t = SeamTraction::new(1.0, SeamTractionForm::Squared).unwrap();
    for scale in [0.75, 1.001953125, 1.25] {
        let cloth: Vec<Vec3> = s
            .cloth_layout
            .iter()
            .map(|p| Vec3::new(scale * p.x, 0.0, scale * p.y))
            .collect();
        check_term_gradient(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout, &fd());
        check_term_residuals(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout, &fd());
    }
}

#[test]
fn bent_garment_gradient_and_residuals() {
    // A strip wrapped round a cylinder with stretch growing along the seam.
    let s = strip(4, 2, 0.05);
    let fabric = fabric();
    let t = SeamTraction::new(1.0, SeamTractionForm::Squared).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let cloth: Vec<Vec3> = s
        .cloth_layout
        .iter()
        .map(|p| {
            let sx = 0.9 + 1.5 * p.x;
            let a = p.x * sx / 0.3;
            let j = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ) * 1e-4;
            Vec3::new(0.3 * a.cos(), 0.3 * a.sin(), (1.0 + 0.4 * p.y) * p.y) + j
        })
        .collect();
    let e = t
        .evaluate(&input(&s, &cloth, &s.pattern_layout, &fabric), None)
        .unwrap();
    assert!(e.per_element.iter().all(|v| v.is_finite()));
    check_term_gradient(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout, &fd());
    check_term_residuals(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout, &fd());
}

#[test]
fn bad_seams_fabric_and_patterns_are_errors() {
    let s = strip(2, 1, 0.1);
    let fabric = fabric();
    let t = SeamTraction::new(1.0, SeamTractionForm::Squared).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let f = deformation(&mut rng, 1.2, 1.1);
    let (cloth, pattern) = place(&mut rng, &s, &f, 0.4, 0.0);
    // A seam whose edge is interior to a panel (a side of two triangles).
    let mut mesh = s.mesh.clone();
    mesh.seams[0].vertices = [vec![0, 4], vec![3, 7]];
    let inp = TermInput {
        mesh: &mesh,
        cloth: &cloth,
        pattern: &pattern,
        fabric: &fabric,
    };
    let err = t.evaluate(&inp, None).unwrap_err();
    assert!(matches!(err, TermError::Invalid { .. }), "{err}");
    // Bad fabric thickness.
    let thin = Fabric {
        thickness: 0.0,
        ..fabric.clone()
    };
    let inp = TermInput {
        mesh: &s.mesh,
        cloth: &cloth,
        pattern: &pattern,
        fabric: &thin,
    };
    assert!(matches!(
        t.evaluate(&inp, None),
        Err(TermError::Invalid { .. })
    ));
    for w in [-1.0, Real::NAN, Real::INFINITY] {
        assert!(matches!(
            SeamTraction::new(w, SeamTractionForm::Linear),
            Err(TermError::Parameter { .. })
        ));
    }
    // A collapsed cloth triangle is fine (slack); an inverted pattern triangle is not.
    let flat = vec![Vec3::zeros(); cloth.len()];
    let inp = TermInput {
        mesh: &s.mesh,
        cloth: &flat,
        pattern: &pattern,
        fabric: &fabric,
    };
    assert_eq!(t.evaluate(&inp, None).unwrap().value, 0.0);
    let mut inverted = pattern.clone();
    let [a, b, _] = s.mesh.pattern_triangles[0];
    inverted.swap(a, b);
    let inp = TermInput {
        mesh: &s.mesh,
        cloth: &cloth,
        pattern: &inverted,
        fabric: &fabric,
    };
    assert!(matches!(
        t.evaluate(&inp, None),
        Err(TermError::Collapsed { .. })
    ));
}

#[test]
fn closed_seam_includes_the_closing_edge() {
    // One triangle per panel, every side sewn to the other panel's triangle: a closed seam of three
    // edges. Both triangles have the same (equibiaxial) strain, so every side sees the same traction.
    let mesh = DesignMesh {
        cloth_triangles: vec![[0, 1, 2], [0, 2, 1]],
        pattern_triangles: vec![[0, 1, 2], [3, 4, 5]],
        pattern_cloth_vertex: vec![0, 1, 2, 0, 2, 1],
        pattern_panel: vec![0, 0, 0, 1, 1, 1],
        panels: vec![],
        seams: vec![crate::design_mesh::DesignSeam {
            panels: [0, 1],
            vertices: [vec![0, 1, 2], vec![3, 5, 4]],
            closed: true,
        }],
        num_cloth_vertices: 3,
    };
    let pattern = vec![
        Vec2::new(0.0, 0.0),
        Vec2::new(0.5, 0.0),
        Vec2::new(0.0, 0.5),
        Vec2::new(1.0, 1.0),
        Vec2::new(1.5, 1.0),
        Vec2::new(1.0, 1.5),
    ];
    let cloth = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.625, 0.0, 0.0),
        Vec3::new(0.0, 0.625, 0.0),
    ];
    let fabric = fabric();
    let t = SeamTraction::new(1.0, SeamTractionForm::Linear).unwrap();
    let inp = TermInput {
        mesh: &mesh,
        cloth: &cloth,
        pattern: &pattern,
        fabric: &fabric,
    };
    let e = t.evaluate(&inp, None).unwrap();
    assert_eq!(e.per_element.len(), 6);
    let tau = E * 0.5625 / (2.0 * (1.0 - NU));
    let perimeter = 2.0 * (0.5 + 0.5 + 0.5 * 2.0_f64.sqrt());
    let expect = THICKNESS * perimeter * tau;
    assert!(
        (e.value - expect).abs() <= 1e-12 * expect,
        "{} {expect}",
        e.value
    );
    check_term_gradient(&t, &mesh, &fabric, &cloth, &pattern, &fd());
}

#[test]
fn orthotropic_gradient_matches_finite_differences_and_reads_the_curve() {
    // Issue 46: the traction across the seam of an orthotropic fabric. Pulled uniaxially across the seam
    // (y) with the course along y, τ = T_course(ε) / λ_y ... in the reference frame: S_yy = T/(λ t).
    let s = strip(2, 1, 0.5);
    let nf = s.mesh.num_triangles();
    let course_y =
        crate::young_laplace_pressure::tests::orthotropic_fabric(vec![Vec2::new(0.0, 1.0); nf]);
    let lin = SeamTraction::new(1.0, SeamTractionForm::Linear).unwrap();
    let cloth: Vec<Vec3> = s
        .cloth_layout
        .iter()
        .map(|p| Vec3::new(p.x, 0.0, 1.3 * p.y))
        .collect();
    let e = lin
        .evaluate(&input(&s, &cloth, &s.pattern_layout, &course_y), None)
        .unwrap();
    // Linear form: Σ l0 d τ over the seam's 2 m of sides, τ = nᵀ S n = T/(λ t) (S = 2 ∂ψ/∂C).
    let expect = 2.0 * 5e-4 * 80.0 / (1.3 * 5e-4);
    assert!(
        (e.value - expect).abs() <= 1e-9 * expect,
        "{} {expect}",
        e.value
    );
    // Finite differences with a grain at random per triangle, over stretched, wrinkled and slack states.
    let s = strip(2, 1, 0.1);
    for form in [SeamTractionForm::Squared, SeamTractionForm::Linear] {
        let t = SeamTraction::new(2.0, form).unwrap();
        for seed in [4, 5, 6] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let course: Vec<Vec2> = (0..s.mesh.num_triangles())
                .map(|_| {
                    let a: Real = rng.random_range(-3.0..3.0);
                    Vec2::new(a.cos(), a.sin())
                })
                .collect();
            let fabric = crate::young_laplace_pressure::tests::orthotropic_fabric(course);
            for (m1, m2) in [(1.3, 1.2), (1.4, 0.8), (1.2, 0.95), (0.95, 0.85)] {
                let f = deformation(&mut rng, Real::sqrt(m1), Real::sqrt(m2));
                let angle = rng.random_range(-3.0..3.0);
                let (cloth, pattern) = place(&mut rng, &s, &f, angle, 2e-5);
                let v = check_term_gradient(&t, &s.mesh, &fabric, &cloth, &pattern, &fd());
                if m1 < 1.0 {
                    assert_eq!(v, 0.0);
                } else {
                    assert!(v > 0.0, "({m1}, {m2})");
                }
                if form == SeamTractionForm::Squared {
                    check_term_residuals(&t, &s.mesh, &fabric, &cloth, &pattern, &fd());
                }
            }
        }
    }
}
