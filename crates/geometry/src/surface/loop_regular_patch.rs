//! The 12 quartic box-spline basis functions of a regular Loop patch (thesis appendix A, Eq. 189;
//! Stam 1998, appendix) with their first and second derivatives in closed form.
//!
//! # Control vertex ordering
//!
//! The patch is the face `[7, 8, 4]` (1-based labels of Eq. 189) of the regular 12-vertex neighbourhood
//!
//! ```text
//!        1 --- 2
//!       / \   / \
//!      3 --- 4 --- 5
//!     / \   / \   / \
//!    6 --- 7 --- 8 --- 9
//!     \   / \   / \   /
//!      10 -- 11 -- 12
//! ```
//!
//! with `s1` the weight of vertex 7, `s2` of vertex 8 and `s3 = 1 − s1 − s2` of vertex 4 (thesis: `b1 =
//! s3⁴ + 2 s3³ s1`; Stam's `u, v, w` are `s3, s1, s2`). The labelling is fixed by adjacency: 3 is the common
//! neighbour of 4 and 7 other than 8, 5 of 4 and 8 other than 7, 11 of 7 and 8 other than 4, 1 of 3 and 4
//! other than 7, 2 of 4 and 5 other than 8, 6 of 3 and 7 other than 4, 10 of 7 and 11 other than 8, 12 of 8
//! and 11 other than 7, 9 of 5 and 8 other than 4. Arrays below are 0-based (`index = label − 1`).

use crate::math::Real;

/// Terms `(coefficient, [power of s1, power of s2, power of s3])` of `12 b_i` (Eq. 189).
const TERMS: [&[(Real, [u8; 3])]; 12] = [
    // b1
    &[(1.0, [0, 0, 4]), (2.0, [1, 0, 3])],
    // b2
    &[(1.0, [0, 0, 4]), (2.0, [0, 1, 3])],
    // b3
    &[
        (1.0, [0, 0, 4]),
        (2.0, [0, 1, 3]),
        (6.0, [1, 0, 3]),
        (6.0, [1, 1, 2]),
        (12.0, [2, 0, 2]),
        (6.0, [2, 1, 1]),
        (6.0, [3, 0, 1]),
        (2.0, [3, 1, 0]),
        (1.0, [4, 0, 0]),
    ],
    // b4
    &[
        (6.0, [0, 0, 4]),
        (24.0, [0, 1, 3]),
        (24.0, [0, 2, 2]),
        (8.0, [0, 3, 1]),
        (1.0, [0, 4, 0]),
        (24.0, [1, 0, 3]),
        (60.0, [1, 1, 2]),
        (36.0, [1, 2, 1]),
        (6.0, [1, 3, 0]),
        (24.0, [2, 0, 2]),
        (36.0, [2, 1, 1]),
        (12.0, [2, 2, 0]),
        (8.0, [3, 0, 1]),
        (6.0, [3, 1, 0]),
        (1.0, [4, 0, 0]),
    ],
    // b5
    &[
        (1.0, [0, 0, 4]),
        (6.0, [0, 1, 3]),
        (12.0, [0, 2, 2]),
        (6.0, [0, 3, 1]),
        (1.0, [0, 4, 0]),
        (2.0, [1, 0, 3]),
        (6.0, [1, 1, 2]),
        (6.0, [1, 2, 1]),
        (2.0, [1, 3, 0]),
    ],
    // b6
    &[(2.0, [3, 0, 1]), (1.0, [4, 0, 0])],
    // b7
    &[
        (1.0, [0, 0, 4]),
        (6.0, [0, 1, 3]),
        (12.0, [0, 2, 2]),
        (6.0, [0, 3, 1]),
        (1.0, [0, 4, 0]),
        (8.0, [1, 0, 3]),
        (36.0, [1, 1, 2]),
        (36.0, [1, 2, 1]),
        (8.0, [1, 3, 0]),
        (24.0, [2, 0, 2]),
        (60.0, [2, 1, 1]),
        (24.0, [2, 2, 0]),
        (24.0, [3, 0, 1]),
        (24.0, [3, 1, 0]),
        (6.0, [4, 0, 0]),
    ],
    // b8
    &[
        (1.0, [0, 0, 4]),
        (8.0, [0, 1, 3]),
        (24.0, [0, 2, 2]),
        (24.0, [0, 3, 1]),
        (6.0, [0, 4, 0]),
        (6.0, [1, 0, 3]),
        (36.0, [1, 1, 2]),
        (60.0, [1, 2, 1]),
        (24.0, [1, 3, 0]),
        (12.0, [2, 0, 2]),
        (36.0, [2, 1, 1]),
        (24.0, [2, 2, 0]),
        (6.0, [3, 0, 1]),
        (8.0, [3, 1, 0]),
        (1.0, [4, 0, 0]),
    ],
    // b9
    &[(2.0, [0, 3, 1]), (1.0, [0, 4, 0])],
    // b10
    &[(2.0, [3, 1, 0]), (1.0, [4, 0, 0])],
    // b11
    &[
        (2.0, [0, 3, 1]),
        (1.0, [0, 4, 0]),
        (6.0, [1, 2, 1]),
        (6.0, [1, 3, 0]),
        (6.0, [2, 1, 1]),
        (12.0, [2, 2, 0]),
        (2.0, [3, 0, 1]),
        (6.0, [3, 1, 0]),
        (1.0, [4, 0, 0]),
    ],
    // b12
    &[(1.0, [0, 4, 0]), (2.0, [1, 3, 0])],
];

/// Values and derivatives of the 12 regular-patch basis functions at one point.
///
/// Row `i` (0-based control label) holds `[b, ∂b/∂s1, ∂b/∂s2, ∂²b/∂s1², ∂²b/∂s1∂s2, ∂²b/∂s2²]`, already
/// divided by 12, so `x = Σ_i basis[i][0] y_i`.
pub type RegularBasis = [[Real; 6]; 12];

/// `d`-th derivative of `x^k`: `k!/(k−d)! x^(k−d)` (0 when `d > k`); `pw[j] = x^j`.
#[inline(always)]
fn dpow(pw: &[Real; 5], k: u8, d: u8) -> Real {
    match (k, d) {
        (_, 0) => pw[k as usize],
        (0, _) => 0.0,
        (_, 1) => k as Real * pw[k as usize - 1],
        (1, 2) => 0.0,
        (_, 2) => (k as Real) * (k as Real - 1.0) * pw[k as usize - 2],
        _ => unreachable!("only derivatives up to order 2 are used"),
    }
}

fn powers(x: Real) -> [Real; 5] {
    let x2 = x * x;
    [1.0, x, x2, x2 * x, x2 * x2]
}

/// Evaluates the 12 basis functions (Eq. 189, divided by 12) and their derivatives at `(s1, s2)`, with
/// `s3 = 1 − s1 − s2`. Valid for any real `(s1, s2)` (the polynomials extend outside the triangle).
pub fn regular_basis(s1: Real, s2: Real) -> RegularBasis {
    let s3 = 1.0 - s1 - s2;
    let (p1, p2, p3) = (powers(s1), powers(s2), powers(s3));
    // Value and affine derivatives of the 15 quartic monomials s1^a s2^b s3^e (index a(11 − a)/2 + b).
    // Homogeneous partial derivatives D(i, j, k); with s3 = 1 − s1 − s2 the affine derivatives are
    // ∂/∂s1 = D1 − D3 and ∂/∂s2 = D2 − D3.
    let mut mono = [[0.0; 6]; 15];
    for a in 0..=4u8 {
        for b in 0..=(4 - a) {
            let e = 4 - a - b;
            let d = |i: u8, j: u8, k: u8| dpow(&p1, a, i) * dpow(&p2, b, j) * dpow(&p3, e, k);
            let d001 = d(0, 0, 1);
            let d002 = d(0, 0, 2);
            let d101 = d(1, 0, 1);
            let d011 = d(0, 1, 1);
            mono[monomial_index(a, b)] = [
                d(0, 0, 0),
                d(1, 0, 0) - d001,
                d(0, 1, 0) - d001,
                d(2, 0, 0) - 2.0 * d101 + d002,
                d(1, 1, 0) - d101 - d011 + d002,
                d(0, 2, 0) - 2.0 * d011 + d002,
            ];
        }
    }
    let mut out = [[0.0; 6]; 12];
    for (row, terms) in out.iter_mut().zip(TERMS.iter()) {
        for &(c, [a, b, _]) in terms.iter() {
            let m = &mono[monomial_index(a, b)];
            let c = c / 12.0;
            for k in 0..6 {
                row[k] += c * m[k];
            }
        }
    }
    out
}

#[inline(always)]
fn monomial_index(a: u8, b: u8) -> usize {
    (a as usize * (11 - a as usize)) / 2 + b as usize
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::finite_difference::{FdParams, check_jacobian};

    /// The 12 functions sum to `12 (s1 + s2 + s3)⁴`: per monomial the coefficients add up to 12 times the
    /// multinomial coefficient. Pins transcription errors in the table.
    #[test]
    fn coefficients_sum_to_multinomials() {
        let fact = |n: u8| (1..=n as u32).product::<u32>() as Real;
        for a in 0..=4u8 {
            for b in 0..=(4 - a) {
                let e = 4 - a - b;
                let sum: Real = TERMS
                    .iter()
                    .flat_map(|t| t.iter())
                    .filter(|(_, p)| *p == [a, b, e])
                    .map(|(c, _)| c)
                    .sum();
                let multinomial = fact(4) / (fact(a) * fact(b) * fact(e));
                assert_eq!(sum, 12.0 * multinomial, "monomial s1^{a} s2^{b} s3^{e}");
            }
        }
    }

    /// Swapping s1 and s2 mirrors the patch: 1↔2, 3↔5, 6↔9, 7↔8, 10↔12, 4 and 11 fixed.
    #[test]
    fn mirror_symmetry() {
        let mirror = [1, 0, 4, 3, 2, 8, 7, 6, 5, 11, 10, 9];
        let (s1, s2) = (0.23, 0.41);
        let a = regular_basis(s1, s2);
        let b = regular_basis(s2, s1);
        for i in 0..12 {
            assert!((a[i][0] - b[mirror[i]][0]).abs() < 1e-15);
            assert!((a[i][1] - b[mirror[i]][2]).abs() < 1e-14);
            assert!((a[i][3] - b[mirror[i]][5]).abs() < 1e-13);
        }
    }

    /// At the corners the patch interpolates the regular limit-position mask (1/2 centre, 1/12 neighbours).
    #[test]
    fn corners_give_limit_positions() {
        let at = |s1, s2, centre: usize, ring: [usize; 6]| {
            let b = regular_basis(s1, s2);
            for i in 0..12 {
                let expect = if i == centre {
                    0.5
                } else if ring.contains(&i) {
                    1.0 / 12.0
                } else {
                    0.0
                };
                assert!((b[i][0] - expect).abs() < 1e-15, "label {}", i + 1);
            }
        };
        at(0.0, 0.0, 3, [0, 1, 2, 4, 6, 7]);
        at(1.0, 0.0, 6, [2, 3, 5, 7, 9, 10]);
        at(0.0, 1.0, 7, [3, 4, 6, 8, 10, 11]);
    }

    #[test]
    fn derivatives_match_central_differences() {
        let p = FdParams {
            step: 1e-5,
            rel_tol: 1e-6,
            abs_tol: 1e-9,
        };
        for &(s1, s2) in &[(0.2, 0.3), (0.05, 0.9), (0.7, 0.1), (1.0 / 3.0, 1.0 / 3.0)] {
            let b = regular_basis(s1, s2);
            let vals = |x: &[Real]| -> Vec<Real> {
                regular_basis(x[0], x[1]).iter().map(|r| r[0]).collect()
            };
            let grads = |x: &[Real]| -> Vec<Real> {
                regular_basis(x[0], x[1])
                    .iter()
                    .flat_map(|r| [r[1], r[2]])
                    .collect()
            };
            let jac: Vec<Real> = b.iter().flat_map(|r| [r[1], r[2]]).collect();
            check_jacobian(vals, &[s1, s2], &jac, &p).unwrap();
            let hess: Vec<Real> = b.iter().flat_map(|r| [r[3], r[4], r[4], r[5]]).collect();
            check_jacobian(grads, &[s1, s2], &hess, &p).unwrap();
        }
    }
}
