//! A low-frequency basis of boundary displacements for a coarse-to-fine ("harmonic") start of the
//! design optimization, after the harmonic initialization of Sec. 6.5 of the volumetric-homogenization
//! paper: optimize first in the span of the `K` smoothest eigenvectors of a Laplacian, then raise `K`.
//!
//! Here the Laplacian is that of each panel's closed outer boundary loop, in arc-length parametrization
//! normalized to the loop's initial length `ℓ` (m). With `h_k = ‖X̄_{k+1} − X̄_k‖ / ℓ` the normalized length
//! of boundary edge `k` of the initial pattern:
//!
//! - stiffness `S` (`n × n`, dimensionless): `Σ_k (u_{k+1} − u_k)² / h_k` as a quadratic form;
//! - mass `D = diag(d)` with `d_i = (h_{i−1} + h_i) / 2` (dimensionless, `Σ d_i = 1`).
//!
//! The modes are the generalized eigenvectors `S b = λ D b`, sorted by increasing `λ` (dimensionless;
//! `λ ≈ (2π j)²` for the `j`-th cosine/sine pair of a smooth loop), normalized so that
//! **`Bᵀ D B = I`** — orthonormal for the inner product `⟨u, v⟩ = Σ_i d_i u_i v_i`, the arc-length
//! average of `u v`. Mode 0 is the constant `1` (a translation of the panel); modes `2j − 1, 2j` are the
//! `j`-th frequency pair, so odd `K` (1, 3, 5, …) keeps whole pairs.
//!
//! **Map.** Both coordinates of a panel's boundary use the same scalar modes: with `B_K` the first
//! `K_p = min(K, n_p)` modes of panel `p`,
//!
//! `p = p0 + B c`,  per panel `(x_i, y_i) = p0_i + Σ_{m < K_p} B_im (c_{2m}, c_{2m+1})`,
//!
//! with `p` laid out as in [`PatternMap`](crate::PatternMap) (panel after panel, loop order, `(x, y)`) and
//! the coefficients `c` (m) panel after panel, mode after mode, `(x, y)`: `2 Σ_p K_p` reals. `B` is
//! dimensionless, so `c` is in m (mode 0's coefficients are the panel's translation).
//!
//! **Levels.** [`BoundaryModes::set_num_modes`] changes `K` and converts coefficients: raising `K` keeps
//! the old coefficients and appends zeros (the same `p`), lowering truncates (the `D`-orthogonal
//! projection). With `K ≥ n_p` a panel's basis is complete and square: [`BoundaryModes::project`] inverts
//! [`BoundaryModes::apply`] exactly.
//!
//! Requirements (errors otherwise): `K ≥ 1`, every outer loop with at least 3 in-range vertices, a finite
//! initial pattern and no zero-length initial boundary edge.

use nalgebra::{DMatrix, SymmetricEigen};

use crate::design_mesh::DesignMesh;
use crate::math::{Real, Vec2};

/// Why boundary modes could not be built or applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BoundaryModesError {
    /// `K = 0`.
    #[error("the number of modes must be at least 1")]
    NoModes,
    /// The pattern does not match the mesh, or has non-finite positions.
    #[error("invalid pattern: {0}")]
    InvalidPattern(String),
    /// A panel's boundary loop cannot carry modes.
    #[error("panel {panel}: {message}")]
    InvalidLoop {
        /// The panel.
        panel: usize,
        /// What is wrong.
        message: String,
    },
    /// A vector of the wrong length, or with non-finite entries, was given.
    #[error("{what}: expected {expected} finite entries, got {got} entries")]
    Size {
        /// Which argument.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
}

/// One panel's loop basis.
#[derive(Clone, Debug, PartialEq)]
struct PanelModes {
    /// First parameter index (reals) of the panel in `p`.
    offset: usize,
    /// Mass weights `d_i` (dimensionless).
    mass: Vec<Real>,
    /// Eigenvalues, increasing (dimensionless).
    eigenvalues: Vec<Real>,
    /// `n × n`, column `m` = mode `m`.
    basis: DMatrix<Real>,
}

impl PanelModes {
    fn len(&self) -> usize {
        self.mass.len()
    }
}

/// The low-frequency boundary basis `p = p0 + B c` (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct BoundaryModes {
    initial_parameters: Vec<Real>,
    panels: Vec<PanelModes>,
    num_modes: usize,
}

fn loop_modes(
    panel: usize,
    points: &[Vec2],
    offset: usize,
) -> Result<PanelModes, BoundaryModesError> {
    let n = points.len();
    let invalid = |message: String| Err(BoundaryModesError::InvalidLoop { panel, message });
    if n < 3 {
        return invalid(format!(
            "the boundary loop has {n} vertices, at least 3 are needed"
        ));
    }
    let lengths: Vec<Real> = (0..n)
        .map(|k| (points[(k + 1) % n] - points[k]).norm())
        .collect();
    if let Some(k) = lengths.iter().position(|&l| l.is_nan() || l <= 0.0) {
        return invalid(format!("boundary edge {k} has zero length"));
    }
    let total: Real = lengths.iter().sum();
    let h: Vec<Real> = lengths.iter().map(|l| l / total).collect();
    let mass: Vec<Real> = (0..n).map(|i| 0.5 * (h[(i + n - 1) % n] + h[i])).collect();
    // Symmetric form D^{-1/2} S D^{-1/2}.
    let s = |i: usize| 1.0 / mass[i].sqrt();
    let mut a = DMatrix::<Real>::zeros(n, n);
    for (k, hk) in h.iter().enumerate() {
        let (i, j) = (k, (k + 1) % n);
        let c = 1.0 / hk;
        a[(i, i)] += c * s(i) * s(i);
        a[(j, j)] += c * s(j) * s(j);
        a[(i, j)] -= c * s(i) * s(j);
        a[(j, i)] -= c * s(i) * s(j);
    }
    let eigen = SymmetricEigen::new(a);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&x, &y| eigen.eigenvalues[x].total_cmp(&eigen.eigenvalues[y]));
    let mut basis = DMatrix::<Real>::zeros(n, n);
    for (m, &e) in order.iter().enumerate() {
        let mut column: Vec<Real> = (0..n).map(|i| eigen.eigenvectors[(i, e)] * s(i)).collect();
        // Deterministic sign: the first clearly non-zero entry is positive.
        let max = column.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        if let Some(first) = column.iter().find(|v| v.abs() > 1e-6 * max)
            && *first < 0.0
        {
            column.iter_mut().for_each(|v| *v = -*v);
        }
        for (i, v) in column.into_iter().enumerate() {
            basis[(i, m)] = v;
        }
    }
    let eigenvalues = order
        .iter()
        .map(|&e| eigen.eigenvalues[e].max(0.0))
        .collect();
    if basis.iter().any(|v| !v.is_finite()) {
        return invalid("the loop eigenvectors are not finite".to_string());
    }
    Ok(PanelModes {
        offset,
        mass,
        eigenvalues,
        basis,
    })
}

impl BoundaryModes {
    /// The modes of every panel's outer boundary loop of `mesh` at the initial pattern `pattern` (`#Vp`,
    /// m), using the first `num_modes` (`K ≥ 1`) of each.
    pub fn new(
        mesh: &DesignMesh,
        pattern: &[Vec2],
        num_modes: usize,
    ) -> Result<Self, BoundaryModesError> {
        if num_modes == 0 {
            return Err(BoundaryModesError::NoModes);
        }
        let nv = mesh.num_pattern_vertices();
        if pattern.len() != nv {
            return Err(BoundaryModesError::InvalidPattern(format!(
                "{} positions for {nv} pattern vertices",
                pattern.len()
            )));
        }
        if let Some(v) = pattern
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite()))
        {
            return Err(BoundaryModesError::InvalidPattern(format!(
                "vertex {v} has a non-finite position"
            )));
        }
        let mut panels = Vec::with_capacity(mesh.panels.len());
        let mut initial_parameters = Vec::new();
        for (p, panel) in mesh.panels.iter().enumerate() {
            if let Some(&v) = panel.boundary.iter().find(|&&v| v >= nv) {
                return Err(BoundaryModesError::InvalidLoop {
                    panel: p,
                    message: format!("boundary vertex {v} ≥ #Vp = {nv}"),
                });
            }
            let points: Vec<Vec2> = panel.boundary.iter().map(|&v| pattern[v]).collect();
            panels.push(loop_modes(p, &points, initial_parameters.len())?);
            initial_parameters.extend(points.iter().flat_map(|q| [q.x, q.y]));
        }
        Ok(Self {
            initial_parameters,
            panels,
            num_modes,
        })
    }

    /// The number of modes `K` per panel (each panel uses `min(K, n_p)`).
    pub fn num_modes(&self) -> usize {
        self.num_modes
    }

    /// The largest useful `K`: the longest boundary loop's vertex count (every basis is complete there).
    pub fn max_modes(&self) -> usize {
        self.panels.iter().map(PanelModes::len).max().unwrap_or(0)
    }

    /// Number of coefficients `2 Σ_p min(K, n_p)`.
    pub fn num_coefficients(&self) -> usize {
        self.coefficient_offsets(self.num_modes).1
    }

    /// Number of parameters `p` (`2 Σ_p n_p`).
    pub fn num_parameters(&self) -> usize {
        self.initial_parameters.len()
    }

    /// The parameters `p0` (m) the modes displace.
    pub fn initial_parameters(&self) -> &[Real] {
        &self.initial_parameters
    }

    /// The coefficients of `p0` (all zero).
    pub fn initial_coefficients(&self) -> Vec<Real> {
        vec![0.0; self.num_coefficients()]
    }

    /// Panel `panel`'s eigenvalues `λ` (dimensionless, increasing, all `n_p` of them); `None` for a
    /// panel that does not exist.
    pub fn eigenvalues(&self, panel: usize) -> Option<&[Real]> {
        self.panels.get(panel).map(|p| p.eigenvalues.as_slice())
    }

    /// Panel `panel`'s mass weights `d_i` (dimensionless, summing to 1), the inner product's weights.
    pub fn mass(&self, panel: usize) -> Option<&[Real]> {
        self.panels.get(panel).map(|p| p.mass.as_slice())
    }

    /// Mode `mode` of panel `panel` (dimensionless, one entry per boundary vertex in loop order); `None`
    /// when either does not exist.
    pub fn mode(&self, panel: usize, mode: usize) -> Option<Vec<Real>> {
        let p = self.panels.get(panel)?;
        (mode < p.len()).then(|| p.basis.column(mode).iter().copied().collect())
    }

    /// Per panel, the first coefficient index for `k` modes, and the total count.
    fn coefficient_offsets(&self, k: usize) -> (Vec<usize>, usize) {
        let mut offsets = Vec::with_capacity(self.panels.len());
        let mut total = 0;
        for p in &self.panels {
            offsets.push(total);
            total += 2 * k.min(p.len());
        }
        (offsets, total)
    }

    fn check(
        what: &'static str,
        expected: usize,
        values: &[Real],
    ) -> Result<(), BoundaryModesError> {
        if values.len() != expected || values.iter().any(|v| !v.is_finite()) {
            Err(BoundaryModesError::Size {
                what,
                expected,
                got: values.len(),
            })
        } else {
            Ok(())
        }
    }

    /// `B dc`: the parameter change (m, [`num_parameters`](Self::num_parameters)) of a coefficient change
    /// `dc` (m, [`num_coefficients`](Self::num_coefficients)).
    pub fn apply_jacobian(&self, dc: &[Real]) -> Result<Vec<Real>, BoundaryModesError> {
        let (offsets, total) = self.coefficient_offsets(self.num_modes);
        Self::check("coefficients", total, dc)?;
        let mut out = vec![0.0; self.num_parameters()];
        for (p, &c0) in self.panels.iter().zip(&offsets) {
            let k = self.num_modes.min(p.len());
            for i in 0..p.len() {
                let (mut x, mut y) = (0.0, 0.0);
                for m in 0..k {
                    x += p.basis[(i, m)] * dc[c0 + 2 * m];
                    y += p.basis[(i, m)] * dc[c0 + 2 * m + 1];
                }
                out[p.offset + 2 * i] = x;
                out[p.offset + 2 * i + 1] = y;
            }
        }
        Ok(out)
    }

    /// `p = p0 + B c` (m) for coefficients `c` (m, [`num_coefficients`](Self::num_coefficients)).
    pub fn apply(&self, c: &[Real]) -> Result<Vec<Real>, BoundaryModesError> {
        let mut p = self.apply_jacobian(c)?;
        p.iter_mut()
            .zip(&self.initial_parameters)
            .for_each(|(a, b)| *a += b);
        Ok(p)
    }

    /// `Bᵀ g` (plain transpose): the derivative with respect to the coefficients of a quantity whose
    /// derivative with respect to the parameters is `g` ([`num_parameters`](Self::num_parameters) reals),
    /// e.g. `dT/dp` from
    /// [`PatternMap::apply_jacobian_transpose`](crate::PatternMap::apply_jacobian_transpose).
    pub fn apply_jacobian_transpose(&self, g: &[Real]) -> Result<Vec<Real>, BoundaryModesError> {
        Self::check("parameter gradient", self.num_parameters(), g)?;
        self.transpose_weighted(g, false)
    }

    /// The coefficients (m) of the `D`-orthogonal projection of `p − p0` on the first `K` modes,
    /// `c = Bᵀ D (p − p0)`: the best approximation of `p` in the arc-length-weighted least-squares sense,
    /// and the exact inverse of [`apply`](Self::apply) when `K ≥ n_p` for every panel.
    pub fn project(&self, p: &[Real]) -> Result<Vec<Real>, BoundaryModesError> {
        Self::check("parameters", self.num_parameters(), p)?;
        let d: Vec<Real> = p
            .iter()
            .zip(&self.initial_parameters)
            .map(|(a, b)| a - b)
            .collect();
        self.transpose_weighted(&d, true)
    }

    fn transpose_weighted(
        &self,
        g: &[Real],
        weighted: bool,
    ) -> Result<Vec<Real>, BoundaryModesError> {
        let (offsets, total) = self.coefficient_offsets(self.num_modes);
        let mut out = vec![0.0; total];
        for (p, &c0) in self.panels.iter().zip(&offsets) {
            let k = self.num_modes.min(p.len());
            for i in 0..p.len() {
                let w = if weighted { p.mass[i] } else { 1.0 };
                let (gx, gy) = (w * g[p.offset + 2 * i], w * g[p.offset + 2 * i + 1]);
                for m in 0..k {
                    out[c0 + 2 * m] += p.basis[(i, m)] * gx;
                    out[c0 + 2 * m + 1] += p.basis[(i, m)] * gy;
                }
            }
        }
        Ok(out)
    }

    /// Changes `K` to `num_modes` (≥ 1) and returns the coefficients at the new level for the coefficients
    /// `c` at the current level: raising `K` appends zero coefficients (the same parameters `p`), lowering
    /// it drops the highest modes (the `D`-orthogonal projection). An error (and no change) for `K = 0` or
    /// `c` of the wrong length.
    pub fn set_num_modes(
        &mut self,
        num_modes: usize,
        c: &[Real],
    ) -> Result<Vec<Real>, BoundaryModesError> {
        if num_modes == 0 {
            return Err(BoundaryModesError::NoModes);
        }
        let (old_offsets, old_total) = self.coefficient_offsets(self.num_modes);
        Self::check("coefficients", old_total, c)?;
        let (new_offsets, new_total) = self.coefficient_offsets(num_modes);
        let mut out = vec![0.0; new_total];
        for (p, (&o, &n)) in self.panels.iter().zip(old_offsets.iter().zip(&new_offsets)) {
            let keep = 2 * self.num_modes.min(num_modes).min(p.len());
            out[n..n + keep].copy_from_slice(&c[o..o + keep]);
        }
        self.num_modes = num_modes;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pattern_map::PatternMap;
    use crate::test_support::{polygon_panel, rng, two_panel_mesh};
    use rand::Rng;
    use std::f64::consts::PI;

    fn random_vector(n: usize, seed: u64) -> Vec<Real> {
        let mut r = rng(seed);
        (0..n).map(|_| r.random_range(-1.0..1.0)).collect()
    }

    #[test]
    fn basis_is_mass_orthonormal_and_sorted() {
        let (mesh, pattern) = two_panel_mesh(4, 3, 1);
        let modes = BoundaryModes::new(&mesh, &pattern, 5).unwrap();
        for panel in 0..2 {
            let n = mesh.panels[panel].boundary.len();
            let d = modes.mass(panel).unwrap();
            assert!((d.iter().sum::<Real>() - 1.0).abs() < 1e-12);
            let b: Vec<Vec<Real>> = (0..n).map(|m| modes.mode(panel, m).unwrap()).collect();
            for i in 0..n {
                for j in 0..n {
                    let dot: Real = (0..n).map(|k| d[k] * b[i][k] * b[j][k]).sum();
                    let expected = if i == j { 1.0 } else { 0.0 };
                    assert!((dot - expected).abs() < 1e-10, "⟨b{i}, b{j}⟩ = {dot}");
                }
            }
            // Mode 0 is the constant 1 with eigenvalue 0; eigenvalues increase.
            assert!(b[0].iter().all(|v| (v - 1.0).abs() < 1e-10));
            let lambda = modes.eigenvalues(panel).unwrap();
            assert!(lambda[0].abs() < 1e-9);
            assert!(lambda.windows(2).all(|w| w[0] <= w[1]));
        }
        assert!(modes.mode(0, 1000).is_none());
        assert!(modes.mode(7, 0).is_none());
    }

    #[test]
    fn eigenvalues_of_a_regular_polygon() {
        // Uniform sampling h = 1/n: λ_j = 4 n² sin²(π j / n), each j ≥ 1 twice (cosine and sine).
        let n = 12;
        let corners: Vec<Vec2> = (0..n)
            .map(|k| {
                let a = 2.0 * PI * k as Real / n as Real;
                Vec2::new(0.3 * a.cos(), 0.3 * a.sin())
            })
            .collect();
        let (mesh, pattern) = polygon_panel(&corners);
        let modes = BoundaryModes::new(&mesh, &pattern, 3).unwrap();
        let lambda = modes.eigenvalues(0).unwrap();
        for j in 1..n / 2 {
            let expected = 4.0 * (n * n) as Real * (PI * j as Real / n as Real).sin().powi(2);
            assert!((lambda[2 * j - 1] - expected).abs() < 1e-9 * expected);
            assert!((lambda[2 * j] - expected).abs() < 1e-9 * expected);
        }
        // Close to (2π j)² for low frequencies.
        assert!((lambda[1] / (4.0 * PI * PI) - 1.0).abs() < 0.03);
    }

    #[test]
    fn all_modes_span_everything() {
        let (mesh, pattern) = two_panel_mesh(3, 2, 2);
        let max = mesh.panels.iter().map(|p| p.boundary.len()).max().unwrap();
        let modes = BoundaryModes::new(&mesh, &pattern, max).unwrap();
        assert_eq!(modes.max_modes(), max);
        assert_eq!(modes.num_coefficients(), modes.num_parameters());
        let p: Vec<Real> = modes
            .initial_parameters()
            .iter()
            .zip(random_vector(modes.num_parameters(), 3))
            .map(|(a, b)| a + 0.05 * b)
            .collect();
        let c = modes.project(&p).unwrap();
        let back = modes.apply(&c).unwrap();
        for (a, b) in p.iter().zip(&back) {
            assert!((a - b).abs() < 1e-12);
        }
        let c = random_vector(modes.num_coefficients(), 4);
        let again = modes.project(&modes.apply(&c).unwrap()).unwrap();
        for (a, b) in c.iter().zip(&again) {
            assert!((a - b).abs() < 1e-10);
        }
    }

    #[test]
    fn layout_matches_the_pattern_map_and_translation_mode() {
        let (mesh, pattern) = two_panel_mesh(3, 3, 5);
        let map = PatternMap::new(&mesh, &pattern).unwrap();
        let modes = BoundaryModes::new(&mesh, &pattern, 1).unwrap();
        assert_eq!(
            modes.initial_parameters(),
            map.initial_parameters().as_slice()
        );
        assert_eq!(modes.num_coefficients(), 4);
        // K = 1: c moves each panel rigidly by (c_x, c_y).
        let p = modes.apply(&[0.1, -0.2, 0.0, 0.3]).unwrap();
        let moved = map.apply(&p).unwrap();
        for (v, q) in moved.iter().enumerate() {
            let t = if mesh.pattern_panel[v] == 0 {
                Vec2::new(0.1, -0.2)
            } else {
                Vec2::new(0.0, 0.3)
            };
            assert!((q - pattern[v] - t).norm() < 1e-12);
        }
    }

    #[test]
    fn jacobian_transpose_is_consistent() {
        let (mesh, pattern) = two_panel_mesh(3, 4, 6);
        let modes = BoundaryModes::new(&mesh, &pattern, 4).unwrap();
        for seed in 0..3 {
            let dc = random_vector(modes.num_coefficients(), 10 + seed);
            let g = random_vector(modes.num_parameters(), 20 + seed);
            let bdc = modes.apply_jacobian(&dc).unwrap();
            let btg = modes.apply_jacobian_transpose(&g).unwrap();
            let lhs: Real = bdc.iter().zip(&g).map(|(a, b)| a * b).sum();
            let rhs: Real = dc.iter().zip(&btg).map(|(a, b)| a * b).sum();
            assert!((lhs - rhs).abs() < 1e-12 * lhs.abs().max(1.0));
            // The map is affine: apply(c + dc) − apply(c) = B dc.
            let c = random_vector(modes.num_coefficients(), 30 + seed);
            let c2: Vec<Real> = c.iter().zip(&dc).map(|(a, b)| a + b).collect();
            let (p1, p2) = (modes.apply(&c).unwrap(), modes.apply(&c2).unwrap());
            for ((a, b), d) in p2.iter().zip(&p1).zip(&bdc) {
                assert!((a - b - d).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn raising_and_lowering_levels() {
        let (mesh, pattern) = two_panel_mesh(3, 3, 7);
        let mut modes = BoundaryModes::new(&mesh, &pattern, 1).unwrap();
        let c1 = vec![0.01, 0.02, -0.03, 0.04];
        let p1 = modes.apply(&c1).unwrap();
        let c3 = modes.set_num_modes(3, &c1).unwrap();
        assert_eq!(modes.num_modes(), 3);
        assert_eq!(c3.len(), modes.num_coefficients());
        assert_eq!(modes.apply(&c3).unwrap(), p1);
        let mut c3 = c3;
        c3[2] = 0.05; // a first-frequency x coefficient of panel 0
        let p3 = modes.apply(&c3).unwrap();
        // Lowering is the D-orthogonal projection: the same as projecting p3 at the lower level.
        let lowered = modes.set_num_modes(1, &c3).unwrap();
        let projected = modes.project(&p3).unwrap();
        for (a, b) in lowered.iter().zip(&projected) {
            assert!((a - b).abs() < 1e-12);
        }
        // Raising beyond a loop's length saturates at n_p modes for that panel.
        let big = modes.set_num_modes(1000, &lowered).unwrap();
        assert_eq!(big.len(), modes.num_parameters());
        assert!(modes.set_num_modes(0, &big).is_err());
        assert!(modes.set_num_modes(2, &big[1..]).is_err());
        assert_eq!(modes.num_modes(), 1000);
    }

    #[test]
    fn invalid_inputs_are_errors() {
        let (mesh, pattern) = two_panel_mesh(2, 2, 8);
        assert_eq!(
            BoundaryModes::new(&mesh, &pattern, 0),
            Err(BoundaryModesError::NoModes)
        );
        assert!(matches!(
            BoundaryModes::new(&mesh, &pattern[1..], 2),
            Err(BoundaryModesError::InvalidPattern(_))
        ));
        let mut nan = pattern.clone();
        nan[0].y = Real::NAN;
        assert!(BoundaryModes::new(&mesh, &nan, 2).is_err());
        let mut dup = pattern.clone();
        dup[1] = dup[0];
        assert!(matches!(
            BoundaryModes::new(&mesh, &dup, 2),
            Err(BoundaryModesError::InvalidLoop { panel: 0, .. })
        ));
        let mut short = mesh.clone();
        short.panels[1].boundary.truncate(2);
        assert!(matches!(
            BoundaryModes::new(&short, &pattern, 2),
            Err(BoundaryModesError::InvalidLoop { panel: 1, .. })
        ));
        let modes = BoundaryModes::new(&mesh, &pattern, 2).unwrap();
        assert!(modes.apply(&[0.0]).is_err());
        assert!(modes.project(&[0.0]).is_err());
        assert!(modes.apply_jacobian_transpose(&[0.0]).is_err());
        let mut c = modes.initial_coefficients();
        c[0] = Real::INFINITY;
        assert!(modes.apply(&c).is_err());
    }
}
