//! Target edge lengths graded by curvature, so that every triangle of a remeshed surface stays within the
//! same chord error of the surface: short edges where the surface bends sharply (wrists, ankles, fingers),
//! the uniform length elsewhere.
//!
//! **Equation.** A triangle of edge `e` with its corners on a sphere of radius `r = 1/κ` lies inside it by at
//! most `ε = r − √(r² − e²/3)` (at its centre), so the longest edge with chord error `ε` on curvature `κ` is
//! (Dunyach, Vanderhaeghe, Barthe & Botsch 2013, "Adaptive remeshing for real-time mesh deformation")
//!
//! ```text
//!     L(κ) = √(6ε/κ − 3ε²),
//! ```
//!
//! taken at each vertex for its largest absolute normal curvature and clamped to `[l_min, l_max]`. The
//! curvature along an edge `(a, b)` with unit vertex normals `n_a`, `n_b` is estimated as
//!
//! ```text
//!     κ_ab = (n_a − n_b) · (p_a − p_b) / |p_a − p_b|²,
//! ```
//!
//! exact on a sphere (`n = p / r` gives `1/r`); a vertex takes the largest `|κ_ab|` of its edges, averaged
//! once with its neighbours' to damp the noise of a scanned surface. The tolerance comes from the uniform
//! length: `ε` is the chord error of an edge of `l_max` on a radius `r_ref`, so surfaces curved more gently
//! than `r_ref` keep `l_max` and only tighter ones are refined. Finally the lengths are graded — `L_v ≤
//! L_u + g |p_u − p_v|` for neighbours, a few passes — so that the mesh does not jump from one size to the
//! other.
//!
//! Units: lengths in the mesh's unit (metres in skintight), curvature in its inverse.

use crate::math::Real;
use crate::mesh::TriMesh;

/// Settings of [`curvature_sizing`] (lengths in the mesh's unit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SizingParams {
    /// The uniform edge length, kept where the surface is flatter than `r_ref`.
    pub l_max: Real,
    /// The shortest edge.
    pub l_min: Real,
    /// The radius of curvature below which edges get shorter than `l_max`.
    pub r_ref: Real,
    /// Grading: how fast the length may grow with distance (dimensionless).
    pub gradation: Real,
}

impl SizingParams {
    /// Edges of `edge` on surfaces flatter than a 50 mm radius, down to `edge / 2` (metres).
    pub fn for_edge_length(edge: Real) -> Self {
        Self {
            l_max: edge,
            l_min: 0.5 * edge,
            r_ref: 0.05,
            gradation: 0.5,
        }
    }

    /// The chord error `ε` of an edge of `l_max` on a radius `r_ref` (the inverse of the equation above).
    pub fn tolerance(&self) -> Real {
        let r = self.r_ref;
        r - (r * r - self.l_max * self.l_max / 3.0).max(0.0).sqrt()
    }
}

/// The longest edge with chord error `eps` on curvature `kappa` (see the module documentation); infinite
/// on a flat surface.
pub fn edge_length_for_error(kappa: Real, eps: Real) -> Real {
    if kappa.is_nan() || kappa <= 0.0 {
        return Real::INFINITY;
    }
    (6.0 * eps / kappa - 3.0 * eps * eps).max(0.0).sqrt()
}

/// The edges of `mesh`, each once.
fn edges(mesh: &TriMesh) -> Vec<(usize, usize)> {
    let mut e: Vec<(usize, usize)> = mesh
        .faces
        .iter()
        .flat_map(|f| (0..3).map(move |k| (f[k].min(f[(k + 1) % 3]), f[k].max(f[(k + 1) % 3]))))
        .collect();
    e.sort_unstable();
    e.dedup();
    e
}

/// Per vertex, the largest absolute normal curvature of its edges, averaged once with its neighbours'.
pub fn vertex_max_curvature(mesh: &TriMesh) -> Vec<Real> {
    let n = mesh.vertex_normals();
    let p = &mesh.positions;
    let edges = edges(mesh);
    let mut kmax = vec![0.0; p.len()];
    for &(a, b) in &edges {
        let d = p[a] - p[b];
        let l2 = d.norm_squared();
        if l2.is_nan() || l2 <= 0.0 {
            continue;
        }
        let k = ((n[a] - n[b]).dot(&d) / l2).abs();
        if k.is_finite() {
            kmax[a] = Real::max(kmax[a], k);
            kmax[b] = Real::max(kmax[b], k);
        }
    }
    let mut sum = kmax.clone();
    let mut count = vec![1.0; p.len()];
    for &(a, b) in &edges {
        sum[a] += kmax[b];
        sum[b] += kmax[a];
        count[a] += 1.0;
        count[b] += 1.0;
    }
    sum.iter().zip(&count).map(|(s, c)| s / c).collect()
}

/// Target edge length at each vertex of `mesh` (see the module documentation).
pub fn curvature_sizing(mesh: &TriMesh, params: &SizingParams) -> Vec<Real> {
    let eps = params.tolerance();
    let mut size: Vec<Real> = vertex_max_curvature(mesh)
        .into_iter()
        .map(|k| edge_length_for_error(k, eps).clamp(params.l_min, params.l_max))
        .collect();
    let edges = edges(mesh);
    for _ in 0..100 {
        let mut changed = false;
        for &(a, b) in &edges {
            let d = params.gradation * (mesh.positions[a] - mesh.positions[b]).norm();
            if size[a] > size[b] + d {
                size[a] = size[b] + d;
                changed = true;
            } else if size[b] > size[a] + d {
                size[b] = size[a] + d;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    size
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::{capped_cylinder, icosphere};

    #[test]
    fn the_edge_of_a_given_chord_error_inverts_the_sagitta_of_a_triangle() {
        let (r, e): (Real, Real) = (0.05, 0.012);
        let eps = r - (r * r - e * e / 3.0).sqrt();
        assert!((edge_length_for_error(1.0 / r, eps) - e).abs() < 1e-12);
        assert_eq!(edge_length_for_error(0.0, eps), Real::INFINITY);
        let p = SizingParams::for_edge_length(e);
        assert!((p.tolerance() - eps).abs() < 1e-15);
    }

    /// The estimate is exact for exactly radial normals; area-weighted normals of an icosphere's uneven
    /// fans tilt a little, which reads up to 8 % high.
    #[test]
    fn curvature_of_spheres_is_their_inverse_radius() {
        for r in [0.02, 0.1] {
            let m = icosphere(4, r);
            let k = vertex_max_curvature(&m);
            for x in k {
                assert!((x * r - 1.0).abs() < 0.08, "r {r}: κ {x}");
            }
        }
    }

    /// A wrist-sized sphere gets the edges of its chord error, a torso-sized one keeps the uniform
    /// length, and a thin cylinder (curved one way) is refined as its radius asks.
    #[test]
    fn tight_curvature_gets_short_edges_and_gentle_curvature_keeps_the_uniform_length() {
        let p = SizingParams::for_edge_length(0.012);
        let eps = p.tolerance();
        let wrist = curvature_sizing(&icosphere(4, 0.02), &p);
        let want = edge_length_for_error(1.0 / 0.02, eps);
        assert!(want > p.l_min && want < 0.7 * p.l_max, "{want}");
        for l in &wrist {
            assert!((l / want - 1.0).abs() < 0.04, "{l} vs {want}");
        }
        for l in curvature_sizing(&icosphere(4, 0.15), &p) {
            assert_eq!(l, p.l_max);
        }
        let finger = curvature_sizing(&icosphere(4, 0.005), &p);
        assert!(finger.iter().all(|&l| l == p.l_min));
        // A cylinder of radius 20 mm: the side wants the wrist's length (the caps' rims are sharper still).
        let cyl = capped_cylinder(0.02, 0.3, 48, 30);
        let s = curvature_sizing(&cyl, &p);
        let mid: Vec<Real> = cyl
            .positions
            .iter()
            .zip(&s)
            .filter(|(q, _)| (q.z - 0.15).abs() < 0.05 && q.x.hypot(q.y) > 0.019)
            .map(|(_, &l)| l)
            .collect();
        assert!(!mid.is_empty());
        for l in mid {
            assert!((l / want - 1.0).abs() < 0.05, "{l} vs {want}");
        }
    }

    #[test]
    fn lengths_are_graded() {
        let p = SizingParams::for_edge_length(0.012);
        let cyl = capped_cylinder(0.02, 0.3, 48, 30);
        let s = curvature_sizing(&cyl, &p);
        for f in &cyl.faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                let d = (cyl.positions[a] - cyl.positions[b]).norm();
                assert!((s[a] - s[b]).abs() <= p.gradation * d + 1e-12);
            }
        }
    }
}
