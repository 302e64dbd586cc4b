//! `V(F)`, the closest volume-preserving matrix to a deformation gradient (the knitwear paper Eq. 8 and
//! the local step of Sec. 7.1, Eq. 26): with the rotation-variant SVD `F = U diag(σ) Wᵀ`
//! ([`crate::polar_decomposition`], `U`, `W` proper rotations, `σ₃ < 0` for an inverted `F`),
//! `V = U diag(s) Wᵀ` where `s` solves
//!
//! ```text
//! min_s ½ Σ (s_i − σ_i)²   s.t.   s₁ s₂ s₃ = 1,   s_i ≥ s_min          (Eq. 26 with Δσ = s − σ)
//! ```
//!
//! so `det V = s₁ s₂ s₃ = 1` and `‖F − V‖²_F = Σ (σ_i − s_i)²`. Dimensionless.
//!
//! **Solver.** Newton on the KKT system of the equality constraint, as the paper: the unknowns are the
//! free `s_i` and the multiplier `μ`, the residuals `r_i = s_i − σ_i − μ Π_{j≠i} s_j` and
//! `r_c = Π s − 1`; its Jacobian is the 4 × 4 (or smaller) matrix `[[I − μ P, −p], [pᵀ, 0]]` with
//! `p_i = Π_{j≠i} s_j` and `P_ik = Π_{j≠i,k} s_j` (`i ≠ k`). The paper's clamping: a value that falls
//! below `s_min` (0.01) is set to `s_min` and held fixed at the next iteration. We read "fixed" as an
//! active bound: it stays fixed while its bound multiplier `ν_i = s_i − σ_i − μ p_i` is non-negative (the
//! objective would push it lower still) and is freed otherwise, so a converged point satisfies the KKT
//! conditions of the bound-constrained problem — what the derivative below needs. The constraint set is
//! not convex, and for large `σ` the problem has several KKT points (for `σ = (10, 10, 10)`,
//! `s = (1, 1, 1)` is a local maximum on the constraint and the minima break the symmetry), and plain
//! Newton from `σ` may end at the wrong one or not converge (60 iterations were not enough for
//! `σ = (119.5, 76.8, 1.87)`, the clamped regime). So Newton starts from the least-cost KKT point found on the one-parameter families
//! of stationary points (stationarity of a free `s_i` reads `s_i² − σ_i s_i = μ`, so the smallest free
//! stretch `t` fixes `μ` and the others; the roots of `Π s(t) = 1` are bracketed on a log grid and
//! refined, for no value clamped, `s₃` clamped, and `s₂`, `s₃` clamped), and polishes it on the KKT
//! system to the tolerance (0–2 iterations). Most calls skip that scan: Newton from the nearby point
//! `σ/(Π σ)^⅓` is kept when a convexity certificate proves its answer global (`certified_near_start`). At the least-cost point the stretches keep the order of
//! `σ`, and only the smallest can be clamped (a swap would lower the cost).
//!
//! **When it is the closest.** For `det F ≥ 0` the von Neumann trace inequality gives
//! `‖F − A‖² ≥ Σ (σ_i(F) − σ_i(A))²` for every `A`, with `Π σ_i(A) = 1` on SL(3), and `U diag(s) Wᵀ`
//! attains the bound: `V` is the closest matrix of SL(3) (up to the floor). For an inverted `F` the
//! paper's positivity (`s > 0` in the signed frame) defines `V`: the closest among the
//! `U diag(s) Wᵀ`, `s > 0`, which un-inverts the element.
//!
//! **Derivative.** `∂s/∂σ` by implicit differentiation of the converged KKT system: the Jacobian above
//! times `[ds_F; dμ]` equals `[dσ_F; 0]`, so `ds_F/dσ_F` is the free block of its inverse; a clamped
//! `s_i` has zero derivative. It exists where the active set and the chosen KKT point do not change: at
//! a clamping transition `s(σ)` is only continuous, and where two KKT points tie (the cut locus of the
//! projection) `V` jumps.

use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};

use crate::polar_decomposition::polar_decomposition;

/// Settings of [`closest_volume_preserving`] and [`volume_preserving_stretches`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumePreservingParams {
    /// The paper's floor on the stretches `s_i` (dimensionless; Sec. 7.1: 0.01).
    pub floor: f64,
    /// Most Newton iterations per start.
    pub max_iterations: usize,
    /// Converged when `|Π s − 1|` is at most this and every stationarity residual at most this times
    /// `max(1, |σ|∞)` (dimensionless).
    pub tolerance: f64,
}

impl Default for VolumePreservingParams {
    fn default() -> Self {
        Self {
            floor: 0.01,
            max_iterations: 60,
            tolerance: 1e-14,
        }
    }
}

/// Why [`VolumePreservingParams`] or the input cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum VolumePreservingError {
    /// A setting out of range.
    #[error(
        "volume-preserving projection: {field} = {value} is out of range ({expected}); use the default"
    )]
    Params {
        /// Which setting.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        expected: &'static str,
    },
    /// The deformation gradient has a non-finite entry.
    #[error(
        "volume-preserving projection: the deformation gradient has a non-finite entry ({value}); check the node positions"
    )]
    NonFinite {
        /// The offending value.
        value: f64,
    },
}

impl VolumePreservingParams {
    /// Checks the settings: `0 < floor < 1`, `max_iterations ≥ 1`, `0 < tolerance < 1e-3`.
    pub fn validate(&self) -> Result<(), VolumePreservingError> {
        let bad = |field, value, expected| {
            Err(VolumePreservingError::Params {
                field,
                value,
                expected,
            })
        };
        if !(self.floor > 0.0 && self.floor < 1.0) {
            return bad("floor", self.floor, "0 < floor < 1");
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", 0.0, "at least 1");
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1e-3) {
            return bad("tolerance", self.tolerance, "0 < tolerance < 1e-3");
        }
        Ok(())
    }
}

/// The solution of Eq. 26 for one set of signed singular values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumePreservingStretches {
    /// The singular values `σ` it was solved for (dimensionless, signed, descending magnitude).
    pub sigma: Vector3<f64>,
    /// The stretches `s` (dimensionless, `≥ floor`, `Π s = 1` when converged).
    pub stretches: Vector3<f64>,
    /// The multiplier `μ` of `Π s = 1` (dimensionless).
    pub multiplier: f64,
    /// Which `s_i` sit on the floor (the paper's clamping, active at the solution).
    pub clamped: [bool; 3],
    /// Newton iterations of the start that was kept.
    pub iterations: usize,
    /// Whether the KKT residual met the tolerance. When not (never seen in the tests), `stretches` are
    /// the last iterate rescaled so that `Π s = 1`.
    pub converged: bool,
}

impl VolumePreservingStretches {
    /// `Σ (σ_i − s_i)² = ‖F − V(F)‖²_F` (dimensionless).
    pub fn distance_squared(&self) -> f64 {
        (self.sigma - self.stretches).norm_squared()
    }

    /// `∂s/∂σ` (3 × 3, row `i` = `∂s_i/∂σ`), by implicit differentiation of the converged KKT system
    /// (see the module doc): zero rows for clamped stretches.
    pub fn jacobian(&self) -> Matrix3<f64> {
        let free: Vec<usize> = (0..3).filter(|&i| !self.clamped[i]).collect();
        let kkt = kkt_matrix(&self.stretches, self.multiplier, &free);
        let mut out = Matrix3::zeros();
        // A singular KKT matrix is a bifurcation of the KKT points (the cut locus): no derivative
        // exists there, and the zero matrix is returned (finite, never NaN).
        if let Some(inv) = kkt.try_inverse() {
            for (a, &i) in free.iter().enumerate() {
                for (b, &k) in free.iter().enumerate() {
                    out[(i, k)] = inv[(a, b)];
                }
            }
        }
        out
    }
}

/// `V(F)` with its SVD frame and the solved stretches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumePreserving {
    /// `V = U diag(s) Wᵀ`, `det V = 1` (dimensionless).
    pub matrix: Matrix3<f64>,
    /// `U` of `F`'s rotation-variant SVD.
    pub u: Matrix3<f64>,
    /// `W` of `F`'s rotation-variant SVD.
    pub w: Matrix3<f64>,
    /// The solution of Eq. 26.
    pub stretches: VolumePreservingStretches,
}

/// `V(F)`, the closest volume-preserving matrix to `f` (see the module doc), for any finite `f`
/// (inverted and degenerate included).
pub fn closest_volume_preserving(
    f: &Matrix3<f64>,
    params: &VolumePreservingParams,
) -> Result<VolumePreserving, VolumePreservingError> {
    params.validate()?;
    if let Some(&value) = f.iter().find(|v| !v.is_finite()) {
        return Err(VolumePreservingError::NonFinite { value });
    }
    let polar = polar_decomposition(f);
    let stretches = volume_preserving_stretches(&polar.sigma, params);
    let matrix = polar.u * Matrix3::from_diagonal(&stretches.stretches) * polar.w.transpose();
    Ok(VolumePreserving {
        matrix,
        u: polar.u,
        w: polar.w,
        stretches,
    })
}

/// The solution of Eq. 26 for signed singular values `sigma` (finite; `params` valid), in any order
/// (sorted internally; at most one negative, as the rotation-variant SVD gives them).
pub fn volume_preserving_stretches(
    sigma: &Vector3<f64>,
    params: &VolumePreservingParams,
) -> VolumePreservingStretches {
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| sigma[b].total_cmp(&sigma[a]));
    let sorted = Vector3::new(sigma[order[0]], sigma[order[1]], sigma[order[2]]);
    let solved = certified_near_start(&sorted, params).unwrap_or_else(|| {
        let (start, clamped) = global_start(&sorted, params.floor);
        newton(&sorted, start, clamped, params)
    });
    let mut out = solved;
    out.sigma = *sigma;
    for (k, &i) in order.iter().enumerate() {
        out.stretches[i] = solved.stretches[k];
        out.clamped[i] = solved.clamped[k];
    }
    out
}

/// Newton from the nearby point `|σ| / (Π |σ|)^⅓` (floored), kept only when a certificate proves it the
/// global minimum of Eq. 26; `None` sends the caller to the scan of [`global_start`]. The certificate
/// rests on the convexity of `C = {s > 0 : Π s ≥ 1}` (a superlevel set of `g(s) = Σ ln s_i`, which is
/// concave), using that at a KKT point on `Π s = 1` the residual reads `s − σ = μ ∇g(s)`:
///
/// - `μ ≥ 0` (`σ` outside `C`, an element that lost volume): `s` is a KKT point of the convex problem
///   `min ½‖s − σ‖²` over `C`, hence its unique minimizer; every point with `Π s = 1, s ≥ floor` lies in
///   `C`, so none is closer.
/// - `μ < 0` (`σ` inside `C`): with `r = ‖σ − s‖ < σ_min`, every `y` of the ball `B(σ, r)` has
///   `y_i ≥ σ_min − r > 0`, so `g` there is concave with curvature at most `L = (σ_min − r)⁻²`, and
///   writing `y − s = r n + w` (`n = (σ − s)/r`, `‖w‖ ≤ r`) gives `g(y) ≥ (r + n·w)(r/|μ| − L r)`: the
///   ball lies in `C` when `|μ| ≤ (σ_min − r)²`, so no point of `Π s = 1` is closer than `r`.
///
/// An element near its rest shape (every step of a simulation but the first few) passes in 2–3 Newton
/// iterations instead of the scan's ~100 evaluations of the families (docs/BENCHMARKS.md, issue 44).
fn certified_near_start(
    sigma: &Vector3<f64>,
    params: &VolumePreservingParams,
) -> Option<VolumePreservingStretches> {
    let floored = sigma.map(|v| v.abs().max(params.floor));
    let start = floored / floored.product().cbrt();
    let solved = newton(sigma, start, [false; 3], params);
    if !solved.converged || solved.clamped.iter().any(|&c| c) {
        return None;
    }
    let mu = solved.multiplier;
    if mu >= 0.0 {
        return Some(solved);
    }
    let r = (sigma - solved.stretches).norm();
    let sigma_min = sigma.min();
    (r < sigma_min && -mu <= (sigma_min - r).powi(2)).then_some(solved)
}

/// Grid points per family of KKT points in [`global_start`].
const PATH_SAMPLES: usize = 48;

/// The KKT point of least cost, found on the one-parameter families of stationary points (see
/// [`path_roots`]); `sigma` sorted descending. Returns the stretches and which sit on the floor.
fn global_start(sigma: &Vector3<f64>, floor: f64) -> (Vector3<f64>, [bool; 3]) {
    // Two clamped: s = (1/m², m, m).
    let mut best = (
        Vector3::new(1.0 / (floor * floor), floor, floor),
        [false, true, true],
    );
    let mut best_cost = (best.0 - sigma).norm_squared();
    // None clamped: parameter t = s₃ ∈ [m, 1]; one clamped (s₃ = m): parameter t = s₂ ∈ [m, 1/√m].
    for (clamped, upper) in [(false, 1.0), (true, 1.0 / floor.sqrt())] {
        for s in path_roots(sigma, floor, clamped, upper) {
            let cost = (s - sigma).norm_squared();
            if cost < best_cost {
                best_cost = cost;
                best = (s, [false, false, clamped]);
            }
        }
    }
    best
}

/// The stationary points of Eq. 26 on one family. Stationarity of a free `s_i` on `Π s = 1` reads
/// `s_i² − σ_i s_i = μ`; at the least-cost point the stretches keep the order of `σ` and all but the
/// smallest free one take the larger root `(σ_i + √(σ_i² + 4μ))/2`. So, with `t` the smallest free
/// stretch, `μ = t² − σ_k t` (`k` its index) and the larger ones follow from `t`; the product
/// `P(t)` grows from 0 and the roots of `P(t) = 1` in `[m, upper]` are bracketed on a log grid
/// ([`PATH_SAMPLES`] points) and refined by safeguarded Newton on `ln P`. Two roots within one grid
/// step (a minimum about to merge with a saddle) can be missed; the tests' brute-force grid over the
/// constraint never found a lower cost than the point kept.
fn path_roots(sigma: &Vector3<f64>, floor: f64, clamped: bool, upper: f64) -> Vec<Vector3<f64>> {
    // k: index of the parameter; the free ones above it; the clamped factor below.
    let k = if clamped { 1 } else { 2 };
    let fixed = if clamped { floor } else { 1.0 };
    let stretches = |t: f64| -> Vector3<f64> {
        let c = 2.0 * t - sigma[k];
        let mut s = Vector3::new(0.0, 0.0, floor);
        for i in 0..k {
            let radicand = (sigma[i] * sigma[i] - sigma[k] * sigma[k] + c * c).max(0.0);
            s[i] = 0.5 * (sigma[i] + radicand.sqrt());
        }
        s[k] = t;
        s
    };
    // ln P(t) and its derivative.
    let log_product = |t: f64| -> (f64, f64) {
        let s = stretches(t);
        let c = 2.0 * t - sigma[k];
        let mut value = fixed.ln() + t.ln();
        let mut slope = 1.0 / t;
        for i in 0..k {
            value += s[i].max(f64::MIN_POSITIVE).ln();
            let root = (2.0 * s[i] - sigma[i]).max(f64::MIN_POSITIVE);
            slope += c / (root * s[i].max(f64::MIN_POSITIVE));
        }
        (value, slope)
    };
    // The scan compares the product (the clamped value included) with 1, without logarithms, on a
    // geometric grid.
    let excess = |t: f64| stretches(t).product() - 1.0;
    let ratio = (upper / floor).powf(1.0 / PATH_SAMPLES as f64);
    let mut roots = Vec::new();
    let mut a = floor;
    let mut fa = excess(a);
    if fa == 0.0 {
        roots.push(stretches(a));
    }
    for j in 1..=PATH_SAMPLES {
        let b = if j == PATH_SAMPLES { upper } else { a * ratio };
        let fb = excess(b);
        if fb == 0.0 {
            roots.push(stretches(b));
        } else if fa * fb < 0.0 {
            // Safeguarded Newton in the bracket [x0, x1] with ln P(x0) < 0 < ln P(x1) or reversed.
            let (mut x0, mut x1) = (a, b);
            let rising = fb > 0.0;
            let mut t = 0.5 * (a + b);
            for _ in 0..100 {
                let (v, d) = log_product(t);
                if (v < 0.0) == rising {
                    x0 = t;
                } else {
                    x1 = t;
                }
                let newton = t - v / d;
                let next =
                    if d.is_finite() && d != 0.0 && newton > x0.min(x1) && newton < x0.max(x1) {
                        newton
                    } else {
                        0.5 * (x0 + x1)
                    };
                let done = (next - t).abs() <= 1e-16 * t || v == 0.0;
                t = next;
                if done || (x1 - x0).abs() <= 1e-16 * t {
                    break;
                }
            }
            roots.push(stretches(t));
        }
        a = b;
        fa = fb;
    }
    roots
}

/// `p_i = Π_{j≠i} s_j`.
fn cofactors(s: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(s[1] * s[2], s[0] * s[2], s[0] * s[1])
}

/// The KKT matrix over the free stretches (rows `0..n`) and the multiplier (row `n`), see the module
/// doc; padded to 4 × 4 with the identity (rows past `n`), so it lives on the stack.
fn kkt_matrix(s: &Vector3<f64>, mu: f64, free: &[usize]) -> Matrix4<f64> {
    let n = free.len();
    let p = cofactors(s);
    let mut j = Matrix4::identity();
    j[(n, n)] = 0.0;
    for (a, &i) in free.iter().enumerate() {
        for (b, &k) in free.iter().enumerate() {
            j[(a, b)] = if i == k {
                1.0
            } else {
                // Π_{j ≠ i, k} s_j: the third index.
                -mu * s[3 - i - k]
            };
        }
        j[(a, n)] = -p[i];
        j[(n, a)] = p[i];
    }
    j
}

/// Newton on the KKT system from `start` (free set: not `clamped`) with the paper's clamping.
fn newton(
    sigma: &Vector3<f64>,
    start: Vector3<f64>,
    mut clamped: [bool; 3],
    params: &VolumePreservingParams,
) -> VolumePreservingStretches {
    let m = params.floor;
    let tol = params.tolerance * sigma.amax().max(1.0);
    let mut s = start;
    // Least-squares multiplier over the free values: min_μ Σ (s_i − σ_i − μ p_i)².
    let p = cofactors(&s);
    let (mut num, mut den) = (0.0, 0.0);
    for i in (0..3).filter(|&i| !clamped[i]) {
        num += (s[i] - sigma[i]) * p[i];
        den += p[i] * p[i];
    }
    let mut mu = num / den.max(f64::MIN_POSITIVE);
    let mut iterations = 0;
    let mut converged = false;
    loop {
        // Free a clamped value whose bound multiplier turned negative (it wants to grow).
        let p = cofactors(&s);
        let mut changed = false;
        for i in 0..3 {
            if clamped[i] && s[i] - sigma[i] - mu * p[i] < 0.0 {
                clamped[i] = false;
                changed = true;
            }
        }
        let free: Vec<usize> = (0..3).filter(|&i| !clamped[i]).collect();
        let n = free.len();
        let mut r = Vector4::zeros();
        for (a, &i) in free.iter().enumerate() {
            r[a] = s[i] - sigma[i] - mu * p[i];
        }
        r[n] = s.product() - 1.0;
        let stationary = (0..n).all(|a| r[a].abs() <= tol);
        if !changed && stationary && r[n].abs() <= params.tolerance {
            converged = true;
            break;
        }
        if iterations >= params.max_iterations {
            break;
        }
        iterations += 1;
        let kkt = kkt_matrix(&s, mu, &free);
        let Some(step) = kkt.lu().solve(&(-r)) else {
            break;
        };
        if step.iter().any(|v| !v.is_finite()) {
            break;
        }
        for (a, &i) in free.iter().enumerate() {
            s[i] += step[a];
            if s[i] < m {
                s[i] = m;
                clamped[i] = true;
            }
        }
        mu += step[n];
        if clamped.iter().all(|&c| c) {
            // All three on the floor is infeasible (Π s = m³ < 1): the largest is freed and lifted.
            clamped[0] = false;
        }
    }
    if !converged {
        s /= s.product().abs().max(f64::MIN_POSITIVE).cbrt();
        s = s.map(|v| if v.is_finite() { v.max(m) } else { 1.0 });
        if !mu.is_finite() {
            mu = 0.0;
        }
    }
    VolumePreservingStretches {
        sigma: *sigma,
        stretches: s,
        multiplier: mu,
        clamped,
        iterations,
        converged,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::{FdParams, check_jacobian};

    fn rotation(rng: &mut ChaCha8Rng) -> Matrix3<f64> {
        let axis = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
        *Rotation3::new(axis * rng.random_range(0.0..3.1)).matrix()
    }

    fn with_singular_values(sigma: Vector3<f64>, rng: &mut ChaCha8Rng) -> Matrix3<f64> {
        rotation(rng) * Matrix3::from_diagonal(&sigma) * rotation(rng).transpose()
    }

    /// Singular values of every regime: near identity, large stretch, compression, near-degenerate,
    /// inverted, the clamping active, degenerate.
    fn regimes(rng: &mut ChaCha8Rng) -> Vec<(&'static str, Vector3<f64>)> {
        let mut r = |a: f64, b: f64| rng.random_range(a..b);
        vec![
            (
                "near identity",
                Vector3::new(
                    1.0 + r(-0.05, 0.05),
                    1.0 + r(-0.05, 0.05),
                    1.0 + r(-0.05, 0.05),
                ),
            ),
            (
                "large stretch",
                Vector3::new(r(1.5, 3.0), r(1.2, 2.0), r(1.0, 1.5)),
            ),
            (
                "compression",
                Vector3::new(r(0.5, 0.9), r(0.3, 0.6), r(0.1, 0.4)),
            ),
            (
                "near-degenerate",
                Vector3::new(r(0.8, 1.5), r(0.5, 1.0), 1e-3 * r(0.5, 1.5)),
            ),
            (
                "inverted",
                Vector3::new(r(0.8, 1.5), r(0.5, 1.0), -r(0.05, 0.45)),
            ),
            (
                "clamped",
                Vector3::new(r(60.0, 120.0), r(60.0, 120.0), r(0.5, 2.0)),
            ),
        ]
    }

    fn sorted(mut v: Vector3<f64>) -> Vector3<f64> {
        // Descending magnitude with the sign kept on the last (what the rotation-variant SVD gives).
        let mut a = [v[0].abs(), v[1].abs(), v[2].abs()];
        let negative = v.product() < 0.0;
        a.sort_by(|x, y| y.total_cmp(x));
        v = Vector3::new(a[0], a[1], if negative { -a[2] } else { a[2] });
        v
    }

    /// The certified start agrees with the scan of the KKT families wherever it is accepted, and it is
    /// accepted near the identity (the simulation's common case); the certificate refuses some points
    /// (else it would be decoration).
    #[test]
    fn certified_start_agrees_with_the_scan() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let p = VolumePreservingParams::default();
        let (mut accepted, mut refused) = (0, 0);
        for _ in 0..400 {
            for (name, sigma) in regimes(&mut rng) {
                let sigma = sorted(sigma);
                let (start, clamped) = global_start(&sigma, p.floor);
                let scanned = newton(&sigma, start, clamped, &p);
                match certified_near_start(&sigma, &p) {
                    Some(fast) => {
                        accepted += 1;
                        assert!(
                            (fast.stretches - scanned.stretches).amax() <= 1e-10,
                            "{name}: σ = {sigma:?}: certified {:?}, scan {:?}",
                            fast.stretches,
                            scanned.stretches
                        );
                        assert!(fast.distance_squared() <= scanned.distance_squared() + 1e-12);
                    }
                    None => {
                        refused += 1;
                        assert_ne!(name, "near identity", "σ = {sigma:?} was not certified");
                    }
                }
            }
        }
        assert!(
            accepted > 1000 && refused > 0,
            "accepted {accepted}, refused {refused}"
        );
    }

    #[test]
    fn determinant_is_one_in_every_regime() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let p = VolumePreservingParams::default();
        for _ in 0..100 {
            for (name, sigma) in regimes(&mut rng) {
                let f = with_singular_values(sigma, &mut rng);
                let v = closest_volume_preserving(&f, &p).unwrap();
                assert!(v.stretches.converged, "{name}: {v:?}");
                // Either start leaves the KKT Newton little to do: the nearby one converges
                // quadratically (up to 5 seen, for σ far from the surface), the one from the
                // stationary families is polished in at most 2.
                assert!(v.stretches.iterations <= 8, "{name}: {v:?}");
                assert!(
                    (v.stretches.stretches.product() - 1.0).abs() < 2e-14,
                    "{name}: {v:?}"
                );
                let tol = 1e-14 * v.matrix.norm().powi(3).max(1.0);
                assert!((v.matrix.determinant() - 1.0).abs() < tol, "{name}: {v:?}");
                assert!(v.stretches.stretches.iter().all(|&s| s >= p.floor));
            }
        }
        for f in [
            Matrix3::zeros(),
            Matrix3::from_diagonal(&Vector3::new(1.0, 0.0, 0.0)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)),
            Matrix3::from_diagonal(&Vector3::new(1e8, 1.0, 1.0)),
            Matrix3::from_diagonal(&Vector3::new(1e-9, 1e-9, 1e-9)),
        ] {
            let v = closest_volume_preserving(&f, &p).unwrap();
            assert!(v.matrix.iter().all(|x| x.is_finite()), "{f}");
            assert!(
                (v.stretches.stretches.product() - 1.0).abs() < 1e-14,
                "{f}: {v:?}"
            );
        }
    }

    #[test]
    fn volume_preserving_matrices_are_their_own_projection() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let p = VolumePreservingParams::default();
        for _ in 0..300 {
            let g: Matrix3<f64> = Matrix3::from_fn(|_, _| rng.random_range(-1.5..1.5));
            let det = g.determinant();
            if det.abs() < 1e-3 {
                continue;
            }
            // Make det = +1 (flip a column if needed).
            let mut f = g / det.abs().cbrt();
            if det < 0.0 {
                f.set_column(0, &(-f.column(0)));
            }
            let v = closest_volume_preserving(&f, &p).unwrap();
            // Stretches this small would be clamped: their projection is not F.
            if v.stretches.sigma.iter().any(|s| *s < p.floor) {
                continue;
            }
            assert!((v.matrix - f).norm() < 1e-11 * f.norm(), "{f} {v:?}");
        }
    }

    #[test]
    fn no_volume_preserving_candidate_is_closer() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let p = VolumePreservingParams::default();
        for _ in 0..40 {
            for (name, sigma) in regimes(&mut rng) {
                let f = with_singular_values(sigma, &mut rng);
                let v = closest_volume_preserving(&f, &p).unwrap();
                let best = (f - v.matrix).norm();
                for _ in 0..200 {
                    // A positive diagonal with product 1 and entries ≥ the floor, in F's frame …
                    let a: f64 = rng.random_range(-5.0..3.0);
                    let b: f64 = rng.random_range(-5.0..3.0);
                    let d = Vector3::new(a.exp(), b.exp(), (-a - b).exp());
                    if d.iter().any(|x| *x < p.floor) {
                        continue;
                    }
                    let in_frame = v.u * Matrix3::from_diagonal(&d) * v.w.transpose();
                    assert!(
                        (f - in_frame).norm() >= best - 1e-10,
                        "{name}: {d} beats {v:?}"
                    );
                    // … and, for det F > 0 (where V is the closest of all SL(3)), rotated out of it.
                    if sigma[2] > 0.0 {
                        let rotated = rotation(&mut rng) * in_frame * rotation(&mut rng);
                        assert!((f - rotated).norm() >= best - 1e-10, "{name}");
                        let near = rotation_near(&mut rng, 0.05) * v.matrix;
                        assert!((f - near).norm() >= best - 1e-10, "{name}");
                    }
                }
                // A brute-force grid over (ln s₁, ln s₂) in F's frame.
                let mut grid_best = f64::INFINITY;
                for i in 0..=120 {
                    for j in 0..=120 {
                        let a = -5.0 + 10.0 * i as f64 / 120.0;
                        let b = -5.0 + 10.0 * j as f64 / 120.0;
                        let d = Vector3::new(a.exp(), b.exp(), (-a - b).exp());
                        if d.iter().all(|x| *x >= p.floor) {
                            grid_best = grid_best.min((v.stretches.sigma - d).norm());
                        }
                    }
                }
                assert!(
                    grid_best >= best - 1e-10,
                    "{name}: grid {grid_best} < {best}"
                );
                assert!(
                    grid_best <= best * 1.2 + 0.2,
                    "{name}: grid {grid_best} vs {best}"
                );
            }
        }
    }

    fn rotation_near(rng: &mut ChaCha8Rng, angle: f64) -> Matrix3<f64> {
        let axis = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
        *Rotation3::new(axis.normalize() * rng.random_range(0.0..angle)).matrix()
    }

    #[test]
    fn rotation_equivariant() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let p = VolumePreservingParams::default();
        for _ in 0..50 {
            for (name, sigma) in regimes(&mut rng) {
                let f = with_singular_values(sigma, &mut rng);
                let q = rotation(&mut rng);
                let v = closest_volume_preserving(&f, &p).unwrap().matrix;
                let left = closest_volume_preserving(&(q * f), &p).unwrap().matrix;
                let right = closest_volume_preserving(&(f * q), &p).unwrap().matrix;
                let scale = 1e-10 * v.norm();
                assert!((left - q * v).norm() < scale, "{name}: V(QF) ≠ Q V(F)");
                assert!((right - v * q).norm() < scale, "{name}: V(FQ) ≠ V(F) Q");
            }
        }
    }

    #[test]
    fn clamping_holds_the_smallest_stretch_on_the_floor() {
        // σ = (100, 60, 1): without the floor s₃ < 0.01; with it s₃ = 0.01 held, s₁ s₂ = 100, and the free
        // pair stationary: s_i² − σ_i s_i equal for both (= μ).
        let p = VolumePreservingParams::default();
        let sigma = Vector3::new(100.0, 60.0, 1.0);
        let loose = VolumePreservingParams { floor: 1e-8, ..p };
        assert!(volume_preserving_stretches(&sigma, &loose).stretches[2] < 0.01);
        let s = volume_preserving_stretches(&sigma, &p);
        assert!(s.converged);
        assert_eq!(s.clamped, [false, false, true]);
        let v = s.stretches;
        assert_eq!(v[2], 0.01);
        assert!((v[0] * v[1] - 100.0).abs() < 1e-10, "{s:?}");
        let mu = |i: usize| v[i] * v[i] - sigma[i] * v[i];
        assert!((mu(0) - mu(1)).abs() < 1e-9 * mu(0).abs(), "{s:?}");
        // The bound's multiplier ν₃ = s₃ − σ₃ − μ s₁ s₂ is ≥ 0: the floor holds it down.
        assert!(v[2] - sigma[2] - s.multiplier * v[0] * v[1] >= 0.0);
        // Inactive: a moderate stretch has all three free.
        let s = volume_preserving_stretches(&Vector3::new(1.5, 1.2, 0.9), &p);
        assert_eq!(s.clamped, [false; 3]);
    }

    #[test]
    fn stretch_jacobian_matches_central_differences() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let p = VolumePreservingParams::default();
        let fd = FdParams {
            step: 1e-6,
            rel_tol: 1e-6,
            abs_tol: 1e-8,
        };
        let mut clamped_seen = 0;
        for _ in 0..30 {
            for (name, sigma) in regimes(&mut rng) {
                let sigma = sorted(sigma);
                let sol = volume_preserving_stretches(&sigma, &p);
                clamped_seen += sol.clamped.iter().filter(|&&c| c).count();
                let jac = sol.jacobian();
                // Row-major for check_jacobian.
                let flat: Vec<f64> = (0..3)
                    .flat_map(|i| (0..3).map(move |k| (i, k)))
                    .map(|(i, k)| jac[(i, k)])
                    .collect();
                let g = |x: &[f64]| {
                    let s = volume_preserving_stretches(&Vector3::new(x[0], x[1], x[2]), &p);
                    s.stretches.iter().copied().collect::<Vec<_>>()
                };
                if let Err(e) = check_jacobian(g, sigma.as_slice(), &flat, &fd) {
                    panic!("{name} σ = {sigma}: {e}");
                }
                // The check can fail: a wrong derivative is caught.
                let mut wrong = flat.clone();
                wrong[0] += 1e-3 * (1.0 + wrong[0].abs());
                assert!(check_jacobian(g, sigma.as_slice(), &wrong, &fd).is_err());
            }
        }
        assert!(clamped_seen > 0, "the clamped regime was exercised");
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = VolumePreservingParams::default();
        let mut f = Matrix3::identity();
        f[(1, 2)] = f64::NAN;
        let e = closest_volume_preserving(&f, &p).unwrap_err();
        assert!(e.to_string().contains("non-finite"));
        let bad = VolumePreservingParams { floor: 0.0, ..p };
        let e = closest_volume_preserving(&Matrix3::identity(), &bad).unwrap_err();
        assert!(e.to_string().contains("floor"));
    }
}
