//! The garment worn on the body: the total energy `U(q) = U_body(y) + Σ_e U_e(x(s, y))` over the coupled
//! unknowns `q = {s, y}` (thesis Eq. 139–140 and 144), with its gradient and Hessian by the chain rule through
//! the surface derivative (Eq. 155–157).
//!
//! Every cloth vertex `i` lies on the body's smooth surface at coordinates `s_i` of a surface face:
//! `x_i = Σ_j w_j(s_i) y_{c(j)}`, linear in the body positions `y` of the face's control stencil
//! ([`skintight_geometry::LimitSurface`]; `c` maps control vertices to body vertices). For one cloth triangle
//! with corners `i, k` and element derivatives `g_i = ∂U_e/∂x_i` (N), `H_ik = ∂²U_e/∂x_i∂x_k` (N/m), with
//! `T_i = ∂x_i/∂s_i` (3 × 2, m), `x_{i,ab} = ∂²x_i/∂s_a∂s_b` (m) and stencil weights `w_ui = w_u(s_i)`:
//!
//! ```text
//! ∂U/∂s_i        = T_iᵀ g_i                                            (Eq. 155, N·m)
//! ∂U/∂y_u        = Σ_i w_ui g_i                                        (Eq. 155, N)
//! ∂²U/∂s_i∂s_k   = T_iᵀ H_ik T_k + δ_ik [g_i · x_{i,ab}]_ab             (Eq. 156, second term = Σ ∂²x/∂q² ∂U/∂x)
//! ∂²U/∂s_ia∂y_u  = Σ_k T_i[:,a]ᵀ H_ik w_uk + ∂w_ui/∂s_a g_iᵀ
//! ∂²U/∂y_u∂y_v   = Σ_ik w_ui H_ik w_vk
//! ```
//!
//! **Unknowns.** `q` holds `(s1, s2)` of every cloth vertex that is not pinned (dimensionless, in the
//! coordinates of its current face), then `(x, y, z)` (m) of every free body vertex, each group in increasing
//! vertex order. Pinned cloth vertices keep their surface coordinates (they still move with the body);
//! fixed body vertices keep their positions. Because `s` is only meaningful together with its face, states
//! are [`ClothOnBodyState`]s and a Newton step is applied with [`ClothOnBody::step`], which walks `s` across
//! faces (Eq. 147–154).
//!
//! Units: energy J, `∂U/∂y` N, `∂U/∂s` J (N·m per unit surface coordinate), Hessian blocks N/m, N and N·m.
//!
//! **Layout.** This module holds the system, its specs and construction; the methods live by concern in
//! `unknowns` (numbering of `q`, DOFs ↔ state, the walk step), `energy` (`U` and `∂U/∂q`), `structure`
//! (the Hessian's node lists and reserve), `hessian` (Hessian assembly), `sensitivities` (the cloth
//! Jacobian and pattern derivatives the design uses) and `reports` (element states, pressures, forces and
//! residual norms).

mod chart_change;
mod energy;
mod hessian;
pub(crate) mod hessian_form;
mod reports;
mod sensitivities;
mod structure;
mod unknowns;

pub use chart_change::{ChartChange, CoordinateCharts};
pub use hessian::Evaluation;
pub use hessian_form::HessianForm;

use std::sync::Arc;

use crate::math::FaceId;
use crate::math::{Mat3, Real, Vec2, Vec3};
use crate::membrane_element::{MembraneElement, MembraneError};
use crate::membrane_law::MembraneLaw;
use crate::neo_hookean::{NeoHookeanBody, NeoHookeanError, NeoHookeanParams};
use crate::node_block_assembly::Node;
use crate::orthotropic_density::OrthotropicDensity;
use crate::tension_field_density::{MaterialError, TensionFieldDensity, TensionFieldParams};
use skintight_geometry::{LimitSurface, Stencil, SurfaceCoord, SurfaceError, SurfacePoint};
use structure::face_reach;
use unknowns::Unknowns;

/// A surface the garment can lie on, shareable across threads.
pub type SharedSurface = Arc<dyn LimitSurface + Send + Sync>;

/// Why a coupled system could not be built or evaluated. Messages name the element or vertex.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ClothOnBodyError {
    /// The body energy could not be built.
    #[error("body: {0}")]
    Body(#[from] NeoHookeanError),
    /// The fabric material is invalid.
    #[error("fabric: {0}")]
    Fabric(#[from] MaterialError),
    /// A cloth triangle's pattern is invalid.
    #[error("cloth triangle {triangle}: {source}")]
    Pattern {
        /// The cloth triangle.
        triangle: usize,
        /// What is wrong with its pattern.
        source: MembraneError,
    },
    /// A list has the wrong length or an index is out of range.
    #[error("{0}")]
    Shape(String),
    /// The surface rejected a query.
    #[error("body surface: {0}")]
    Surface(#[from] SurfaceError),
    /// A body element is inverted at this state, so the gradient and Hessian do not exist.
    #[error("body tetrahedron {tet} is inverted at this state (det F = {det:e})")]
    InvertedBody {
        /// The tetrahedron.
        tet: usize,
        /// `det F`.
        det: Real,
    },
    /// A cloth triangle cannot be evaluated at this state (collapsed or non-finite).
    #[error("cloth triangle {triangle} cannot be evaluated at this state: {source}")]
    Cloth {
        /// The cloth triangle.
        triangle: usize,
        /// Why.
        source: MembraneError,
    },
}

/// The cloth's material and triangles.
#[derive(Clone, Debug)]
pub struct ClothSpec {
    /// `#Fc × 3` cloth triangles (cloth vertex ids), counter-clockwise seen from outside the body.
    pub triangles: Vec<[usize; 3]>,
    /// `#Fc` pattern (rest) corners of each triangle (m), counter-clockwise in the pattern plane.
    pub rest: Vec<[Vec2; 3]>,
    /// Fabric Young's modulus (Pa). With an orthotropic law it is the isotropic equivalent that scales
    /// the solver's force floor and that the design's terms read.
    pub youngs_modulus: Real,
    /// Fabric Poisson's ratio (dimensionless, in `[0, 1)`).
    pub poisson_ratio: Real,
    /// The orthotropic curve law of the membrane; `None` for the isotropic tension-field StVK membrane
    /// of `youngs_modulus` and `poisson_ratio`.
    pub orthotropic: Option<OrthotropicDensity>,
    /// `#Fc` course direction of each triangle (rad, counter-clockwise from the pattern's x), or empty
    /// for the pattern's x everywhere. Read only by an orthotropic law.
    pub grain: Vec<Real>,
    /// Fabric thickness (m).
    pub thickness: Real,
    /// Smoothing of the tension-field regimes.
    pub tension_field: TensionFieldParams,
    /// `#Vc` pinned flags: a pinned cloth vertex keeps its surface coordinates.
    pub pinned: Vec<bool>,
}

/// The body: a tetrahedral mesh, its material, and how its boundary carries the garment's surface.
#[derive(Clone)]
pub struct BodySpec {
    /// `#Vb` rest positions (m).
    pub rest_positions: Vec<Vec3>,
    /// `#T × 4` positively oriented tetrahedra.
    pub tets: Vec<[usize; 4]>,
    /// `#Vb` fixed flags.
    pub fixed: Vec<bool>,
    /// Neo-Hookean material.
    pub material: NeoHookeanParams,
    /// The smooth surface over the body's boundary.
    pub surface: SharedSurface,
    /// `#Vs` (the surface's control vertex count): body vertex of each control vertex.
    pub surface_body_vertex: Vec<usize>,
}

/// A state of the coupled system. Serializable (bit for bit in a binary format) so that checkpoints can
/// store it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClothOnBodyState {
    /// `#Vc` surface location of each cloth vertex.
    pub cloth: Vec<SurfaceCoord>,
    /// `#Vb` body vertex positions (m), fixed ones included.
    pub body: Vec<Vec3>,
}

/// The body surface evaluated at every cloth vertex of one state (points, tangents, stencils): computed once
/// per state with [`ClothOnBody::frames_at`] and shared by [`ClothOnBody::structure`] and
/// [`ClothOnBody::hessian_at`].
pub struct SurfaceFrames(Frames);

/// Surface points and stencils of all cloth vertices at one state.
struct Frames {
    points: Vec<SurfacePoint>,
    /// The face of each cloth vertex (the chart its `s` are coordinates in).
    faces: Vec<FaceId>,
    /// Stencil of cloth vertex `i`: `entries[offsets[i]..offsets[i + 1]]`, each `(body vertex, w, ∂w/∂s)`.
    offsets: Vec<usize>,
    entries: Vec<(usize, Real, [Real; 2])>,
}

/// Reused per-element scratch space of the Hessian.
#[derive(Default)]
struct ElementScratch {
    /// Union of the free body vertices in the three corners' stencils (sorted).
    union: Vec<usize>,
    /// Per union vertex: weights `w_u(s_i)` and derivatives for the three corners.
    w: Vec<[Real; 3]>,
    dw: Vec<[[Real; 2]; 3]>,
    nodes: Vec<Node>,
    block: Vec<Real>,
    /// Per union vertex, `Σ_k H_ik w_uk` for each corner `i` (three 3 × 3 blocks).
    hw: Vec<[Mat3; 3]>,
}

/// The coupled cloth-on-body system; see the module documentation.
#[derive(Clone)]
pub struct ClothOnBody {
    body: NeoHookeanBody,
    tets: Vec<[usize; 4]>,
    rest_positions: Vec<Vec3>,
    surface: SharedSurface,
    surface_body_vertex: Vec<usize>,
    triangles: Vec<[usize; 3]>,
    elements: Vec<MembraneElement>,
    density: TensionFieldDensity,
    /// The membrane law the elements evaluate (the isotropic `density`, or an orthotropic law).
    law: MembraneLaw,
    fabric_youngs_modulus: Real,
    /// First DOF of each cloth vertex's `(s1, s2)`, `None` if pinned.
    cloth_dof: Vec<Option<usize>>,
    /// First DOF of each body vertex, `None` if fixed.
    body_dof: Vec<Option<usize>>,
    nodes: Vec<Node>,
    num_dofs: usize,
    /// Per surface face `f`: the free body vertices (sorted) that the stencils of `f` and of its three
    /// edge-neighbours involve — where a cloth vertex in `f` couples after sliding across an edge. (The
    /// faces around the corners too would leave the pattern unchanged in all but a couple of iterations,
    /// but their extra fill slows every factorization more than the analyses it saves: measured in
    /// docs/BENCHMARKS.md.)
    /// `reach_entries[reach_offsets[f]..reach_offsets[f + 1]]`.
    reach_offsets: Vec<usize>,
    reach_entries: Vec<usize>,
    /// Per body tetrahedron: the index of its Hessian block in a pass (`None` when all its corners are
    /// fixed and it emits none).
    tet_block: Vec<Option<usize>>,
}

/// The membrane elements of a cloth after checking its lists: one rest triangle per triangle, vertex
/// ids below `num_vertices`.
fn cloth_elements(
    triangles: &[[usize; 3]],
    rest: &[[Vec2; 3]],
    num_vertices: usize,
    thickness: Real,
    grain: &[Real],
) -> Result<Vec<MembraneElement>, ClothOnBodyError> {
    if !grain.is_empty() && grain.len() != triangles.len() {
        return Err(ClothOnBodyError::Shape(format!(
            "{} cloth triangles but {} grain angles",
            triangles.len(),
            grain.len()
        )));
    }
    if let Some(t) = grain.iter().position(|a| !a.is_finite()) {
        return Err(ClothOnBodyError::Shape(format!(
            "the grain angle of cloth triangle {t} is not finite"
        )));
    }
    if rest.len() != triangles.len() {
        return Err(ClothOnBodyError::Shape(format!(
            "{} cloth triangles but {} pattern triangles",
            triangles.len(),
            rest.len()
        )));
    }
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&v) = tri.iter().find(|&&v| v >= num_vertices) {
            return Err(ClothOnBodyError::Shape(format!(
                "cloth triangle {t} names vertex {v}, but the cloth has {num_vertices} vertices"
            )));
        }
    }
    rest.iter()
        .enumerate()
        .map(|(triangle, rest)| {
            MembraneElement::new(*rest, thickness)
                .map(|e| e.with_grain(grain.get(triangle).copied().unwrap_or(0.0)))
                .map_err(|source| ClothOnBodyError::Pattern { triangle, source })
        })
        .collect()
}

impl ClothOnBody {
    /// Builds the coupled system. Errors name the triangle or list that is wrong.
    pub fn new(body: BodySpec, cloth: ClothSpec) -> Result<Self, ClothOnBodyError> {
        let nb = body.rest_positions.len();
        let mut neo = NeoHookeanBody::new(
            &body.rest_positions,
            &body.tets,
            &body.fixed,
            &body.material,
        )?;
        neo.set_project_psd(false);
        if body.surface_body_vertex.len() != body.surface.num_control_vertices() {
            return Err(ClothOnBodyError::Shape(format!(
                "the surface has {} control vertices but {} body vertices were given for them",
                body.surface.num_control_vertices(),
                body.surface_body_vertex.len()
            )));
        }
        if let Some(&v) = body.surface_body_vertex.iter().find(|&&v| v >= nb) {
            return Err(ClothOnBodyError::Shape(format!(
                "surface control vertex maps to body vertex {v}, but the body has {nb} vertices"
            )));
        }
        let density = TensionFieldDensity::new(
            cloth.youngs_modulus,
            cloth.poisson_ratio,
            &cloth.tension_field,
        )?;
        let elements = cloth_elements(
            &cloth.triangles,
            &cloth.rest,
            cloth.pinned.len(),
            cloth.thickness,
            &cloth.grain,
        )?;
        let law = match cloth.orthotropic {
            Some(o) if o.thickness() != cloth.thickness => {
                return Err(ClothOnBodyError::Shape(format!(
                    "the orthotropic law is for a fabric {} m thick but the cloth is {} m thick",
                    o.thickness(),
                    cloth.thickness
                )));
            }
            Some(o) => MembraneLaw::Orthotropic(o),
            None => MembraneLaw::Isotropic(density),
        };
        let u = Unknowns::new(&cloth.pinned, &body.fixed);
        let (reach_offsets, reach_entries) =
            face_reach(&*body.surface, &body.surface_body_vertex, &u.body_dof)?;
        let mut blocks = 0;
        let tet_block = body
            .tets
            .iter()
            .map(|tet| {
                tet.iter().any(|&v| u.body_dof[v].is_some()).then(|| {
                    blocks += 1;
                    blocks - 1
                })
            })
            .collect();
        Ok(Self {
            body: neo,
            tets: body.tets,
            rest_positions: body.rest_positions,
            surface: body.surface,
            surface_body_vertex: body.surface_body_vertex,
            triangles: cloth.triangles,
            elements,
            density,
            law,
            fabric_youngs_modulus: cloth.youngs_modulus,
            cloth_dof: u.cloth_dof,
            body_dof: u.body_dof,
            nodes: u.nodes,
            num_dofs: u.num_dofs,
            reach_offsets,
            reach_entries,
            tet_block,
        })
    }

    /// The same body, surface and fabric with another cloth (a remeshed garment): `#Fc' × 3` triangles
    /// (cloth vertex ids, counter-clockwise seen from outside the body), their pattern corners (m,
    /// counter-clockwise) and `#Vc'` pinned flags. Errors as [`Self::new`]'s for the cloth.
    pub fn remeshed(
        &self,
        triangles: Vec<[usize; 3]>,
        rest: Vec<[Vec2; 3]>,
        pinned: Vec<bool>,
    ) -> Result<Self, ClothOnBodyError> {
        let thickness = self.elements.first().map_or(0.0, |e| e.thickness());
        // One grain for the remeshed cloth: the first triangle's.
        let course = self.elements.first().map_or(0.0, |e| {
            let c = e.course();
            c.y.atan2(c.x)
        });
        let grain = vec![course; triangles.len()];
        let elements = cloth_elements(&triangles, &rest, pinned.len(), thickness, &grain)?;
        // The body and its free vertices are unchanged, and so is each face's reach (body vertex ids);
        // only the numbering moves with the number of free cloth vertices.
        let fixed: Vec<bool> = self.body_dof.iter().map(|d| d.is_none()).collect();
        let u = Unknowns::new(&pinned, &fixed);
        Ok(Self {
            body: self.body.clone(),
            tets: self.tets.clone(),
            rest_positions: self.rest_positions.clone(),
            surface: self.surface.clone(),
            surface_body_vertex: self.surface_body_vertex.clone(),
            triangles,
            elements,
            density: self.density,
            law: self.law.clone(),
            fabric_youngs_modulus: self.fabric_youngs_modulus,
            cloth_dof: u.cloth_dof,
            body_dof: u.body_dof,
            nodes: u.nodes,
            num_dofs: u.num_dofs,
            reach_offsets: self.reach_offsets.clone(),
            reach_entries: self.reach_entries.clone(),
            tet_block: self.tet_block.clone(),
        })
    }

    /// Number of unknowns `#q`.
    pub fn num_dofs(&self) -> usize {
        self.num_dofs
    }

    /// All DOF nodes (one per free cloth vertex, dimension 2, then one per free body vertex, dimension 3).
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// Number of cloth vertices `#Vc`.
    pub fn num_cloth_vertices(&self) -> usize {
        self.cloth_dof.len()
    }

    /// Number of body vertices `#Vb`.
    pub fn num_body_vertices(&self) -> usize {
        self.body_dof.len()
    }

    /// The cloth triangles (`#Fc × 3`).
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// The cloth elements (pattern shape and thickness).
    pub fn elements(&self) -> &[MembraneElement] {
        &self.elements
    }

    /// The fabric's isotropic energy density (for an orthotropic fabric, the isotropic equivalent of
    /// [`ClothSpec::youngs_modulus`] the design's terms read).
    pub fn density(&self) -> &TensionFieldDensity {
        &self.density
    }

    /// The membrane law the cloth elements evaluate.
    pub fn law(&self) -> &MembraneLaw {
        &self.law
    }

    /// Fabric Young's modulus (Pa).
    pub fn fabric_youngs_modulus(&self) -> Real {
        self.fabric_youngs_modulus
    }

    /// The body surface.
    pub fn surface(&self) -> &SharedSurface {
        &self.surface
    }

    /// Body rest positions (`#Vb`, m).
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest_positions
    }

    /// Body tetrahedra.
    pub fn tets(&self) -> &[[usize; 4]] {
        &self.tets
    }

    /// First DOF of cloth vertex `i`'s `(s1, s2)`, `None` if pinned.
    pub fn cloth_dof(&self, i: usize) -> Option<usize> {
        self.cloth_dof[i]
    }

    /// First DOF of body vertex `v`, `None` if fixed.
    pub fn body_dof(&self, v: usize) -> Option<usize> {
        self.body_dof[v]
    }

    /// The state with the body at rest and the cloth at `cloth` (`#Vc` surface locations).
    pub fn rest_state(
        &self,
        cloth: Vec<SurfaceCoord>,
    ) -> Result<ClothOnBodyState, ClothOnBodyError> {
        let state = ClothOnBodyState {
            cloth,
            body: self.rest_positions.clone(),
        };
        self.check_state(&state)?;
        Ok(state)
    }

    fn check_state(&self, state: &ClothOnBodyState) -> Result<(), ClothOnBodyError> {
        if state.cloth.len() != self.cloth_dof.len() || state.body.len() != self.body_dof.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "state has {} cloth and {} body vertices, the system {} and {}",
                state.cloth.len(),
                state.body.len(),
                self.cloth_dof.len(),
                self.body_dof.len()
            )));
        }
        Ok(())
    }

    /// Control positions of the surface (`#Vs × 3`, m) at body positions `body`.
    pub fn control_positions(&self, body: &[Vec3]) -> Vec<Vec3> {
        self.surface_body_vertex.iter().map(|&v| body[v]).collect()
    }

    fn frames(&self, state: &ClothOnBodyState) -> Result<Frames, ClothOnBodyError> {
        self.check_state(state)?;
        let control = self.control_positions(&state.body);
        let nc = state.cloth.len();
        let mut frames = Frames {
            points: Vec::with_capacity(nc),
            faces: state.cloth.iter().map(|c| c.face).collect(),
            offsets: Vec::with_capacity(nc + 1),
            entries: Vec::with_capacity(16 * nc),
        };
        let mut stencil = Stencil::with_capacity(64);
        frames.offsets.push(0);
        for c in &state.cloth {
            self.surface.stencil(c.face, c.s, &mut stencil)?;
            frames.points.push(stencil.apply(&control));
            for e in &stencil.entries {
                frames
                    .entries
                    .push((self.surface_body_vertex[e.vertex], e.w, e.dw));
            }
            frames.offsets.push(frames.entries.len());
        }
        Ok(frames)
    }

    /// The surface at every cloth vertex of `state`, for [`Self::structure`] and [`Self::hessian_at`].
    pub fn frames_at(&self, state: &ClothOnBodyState) -> Result<SurfaceFrames, ClothOnBodyError> {
        Ok(SurfaceFrames(self.frames(state)?))
    }

    /// Cloth vertex positions `x(s, y)` (`#Vc × 3`, m).
    pub fn cloth_positions(&self, state: &ClothOnBodyState) -> Result<Vec<Vec3>, ClothOnBodyError> {
        Ok(self
            .frames(state)?
            .points
            .iter()
            .map(|p| p.position)
            .collect())
    }

    /// Surface points (position, tangents, second derivatives) of all cloth vertices.
    pub fn cloth_surface_points(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<SurfacePoint>, ClothOnBodyError> {
        Ok(self.frames(state)?.points)
    }

    /// Replaces the pattern (rest) corners of every cloth triangle (`#Fc`, m, counter-clockwise): the
    /// design changes them between solves. The unknowns and the Hessian's structure stay the same. On an
    /// error (a triangle without positive area) nothing changes.
    pub fn set_rest(&mut self, rest: &[[Vec2; 3]]) -> Result<(), ClothOnBodyError> {
        if rest.len() != self.triangles.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "{} pattern triangles for {} cloth triangles",
                rest.len(),
                self.triangles.len()
            )));
        }
        let thickness = self.elements.first().map_or(0.0, |e| e.thickness());
        let elements = rest
            .iter()
            .enumerate()
            .map(|(triangle, r)| {
                MembraneElement::new(*r, thickness)
                    .map(|e| e.with_course(self.elements[triangle].course()))
                    .map_err(|source| ClothOnBodyError::Pattern { triangle, source })
            })
            .collect::<Result<Vec<_>, _>>()?;
        self.elements = elements;
        Ok(())
    }

    /// Checks that `q` (named `what` in the error) has one entry per unknown.
    fn check_dofs(&self, q: &[Real], what: &str) -> Result<(), ClothOnBodyError> {
        if q.len() != self.num_dofs {
            return Err(ClothOnBodyError::Shape(format!(
                "{what} has {} entries, the system {} unknowns",
                q.len(),
                self.num_dofs
            )));
        }
        Ok(())
    }

    fn corners(&self, t: usize, points: &[SurfacePoint]) -> [Vec3; 3] {
        self.triangles[t].map(|i| points[i].position)
    }
}

#[cfg(test)]
pub(crate) mod tests;
