//! Procedural solid bodies for tests and demos: a solid cylinder and a solid ball as conforming, positively
//! oriented tetrahedral meshes, and ways to mark some of their vertices fixed.
//!
//! * [`solid_cylinder`]: a disk triangulation (a centre vertex and concentric rings whose segment counts grow
//!   linearly with the radius, so the triangles keep roughly the same shape everywhere) extruded along +y in
//!   layers. Each prism is split into three tetrahedra by a rule that depends only on the global vertex
//!   order (see [`prism_tets`]), so neighbouring prisms split their shared quadrilateral the same way.
//! * [`solid_sphere`]: a structured grid of the cube `[−1, 1]³`, each cell split into the six Kuhn
//!   (Freudenthal) tetrahedra around its main diagonal — conforming because every cell is split the same
//!   way — mapped onto the ball by the radial map [`cube_to_ball`] and scaled by the radius.
//! * [`fix_region`] fixes every vertex inside a [`Region`] (the plane-cut conjunction of half-spaces);
//!   [`fix_core`] fixes every vertex within a fraction of the body's radius of its axis or centre.
//!
//! Units: lengths in metres (m). All meshes are centred at the origin.

use std::f64::consts::PI;

use crate::body::tet_mesh::{TetMesh, tet_signed_volume};
use crate::math::{Real, Vec3, VertexId};
use crate::region::Region;

/// Largest number of vertices a procedural body may have; larger requests are rejected instead of
/// exhausting memory.
pub const MAX_VERTICES: usize = 20_000_000;

/// Why a procedural body cannot be built or its vertices fixed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ProceduralBodyError {
    /// A parameter is out of its range.
    #[error("parameter `{field}` = {value} is invalid: {reason}")]
    BadParam {
        /// Name of the offending field.
        field: &'static str,
        /// Its value, as written.
        value: String,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The requested resolution gives more vertices than [`MAX_VERTICES`].
    #[error(
        "the requested body would have {num_vertices} vertices (more than {max}); lower `{field}`"
    )]
    TooLarge {
        field: &'static str,
        num_vertices: usize,
        max: usize,
    },
    /// A half-space of a region cannot be used.
    #[error(
        "half-space {half_space} of region `{region}` is invalid: {reason} (normal {normal:?}, offset {offset})"
    )]
    BadHalfSpace {
        region: String,
        half_space: usize,
        normal: [Real; 3],
        offset: Real,
        reason: &'static str,
    },
    /// The mesh's fixed flags do not match its vertex count.
    #[error("the mesh has {num_vertices} vertices but {num_flags} fixed-vertex flags")]
    FixedLength {
        num_vertices: usize,
        num_flags: usize,
    },
    /// The mesh has a vertex with a non-finite position.
    #[error("vertex {vertex} has a non-finite position")]
    NonFinite { vertex: VertexId },
}

fn bad(field: &'static str, value: impl ToString, reason: &'static str) -> ProceduralBodyError {
    ProceduralBodyError::BadParam {
        field,
        value: value.to_string(),
        reason,
    }
}

fn positive_length(field: &'static str, x: Real) -> Result<(), ProceduralBodyError> {
    if !x.is_finite() {
        return Err(bad(field, x, "must be a finite length in metres"));
    }
    if x <= 0.0 {
        return Err(bad(field, x, "must be positive (m)"));
    }
    Ok(())
}

fn at_least(field: &'static str, n: usize, min: usize) -> Result<(), ProceduralBodyError> {
    if n < min {
        let reason = match min {
            1 => "must be at least 1",
            _ => "must be at least 3",
        };
        return Err(bad(field, n, reason));
    }
    Ok(())
}

/// Settings of [`solid_cylinder`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CylinderParams {
    /// Radius (m), > 0.
    pub radius: Real,
    /// Height along y (m), > 0; the cylinder spans `y ∈ [−height/2, height/2]`.
    pub height: Real,
    /// Number of segments of the outermost ring (≥ 3). Ring `k` of `rings` has
    /// `max(3, round(radial_segments · k / rings))` segments. Triangles are best shaped when
    /// `radial_segments ≈ 2π · rings` (about 6 per ring).
    pub radial_segments: usize,
    /// Number of concentric rings around the centre vertex (≥ 1): the radial resolution.
    pub rings: usize,
    /// Number of layers along the axis (≥ 1). Tetrahedra are best shaped when the layer thickness
    /// `height / layers` is close to the ring spacing `radius / rings`.
    pub layers: usize,
}

impl Default for CylinderParams {
    /// A 5 cm × 20 cm limb-like cylinder with about 1.25 cm elements.
    fn default() -> Self {
        Self {
            radius: 0.05,
            height: 0.2,
            radial_segments: 24,
            rings: 4,
            layers: 16,
        }
    }
}

/// Settings of [`solid_sphere`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SphereParams {
    /// Radius (m), > 0.
    pub radius: Real,
    /// Number of grid cells along each edge of the cube that is mapped onto the ball (≥ 1).
    pub resolution: usize,
}

impl Default for SphereParams {
    /// A ball of 10 cm radius with 8³ cells (3072 tetrahedra).
    fn default() -> Self {
        Self {
            radius: 0.1,
            resolution: 8,
        }
    }
}

/// Segment count of ring `k` (1 ≤ k ≤ rings) of the cylinder's disk.
fn ring_segments(p: &CylinderParams, k: usize) -> usize {
    let n = (p.radial_segments as Real * k as Real / p.rings as Real).round() as usize;
    n.max(3)
}

/// The disk triangulation of the cylinder's cross-section in the `(x, z)` plane: `#Vd` points `(x, z)`
/// (m) — the centre first, then ring after ring, each counter-clockwise from angle 0 — and triangles.
fn disk(p: &CylinderParams) -> (Vec<[Real; 2]>, Vec<[usize; 3]>) {
    let mut points = vec![[0.0, 0.0]];
    let mut tris = Vec::new();
    let mut prev_start = 0;
    let mut prev_n = 1;
    for k in 1..=p.rings {
        let n = ring_segments(p, k);
        let r = p.radius * k as Real / p.rings as Real;
        let start = points.len();
        for j in 0..n {
            let theta = 2.0 * PI * j as Real / n as Real;
            points.push([r * theta.cos(), r * theta.sin()]);
        }
        if k == 1 {
            // Fan around the centre.
            for j in 0..n {
                tris.push([0, start + j, start + (j + 1) % n]);
            }
        } else {
            // Zip the annulus between the previous ring (m points) and this one (n points): advance on
            // whichever ring has the next vertex at the smaller angle; m + n triangles in all.
            let m = prev_n;
            let (mut i, mut j) = (0, 0);
            while i < m || j < n {
                let next_inner = (i + 1) as Real / m as Real;
                let next_outer = (j + 1) as Real / n as Real;
                let inner = prev_start + i % m;
                let outer = start + j % n;
                if j < n && (i >= m || next_outer <= next_inner) {
                    tris.push([inner, outer, start + (j + 1) % n]);
                    j += 1;
                } else {
                    tris.push([inner, outer, prev_start + (i + 1) % m]);
                    i += 1;
                }
            }
        }
        prev_start = start;
        prev_n = n;
    }
    (points, tris)
}

/// The three tetrahedra of the prism over the triangle `tri` between a bottom vertex layer (offset `lo`)
/// and a top one (offset `hi`). With the triangle's vertices sorted `a < b < c`, the split is
/// `[a₀ b₀ c₀ a₁]`, `[b₀ c₀ a₁ b₁]`, `[c₀ a₁ b₁ c₁]`: every side quadrilateral over an edge `(u, v)` with
/// `u < v` is cut along the diagonal `u₁ v₀` (top of the smaller index to bottom of the larger). The rule
/// depends only on the edge, so the two prisms sharing a quadrilateral cut it the same way. Orientation is
/// not fixed here (see `orient`).
pub fn prism_tets(tri: [usize; 3], lo: usize, hi: usize) -> [[VertexId; 4]; 3] {
    let mut t = tri;
    t.sort_unstable();
    let [a, b, c] = t;
    [
        [a + lo, b + lo, c + lo, a + hi],
        [b + lo, c + lo, a + hi, b + hi],
        [c + lo, a + hi, b + hi, c + hi],
    ]
}

/// Swaps two corners of every tetrahedron with negative signed volume so that all are positive.
fn orient(positions: &[Vec3], tets: &mut [[VertexId; 4]]) {
    for t in tets.iter_mut() {
        let [a, b, c, d] = *t;
        if tet_signed_volume(&positions[a], &positions[b], &positions[c], &positions[d]) < 0.0 {
            t.swap(2, 3);
        }
    }
}

/// A fully deformable (no fixed vertex) solid cylinder of the given radius and height along +y, centred at
/// the origin (`y ∈ [−h/2, h/2]`). `#V = #Vd · (layers + 1)` with `#Vd` the disk's vertex count; vertex
/// `l · #Vd + i` is disk vertex `i` on layer `l` (layer 0 at `y = −h/2`); disk vertex 0 is the centre, then
/// ring after ring. `#T = 3 · #Td · layers`, all positively oriented.
///
/// The rim is a polygon inscribed in the circle, so the volume is slightly below `π r² h`
/// (relative deficit ≈ `(2π²/3) / radial_segments²`).
pub fn solid_cylinder(p: &CylinderParams) -> Result<TetMesh, ProceduralBodyError> {
    positive_length("radius", p.radius)?;
    positive_length("height", p.height)?;
    at_least("radial_segments", p.radial_segments, 3)?;
    at_least("rings", p.rings, 1)?;
    at_least("layers", p.layers, 1)?;
    // Vertex count estimate without overflow: ring k has ≤ radial_segments·k/rings + 3 points.
    let per_disk = (p.radial_segments as u128 + 3) * (p.rings as u128 + 1) + 1;
    let total = per_disk * (p.layers as u128 + 1);
    if total > MAX_VERTICES as u128 {
        let field = if p.layers > p.rings {
            "layers"
        } else {
            "rings"
        };
        return Err(ProceduralBodyError::TooLarge {
            field,
            num_vertices: total.min(usize::MAX as u128) as usize,
            max: MAX_VERTICES,
        });
    }

    let (points, tris) = disk(p);
    let nd = points.len();
    let mut positions = Vec::with_capacity(nd * (p.layers + 1));
    for l in 0..=p.layers {
        let y = -0.5 * p.height + p.height * l as Real / p.layers as Real;
        positions.extend(points.iter().map(|&[x, z]| Vec3::new(x, y, z)));
    }
    let mut tets = Vec::with_capacity(3 * tris.len() * p.layers);
    for l in 0..p.layers {
        for &tri in &tris {
            tets.extend_from_slice(&prism_tets(tri, l * nd, (l + 1) * nd));
        }
    }
    orient(&positions, &mut tets);
    Ok(TetMesh::new(positions, tets))
}

/// Maps the cube `[−1, 1]³` onto the unit ball by sliding each point along its ray from the centre:
/// `x' = x · ‖x‖∞ / ‖x‖₂` (`0 ↦ 0`), so every cube shell `‖x‖∞ = s` lands on the sphere of radius `s`.
/// The map is continuous and bi-Lipschitz (smooth except on the planes `|xᵢ| = |xⱼ|` where the largest
/// coordinate changes), so element quality stays bounded below as the grid is refined.
///
/// The smooth "spherified cube" map `x √(1 − y²/2 − z²/2 + y²z²/3)` (cyclically) was tried first and
/// rejected: its Jacobian is singular at the cube's corners, and the minimum quality of the Kuhn grid fell
/// like `1/resolution` (0.49, 0.23, 0.10 at resolutions 8, 16, 32, against ≈ 0.57, 0.53, 0.51 here).
pub fn cube_to_ball(q: &Vec3) -> Vec3 {
    let n2 = q.norm();
    if n2 > 0.0 { q * (q.amax() / n2) } else { *q }
}

/// The six Kuhn tetrahedra of the unit cell, as corner bit masks (bit 0: +x, bit 1: +y, bit 2: +z): each
/// walks from corner 0 to corner 7 adding one axis at a time, in one of the 6 axis orders.
const KUHN: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// A fully deformable solid ball of the given radius centred at the origin: `(resolution + 1)³` vertices
/// (vertex `i + (n+1)(j + (n+1)k)` is the image of grid point `(i, j, k)`) and `6 · resolution³`
/// positively oriented tetrahedra. Boundary vertices lie exactly on the sphere, so the volume is slightly
/// below `4/3 π r³` and converges to it as the resolution grows.
pub fn solid_sphere(p: &SphereParams) -> Result<TetMesh, ProceduralBodyError> {
    positive_length("radius", p.radius)?;
    at_least("resolution", p.resolution, 1)?;
    let n = p.resolution;
    let side = n as u128 + 1;
    let total = side.saturating_mul(side).saturating_mul(side);
    if total > MAX_VERTICES as u128 {
        return Err(ProceduralBodyError::TooLarge {
            field: "resolution",
            num_vertices: total.min(usize::MAX as u128) as usize,
            max: MAX_VERTICES,
        });
    }
    let s = n + 1;
    let index = |i: usize, j: usize, k: usize| i + s * (j + s * k);
    let coord = |i: usize| -1.0 + 2.0 * i as Real / n as Real;
    let mut positions = Vec::with_capacity(s * s * s);
    for k in 0..s {
        for j in 0..s {
            for i in 0..s {
                let q = Vec3::new(coord(i), coord(j), coord(k));
                positions.push(cube_to_ball(&q) * p.radius);
            }
        }
    }
    let mut tets = Vec::with_capacity(6 * n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                // Mirror the split per axis in the lower half so that every cell's main diagonal points
                // away from the centre (better shaped near the cube's corners). Conforming: the diagonal
                // of a face normal to axis a depends only on the flips of the other two axes, which the
                // two cells sharing that face have in common.
                let flip = [2 * i + 1 < n, 2 * j + 1 < n, 2 * k + 1 < n];
                let bit = |m: usize, a: usize| ((m >> a) & 1) ^ usize::from(flip[a]);
                let corner = |m: usize| index(i + bit(m, 0), j + bit(m, 1), k + bit(m, 2));
                for kt in &KUHN {
                    tets.push(kt.map(corner));
                }
            }
        }
    }
    orient(&positions, &mut tets);
    Ok(TetMesh::new(positions, tets))
}

fn check_mesh(mesh: &TetMesh) -> Result<(), ProceduralBodyError> {
    if mesh.fixed.len() != mesh.positions.len() {
        return Err(ProceduralBodyError::FixedLength {
            num_vertices: mesh.positions.len(),
            num_flags: mesh.fixed.len(),
        });
    }
    if let Some(v) = mesh
        .positions
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
    {
        return Err(ProceduralBodyError::NonFinite { vertex: v });
    }
    Ok(())
}

/// Marks fixed every vertex inside `region` (the closed intersection of its half-spaces `n̂·x ≤ d`, with
/// the normal normalised as in [`crate::region::HalfSpace`]; an empty region is all of space). Vertices
/// already fixed stay fixed. Returns the number of vertices inside the region.
///
/// A half-space whose normal is zero or non-finite, or whose offset is non-finite, is an error.
pub fn fix_region(mesh: &mut TetMesh, region: &Region) -> Result<usize, ProceduralBodyError> {
    check_mesh(mesh)?;
    let mut planes = Vec::with_capacity(region.half_spaces.len());
    for (h, hs) in region.half_spaces.iter().enumerate() {
        let norm = hs.normal.norm();
        let err = |reason| ProceduralBodyError::BadHalfSpace {
            region: region.label.clone(),
            half_space: h,
            normal: [hs.normal.x, hs.normal.y, hs.normal.z],
            offset: hs.offset,
            reason,
        };
        if !norm.is_finite() {
            return Err(err("the normal is not finite"));
        }
        if norm <= 0.0 {
            return Err(err("the normal is zero"));
        }
        if !hs.offset.is_finite() {
            return Err(err("the offset is not finite"));
        }
        planes.push((hs.normal / norm, hs.offset / norm));
    }
    let mut count = 0;
    for (p, fixed) in mesh.positions.iter().zip(mesh.fixed.iter_mut()) {
        if planes.iter().all(|(n, d)| n.dot(p) <= *d) {
            *fixed = true;
            count += 1;
        }
    }
    Ok(count)
}

/// What [`fix_core`] measures distance from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Core {
    /// The y axis (for [`solid_cylinder`]): distance `√(x² + z²)`.
    Axis,
    /// The origin (for [`solid_sphere`]): distance `|p|`.
    Centre,
}

/// Marks fixed every vertex whose distance from the axis or centre (see [`Core`]) is at most
/// `fraction · R`, where `R` is the largest such distance over the mesh (the body's radius). A relative
/// tolerance of 1e-9 keeps vertices lying exactly on that radius (a whole ring, say) together.
/// `fraction` is dimensionless, in `[0, 1]`. Vertices already fixed stay fixed. Returns the number of
/// vertices within the core.
pub fn fix_core(
    mesh: &mut TetMesh,
    core: Core,
    fraction: Real,
) -> Result<usize, ProceduralBodyError> {
    if !(0.0..=1.0).contains(&fraction) {
        return Err(bad(
            "fraction",
            fraction,
            "must be a number between 0 and 1 (share of the body's radius)",
        ));
    }
    check_mesh(mesh)?;
    let dist = |p: &Vec3| match core {
        Core::Axis => (p.x * p.x + p.z * p.z).sqrt(),
        Core::Centre => p.norm(),
    };
    let radius = mesh.positions.iter().map(dist).fold(0.0, Real::max);
    let limit = fraction * radius * (1.0 + 1e-9);
    let mut count = 0;
    for (p, fixed) in mesh.positions.iter().zip(mesh.fixed.iter_mut()) {
        if dist(p) <= limit {
            *fixed = true;
            count += 1;
        }
    }
    Ok(count)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::tet_boundary::outer_boundary_surface;
    use crate::mesh::topology::Topology;
    use crate::region::HalfSpace;

    fn cyl(rings: usize) -> CylinderParams {
        // Elements about radius/rings in every direction.
        CylinderParams {
            radius: 0.05,
            height: 0.2,
            radial_segments: 6 * rings,
            rings,
            layers: 4 * rings,
        }
    }

    fn check_closed_outward(mesh: &TetMesh, expected_volume: Real) {
        let b = outer_boundary_surface(mesh).unwrap();
        let topo = Topology::new(b.mesh.positions.len(), &b.mesh.faces).unwrap();
        assert!(topo.is_closed());
        let (_, components) = topo.face_components();
        assert_eq!(components, 1);
        // The boundary encloses exactly the tetrahedra's volume, with outward orientation.
        let v = b.mesh.signed_volume();
        assert!(v > 0.0);
        assert!((v - expected_volume).abs() < 1e-12 * expected_volume.abs().max(1e-9));
    }

    #[test]
    fn procedural_cylinder_is_positive_well_shaped_and_closed() {
        let mut prev_err = Real::INFINITY;
        for rings in [1, 2, 4, 8] {
            let p = cyl(rings);
            let mesh = solid_cylinder(&p).unwrap();
            mesh.validate(0.5).unwrap();
            let stats = mesh.quality_stats();
            assert_eq!(stats.inverted, 0);
            assert!(stats.min > 0.5, "rings {rings}: min quality {}", stats.min);
            assert_eq!(mesh.num_fixed(), 0);
            let exact = PI * p.radius * p.radius * p.height;
            let err = (mesh.volume() - exact).abs() / exact;
            // Inscribed polygon: deficit ≈ (2π²/3)/radial_segments².
            let bound = 1.1 * (2.0 * PI * PI / 3.0) / (p.radial_segments as Real).powi(2);
            assert!(mesh.volume() < exact);
            assert!(err < bound, "rings {rings}: volume error {err}");
            assert!(err < prev_err);
            prev_err = err;
            check_closed_outward(&mesh, mesh.volume());
            for q in &mesh.positions {
                assert!(q.y >= -0.1 - 1e-15 && q.y <= 0.1 + 1e-15);
                assert!((q.x * q.x + q.z * q.z).sqrt() <= p.radius * (1.0 + 1e-12));
            }
        }
        assert!(prev_err < 0.02);
    }

    #[test]
    fn procedural_cylinder_counts_and_conformity() {
        let p = cyl(3);
        let mesh = solid_cylinder(&p).unwrap();
        let nd = 1 + (1..=3).map(|k| ring_segments(&p, k)).sum::<usize>();
        assert_eq!(mesh.num_vertices(), nd * (p.layers + 1));
        // Disk triangles: n₁ + Σ_{k≥2} (n_{k−1} + n_k).
        let nt: usize = ring_segments(&p, 1)
            + (2..=3)
                .map(|k| ring_segments(&p, k - 1) + ring_segments(&p, k))
                .sum::<usize>();
        assert_eq!(mesh.num_tets(), 3 * nt * p.layers);
        // Conformity: every triangle is shared by at most two tets (checked inside boundary extraction),
        // and the boundary count matches a closed cylinder's: 2 caps of nt triangles plus 2 per rim quad.
        let b = outer_boundary_surface(&mesh).unwrap();
        assert_eq!(
            b.mesh.faces.len(),
            2 * nt + 2 * ring_segments(&p, 3) * p.layers
        );
    }

    #[test]
    fn procedural_sphere_is_positive_well_shaped_and_closed() {
        let mut prev_err = Real::INFINITY;
        for resolution in [2, 4, 8, 16] {
            let p = SphereParams {
                radius: 0.1,
                resolution,
            };
            let mesh = solid_sphere(&p).unwrap();
            mesh.validate(0.5).unwrap();
            let stats = mesh.quality_stats();
            assert_eq!(stats.inverted, 0);
            assert!(
                stats.min > 0.5,
                "res {resolution}: min quality {}",
                stats.min
            );
            assert_eq!(mesh.num_tets(), 6 * resolution.pow(3));
            let exact = 4.0 / 3.0 * PI * p.radius.powi(3);
            let err = (mesh.volume() - exact).abs() / exact;
            assert!(err < prev_err, "res {resolution}: volume error {err}");
            prev_err = err;
            check_closed_outward(&mesh, mesh.volume());
            for q in &mesh.positions {
                assert!(q.norm() <= p.radius * (1.0 + 1e-12));
            }
        }
        assert!(prev_err < 0.03, "volume error {prev_err}");
    }

    #[test]
    fn procedural_sphere_boundary_vertices_lie_on_the_sphere() {
        let p = SphereParams {
            radius: 0.3,
            resolution: 5,
        };
        let mesh = solid_sphere(&p).unwrap();
        let b = outer_boundary_surface(&mesh).unwrap();
        assert_eq!(b.tet_vertex.len(), 6 * 16 + 12 * 4 + 8);
        for q in &b.mesh.positions {
            assert!((q.norm() - 0.3).abs() < 1e-12);
        }
    }

    #[test]
    fn procedural_fix_region_picks_bottom_cap_and_half() {
        let p = cyl(2);
        let mut mesh = solid_cylinder(&p).unwrap();
        let nd = mesh.num_vertices() / (p.layers + 1);
        // Bottom cap: y ≤ −h/2 + a tenth of a layer.
        let region = Region {
            label: "bottom".into(),
            half_spaces: vec![HalfSpace {
                normal: Vec3::new(0.0, 2.0, 0.0), // not unit: rescaled
                offset: 2.0 * (-0.1 + 0.1 * p.height / p.layers as Real),
            }],
        };
        assert_eq!(fix_region(&mut mesh, &region).unwrap(), nd);
        assert_eq!(mesh.fixed_vertices(), (0..nd).collect::<Vec<_>>());

        // A second, two-plane region adds the x > 0 (strictly) part of the top layer.
        let region = Region {
            label: "top right".into(),
            half_spaces: vec![
                HalfSpace {
                    normal: Vec3::new(0.0, -1.0, 0.0),
                    offset: -0.1 + 1e-9,
                },
                HalfSpace {
                    normal: Vec3::new(-1.0, 0.0, 0.0),
                    offset: -1e-9,
                },
            ],
        };
        let top = p.layers * nd;
        let expected: Vec<usize> = (top..top + nd)
            .filter(|&v| mesh.positions[v].x >= 1e-9)
            .collect();
        assert!(!expected.is_empty());
        assert_eq!(fix_region(&mut mesh, &region).unwrap(), expected.len());
        let mut all: Vec<usize> = (0..nd).collect();
        all.extend(&expected);
        assert_eq!(mesh.fixed_vertices(), all);

        // Empty region: everything.
        let everything = Region {
            label: "all".into(),
            half_spaces: vec![],
        };
        assert_eq!(
            fix_region(&mut mesh, &everything).unwrap(),
            mesh.num_vertices()
        );
        assert_eq!(mesh.num_fixed(), mesh.num_vertices());
    }

    #[test]
    fn procedural_fix_core_picks_inner_rings_and_inner_ball() {
        let p = cyl(4);
        let mut mesh = solid_cylinder(&p).unwrap();
        // Half the radius = rings 0..=2 of 4 on every layer.
        let per_layer = 1 + ring_segments(&p, 1) + ring_segments(&p, 2);
        assert_eq!(
            fix_core(&mut mesh, Core::Axis, 0.5).unwrap(),
            per_layer * (p.layers + 1)
        );
        let nd = mesh.num_vertices() / (p.layers + 1);
        for v in 0..mesh.num_vertices() {
            assert_eq!(mesh.fixed[v], v % nd < per_layer, "vertex {v}");
        }

        let s = SphereParams {
            radius: 0.1,
            resolution: 6,
        };
        let mut ball = solid_sphere(&s).unwrap();
        assert_eq!(fix_core(&mut ball, Core::Centre, 0.0).unwrap(), 1);
        assert!(ball.fixed[3 + 7 * (3 + 7 * 3)]);
        let n = fix_core(&mut ball, Core::Centre, 0.6).unwrap();
        let expected = ball
            .positions
            .iter()
            .filter(|q| q.norm() <= 0.06 * (1.0 + 1e-9))
            .count();
        assert_eq!(n, expected);
        assert!(n > 1 && n < ball.num_vertices());
        assert_eq!(ball.num_fixed(), expected);
        assert_eq!(
            fix_core(&mut ball, Core::Centre, 1.0).unwrap(),
            ball.num_vertices()
        );
    }

    fn field_of(e: ProceduralBodyError) -> &'static str {
        match e {
            ProceduralBodyError::BadParam { field, .. } => field,
            ProceduralBodyError::TooLarge { field, .. } => field,
            other => panic!("unexpected error {other}"),
        }
    }

    #[test]
    fn procedural_bad_params_name_the_field() {
        let ok = CylinderParams::default();
        let cases: Vec<(CylinderParams, &str)> = vec![
            (CylinderParams { radius: 0.0, ..ok }, "radius"),
            (CylinderParams { radius: -1.0, ..ok }, "radius"),
            (
                CylinderParams {
                    radius: Real::NAN,
                    ..ok
                },
                "radius",
            ),
            (
                CylinderParams {
                    height: Real::INFINITY,
                    ..ok
                },
                "height",
            ),
            (
                CylinderParams {
                    height: Real::NAN,
                    ..ok
                },
                "height",
            ),
            (
                CylinderParams {
                    radial_segments: 0,
                    ..ok
                },
                "radial_segments",
            ),
            (
                CylinderParams {
                    radial_segments: 2,
                    ..ok
                },
                "radial_segments",
            ),
            (CylinderParams { rings: 0, ..ok }, "rings"),
            (CylinderParams { layers: 0, ..ok }, "layers"),
            (
                CylinderParams {
                    layers: usize::MAX,
                    ..ok
                },
                "layers",
            ),
        ];
        for (p, field) in cases {
            let e = solid_cylinder(&p).unwrap_err();
            assert!(e.to_string().contains(field), "{e}");
            assert_eq!(field_of(e), field);
        }
        let ok = SphereParams::default();
        for (p, field) in [
            (
                SphereParams {
                    radius: Real::NAN,
                    ..ok
                },
                "radius",
            ),
            (SphereParams { radius: -0.1, ..ok }, "radius"),
            (
                SphereParams {
                    resolution: 0,
                    ..ok
                },
                "resolution",
            ),
            (
                SphereParams {
                    resolution: usize::MAX,
                    ..ok
                },
                "resolution",
            ),
        ] {
            let e = solid_sphere(&p).unwrap_err();
            assert!(e.to_string().contains(field), "{e}");
            assert_eq!(field_of(e), field);
        }

        let mut mesh = solid_sphere(&SphereParams::default()).unwrap();
        for f in [Real::NAN, -0.1, 1.5] {
            assert_eq!(
                field_of(fix_core(&mut mesh, Core::Centre, f).unwrap_err()),
                "fraction"
            );
        }
        let zero = Region {
            label: "broken".into(),
            half_spaces: vec![HalfSpace {
                normal: Vec3::zeros(),
                offset: 0.0,
            }],
        };
        let e = fix_region(&mut mesh, &zero).unwrap_err();
        assert!(e.to_string().contains("broken") && e.to_string().contains("zero"));
        let nan = Region {
            label: "nan".into(),
            half_spaces: vec![HalfSpace {
                normal: Vec3::x(),
                offset: Real::NAN,
            }],
        };
        assert!(fix_region(&mut mesh, &nan).is_err());
        assert_eq!(mesh.num_fixed(), 0);
        mesh.fixed.pop();
        assert!(matches!(
            fix_core(&mut mesh, Core::Centre, 0.5),
            Err(ProceduralBodyError::FixedLength { .. })
        ));
    }

    #[test]
    fn procedural_sphere_quality_does_not_decay_at_cube_corners() {
        // Regression: the spherified-cube map is singular at the cube's corners (min quality 0.10 here).
        let mesh = solid_sphere(&SphereParams {
            radius: 0.1,
            resolution: 32,
        })
        .unwrap();
        let stats = mesh.quality_stats();
        assert!(stats.min > 0.5, "min quality {}", stats.min);
    }
}
