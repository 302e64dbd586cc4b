//! The factorization of a shifted matrix `A + σ D` (`D` a positive diagonal metric, `σ ≥ 0` a shift in
//! the units of `A` per unit of `D`), retried with larger shifts while it is not positive definite.
//!
//! Away from a minimum the Hessian of an energy may be indefinite (compressed rods, contact, a surface
//! chart's curvature); a large enough shift makes it positive definite, so the sparse Cholesky applies
//! to every matrix a Newton solve factors. The rule that raises the shift is the caller's (its damping
//! policy: [`super::LevenbergMarquardt::raised`], or the adjoint's decades), and so is the limit where it
//! gives up.

use crate::sparse_cholesky::CholeskyError;

/// Adds `shift · metric[i]` to the entry at `slots[i]` of `values` (the diagonal of a matrix stored by
/// its values, `slots` the positions of its diagonal entries).
pub fn add_to_diagonal(values: &mut [f64], slots: &[usize], shift: f64, metric: &[f64]) {
    for (&p, d) in slots.iter().zip(metric) {
        values[p] += shift * d;
    }
}

/// Whether a factorization failed only because the matrix is not positive definite (a larger shift may
/// factor).
pub fn indefinite(error: &CholeskyError) -> bool {
    matches!(error, CholeskyError::NotPositiveDefinite { .. })
}

/// Calls `factor(σ)` for `σ = first`, then for each shift `raise` gives after a failure that
/// `is_indefinite` says a larger shift may cure, until one factors (returns its `σ`), `raise` gives up
/// (`None`) or `factor` fails otherwise: then the last shift tried with its error.
pub fn shifted_factorization<E>(
    first: f64,
    mut raise: impl FnMut(f64) -> Option<f64>,
    mut factor: impl FnMut(f64) -> Result<(), E>,
    is_indefinite: impl Fn(&E) -> bool,
) -> Result<f64, (f64, E)> {
    let mut shift = first;
    loop {
        match factor(shift) {
            Ok(()) => return Ok(shift),
            Err(e) if is_indefinite(&e) => match raise(shift) {
                Some(next) => shift = next,
                None => return Err((shift, e)),
            },
            Err(e) => return Err((shift, e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shift_rises_until_the_matrix_factors_or_the_rule_gives_up() {
        // A 1 × 1 matrix −2 + σ·1 factors once σ > 2.
        let attempt = |sigma: f64| {
            if -2.0 + sigma > 0.0 {
                Ok(())
            } else {
                Err(CholeskyError::NotPositiveDefinite {
                    pivot: 0,
                    unknown: 0,
                })
            }
        };
        let raise = |s: f64| (s < 100.0).then(|| (10.0 * s).max(1e-6));
        assert_eq!(
            shifted_factorization(0.0, raise, attempt, indefinite),
            Ok(10.0)
        );
        let (last, e) =
            shifted_factorization(0.0, |s| (s < 1.0).then(|| s + 0.5), attempt, indefinite)
                .unwrap_err();
        assert_eq!(last, 1.0);
        assert!(indefinite(&e));
        let mut values = vec![1.0, 5.0, 2.0];
        add_to_diagonal(&mut values, &[0, 2], 0.5, &[2.0, 4.0]);
        assert_eq!(values, [2.0, 5.0, 4.0]);
    }
}
