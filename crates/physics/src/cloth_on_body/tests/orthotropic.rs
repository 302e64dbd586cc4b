//! The coupled system with the orthotropic curve law (issue 46): derivatives by central differences.

use super::*;

/// A knit with a soft course and a stiff wale (N/m), about as stiff as the isotropic test cloth.
fn ortho_knit() -> OrthotropicDensity {
    OrthotropicDensity::new(
        &[[0.1, 30.0], [0.3, 100.0], [0.6, 260.0]],
        &[[0.1, 150.0], [0.3, 500.0], [0.6, 1300.0]],
        &[[0.1, 5.0], [0.3, 16.0]],
        1e-4,
    )
    .unwrap()
}

#[test]
fn orthotropic_patch_is_mixed_and_its_derivatives_match_central_differences() {
    for (kind, seed) in [(Kind::Loop, 31), (Kind::Linear, 32)] {
        let (system, state) = sphere_system_law(kind, seed, &MIXED, |i| i == 0, Some(ortho_knit()));
        let regimes: Vec<Regime> = system
            .element_states(&state)
            .unwrap()
            .iter()
            .map(|s| s.regime)
            .collect();
        for r in [Regime::Taut, Regime::Wrinkled, Regime::Slack] {
            assert!(regimes.contains(&r), "{r:?} missing in {regimes:?}");
        }
        let q = system.dofs(&state);
        let (g, h) = dense_hessian(&system, &state);
        check_gradient(
            |x| system.energy(&system.with_dofs(&state, x)).unwrap(),
            &q,
            &g,
            &fd(),
        )
        .unwrap_or_else(|m| panic!("{kind:?} gradient: {m}"));
        check_jacobian(
            |x| {
                let mut out = vec![0.0; x.len()];
                system
                    .gradient(&system.with_dofs(&state, x), &mut out)
                    .unwrap();
                out
            },
            &q,
            &h,
            &fd(),
        )
        .unwrap_or_else(|m| panic!("{kind:?} hessian: {m}"));
        // The pattern derivative the design's adjoint reads.
        let rest: Vec<[Vec2; 3]> = system.elements().iter().map(|e| *e.rest()).collect();
        let flat_rest: Vec<Real> = rest.iter().flatten().flat_map(|p| [p.x, p.y]).collect();
        let g = system.rest_gradient(&state).unwrap();
        let analytic: Vec<Real> = g.iter().flatten().flat_map(|p| [p.x, p.y]).collect();
        check_gradient(
            |r: &[Real]| {
                let mut s = system.clone();
                let unflat: Vec<[Vec2; 3]> = r
                    .chunks(6)
                    .map(|c| [0, 1, 2].map(|k| Vec2::new(c[2 * k], c[2 * k + 1])))
                    .collect();
                s.set_rest(&unflat).unwrap();
                s.energies(&state).unwrap().1
            },
            &flat_rest,
            &analytic,
            &fd(),
        )
        .unwrap_or_else(|m| panic!("{kind:?} rest gradient: {m}"));
    }
}
