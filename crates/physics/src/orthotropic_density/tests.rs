use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};

const T: Real = 5e-4;

/// Course soft and J-shaped, wale `ratio` times stiffer (N/m), a soft shear curve.
pub(crate) fn knit(ratio: Real) -> OrthotropicDensity {
    let course = [[0.2, 15.0], [0.5, 45.0], [0.8, 100.0], [1.2, 220.0]];
    let wale: Vec<[Real; 2]> = course.iter().map(|p| [p[0], ratio * p[1]]).collect();
    OrthotropicDensity::new(&course, &wale, &[[0.1, 2.0], [0.3, 8.0]], T).unwrap()
}

fn scale(d: &OrthotropicDensity) -> Real {
    d.course().initial_slope().max(d.wale().initial_slope()) / T
}

fn fd_check(d: &OrthotropicDensity, x: Vec3, what: &str) {
    let sc = scale(d);
    let p = FdParams {
        step: 1e-7,
        rel_tol: 1e-5,
        abs_tol: 1e-7 * sc,
    };
    let der = d.derivatives(&x);
    let xs = [x[0], x[1], x[2]];
    check_gradient(
        |v| d.value(&Vec3::new(v[0], v[1], v[2])),
        &xs,
        der.gradient.as_slice(),
        &p,
    )
    .unwrap_or_else(|e| panic!("{what}: gradient at {x:?} ({:?}): {e}", der.regime));
    let h = der.hessian;
    let flat: Vec<Real> = (0..3)
        .flat_map(|i| (0..3).map(move |j| h[(i, j)]))
        .collect();
    check_jacobian(
        |v| {
            let g = d.derivatives(&Vec3::new(v[0], v[1], v[2])).gradient;
            vec![g[0], g[1], g[2]]
        },
        &xs,
        &flat,
        &p,
    )
    .unwrap_or_else(|e| panic!("{what}: hessian at {x:?} ({:?}): {e}", der.regime));
}

/// `x` of a state with course/wale stretches `(sc, sw)` and fibre-angle cosine term `c`.
fn state(sc: Real, sw: Real, shear: Real) -> Vec3 {
    Vec3::new(sc * sc, sw * sw, shear * sc * sw)
}

#[test]
fn derivatives_match_finite_differences_in_every_regime() {
    let mut rng = ChaCha8Rng::seed_from_u64(46);
    for ratio in [0.1, 1.0, 10.0] {
        let d = knit(ratio);
        let mut seen = [0usize; 3];
        for _ in 0..40 {
            // Taut: both fibres stretched, little shear.
            let x = state(
                rng.random_range(1.05..1.9),
                rng.random_range(1.05..1.6),
                rng.random_range(-0.02..0.02),
            );
            assert_eq!(d.regime(&x), Regime::Taut, "{x:?}");
            fd_check(&d, x, "taut");
            seen[0] += 1;
            // Wrinkled: course stretched, wale shortened (the worn state of a stocking), any shear.
            let x = state(
                rng.random_range(1.05..1.9),
                rng.random_range(0.6..0.97),
                rng.random_range(-0.3..0.3),
            );
            assert_eq!(d.regime(&x), Regime::Wrinkled, "{x:?}");
            fd_check(&d, x, "wrinkled");
            seen[1] += 1;
            // Wrinkled by shear alone: fibres at rest length, sheared.
            let x = state(1.0, 1.0, rng.random_range(0.1..0.5));
            assert_eq!(d.regime(&x), Regime::Wrinkled, "{x:?}");
            fd_check(&d, x, "sheared");
            // Slack: no fibre longer than at rest.
            let x = state(
                rng.random_range(0.5..0.95),
                rng.random_range(0.5..0.95),
                rng.random_range(-0.02..0.02),
            );
            assert_eq!(d.regime(&x), Regime::Slack, "{x:?}");
            let der = d.derivatives(&x);
            assert_eq!(
                (der.value, der.gradient, der.hessian),
                (0.0, Vec3::zeros(), Mat3::zeros())
            );
            fd_check(&d, x, "slack");
            seen[2] += 1;
        }
        assert!(seen.iter().all(|&n| n == 40));
    }
}

#[test]
fn hessian_is_positive_semi_definite_in_every_regime() {
    let mut rng = ChaCha8Rng::seed_from_u64(47);
    for ratio in [0.1, 1.0, 10.0] {
        let d = knit(ratio);
        let sc = scale(&d);
        let mut regimes = std::collections::HashSet::new();
        for _ in 0..2000 {
            let x = state(
                rng.random_range(0.6..1.8),
                rng.random_range(0.6..1.8),
                rng.random_range(-0.4..0.4),
            );
            let der = d.derivatives(&x);
            regimes.insert(der.regime);
            let eig = der.hessian.symmetric_eigenvalues();
            assert!(eig.min() >= -1e-9 * sc, "{x:?} {:?}: {eig:?}", der.regime);
            // The stress is never compressive.
            let s = stress_matrix(&der.gradient);
            assert!(s.symmetric_eigenvalues().min() >= -1e-9 * sc, "{x:?}");
        }
        assert_eq!(regimes.len(), 3);
    }
}

#[test]
fn relaxed_energy_is_the_least_over_wrinkle_strains() {
    // ψ_rel(C) ≤ ψ(C + β m mᵀ) for every sampled wrinkle strain, with equality attained by the solve,
    // and ψ_rel ≤ ψ. The KKT conditions hold: S(C') ⪰ 0 (tested above) with S v = 0.
    let mut rng = ChaCha8Rng::seed_from_u64(48);
    let d = knit(10.0);
    for _ in 0..200 {
        let x = state(
            rng.random_range(0.8..1.6),
            rng.random_range(0.7..1.4),
            rng.random_range(-0.3..0.3),
        );
        let rel = d.value(&x);
        assert!(rel <= d.taut(&x) + 1e-12 * d.taut(&x).abs());
        for _ in 0..50 {
            let phi: Real = rng.random_range(0.0..std::f64::consts::PI);
            let beta: Real = rng.random_range(0.0..0.8);
            let m = Vec2::new(phi.cos(), phi.sin());
            let y = x + d_of(&m) * beta;
            assert!(rel <= d.taut(&y) + 1e-10 * (1.0 + rel.abs()), "{x:?}");
        }
        if d.regime(&x) == Regime::Wrinkled {
            let v = d.wrinkle(&x, &d.taut_at(&x).p);
            let s = stress_matrix(&d.taut_at(&(x + d_of(&v))).p);
            let sv = s * v;
            assert!(
                sv.norm() <= 1e-8 * s.norm() * v.norm(),
                "{x:?}: S v = {sv:?}"
            );
        }
    }
}

fn d_of(v: &Vec2) -> Vec3 {
    super::d(v)
}

#[test]
fn strip_test_returns_the_measured_curve() {
    // Uniaxial course stretch with the wale free: the nominal tension t ∂ψ_rel/∂s is the course curve,
    // whatever the wale does, and the same for the wale.
    let d = knit(3.0);
    for eps in [0.05, 0.2, 0.35, 0.5, 0.8, 1.0, 1.4] {
        let s: Real = 1.0 + eps;
        for sw in [0.7, 0.9, 1.0] {
            let g = d.derivatives(&state(s, sw, 0.0)).gradient;
            let tension = T * 2.0 * s * g[0];
            let want = d.course().tension(eps);
            assert!((tension - want).abs() <= 1e-9 * want, "{eps} {sw}");
            let g = d.derivatives(&state(sw, s, 0.0)).gradient;
            let want = d.wale().tension(eps);
            assert!((T * 2.0 * s * g[1] - want).abs() <= 1e-9 * want);
        }
    }
}

/// Walks from `a` to `b` in `n` steps and checks the C¹ property: trapezoid increments of the energy
/// match to O(step²) and the gradient moves O(step) per step. Returns the regimes crossed.
fn walk(d: &OrthotropicDensity, a: Vec3, b: Vec3, n: usize) -> Vec<Regime> {
    let sc = scale(d);
    let step = (b - a).norm() / n as Real;
    let mut prev = d.derivatives(&a);
    let mut regimes = vec![prev.regime];
    for i in 1..=n {
        let x = a + (b - a) * (i as Real / n as Real);
        let cur = d.derivatives(&x);
        let predicted = 0.5 * (prev.gradient + cur.gradient).dot(&((b - a) / n as Real));
        assert!(
            (cur.value - prev.value - predicted).abs() <= 100.0 * sc * step * step,
            "energy increment at {x:?}"
        );
        assert!(
            (cur.gradient - prev.gradient).norm() <= 50.0 * sc * step,
            "gradient jump at {x:?} ({:?} → {:?})",
            prev.regime,
            cur.regime
        );
        if *regimes.last().unwrap() != cur.regime {
            regimes.push(cur.regime);
        }
        prev = cur;
    }
    regimes
}

#[test]
fn value_and_stress_are_continuous_across_every_transition() {
    for ratio in [0.1, 10.0] {
        let d = knit(ratio);
        // Taut → wrinkled (wale shortening), wrinkled → slack (course relaxing), slack → wrinkled →
        // taut along the diagonal with shear, and wrinkled → taut by shear at fixed stretches.
        let r = walk(&d, state(1.4, 1.1, 0.0), state(1.4, 0.8, 0.05), 4000);
        assert_eq!(r, vec![Regime::Taut, Regime::Wrinkled]);
        let r = walk(&d, state(1.2, 0.8, 0.05), state(0.9, 0.8, 0.05), 4000);
        assert_eq!(r, vec![Regime::Wrinkled, Regime::Slack]);
        let r = walk(&d, state(0.9, 0.9, 0.02), state(1.3, 1.3, 0.02), 4000);
        assert_eq!(r.first(), Some(&Regime::Slack));
        assert_eq!(r.last(), Some(&Regime::Taut));
        let r = walk(&d, state(1.05, 1.03, 0.0), state(1.05, 1.03, 0.6), 4000);
        assert_eq!(r, vec![Regime::Taut, Regime::Wrinkled]);
    }
}

#[test]
fn derivatives_match_finite_differences_next_to_the_boundaries() {
    // Either side of the taut/wrinkled boundary (wale at rest length) and of the wrinkled/slack one
    // (course at rest length), where the wrinkle strain is small.
    let d = knit(10.0);
    for delta in [2e-3, 2e-4] {
        fd_check(&d, state(1.3, 1.0 + delta, 0.01), "taut side");
        fd_check(&d, state(1.3, 1.0 - delta, 0.01), "wrinkled side");
        fd_check(&d, state(1.0 + delta, 0.8, 0.0), "wrinkled near slack");
    }
}

#[test]
fn bad_curves_are_rejected_naming_the_curve() {
    let ok = [[0.2, 15.0], [0.5, 45.0]];
    let e = OrthotropicDensity::new(&ok, &[[0.5, 10.0]], &ok, T).unwrap_err();
    assert!(e.to_string().starts_with("wale curve"), "{e}");
    let e = OrthotropicDensity::new(&ok, &ok, &[[0.2, 5.0], [0.1, 6.0]], T).unwrap_err();
    assert!(e.to_string().starts_with("shear curve"), "{e}");
    let e = OrthotropicDensity::new(&[[0.2, 100.0], [0.6, 101.0], [1.0, 102.0]], &ok, &ok, T)
        .unwrap_err();
    assert!(
        matches!(e, OrthotropicError::NotConvex { key: "course", .. }),
        "{e}"
    );
    assert!(OrthotropicDensity::new(&ok, &ok, &ok, 0.0).is_err());
}
