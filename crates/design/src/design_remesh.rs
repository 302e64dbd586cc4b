//! Remeshing a design whose pattern triangles have degraded (issue deliverable 6): resample the boundary,
//! remesh, re-embed, continue.
//!
//! The design moves the boundary and the interior follows by biharmonic coordinates, so after large
//! changes some pattern triangles get thin ([`mod@crate::pattern_quality`] says when). [`design_remesh`] then
//! 1. remeshes the current patterns at the target edge length
//!    ([`garment_remesh`]: boundaries resampled by pattern arc length with the corners and seam ends kept,
//!    both sides of every seam with the same samples, a constrained Delaunay refinement inside), and
//!    locates every new vertex in a previous pattern triangle;
//! 2. re-embeds the worn garment: a new cloth vertex goes to the same barycentric combination of its previous
//!    triangle's *worn* positions, projected onto the body's smooth surface (the previous deformation is
//!    piecewise linear over the previous triangles, so the new cloth starts where the old one was and its
//!    first equilibrium is a short warm start); a new vertex that is a previous one keeps its surface
//!    coordinates exactly. The body keeps its deformed state;
//! 3. pins a new vertex on the free boundary when every previous vertex it is interpolated from was pinned;
//! 4. rebuilds the system ([`ClothOnBody::remeshed`](skintight_physics::ClothOnBody::remeshed)), the connectivity ([`DesignMesh`]), the boundary
//!    parametrization ([`PatternMap`], biharmonic coordinates of the new mesh) and hands the problem its new
//!    cloth, keeping its terms and solver settings ([`DesignProblem::replace_cloth`]).
//!
//! [`remesh_edge_length`] gives the pattern edge length that keeps the worn triangles at the job's cloth
//! edge length.

use skintight_garment::garment::Garment;
use skintight_garment::garment_remesh::garment_remesh;
use skintight_garment::pattern_remesh::RemeshParams;
use skintight_geometry::surface::SurfaceCoord;
use skintight_geometry::surface::closest_point::{ClosestPointParams, closest_point_from};
use skintight_physics::ClothOnBodyState;

use crate::design_mesh::DesignMesh;
use crate::design_problem::{DesignError, DesignProblem};
use crate::math::{Real, Vec2};
use crate::pattern_map::PatternMap;

/// A barycentric weight above this is "the previous vertex itself" (its surface coordinates are kept).
const AT_VERTEX: Real = 1.0 - 1e-12;

/// What [`design_remesh`] made besides the new problem.
#[derive(Clone, Debug)]
pub struct RemeshedDesign {
    /// The remeshed garment (its `vertex_body` locate the cloth vertices on the previous cloth).
    pub garment: Garment,
    /// `#Vc` pinned flags of the new cloth vertices.
    pub pinned: Vec<bool>,
    /// The new pattern (`#Vp`, m, the design numbering of [`DesignMesh::from_garment`]).
    pub pattern: Vec<Vec2>,
    /// The boundary parametrization of the new mesh, its initial parameters at `pattern`.
    pub map: PatternMap,
}

/// Remeshes the design of `problem` (whose cloth is `garment`'s, in order, with state the equilibrium of
/// `pattern`, `#Vp` m) at pattern edge length `target_edge_length` (m) and replaces the problem's cloth
/// with the new one at the re-embedded state (see the module documentation). On error the problem is
/// left as it was.
///
/// Errors: a `pattern` of the wrong size, a boundary that crosses itself (the triangulation cannot follow
/// it), or a new cloth the system rejects.
pub fn design_remesh(
    problem: &mut DesignProblem,
    garment: &Garment,
    pattern: &[Vec2],
    target_edge_length: Real,
) -> Result<RemeshedDesign, DesignError> {
    let mesh = problem.mesh();
    if pattern.len() != mesh.num_pattern_vertices() {
        return Err(DesignError::Pattern(format!(
            "{} pattern positions for {} pattern vertices",
            pattern.len(),
            mesh.num_pattern_vertices()
        )));
    }
    if garment.num_faces() != mesh.num_triangles() || garment.faces != mesh.cloth_triangles {
        return Err(DesignError::Pattern(
            "the garment's cloth triangles are not the design's".into(),
        ));
    }
    let system = problem.system();
    let state = problem.state();
    let positions = system
        .cloth_positions(state)
        .map_err(|e| DesignError::Solve(e.to_string()))?;
    let patterns: Vec<Vec<Vec2>> = mesh
        .panels
        .iter()
        .map(|p| pattern[p.first_vertex..p.first_vertex + p.num_vertices].to_vec())
        .collect();
    let new = garment_remesh(
        garment,
        &positions,
        &patterns,
        &RemeshParams {
            target_edge_length,
            ..RemeshParams::default()
        },
    )
    .map_err(|e| DesignError::Pattern(format!("remeshing: {e}")))?;

    // Re-embedding.
    let control = system.control_positions(&state.body);
    let surface = system.surface();
    let projection = ClosestPointParams::default();
    let old_pinned: Vec<bool> = (0..system.num_cloth_vertices())
        .map(|c| system.cloth_dof(c).is_none())
        .collect();
    let mut coords: Vec<SurfaceCoord> = Vec::with_capacity(new.num_vertices());
    let mut pinned = Vec::with_capacity(new.num_vertices());
    for (c, sp) in new.vertex_body.iter().enumerate() {
        let corners = garment.faces[sp.face];
        let (k, &w) = sp
            .bary
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .expect("three weights");
        let nearest = state.cloth[corners[k]];
        let coord = if w >= AT_VERTEX {
            nearest
        } else {
            closest_point_from(&**surface, &control, new.positions[c], nearest, &projection)
                .map(|p| p.coord)
                .map_err(|e| {
                    DesignError::Solve(format!(
                        "re-embedding cloth vertex {c} on the body surface: {e}"
                    ))
                })?
        };
        coords.push(coord);
        let from_pinned = (0..3)
            .filter(|&i| sp.bary[i] > 1.0 - AT_VERTEX)
            .all(|i| old_pinned[corners[i]]);
        pinned.push(new.free_boundary[c] && from_pinned);
    }
    let rest: Vec<[Vec2; 3]> = (0..new.num_faces()).map(|f| new.rest_triangle(f)).collect();
    // Each new triangle keeps its panel's grain (the course of the panel's first old triangle).
    let mut panel_course = vec![None; garment.panels.len()];
    for (f, &p) in garment.face_panel.iter().enumerate() {
        if panel_course[p].is_none() {
            let c = system.elements()[f].course();
            panel_course[p] = Some(c.y.atan2(c.x));
        }
    }
    let grain: Vec<Real> = new
        .face_panel
        .iter()
        .map(|&p| panel_course.get(p).copied().flatten().unwrap_or(0.0))
        .collect();
    let new_system = system
        .remeshed_with_grain(new.faces.clone(), rest, pinned.clone(), grain)
        .map_err(|e| DesignError::Pattern(format!("the remeshed cloth: {e}")))?;
    let new_state = ClothOnBodyState {
        cloth: coords,
        body: state.body.clone(),
    };
    let (new_mesh, new_pattern) = DesignMesh::from_garment(&new);
    let map = PatternMap::new(&new_mesh, &new_pattern)
        .map_err(|e| DesignError::Pattern(format!("the remeshed pattern: {e}")))?;
    problem.replace_cloth(new_system, new_state, new_mesh)?;
    Ok(RemeshedDesign {
        garment: new,
        pinned,
        pattern: new_pattern,
        map,
    })
}

/// The pattern edge length (m) a remesh aims at so that the worn triangles keep about the job's cloth
/// edge length `edge_length`: `edge_length · √(pattern area / worn area)` at the current equilibrium (the
/// pattern of a design that loosened the garment grows, and remeshing it at a fixed pattern length would
/// refine the cloth); `edge_length · (1 + ease)`-like at the start.
pub fn remesh_edge_length(problem: &DesignProblem, edge_length: Real) -> Real {
    let system = problem.system();
    let rest: Real = system.elements().iter().map(|e| e.rest_area()).sum();
    let worn: Real = system
        .cloth_positions(problem.state())
        .map(|x| {
            system
                .triangles()
                .iter()
                .map(|t| 0.5 * (x[t[1]] - x[t[0]]).cross(&(x[t[2]] - x[t[0]])).norm())
                .sum()
        })
        .unwrap_or(0.0);
    if rest > 0.0 && worn > 0.0 {
        edge_length * (rest / worn).sqrt()
    } else {
        edge_length
    }
}
