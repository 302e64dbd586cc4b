//! Seam truing: the two sides of every seam made the same length, edge by edge, with the least change to the
//! patterns — so that the pieces sew up without easing one side into the other.
//!
//! The panels are flattened one by one, so the two sides of a seam (the same curve on the body) come out of
//! the flattening with slightly different lengths (a few mm on a 600 mm leg seam). A pattern maker "trues"
//! such seams by walking them and correcting one side; here both sides move, and the interior follows.
//!
//! **Problem** (solved nearly, see the solver). With `X̄⁰` the `#Vp × 2` pattern positions (m) of all panels and `u = X̄ − X̄⁰` the change,
//!
//! `min_u  ½ Σ_t A_t ‖∇u‖²_t + ½ ε Σ_v m_v ‖u_v‖²   s.t.  c_j(X̄⁰ + u) = ‖a_{k+1} − a_k‖ − ‖b_{k+1} − b_k‖ = 0`
//!
//! for every pair `j` of corresponding seam edges (`a[k]` sewn to `b[k]`, the closing edge of a closed seam
//! included): the Dirichlet energy of the change over each pattern triangle `t` (area `A_t` in the
//! original pattern; dimensionless, m² · m⁻²), so the pieces move as smoothly as they can, plus a tiny
//! lumped-mass term `ε` (m⁻²) that pins the free translation of each panel. The energy's Hessian is
//! `K = L ⊗ I₂ + ε M` with `L` the cotangent Laplacian of each panel (the stiffness matrix of linear
//! elements, `L_ij = −½ (cot α_ij + cot β_ij)`), the same for both coordinates.
//!
//! **Solver** (Newton's method for the underdetermined system `c(X̄) = 0`, each step the smallest in the
//! energy's norm). At the current positions the constraints are linearized, `c(X̄ + δ) ≈ c + C δ` with
//! `C = ∂c/∂X̄` (`#J × 2#Vp`, rows of unit edge directions: `∂‖e‖/∂e = e / ‖e‖`), and the step `δ` minimizes
//! `½ δᵀ K δ` subject to `C δ = −c`: `δ = K⁻¹ Cᵀ μ` with `(C K⁻¹ Cᵀ) μ = −c`, halved until the largest
//! mismatch falls. One sparse Cholesky factorization of `K` for the whole solve (analyse and factorize
//! once), `#J` pairs of triangular solves per iteration for the dense `#J × #J` Schur complement (memory
//! `#J²` reals, plus `#Vp` per solve), and its dense Cholesky. The mismatch falls quadratically near the
//! solution: to the default 1e-7 m (a ten-thousandth of a millimetre) in a few iterations. (The first step
//! is the least-energy correction of the linearized problem; later steps fix what the linearization missed
//! rather than re-solving for the least total change — whose fixed-point iteration, tried first, only
//! converges linearly and stalled where a seam turns sharp corners, across the end caps of a cylinder.)
//!
//! **Why every pair of edges.** Equal sides edge by edge is more than a sewer needs (equal lengths between
//! notches would do), but it is what the simulation sews — corresponding samples are one cloth vertex — and
//! it is the robust choice: constraining only the arc length at a few anchors puts point loads on the
//! pieces, whose logarithmic response (the Green's function of the Laplacian in 2D) bends the seam between
//! samples, so the linearization stalls (tried: it stopped at 0.6 mm on the pants). Per edge the loads are
//! spread along the seam and the steps stay small.
//!
//! Pieces keep their triangles counter-clockwise (checked); the seam sides keep their vertex counts, so
//! the cloth vertices shared along a seam stay shared.

use faer::prelude::Solve;
use faer::sparse::{SparseColMat, Triplet};

use crate::garment::{Garment, GarmentSeam};
use crate::lscm::signed_area;
use crate::math::{Real, Vec2};

/// Settings of [`true_seams`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeamTruingParams {
    /// Largest length difference (m) left between two corresponding seam edges (1e-7: far below what a
    /// sewer sees).
    pub tolerance: Real,
    /// Largest number of linearized solves.
    pub max_iterations: usize,
    /// Largest number of corresponding seam edge pairs solved for at once: the Schur complement is dense,
    /// `#J²` reals (8 · 4000² B = 128 MB at the default).
    pub max_edge_pairs: usize,
}

impl Default for SeamTruingParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-7,
            max_iterations: 30,
            max_edge_pairs: 4000,
        }
    }
}

/// What [`true_seams`] changed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SeamTruingReport {
    /// Linearized solves made.
    pub iterations: usize,
    /// Corresponding seam edge pairs.
    pub edge_pairs: usize,
    /// Largest `|length(side 0) − length(side 1)|` over the seams before truing (m).
    pub max_seam_mismatch_before: Real,
    /// The same after truing (m).
    pub max_seam_mismatch_after: Real,
    /// Largest movement of a pattern vertex (m).
    pub max_displacement: Real,
    /// Wall-clock time of the truing (s).
    pub seconds: Real,
}

/// Why the seams could not be trued.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SeamTruingError {
    /// The two sides of a seam have different vertex counts (an internal inconsistency).
    #[error(
        "seam {seam} has {a} vertices on one side and {b} on the other; its sides cannot be matched edge by edge"
    )]
    UnequalSides { seam: usize, a: usize, b: usize },
    /// More corresponding edge pairs than the dense solve allows.
    #[error(
        "the seams have {pairs} edge pairs, more than the {limit} seam truing solves at once; use a coarser garment.edge_length"
    )]
    TooManyEdgePairs { pairs: usize, limit: usize },
    /// The linear algebra failed (a degenerate pattern).
    #[error("seam truing failed: {0}")]
    Solver(String),
    /// The seams could not be made equal to the tolerance.
    #[error(
        "seam truing left corresponding seam edges {mismatch:.3e} m apart in length after {iterations} iterations"
    )]
    NotConverged { mismatch: Real, iterations: usize },
    /// Truing folded a pattern triangle over (seams too different for a small correction).
    #[error(
        "seam truing folded triangle {face} of panel '{panel}' over; the two sides of its seams differ too much to be trued"
    )]
    Folded { panel: String, face: usize },
}

/// One pair of corresponding seam edges: global pattern vertex ids of the edge on side 0 and on side 1.
#[derive(Clone, Copy, Debug)]
struct EdgePair {
    a: [usize; 2],
    b: [usize; 2],
}

/// Length differences of the edge pairs (m) at global positions `x`.
fn residuals(pairs: &[EdgePair], x: &[Vec2]) -> Vec<Real> {
    pairs
        .iter()
        .map(|p| (x[p.a[1]] - x[p.a[0]]).norm() - (x[p.b[1]] - x[p.b[0]]).norm())
        .collect()
}

/// Length of one side of a seam (m) in panel `panel`'s pattern.
pub fn seam_side_length(garment: &Garment, seam: &GarmentSeam, side: usize) -> Real {
    let pattern = &garment.panels[seam.panels[side]].pattern;
    let v = &seam.vertices[side];
    let mut total: Real = v
        .windows(2)
        .map(|w| (pattern[w[1]] - pattern[w[0]]).norm())
        .sum();
    if seam.closed && v.len() > 1 {
        total += (pattern[v[0]] - pattern[v[v.len() - 1]]).norm();
    }
    total
}

/// Largest `|length(side 0) − length(side 1)|` over the seams of `garment` (m); 0 without seams.
pub fn max_seam_mismatch(garment: &Garment) -> Real {
    garment
        .seams
        .iter()
        .map(|s| (seam_side_length(garment, s, 0) - seam_side_length(garment, s, 1)).abs())
        .fold(0.0, Real::max)
}

/// Trues the seams of `garment` in place (see the module documentation): afterwards corresponding seam
/// edges have equal lengths to `params.tolerance`, so every seam's two sides are equally long. Only the
/// pattern positions change; the 3D cloth, the seams and the triangles stay as they are.
pub fn true_seams(
    garment: &mut Garment,
    params: &SeamTruingParams,
) -> Result<SeamTruingReport, SeamTruingError> {
    let start = std::time::Instant::now();
    let before = max_seam_mismatch(garment);
    // Global numbering of the pattern vertices, panel after panel.
    let mut first = Vec::with_capacity(garment.panels.len());
    let mut x0: Vec<Vec2> = Vec::new();
    for panel in &garment.panels {
        first.push(x0.len());
        x0.extend_from_slice(&panel.pattern);
    }
    let n = x0.len();
    let mut pairs = Vec::new();
    for (s, seam) in garment.seams.iter().enumerate() {
        let [a, b] = &seam.vertices;
        if a.len() != b.len() {
            return Err(SeamTruingError::UnequalSides {
                seam: s,
                a: a.len(),
                b: b.len(),
            });
        }
        let (fa, fb) = (first[seam.panels[0]], first[seam.panels[1]]);
        let m = a.len();
        let edges = if seam.closed && m > 1 {
            m
        } else {
            m.saturating_sub(1)
        };
        for k in 0..edges {
            let k1 = (k + 1) % m;
            pairs.push(EdgePair {
                a: [fa + a[k], fa + a[k1]],
                b: [fb + b[k], fb + b[k1]],
            });
        }
    }
    let mut report = SeamTruingReport {
        edge_pairs: pairs.len(),
        max_seam_mismatch_before: before,
        max_seam_mismatch_after: before,
        ..Default::default()
    };
    if pairs.is_empty() {
        return Ok(report);
    }
    if pairs.len() > params.max_edge_pairs {
        return Err(SeamTruingError::TooManyEdgePairs {
            pairs: pairs.len(),
            limit: params.max_edge_pairs,
        });
    }
    let worst = |r: &[Real]| r.iter().fold(0.0, |m: Real, c| m.max(c.abs()));
    let mut c = residuals(&pairs, &x0);
    if worst(&c) <= params.tolerance {
        return Ok(report);
    }

    // K = cotangent Laplacian of each panel + ε · lumped mass, one scalar matrix for both coordinates.
    let mut triplets: Vec<Triplet<usize, usize, Real>> = Vec::new();
    let mut mass = vec![0.0; n];
    for (p, panel) in garment.panels.iter().enumerate() {
        for f in &panel.faces {
            let g = f.map(|v| first[p] + v);
            let q = g.map(|v| x0[v]);
            let area = signed_area(q[0], q[1], q[2]);
            if !(area > 0.0) {
                return Err(SeamTruingError::Solver(format!(
                    "panel '{}' has a triangle without positive area",
                    panel.name
                )));
            }
            for k in 0..3 {
                let (i, j, o) = (g[(k + 1) % 3], g[(k + 2) % 3], k);
                // Cotangent of the angle at corner o, opposite edge (i, j).
                let (u, w) = (q[(k + 1) % 3] - q[o], q[(k + 2) % 3] - q[o]);
                let cot = u.dot(&w) / (2.0 * area);
                let h = 0.5 * cot;
                triplets.push(Triplet::new(i, j, -h));
                triplets.push(Triplet::new(j, i, -h));
                triplets.push(Triplet::new(i, i, h));
                triplets.push(Triplet::new(j, j, h));
                mass[g[k]] += area / 3.0;
            }
        }
    }
    // ε: small against the Laplacian (whose entries are O(1)), relative to the mean vertex area.
    let mean_mass = mass.iter().sum::<Real>() / n as Real;
    let eps = 1e-6 / mean_mass.max(Real::MIN_POSITIVE);
    for (v, &m) in mass.iter().enumerate() {
        // Vertices outside every triangle (none in a valid garment) still get a positive diagonal.
        triplets.push(Triplet::new(v, v, eps * m.max(mean_mass)));
    }
    let k = SparseColMat::<usize, Real>::try_new_from_triplets(n, n, &triplets)
        .map_err(|e| SeamTruingError::Solver(format!("{e:?}")))?;
    let llt = k
        .sp_cholesky(faer::Side::Lower)
        .map_err(|e| SeamTruingError::Solver(format!("{e:?}")))?;

    let m = pairs.len();
    let mut u = vec![Vec2::zeros(); n];
    let mut x = x0.clone();
    let mut iterations = 0;
    while worst(&c) > params.tolerance {
        if iterations == params.max_iterations {
            return Err(SeamTruingError::NotConverged {
                mismatch: worst(&c),
                iterations,
            });
        }
        iterations += 1;
        // Rows of C: ∂c_j/∂X̄ = (−t_a at a0, +t_a at a1, +t_b at b0, −t_b at b1), t unit edge directions.
        let rows: Vec<[(usize, Vec2); 4]> = pairs
            .iter()
            .map(|p| {
                let unit = |e: Vec2| {
                    let l = e.norm();
                    if l > 0.0 { e / l } else { Vec2::zeros() }
                };
                let ta = unit(x[p.a[1]] - x[p.a[0]]);
                let tb = unit(x[p.b[1]] - x[p.b[0]]);
                [(p.a[0], -ta), (p.a[1], ta), (p.b[0], tb), (p.b[1], -tb)]
            })
            .collect();
        // S = C K⁻¹ Cᵀ (#J × #J, symmetric positive definite for independent rows), column by column: one
        // solve of K per edge pair, both coordinates at once (K acts on each coordinate alike).
        let spread = |weights: &dyn Fn(usize) -> Real| {
            let mut rhs = faer::Mat::<Real>::zeros(n, 2);
            for (j, row) in rows.iter().enumerate() {
                let w = weights(j);
                if w != 0.0 {
                    for &(v, g) in row {
                        rhs[(v, 0)] += w * g.x;
                        rhs[(v, 1)] += w * g.y;
                    }
                }
            }
            rhs
        };
        let mut s = faer::Mat::<Real>::zeros(m, m);
        for j in 0..m {
            let col = llt.solve(spread(&|i| if i == j { 1.0 } else { 0.0 }));
            for (i, row) in rows.iter().enumerate() {
                s[(i, j)] = row
                    .iter()
                    .map(|&(v, g)| g.x * col[(v, 0)] + g.y * col[(v, 1)])
                    .sum();
            }
        }
        let rhs = faer::Col::<Real>::from_fn(m, |i| -c[i]);
        // Rows can be dependent (a closed seam of equal sides); a tiny diagonal shift keeps S definite.
        let shift = 1e-12 * (0..m).map(|i| s[(i, i)]).fold(0.0, Real::max);
        for i in 0..m {
            s[(i, i)] += shift;
        }
        let mu = s
            .llt(faer::Side::Lower)
            .map_err(|e| SeamTruingError::Solver(format!("{e:?}")))?
            .solve(&rhs);
        let z = llt.solve(spread(&|j| mu[j]));
        let step: Vec<Vec2> = (0..n).map(|v| Vec2::new(z[(v, 0)], z[(v, 1)])).collect();
        if step.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
            return Err(SeamTruingError::Solver(
                "the correction is not finite".into(),
            ));
        }
        // Backtracking: halve the step until the largest mismatch falls.
        let before = worst(&c);
        let mut t = 1.0;
        loop {
            let trial: Vec<Vec2> = (0..n).map(|v| x[v] + step[v] * t).collect();
            let ct = residuals(&pairs, &trial);
            if worst(&ct) < before || t < 1e-3 {
                x = trial;
                c = ct;
                break;
            }
            t *= 0.5;
        }
    }
    for (v, uv) in u.iter_mut().enumerate() {
        *uv = x[v] - x0[v];
    }

    // Write back, refusing a fold.
    for (p, panel) in garment.panels.iter().enumerate() {
        for (fi, f) in panel.faces.iter().enumerate() {
            let q = f.map(|v| x[first[p] + v]);
            if !(signed_area(q[0], q[1], q[2]) > 0.0) {
                return Err(SeamTruingError::Folded {
                    panel: panel.name.clone(),
                    face: fi,
                });
            }
        }
    }
    for (p, panel) in garment.panels.iter_mut().enumerate() {
        for (k, v) in panel.pattern.iter_mut().enumerate() {
            *v = x[first[p] + k];
        }
    }
    report.iterations = iterations;
    report.max_displacement = u.iter().map(|d| d.norm()).fold(0.0, Real::max);
    report.max_seam_mismatch_after = max_seam_mismatch(garment);
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}
