//! Surface walking (Eq. 147–154) and closest-point projection.

mod common;

use common::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::surface::closest_point::{
    ClosestPointParams, closest_point, closest_point_from,
};
use skintight_geometry::surface::walk::{WalkError, WalkParams, WalkSegment, surface_walk};
use skintight_geometry::{
    LimitSurface, LinearSurface, LoopSurface, Real, SurfaceCoord, Vec2, Vec3,
};

/// Twice-subdivided icosahedron on the unit sphere as a Loop surface (valence-5 vertices isolated).
fn sphere() -> (LoopSurface, Vec<Vec3>) {
    let m = subdivide(&subdivide(&icosahedron()));
    let y: Vec<Vec3> = m.positions.iter().map(|p| p.normalize()).collect();
    (LoopSurface::new(y.len(), &m.faces).unwrap(), y)
}

/// A flat `n × n` grid of unit squares in the plane z = 0.5 x − 0.25 y, each split along its diagonal.
fn flat_grid(n: usize) -> (LinearSurface, Vec<Vec3>) {
    let mut y = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, v) = (i as Real, j as Real);
            y.push(Vec3::new(x, v, 0.5 * x - 0.25 * v));
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i;
    let mut faces = Vec::new();
    for j in 0..n {
        for i in 0..n {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    (LinearSurface::new(y.len(), &faces).unwrap(), y)
}

/// Consecutive pieces of a walk meet at the same 3D point, and every piece lies inside its face.
fn assert_connected(surf: &dyn LimitSurface, y: &[Vec3], trace: &[WalkSegment], tol: Real) {
    for seg in trace {
        for s in [seg.from, seg.to] {
            assert!(
                s.x >= 0.0 && s.y >= 0.0 && s.x + s.y <= 1.0 + 1e-15,
                "{seg:?}"
            );
        }
    }
    for w in trace.windows(2) {
        let a = surf.point(y, w[0].face, w[0].to).unwrap().position;
        let b = surf.point(y, w[1].face, w[1].from).unwrap().position;
        assert!(
            (a - b).norm() < tol,
            "gap {:e} between {:?} and {:?}",
            (a - b).norm(),
            w[0],
            w[1]
        );
    }
}

fn path_length(surf: &dyn LimitSurface, y: &[Vec3], trace: &[WalkSegment]) -> Real {
    let mut len = 0.0;
    for seg in trace {
        let mut prev = surf.point(y, seg.face, seg.from).unwrap().position;
        for k in 1..=16 {
            let s = seg.from + (seg.to - seg.from) * (k as Real / 16.0);
            let q = surf.point(y, seg.face, s).unwrap().position;
            len += (q - prev).norm();
            prev = q;
        }
    }
    len
}

#[test]
fn zero_step_and_step_inside_a_face() {
    let (surf, y) = sphere();
    let start = SurfaceCoord::new(7, 0.2, 0.3);
    let end = surface_walk(
        &surf,
        &y,
        start,
        Vec2::zeros(),
        &WalkParams::default(),
        None,
    )
    .unwrap();
    assert_eq!(end.coord, start);
    assert_eq!(end.crossings, 0);
    let end = surface_walk(
        &surf,
        &y,
        start,
        Vec2::new(0.1, -0.05),
        &WalkParams::default(),
        None,
    )
    .unwrap();
    assert_eq!(end.crossings, 0);
    assert!((end.coord.s - Vec2::new(0.3, 0.25)).norm() < 1e-15);
}

#[test]
fn long_steps_on_a_sphere_stay_connected_with_the_expected_length() {
    let (surf, y) = sphere();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for trial in 0..6 {
        let face = rng.random_range(0..surf.num_faces());
        let start = SurfaceCoord {
            face,
            s: random_s(&mut rng),
        };
        let j = surf.point(&y, face, start.s).unwrap().tangents;
        let a: Real = rng.random_range(0.0..std::f64::consts::TAU);
        let dir = Vec2::new(a.cos(), a.sin());
        // A step of 3D length ≈ 1.5 (about a quarter of a great circle).
        let step = dir * (1.5 / (j * dir).norm());
        let mut trace = Vec::new();
        let end = surface_walk(
            &surf,
            &y,
            start,
            step,
            &WalkParams::default(),
            Some(&mut trace),
        )
        .unwrap();
        assert!(
            end.crossings >= 5,
            "trial {trial}: only {} crossings",
            end.crossings
        );
        assert_eq!(trace.len(), end.crossings + 1);
        assert_eq!(trace.last().unwrap().face, end.coord.face);
        assert_connected(&surf, &y, &trace, 1e-12);
        let len = path_length(&surf, &y, &trace);
        assert!((len - 1.5).abs() < 0.15, "trial {trial}: path length {len}");
        // The end point is a surface point near the sphere.
        let p = surf
            .point(&y, end.coord.face, end.coord.s)
            .unwrap()
            .position;
        assert!((p.norm() - 1.0).abs() < 0.1);
    }
}

#[test]
fn flat_surface_walk_is_exactly_the_straight_line() {
    let (surf, y) = flat_grid(14);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    for _ in 0..20 {
        // Start in the middle cell; |J Δs| ≤ 2 (1 + √2) < 5 cells keeps the walk inside the grid.
        let face = 2 * (6 * 14 + 6) + rng.random_range(0..2);
        let start = SurfaceCoord {
            face,
            s: random_s(&mut rng),
        };
        let p0 = surf.point(&y, face, start.s).unwrap();
        let step = Vec2::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
        let end = surface_walk(&surf, &y, start, step, &WalkParams::default(), None).unwrap();
        let p1 = surf
            .point(&y, end.coord.face, end.coord.s)
            .unwrap()
            .position;
        let expect = p0.position + p0.tangents * step;
        assert!((p1 - expect).norm() < 1e-12, "{:e}", (p1 - expect).norm());
    }
}

#[test]
fn steps_exactly_through_vertices_and_along_edges() {
    // Flat grid: the diagonal of the squares runs through vertices exactly.
    let (surf, y) = flat_grid(8);
    let face = 2 * (2 * 8 + 2); // [ (2,2), (3,2), (3,3) ]
    // From the middle of the diagonal edge 2 (f[2] → f[0], s2 = 0), along the diagonal through the grid
    // vertices (3, 3), (4, 4) or (2, 2), (1, 1); from the face centre straight through the corner f[0].
    let centre = Vec2::new(1.0 / 3.0, 1.0 / 3.0);
    for (s0, step) in [
        (Vec2::new(0.5, 0.0), Vec2::new(-2.0, 0.0)),
        (Vec2::new(0.5, 0.0), Vec2::new(1.4, 0.0)),
        (centre, 2.0 * (Vec2::new(1.0, 0.0) - centre)),
        (centre, 4.0 * (Vec2::new(0.0, 1.0) - centre)),
    ] {
        let start = SurfaceCoord { face, s: s0 };
        let p0 = surf.point(&y, face, s0).unwrap();
        let mut trace = Vec::new();
        let end = surface_walk(
            &surf,
            &y,
            start,
            step,
            &WalkParams::default(),
            Some(&mut trace),
        )
        .unwrap();
        assert!(end.crossings >= 1);
        let p1 = surf
            .point(&y, end.coord.face, end.coord.s)
            .unwrap()
            .position;
        let expect = p0.position + p0.tangents * step;
        assert!(
            (p1 - expect).norm() < 1e-8,
            "step {step:?}: off by {:e}",
            (p1 - expect).norm()
        );
        assert_connected(&surf, &y, &trace, 1e-8);
    }
    // Loop sphere: from a face centre straight through a corner, and along an edge past its end vertex.
    let (surf, y) = sphere();
    for face in [0, 17, 100, 250] {
        let c = Vec2::new(1.0 / 3.0, 1.0 / 3.0);
        let through_corner = 2.0 * (Vec2::new(1.0, 0.0) - c);
        let mut trace = Vec::new();
        let end = surface_walk(
            &surf,
            &y,
            SurfaceCoord { face, s: c },
            through_corner,
            &WalkParams::default(),
            Some(&mut trace),
        )
        .unwrap();
        assert!(end.crossings >= 1);
        assert_connected(&surf, &y, &trace, 1e-12);
        let along_edge = Vec2::new(0.9, -0.9); // on edge 0 (s3 = 0) towards f[0] and beyond
        let mut trace = Vec::new();
        let end = surface_walk(
            &surf,
            &y,
            SurfaceCoord::new(face, 0.5, 0.5),
            along_edge,
            &WalkParams::default(),
            Some(&mut trace),
        )
        .unwrap();
        assert!(end.crossings >= 1);
        assert_connected(&surf, &y, &trace, 1e-12);
        let len = path_length(&surf, &y, &trace);
        let j = surf.point(&y, face, Vec2::new(0.5, 0.5)).unwrap().tangents;
        let expect = (j * along_edge).norm();
        assert!((len - expect).abs() < 0.2 * expect, "{len} vs {expect}");
    }
}

#[test]
fn walking_errors_are_reported() {
    let (surf, y) = flat_grid(4);
    let err = surface_walk(
        &surf,
        &y,
        SurfaceCoord::new(0, 0.3, 0.3),
        Vec2::new(-10.0, 0.0),
        &WalkParams::default(),
        None,
    )
    .unwrap_err();
    assert!(matches!(err, WalkError::Boundary { .. }), "{err}");
    let (surf, y) = sphere();
    let start = SurfaceCoord::new(0, 0.3, 0.3);
    let capped = WalkParams {
        max_crossings: 2,
        ..WalkParams::default()
    };
    let err = surface_walk(&surf, &y, start, Vec2::new(20.0, -5.0), &capped, None).unwrap_err();
    assert!(
        matches!(err, WalkError::TooManyCrossings { crossings: 2, .. }),
        "{err}"
    );
    let err = surface_walk(&surf, &y, start, Vec2::new(Real::NAN, 0.0), &capped, None).unwrap_err();
    assert!(matches!(err, WalkError::NonFiniteStep(..)));
    assert!(
        surface_walk(
            &surf,
            &y,
            SurfaceCoord::new(99999, 0.1, 0.1),
            Vec2::zeros(),
            &capped,
            None
        )
        .is_err()
    );
}

#[test]
fn projection_recovers_points_offset_along_the_normal() {
    let m = subdivide(&subdivide(&icosahedron()));
    let y = jittered(&m.positions, 0.02, 13);
    let surf = LoopSurface::new(y.len(), &m.faces).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let params = ClosestPointParams::default();
    for _ in 0..30 {
        let face = rng.random_range(0..surf.num_faces());
        let s = random_s(&mut rng);
        let p = surf.point(&y, face, s).unwrap();
        let n = p.normal().unwrap();
        let delta: Real = rng.random_range(-0.05..0.05);
        let target = p.position + delta * n;
        let r = closest_point(&surf, &y, target, &params).unwrap();
        assert!(
            (r.distance - delta.abs()).abs() < 1e-9,
            "{} vs {delta}",
            r.distance
        );
        assert!((r.position - p.position).norm() < 1e-8);
        // Warm start from a neighbouring face.
        let nb = surf.topology().twin(face, 0).unwrap().face;
        let r2 = closest_point_from(&surf, &y, target, SurfaceCoord::new(nb, 0.3, 0.3), &params)
            .unwrap();
        assert!((r2.position - p.position).norm() < 1e-8);
    }
    assert!(closest_point(&surf, &y, Vec3::new(Real::NAN, 0.0, 0.0), &params).is_err());
}

#[test]
fn projection_on_the_regular_body() {
    let body = read_obj("regular_1k.obj");
    let surf =
        LoopSurface::with_preprocessing_subdivision(body.positions.len(), &body.faces).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(15);
    let params = ClosestPointParams::default();
    for _ in 0..10 {
        let face = rng.random_range(0..surf.num_faces());
        let s = random_s(&mut rng);
        let p = surf.point(&body.positions, face, s).unwrap();
        let target = p.position + 1e-3 * p.normal().unwrap(); // 1 mm outside
        let r = closest_point(&surf, &body.positions, target, &params).unwrap();
        assert!((r.distance - 1e-3).abs() < 1e-9, "distance {}", r.distance);
        assert!((r.position - p.position).norm() < 1e-8);
    }
}
