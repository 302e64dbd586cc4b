//! Finite-difference tests of the coupled cloth-on-body energy (Eq. 155–157) on the Loop and the linear
//! surface, with cloth triangles in every tension-field regime.

use super::*;
use crate::math::Mat2;
use crate::node_block_assembly::{HessianTriplets, NodeBlockAssembler, NodeBlockRecorder};
use crate::tension_field_density::Regime;
use faer::sparse::SparseColMat;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::body::procedural_body::{Core, SphereParams, fix_core, solid_sphere};
use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};
use skintight_geometry::surface::walk::WalkParams;
use skintight_geometry::{LinearSurface, LoopSurface, outer_boundary_surface};

/// Which surface the cloth lies on.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Kind {
    Loop,
    Linear,
}

/// A small sphere body with a cloth patch made of one cloth vertex per surface face around a few body
/// vertices, triangles fanning around them, and pattern shapes scaled so that the triangles fall in
/// different regimes (taut, wrinkled, slack).
pub(crate) fn sphere_system(
    kind: Kind,
    seed: u64,
    scales: &[(Real, Real)],
) -> (ClothOnBody, ClothOnBodyState) {
    sphere_system_pinned(kind, seed, scales, |i| i == 0)
}

/// [`sphere_system`] with the cloth vertices `pin(i)` pinned (instead of the first alone).
pub(crate) fn sphere_system_pinned(
    kind: Kind,
    seed: u64,
    scales: &[(Real, Real)],
    pin: impl Fn(usize) -> bool,
) -> (ClothOnBody, ClothOnBodyState) {
    sphere_system_law(kind, seed, scales, pin, None)
}

/// [`sphere_system_pinned`] with an orthotropic law (and a random grain per triangle) when `law` is
/// given.
pub(crate) fn sphere_system_law(
    kind: Kind,
    seed: u64,
    scales: &[(Real, Real)],
    pin: impl Fn(usize) -> bool,
    law: Option<OrthotropicDensity>,
) -> (ClothOnBody, ClothOnBodyState) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut tet = solid_sphere(&SphereParams {
        radius: 0.1,
        resolution: 3,
    })
    .unwrap();
    fix_core(&mut tet, Core::Centre, 0.5).unwrap();
    let boundary = outer_boundary_surface(&tet).unwrap();
    let nv = boundary.mesh.num_vertices();
    let surface: SharedSurface = match kind {
        Kind::Loop => Arc::new(
            LoopSurface::new(nv, &boundary.mesh.faces)
                .or_else(|_| LoopSurface::with_preprocessing_subdivision(nv, &boundary.mesh.faces))
                .unwrap(),
        ),
        Kind::Linear => Arc::new(LinearSurface::new(nv, &boundary.mesh.faces).unwrap()),
    };
    let topo = surface.topology().clone();
    // Cloth vertices: one in each face around two surface vertices; a pinned one is the first.
    let mut cloth = Vec::new();
    let mut triangles = Vec::new();
    let mut vertex_of_face = std::collections::HashMap::new();
    let centres = [0usize, topo.faces()[topo.num_faces() / 2][0]];
    for &centre in &centres {
        let fan: Vec<usize> = topo.fan(centre).iter().map(|c| c.face).collect();
        let ids: Vec<usize> = fan
            .iter()
            .map(|&f| {
                *vertex_of_face.entry(f).or_insert_with(|| {
                    let s1 = rng.random_range(0.2..0.45);
                    let s2 = rng.random_range(0.2..0.45);
                    cloth.push(SurfaceCoord::new(f, s1, s2));
                    cloth.len() - 1
                })
            })
            .collect();
        for j in 1..ids.len() - 1 {
            triangles.push([ids[0], ids[j], ids[j + 1]]);
        }
    }
    let pinned: Vec<bool> = (0..cloth.len()).map(pin).collect();
    // Body state: rest plus a small random displacement of the free vertices.
    let mut body_state = tet.positions.clone();
    for (p, &fixed) in body_state.iter_mut().zip(&tet.fixed) {
        if !fixed {
            *p += Vec3::from_fn(|_, _| rng.random_range(-2e-3..2e-3));
        }
    }
    // Pattern shapes: each triangle's deformed shape in its own plane frame, scaled by (a, b) along a
    // random direction, so the deformed/rest stretch is (1/a, 1/b).
    let control: Vec<Vec3> = boundary.tet_vertex.iter().map(|&v| body_state[v]).collect();
    let pos: Vec<Vec3> = cloth
        .iter()
        .map(|c| surface.point(&control, c.face, c.s).unwrap().position)
        .collect();
    let rest: Vec<[Vec2; 3]> = triangles
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            let [p0, p1, p2] = tri.map(|i| pos[i]);
            let e1 = (p1 - p0).normalize();
            let n = (p1 - p0).cross(&(p2 - p0)).normalize();
            let e2 = n.cross(&e1);
            let flat = [p0, p1, p2].map(|p| Vec2::new((p - p0).dot(&e1), (p - p0).dot(&e2)));
            let (a, b) = scales[t % scales.len()];
            let theta: Real = rng.random_range(0.0..3.0);
            let (c, s) = (theta.cos(), theta.sin());
            let rot = nalgebra::Matrix2::new(c, -s, s, c);
            let m = rot * nalgebra::Matrix2::new(a, 0.0, 0.0, b) * rot.transpose();
            flat.map(|p| m * p)
        })
        .collect();
    let triangles_len = triangles.len();
    let system = ClothOnBody::new(
        BodySpec {
            rest_positions: tet.positions.clone(),
            tets: tet.tets.clone(),
            fixed: tet.fixed.clone(),
            material: NeoHookeanParams::default(),
            surface,
            surface_body_vertex: boundary.tet_vertex.clone(),
        },
        ClothSpec {
            triangles,
            rest,
            youngs_modulus: 5.4e6,
            poisson_ratio: 0.33,
            thickness: 1e-4,
            tension_field: TensionFieldParams::default(),
            pinned,
            grain: if law.is_some() {
                (0..triangles_len).map(|t| 0.7 * t as Real).collect()
            } else {
                Vec::new()
            },
            orthotropic: law,
        },
    )
    .unwrap();
    let state = ClothOnBodyState {
        cloth,
        body: body_state,
    };
    (system, state)
}

/// Rest scales giving taut (shrunk pattern), wrinkled (shrunk one way, loose the other) and slack
/// (enlarged) triangles.
pub(crate) const MIXED: [(Real, Real); 3] = [(0.9, 0.93), (0.9, 1.2), (1.15, 1.2)];

fn fd() -> FdParams {
    FdParams {
        step: 1e-6,
        rel_tol: 1e-5,
        abs_tol: 0.0,
    }
}

fn dense_hessian(system: &ClothOnBody, state: &ClothOnBodyState) -> (Vec<Real>, Vec<Real>) {
    let n = system.num_dofs();
    let mut triplets = HessianTriplets::new(n);
    let mut g = vec![0.0; n];
    system.hessian(state, &mut g, &mut triplets).unwrap();
    (g, triplets.to_dense())
}

#[test]
fn regimes_of_the_test_patch_are_mixed() {
    let (system, state) = sphere_system(Kind::Loop, 1, &MIXED);
    let regimes: Vec<Regime> = system
        .element_states(&state)
        .unwrap()
        .iter()
        .map(|s| s.regime)
        .collect();
    for r in [Regime::Taut, Regime::Wrinkled, Regime::Slack] {
        assert!(regimes.contains(&r), "{r:?} missing in {regimes:?}");
    }
}

#[test]
fn coupled_gradient_matches_central_differences_on_both_surfaces() {
    for kind in [Kind::Loop, Kind::Linear] {
        for seed in 1..4 {
            let (system, state) = sphere_system(kind, seed, &MIXED);
            let q = system.dofs(&state);
            let mut g = vec![0.0; system.num_dofs()];
            let e = system.gradient(&state, &mut g).unwrap();
            assert!((e - system.energy(&state).unwrap()).abs() <= 1e-12 * e.abs());
            check_gradient(
                |x| system.energy(&system.with_dofs(&state, x)).unwrap(),
                &q,
                &g,
                &fd(),
            )
            .unwrap_or_else(|m| panic!("{kind:?} seed {seed}: {m}"));
        }
    }
}

#[test]
fn coupled_hessian_matches_central_differences_on_both_surfaces() {
    for kind in [Kind::Loop, Kind::Linear] {
        for seed in 1..4 {
            let (system, state) = sphere_system(kind, seed, &MIXED);
            let q = system.dofs(&state);
            let (g, h) = dense_hessian(&system, &state);
            let mut g2 = vec![0.0; system.num_dofs()];
            system.gradient(&state, &mut g2).unwrap();
            for (a, b) in g.iter().zip(&g2) {
                assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()));
            }
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
            .unwrap_or_else(|m| panic!("{kind:?} seed {seed}: {m}"));
        }
    }
}

/// The sliding block alone (body held): pins the second-derivative term of Eq. 156 — without it the
/// s–s blocks are wrong wherever the cloth pulls, which the full check above could hide behind the larger
/// body entries.
#[test]
fn surface_coordinate_block_includes_the_surface_curvature_term() {
    let (system, state) = sphere_system(Kind::Loop, 7, &[(0.85, 0.85)]);
    let q = system.dofs(&state);
    let (_, h) = dense_hessian(&system, &state);
    let n = system.num_dofs();
    let s_dofs: Vec<usize> = (0..system.num_cloth_vertices())
        .filter_map(|c| system.cloth_dof(c))
        .flat_map(|d| [d, d + 1])
        .collect();
    let sub = |x: &[Real]| -> Vec<Real> {
        let mut full = q.clone();
        for (k, &d) in s_dofs.iter().enumerate() {
            full[d] = x[k];
        }
        let mut out = vec![0.0; n];
        system
            .gradient(&system.with_dofs(&state, &full), &mut out)
            .unwrap();
        s_dofs.iter().map(|&d| out[d]).collect()
    };
    let x0: Vec<Real> = s_dofs.iter().map(|&d| q[d]).collect();
    let jac: Vec<Real> = s_dofs
        .iter()
        .flat_map(|&r| s_dofs.iter().map(move |&c| (r, c)))
        .map(|(r, c)| h[r * n + c])
        .collect();
    check_jacobian(sub, &x0, &jac, &fd()).unwrap();
}

#[test]
fn node_block_assembly_equals_triplets_and_detects_face_changes() {
    let (system, state) = sphere_system(Kind::Loop, 3, &MIXED);
    let n = system.num_dofs();
    let mut recorder = NodeBlockRecorder::default();
    let mut g = vec![0.0; n];
    system.hessian(&state, &mut g, &mut recorder).unwrap();
    let mut asm = NodeBlockAssembler::new(n, system.nodes(), &recorder);
    asm.begin();
    system.hessian(&state, &mut g, &mut asm).unwrap();
    assert!(asm.finish().is_ok());
    let (_, reference) = dense_hessian(&system, &state);
    for (a, b) in asm.to_dense().iter().zip(&reference) {
        assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()));
    }
    // Move an unpinned cloth vertex to a face on the far side of the body, whose stencil shares no vertex
    // with the others: the pattern no longer fits and the assembler says so. (A move into a neighbouring
    // face may keep the element's node list, and then the pattern rightly still fits.)
    let mut moved = state.clone();
    let c = (0..system.num_cloth_vertices())
        .find(|&c| system.cloth_dof(c).is_some())
        .unwrap();
    let points = system.cloth_surface_points(&state).unwrap();
    let control = system.control_positions(&state.body);
    let surface = system.surface();
    let far = (0..surface.num_faces())
        .max_by(|&a, &b| {
            let da = (surface
                .point(&control, a, Vec2::new(0.3, 0.3))
                .unwrap()
                .position
                - points[c].position)
                .norm();
            let db = (surface
                .point(&control, b, Vec2::new(0.3, 0.3))
                .unwrap()
                .position
                - points[c].position)
                .norm();
            da.total_cmp(&db)
        })
        .unwrap();
    moved.cloth[c] = SurfaceCoord::new(far, 0.3, 0.3);
    asm.begin();
    system.hessian(&moved, &mut g, &mut asm).unwrap();
    assert!(asm.finish().is_err());
}

#[test]
fn pinned_vertices_and_fixed_body_vertices_carry_no_unknowns() {
    let (system, state) = sphere_system(Kind::Linear, 2, &MIXED);
    let free_cloth = (0..system.num_cloth_vertices())
        .filter(|&c| system.cloth_dof(c).is_some())
        .count();
    let free_body = (0..system.num_body_vertices())
        .filter(|&v| system.body_dof(v).is_some())
        .count();
    assert_eq!(free_cloth, system.num_cloth_vertices() - 1);
    assert_eq!(system.num_dofs(), 2 * free_cloth + 3 * free_body);
    // Round trip of the DOF vector.
    let q = system.dofs(&state);
    assert_eq!(system.with_dofs(&state, &q), state);
}

#[test]
fn an_inverted_body_element_has_infinite_energy_and_no_gradient() {
    let (system, mut state) = sphere_system(Kind::Linear, 4, &MIXED);
    // Push a free body vertex through the opposite face of one of its tets.
    let v = (0..system.num_body_vertices())
        .find(|&v| system.body_dof(v).is_some())
        .unwrap();
    state.body[v] = -state.body[v] * 3.0;
    assert_eq!(system.energy(&state).unwrap(), Real::INFINITY);
    let mut g = vec![0.0; system.num_dofs()];
    assert!(matches!(
        system.gradient(&state, &mut g),
        Err(ClothOnBodyError::InvertedBody { .. })
    ));
}

#[test]
fn normal_forces_press_a_tight_patch_onto_a_convex_body() {
    let (system, state) = sphere_system(Kind::Loop, 5, &[(0.85, 0.85)]);
    let pressures = system.element_pressures(&state).unwrap();
    assert!(pressures.iter().all(|&p| p > 0.0), "{pressures:?}");
    let forces = system.cloth_normal_forces(&state).unwrap();
    assert!(forces.iter().sum::<Real>() > 0.0);
}

#[test]
fn parallel_assembly_equals_the_sequential_pass_for_any_thread_count() {
    for kind in [Kind::Loop, Kind::Linear] {
        let (system, state) = sphere_system(kind, 5, &MIXED);
        let n = system.num_dofs();
        let mut recorder = NodeBlockRecorder::default();
        let mut g_seq = vec![0.0; n];
        let eval_seq = system.hessian(&state, &mut g_seq, &mut recorder).unwrap();
        let mut asm = NodeBlockAssembler::new(n, system.nodes(), &recorder);
        asm.begin();
        system.hessian(&state, &mut g_seq, &mut asm).unwrap();
        let reference = asm.to_dense();
        let frames = system.frames_at(&state).unwrap();
        for threads in [1, 2, 3, 7] {
            let mut g = vec![1.0; n];
            asm.begin();
            let eval = system
                .hessian_parallel(
                    &state,
                    &frames,
                    &mut g,
                    &mut asm,
                    threads,
                    HessianForm::Coordinate,
                )
                .unwrap();
            assert!(asm.finish().is_ok());
            assert_eq!(asm.slow_blocks(), 0);
            let scale = reference.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for (a, b) in asm.to_dense().iter().zip(&reference) {
                assert!(
                    (a - b).abs() <= 1e-12 * scale,
                    "{threads} threads: {a} vs {b}"
                );
            }
            let gscale = g_seq.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for (a, b) in g.iter().zip(&g_seq) {
                assert!((a - b).abs() <= 1e-12 * gscale);
            }
            assert!((eval.energy - eval_seq.energy).abs() <= 1e-12 * eval_seq.energy.abs());
            assert!(
                (eval.cloth_force_norm - eval_seq.cloth_force_norm).abs()
                    <= 1e-12 * eval_seq.cloth_force_norm
            );
        }
    }
}

#[test]
fn reserved_pattern_survives_a_cloth_vertex_sliding_into_a_neighbouring_face() {
    let (system, state) = sphere_system(Kind::Loop, 3, &MIXED);
    let n = system.num_dofs();
    let mut recorder = NodeBlockRecorder::default();
    let mut g = vec![0.0; n];
    system.hessian(&state, &mut g, &mut recorder).unwrap();
    let mut reserve = NodeBlockRecorder::default();
    system.reserve_structure(&state, &mut reserve);
    let plain = NodeBlockAssembler::new(n, system.nodes(), &recorder);
    let asm = NodeBlockAssembler::with_reserve(n, system.nodes(), &recorder, Some(&reserve), None);
    assert!(asm.nnz() > plain.nnz(), "the reserve adds pairs");
    // Every move of one free cloth vertex across an edge of its face fits the reserved pattern, and some
    // of them would not have fitted the plain one.
    let topology = system.surface().topology().clone();
    let (mut moves, mut outside_plain) = (0, 0);
    for c in (0..system.num_cloth_vertices()).filter(|&c| system.cloth_dof(c).is_some()) {
        let face = state.cloth[c].face;
        for e in 0..3 {
            let Some(twin) = topology.twin(face, e) else {
                continue;
            };
            let mut moved = state.clone();
            moved.cloth[c] = SurfaceCoord::new(twin.face, 0.3, 0.3);
            let frames = system.frames_at(&moved).unwrap();
            let mut rec = NodeBlockRecorder::default();
            system.structure(&frames, &mut rec);
            assert!(
                asm.fit(&rec).is_some(),
                "vertex {c} into face {}",
                twin.face
            );
            moves += 1;
            outside_plain += usize::from(plain.fit(&rec).is_none());
        }
    }
    assert!(
        moves > 0 && outside_plain > 0,
        "{moves} moves, {outside_plain} outside"
    );
}

/// Two edge steps of reserve hold every move of a cloth vertex two faces over that one step does not,
/// and the in-place growth from a one-step pattern by exactly the blocks that moved out fits them
/// (the equilibrium solver's path when vertices keep sliding).
#[test]
fn two_step_reserve_and_in_place_growth_hold_a_vertex_sliding_two_faces() {
    let (system, state) = sphere_system(Kind::Loop, 3, &MIXED);
    let n = system.num_dofs();
    let frames = system.frames_at(&state).unwrap();
    let mut recorder = NodeBlockRecorder::default();
    system.structure(&frames, &mut recorder);
    let all: Vec<usize> = (0..system.triangles().len()).collect();
    let (mut one, mut two) = (NodeBlockRecorder::default(), NodeBlockRecorder::default());
    system.reserve_structure_of(&state, &all, 1, &mut one);
    system.reserve_structure_of(&state, &all, 2, &mut two);
    let asm1 = NodeBlockAssembler::with_reserve(n, system.nodes(), &recorder, Some(&one), None);
    let asm2 = NodeBlockAssembler::with_reserve(n, system.nodes(), &recorder, Some(&two), None);
    assert!(asm2.nnz() > asm1.nnz());
    let topology = system.surface().topology().clone();
    let (mut moves, mut outside_one) = (0, 0);
    for c in (0..system.num_cloth_vertices()).filter(|&c| system.cloth_dof(c).is_some()) {
        let face = state.cloth[c].face;
        for e in 0..3 {
            let Some(first) = topology.twin(face, e) else {
                continue;
            };
            for e2 in 0..3 {
                let Some(second) = topology.twin(first.face, e2) else {
                    continue;
                };
                let mut moved = state.clone();
                moved.cloth[c] = SurfaceCoord::new(second.face, 0.3, 0.3);
                let frames = system.frames_at(&moved).unwrap();
                let mut rec = NodeBlockRecorder::default();
                system.structure(&frames, &mut rec);
                assert!(
                    asm2.fit(&rec).is_some(),
                    "vertex {c} into face {}",
                    second.face
                );
                moves += 1;
                let outside = asm1.outside_blocks(&rec);
                if outside.is_empty() {
                    continue;
                }
                outside_one += 1;
                // Growing the one-step pattern by the blocks that moved out fits the move.
                let hot: Vec<usize> = outside
                    .iter()
                    .filter_map(|&b| system.cloth_triangle_of_block(b))
                    .collect();
                assert!(!hot.is_empty(), "only cloth blocks move");
                let mut reserve = NodeBlockRecorder::default();
                system.reserve_structure_of(&moved, &hot, 2, &mut reserve);
                let mut grown = asm1.clone();
                assert!(grown.grow(&rec, Some(&reserve)));
                assert!(grown.outside_blocks(&rec).is_empty());
                assert_eq!(
                    grown.fit(&rec),
                    Some(0),
                    "the recorded lists are taken over"
                );
            }
        }
        if outside_one > 3 {
            break;
        }
    }
    assert!(
        moves > 0 && outside_one > 0,
        "{moves} moves, {outside_one} outside"
    );
}

fn random_vector(rng: &mut ChaCha8Rng, n: usize) -> Vec<Real> {
    (0..n).map(|_| rng.random_range(-1.0..1.0)).collect()
}

#[test]
fn cloth_jacobian_matches_central_differences_and_its_transpose() {
    for (kind, seed) in [(Kind::Loop, 11), (Kind::Linear, 12), (Kind::Loop, 13)] {
        let (system, state) = sphere_system(kind, seed, &MIXED);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let q = system.dofs(&state);
        let dq: Vec<Real> = random_vector(&mut rng, q.len())
            .iter()
            .enumerate()
            .map(|(i, v)| {
                if i < 2 * system.num_cloth_vertices() {
                    0.01 * v
                } else {
                    1e-3 * v
                }
            })
            .collect();
        let dx = system.cloth_jacobian(&state, &dq).unwrap();
        let flat = |x: &[Vec3]| -> Vec<Real> { x.iter().flat_map(|v| [v.x, v.y, v.z]).collect() };
        // Along dq: (x(q + h dq) − x(q − h dq)) / 2h.
        let h = 1e-6;
        let at = |t: Real| {
            let qt: Vec<Real> = q.iter().zip(&dq).map(|(a, b)| a + t * b).collect();
            flat(
                &system
                    .cloth_positions(&system.with_dofs(&state, &qt))
                    .unwrap(),
            )
        };
        let (xp, xm) = (at(h), at(-h));
        let analytic = flat(&dx);
        let scale = analytic.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        for k in 0..analytic.len() {
            let numeric = (xp[k] - xm[k]) / (2.0 * h);
            assert!(
                (analytic[k] - numeric).abs() <= 1e-6 * scale,
                "{kind:?} entry {k}: {} vs {numeric}",
                analytic[k]
            );
        }
        // ⟨J dq, g⟩ = ⟨dq, Jᵀ g⟩.
        let g: Vec<Vec3> = (0..system.num_cloth_vertices())
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let jt = system.cloth_jacobian_transpose(&state, &g).unwrap();
        let lhs: Real = dx.iter().zip(&g).map(|(a, b)| a.dot(b)).sum();
        let rhs: Real = dq.iter().zip(&jt).map(|(a, b)| a * b).sum();
        assert!((lhs - rhs).abs() <= 1e-12 * lhs.abs().max(rhs.abs()));
    }
}

#[test]
fn rest_derivatives_match_central_differences_in_every_regime() {
    for (kind, seed) in [(Kind::Loop, 21), (Kind::Linear, 22), (Kind::Loop, 23)] {
        let (system, state) = sphere_system(kind, seed, &MIXED);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let dx: Vec<Vec3> = (0..system.num_cloth_vertices())
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let rest: Vec<[Vec2; 3]> = system.elements().iter().map(|e| *e.rest()).collect();
        let flat_rest: Vec<Real> = rest.iter().flatten().flat_map(|p| [p.x, p.y]).collect();
        let unflat = |r: &[Real]| -> Vec<[Vec2; 3]> {
            r.chunks(6)
                .map(|c| [0, 1, 2].map(|k| Vec2::new(c[2 * k], c[2 * k + 1])))
                .collect()
        };
        let with_rest = |r: &[Real]| {
            let mut s = system.clone();
            s.set_rest(&unflat(r)).unwrap();
            s
        };
        // (∂²U/∂x∂X̄)ᵀ dx = ∂/∂X̄ (∂U/∂x · dx).
        let mixed = system.rest_mixed_product(&state, &dx).unwrap();
        let analytic: Vec<Real> = mixed.iter().flatten().flat_map(|p| [p.x, p.y]).collect();
        let directional = |r: &[Real]| -> Real {
            let f = with_rest(r).cloth_vertex_forces(&state).unwrap();
            f.iter().zip(&dx).map(|(a, b)| a.dot(b)).sum()
        };
        check_gradient(directional, &flat_rest, &analytic, &fd()).unwrap();
        // ∂U/∂X̄.
        let g = system.rest_gradient(&state).unwrap();
        let analytic: Vec<Real> = g.iter().flatten().flat_map(|p| [p.x, p.y]).collect();
        check_gradient(
            |r: &[Real]| with_rest(r).energies(&state).unwrap().1,
            &flat_rest,
            &analytic,
            &fd(),
        )
        .unwrap();
    }
}

#[test]
fn set_rest_rejects_a_collapsed_triangle_and_keeps_the_old_pattern() {
    let (mut system, state) = sphere_system(Kind::Loop, 3, &MIXED);
    let e0 = system.energy(&state).unwrap();
    let mut rest: Vec<[Vec2; 3]> = system.elements().iter().map(|e| *e.rest()).collect();
    rest[1] = [Vec2::zeros(); 3];
    assert!(matches!(
        system.set_rest(&rest),
        Err(ClothOnBodyError::Pattern { triangle: 1, .. })
    ));
    assert_eq!(system.energy(&state).unwrap(), e0);
    assert!(system.set_rest(&rest[..2]).is_err());
}

/// `y = A x` for a faer sparse matrix (all entries stored).
fn sparse_product(a: &SparseColMat<usize, Real>, x: &[Real]) -> Vec<Real> {
    let mut y = vec![0.0; a.nrows()];
    let (cp, ri, v) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    for c in 0..a.ncols() {
        for k in cp[c]..cp[c + 1] {
            y[ri[k]] += v[k] * x[c];
        }
    }
    y
}

/// `y = Aᵀ x` for a faer sparse matrix.
fn sparse_transpose_product(a: &SparseColMat<usize, Real>, x: &[Real]) -> Vec<Real> {
    let (cp, ri, v) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    (0..a.ncols())
        .map(|c| (cp[c]..cp[c + 1]).map(|k| v[k] * x[ri[k]]).sum())
        .collect()
}

#[test]
fn explicit_cloth_jacobian_equals_the_matrix_free_products() {
    for (kind, seed) in [(Kind::Loop, 31), (Kind::Linear, 32)] {
        let (system, state) = sphere_system(kind, seed, &MIXED);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let j = system.cloth_jacobian_matrix(&state).unwrap();
        assert_eq!(
            (j.nrows(), j.ncols()),
            (3 * system.num_cloth_vertices(), system.num_dofs())
        );
        let dq = random_vector(&mut rng, system.num_dofs());
        let expected: Vec<Real> = system
            .cloth_jacobian(&state, &dq)
            .unwrap()
            .iter()
            .flat_map(|v| [v.x, v.y, v.z])
            .collect();
        let got = sparse_product(&j, &dq);
        let scale = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        assert!(scale > 0.0);
        for (a, b) in got.iter().zip(&expected) {
            assert!((a - b).abs() <= 1e-12 * scale, "{kind:?}: {a} vs {b}");
        }
        let g: Vec<Vec3> = (0..system.num_cloth_vertices())
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let expected = system.cloth_jacobian_transpose(&state, &g).unwrap();
        let flat: Vec<Real> = g.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
        let got = sparse_transpose_product(&j, &flat);
        let scale = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        for (a, b) in got.iter().zip(&expected) {
            assert!((a - b).abs() <= 1e-12 * scale, "{kind:?}: {a} vs {b}");
        }
    }
}

#[test]
fn explicit_mixed_derivative_equals_the_matrix_free_product_and_rejects_bad_ids() {
    for (kind, seed) in [(Kind::Loop, 41), (Kind::Linear, 42)] {
        let (system, state) = sphere_system(kind, seed, &MIXED);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // Pattern vertices: the cloth vertex ids, one pattern vertex per cloth vertex.
        let np = system.num_cloth_vertices();
        let tris = system.triangles().to_vec();
        let k = system.rest_mixed_matrix(&state, &tris, np).unwrap();
        assert_eq!((k.nrows(), k.ncols()), (system.num_dofs(), 2 * np));
        // Kᵀ λ = P (∂²U/∂x∂X̄)ᵀ J λ.
        let lambda = random_vector(&mut rng, system.num_dofs());
        let dx = system.cloth_jacobian(&state, &lambda).unwrap();
        let mixed = system.rest_mixed_product(&state, &dx).unwrap();
        let mut expected = vec![0.0; 2 * np];
        for (t, m) in tris.iter().zip(&mixed) {
            for a in 0..3 {
                expected[2 * t[a]] += m[a].x;
                expected[2 * t[a] + 1] += m[a].y;
            }
        }
        let got = sparse_transpose_product(&k, &lambda);
        let scale = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        assert!(scale > 0.0);
        for (a, b) in got.iter().zip(&expected) {
            assert!((a - b).abs() <= 1e-10 * scale, "{kind:?}: {a} vs {b}");
        }
        // K δX̄ matrix-free (rest_mixed_apply) equals the matrix's product.
        let delta = random_vector(&mut rng, 2 * np);
        let per_triangle: Vec<[Vec2; 3]> = tris
            .iter()
            .map(|t| t.map(|v| Vec2::new(delta[2 * v], delta[2 * v + 1])))
            .collect();
        let applied = system.rest_mixed_apply(&state, &per_triangle).unwrap();
        let mut product = vec![0.0; system.num_dofs()];
        let (cp, ri, vals) = (k.symbolic().col_ptr(), k.symbolic().row_idx(), k.val());
        for (j, &d) in delta.iter().enumerate() {
            for p in cp[j]..cp[j + 1] {
                product[ri[p]] += vals[p] * d;
            }
        }
        let scale = product.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        assert!(scale > 0.0);
        for (a, b) in applied.iter().zip(&product) {
            assert!((a - b).abs() <= 1e-10 * scale, "{kind:?}: K δX̄ {a} vs {b}");
        }
        assert!(system.rest_mixed_apply(&state, &per_triangle[1..]).is_err());
        // K A matrix-free (rest_mixed_times, A given by rows) equals the matrix's product, column by column.
        let nc = 3;
        let a_rows = random_vector(&mut rng, 2 * np * nc);
        let ka = system.rest_mixed_times(&state, &tris, &a_rows, nc).unwrap();
        let nq = system.num_dofs();
        assert_eq!(ka.len(), nq * nc);
        for c in 0..nc {
            let mut expected = vec![0.0; nq];
            for j in 0..2 * np {
                let d = a_rows[j * nc + c];
                for p in cp[j]..cp[j + 1] {
                    expected[ri[p]] += vals[p] * d;
                }
            }
            let scale = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for (a, b) in ka[c * nq..(c + 1) * nq].iter().zip(&expected) {
                assert!(
                    (a - b).abs() <= 1e-10 * scale,
                    "{kind:?}: (K A) column {c}: {a} vs {b}"
                );
            }
        }
        assert!(
            system
                .rest_mixed_times(&state, &tris, &a_rows[1..], nc)
                .is_err()
        );
        assert!(
            system
                .rest_mixed_times(&state, &tris, &a_rows[..2 * nc], nc)
                .is_err()
        );
        let mut bad = tris.clone();
        bad[0][1] = np;
        assert!(system.rest_mixed_matrix(&state, &bad, np).is_err());
        assert!(system.rest_mixed_matrix(&state, &tris[1..], np).is_err());
    }
}

mod orthotropic;
mod remeshed;
