use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[test]
fn the_pairs_in_contact_at_the_start_get_friction_and_bad_settings_are_named() {
    let (model, _) = groove([0.0, 0.0, -9.81]);
    let x = model.initial_state();
    let f = PatchFriction::new(&model, &x, 0.5, 1e-6).unwrap();
    // The top yarn's 10 segments each touch a segment or two of each base yarn; the base yarns are apart.
    assert!(f.len() >= 20, "{} pairs", f.len());
    assert!(f.bound() > 0.0);
    let top: Vec<usize> = GROOVE_TOP.collect();
    for (dofs, _) in &f.pairs {
        let on_top = |i: usize| top.contains(&(dofs[3 * i] / 4));
        assert!(on_top(0) != on_top(2), "a pair within one side: {dofs:?}");
    }
    // The bound scales with μ; frictionless assembles nothing.
    let f2 = PatchFriction::new(&model, &x, 1.0, 1e-6).unwrap();
    assert!((f2.bound() - 2.0 * f.bound()).abs() <= 1e-12 * f2.bound());
    assert!(
        PatchFriction::new(&model, &x, 0.0, 1e-6)
            .unwrap()
            .is_empty()
    );
    // Lifted out of reach: no pair.
    let mut lifted = x.clone();
    for v in GROOVE_TOP {
        lifted[4 * v + 2] += 1e-3;
    }
    assert!(
        PatchFriction::new(&model, &lifted, 0.5, 1e-6)
            .unwrap()
            .is_empty()
    );
    for (mu, eps, name) in [
        (-0.1, 1e-6, "friction_coefficient"),
        (f64::NAN, 1e-6, "friction_coefficient"),
        (f64::INFINITY, 1e-6, "friction_coefficient"),
        (0.5, 0.0, "friction_slip"),
        (0.5, -1e-6, "friction_slip"),
        (0.5, f64::NAN, "friction_slip"),
    ] {
        let e = PatchFriction::new(&model, &x, mu, eps).unwrap_err();
        assert!(e.starts_with(name), "{e}");
    }
    assert!(
        PatchFriction::new(&model, &x[1..], 0.5, 1e-6)
            .unwrap_err()
            .contains("unknowns")
    );
}

/// The pairs' forces are internal (they sum to zero: Newton's third law between the two yarns), the
/// assembled Hessian is positive semidefinite, and the energy is the one of the derivatives.
#[test]
fn friction_forces_are_internal_and_the_hessian_semidefinite() {
    let (model, _) = groove([0.0, 0.0, -9.81]);
    let x0 = model.initial_state();
    let eps = 1e-6;
    let f = PatchFriction::new(&model, &x0, 0.7, eps).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(45);
    let n = x0.len();
    for size in [0.3 * eps, eps, 30.0 * eps] {
        let mut x = x0.clone();
        for v in GROOVE_TOP {
            for k in 0..3 {
                x[4 * v + k] += size * rng.random_range(-1.0..1.0);
            }
        }
        let (mut e, mut g, mut t) = (0.0, vec![0.0; n], Vec::new());
        f.add_derivatives(&x, true, &mut e, &mut g, &mut t);
        assert_eq!(e, f.energy(&x));
        let gmax = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(gmax > 0.0);
        for k in 0..3 {
            let sum: f64 = (0..n / 4).map(|v| g[4 * v + k]).sum();
            assert!(sum.abs() <= 1e-12 * gmax * n as f64, "axis {k}: {sum}");
        }
        assert!((0..n / 4).all(|v| g[4 * v + 3] == 0.0), "no torque");
        let mut h = vec![vec![0.0; n]; n];
        for tr in &t {
            assert!(tr.row >= tr.col);
            h[tr.row][tr.col] += tr.val;
            if tr.row != tr.col {
                h[tr.col][tr.row] += tr.val;
            }
        }
        let hmax = h.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for _ in 0..20 {
            let z: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
            let zhz: f64 = (0..n)
                .map(|i| z[i] * (0..n).map(|j| h[i][j] * z[j]).sum::<f64>())
                .sum();
            assert!(zhz >= -1e-10 * hmax * n as f64, "{zhz}");
        }
    }
}

/// A straight open yarn of `n` vertices 1 mm apart along x from `start` (m), its rest state straight and
/// untwisted.
pub(crate) fn straight_yarn(start: [f64; 3], n: usize) -> crate::tile::Yarn {
    let positions: Vec<[f64; 3]> = (0..n)
        .map(|i| [start[0] + i as f64 * 1e-3, start[1], start[2]])
        .collect();
    let interior = |i: usize| i > 0 && i + 1 < n;
    crate::tile::Yarn {
        source: vec![(0, [0, 0]); n],
        closed: false,
        twist: vec![0.0; n - 1],
        rest_length: vec![1e-3; n - 1],
        reference_director: vec![[0.0, 0.0, 1.0]; n - 1],
        rest_curvature: (0..n).map(|i| interior(i).then_some([0.0; 2])).collect(),
        rest_twist: (0..n).map(|i| interior(i).then_some(0.0)).collect(),
        reference_twist: (0..n).map(|i| interior(i).then_some(0.0)).collect(),
        positions,
    }
}

/// Vertices of the top yarn of [`groove`] (the last 11 of the model).
pub(crate) const GROOVE_TOP: std::ops::Range<usize> = 62..73;

/// A groove: two straight yarns (radius 1 mm, 31 vertices, x from −15 to 15 mm) side by side at
/// `y = ±1.2 r`, `z = 0`, every vertex clamped, and a third, 10 mm long (x from −5 to 5 mm), lying in the
/// groove between them at `y = 0`, its centreline `0.99997 D` from each (just within the contact
/// distance `D = 2r`), under gravity `gravity` (m/s²). The model and the clamped vertices (the two base
/// yarns', `0..GROOVE_TOP.start`).
pub(crate) fn groove(gravity: [f64; 3]) -> (crate::patch::PatchModel, std::ops::Range<usize>) {
    let r: f64 = 1e-3;
    let d = 1.2 * r;
    let h = ((0.999_97 * 2.0 * r).powi(2) - d * d).sqrt();
    let patch = crate::tile::Patch {
        cells: [1, 1],
        radius: r,
        yarns: vec![
            straight_yarn([-15e-3, -d, 0.0], 31),
            straight_yarn([-15e-3, d, 0.0], 31),
            straight_yarn([-5e-3, 0.0, h], 11),
        ],
    };
    let loads = crate::patch::PatchLoads {
        gravity,
        sphere: None,
    };
    let model =
        crate::patch::PatchModel::new(&patch, &crate::yarn_params::YarnParams::default(), loads)
            .unwrap();
    (model, 0..GROOVE_TOP.start)
}
