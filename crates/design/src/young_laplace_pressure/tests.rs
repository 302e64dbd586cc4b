use super::*;
use crate::design_mesh::DesignMesh;
use crate::mid_edge_shape_operator::BoundaryEdges;
use crate::test_support::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::finite_difference::{FdParams, check_jacobian};
use skintight_physics::Regime;

/// Squared stretches `(μ1, μ2)` of each regime of the density (w = 0.01, ν = 0.3), as in the seam
/// traction tests.
pub(crate) fn regimes() -> Vec<(Regime, Real, Real, Real)> {
    vec![
        (Regime::Taut, 1.3, 1.2, 1e-4),
        (Regime::Taut, 1.25, 1.25, 0.0),
        (Regime::Wrinkled, 1.3, 0.8, 1e-4),
        (Regime::Slack, 0.95, 0.85, 1e-4),
        (Regime::Transition, 1.005, 0.9, 0.0),
        (Regime::Transition, 1.2, 0.947, 0.0),
        (Regime::Transition, 1.004, 1.004, 0.0),
    ]
}

/// The two-panel strip wrapped isometrically round a cylinder of radius `radius` (m) and turned at
/// random, with the pattern stretched so that the cloth has squared principal stretches `(m1, m2)` along
/// random directions; `noise` (m) on every position.
pub(crate) fn bent_strip(
    rng: &mut ChaCha8Rng,
    s: &Strip,
    radius: Real,
    m1: Real,
    m2: Real,
    noise: Real,
) -> (Vec<Vec3>, Vec<Vec2>) {
    let angle: Real = rng.random_range(-3.0..3.0);
    let v = *nalgebra::Rotation2::new(angle).matrix();
    let m = v * crate::math::Mat2::new(m1.sqrt(), 0.0, 0.0, m2.sqrt()) * v.transpose();
    let m_inv = m.try_inverse().unwrap();
    let rot = random_rotation(rng);
    let mut jitter3 = || {
        Vec3::new(
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
        ) * noise
    };
    let cloth: Vec<Vec3> = s
        .cloth_layout
        .iter()
        .map(|p| {
            let a = p.x / radius;
            rot * Vec3::new(radius * a.sin(), p.y, radius * (1.0 - a.cos())) + jitter3()
        })
        .collect();
    let pattern = s
        .pattern_layout
        .iter()
        .map(|p| {
            m_inv * p
                + Vec2::new(rng.random_range(-1.0..=1.0), rng.random_range(-1.0..=1.0)) * noise
        })
        .collect();
    (cloth, pattern)
}

/// Every triangle's pressure at the flattened state `v` with the corrections `phi` held fixed.
fn pressures_at_fixed_phi(
    op: &MidEdgeShapeOperator,
    mesh: &DesignMesh,
    fabric: &Fabric,
    phi: &[Real],
    v: &[Real],
) -> Vec<Real> {
    let (cloth, pattern) = unflatten(v, mesh.num_cloth_vertices);
    let input = TermInput {
        mesh,
        cloth: &cloth,
        pattern: &pattern,
        fabric,
    };
    (0..mesh.num_triangles())
        .map(|f| triangle_pressure(op, &input, phi, f).unwrap().value)
        .collect()
}

#[test]
fn pressure_partials_match_finite_differences_in_every_regime() {
    // (And the value alone, `triangle_pressure_value`, is the value with the partials to the bit.)
    let s = strip(3, 2, 0.05);
    let fabric = fabric();
    let params = FdParams {
        step: 1e-7,
        rel_tol: 2e-5,
        abs_tol: 1e-6,
    };
    for seed in [1, 2, 3] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for (regime, m1, m2, noise) in regimes() {
            let (cloth, pattern) = bent_strip(&mut rng, &s, 0.4, m1, m2, noise);
            let input = TermInput {
                mesh: &s.mesh,
                cloth: &cloth,
                pattern: &pattern,
                fabric: &fabric,
            };
            for f in 0..s.mesh.num_triangles() {
                let x = s.mesh.cloth_triangles[f].map(|v| cloth[v]);
                let r = s.mesh.pattern_triangles[f].map(|v| pattern[v]);
                let st = TriangleStrain::new(&x, &r).unwrap();
                assert_eq!(
                    fabric.density.regime(st.mu[0], st.mu[1]),
                    regime,
                    "({m1}, {m2})"
                );
            }
            let (op, sol) = solve_shape_operator(&input, BoundaryEdges::Free).unwrap();
            // Random corrections: the partials hold for any φ.
            let phi: Vec<Real> = sol
                .phi
                .iter()
                .map(|p| p + rng.random_range(-0.05..0.05))
                .collect();
            let (nc, np) = (s.mesh.num_cloth_vertices, s.mesh.num_pattern_vertices());
            let n = 3 * nc + 2 * np;
            let nf = s.mesh.num_triangles();
            let mut jac = vec![0.0; nf * n];
            let mut any = 0.0_f64;
            // The values alone (the figures' path) are these values to the bit, here and at φ*.
            let at_solution = young_laplace_pressures(&input, BoundaryEdges::Free).unwrap();
            for f in 0..nf {
                let tp = triangle_pressure(&op, &input, &phi, f).unwrap();
                any = any.max(tp.value.abs());
                let alone = triangle_pressure_value(&op, &input, &phi, f).unwrap();
                assert_eq!(
                    alone.to_bits(),
                    tp.value.to_bits(),
                    "{f}: {alone} vs {}",
                    tp.value
                );
                let with = triangle_pressure(&op, &input, &sol.phi, f).unwrap().value;
                assert_eq!(at_solution[f].to_bits(), with.to_bits(), "{f}");
                let o = op.face_opposite(f);
                let t = s.mesh.cloth_triangles[f];
                let verts = [Some(t[0]), Some(t[1]), Some(t[2]), o[0], o[1], o[2]];
                for (slot, v) in verts.iter().enumerate() {
                    if let Some(v) = v {
                        for c in 0..3 {
                            jac[f * n + 3 * v + c] += tp.d_cloth[slot][c];
                        }
                    }
                }
                for (c, v) in s.mesh.pattern_triangles[f].iter().enumerate() {
                    for k in 0..2 {
                        jac[f * n + 3 * nc + 2 * v + k] += tp.d_pattern[c][k];
                    }
                }
                // ∂p/∂φ against a central difference.
                for k in 0..3 {
                    let e = op.face_edges(f)[k];
                    let h = 1e-6;
                    let mut pp = phi.clone();
                    pp[e] += h;
                    let up = triangle_pressure(&op, &input, &pp, f).unwrap().value;
                    pp[e] -= 2.0 * h;
                    let down = triangle_pressure(&op, &input, &pp, f).unwrap().value;
                    let fd = (up - down) / (2.0 * h);
                    assert!(
                        (fd - tp.d_phi[k]).abs() <= 1e-6 * (fd.abs() + 1.0),
                        "{fd} vs {}",
                        tp.d_phi[k]
                    );
                }
            }
            if regime == Regime::Slack {
                assert_eq!(any, 0.0);
            } else {
                assert!(any > 0.0);
            }
            let v = flatten(&cloth, &pattern);
            if let Err(e) = check_jacobian(
                |v| pressures_at_fixed_phi(&op, &s.mesh, &fabric, &phi, v),
                &v,
                &jac,
                &params,
            ) {
                panic!("{regime:?} ({m1}, {m2}) seed {seed}: {e}");
            }
        }
    }
}

/// The cylinder of `crate::test_support::cylinder` as a soup of pattern triangles unrolled from the
/// (angle, z) parameters: circumferential stretch `lc`, axial stretch `lz`.
fn unrolled_cylinder(
    faces: &[[usize; 3]],
    params: &[Vec2],
    radius: Real,
    lc: Real,
    lz: Real,
    num_cloth: usize,
) -> (DesignMesh, Vec<Vec2>) {
    let mut pattern = Vec::new();
    let mut pattern_triangles = Vec::new();
    let mut pattern_cloth_vertex = Vec::new();
    for t in faces {
        let a0 = params[t[0]].x;
        let first = pattern.len();
        for &v in t {
            let mut a = params[v].x;
            while a - a0 > std::f64::consts::PI {
                a -= 2.0 * std::f64::consts::PI;
            }
            while a0 - a > std::f64::consts::PI {
                a += 2.0 * std::f64::consts::PI;
            }
            pattern.push(Vec2::new(radius * a / lc, params[v].y / lz));
        }
        pattern_triangles.push([first, first + 1, first + 2]);
        pattern_cloth_vertex.extend_from_slice(t);
    }
    let mesh = DesignMesh {
        cloth_triangles: faces.to_vec(),
        pattern_triangles,
        pattern_panel: vec![0; pattern.len()],
        pattern_cloth_vertex,
        panels: vec![],
        seams: vec![],
        num_cloth_vertices: num_cloth,
    };
    (mesh, pattern)
}

#[test]
fn cylinder_pressure_is_tension_over_radius_and_converges() {
    // Circumferential stretch 1.2, axial 1 (taut: the axial stress is there, but the axial curvature is
    // zero so it presses nothing). σ_cc = λc 2ψ1 / λz, τ = d σ_cc (N/m), p = τ/R.
    let fabric = fabric();
    let r = 0.05;
    let (lc, lz) = (1.2, 1.0);
    let der = fabric.density.derivatives(lc * lc, lz * lz);
    let tau = fabric.thickness * lc * 2.0 * der.gradient[0] / lz;
    let expect = tau / r;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for jitter in [0.0, 0.15] {
        let mut errors = Vec::new();
        for (around, rows) in [(12, 4), (24, 8), (48, 16)] {
            let height = 2.0 * std::f64::consts::PI * r / around as Real * rows as Real;
            let (faces, x, params) = cylinder(&mut rng, r, height, around, rows, true, jitter);
            let (mesh, pattern) = unrolled_cylinder(&faces, &params, r, lc, lz, x.len());
            let input = TermInput {
                mesh: &mesh,
                cloth: &x,
                pattern: &pattern,
                fabric: &fabric,
            };
            let p = young_laplace_pressures(&input, BoundaryEdges::Free).unwrap();
            let worst = p
                .iter()
                .fold(0.0_f64, |m, p| m.max((p - expect).abs() / expect));
            errors.push(worst);
        }
        // Second order (chords shorten the stretch and the angles by O(h²)): ≥ 3× per halving; the
        // finest mesh within 1% everywhere (0.8% measured with jitter), boundary triangles included.
        for w in errors.windows(2) {
            assert!(
                w[1] < w[0] / 3.0,
                "jitter {jitter}: {errors:?} (expect {expect} Pa)"
            );
        }
        assert!(errors[2] < 1e-2, "jitter {jitter}: {errors:?}");
    }
}

#[test]
fn sphere_pressure_is_twice_tension_over_radius_and_converges() {
    // Isotropic stretch 1.15 on every triangle: σ = S = 2ψ1 I, τ = d 2ψ1, p = 2τ/R.
    let fabric = fabric();
    let r = 0.1;
    let stretch: Real = 1.15;
    let der = fabric
        .density
        .derivatives(stretch * stretch, stretch * stretch);
    let tau = fabric.thickness * 2.0 * der.gradient[0];
    let expect = 2.0 * tau / r;
    let mut errors = Vec::new();
    for level in 1..=4 {
        let (faces, x) = icosphere(r, level);
        let (mesh, pattern) = soup_design_mesh(&faces, &x, stretch);
        let input = TermInput {
            mesh: &mesh,
            cloth: &x,
            pattern: &pattern,
            fabric: &fabric,
        };
        let p = young_laplace_pressures(&input, BoundaryEdges::Free).unwrap();
        errors.push(
            p.iter()
                .fold(0.0_f64, |m, p| m.max((p - expect).abs() / expect)),
        );
        let stats = young_laplace_statistics(&input, BoundaryEdges::Free, false).unwrap();
        assert!((stats.mean_pa - expect).abs() < 0.2 * expect);
        assert_eq!(stats.negative_area_fraction, 0.0);
        assert!(stats.negative_area_fraction.is_sign_positive());
    }
    for w in errors.windows(2) {
        assert!(w[1] < w[0] / 1.5, "{errors:?} (expect {expect} Pa)");
    }
    assert!(errors[3] < 0.02, "{errors:?}");
}

#[test]
fn cauchy_stress_and_statistics() {
    // Uniaxial stretch 1.25 along x in a plane, wrinkled across: σ = λ S_xx / λ_y e_x e_xᵀ... with λ_y
    // = 0.8: σ_xx = (1.25²) S_xx / (1.25 · 0.8).
    let fabric = fabric();
    let rest = [
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(0.0, 1.0),
    ];
    let x = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.25, 0.0, 0.0),
        Vec3::new(0.0, 0.8, 0.0),
    ];
    let s = cauchy_stress(&fabric, 0, &x, &rest).unwrap();
    let der = fabric.density.derivatives(1.5625, 0.64);
    let expect = 1.5625 * 2.0 * der.gradient[0] / (1.25 * 0.8);
    assert!((s[(0, 0)] - expect).abs() < 1e-9 * expect);
    assert!(s[(1, 1)].abs() < 1e-9 * expect && s[(2, 2)] == 0.0);
    let cw = [rest[0], rest[2], rest[1]];
    assert!(cauchy_stress(&fabric, 0, &x, &cw).is_none());
    let st = PressureStatistics::new(&[100.0, 300.0, -50.0], &[1.0, 1.0, 2.0]).unwrap();
    assert!((st.mean_pa - 75.0).abs() < 1e-12);
    let var = (25.0 * 25.0 + 225.0 * 225.0 + 2.0 * 125.0 * 125.0) / 4.0;
    assert!((st.std_pa - Real::sqrt(var)).abs() < 1e-9);
    assert!((st.spread - st.std_pa / 75.0).abs() < 1e-12);
    assert_eq!(
        (st.min_pa, st.max_pa, st.negative_area_fraction),
        (-50.0, 300.0, 0.5)
    );
    assert!(PressureStatistics::new(&[1.0], &[0.0]).is_none());
    assert!(PressureStatistics::new(&[Real::NAN], &[1.0]).is_none());
    assert!(PressureStatistics::new(&[1.0, 2.0], &[1.0]).is_none());
}

/// An orthotropic test fabric (issue 46): course softer than the wale, a soft shear; 0.5 mm.
pub(crate) fn orthotropic_fabric(course: Vec<Vec2>) -> Fabric {
    let law = skintight_physics::orthotropic_density::OrthotropicDensity::new(
        &[[0.1, 20.0], [0.3, 80.0], [0.6, 250.0]],
        &[[0.1, 60.0], [0.3, 240.0], [0.6, 750.0]],
        &[[0.05, 1.0], [0.2, 6.0], [0.4, 15.0]],
        5e-4,
    )
    .unwrap();
    Fabric {
        orthotropic: Some(law),
        course,
        ..Fabric::isotropic(fabric().density, 5e-4)
    }
}

#[test]
fn orthotropic_cylinder_pressure_is_the_curve_tension_over_radius() {
    // Issue 46's hoop law on the design's side: with the course around the cylinder (pattern x) at
    // stretch 1.3 and the wale along it at 1, σ_cc d = T_course(0.3) and p = T/R; with the grain turned
    // by 90° the wale runs around and p = T_wale(0.3)/R.
    let r = 0.05;
    let (lc, lz) = (1.3, 1.0);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (around, rows) = (48, 16);
    let height = 2.0 * std::f64::consts::PI * r / around as Real * rows as Real;
    let (faces, x, params) = cylinder(&mut rng, r, height, around, rows, true, 0.0);
    let (mesh, pattern) = unrolled_cylinder(&faces, &params, r, lc, lz, x.len());
    let nf = faces.len();
    for (course, tension) in [
        (Vec2::new(1.0, 0.0), 80.0),
        (Vec2::new(0.0, 1.0), 240.0),
        (Vec2::new(0.0, -1.0), 240.0),
    ] {
        let fabric = orthotropic_fabric(vec![course; nf]);
        let input = TermInput {
            mesh: &mesh,
            cloth: &x,
            pattern: &pattern,
            fabric: &fabric,
        };
        let expect = tension / r;
        let p = young_laplace_pressures(&input, BoundaryEdges::Free).unwrap();
        let worst = p
            .iter()
            .fold(0.0_f64, |m, p| m.max((p - expect).abs() / expect));
        assert!(
            worst < 1e-2,
            "course {course:?}: {worst} (expect {expect} Pa)"
        );
    }
}

#[test]
fn orthotropic_pressure_partials_match_finite_differences_in_every_regime() {
    let s = strip(3, 2, 0.05);
    let nf = s.mesh.num_triangles();
    let params = FdParams {
        step: 1e-7,
        rel_tol: 2e-5,
        abs_tol: 1e-6,
    };
    let mut seen = std::collections::BTreeSet::new();
    for seed in [1, 2, 3] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // A grain at random per triangle.
        let course: Vec<Vec2> = (0..nf)
            .map(|_| {
                let a: Real = rng.random_range(-3.0..3.0);
                Vec2::new(a.cos(), a.sin())
            })
            .collect();
        let fabric = orthotropic_fabric(course);
        let law = fabric.orthotropic.clone().unwrap();
        for (m1, m2) in [
            (1.3, 1.2),
            (1.4, 0.8),
            (1.2, 0.95),
            (0.95, 0.85),
            (1.1, 1.1),
        ] {
            let (cloth, pattern) = bent_strip(&mut rng, &s, 0.4, m1, m2, 1e-4);
            let input = TermInput {
                mesh: &s.mesh,
                cloth: &cloth,
                pattern: &pattern,
                fabric: &fabric,
            };
            for f in 0..nf {
                let x = s.mesh.cloth_triangles[f].map(|v| cloth[v]);
                let r = s.mesh.pattern_triangles[f].map(|v| pattern[v]);
                let st = TriangleStrain::new(&x, &r).unwrap();
                let (c, w) = (
                    fabric.course_of(f),
                    Vec2::new(-fabric.course_of(f).y, fabric.course_of(f).x),
                );
                let voigt = Vec3::new(c.dot(&(st.c * c)), w.dot(&(st.c * w)), c.dot(&(st.c * w)));
                seen.insert(format!("{:?}", law.regime(&voigt)));
            }
            let (op, sol) = solve_shape_operator(&input, BoundaryEdges::Free).unwrap();
            let phi: Vec<Real> = sol
                .phi
                .iter()
                .map(|p| p + rng.random_range(-0.05..0.05))
                .collect();
            let (nc, np) = (s.mesh.num_cloth_vertices, s.mesh.num_pattern_vertices());
            let n = 3 * nc + 2 * np;
            let mut jac = vec![0.0; nf * n];
            for f in 0..nf {
                let tp = triangle_pressure(&op, &input, &phi, f).unwrap();
                let alone = triangle_pressure_value(&op, &input, &phi, f).unwrap();
                assert!((alone - tp.value).abs() <= 1e-12 * (1.0 + tp.value.abs()));
                let o = op.face_opposite(f);
                let t = s.mesh.cloth_triangles[f];
                let verts = [Some(t[0]), Some(t[1]), Some(t[2]), o[0], o[1], o[2]];
                for (slot, v) in verts.iter().enumerate() {
                    if let Some(v) = v {
                        for c in 0..3 {
                            jac[f * n + 3 * v + c] += tp.d_cloth[slot][c];
                        }
                    }
                }
                for (c, v) in s.mesh.pattern_triangles[f].iter().enumerate() {
                    for k in 0..2 {
                        jac[f * n + 3 * nc + 2 * v + k] += tp.d_pattern[c][k];
                    }
                }
                for k in 0..3 {
                    let e = op.face_edges(f)[k];
                    let h = 1e-6;
                    let mut pp = phi.clone();
                    pp[e] += h;
                    let up = triangle_pressure(&op, &input, &pp, f).unwrap().value;
                    pp[e] -= 2.0 * h;
                    let down = triangle_pressure(&op, &input, &pp, f).unwrap().value;
                    let fd = (up - down) / (2.0 * h);
                    assert!(
                        (fd - tp.d_phi[k]).abs() <= 1e-6 * (fd.abs() + 1.0),
                        "{fd} vs {}",
                        tp.d_phi[k]
                    );
                }
            }
            let v = flatten(&cloth, &pattern);
            if let Err(e) = check_jacobian(
                |v| pressures_at_fixed_phi(&op, &s.mesh, &fabric, &phi, v),
                &v,
                &jac,
                &params,
            ) {
                panic!("({m1}, {m2}) seed {seed}: {e}");
            }
        }
    }
    for regime in ["Taut", "Wrinkled", "Slack"] {
        assert!(seen.contains(regime), "{regime} never reached: {seen:?}");
    }
}
