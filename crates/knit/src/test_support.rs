//! Helpers of the crate's tests: the shared yarn data and central-difference checks of derivatives.

use std::path::PathBuf;

use rand::Rng;

/// The five shared pattern folders.
pub const PATTERNS: [&str; 5] = ["stock_9", "rib_9", "basket_9", "satin_9", "stocktiniest_9"];

/// `shared/data/yarns` beside the repository (`CARGO_MANIFEST_DIR/../../../shared/data/yarns`).
pub fn shared_yarns_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/yarns")
}

/// The 12 unknowns of a segment pair from its four points `p₀, p₁, q₀, q₁` (m).
pub fn flat(p: [[f64; 3]; 4]) -> [f64; 12] {
    std::array::from_fn(|i| p[i / 3][i % 3])
}

/// The contact pair of the contact and friction tests: segments ~1 mm long, yarn radius 1 mm.
pub fn test_contact_pair() -> crate::contact::ContactPair {
    crate::contact::ContactPair {
        rest_lengths: [1.1e-3, 0.9e-3],
        contact_distance: 2.0e-3,
        stiffness: 3.0e4,
    }
}

/// A point with coordinates uniform in `[−s, s]`.
pub fn random_point(rng: &mut impl Rng, s: f64) -> [f64; 3] {
    std::array::from_fn(|_| rng.random_range(-s..s))
}

/// Largest differences between analytic and central-difference derivatives, each relative to the
/// largest magnitude of the analytic one.
#[derive(Clone, Copy, Debug)]
pub struct DerivativeErrors {
    /// `‖g_fd − g‖∞ / ‖g‖∞`.
    pub gradient_error: f64,
    /// `‖H_fd − H‖∞ / ‖H‖∞` (columns of `H_fd` from central differences of the gradient).
    pub hessian_error: f64,
    /// `‖g‖∞`.
    #[allow(dead_code)]
    pub gradient_scale: f64,
}

/// Central differences with the same step `h` for every unknown.
pub fn check_derivatives<const N: usize>(
    q: &[f64; N],
    h: f64,
    f: &impl Fn(&[f64; N]) -> (f64, [f64; N], [[f64; N]; N]),
) -> DerivativeErrors {
    check_derivatives_steps(q, &[h; N], f)
}

/// Central differences with step `steps[i]` for unknown `i`.
pub fn check_derivatives_steps<const N: usize>(
    q: &[f64; N],
    steps: &[f64; N],
    f: &impl Fn(&[f64; N]) -> (f64, [f64; N], [[f64; N]; N]),
) -> DerivativeErrors {
    let (_, g, hess) = f(q);
    let gmax = g.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
    let hmax = hess
        .iter()
        .flatten()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1e-300);
    let mut gerr = 0.0f64;
    let mut herr = 0.0f64;
    for i in 0..N {
        let mut qp = *q;
        let mut qm = *q;
        qp[i] += steps[i];
        qm[i] -= steps[i];
        let (ep, gp, _) = f(&qp);
        let (em, gm, _) = f(&qm);
        let fd = (ep - em) / (2.0 * steps[i]);
        gerr = gerr.max((fd - g[i]).abs());
        for j in 0..N {
            let fdh = (gp[j] - gm[j]) / (2.0 * steps[i]);
            herr = herr.max((fdh - hess[j][i]).abs());
        }
    }
    DerivativeErrors {
        gradient_error: gerr / gmax,
        hessian_error: herr / hmax,
        gradient_scale: gmax,
    }
}

/// A straight open yarn of `n` vertices 1 mm apart along x from `start` (m), its rest state straight and
/// untwisted.
pub fn straight_yarn(start: [f64; 3], n: usize) -> crate::tile::Yarn {
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
pub const GROOVE_TOP: std::ops::Range<usize> = 62..73;

/// A groove: two straight yarns (radius 1 mm, 31 vertices, x from −15 to 15 mm) side by side at
/// `y = ±1.2 r`, `z = 0`, every vertex clamped, and a third, 10 mm long (x from −5 to 5 mm), lying in the
/// groove between them at `y = 0`, its centreline `0.99997 D` from each (just within the contact
/// distance `D = 2r`), under gravity `gravity` (m/s²). The model and the clamps.
pub fn groove(
    gravity: [f64; 3],
) -> (
    crate::patch::PatchModel,
    Vec<crate::implicit_euler::Prescribed>,
) {
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
    let x = model.initial_state();
    let clamps = (0..GROOVE_TOP.start)
        .map(|v| {
            let p = [x[4 * v], x[4 * v + 1], x[4 * v + 2]];
            crate::implicit_euler::Prescribed {
                vertex: v,
                start: p,
                end: p,
                ramp_time: 0.0,
            }
        })
        .collect();
    (model, clamps)
}
