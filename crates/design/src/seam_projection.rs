//! Seams held during design: the design map's last step puts the boundary parameters onto the set where
//! every pair of sewn edges is equally long, so every pattern the optimizer evaluates can be sewn as it
//! is, and the truing after the design has nothing left to move.
//!
//! **Constraint.** For every seam with sides `a = vertices[0]`, `b = vertices[1]` (`a[k]` sewn to `b[k]`)
//! and every pair of corresponding edges `k → k + 1` (and the closing edge of a closed seam),
//!
//! `c_j(q) = ‖q_{a[k+1]} − q_{a[k]}‖ − ‖q_{b[k+1]} − q_{b[k]}‖ = 0`   (m),
//!
//! with `q` the boundary parameters of [`PatternMap`] (m; every seam vertex is a boundary vertex). The
//! same edge pairs as [`crate::SeamLength`] and as the truing of the cut patterns
//! (`skintight_garment::seam_truing`), whose constraint this is.
//!
//! **Projection.** The parameters `p` the optimizer chooses are mapped to the nearest sewable ones,
//!
//! `q(p) = argmin_q ½ ‖q − p‖²   s.t.   c(q) = 0`,
//!
//! and the pattern is `X̄ = P(q(p))` ([`PatternMap::apply`]). Only seam vertices move (the interior
//! follows through the bi-harmonic map); the nearest point in the plain Euclidean norm slides the seam
//! vertices along the seam, which keeps the boundary's shape. The KKT conditions `F(q, λ) = 0`,
//!
//! `q − p + C(q)ᵀ λ = 0`,   `c(q) = 0`,   `C = ∂c/∂q` (`#J × #p`, rows of unit edge directions ±`e/‖e‖`),
//!
//! are solved by Newton's method from `(p, 0)` with the sparse symmetric KKT matrix
//!
//! `S = [M  Cᵀ; C  −ηI]`,   `M = I + Σ_j λ_j ∂²c_j/∂q²`,   `∂²‖e‖/∂e² = (I − ê êᵀ) / ‖e‖`
//!
//! (`η = 10⁻¹⁴` m² keeps `S` regular where two constraints coincide), halving a step while it does not
//! lower `‖F‖`, until `max_j |c_j| ≤ tolerance` and the stationarity residual is below it too (quadratic
//! convergence: 2–4 steps from a near-sewable `p`). One sparse LU of `S` per step.
//!
//! **Derivative** (implicit function theorem on `F(q(p), λ(p); p) = 0`): `S [dq; dλ] = [dp; 0]`, so
//! `dq/dp` is the upper-left block of `S⁻¹` (symmetric), and a gradient `g = ∂T/∂q` pulls back to
//! `∂T/∂p = (dq/dp)ᵀ g = [S⁻¹ [g; 0]]_q` — one solve with the factor of the converged `S`
//! ([`SeamProjected::pull_back`], [`SeamProjected::push_forward`]). At a sewable `p` (`λ = 0`) it is the
//! orthogonal projection onto the tangent space of the constraints. Checked against central finite
//! differences in the tests.
//!
//! **Why this and not a penalty or an augmented Lagrangian.** The seam-length penalty at a weight that
//! leaves the fit free lets the sides drift apart by centimetres (issue 47: 32–54 mm on the leggings), and
//! truing afterwards then moves the patterns by as much and loses the fit. An augmented Lagrangian needs
//! several outer design runs (minutes each) to bring the mismatch to a millimetre. The projection holds
//! the constraint exactly at every evaluation within one run, costs one small sparse solve per Newton
//! step (`#p + #J` unknowns, against an equilibrium of the whole garment), and the optimizers see an
//! ordinary smooth objective of `p`. Constant over normal directions, the objective leaves those
//! directions alone (its gradient lies in the tangent space).

use faer::Mat;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Lu;
use faer::sparse::{SparseColMat, Triplet};

use crate::design_mesh::DesignMesh;
use crate::math::{Real, Vec2};
use crate::pattern_map::PatternMap;

/// `η` (m²): the regularization of the multipliers' block of the KKT matrix.
const REGULARIZATION: Real = 1e-14;

/// Why the seams could not be held.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SeamProjectionError {
    /// A seam does not fit the map (unequal sides, a seam vertex that is not a boundary parameter).
    #[error("seam {seam}: {message}")]
    Seam {
        /// The seam (index into [`DesignMesh::seams`]).
        seam: usize,
        /// What is wrong.
        message: String,
    },
    /// Parameters of the wrong length or not finite.
    #[error("seam projection: {0}")]
    Parameters(String),
    /// Newton's method did not make the seams sewable (sides too different, or edges collapsed).
    #[error(
        "the seams could not be made equally long: {mismatch:.3e} m left after {iterations} Newton steps"
    )]
    NotConverged {
        /// Largest `|c_j|` left (m).
        mismatch: Real,
        /// Newton steps made.
        iterations: usize,
    },
    /// The KKT matrix could not be factored.
    #[error("seam projection: the KKT matrix could not be factored ({0})")]
    Solver(String),
}

/// One pair of corresponding seam edges: the parameter index of the `x` coordinate of each end, side 0
/// and side 1.
#[derive(Clone, Copy, Debug, PartialEq)]
struct EdgePair {
    a: [usize; 2],
    b: [usize; 2],
}

/// The projection onto sewable boundary parameters (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct SeamProjection {
    pairs: Vec<EdgePair>,
    num_parameters: usize,
    tolerance: Real,
    max_iterations: usize,
}

/// A projected point `q(p)` with the factor of its KKT matrix, for derivatives.
#[derive(Clone)]
pub struct SeamProjected {
    /// `q` (m), [`PatternMap::num_parameters`] reals.
    pub parameters: Vec<Real>,
    /// `λ` (m), one per edge pair.
    pub multipliers: Vec<Real>,
    /// Newton steps made.
    pub iterations: usize,
    /// Largest `|c_j(q)|` (m).
    pub max_mismatch: Real,
    /// Largest `|q_i − p_i|` (m).
    pub max_displacement: Real,
    /// The LU of `S` at `(q, λ)`; `None` without edge pairs (then `q = p`).
    factor: Option<Lu<usize, Real>>,
    num_parameters: usize,
    num_pairs: usize,
}

impl std::fmt::Debug for SeamProjected {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SeamProjected")
            .field("iterations", &self.iterations)
            .field("max_mismatch", &self.max_mismatch)
            .field("max_displacement", &self.max_displacement)
            .finish_non_exhaustive()
    }
}

impl SeamProjection {
    /// The projection for the seams of `mesh` over the parameters of `map` (built from `mesh`), to
    /// `tolerance` (m, largest `|c_j|` left; default [`Self::DEFAULT_TOLERANCE`]). Errors name a seam
    /// whose sides differ in vertex count or whose vertex is not on a panel's outer boundary.
    pub fn new(mesh: &DesignMesh, map: &PatternMap) -> Result<Self, SeamProjectionError> {
        let mut parameter_of = vec![None; mesh.num_pattern_vertices()];
        for (p, panel) in mesh.panels.iter().enumerate() {
            let Some(range) = map.panel_parameters(p) else {
                return Err(SeamProjectionError::Parameters(format!(
                    "the map has no panel {p}"
                )));
            };
            for (k, &v) in panel.boundary.iter().enumerate() {
                if let Some(slot) = parameter_of.get_mut(v) {
                    *slot = Some(range.start + 2 * k);
                }
            }
        }
        let mut pairs = Vec::new();
        for (s, seam) in mesh.seams.iter().enumerate() {
            let [a, b] = &seam.vertices;
            let bad = |message: String| SeamProjectionError::Seam { seam: s, message };
            if a.len() != b.len() {
                return Err(bad(format!(
                    "the sides have {} and {} vertices",
                    a.len(),
                    b.len()
                )));
            }
            let index = |v: usize| {
                parameter_of.get(v).copied().flatten().ok_or_else(|| {
                    bad(format!(
                        "vertex {v} is not on a panel's outer boundary, so no design parameter moves it"
                    ))
                })
            };
            let m = a.len();
            let edges = if seam.closed && m > 1 {
                m
            } else {
                m.saturating_sub(1)
            };
            for k in 0..edges {
                let k1 = (k + 1) % m;
                let pair = EdgePair {
                    a: [index(a[k])?, index(a[k1])?],
                    b: [index(b[k])?, index(b[k1])?],
                };
                // An edge sewn to itself is always equally long: no constraint.
                let same = pair.a == pair.b || (pair.a[0] == pair.b[1] && pair.a[1] == pair.b[0]);
                if !same {
                    pairs.push(pair);
                }
            }
        }
        Ok(Self {
            pairs,
            num_parameters: map.num_parameters(),
            tolerance: Self::DEFAULT_TOLERANCE,
            max_iterations: 30,
        })
    }

    /// Default largest length difference left between two sewn edges (m): 10⁻⁹ m, far below what a sewer
    /// sees and far above round-off.
    pub const DEFAULT_TOLERANCE: Real = 1e-9;

    /// The same projection to `tolerance` (m, > 0).
    pub fn with_tolerance(mut self, tolerance: Real) -> Self {
        if tolerance.is_finite() && tolerance > 0.0 {
            self.tolerance = tolerance;
        }
        self
    }

    /// Number of constrained edge pairs `#J`.
    pub fn num_pairs(&self) -> usize {
        self.pairs.len()
    }

    /// The parameter indices the projection can move (both coordinates of every vertex of a constrained
    /// edge pair), ascending: `dq/dp` is the identity on every other parameter.
    pub fn constrained_parameters(&self) -> Vec<usize> {
        let mut out: Vec<usize> = self
            .pairs
            .iter()
            .flat_map(|p| [p.a[0], p.a[1], p.b[0], p.b[1]])
            .flat_map(|x| [x, x + 1])
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// `c(q)` (m), one entry per edge pair.
    pub fn mismatches(&self, q: &[Real]) -> Vec<Real> {
        self.pairs
            .iter()
            .map(|pair| edge(q, pair.a).norm() - edge(q, pair.b).norm())
            .collect()
    }

    /// The sewable parameters nearest `p` (m), with what their derivative needs.
    pub fn project(&self, p: &[Real]) -> Result<SeamProjected, SeamProjectionError> {
        let n = self.num_parameters;
        if p.len() != n {
            return Err(SeamProjectionError::Parameters(format!(
                "{} parameters for a map of {n}",
                p.len()
            )));
        }
        if let Some(i) = p.iter().position(|v| !v.is_finite()) {
            return Err(SeamProjectionError::Parameters(format!(
                "parameter {i} is not finite"
            )));
        }
        let nj = self.pairs.len();
        if nj == 0 {
            return Ok(SeamProjected {
                parameters: p.to_vec(),
                multipliers: Vec::new(),
                iterations: 0,
                max_mismatch: 0.0,
                max_displacement: 0.0,
                factor: None,
                num_parameters: n,
                num_pairs: 0,
            });
        }
        let mut q = p.to_vec();
        let mut lambda = vec![0.0; nj];
        let mut residual = self.kkt_residual(p, &q, &lambda);
        let mut norm = max_abs(&residual);
        let mut iterations = 0;
        loop {
            let mismatch = max_abs(&residual[n..]);
            let stationarity = max_abs(&residual[..n]);
            if mismatch <= self.tolerance && stationarity <= self.tolerance {
                let factor = self.factor(&q, &lambda)?;
                return Ok(SeamProjected {
                    max_displacement: q
                        .iter()
                        .zip(p)
                        .map(|(a, b)| (a - b).abs())
                        .fold(0.0, Real::max),
                    parameters: q,
                    multipliers: lambda,
                    iterations,
                    max_mismatch: mismatch,
                    factor: Some(factor),
                    num_parameters: n,
                    num_pairs: nj,
                });
            }
            if iterations >= self.max_iterations {
                return Err(SeamProjectionError::NotConverged {
                    mismatch,
                    iterations,
                });
            }
            iterations += 1;
            let factor = self.factor(&q, &lambda)?;
            let mut step = Mat::<Real>::from_fn(n + nj, 1, |i, _| -residual[i]);
            factor.solve_in_place(step.as_mut());
            if (0..n + nj).any(|i| !step[(i, 0)].is_finite()) {
                return Err(SeamProjectionError::Solver(
                    "the Newton step is not finite".into(),
                ));
            }
            // Halve the step while it does not lower the largest KKT residual.
            let mut alpha = 1.0;
            loop {
                let q_try: Vec<Real> = (0..n).map(|i| q[i] + alpha * step[(i, 0)]).collect();
                let l_try: Vec<Real> = (0..nj)
                    .map(|j| lambda[j] + alpha * step[(n + j, 0)])
                    .collect();
                let r_try = self.kkt_residual(p, &q_try, &l_try);
                let n_try = max_abs(&r_try);
                if n_try < norm || alpha < 1e-3 {
                    q = q_try;
                    lambda = l_try;
                    residual = r_try;
                    norm = n_try;
                    break;
                }
                alpha *= 0.5;
            }
        }
    }

    /// `F(q, λ) = [q − p + Cᵀλ; c(q)]` (m).
    fn kkt_residual(&self, p: &[Real], q: &[Real], lambda: &[Real]) -> Vec<Real> {
        let n = self.num_parameters;
        let mut r: Vec<Real> = q.iter().zip(p).map(|(q, p)| q - p).collect();
        r.reserve(self.pairs.len());
        let mut c = Vec::with_capacity(self.pairs.len());
        for (pair, &l) in self.pairs.iter().zip(lambda) {
            let (ea, eb) = (edge(q, pair.a), edge(q, pair.b));
            let (la, lb) = (ea.norm(), eb.norm());
            for (ends, e, len, sign) in [(pair.a, ea, la, 1.0), (pair.b, eb, lb, -1.0)] {
                if len > 0.0 {
                    let u = e * (sign * l / len);
                    add(&mut r, ends[1], u);
                    add(&mut r, ends[0], -u);
                }
            }
            c.push(la - lb);
        }
        debug_assert_eq!(r.len(), n);
        r.extend(c);
        r
    }

    /// The LU of `S(q, λ)`.
    fn factor(&self, q: &[Real], lambda: &[Real]) -> Result<Lu<usize, Real>, SeamProjectionError> {
        let n = self.num_parameters;
        let nj = self.pairs.len();
        let mut t: Vec<Triplet<usize, usize, Real>> = Vec::with_capacity(n + 40 * nj);
        for i in 0..n {
            t.push(Triplet::new(i, i, 1.0));
        }
        for (j, (pair, &l)) in self.pairs.iter().zip(lambda).enumerate() {
            for (ends, sign) in [(pair.a, 1.0), (pair.b, -1.0)] {
                let e = edge(q, ends);
                let len = e.norm();
                if len <= 0.0 {
                    continue;
                }
                let u = e / len;
                // Row j of C (and its transpose): ±u at the end, ∓u at the start.
                for (v, s) in [(ends[1], sign), (ends[0], -sign)] {
                    for d in 0..2 {
                        t.push(Triplet::new(n + j, v + d, s * u[d]));
                        t.push(Triplet::new(v + d, n + j, s * u[d]));
                    }
                }
                // λ_j times the Hessian of ±‖e‖: ±(I − u uᵀ)/‖e‖ on (end − start).
                let h = [[1.0 - u.x * u.x, -u.x * u.y], [-u.y * u.x, 1.0 - u.y * u.y]];
                let w = sign * l / len;
                for (v, sv) in [(ends[1], 1.0), (ends[0], -1.0)] {
                    for (x, sx) in [(ends[1], 1.0), (ends[0], -1.0)] {
                        for (dr, row) in h.iter().enumerate() {
                            for (dc, &hv) in row.iter().enumerate() {
                                t.push(Triplet::new(v + dr, x + dc, w * sv * sx * hv));
                            }
                        }
                    }
                }
            }
            t.push(Triplet::new(n + j, n + j, -REGULARIZATION));
        }
        let s = SparseColMat::<usize, Real>::try_new_from_triplets(n + nj, n + nj, &t)
            .map_err(|e| SeamProjectionError::Solver(format!("{e:?}")))?;
        s.sp_lu()
            .map_err(|e| SeamProjectionError::Solver(format!("{e:?}")))
    }
}

impl SeamProjected {
    /// `[S⁻¹ [v; 0]]_q`: `dq/dp · v`, which is also `(dq/dp)ᵀ v` (the block is symmetric).
    fn solve(&self, v: &[Real], what: &str) -> Result<Vec<Real>, SeamProjectionError> {
        let n = self.num_parameters;
        if v.len() != n {
            return Err(SeamProjectionError::Parameters(format!(
                "{what}: {} entries for {n} parameters",
                v.len()
            )));
        }
        let Some(factor) = &self.factor else {
            return Ok(v.to_vec());
        };
        let mut rhs =
            Mat::<Real>::from_fn(n + self.num_pairs, 1, |i, _| if i < n { v[i] } else { 0.0 });
        factor.solve_in_place(rhs.as_mut());
        let out: Vec<Real> = (0..n).map(|i| rhs[(i, 0)]).collect();
        if out.iter().any(|x| !x.is_finite()) {
            return Err(SeamProjectionError::Solver(format!(
                "{what}: the solve is not finite"
            )));
        }
        Ok(out)
    }

    /// `∂T/∂p = (dq/dp)ᵀ g` for a gradient `g = ∂T/∂q` (per m, one entry per parameter).
    pub fn pull_back(&self, g: &[Real]) -> Result<Vec<Real>, SeamProjectionError> {
        self.solve(g, "gradient")
    }

    /// `dq = (dq/dp) dp` for a parameter change `dp` (m).
    pub fn push_forward(&self, dp: &[Real]) -> Result<Vec<Real>, SeamProjectionError> {
        self.solve(dp, "parameter change")
    }
}

/// The edge `q[end] − q[start]` of parameter indices `ends` (x coordinates).
fn edge(q: &[Real], ends: [usize; 2]) -> Vec2 {
    Vec2::new(q[ends[1]] - q[ends[0]], q[ends[1] + 1] - q[ends[0] + 1])
}

fn add(r: &mut [Real], at: usize, v: Vec2) {
    r[at] += v.x;
    r[at + 1] += v.y;
}

fn max_abs(v: &[Real]) -> Real {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{perturbed, rng, two_panel_mesh};
    use rand::Rng;
    use skintight_geometry::finite_difference::{FdParams, check_jacobian};

    /// A two-panel mesh and its map; the seam's sides made unequal by perturbing the pattern.
    fn setup(seed: u64, closed: bool) -> (DesignMesh, PatternMap, Vec<Real>) {
        let (mut mesh, pattern) = two_panel_mesh(3, 5, seed);
        mesh.seams[0].closed = closed;
        let map = PatternMap::new(&mesh, &pattern).unwrap();
        let mut r = rng(seed + 50);
        let p: Vec<Real> = map
            .initial_parameters()
            .iter()
            .map(|v| v + 0.004 * r.random_range(-1.0..1.0))
            .collect();
        (mesh, map, p)
    }

    #[test]
    fn projected_parameters_are_sewable_and_the_nearest() {
        for seed in 0..4 {
            let closed = seed % 2 == 1;
            let (mesh, map, p) = setup(seed, closed);
            let proj = SeamProjection::new(&mesh, &map).unwrap();
            assert_eq!(proj.num_pairs(), if closed { 6 } else { 5 });
            let before = max_abs(&proj.mismatches(&p));
            assert!(before > 1e-4, "the test must start unsewable: {before}");
            let out = proj.project(&p).unwrap();
            let after = max_abs(&proj.mismatches(&out.parameters));
            assert!(after <= 1e-9, "seed {seed}: {after}");
            assert!(out.iterations >= 1 && out.iterations < 10, "{out:?}");
            // Nearest: no sewable point along the constraint set's tangent directions is closer to p.
            let d0: Real = out
                .parameters
                .iter()
                .zip(&p)
                .map(|(a, b)| (a - b).powi(2))
                .sum();
            let mut r = rng(seed + 7);
            for _ in 0..5 {
                let dq: Vec<Real> = (0..p.len())
                    .map(|_| 1e-3 * r.random_range(-1.0..1.0))
                    .collect();
                let moved: Vec<Real> = out.parameters.iter().zip(&dq).map(|(a, b)| a + b).collect();
                let other = proj.project(&moved).unwrap().parameters;
                let d1: Real = other.iter().zip(&p).map(|(a, b)| (a - b).powi(2)).sum();
                assert!(d1 >= d0 * (1.0 - 1e-9), "seed {seed}: {d1} < {d0}");
            }
            // Only the seam's vertices moved, and a sewable point stays where it is.
            let again = proj.project(&out.parameters).unwrap();
            assert!(again.max_displacement < 1e-9, "{again:?}");
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        for seed in 0..4 {
            let (mesh, map, p) = setup(10 + seed, seed % 2 == 0);
            let proj = SeamProjection::new(&mesh, &map)
                .unwrap()
                .with_tolerance(1e-13);
            let n = p.len();
            let out = proj.project(&p).unwrap();
            // Analytic Jacobian, row-major, column by column through push_forward.
            let mut jac = vec![0.0; n * n];
            for c in 0..n {
                let mut e = vec![0.0; n];
                e[c] = 1.0;
                let col = out.push_forward(&e).unwrap();
                for r in 0..n {
                    jac[r * n + c] = col[r];
                }
            }
            check_jacobian(
                |x| proj.project(x).unwrap().parameters,
                &p,
                &jac,
                &FdParams {
                    step: 1e-6,
                    rel_tol: 1e-5,
                    abs_tol: 1e-7,
                },
            )
            .unwrap_or_else(|e| panic!("seed {seed}: {e:?}"));
            // The pull-back is the transpose: ⟨g, J dp⟩ = ⟨Jᵀ g, dp⟩.
            let mut r = rng(seed + 99);
            let g: Vec<Real> = (0..n).map(|_| r.random_range(-1.0..1.0)).collect();
            let dp: Vec<Real> = (0..n).map(|_| r.random_range(-1.0..1.0)).collect();
            let jdp = out.push_forward(&dp).unwrap();
            let jtg = out.pull_back(&g).unwrap();
            let lhs: Real = g.iter().zip(&jdp).map(|(a, b)| a * b).sum();
            let rhs: Real = jtg.iter().zip(&dp).map(|(a, b)| a * b).sum();
            assert!(
                (lhs - rhs).abs() <= 1e-10 * (1.0 + lhs.abs()),
                "{lhs} vs {rhs}"
            );
        }
    }

    #[test]
    fn a_gradient_through_the_projection_matches_finite_differences() {
        // T(q) = Σ_i w_i q_i² with random weights: dT/dp by pull_back against central differences.
        let (mesh, map, p) = setup(21, false);
        let proj = SeamProjection::new(&mesh, &map)
            .unwrap()
            .with_tolerance(1e-13);
        let n = p.len();
        let mut r = rng(5);
        let w: Vec<Real> = (0..n).map(|_| r.random_range(0.5..2.0)).collect();
        let t = |q: &[Real]| q.iter().zip(&w).map(|(q, w)| w * q * q).sum::<Real>();
        let out = proj.project(&p).unwrap();
        let gq: Vec<Real> = out
            .parameters
            .iter()
            .zip(&w)
            .map(|(q, w)| 2.0 * w * q)
            .collect();
        let gp = out.pull_back(&gq).unwrap();
        skintight_geometry::finite_difference::check_gradient(
            |x| t(&proj.project(x).unwrap().parameters),
            &p,
            &gp,
            &FdParams {
                step: 1e-6,
                rel_tol: 1e-5,
                abs_tol: 1e-8,
            },
        )
        .unwrap();
    }

    #[test]
    fn large_mismatches_converge_and_bad_inputs_are_named() {
        let (mesh, pattern) = two_panel_mesh(2, 4, 3);
        let map = PatternMap::new(&mesh, &perturbed(&pattern, 0.0, 0)).unwrap();
        let proj = SeamProjection::new(&mesh, &map).unwrap();
        // One side 10 % longer than the other.
        let mut p = map.initial_parameters();
        let range = map.panel_parameters(1).unwrap();
        for v in &mut p[range] {
            *v *= 1.1;
        }
        let out = proj.project(&p).unwrap();
        assert!(max_abs(&proj.mismatches(&out.parameters)) <= 1e-9);
        assert!(proj.project(&p[1..]).is_err());
        let mut nan = p.clone();
        nan[0] = Real::NAN;
        assert!(proj.project(&nan).is_err());
        let mut bad = mesh.clone();
        bad.seams[0].vertices[1].pop();
        let e = SeamProjection::new(&bad, &map).unwrap_err();
        assert!(e.to_string().starts_with("seam 0: the sides have"), "{e}");
        // A seam vertex inside a panel is no parameter.
        let mut inner = mesh.clone();
        let interior = (0..mesh.panels[0].num_vertices)
            .find(|v| !mesh.panels[0].boundary.contains(v))
            .unwrap();
        inner.seams[0].vertices[0][1] = interior;
        let e = SeamProjection::new(&inner, &map).unwrap_err();
        assert!(
            e.to_string().contains("not on a panel's outer boundary"),
            "{e}"
        );
    }
}
