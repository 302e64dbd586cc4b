//! Exact evaluation of a Loop patch with one extraordinary vertex (valence `N ≠ 6`), after Stam 1998
//! "Evaluation of Loop subdivision surfaces", by explicit local subdivision.
//!
//! # Local control vertices
//!
//! The face is `[A, B, C]` with the extraordinary vertex `C` at `s3 = 1` (`s1` weighs `A`, `s2` weighs `B`).
//! Its `K = N + 6` control vertices, 0-based:
//!
//! * `0`: `C`;
//! * `1..=N`: the ring of `C`, `r_1 = A`, `r_2` the common neighbour of `C` and `A` other than `B`, …,
//!   `r_N = B`;
//! * `N+1`: `X6`, the common neighbour of `A` and `r_2` other than `C`;
//! * `N+2`: `X10`, the common neighbour of `A` and `X11` other than `B`;
//! * `N+3`: `X11`, the common neighbour of `A` and `B` other than `C`;
//! * `N+4`: `X12`, the common neighbour of `B` and `X11` other than `A`;
//! * `N+5`: `X9`, the common neighbour of `B` and `r_{N−1}` other than `C`.
//!
//! (For `N = 6` these are the labels of the regular patch, see [`crate::surface::loop_regular_patch`]: `4 = C`,
//! `7 = A`, `8 = B`, `3 = r_2`, `1 = r_3`, `2 = r_4`, `5 = r_5`.)
//!
//! # Method
//!
//! One Loop step maps these `K` vertices to the same structure around `C` one level finer: the `K × K`
//! subdivision matrix `𝐀`. The extended `(K + 6) × K` matrix `Ā` adds the six further edge points that,
//! with the `K`, control the three regular sub-patches of the face at the next level (corner `A`, corner `B`,
//! middle); the `12 × (K + 6)` picking matrices `P_k` order them as in Eq. 189. A point with
//! `2^{−n} ≤ s1 + s2 < 2^{1−n}` lies in a regular sub-patch after `n` steps, so
//! `x(s) = b(t)ᵀ P_k Ā 𝐀^{n−1} y_local` with `t` the sub-patch coordinates (`t = 2^n s` up to a shift and
//! sign). The matrices are precomputed per valence for `m < MAX_LEVELS`, which makes an evaluation one
//! `12 × K` product — exact, without an eigen-decomposition (whose non-symmetric eigenvectors would add
//! round-off; `𝐀` is row-stochastic, so its powers are stable).
//!
//! Near `C` the rows of `𝐀^m` all approach the limit-position mask `ℓ` (`ℓ_C = ω/(ω+N)`, `ℓ_{r_i} =
//! 1/(ω+N)`, `ω = 3/(8β_N)`), and the derivative weights `∂b/∂t` (which sum to zero) would cancel that common
//! part with a round-off of `ε 4^n` in second derivatives. So the tables hold the deviation
//! `D_{k,m} = P_k Ā (𝐀^m − 1ℓᵀ)` (entries `O(λ^m)`, `λ` the subdominant eigenvalue) and the weights are
//! `w = ℓ + Dᵀ b`, `∂w = Dᵀ ∂b`: the round-off left in second derivatives is about `ε (4λ)^n` relative,
//! i.e. `ε 2^n` on a regular configuration.
//!
//! # At the extraordinary vertex
//!
//! The parametrization is singular at `C`: `∂x/∂s` tends to zero (`N < 6`) or grows without bound
//! (`N > 6`) and `∂²x/∂s²` grows without bound for `N > 3`. Derivatives at points with
//! `s1 + s2 < 2^{1 − MAX_LEVELS}` (≈ 1e−19) are those at the nearest point at that distance (along the same
//! direction, or the diagonal at `C` itself), which keeps every value finite; the position there differs
//! from the exact one by `O(λ^64)` (< 1e−13 of the patch size for valences up to 32), and at `C` itself the
//! position is the exact limit position `ℓᵀ y`.

use crate::math::Real;
use crate::surface::loop_regular_patch::regular_basis;
use crate::surface::loop_subdivision::loop_beta;

/// Number of subdivision levels tabulated; see the module docs.
pub const MAX_LEVELS: usize = 64;

/// Precomputed evaluation matrices for one valence.
#[derive(Clone, Debug)]
pub struct IrregularPatch {
    valence: usize,
    /// `D_{k,m}` flattened: `((m · 3 + k) · 12 + j) · K + col`.
    q: Vec<Real>,
    /// The limit-position mask `ℓ` (`K`).
    limit: Vec<Real>,
}

fn limit_row(limit: &[Real]) -> nalgebra::RowDVector<Real> {
    nalgebra::RowDVector::from_row_slice(limit)
}

/// Loop's limit-position mask of a vertex of valence `n` in the local layout (`K = n + 6` entries).
pub fn limit_mask(n: usize) -> Vec<Real> {
    let omega = 3.0 / (8.0 * loop_beta(n));
    let denom = omega + n as Real;
    let mut l = vec![0.0; n + 6];
    l[0] = omega / denom;
    for v in l[1..=n].iter_mut() {
        *v = 1.0 / denom;
    }
    l
}

/// Local weights of the `K` control vertices: `[w, ∂w/∂s1, ∂w/∂s2, ∂²w/∂s1², ∂²w/∂s1∂s2, ∂²w/∂s2²]`.
pub type LocalWeights = [Real; 6];

impl IrregularPatch {
    /// Tables for valence `n ≥ 3`.
    pub fn new(n: usize) -> Self {
        assert!(n >= 3, "Loop patches need valence ≥ 3");
        let k = n + 6;
        let a = subdivision_matrix(n);
        let ext = extended_matrix(n);
        let picks = picking(n);
        let limit = limit_mask(n);
        let mut q = vec![0.0; MAX_LEVELS * 3 * 12 * k];
        // power = 𝐀^m − 1ℓᵀ, starting at I − 1ℓᵀ; 𝐀 (𝐀^m − 1ℓᵀ) = 𝐀^{m+1} − 1ℓᵀ since 𝐀1 = 1, ℓᵀ𝐀 = ℓᵀ.
        let mut power = nalgebra::DMatrix::<Real>::identity(k, k);
        for i in 0..k {
            for j in 0..k {
                power[(i, j)] -= limit[j];
            }
        }
        for m in 0..MAX_LEVELS {
            let ext_pow = &ext * &power;
            for (kk, pick) in picks.iter().enumerate() {
                for (j, &row) in pick.iter().enumerate() {
                    let base = ((m * 3 + kk) * 12 + j) * k;
                    for col in 0..k {
                        q[base + col] = ext_pow[(row, col)];
                    }
                }
            }
            power = &a * &power;
            // Exactly ℓᵀ(𝐀^m − 1ℓᵀ) = 0. Round-off along the eigenvector 1 would not decay (𝐀1 = 1) and, after
            // the 4^n scaling of second derivatives, would dominate near C: project it out.
            let drift = limit_row(&limit) * &power;
            for i in 0..k {
                for j in 0..k {
                    power[(i, j)] -= drift[j];
                }
            }
        }
        Self {
            valence: n,
            q,
            limit,
        }
    }

    /// The valence `N` of the extraordinary vertex.
    pub fn valence(&self) -> usize {
        self.valence
    }

    /// Number of local control vertices `K = N + 6`.
    pub fn num_control(&self) -> usize {
        self.valence + 6
    }

    /// Evaluates the weights of the `K` local control vertices at `(s1, s2)` (inside the triangle, `s3 = 1 −
    /// s1 − s2` at the extraordinary vertex) into `out[..K]`.
    pub fn weights(&self, s1: Real, s2: Real, out: &mut [LocalWeights]) {
        let k = self.num_control();
        let (mut u1, mut u2) = (s1.max(0.0), s2.max(0.0));
        let min_sum = (2.0 as Real).powi(1 - MAX_LEVELS as i32);
        let sum = u1 + u2;
        let at_vertex = sum == 0.0;
        if sum < min_sum {
            if sum > 0.0 {
                u1 *= min_sum / sum;
                u2 *= min_sum / sum;
            } else {
                u1 = 0.5 * min_sum;
                u2 = 0.5 * min_sum;
            }
        }
        // Level n ≥ 1 with 2^{−n} ≤ u1 + u2 < 2^{1−n}; scaled coordinates ũ = 2^{n−1} u have sum in [1/2, 1].
        let mut n = 1usize;
        let mut scale = 1.0; // 2^{n−1}
        while (u1 + u2) * scale < 0.5 && n < MAX_LEVELS {
            scale *= 2.0;
            n += 1;
        }
        let (v1, v2) = (u1 * scale, u2 * scale);
        let v3 = 1.0 - v1 - v2;
        let g = 2.0 * scale; // 2^n: derivative of the sub-patch coordinates with respect to s
        // Sub-patch, its coordinates t and Jacobian ∂t/∂s (rows t1, t2).
        let (which, t1, t2, jac) = if v1 >= 0.5 {
            (0, 2.0 * v1 - 1.0, 2.0 * v2, [[g, 0.0], [0.0, g]])
        } else if v2 >= 0.5 {
            (1, 2.0 * v2 - 1.0, 2.0 * v3, [[0.0, g], [-g, -g]])
        } else {
            (2, 1.0 - 2.0 * v1, 1.0 - 2.0 * v2, [[-g, 0.0], [0.0, -g]])
        };
        let basis = regular_basis(t1, t2);
        let base = ((n - 1) * 3 + which) * 12 * k;
        for (o, &l) in out[..k].iter_mut().zip(&self.limit) {
            *o = [l, 0.0, 0.0, 0.0, 0.0, 0.0];
        }
        for (j, b) in basis.iter().enumerate() {
            let ws = chain(b, &jac);
            let row = &self.q[base + j * k..base + (j + 1) * k];
            for (o, &qv) in out[..k].iter_mut().zip(row) {
                if qv != 0.0 {
                    for c in 0..6 {
                        o[c] += qv * ws[c];
                    }
                }
            }
        }
        if at_vertex {
            for (o, &l) in out[..k].iter_mut().zip(&self.limit) {
                o[0] = l;
            }
        }
    }
}

/// Pulls value and derivatives with respect to `t` back to `s` through the constant Jacobian
/// `jac[p][a] = ∂t_p/∂s_a`.
#[inline]
pub(crate) fn chain(b: &[Real; 6], jac: &[[Real; 2]; 2]) -> [Real; 6] {
    let (g1, g2) = (b[1], b[2]);
    let (h11, h12, h22) = (b[3], b[4], b[5]);
    let d = |a: usize| g1 * jac[0][a] + g2 * jac[1][a];
    let h = |a: usize, c: usize| {
        let (p1a, p2a, p1c, p2c) = (jac[0][a], jac[1][a], jac[0][c], jac[1][c]);
        h11 * p1a * p1c + h12 * (p1a * p2c + p2a * p1c) + h22 * p2a * p2c
    };
    [b[0], d(0), d(1), h(0, 0), h(0, 1), h(1, 1)]
}

/// Indices of the local layout (see module docs).
struct Layout {
    n: usize,
}

impl Layout {
    const C: usize = 0;
    /// `r_i`, `i` 1-based and cyclic (`r_0 = r_N`, `r_{N+1} = r_1`).
    fn r(&self, i: isize) -> usize {
        let n = self.n as isize;
        ((i - 1).rem_euclid(n) + 1) as usize
    }
    fn a(&self) -> usize {
        1
    }
    fn b(&self) -> usize {
        self.n
    }
    fn x6(&self) -> usize {
        self.n + 1
    }
    fn x10(&self) -> usize {
        self.n + 2
    }
    fn x11(&self) -> usize {
        self.n + 3
    }
    fn x12(&self) -> usize {
        self.n + 4
    }
    fn x9(&self) -> usize {
        self.n + 5
    }
}

/// Edge-point row: `3/8 (a + b) + 1/8 (c + d)`.
fn edge_row(row: &mut [Real], a: usize, b: usize, c: usize, d: usize) {
    row[a] += 0.375;
    row[b] += 0.375;
    row[c] += 0.125;
    row[d] += 0.125;
}

/// Regular vertex-point row: `10/16 v + 1/16 Σ ring`.
fn regular_vertex_row(row: &mut [Real], v: usize, ring: [usize; 6]) {
    row[v] += 0.625;
    for u in ring {
        row[u] += 0.0625;
    }
}

/// The `K × K` subdivision matrix `𝐀` of the local layout.
pub fn subdivision_matrix(n: usize) -> nalgebra::DMatrix<Real> {
    let k = n + 6;
    let l = Layout { n };
    let mut m = nalgebra::DMatrix::<Real>::zeros(k, k);
    let mut rows: Vec<Vec<Real>> = vec![vec![0.0; k]; k];
    // C' (vertex rule, valence n).
    let beta = loop_beta(n);
    rows[Layout::C][Layout::C] = 1.0 - n as Real * beta;
    for i in 1..=n as isize {
        rows[Layout::C][l.r(i)] += beta;
    }
    // r_i' = edge point of (C, r_i), opposite vertices r_{i−1}, r_{i+1}.
    for i in 1..=n as isize {
        edge_row(&mut rows[l.r(i)], Layout::C, l.r(i), l.r(i - 1), l.r(i + 1));
    }
    let (a, b, c) = (l.a(), l.b(), Layout::C);
    let (r2, rn1) = (l.r(2), l.r(n as isize - 1));
    // X6' = e(A, r2), opposite C and X6.
    edge_row(&mut rows[l.x6()], a, r2, c, l.x6());
    // X10' = vertex point of A (ring C, r2, X6, X10, X11, B).
    regular_vertex_row(&mut rows[l.x10()], a, [c, r2, l.x6(), l.x10(), l.x11(), b]);
    // X11' = e(A, B), opposite C and X11.
    edge_row(&mut rows[l.x11()], a, b, c, l.x11());
    // X12' = vertex point of B (ring C, r_{N−1}, X9, X12, X11, A).
    regular_vertex_row(&mut rows[l.x12()], b, [c, rn1, l.x9(), l.x12(), l.x11(), a]);
    // X9' = e(B, r_{N−1}), opposite C and X9.
    edge_row(&mut rows[l.x9()], b, rn1, c, l.x9());
    for (i, row) in rows.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            m[(i, j)] = v;
        }
    }
    m
}

/// The `(K + 6) × K` extended subdivision matrix `Ā`: `𝐀` followed by the edge points
/// `e(A, X6)`, `e(A, X10)`, `e(A, X11)`, `e(B, X11)`, `e(B, X12)`, `e(B, X9)`.
pub fn extended_matrix(n: usize) -> nalgebra::DMatrix<Real> {
    let k = n + 6;
    let l = Layout { n };
    let a_mat = subdivision_matrix(n);
    let mut m = nalgebra::DMatrix::<Real>::zeros(k + 6, k);
    m.view_mut((0, 0), (k, k)).copy_from(&a_mat);
    let (a, b) = (l.a(), l.b());
    let (r2, rn1) = (l.r(2), l.r(n as isize - 1));
    let (x6, x9, x10, x11, x12) = (l.x6(), l.x9(), l.x10(), l.x11(), l.x12());
    let extra: [[usize; 4]; 6] = [
        [a, x6, r2, x10],
        [a, x10, x6, x11],
        [a, x11, x10, b],
        [b, x11, x12, a],
        [b, x12, x9, x11],
        [b, x9, rn1, x12],
    ];
    for (e, [p, q, r, s]) in extra.into_iter().enumerate() {
        let mut row = vec![0.0; k];
        edge_row(&mut row, p, q, r, s);
        for (j, v) in row.into_iter().enumerate() {
            m[(k + e, j)] = v;
        }
    }
    m
}

/// Picking of the 12 regular-patch control vertices (Eq. 189 order) from the `K + 6` extended vertices for
/// the sub-patches at corner `A` (coordinates `t = (2s1 − 1, 2s2)`), corner `B` (`t = (2s2 − 1, 2s3)`) and
/// the middle (`t = (1 − 2s1, 1 − 2s2)`).
pub fn picking(n: usize) -> [[usize; 12]; 3] {
    let k = n + 6;
    let l = Layout { n };
    let (c, a, b) = (Layout::C, l.a(), l.b());
    let (r2, rn1) = (l.r(2), l.r(n as isize - 1));
    let (x6, x9, x10, x11, x12) = (l.x6(), l.x9(), l.x10(), l.x11(), l.x12());
    let (e_ax6, e_ax10, e_ax11, e_bx11, e_bx12, e_bx9) = (k, k + 1, k + 2, k + 3, k + 4, k + 5);
    [
        // Corner A: 7 = A, 8 = e(A, B), 4 = e(A, C).
        [
            r2, c, x6, a, b, e_ax6, x10, x11, x12, e_ax10, e_ax11, e_bx11,
        ],
        // Corner B: 7 = B, 8 = e(B, C), 4 = e(A, B).
        [
            e_ax11, x10, e_bx11, x11, a, e_bx12, x12, b, c, e_bx9, x9, rn1,
        ],
        // Middle: 7 = e(B, C), 8 = e(C, A), 4 = e(A, B).
        [e_bx11, e_ax11, x12, x11, x10, x9, b, a, x6, rn1, c, r2],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subdivision_matrices_are_row_stochastic() {
        for n in 3..=12 {
            let e = extended_matrix(n);
            for i in 0..e.nrows() {
                let sum: Real = e.row(i).iter().sum();
                assert!((sum - 1.0).abs() < 1e-14, "valence {n} row {i}");
                assert!(e.row(i).iter().all(|&v| v >= 0.0));
            }
        }
    }

    /// 𝐀^m converges to the rank-one limit map: every row becomes Loop's limit-position mask
    /// `(ω C + Σ ring) / (ω + N)` with `ω = 3 / (8 β_N)` (dominant eigenvalue 1, all others below 1).
    #[test]
    fn matrix_powers_converge_to_limit_mask() {
        for n in 3..=12 {
            let a = subdivision_matrix(n);
            let mut p = a.clone();
            for _ in 0..200 {
                p = &a * &p;
            }
            let omega = 3.0 / (8.0 * loop_beta(n));
            for i in 0..n + 1 {
                for j in 0..n + 6 {
                    let expect = if j == 0 {
                        omega / (omega + n as Real)
                    } else if j <= n {
                        1.0 / (omega + n as Real)
                    } else {
                        0.0
                    };
                    assert!((p[(i, j)] - expect).abs() < 1e-10, "valence {n} ({i}, {j})");
                }
            }
        }
    }

    #[test]
    fn weights_partition_unity() {
        for n in [3, 4, 5, 6, 7, 9, 12] {
            let p = IrregularPatch::new(n);
            let mut w = vec![[0.0; 6]; p.num_control()];
            for &(s1, s2) in &[(0.3, 0.2), (1e-5, 2e-5), (0.0, 0.0), (0.6, 0.1), (0.1, 0.6)] {
                p.weights(s1, s2, &mut w);
                for c in 0..6 {
                    let sum: Real = w.iter().map(|x| x[c]).sum();
                    // Intermediate terms grow like (s1 + s2)^−order near the vertex and cancel.
                    let order = [0, 1, 1, 2, 2, 2][c];
                    let scale = (s1 + s2 as Real).max(1e-12).powi(-order).max(1.0);
                    let expect = if c == 0 { 1.0 } else { 0.0 };
                    assert!(
                        (sum - expect).abs() < 1e-12 * scale,
                        "valence {n} at ({s1}, {s2}) component {c}: {sum}"
                    );
                }
            }
        }
    }
}
