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

fn band(name: &str, center: Real, half_width: Real, min: Real, max: Real) -> PressureBand {
    PressureBand {
        name: name.into(),
        center,
        half_width,
        taper: 0.5 * half_width,
        min,
        max,
    }
}

fn random_axis(rng: &mut ChaCha8Rng) -> Vec3 {
    Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .normalize()
}

/// Axis coordinates of the triangle centroids.
fn coordinates(s: &Strip, cloth: &[Vec3], origin: Vec3, axis: Vec3) -> Vec<Real> {
    s.mesh
        .cloth_triangles
        .iter()
        .map(|t| axis.dot(&((cloth[t[0]] + cloth[t[1]] + cloth[t[2]]) / 3.0 - origin)))
        .collect()
}

#[test]
fn gradient_and_residuals_match_finite_differences_in_every_regime_with_triangles_across_band_edges()
 {
    // Three overlapping bands over the strip: one whose window lies below its pressure, one above, one
    // containing it; their edges cut through the triangles (every ω in (0, 1) somewhere), so the bump's
    // derivative is exercised, not only its flat top.
    let s = strip(4, 3, 0.04);
    let fabric = fabric();
    let origin = Vec3::new(0.01, -0.02, 0.03);
    let mut mixed_weights = 0;
    for seed in [3, 4] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for (regime, m1, m2, noise) in regimes() {
            let (cloth, pattern) = bent_strip(&mut rng, &s, 0.3, m1, m2, noise);
            let axis = random_axis(&mut rng);
            let c = coordinates(&s, &cloth, origin, axis);
            let lo = c.iter().copied().fold(Real::INFINITY, Real::min);
            let hi = c.iter().copied().fold(Real::NEG_INFINITY, Real::max);
            let (mid, span) = (0.5 * (lo + hi), hi - lo);
            let shapes = [
                (mid - 0.2 * span, 0.35 * span),
                (mid + 0.15 * span, 0.3 * span),
                (mid, 0.45 * span),
            ];
            for ring in [true, false] {
                // Measure the band pressures first, then place the windows around them.
                let probe = BandPressure::new(
                    1.0,
                    origin,
                    axis,
                    shapes
                        .iter()
                        .map(|&(c, h)| band("probe", c, h, -1e9, 1e9))
                        .collect(),
                )
                .unwrap()
                .with_boundary_ring(ring);
                let measured = probe
                    .band_pressures(&input(&s, &cloth, &pattern, &fabric))
                    .unwrap();
                let p: Vec<Real> = measured.iter().map(|m| m.map_or(0.0, |m| m.0)).collect();
                let bands = vec![
                    band("below", shapes[0].0, shapes[0].1, p[0] - 80.0, p[0] - 30.0),
                    band("above", shapes[1].0, shapes[1].1, p[1] + 40.0, p[1] + 90.0),
                    band("inside", shapes[2].0, shapes[2].1, p[2] - 10.0, p[2] + 10.0),
                ];
                for b in &bands {
                    mixed_weights += c
                        .iter()
                        .filter(|&&x| {
                            let a = (x - b.center).abs();
                            a > b.half_width - b.taper && a < b.half_width + b.taper
                        })
                        .count();
                }
                let term = BandPressure::new(2e-3, origin, axis, bands)
                    .unwrap()
                    .with_boundary_ring(ring);
                let v = check_term_gradient(&term, &s.mesh, &fabric, &cloth, &pattern, &fd());
                if regime != Regime::Slack && measured[0].is_some() && measured[1].is_some() {
                    assert!(v > 0.0, "{regime:?}");
                }
                let n = check_term_residuals(&term, &s.mesh, &fabric, &cloth, &pattern, &fd());
                assert_eq!(n, 3);
            }
        }
    }
    assert!(mixed_weights > 100, "{mixed_weights}");
}

#[test]
fn a_wide_band_averages_the_triangle_pressures_by_rest_area_and_a_band_off_the_cloth_is_empty() {
    let s = strip(4, 3, 0.04);
    let fabric = fabric();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let (cloth, pattern) = bent_strip(&mut rng, &s, 0.25, 1.3, 1.2, 1e-4);
    let inp = input(&s, &cloth, &pattern, &fabric);
    let p = young_laplace_pressures(&inp, BoundaryEdges::Free).unwrap();
    let axis = Vec3::new(0.0, 0.0, 1.0);
    let c = coordinates(&s, &cloth, Vec3::zeros(), axis);
    let lo = c.iter().copied().fold(Real::INFINITY, Real::min);
    let hi = c.iter().copied().fold(Real::NEG_INFINITY, Real::max);
    // A band a thousand times wider than the strip: every ω ≈ 1 (to 1e-6).
    let center = 0.5 * (lo + hi);
    let term = BandPressure::new(
        1.0,
        Vec3::zeros(),
        axis,
        vec![
            band("wide", center, 1000.0, 0.0, 1.0),
            band("off", hi + 10.0, 1.0, 0.0, 1.0),
        ],
    )
    .unwrap()
    .with_boundary_ring(true);
    let got = term.band_pressures(&inp).unwrap();
    let areas: Vec<Real> = (0..s.mesh.num_triangles())
        .map(|f| s.mesh.pattern_area(&pattern, f))
        .collect();
    let total: Real = areas.iter().sum();
    let mean = p.iter().zip(&areas).map(|(p, a)| p * a).sum::<Real>() / total;
    let (pw, dw) = got[0].unwrap();
    assert!((pw - mean).abs() <= 1e-5 * mean.abs(), "{pw} vs {mean}");
    assert!((dw - total).abs() <= 1e-5 * total);
    assert_eq!(got[1], None);
    // The value is w D e² with e the excursion outside the window [0, 1] (the strip bends either way).
    let e = term.evaluate(&inp, None).unwrap();
    let excursion = if pw > 1.0 { pw - 1.0 } else { pw.min(0.0) };
    assert!(excursion.abs() > 10.0);
    let expect = dw * excursion * excursion;
    assert!(
        (e.value - expect).abs() <= 1e-12 * expect,
        "{} {expect}",
        e.value
    );
    let r = term.residuals(&inp).unwrap().unwrap();
    assert_eq!(r.values[1], 0.0);
    // Left out by default: the boundary ring (the strip's interior triangles only).
    let interior = BandPressure::new(
        1.0,
        Vec3::zeros(),
        axis,
        vec![band("wide", center, 1000.0, 0.0, 1.0)],
    )
    .unwrap();
    let (pi, di) = interior.band_pressures(&inp).unwrap()[0].unwrap();
    assert!(di < 0.9 * total && di > 0.0);
    assert!(pi != pw);
    // One side of a plane through the middle: about half the area, and the complement adds up.
    let n = Vec3::new(1.0, 0.0, 0.0);
    let cx: Vec<Real> = s
        .mesh
        .cloth_triangles
        .iter()
        .map(|t| (cloth[t[0]].x + cloth[t[1]].x + cloth[t[2]].x) / 3.0)
        .collect();
    let mut sorted = cx.clone();
    sorted.sort_by(Real::total_cmp);
    let cut = 0.5 * (sorted[sorted.len() / 2 - 1] + sorted[sorted.len() / 2]);
    let half = |n: Vec3, o: Real| {
        BandPressure::new(
            1.0,
            Vec3::zeros(),
            axis,
            vec![band("wide", center, 1000.0, 0.0, 1.0)],
        )
        .unwrap()
        .with_boundary_ring(true)
        .with_side(n, o)
        .unwrap()
        .band_pressures(&inp)
        .unwrap()[0]
            .unwrap()
    };
    let (pa, da) = half(n, cut);
    let (pb, db) = half(-n, -cut);
    assert!((da + db - dw).abs() <= 1e-12 * dw && da > 0.2 * dw && db > 0.2 * dw);
    assert!(((pa * da + pb * db) / dw - pw).abs() <= 1e-9 * pw.abs());
    assert!(
        BandPressure::new(
            1.0,
            Vec3::zeros(),
            axis,
            vec![band("w", 0.0, 1.0, 0.0, 1.0)]
        )
        .unwrap()
        .with_side(Vec3::zeros(), 0.0)
        .is_err()
    );
}

#[test]
fn a_window_containing_the_band_pressure_costs_nothing() {
    let s = strip(4, 3, 0.04);
    let fabric = fabric();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (cloth, pattern) = bent_strip(&mut rng, &s, 0.25, 1.3, 1.2, 1e-4);
    let inp = input(&s, &cloth, &pattern, &fabric);
    let axis = Vec3::new(1.0, 0.0, 0.0);
    let probe = BandPressure::new(
        1.0,
        Vec3::zeros(),
        axis,
        vec![band("x", 0.0, 1000.0, 0.0, 0.0)],
    )
    .unwrap();
    let (p, _) = probe.band_pressures(&inp).unwrap()[0].unwrap();
    let term = BandPressure::new(
        1.0,
        Vec3::zeros(),
        axis,
        vec![band("x", 0.0, 1000.0, p - 1.0, p + 1.0)],
    )
    .unwrap();
    let mut g = TermGradient::zeros(&s.mesh);
    assert_eq!(term.evaluate(&inp, Some(&mut g)).unwrap().value, 0.0);
    assert!(g.cloth.iter().all(|d| *d == Vec3::zeros()));
    assert!(g.pattern.iter().all(|d| *d == Vec2::zeros()));
}

#[test]
fn bad_parameters_are_errors_that_name_the_band() {
    let ok = || band("C", 0.3, 0.025, 1000.0, 2000.0);
    let axis = Vec3::new(0.0, 1.0, 0.0);
    let cases: Vec<(Real, Vec3, Vec3, Vec<PressureBand>, &str)> = vec![
        (-1.0, Vec3::zeros(), axis, vec![ok()], "weight"),
        (
            1.0,
            Vec3::new(Real::NAN, 0.0, 0.0),
            axis,
            vec![ok()],
            "origin",
        ),
        (1.0, Vec3::zeros(), Vec3::zeros(), vec![ok()], "direction"),
        (1.0, Vec3::zeros(), axis, vec![], "at least one band"),
        (
            1.0,
            Vec3::zeros(),
            axis,
            vec![band("C", 0.3, 0.0, 1.0, 2.0)],
            "band 'C'",
        ),
        (
            1.0,
            Vec3::zeros(),
            axis,
            vec![band("D", 0.3, 0.02, 2.0, 1.0)],
            "band 'D'",
        ),
        (
            1.0,
            Vec3::zeros(),
            axis,
            vec![band("F", Real::INFINITY, 0.02, 1.0, 2.0)],
            "band 'F'",
        ),
    ];
    for (w, o, a, bands, needle) in cases {
        let err = BandPressure::new(w, o, a, bands).unwrap_err();
        assert!(matches!(
            err,
            TermError::Parameter {
                term: "band_pressure",
                ..
            }
        ));
        assert!(err.to_string().contains(needle), "{err} lacks {needle}");
    }
    // The axis is normalized.
    let t = BandPressure::new(1.0, Vec3::zeros(), Vec3::new(0.0, 3.0, 0.0), vec![ok()]).unwrap();
    assert_eq!(t.axis().1, Vec3::new(0.0, 1.0, 0.0));
}

/// The band kernel `ω(s)`: 1 inside, ½ at the edge, 0 beyond the taper, continuous, and its derivative
/// matches central differences at seeded random offsets in every regime (inside, both tapers on both
/// sides, outside) and next to the transitions `|s| = h ± w`.
#[test]
fn the_band_weight_and_its_derivative_match_finite_differences_in_every_regime() {
    let (h, w) = (0.025, 0.005);
    assert_eq!(band_weight(0.0, h, w), (1.0, 0.0));
    assert!((band_weight(h, h, w).0 - 0.5).abs() < 1e-15);
    assert!((band_weight(-h, h, w).0 - 0.5).abs() < 1e-15);
    assert_eq!(band_weight(h + w, h, w), (0.0, 0.0));
    assert_eq!(band_weight(-0.1, h, w), (0.0, 0.0));
    // Continuous at both transitions, from either side.
    for edge in [h - w, h + w] {
        for sign in [-1.0, 1.0] {
            let (a, _) = band_weight(sign * (edge - 1e-12), h, w);
            let (b, _) = band_weight(sign * (edge + 1e-12), h, w);
            assert!((a - b).abs() < 1e-9, "jump at {}", sign * edge);
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(47);
    let mut offsets: Vec<Real> = (0..40).map(|_| rng.random_range(-0.04..0.04)).collect();
    for edge in [h - w, h + w] {
        for sign in [-1.0, 1.0] {
            offsets.push(sign * (edge - 1e-5));
            offsets.push(sign * (edge + 1e-5));
        }
    }
    let params = FdParams {
        step: 1e-8,
        rel_tol: 1e-5,
        abs_tol: 1e-6,
    };
    for s in offsets {
        let (_, d) = band_weight(s, h, w);
        skintight_geometry::finite_difference::check_gradient(
            |x| band_weight(x[0], h, w).0,
            &[s],
            &[d],
            &params,
        )
        .unwrap_or_else(|e| panic!("at s = {s}: {e:?}"));
    }
}
