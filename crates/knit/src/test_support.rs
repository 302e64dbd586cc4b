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
        kernel: crate::contact::ContactKernel::Smooth,
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
