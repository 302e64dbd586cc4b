//! The adjoint Gauss-Newton direction in reduced form: the same direction as the KKT system of
//! [`crate::kkt_direction`] (`(2 R_totᵀ R_tot + κ I) dc = −g`, see its module documentation for the
//! symbols), computed by forming the sensitivity `S = −H⁻¹ K A` with **one multi-column solve** against
//! the equilibrium's Cholesky factor and then the small dense `#c × #c` Gauss-Newton matrix.
//!
//! **When.** The KKT system avoids the dense matrix but its indefinite sparse LU fills in badly when the
//! design map `A` is dense per panel (every interior pattern vertex follows every boundary parameter of
//! its panel): on the tapered cylinder (4650 unknowns, 570 parameters) one KKT factorization takes
//! ~15 s, almost all of it dense updates of large supernodes. Here the cost is one supernodal solve
//! with `#c` right-hand sides (the factor exists already), `nnz(R_q) · #c` for `R_q S`, and
//! `#r · #c²` for `R_totᵀ R_tot` — well under a second at that size. The memory is the dense `#q × #c`
//! sensitivity, which is why [`crate::GaussNewtonSolver::Auto`] falls back to the KKT system for very
//! large `#q · #c`.
//!
//! ```text
//! Z = H⁻¹ (K A)                 (#q × #c, one solve with #c columns)
//! R_tot = −R_q Z + R_X A        (#r × #c, R_q = R_x J + the direct ∂r/∂q)
//! (2 R_totᵀ R_tot + κ I) dc = −g,   dq = −Z dc,   dX̄ = A dc
//! ```

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::matmul::sparse_dense_matmul;
use faer::{Accum, Mat, MatRef, Par, Side};

use crate::kkt_direction::{
    GaussNewtonDirection, GaussNewtonError, GaussNewtonSystem, MixedDerivative,
};
use crate::math::Real;

/// Entries of a column-compressed matrix as `(row, column, value)`.
fn entries(
    m: faer::sparse::SparseColMatRef<'_, usize, Real>,
) -> impl Iterator<Item = (usize, usize, Real)> + '_ {
    let (cp, ri, v) = (m.symbolic().col_ptr(), m.symbolic().row_idx(), m.val());
    (0..m.ncols()).flat_map(move |c| (cp[c]..cp[c + 1]).map(move |k| (ri[k], c, v[k])))
}

/// The damped Gauss-Newton direction `dc` of `system` with damping `κ ≥ 0` (units of `T` per unit² of
/// `c`), through the sensitivity matrix. `solve_hessian(rhs, columns)` overwrites the column-major
/// `#q × columns` block `rhs` with `H⁻¹ rhs` (the same `H` as `system.hessian`, e.g.
/// [`crate::DesignProblem::solve_hessian_columns`]). `system.hessian` itself is not read.
///
/// Errors: inputs of inconsistent sizes or non-finite values ([`GaussNewtonError::Invalid`]); a failed
/// Hessian solve or a Gauss-Newton matrix that does not factor ([`GaussNewtonError::Solve`]).
pub fn reduced_gauss_newton_direction(
    system: &GaussNewtonSystem<'_>,
    damping: Real,
    mut solve_hessian: impl FnMut(&mut [Real], usize) -> Result<(), String>,
) -> Result<GaussNewtonDirection, GaussNewtonError> {
    let bad = |m: String| Err(GaussNewtonError::Invalid(m));
    let res = system.residuals;
    let nr = res.values.len();
    let j = system.cloth_jacobian;
    let nq = j.ncols();
    let a = system.design_map;
    let nx = a.nrows();
    let nc = a.ncols();
    if j.nrows() % 3 != 0 {
        return bad(format!(
            "the cloth Jacobian has {} rows, not 3 per vertex",
            j.nrows()
        ));
    }
    let nvc = j.nrows() / 3;
    match system.mixed {
        MixedDerivative::Matrix(k) if k.nrows() != nq || k.ncols() != nx || nx % 2 != 0 => {
            return bad(format!(
                "the mixed derivative is {} × {} for {nq} unknowns and the design map's {nx} pattern \
                 coordinates (2 per pattern vertex)",
                k.nrows(),
                k.ncols()
            ));
        }
        MixedDerivative::TimesDesignMap(ka) if ka.len() != nq * nc => {
            return bad(format!(
                "K A has {} entries for {nq} unknowns × {nc} parameters",
                ka.len()
            ));
        }
        _ => {}
    }
    if system.gradient.len() != nc {
        return bad(format!(
            "the gradient has {} entries for {nc} design parameters",
            system.gradient.len()
        ));
    }
    if !(damping.is_finite() && damping >= 0.0) {
        return bad(format!("the damping must be finite and ≥ 0, got {damping}"));
    }
    if nr == 0 && damping == 0.0 {
        return bad("no residuals and no damping: the Gauss-Newton matrix is zero".into());
    }
    if let Some(&(k, c, _)) = res
        .cloth_jacobian
        .iter()
        .find(|(k, c, _)| *k >= nr || *c >= nvc)
    {
        return bad(format!(
            "residual Jacobian entry ({k}, cloth vertex {c}) out of range"
        ));
    }
    if let Some(&(k, v, _)) = res
        .pattern_jacobian
        .iter()
        .find(|(k, v, _)| *k >= nr || 2 * v >= nx)
    {
        return bad(format!(
            "residual Jacobian entry ({k}, pattern vertex {v}) out of range"
        ));
    }
    if let Some(&(k, q, _)) = res
        .state_jacobian
        .iter()
        .find(|(k, q, _)| *k >= nr || *q >= nq)
    {
        return bad(format!(
            "residual Jacobian entry ({k}, unknown {q}) out of range"
        ));
    }
    let finite = res.state_jacobian.iter().all(|e| e.2.is_finite())
        && system.gradient.iter().all(|v| v.is_finite())
        && res
            .cloth_jacobian
            .iter()
            .all(|e| e.2.iter().all(|v| v.is_finite()))
        && res
            .pattern_jacobian
            .iter()
            .all(|e| e.2.iter().all(|v| v.is_finite()))
        && entries(j).all(|e| e.2.is_finite())
        && match system.mixed {
            MixedDerivative::Matrix(k) => entries(k).all(|e| e.2.is_finite()),
            MixedDerivative::TimesDesignMap(ka) => ka.iter().all(|v| v.is_finite()),
        }
        && entries(a).all(|e| e.2.is_finite());
    if !finite {
        return bad("a residual derivative, gradient, J, K or A entry is not finite".into());
    }

    // Z = H⁻¹ K A (A made dense: it is dense per panel anyway).
    let mut a_dense = Mat::<Real>::zeros(nx, nc);
    for (x, c, v) in entries(a) {
        a_dense[(x, c)] += v;
    }
    let mut z: Vec<Real> = match system.mixed {
        MixedDerivative::TimesDesignMap(ka) => ka.to_vec(),
        MixedDerivative::Matrix(k) => {
            let mut ka = Mat::<Real>::zeros(nq, nc);
            sparse_dense_matmul(
                ka.as_mut(),
                Accum::Replace,
                k,
                a_dense.as_ref(),
                1.0,
                Par::rayon(0),
            );
            (0..nc)
                .flat_map(|c| ka.col(c).iter().copied().collect::<Vec<_>>())
                .collect()
        }
    };
    solve_hessian(&mut z, nc).map_err(GaussNewtonError::Solve)?;
    if z.iter().any(|v| !v.is_finite()) {
        return Err(GaussNewtonError::Solve(
            "the sensitivity H⁻¹ K A is not finite".into(),
        ));
    }
    let z = MatRef::from_column_major_slice(&z, nq, nc);
    // Rows of Z and of A made contiguous (`Zᵀ`, `Aᵀ`), so every residual-Jacobian entry is one axpy of
    // length #c into its row of R_tot (kept transposed, `R_totᵀ`: #c × #r): no sorting of the entries.
    let zt: Vec<Real> = (0..nq)
        .flat_map(|q| (0..nc).map(move |c| z[(q, c)]))
        .collect();
    let a_ref = a_dense.as_ref();
    let at: Vec<Real> = (0..nx)
        .flat_map(|x| (0..nc).map(move |c| a_ref[(x, c)]))
        .collect();
    let mut rt = vec![0.0; nr * nc];
    let mut axpy = |k: usize, w: Real, src: &[Real]| {
        for (d, s) in rt[k * nc..(k + 1) * nc].iter_mut().zip(src) {
            *d += w * s;
        }
    };
    // R_q = R_x J + the direct part: −R_q Z.
    let mut j_rows: Vec<Vec<(usize, [Real; 3])>> = vec![Vec::new(); nvc];
    for (r, c, v) in entries(j) {
        let row = &mut j_rows[r / 3];
        match row.iter_mut().find(|(d, _)| *d == c) {
            Some((_, e)) => e[r % 3] += v,
            None => {
                let mut e = [0.0; 3];
                e[r % 3] = v;
                row.push((c, e));
            }
        }
    }
    for &(row, cv, d) in &res.cloth_jacobian {
        for &(q, e) in &j_rows[cv] {
            let w = d.x * e[0] + d.y * e[1] + d.z * e[2];
            if w != 0.0 {
                axpy(row, -w, &zt[q * nc..(q + 1) * nc]);
            }
        }
    }
    for &(row, q, d) in &res.state_jacobian {
        if d != 0.0 {
            axpy(row, -d, &zt[q * nc..(q + 1) * nc]);
        }
    }
    // + R_X A.
    for &(row, v, d) in &res.pattern_jacobian {
        for (i, dv) in [d.x, d.y].into_iter().enumerate() {
            if dv != 0.0 {
                let x = 2 * v + i;
                axpy(row, dv, &at[x * nc..(x + 1) * nc]);
            }
        }
    }
    drop(zt);
    let r_tot_t = MatRef::from_column_major_slice(&rt, nc, nr);

    // (2 R_totᵀ R_tot + κ I) dc = −g.
    let mut m = Mat::<Real>::zeros(nc, nc);
    matmul(
        m.as_mut(),
        Accum::Replace,
        r_tot_t,
        r_tot_t.transpose(),
        2.0,
        Par::rayon(0),
    );
    for i in 0..nc {
        m[(i, i)] += damping;
    }
    let rhs = Mat::<Real>::from_fn(nc, 1, |i, _| -system.gradient[i]);
    let llt = m.llt(Side::Lower).map_err(|e| {
        GaussNewtonError::Solve(format!(
            "the Gauss-Newton matrix does not factor ({e:?}): no damping and rank-deficient residuals"
        ))
    })?;
    let dc = llt.solve(&rhs);
    let design: Vec<Real> = (0..nc).map(|i| dc[(i, 0)]).collect();
    // Residual of the normal equations, relative to ‖g‖.
    let check = &m * &dc;
    let g_norm = system.gradient.iter().map(|v| v * v).sum::<Real>().sqrt();
    let r_norm = (0..nc)
        .map(|i| (check[(i, 0)] - rhs[(i, 0)]).powi(2))
        .sum::<Real>()
        .sqrt();
    let residual = if g_norm > 0.0 { r_norm / g_norm } else { 0.0 };
    if !(residual.is_finite() && residual < 1e-6) || design.iter().any(|v| !v.is_finite()) {
        return Err(GaussNewtonError::Solve(format!(
            "the solution is not accurate (relative residual {residual:e}): the Gauss-Newton matrix is \
             singular or nearly so"
        )));
    }
    let mut state = vec![0.0; nq];
    for (c, dc) in design.iter().enumerate() {
        for (sq, zq) in state.iter_mut().zip(z.col(c).iter()) {
            *sq -= zq * dc;
        }
    }
    let mut pattern = vec![0.0; nx];
    for (x, c, v) in entries(a) {
        pattern[x] += v * design[c];
    }
    Ok(GaussNewtonDirection {
        design,
        state,
        pattern,
        kkt_residual: residual,
        reused_analysis: true,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kkt_direction::AdjointGaussNewton;
    use crate::kkt_direction::tests::{dense_direction, random, solve, sparse};
    use nalgebra::DMatrix;

    #[test]
    fn reduced_direction_equals_the_dense_and_kkt_directions() {
        for (seed, nr) in [(0_u64, 7), (1, 3), (2, 12), (3, 0)] {
            let p = random(seed, nr);
            let (j, h, k, a) = (
                sparse(&p.j, false),
                sparse(&p.h, true),
                sparse(&p.k, false),
                sparse(&p.a, false),
            );
            let system = GaussNewtonSystem {
                residuals: &p.residuals,
                cloth_jacobian: j.as_ref(),
                hessian: h.as_ref(),
                mixed: MixedDerivative::Matrix(k.as_ref()),
                design_map: a.as_ref(),
                gradient: &p.g,
            };
            let lu = p.h.clone().lu();
            let nq = p.h.nrows();
            let solve_h = |rhs: &mut [Real], columns: usize| {
                let b = DMatrix::from_column_slice(nq, columns, rhs);
                let x = lu.solve(&b).ok_or("singular")?;
                rhs.copy_from_slice(x.as_slice());
                Ok::<(), String>(())
            };
            // K A formed beforehand (as the design loop does, matrix-free) gives the same direction.
            let ka = &p.k * &p.a;
            let times = GaussNewtonSystem {
                mixed: MixedDerivative::TimesDesignMap(ka.as_slice()),
                ..system
            };
            for kappa in [1e-3, 1.0, 100.0] {
                let d = reduced_gauss_newton_direction(&system, kappa, solve_h).unwrap();
                let e = reduced_gauss_newton_direction(&times, kappa, solve_h).unwrap();
                for (a, b) in d.design.iter().zip(&e.design) {
                    assert!(
                        (a - b).abs() <= 1e-12 * (1.0 + a.abs()),
                        "K A given: {b} vs {a}"
                    );
                }
                let expected = dense_direction(&p, kappa);
                let kkt = solve(&mut AdjointGaussNewton::new(), &p, kappa);
                let scale = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                for ((a, b), c) in d.design.iter().zip(&expected).zip(&kkt.design) {
                    assert!(
                        (a - b).abs() <= 1e-8 * scale && (a - c).abs() <= 1e-8 * scale,
                        "seed {seed} κ {kappa}: {a} vs dense {b}, KKT {c}"
                    );
                }
                for (a, b) in d.state.iter().zip(&kkt.state) {
                    assert!((a - b).abs() <= 1e-8 * scale.max(1e-300) * 1e3);
                }
                for (a, b) in d.pattern.iter().zip(&kkt.pattern) {
                    assert!((a - b).abs() <= 1e-8 * scale.max(1e-300));
                }
            }
            let short = GaussNewtonSystem {
                mixed: MixedDerivative::TimesDesignMap(&ka.as_slice()[1..]),
                ..system
            };
            assert!(matches!(
                reduced_gauss_newton_direction(&short, 1.0, solve_h),
                Err(GaussNewtonError::Invalid(_))
            ));
            assert!(matches!(
                reduced_gauss_newton_direction(&system, -1.0, solve_h),
                Err(GaussNewtonError::Invalid(_))
            ));
            assert!(matches!(
                reduced_gauss_newton_direction(&system, 1.0, |_, _| Err("no factor".into())),
                Err(GaussNewtonError::Solve(_))
            ));
        }
    }
}
