//! The shape objective (thesis Eq. 171–172): pull the worn garment onto a target surface through an
//! implicit moving least squares (IMLS) distance, without per-vertex correspondence.
//!
//! # The distance
//!
//! The target is a triangle mesh. Its IMLS points are the mesh **vertices** `c_k` (as Eq. 171 says) with
//! unit **area-weighted vertex normals** `n_k` (the normalised sum of the cross products
//! `(b − a) × (c − a)` of the incident triangles, so the target must be oriented consistently, normals
//! pointing to the side where the distance is positive). Vertices used by no triangle, or whose normal
//! sum vanishes, are not IMLS points. With the kernel `φ(r) = (1 − r²/h²)⁴` for `r < h`, 0 beyond
//! (Eq. 172; C³ at `r = h`),
//!
//! ```text
//! d(x) = Σ_k n_k·(x − c_k) φ(|x − c_k|) / Σ_k φ(|x − c_k|)                       (m)
//! ```
//!
//! (Eq. 171 as printed has a stray outer sum over `k`; this is the IMLS surface of Kolluri 2005 /
//! Öztireli et al. 2009 that it cites.) Near a smooth target it approximates the signed distance, with a
//! bias of about `h²/(12 R)` for a surface of curvature radius `R`.
//!
//! **Radius** `h` (m): given, or by default [`ShapeImls::DEFAULT_RADIUS_FACTOR`] (3) times the target's
//! mean triangle side length, so that a query on the surface sees a few dozen points.
//!
//! **Far from the target** (no IMLS point within `h`): `d(x) = n_k·(x − c_k)` for the *nearest* IMLS point
//! `k` (the distance to its tangent plane; ties go to the lower index). This is what the IMLS formula
//! itself gives when a single point is in reach, and the nearest point is the last one to leave the
//! support, so `d` is continuous (and C¹) across the `h` shell. Beyond `h` it is piecewise linear, with
//! jumps only where two points are equally near. Its gradient there is `n_k`, exact.
//!
//! The weights are evaluated relative to the largest one (`(t_k/t_max)⁴`, `t = 1 − r²/h²`), which leaves
//! `d` unchanged and keeps the denominator ≥ 1, so nothing underflows near the support's edge.
//!
//! Neighbours within `h` come from a hashed uniform grid of cell size `h` (the 27 cells around the query);
//! the nearest point for the fallback from a k-d tree. Both are built once in the constructor.
//!
//! # The term
//!
//! `T = w Σ_i d(x_i)²` (m² × weight) over all cloth vertices or a chosen subset; `per_element[i]` is
//! `w d(x_i)²` for cloth vertex `i` (0 for vertices not in the subset). The term does not depend on the
//! pattern. Residuals `r_i = √w d(x_i)` with `∂r_i/∂x_i = √w ∇d(x_i)`, one per vertex of the subset.

use crate::math::{Real, Vec3};
use crate::term::{
    Residuals, Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight,
};
use skintight_geometry::mesh::TriMesh;
use std::collections::HashMap;

/// The shape objective of Eq. 171–172; see the module documentation.
#[derive(Clone, Debug)]
pub struct ShapeImls {
    weight: Real,
    radius: Real,
    points: Vec<Vec3>,
    normals: Vec<Vec3>,
    grid: PointGrid,
    tree: KdTree,
    vertices: Option<Vec<usize>>,
}

fn parameter_error<T>(message: String) -> Result<T, TermError> {
    Err(TermError::Parameter {
        term: ShapeImls::NAME,
        message,
    })
}

impl ShapeImls {
    /// Name of the term in reports.
    pub const NAME: &'static str = "shape";

    /// Default IMLS radius, in mean triangle side lengths of the target.
    pub const DEFAULT_RADIUS_FACTOR: Real = 3.0;

    /// The objective with weight `weight` (≥ 0, finite; multiplies m²) towards the target surface with
    /// `#Vt` vertex positions `target_positions` (m) and `#Ft × 3` consistently oriented triangles
    /// `target_triangles` (the distance is positive on the side the normals point to). `radius` is the
    /// IMLS radius `h` (m, finite and positive); `None` takes [`Self::DEFAULT_RADIUS_FACTOR`] times the
    /// mean triangle side length.
    pub fn new(
        weight: Real,
        target_positions: &[Vec3],
        target_triangles: &[[usize; 3]],
        radius: Option<Real>,
    ) -> Result<Self, TermError> {
        check_weight(Self::NAME, "weight", weight)?;
        if let Some(h) = radius
            && !(h.is_finite() && h > 0.0)
        {
            return parameter_error(format!("radius must be finite and positive, got {h} m"));
        }
        if target_triangles.is_empty() {
            return parameter_error("the target surface has no triangles".into());
        }
        if let Some(v) = target_positions
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return parameter_error(format!("target vertex {v} is not finite"));
        }
        let nv = target_positions.len();
        if let Some(f) = target_triangles
            .iter()
            .position(|t| t.iter().any(|&v| v >= nv))
        {
            return parameter_error(format!(
                "target triangle {f} has a vertex id out of range ({nv} vertices)"
            ));
        }
        let mut normal_sum = vec![Vec3::zeros(); nv];
        let mut side_sum = 0.0;
        for t in target_triangles {
            let [a, b, c] = t.map(|v| target_positions[v]);
            let n = (b - a).cross(&(c - a));
            for &v in t {
                normal_sum[v] += n;
            }
            side_sum += (b - a).norm() + (c - b).norm() + (a - c).norm();
        }
        let mean_side = side_sum / (3 * target_triangles.len()) as Real;
        let h = radius.unwrap_or(Self::DEFAULT_RADIUS_FACTOR * mean_side);
        if !(h.is_finite() && h > 0.0) {
            return parameter_error(format!(
                "the target's triangles have no extent, so no default radius (got {h} m)"
            ));
        }
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for (p, n) in target_positions.iter().zip(&normal_sum) {
            let len = n.norm();
            if len > 0.0 && len.is_finite() {
                points.push(*p);
                normals.push(n / len);
            }
        }
        if points.is_empty() {
            return parameter_error("the target surface has no vertex with a normal".into());
        }
        let grid = PointGrid::new(&points, h);
        let tree = KdTree::new(&points);
        Ok(Self {
            weight,
            radius: h,
            points,
            normals,
            grid,
            tree,
            vertices: None,
        })
    }

    /// [`Self::new`] with the target as a [`TriMesh`].
    pub fn from_mesh(
        weight: Real,
        target: &TriMesh,
        radius: Option<Real>,
    ) -> Result<Self, TermError> {
        Self::new(weight, &target.positions, &target.faces, radius)
    }

    /// Restricts the objective to the cloth vertices `vertices` (distinct cloth vertex ids, checked
    /// against `#Vc` when evaluated).
    pub fn with_vertices(mut self, vertices: Vec<usize>) -> Result<Self, TermError> {
        let mut sorted = vertices.clone();
        sorted.sort_unstable();
        if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
            return parameter_error(format!("cloth vertex {} is listed twice", w[0]));
        }
        self.vertices = Some(vertices);
        Ok(self)
    }

    /// The weight `w` (multiplies m²).
    pub fn weight(&self) -> Real {
        self.weight
    }

    /// The IMLS radius `h` (m).
    pub fn radius(&self) -> Real {
        self.radius
    }

    /// The IMLS points `c_k` (m), `#K`.
    pub fn points(&self) -> &[Vec3] {
        &self.points
    }

    /// The unit normals `n_k` of the IMLS points, `#K`.
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// The cloth vertices the objective covers; `None` for all.
    pub fn vertices(&self) -> Option<&[usize]> {
        self.vertices.as_deref()
    }

    /// The IMLS distance `d(x)` (m) of the point `x` (m, finite).
    pub fn distance(&self, x: &Vec3) -> Real {
        self.distance_gradient(x).0
    }

    /// `d(x)` (m) and its gradient `∇d(x)` (dimensionless) at the finite point `x` (m).
    pub fn distance_gradient(&self, x: &Vec3) -> (Real, Vec3) {
        let h2 = self.radius * self.radius;
        // (point, t = 1 − r²/h² > 0) for the points within h.
        let mut near: Vec<(usize, Real)> = Vec::new();
        self.grid.for_each_near(x, |k| {
            let s = (x - self.points[k]).norm_squared();
            if s < h2 {
                near.push((k, 1.0 - s / h2));
            }
        });
        let t_max = near.iter().fold(0.0_f64, |m, &(_, t)| m.max(t));
        if t_max <= 0.0 {
            let k = self.tree.nearest(&self.points, x);
            return (self.normals[k].dot(&(x - self.points[k])), self.normals[k]);
        }
        // Weights relative to the largest: w_k = (t_k/t_max)⁴ ∈ (0, 1], one of them 1, so D ≥ 1.
        let (mut den, mut num) = (0.0, 0.0);
        for &(k, t) in &near {
            let w = (t / t_max).powi(4);
            den += w;
            num += w * self.normals[k].dot(&(x - self.points[k]));
        }
        let d = num / den;
        // ∇d = (Σ w_k n_k + Σ (e_k − d) ∇w_k) / D, ∇w_k = 4 (t_k/t_max)³ (−2 (x − c_k)/h²) / t_max.
        let mut grad = Vec3::zeros();
        for &(k, t) in &near {
            let q = t / t_max;
            let diff = x - self.points[k];
            let e = self.normals[k].dot(&diff);
            let dw = diff * (-8.0 * q * q * q / (h2 * t_max));
            grad += self.normals[k] * q.powi(4) + dw * (e - d);
        }
        (d, grad / den)
    }

    /// The cloth vertices evaluated, checked against `#Vc`.
    fn covered(&self, input: &TermInput) -> Result<Vec<usize>, TermError> {
        let nc = input.mesh.num_cloth_vertices;
        match &self.vertices {
            None => Ok((0..nc).collect()),
            Some(v) => {
                if let Some(&bad) = v.iter().find(|&&i| i >= nc) {
                    return Err(TermError::Invalid {
                        term: Self::NAME,
                        message: format!("cloth vertex {bad} of the subset is out of range ({nc})"),
                    });
                }
                Ok(v.clone())
            }
        }
    }
}

impl Term for ShapeImls {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    /// Value in m² × weight; `per_element[i]` for cloth vertex `i` (`#Vc`). Adds `∂T/∂x` (`#Vc × 3`, m ×
    /// weight); `∂T/∂X̄` is zero.
    fn evaluate(
        &self,
        input: &TermInput,
        mut gradient: Option<&mut TermGradient>,
    ) -> Result<TermEvaluation, TermError> {
        input.validate(Self::NAME, gradient.as_deref())?;
        let mut per_element = vec![0.0; input.mesh.num_cloth_vertices];
        for i in self.covered(input)? {
            let (d, g) = self.distance_gradient(&input.cloth[i]);
            per_element[i] = self.weight * d * d;
            if let Some(grad) = gradient.as_deref_mut() {
                grad.cloth[i] += g * (2.0 * self.weight * d);
            }
        }
        TermEvaluation::from_per_element(Self::NAME, per_element)
    }

    /// `r = √w d(x_i)` (m × √weight) for each covered cloth vertex, in the subset's order (or by id).
    fn residuals(&self, input: &TermInput) -> Option<Result<Residuals, TermError>> {
        let run = || {
            input.validate(Self::NAME, None)?;
            let root = self.weight.sqrt();
            let mut out = Residuals::default();
            for (k, i) in self.covered(input)?.into_iter().enumerate() {
                let (d, g) = self.distance_gradient(&input.cloth[i]);
                out.values.push(root * d);
                out.cloth_jacobian.push((k, i, g * root));
            }
            Ok(out)
        };
        Some(run())
    }
}

/// Hashed uniform grid of points with cubic cells of edge `cell` (m).
#[derive(Clone, Debug)]
struct PointGrid {
    cell: Real,
    cells: HashMap<[i64; 3], Vec<u32>>,
}

impl PointGrid {
    fn new(points: &[Vec3], cell: Real) -> Self {
        let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (k, p) in points.iter().enumerate() {
            cells.entry(Self::key(p, cell)).or_default().push(k as u32);
        }
        Self { cell, cells }
    }

    /// Cell of `p`; saturates for coordinates beyond the `i64` range.
    fn key(p: &Vec3, cell: Real) -> [i64; 3] {
        [0, 1, 2].map(|i| (p[i] / cell).floor() as i64)
    }

    /// Calls `visit` with every point in the 27 cells around `x`: a superset of the points closer than
    /// `cell` to `x`.
    fn for_each_near(&self, x: &Vec3, mut visit: impl FnMut(usize)) {
        let [i, j, k] = Self::key(x, self.cell);
        for di in -1..=1_i64 {
            for dj in -1..=1_i64 {
                for dk in -1..=1_i64 {
                    let key = [
                        i.saturating_add(di),
                        j.saturating_add(dj),
                        k.saturating_add(dk),
                    ];
                    if let Some(list) = self.cells.get(&key) {
                        list.iter().for_each(|&p| visit(p as usize));
                    }
                }
            }
        }
    }
}

/// Static k-d tree over the IMLS points, stored implicitly: the node of the index range `[lo, hi)` is
/// `order[mid]`, `mid = lo + (hi − lo)/2`, splitting on coordinate `axis[mid]`, with the smaller half to its
/// left.
#[derive(Clone, Debug)]
struct KdTree {
    order: Vec<u32>,
    axis: Vec<u8>,
}

impl KdTree {
    fn new(points: &[Vec3]) -> Self {
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        let mut axis = vec![0_u8; points.len()];
        Self::build(points, &mut order, &mut axis);
        Self { order, axis }
    }

    fn build(points: &[Vec3], order: &mut [u32], axis: &mut [u8]) {
        if order.len() <= 1 {
            return;
        }
        let mut lo = Vec3::repeat(Real::INFINITY);
        let mut hi = Vec3::repeat(Real::NEG_INFINITY);
        for &k in order.iter() {
            lo = lo.inf(&points[k as usize]);
            hi = hi.sup(&points[k as usize]);
        }
        let a = (hi - lo).imax();
        let mid = order.len() / 2;
        order.select_nth_unstable_by(mid, |&p, &q| {
            points[p as usize][a].total_cmp(&points[q as usize][a])
        });
        axis[mid] = a as u8;
        let (left, right) = order.split_at_mut(mid);
        let (left_axis, right_axis) = axis.split_at_mut(mid);
        Self::build(points, left, left_axis);
        Self::build(points, &mut right[1..], &mut right_axis[1..]);
    }

    /// Index of the point nearest to `q` (the lowest index among equally near ones).
    fn nearest(&self, points: &[Vec3], q: &Vec3) -> usize {
        let mut best = (Real::INFINITY, usize::MAX);
        self.search(points, q, 0, self.order.len(), &mut best);
        best.1
    }

    fn search(&self, points: &[Vec3], q: &Vec3, lo: usize, hi: usize, best: &mut (Real, usize)) {
        if lo >= hi {
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let k = self.order[mid] as usize;
        let d2 = (q - points[k]).norm_squared();
        if d2 < best.0 || (d2 == best.0 && k < best.1) {
            *best = (d2, k);
        }
        let a = self.axis[mid] as usize;
        let diff = q[a] - points[k][a];
        let (near, far) = if diff < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.search(points, q, near.0, near.1, best);
        if diff * diff <= best.0 {
            self.search(points, q, far.0, far.1, best);
        }
    }
}

/// An open cylinder of radius `radius` and height `height` (m) about the z axis from `z = 0`, with
/// `segments` vertices around and `rings + 1` rows of vertices, normals pointing outwards: a procedural
/// target for [`ShapeImls::from_mesh`]. Needs `segments ≥ 3`, `rings ≥ 1` and positive finite sizes.
pub fn cylinder_target(
    radius: Real,
    height: Real,
    segments: usize,
    rings: usize,
) -> Result<TriMesh, TermError> {
    if !(radius.is_finite() && radius > 0.0 && height.is_finite() && height > 0.0) {
        return parameter_error(format!(
            "cylinder radius and height must be finite and positive, got {radius} m and {height} m"
        ));
    }
    if segments < 3 || rings < 1 {
        return parameter_error(format!(
            "a cylinder needs at least 3 segments and 1 ring, got {segments} and {rings}"
        ));
    }
    let mut positions = Vec::with_capacity(segments * (rings + 1));
    for j in 0..=rings {
        let z = height * j as Real / rings as Real;
        for i in 0..segments {
            let a = std::f64::consts::TAU * i as Real / segments as Real;
            positions.push(Vec3::new(radius * a.cos(), radius * a.sin(), z));
        }
    }
    let id = |i: usize, j: usize| j * segments + i % segments;
    let mut faces = Vec::with_capacity(2 * segments * rings);
    for j in 0..rings {
        for i in 0..segments {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Ok(TriMesh::new(positions, faces))
}

/// A latitude–longitude sphere of radius `radius` (m) about the origin with `stacks` bands from pole to
/// pole and `slices` vertices around, normals pointing outwards: a procedural target for
/// [`ShapeImls::from_mesh`]. Needs `stacks ≥ 2`, `slices ≥ 3` and a positive finite radius.
pub fn sphere_target(radius: Real, stacks: usize, slices: usize) -> Result<TriMesh, TermError> {
    if !(radius.is_finite() && radius > 0.0) {
        return parameter_error(format!(
            "sphere radius must be finite and positive, got {radius} m"
        ));
    }
    if stacks < 2 || slices < 3 {
        return parameter_error(format!(
            "a sphere needs at least 2 stacks and 3 slices, got {stacks} and {slices}"
        ));
    }
    let mut positions = vec![Vec3::new(0.0, 0.0, -radius)];
    for j in 1..stacks {
        let polar = std::f64::consts::PI * j as Real / stacks as Real;
        let (sp, cp) = polar.sin_cos();
        for i in 0..slices {
            let a = std::f64::consts::TAU * i as Real / slices as Real;
            positions.push(Vec3::new(
                radius * sp * a.cos(),
                radius * sp * a.sin(),
                -radius * cp,
            ));
        }
    }
    let top = positions.len();
    positions.push(Vec3::new(0.0, 0.0, radius));
    let id = |i: usize, j: usize| 1 + (j - 1) * slices + i % slices;
    let mut faces = Vec::new();
    for i in 0..slices {
        faces.push([0, id(i + 1, 1), id(i, 1)]);
        faces.push([top, id(i, stacks - 1), id(i + 1, stacks - 1)]);
    }
    for j in 1..stacks - 1 {
        for i in 0..slices {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Ok(TriMesh::new(positions, faces))
}

#[cfg(test)]
mod tests;
