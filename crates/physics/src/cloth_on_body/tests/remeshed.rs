//! A remeshed system, and the chart change of a cloth vertex that crossed an edge.

use super::*;

/// A system rebuilt by `remeshed` with its own cloth lists is the system itself (same unknowns, energy,
/// gradient and Hessian); with another cloth it keeps the body and numbers the new cloth's unknowns first.
#[test]
fn remeshed_system_with_the_same_cloth_is_the_same_system() {
    let (system, state) = sphere_system(Kind::Loop, 2, &MIXED);
    let rest: Vec<[Vec2; 3]> = system.elements().iter().map(|e| *e.rest()).collect();
    let pinned: Vec<bool> = (0..system.num_cloth_vertices())
        .map(|c| system.cloth_dof(c).is_none())
        .collect();
    let again = system
        .remeshed(system.triangles().to_vec(), rest.clone(), pinned.clone())
        .unwrap();
    assert_eq!(again.num_dofs(), system.num_dofs());
    assert_eq!(
        again.energy(&state).unwrap(),
        system.energy(&state).unwrap()
    );
    let (h0, g0) = dense_hessian(&system, &state);
    let (h1, g1) = dense_hessian(&again, &state);
    assert_eq!(g0, g1);
    assert_eq!(h0, h1);
    // One triangle fewer, every cloth vertex free: two more unknowns, the body's unchanged.
    let fewer = system
        .remeshed(
            system.triangles()[1..].to_vec(),
            rest[1..].to_vec(),
            vec![false; pinned.len()],
        )
        .unwrap();
    assert_eq!(fewer.num_dofs(), system.num_dofs() + 2);
    assert_eq!(fewer.elements().len(), system.elements().len() - 1);
    // Wrong lists are errors.
    assert!(
        system
            .remeshed(
                system.triangles().to_vec(),
                rest[1..].to_vec(),
                pinned.clone()
            )
            .is_err()
    );
    assert!(
        system
            .remeshed(system.triangles().to_vec(), rest, vec![false; 2])
            .is_err()
    );
}

/// The chart change of a cloth vertex that crossed an edge ([`super::chart_change`]): `A = ∂s_old/∂s_new`
/// solves the least-squares `J A ≈ J'` on both surfaces; on the C¹ Loop surface, at (nearly) the same
/// point, the new chart's tangents are the old ones times `A`, the energy gradient rewritten into the old
/// chart is the old chart's gradient, and a step rewritten into the new chart moves the point the same
/// way. Vertices that stayed in their face are not listed.
#[test]
fn chart_change_rewrites_tangents_gradients_and_steps_of_a_vertex_that_crossed_an_edge() {
    for kind in [Kind::Loop, Kind::Linear] {
        let (system, state) = sphere_system(kind, 5, &MIXED);
        let n = system.num_dofs();
        let gradient = |s: &ClothOnBodyState| {
            let mut g = vec![0.0; n];
            let mut rec = NodeBlockRecorder::default();
            system.hessian(s, &mut g, &mut rec).unwrap();
            g
        };
        let mut checked = 0;
        for c in (0..system.num_cloth_vertices()).filter(|&c| system.cloth_dof(c).is_some()) {
            let dof = system.cloth_dof(c).unwrap();
            // Just inside the edge s1 + s2 = 1 of the vertex's face, then a step of 4e-10 across it.
            let mut before = state.clone();
            before.cloth[c] = SurfaceCoord::new(state.cloth[c].face, 0.5 - 1e-10, 0.5 - 1e-10);
            let mut dq = vec![0.0; n];
            dq[dof] = 2e-10;
            dq[dof + 1] = 2e-10;
            let after = system.step(&before, &dq, &WalkParams::default()).unwrap();
            assert_ne!(
                after.cloth[c].face, before.cloth[c].face,
                "vertex {c} crossed"
            );
            let charts = |s: &ClothOnBodyState| system.charts(&system.frames_at(s).unwrap());
            let (old, new) = (charts(&before), charts(&after));
            let changes = system.chart_changes(&old, &new);
            assert_eq!(changes.len(), 1, "only vertex {c} changed face");
            let change = changes[0];
            assert_eq!(change.dof, dof);
            let a = change.jacobian;
            assert!(
                (a - Mat2::identity()).norm() > 1e-3,
                "the charts of two faces differ: {a}"
            );
            // Tangents: J' = J A.
            let points = |s: &ClothOnBodyState| system.cloth_surface_points(s).unwrap()[c];
            let (j, j_new) = (points(&before).tangents, points(&after).tangents);
            // Least squares in general (the normal equations Jᵀ(J A − J') = 0); on the C¹ Loop surface both
            // charts share the tangent plane at the edge and J' = J A holds.
            let normal = j.transpose() * (j * a - j_new);
            assert!(
                normal.norm() <= 1e-10 * j.norm_squared(),
                "vertex {c}: {normal}"
            );
            if matches!(kind, Kind::Linear) {
                checked += 1;
                continue;
            }
            let err = (j_new - j * a).norm();
            assert!(
                err <= 1e-6 * j_new.norm(),
                "vertex {c}: |J' − J A| = {err:e}"
            );
            // Gradient: g = A⁻ᵀ g' for the vertex's two entries, the rest unchanged.
            let (g_old, mut g) = (gradient(&before), gradient(&after));
            assert!(change.gradient_to_old(&mut g));
            let scale = g_old[dof].hypot(g_old[dof + 1]).max(1e-12);
            for k in [dof, dof + 1] {
                assert!(
                    (g[k] - g_old[k]).abs() <= 1e-5 * scale,
                    "vertex {c}, unknown {k}: {} rewritten, {} in the old chart",
                    g[k],
                    g_old[k]
                );
            }
            // Step: J h = J' h' for h' = A⁻¹ h.
            let mut h = vec![0.0; n];
            (h[dof], h[dof + 1]) = (0.3, -0.7);
            let moved_old = j * Vec2::new(h[dof], h[dof + 1]);
            assert!(change.step_to_new(&mut h));
            let moved_new = j_new * Vec2::new(h[dof], h[dof + 1]);
            assert!((moved_new - moved_old).norm() <= 1e-5 * moved_old.norm());
            checked += 1;
        }
        assert!(checked > 10, "{kind:?}: {checked} vertices");
        // A singular chart change refuses to rewrite rather than produce NaN.
        let singular = ChartChange {
            dof: 0,
            jacobian: Mat2::zeros(),
        };
        let mut v = vec![1.0; n];
        assert!(!singular.gradient_to_old(&mut v) && !singular.step_to_new(&mut v));
        assert!(v.iter().all(|&x| x == 1.0));
    }
}
