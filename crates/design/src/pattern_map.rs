//! The design parametrization (thesis ch. 6–7, "Pattern Parameterization"): the design parameters `p` are
//! the 2D positions of the pattern **boundary** vertices; the interior vertices follow through bi-harmonic
//! coordinates computed once per mesh ([`mod@crate::biharmonic_coordinates`]).
//!
//! **Parameters.** `p` holds `2 · Σ_panels #boundary` reals (m): panel after panel (in
//! [`DesignMesh::panels`] order), each panel's outer boundary loop in loop order
//! ([`DesignPanel::boundary`](crate::DesignPanel)), each vertex as `(x, y)`. So boundary vertex `k` of a
//! panel whose parameters start at `o` ([`PatternMap::panel_parameters`]) has `x = p[o + 2k]`,
//! `y = p[o + 2k + 1]`.
//!
//! **Map.** With `P0` (`#Vp × 2`, m) the initial pattern and `p0` its boundary positions,
//!
//! `P(p) = P0 + W (p − p0)`   per panel (interior vertices), and `P_b = p_b` on the boundary,
//!
//! i.e. the boundary displacement is interpolated into the interior (displacement interpolation), so
//! `P(p0) = P0` exactly, and — because `W` reproduces linear functions — an affine motion of a panel's
//! boundary moves its interior by the same affine map. The map is affine in `p`, its Jacobian
//! `J = ∂P/∂p` (`2#Vp × 2#boundary`) is constant; [`PatternMap::apply_jacobian`] computes `J dp` and
//! [`PatternMap::apply_jacobian_transpose`] `Jᵀ g` (a pattern gradient `∂T/∂X̄` to `dT/dp`).
//!
//! **Seams.** The two sides of a seam are different pattern vertices on (usually) different panels, so
//! they are **separate parameters**: nothing in the map keeps the sides the same length. The
//! [`SeamLength`](crate::SeamLength) regularizer keeps them sewable.
//!
//! Vertices of a panel on inner boundary loops (holes) are not parameters: they are interpolated like the
//! interior. Pattern vertices outside every panel's vertex range stay at `P0`.

use std::ops::Range;

use crate::biharmonic_coordinates::{
    BiharmonicCoordinates, BiharmonicError, biharmonic_coordinates,
};
use crate::design_mesh::DesignMesh;
use crate::math::{Real, Vec2};

/// Why a [`PatternMap`] could not be built or applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PatternMapError {
    /// The mesh is inconsistent (panel ranges, boundary ids, triangles across panels).
    #[error("invalid design mesh: {0}")]
    InvalidMesh(String),
    /// A vector of the wrong length was given.
    #[error("{what}: expected {expected} entries, got {got}")]
    Size {
        /// Which argument.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// A value is NaN or infinite.
    #[error("{what} has a non-finite entry at {index}")]
    NonFinite {
        /// Which argument.
        what: &'static str,
        /// The entry.
        index: usize,
    },
    /// A panel's bi-harmonic coordinates could not be computed.
    #[error("panel {panel}: {source}")]
    Biharmonic {
        /// The panel.
        panel: usize,
        /// The reason.
        source: BiharmonicError,
    },
}

/// One panel's part of the map.
#[derive(Clone, Debug, PartialEq)]
struct PanelMap {
    /// First parameter index (reals) of the panel.
    offset: usize,
    /// Boundary loop, global pattern ids (the columns of `W`).
    boundary: Vec<usize>,
    /// Interior vertices, global pattern ids (the rows of `W`).
    interior: Vec<usize>,
    /// Coordinates in panel-local ids.
    coordinates: BiharmonicCoordinates,
}

/// The map from design parameters `p` (boundary positions, m) to all pattern positions `X̄` (`#Vp`, m).
#[derive(Clone, Debug, PartialEq)]
pub struct PatternMap {
    initial_pattern: Vec<Vec2>,
    initial_parameters: Vec<Real>,
    panels: Vec<PanelMap>,
}

fn check_finite(
    what: &'static str,
    values: impl Iterator<Item = Real>,
) -> Result<(), PatternMapError> {
    for (index, v) in values.enumerate() {
        if !v.is_finite() {
            return Err(PatternMapError::NonFinite { what, index });
        }
    }
    Ok(())
}

fn check_size(what: &'static str, expected: usize, got: usize) -> Result<(), PatternMapError> {
    if expected == got {
        Ok(())
    } else {
        Err(PatternMapError::Size {
            what,
            expected,
            got,
        })
    }
}

impl PatternMap {
    /// The map of `mesh` around the initial pattern `initial_pattern` (`#Vp`, m): computes every panel's
    /// bi-harmonic coordinates (panel triangles from [`DesignMesh::pattern_triangles`], boundary from
    /// [`DesignPanel::boundary`](crate::DesignPanel)).
    pub fn new(mesh: &DesignMesh, initial_pattern: &[Vec2]) -> Result<Self, PatternMapError> {
        let nv = mesh.num_pattern_vertices();
        check_size("initial pattern", nv, initial_pattern.len())?;
        check_finite(
            "initial pattern",
            initial_pattern.iter().flat_map(|p| [p.x, p.y]),
        )?;
        let invalid = |m: String| Err(PatternMapError::InvalidMesh(m));
        if mesh.pattern_panel.len() != nv {
            return invalid(format!(
                "{} panel ids for {nv} pattern vertices",
                mesh.pattern_panel.len()
            ));
        }
        let mut triangles: Vec<Vec<[usize; 3]>> = vec![Vec::new(); mesh.panels.len()];
        for (f, t) in mesh.pattern_triangles.iter().enumerate() {
            if let Some(&v) = t.iter().find(|&&v| v >= nv) {
                return invalid(format!("triangle {f} has vertex {v} ≥ #Vp = {nv}"));
            }
            let p = mesh.pattern_panel[t[0]];
            if p >= mesh.panels.len() || t.iter().any(|&v| mesh.pattern_panel[v] != p) {
                return invalid(format!("triangle {f} is not inside one panel"));
            }
            triangles[p].push(*t);
        }
        let mut panels = Vec::with_capacity(mesh.panels.len());
        let mut initial_parameters = Vec::new();
        for (p, panel) in mesh.panels.iter().enumerate() {
            let range = panel.first_vertex..panel.first_vertex + panel.num_vertices;
            if range.end > nv {
                return invalid(format!("panel {p}'s vertices {range:?} exceed #Vp = {nv}"));
            }
            if let Some(&v) = panel.boundary.iter().find(|v| !range.contains(v)) {
                return invalid(format!(
                    "panel {p}'s boundary vertex {v} is not in {range:?}"
                ));
            }
            let local = |v: usize| v - panel.first_vertex;
            let local_triangles: Vec<[usize; 3]> = triangles[p]
                .iter()
                .map(|t| {
                    if t.iter().all(|v| range.contains(v)) {
                        Ok(t.map(local))
                    } else {
                        Err(PatternMapError::InvalidMesh(format!(
                            "a triangle of panel {p} has a vertex outside {range:?}"
                        )))
                    }
                })
                .collect::<Result<_, _>>()?;
            let local_boundary: Vec<usize> = panel.boundary.iter().map(|&v| local(v)).collect();
            let coordinates = biharmonic_coordinates(
                &initial_pattern[range.clone()],
                &local_triangles,
                &local_boundary,
            )
            .map_err(|source| PatternMapError::Biharmonic { panel: p, source })?;
            let interior = coordinates
                .interior()
                .iter()
                .map(|&v| v + panel.first_vertex)
                .collect();
            panels.push(PanelMap {
                offset: initial_parameters.len(),
                boundary: panel.boundary.clone(),
                interior,
                coordinates,
            });
            initial_parameters.extend(
                panel
                    .boundary
                    .iter()
                    .flat_map(|&v| [initial_pattern[v].x, initial_pattern[v].y]),
            );
        }
        Ok(Self {
            initial_pattern: initial_pattern.to_vec(),
            initial_parameters,
            panels,
        })
    }

    /// Number of design parameters (`2 · Σ_panels #boundary`).
    pub fn num_parameters(&self) -> usize {
        self.initial_parameters.len()
    }

    /// Number of pattern vertices `#Vp`.
    pub fn num_pattern_vertices(&self) -> usize {
        self.initial_pattern.len()
    }

    /// The parameters `p0` (m) of the initial pattern.
    pub fn initial_parameters(&self) -> Vec<Real> {
        self.initial_parameters.clone()
    }

    /// The initial pattern `P0` (`#Vp`, m).
    pub fn initial_pattern(&self) -> &[Vec2] {
        &self.initial_pattern
    }

    /// The parameter indices (reals) of panel `panel`'s boundary loop; `None` for a panel that does not
    /// exist.
    pub fn panel_parameters(&self, panel: usize) -> Option<Range<usize>> {
        self.panels
            .get(panel)
            .map(|p| p.offset..p.offset + 2 * p.boundary.len())
    }

    /// Panel `panel`'s bi-harmonic coordinates, in panel-local vertex ids (global id minus
    /// [`DesignPanel::first_vertex`](crate::DesignPanel)); `None` for a panel that does not exist.
    pub fn coordinates(&self, panel: usize) -> Option<&BiharmonicCoordinates> {
        self.panels.get(panel).map(|p| &p.coordinates)
    }

    /// The pattern positions `X̄ = P0 + W (p − p0)` (`#Vp`, m) of the parameters `p`
    /// ([`num_parameters`](Self::num_parameters) reals, m).
    pub fn apply(&self, p: &[Real]) -> Result<Vec<Vec2>, PatternMapError> {
        check_size("parameters", self.num_parameters(), p.len())?;
        check_finite("parameters", p.iter().copied())?;
        let dp: Vec<Real> = p
            .iter()
            .zip(&self.initial_parameters)
            .map(|(a, b)| a - b)
            .collect();
        let mut pattern = self.initial_pattern.clone();
        self.add_jacobian_product(&dp, &mut pattern)?;
        // Boundary vertices copy p exactly (no round-off from P0 + (p − p0)).
        for panel in &self.panels {
            for (k, &v) in panel.boundary.iter().enumerate() {
                pattern[v] = Vec2::new(p[panel.offset + 2 * k], p[panel.offset + 2 * k + 1]);
            }
        }
        Ok(pattern)
    }

    /// `J dp`: the change of the pattern positions (`#Vp`, m) for a parameter change `dp`
    /// ([`num_parameters`](Self::num_parameters) reals, m).
    pub fn apply_jacobian(&self, dp: &[Real]) -> Result<Vec<Vec2>, PatternMapError> {
        check_size("parameter change", self.num_parameters(), dp.len())?;
        check_finite("parameter change", dp.iter().copied())?;
        let mut out = vec![Vec2::zeros(); self.num_pattern_vertices()];
        self.add_jacobian_product(dp, &mut out)?;
        Ok(out)
    }

    fn add_jacobian_product(&self, dp: &[Real], out: &mut [Vec2]) -> Result<(), PatternMapError> {
        for (p, panel) in self.panels.iter().enumerate() {
            let d: Vec<Vec2> = (0..panel.boundary.len())
                .map(|k| Vec2::new(dp[panel.offset + 2 * k], dp[panel.offset + 2 * k + 1]))
                .collect();
            let inside = panel
                .coordinates
                .interpolate(&d)
                .map_err(|source| PatternMapError::Biharmonic { panel: p, source })?;
            for (&v, di) in panel.interior.iter().zip(inside) {
                out[v] += di;
            }
            for (&v, db) in panel.boundary.iter().zip(d) {
                out[v] += db;
            }
        }
        Ok(())
    }

    /// `Jᵀ g`: the derivative with respect to the parameters (per m; `num_parameters` reals) of a quantity
    /// whose derivative with respect to the pattern positions is `g` (`#Vp`, e.g. `∂T/∂X̄`).
    pub fn apply_jacobian_transpose(&self, g: &[Vec2]) -> Result<Vec<Real>, PatternMapError> {
        check_size("pattern gradient", self.num_pattern_vertices(), g.len())?;
        check_finite("pattern gradient", g.iter().flat_map(|v| [v.x, v.y]))?;
        let mut out = vec![0.0; self.num_parameters()];
        for (p, panel) in self.panels.iter().enumerate() {
            let gi: Vec<Vec2> = panel.interior.iter().map(|&v| g[v]).collect();
            let pulled = panel
                .coordinates
                .interpolate_transpose(&gi)
                .map_err(|source| PatternMapError::Biharmonic { panel: p, source })?;
            for (k, (&v, q)) in panel.boundary.iter().zip(pulled).enumerate() {
                let total = g[v] + q;
                out[panel.offset + 2 * k] += total.x;
                out[panel.offset + 2 * k + 1] += total.y;
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{flatten_pattern, rng, two_panel_mesh};
    use rand::Rng;
    use skintight_geometry::finite_difference::{FdParams, check_jacobian};

    fn random_vector(n: usize, seed: u64) -> Vec<Real> {
        let mut r = rng(seed);
        (0..n).map(|_| r.random_range(-1.0..1.0)).collect()
    }

    #[test]
    fn parameter_layout_and_initial_pattern() {
        let (mesh, pattern) = two_panel_mesh(3, 4, 1);
        let map = PatternMap::new(&mesh, &pattern).unwrap();
        let nb0 = mesh.panels[0].boundary.len();
        assert_eq!(
            map.num_parameters(),
            2 * (nb0 + mesh.panels[1].boundary.len())
        );
        assert_eq!(map.panel_parameters(0), Some(0..2 * nb0));
        assert_eq!(map.panel_parameters(1), Some(2 * nb0..map.num_parameters()));
        assert_eq!(map.panel_parameters(2), None);
        let p0 = map.initial_parameters();
        let v = mesh.panels[1].boundary[2];
        assert_eq!(p0[2 * nb0 + 4], pattern[v].x);
        assert_eq!(p0[2 * nb0 + 5], pattern[v].y);
        // p0 reproduces the initial pattern exactly.
        assert_eq!(map.apply(&p0).unwrap(), pattern);
        assert_eq!(map.initial_pattern(), &pattern[..]);
        assert_eq!(map.coordinates(0).unwrap().num_boundary(), nb0);
    }

    #[test]
    fn affine_boundary_motion_moves_the_interior_affinely() {
        let (mesh, pattern) = two_panel_mesh(4, 3, 2);
        let map = PatternMap::new(&mesh, &pattern).unwrap();
        let affine = [
            |q: Vec2| Vec2::new(1.1 * q.x - 0.2 * q.y + 0.05, 0.3 * q.x + 0.9 * q.y - 0.1),
            |q: Vec2| Vec2::new(0.8 * q.x + 0.4 * q.y, -0.5 * q.x + 1.2 * q.y + 0.3),
        ];
        let mut p = map.initial_parameters();
        for (pi, panel) in mesh.panels.iter().enumerate() {
            let o = map.panel_parameters(pi).unwrap().start;
            for (k, &v) in panel.boundary.iter().enumerate() {
                let q = affine[pi](pattern[v]);
                p[o + 2 * k] = q.x;
                p[o + 2 * k + 1] = q.y;
            }
        }
        let out = map.apply(&p).unwrap();
        for (v, q) in out.iter().enumerate() {
            let expected = affine[mesh.pattern_panel[v]](pattern[v]);
            assert!((q - expected).norm() < 1e-12, "vertex {v}");
        }
    }

    #[test]
    fn jacobian_matches_finite_differences_and_transpose() {
        let (mesh, pattern) = two_panel_mesh(3, 3, 3);
        let map = PatternMap::new(&mesh, &pattern).unwrap();
        let n = map.num_parameters();
        let nv = map.num_pattern_vertices();
        for seed in 0..3 {
            let p: Vec<Real> = map
                .initial_parameters()
                .iter()
                .zip(random_vector(n, seed))
                .map(|(a, b)| a + 0.02 * b)
                .collect();
            // Dense Jacobian from J e_k, checked against central differences of apply.
            let mut jac = vec![0.0; 2 * nv * n];
            for k in 0..n {
                let mut e = vec![0.0; n];
                e[k] = 1.0;
                let col = flatten_pattern(&map.apply_jacobian(&e).unwrap());
                for r in 0..2 * nv {
                    jac[r * n + k] = col[r];
                }
            }
            let f = |x: &[Real]| flatten_pattern(&map.apply(x).unwrap());
            check_jacobian(f, &p, &jac, &FdParams::default()).unwrap();
            // ⟨J dp, g⟩ = ⟨dp, Jᵀ g⟩.
            let dp = random_vector(n, 100 + seed);
            let g: Vec<Vec2> =
                crate::test_support::unflatten_pattern(&random_vector(2 * nv, 200 + seed));
            let jdp = map.apply_jacobian(&dp).unwrap();
            let jtg = map.apply_jacobian_transpose(&g).unwrap();
            let lhs: Real = jdp.iter().zip(&g).map(|(a, b)| a.dot(b)).sum();
            let rhs: Real = dp.iter().zip(&jtg).map(|(a, b)| a * b).sum();
            assert!(
                (lhs - rhs).abs() < 1e-12 * lhs.abs().max(1.0),
                "{lhs} vs {rhs}"
            );
        }
    }

    #[test]
    fn wrong_sizes_and_non_finite_values_are_errors() {
        let (mesh, pattern) = two_panel_mesh(2, 2, 4);
        assert!(matches!(
            PatternMap::new(&mesh, &pattern[1..]),
            Err(PatternMapError::Size { .. })
        ));
        let mut nan = pattern.clone();
        nan[3].x = Real::INFINITY;
        assert!(matches!(
            PatternMap::new(&mesh, &nan),
            Err(PatternMapError::NonFinite { .. })
        ));
        let map = PatternMap::new(&mesh, &pattern).unwrap();
        let mut p = map.initial_parameters();
        assert!(map.apply(&p[1..]).is_err());
        assert!(map.apply_jacobian(&p[1..]).is_err());
        assert!(map.apply_jacobian_transpose(&pattern[1..]).is_err());
        p[0] = Real::NAN;
        assert!(matches!(
            map.apply(&p),
            Err(PatternMapError::NonFinite { .. })
        ));
    }

    #[test]
    fn inconsistent_meshes_are_errors() {
        let (mesh, pattern) = two_panel_mesh(2, 2, 5);
        let mut bad = mesh.clone();
        bad.panels[0].boundary[0] = mesh.panels[1].first_vertex;
        assert!(matches!(
            PatternMap::new(&bad, &pattern),
            Err(PatternMapError::InvalidMesh(_))
        ));
        let mut bad = mesh.clone();
        bad.pattern_triangles[0][0] = mesh.panels[1].first_vertex;
        assert!(matches!(
            PatternMap::new(&bad, &pattern),
            Err(PatternMapError::InvalidMesh(_))
        ));
        let mut bad = mesh.clone();
        bad.panels[1].num_vertices += 1;
        assert!(matches!(
            PatternMap::new(&bad, &pattern),
            Err(PatternMapError::InvalidMesh(_))
        ));
        let mut collapsed = pattern.clone();
        collapsed[1] = collapsed[0];
        assert!(matches!(
            PatternMap::new(&mesh, &collapsed),
            Err(PatternMapError::Biharmonic { panel: 0, .. })
        ));
    }
}
