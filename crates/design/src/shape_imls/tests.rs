use super::*;
use crate::math::Vec2;
use crate::term::Fabric;
use crate::test_support::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::finite_difference::FdParams;

fn fd() -> FdParams {
    FdParams {
        step: 1e-7,
        rel_tol: 1e-5,
        abs_tol: 1e-10,
    }
}

fn random_unit(rng: &mut ChaCha8Rng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n = v.norm();
        if n > 0.1 && n < 1.0 {
            return v / n;
        }
    }
}

/// Reference IMLS by brute force over all points (no grid, no rescaling).
fn brute_force(term: &ShapeImls, x: &Vec3) -> Option<Real> {
    let h = term.radius();
    let (mut num, mut den) = (0.0, 0.0);
    for (c, n) in term.points().iter().zip(term.normals()) {
        let r = (x - c).norm();
        if r < h {
            let phi = (1.0 - r * r / (h * h)).powi(4);
            num += n.dot(&(x - c)) * phi;
            den += phi;
        }
    }
    (den > 0.0).then(|| num / den)
}

#[test]
fn plane_target_gives_the_exact_height() {
    // A flat grid in z = 0 (normals +z): every IMLS point's plane is z = 0, so d(x) = z wherever
    // points are in reach, and the far fallback gives the same.
    let n = 8;
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push(Vec3::new(i as Real * 0.1, j as Real * 0.1, 0.0));
        }
    }
    let mut faces = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            faces.push([a, a + 1, a + n + 2]);
            faces.push([a, a + n + 2, a + n + 1]);
        }
    }
    let term = ShapeImls::new(2.5, &positions, &faces, None).unwrap();
    let mean_side = (0.1 + 0.1 + 0.1 * 2.0_f64.sqrt()) / 3.0;
    assert!((term.radius() - 3.0 * mean_side).abs() < 1e-12);
    for x in [
        Vec3::new(0.33, 0.41, 0.05),
        Vec3::new(0.2, 0.2, -0.1),
        Vec3::new(0.5, 0.5, 0.0),
        Vec3::new(5.0, -3.0, 0.7),
        Vec3::new(0.1, 0.1, 3.0),
    ] {
        let (d, g) = term.distance_gradient(&x);
        assert!((d - x.z).abs() < 1e-12, "{x:?}: {d}");
        assert!((g - Vec3::z()).norm() < 1e-12, "{x:?}: {g:?}");
    }
    // The term on a strip floating at known heights.
    let s = strip(2, 1, 0.1);
    let cloth: Vec<Vec3> = s
        .cloth_layout
        .iter()
        .enumerate()
        .map(|(i, p)| Vec3::new(p.x + 0.2, p.y + 0.3, 0.01 * i as Real - 0.03))
        .collect();
    let fabric = fabric();
    let input = TermInput {
        mesh: &s.mesh,
        cloth: &cloth,
        pattern: &s.pattern_layout,
        fabric: &fabric,
    };
    let e = term.evaluate(&input, None).unwrap();
    let expected: Real = cloth.iter().map(|p| 2.5 * p.z * p.z).sum();
    assert!(
        (e.value - expected).abs() <= 1e-14,
        "{} {expected}",
        e.value
    );
    assert_eq!(e.per_element.len(), s.mesh.num_cloth_vertices);
}

#[test]
fn distance_matches_a_brute_force_imls() {
    let target = cylinder_target(0.15, 0.6, 40, 30).unwrap();
    let term = ShapeImls::from_mesh(1.0, &target, None).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for _ in 0..200 {
        let a: Real = rng.random_range(0.0..std::f64::consts::TAU);
        let r = 0.15 + rng.random_range(-1.2..1.2) * term.radius();
        let x = Vec3::new(r * a.cos(), r * a.sin(), rng.random_range(0.0..0.6));
        let d = term.distance(&x);
        if let Some(reference) = brute_force(&term, &x) {
            assert!((d - reference).abs() <= 1e-12, "{d} vs {reference}");
        } else {
            // The fallback: the nearest point's tangent plane.
            let k = (0..term.points().len())
                .min_by(|&i, &j| {
                    (x - term.points()[i])
                        .norm()
                        .total_cmp(&(x - term.points()[j]).norm())
                })
                .unwrap();
            let plane = term.normals()[k].dot(&(x - term.points()[k]));
            assert!((d - plane).abs() <= 1e-12);
        }
    }
}

#[test]
fn distance_approximates_the_signed_distance_to_sphere_and_cylinder() {
    let sphere = sphere_target(0.2, 48, 96).unwrap();
    let cylinder = cylinder_target(0.12, 0.8, 64, 60).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    for (name, mesh) in [("sphere", sphere), ("cylinder", cylinder)] {
        let term = ShapeImls::from_mesh(1.0, &mesh, None).unwrap();
        let h = term.radius();
        let mut worst: Real = 0.0;
        for _ in 0..300 {
            let delta = rng.random_range(-0.6..0.6) * h;
            let (x, exact) = if name == "sphere" {
                let u = random_unit(&mut rng);
                (u * (0.2 + delta), delta)
            } else {
                let a: Real = rng.random_range(0.0..std::f64::consts::TAU);
                let z = rng.random_range(0.2..0.6);
                let r = 0.12 + delta;
                (Vec3::new(r * a.cos(), r * a.sin(), z), delta)
            };
            worst = worst.max((term.distance(&x) - exact).abs() / h);
        }
        assert!(worst < 0.04, "{name}: worst error {worst} h");
    }
}

#[test]
fn far_points_use_the_nearest_tangent_plane() {
    let sphere = sphere_target(0.2, 24, 48).unwrap();
    let term = ShapeImls::from_mesh(1.0, &sphere, Some(0.02)).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    for _ in 0..50 {
        let u = random_unit(&mut rng);
        for offset in [0.05, 0.5, 30.0, -0.1] {
            let x = u * (0.2 + offset);
            let (d, g) = term.distance_gradient(&x);
            assert!(d.is_finite() && g.iter().all(|v| v.is_finite()));
            assert!((g.norm() - 1.0).abs() < 1e-12);
            // Roughly the signed distance: the nearest vertex is close to the radial line.
            assert!(
                (d - offset).abs() < 0.05 * offset.abs().max(0.2),
                "{offset}: {d}"
            );
        }
    }
    // Far beyond any coordinate range of the grid.
    let (d, g) = term.distance_gradient(&Vec3::new(1e300, -1e300, 0.0));
    assert!(d.is_finite() && g.iter().all(|v| v.is_finite()));
    // Its square overflows: an error, not an infinite or NaN value; with weight 0 it is exactly 0.
    let zero = ShapeImls::from_mesh(0.0, &sphere, Some(0.02)).unwrap();
    let s = strip(1, 1, 0.1);
    let mut cloth = vec![Vec3::zeros(); s.mesh.num_cloth_vertices];
    cloth[2] = Vec3::new(1e300, -1e300, 0.0);
    let fabric = fabric();
    let input = TermInput {
        mesh: &s.mesh,
        cloth: &cloth,
        pattern: &s.pattern_layout,
        fabric: &fabric,
    };
    assert!(matches!(
        term.evaluate(&input, None),
        Err(TermError::Invalid { .. })
    ));
    assert_eq!(zero.evaluate(&input, None).unwrap().value, 0.0);
}

/// A strip with cloth vertices scattered around `target`: inside, outside and far.
fn scattered(rng: &mut ChaCha8Rng, s: &Strip, radius: Real, h: Real) -> (Vec<Vec3>, Vec<Vec2>) {
    let n = s.mesh.num_cloth_vertices;
    let offsets = [-0.7, -0.3, 0.0, 0.2, 0.5, 0.9, 1.5, 3.0, -2.0];
    let cloth = (0..n)
        .map(|i| {
            let u = random_unit(rng);
            let o = offsets[i % offsets.len()] + rng.random_range(-0.05..0.05);
            u * (radius + o * h)
        })
        .collect();
    (cloth, s.pattern_layout.clone())
}

#[test]
fn gradient_matches_finite_differences_inside_outside_and_far() {
    let sphere = sphere_target(0.2, 16, 32).unwrap();
    let term = ShapeImls::from_mesh(4.0, &sphere, None).unwrap();
    let s = strip(3, 2, 0.1);
    let fabric = fabric();
    for seed in [21, 22, 23] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (cloth, pattern) = scattered(&mut rng, &s, 0.2, term.radius());
        let v = check_term_gradient(&term, &s.mesh, &fabric, &cloth, &pattern, &fd());
        assert!(v > 0.0);
        let m = check_term_residuals(&term, &s.mesh, &fabric, &cloth, &pattern, &fd());
        assert_eq!(m, s.mesh.num_cloth_vertices);
    }
}

#[test]
fn gradient_is_exact_where_points_leave_the_support() {
    // A coarse cylinder (vertices 0.05 m apart) with h = 0.045 m, probed from the surface out to
    // beyond h: one, several and no IMLS points in reach, many of them close to the support's edge.
    let cylinder = cylinder_target(0.1, 0.3, 12, 6).unwrap();
    let h = 0.045;
    let term = ShapeImls::from_mesh(1.0, &cylinder, Some(h)).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(24);
    let fd = FdParams {
        step: 1e-8,
        rel_tol: 1e-5,
        abs_tol: 1e-9,
    };
    let (mut several, mut edge, mut none) = (0, 0, 0);
    for _ in 0..300 {
        let a: Real = rng.random_range(0.0..std::f64::consts::TAU);
        let r = 0.1 + rng.random_range(0.0..0.06);
        let x = Vec3::new(r * a.cos(), r * a.sin(), rng.random_range(0.05..0.25));
        let dist: Vec<Real> = term.points().iter().map(|c| (x - c).norm()).collect();
        let reach = dist.iter().filter(|&&r| r < h).count();
        several += usize::from(reach >= 2);
        none += usize::from(reach == 0);
        edge += usize::from(reach >= 2 && dist.iter().any(|&r| r < h && r > 0.9 * h));
        let (d, g) = term.distance_gradient(&x);
        let coords = [x.x, x.y, x.z];
        skintight_geometry::finite_difference::check_gradient(
            |v| term.distance(&Vec3::new(v[0], v[1], v[2])),
            &coords,
            g.as_slice(),
            &fd,
        )
        .unwrap_or_else(|m| panic!("at {x:?} (d = {d}, {reach} in reach): {m}"));
    }
    assert!(
        several >= 50 && edge >= 20 && none >= 20,
        "{several} {edge} {none}"
    );
}

#[test]
fn vertex_subset_restricts_value_gradient_and_residuals() {
    let sphere = sphere_target(0.2, 16, 32).unwrap();
    let all = ShapeImls::from_mesh(1.0, &sphere, None).unwrap();
    let subset = all.clone().with_vertices(vec![5, 1, 7]).unwrap();
    let s = strip(3, 1, 0.1);
    let fabric = fabric();
    let mut rng = ChaCha8Rng::seed_from_u64(25);
    let (cloth, pattern) = scattered(&mut rng, &s, 0.2, all.radius());
    let input = TermInput {
        mesh: &s.mesh,
        cloth: &cloth,
        pattern: &pattern,
        fabric: &fabric,
    };
    let e_all = all.evaluate(&input, None).unwrap();
    let mut grad = TermGradient::zeros(&s.mesh);
    let e = subset.evaluate(&input, Some(&mut grad)).unwrap();
    for i in 0..s.mesh.num_cloth_vertices {
        if [5, 1, 7].contains(&i) {
            assert_eq!(e.per_element[i], e_all.per_element[i]);
        } else {
            assert_eq!(e.per_element[i], 0.0);
            assert_eq!(grad.cloth[i], Vec3::zeros());
        }
    }
    assert!(grad.pattern.iter().all(|g| *g == Vec2::zeros()));
    let r = subset.residuals(&input).unwrap().unwrap();
    assert_eq!(r.values.len(), 3);
    assert_eq!(r.cloth_jacobian[0].1, 5);
    check_term_gradient(&subset, &s.mesh, &fabric, &cloth, &pattern, &fd());
    check_term_residuals(&subset, &s.mesh, &fabric, &cloth, &pattern, &fd());
    // Out of range for this garment.
    let big = all.with_vertices(vec![0, 1000]).unwrap();
    assert!(matches!(
        big.evaluate(&input, None),
        Err(TermError::Invalid { .. })
    ));
}

#[test]
fn invalid_parameters_are_rejected() {
    let sphere = sphere_target(0.2, 4, 8).unwrap();
    let (p, f) = (&sphere.positions, &sphere.faces);
    fn err<T: std::fmt::Debug>(r: Result<T, TermError>) {
        assert!(matches!(r.unwrap_err(), TermError::Parameter { .. }));
    }
    err(ShapeImls::new(-1.0, p, f, None));
    err(ShapeImls::new(Real::NAN, p, f, None));
    err(ShapeImls::new(1.0, p, f, Some(0.0)));
    err(ShapeImls::new(1.0, p, f, Some(-0.1)));
    err(ShapeImls::new(1.0, p, f, Some(Real::INFINITY)));
    err(ShapeImls::new(1.0, p, &[], None));
    err(ShapeImls::new(1.0, &[], f, None));
    err(ShapeImls::new(1.0, p, &[[0, 1, 10_000]], None));
    let mut bad = p.clone();
    bad[3].x = Real::NAN;
    err(ShapeImls::new(1.0, &bad, f, None));
    // All vertices coincide: no extent, no normals.
    let point = vec![Vec3::zeros(); 3];
    err(ShapeImls::new(1.0, &point, &[[0, 1, 2]], None));
    err(ShapeImls::new(1.0, &point, &[[0, 1, 2]], Some(0.1)));
    err(ShapeImls::from_mesh(1.0, &sphere, None)
        .unwrap()
        .with_vertices(vec![1, 2, 1]));
    err(cylinder_target(0.0, 1.0, 8, 2));
    err(cylinder_target(0.1, 1.0, 2, 2));
    err(sphere_target(-1.0, 4, 8));
    err(sphere_target(1.0, 1, 8));
    let fabric: Fabric = fabric();
    let s = strip(1, 1, 0.1);
    let term = ShapeImls::from_mesh(1.0, &sphere, None).unwrap();
    let cloth = vec![Vec3::zeros(); s.mesh.num_cloth_vertices - 1];
    let input = TermInput {
        mesh: &s.mesh,
        cloth: &cloth,
        pattern: &s.pattern_layout,
        fabric: &fabric,
    };
    assert!(matches!(
        term.evaluate(&input, None),
        Err(TermError::Invalid { .. })
    ));
}

#[test]
fn procedural_targets_are_closed_or_open_as_documented_and_outward() {
    let sphere = sphere_target(0.3, 10, 20).unwrap();
    let volume: Real = sphere.signed_volume();
    assert!(volume > 0.0 && volume < 4.0 / 3.0 * std::f64::consts::PI * 0.027);
    let term = ShapeImls::from_mesh(1.0, &sphere, None).unwrap();
    for (c, n) in term.points().iter().zip(term.normals()) {
        assert!(n.dot(&c.normalize()) > 0.99);
    }
    let cylinder = cylinder_target(0.1, 0.5, 16, 4).unwrap();
    let term = ShapeImls::from_mesh(1.0, &cylinder, None).unwrap();
    for (c, n) in term.points().iter().zip(term.normals()) {
        let radial = Vec3::new(c.x, c.y, 0.0).normalize();
        assert!(n.dot(&radial) > 0.9);
    }
}
