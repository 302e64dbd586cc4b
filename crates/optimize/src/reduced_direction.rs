//! The adjoint Gauss-Newton direction in reduced form: the same direction as the KKT system of
//! [`mod@crate::kkt_direction`] (`(2 R_totᵀ R_tot + κ I) dc = −g`, symbols as in
//! [`mod@crate::linearization`]), computed by forming the sensitivity `S = −H⁻¹ K A` with **one
//! multi-column solve** against the equilibrium's factor and then the small dense `#c × #c` Gauss-Newton
//! matrix.
//!
//! ```text
//! Z = H⁻¹ (K A)                 (#q × #c, one solve with #c columns)
//! R_tot = −R_q Z + R_p A        (#r × #c)
//! (2 R_totᵀ R_tot + κ I) dc = −g,   dq = −Z dc,   dp = A dc
//! ```
//!
//! **When.** The KKT system avoids the dense matrix, but its indefinite sparse LU fills in badly when `A`
//! is dense (every interior pattern vertex of a design follows every boundary parameter of its panel):
//! almost all of its time goes into dense updates of large supernodes (docs/BENCHMARKS.md, "Moved from
//! module docs (issue 42, optimize)"). Here the cost is one solve with `#c` right-hand sides against a
//! factor that exists already, `nnz(R_q) · #c` for `R_q Z`, and `#r · #c²` for `R_totᵀ R_tot`. The memory
//! is the dense `#q × #c` sensitivity, which is why [`crate::GaussNewtonSolver::Auto`] falls back to the
//! KKT system for very large `#q · #c`.
//!
//! `R_tot` is accumulated in the order of the caller's Jacobian entries, the state entries first, so that
//! a given linearization gives the same bits every time.

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::matmul::sparse_dense_matmul;
use faer::{Accum, Mat, MatRef, Par, Side};

use crate::Real;
use crate::linearization::{
    GaussNewtonDirection, GaussNewtonError, GaussNewtonSystem, MixedDerivative, Unknown, entries,
    out_of_range,
};

/// The damped Gauss-Newton direction `dc` of `system` with damping `κ ≥ 0` (units of `T` per unit² of
/// `c`), through the sensitivity matrix. `solve_hessian(rhs, columns)` overwrites the column-major
/// `#q × columns` block `rhs` with `H⁻¹ rhs` (the same `H` as the linearization's, e.g. with its
/// factor, [`crate::AdjointProblem::solve_hessian`]); the linearization's `hessian` gives only `#q`.
///
/// Errors: inputs of inconsistent sizes or non-finite values ([`GaussNewtonError::Invalid`]); a failed
/// Hessian solve or a Gauss-Newton matrix that does not factor ([`GaussNewtonError::Solve`]).
pub fn reduced_direction(
    system: &GaussNewtonSystem<'_>,
    damping: Real,
    mut solve_hessian: impl FnMut(&mut [Real], usize) -> Result<(), String>,
) -> Result<GaussNewtonDirection, GaussNewtonError> {
    let bad = |m: String| Err(GaussNewtonError::Invalid(m));
    let lin = system.linearization;
    let nr = lin.residuals.len();
    let nq = lin.hessian.ncols();
    let a = system.parameter_map;
    let nx = a.nrows();
    let nc = a.ncols();
    match &lin.mixed {
        MixedDerivative::Matrix(k) if k.nrows() != nq || k.ncols() != nx => {
            return bad(format!(
                "the mixed derivative is {} × {} for {nq} unknowns and the parameter map's {nx} \
                 parameters",
                k.nrows(),
                k.ncols()
            ));
        }
        MixedDerivative::TimesParameterMap(ka) if ka.len() != nq * nc => {
            return bad(format!(
                "K A has {} entries for {nq} unknowns × {nc} variables",
                ka.len()
            ));
        }
        _ => {}
    }
    if system.gradient.len() != nc {
        return bad(format!(
            "the gradient has {} entries for {nc} variables",
            system.gradient.len()
        ));
    }
    if !(damping.is_finite() && damping >= 0.0) {
        return bad(format!("the damping must be finite and ≥ 0, got {damping}"));
    }
    if nr == 0 && damping == 0.0 {
        return bad("no residuals and no damping: the Gauss-Newton matrix is zero".into());
    }
    if let Some(m) = out_of_range(&lin.jacobian, nr, nq, nx) {
        return bad(m);
    }
    let finite = lin.jacobian.iter().all(|e| e.2.is_finite())
        && system.gradient.iter().all(|v| v.is_finite())
        && match &lin.mixed {
            MixedDerivative::Matrix(k) => entries(k.as_ref()).all(|e| e.2.is_finite()),
            MixedDerivative::TimesParameterMap(ka) => ka.iter().all(|v| v.is_finite()),
        }
        && entries(a).all(|e| e.2.is_finite());
    if !finite {
        return bad("a residual derivative, gradient, K or A entry is not finite".into());
    }

    // Z = H⁻¹ K A (A made dense: where this form pays, it is dense anyway).
    let mut a_dense = Mat::<Real>::zeros(nx, nc);
    for (x, c, v) in entries(a) {
        a_dense[(x, c)] += v;
    }
    let mut z: Vec<Real> = match &lin.mixed {
        MixedDerivative::TimesParameterMap(ka) => ka.clone(),
        MixedDerivative::Matrix(k) => {
            let mut ka = Mat::<Real>::zeros(nq, nc);
            sparse_dense_matmul(
                ka.as_mut(),
                Accum::Replace,
                k.as_ref(),
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
    // −R_q Z (the state entries in order), then + R_p A.
    for &(row, u, v) in &lin.jacobian {
        if let Unknown::State(q) = u
            && v != 0.0
        {
            axpy(row, -v, &zt[q * nc..(q + 1) * nc]);
        }
    }
    for &(row, u, v) in &lin.jacobian {
        if let Unknown::Parameter(x) = u
            && v != 0.0
        {
            axpy(row, v, &at[x * nc..(x + 1) * nc]);
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
        variables: design,
        state,
        parameters: pattern,
        residual,
        reused_analysis: true,
    })
}

#[cfg(test)]
mod tests;
