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

use std::sync::Arc;

use faer::sparse::{SparseColMat, Triplet};

use crate::math::{Mat3, Mat3x2, Real, Vec2, Vec3};
use crate::membrane_element::{Matrix9, MembraneElement, MembraneError, MembraneState, Vector9};
use crate::neo_hookean::{NeoHookeanBody, NeoHookeanError, NeoHookeanParams};
use crate::node_block_assembly::{
    AssemblyPart, Node, NodeBlockAssembler, NodeBlockRecorder, NodeHessianSink,
};
use crate::tension_field_density::{MaterialError, TensionFieldDensity, TensionFieldParams};
use skintight_geometry::surface::walk::{WalkError, WalkParams, surface_walk};
use skintight_geometry::{LimitSurface, Stencil, SurfaceCoord, SurfaceError, SurfacePoint};

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
    /// Fabric Young's modulus (Pa).
    pub youngs_modulus: Real,
    /// Fabric Poisson's ratio (dimensionless, in `[0, 1)`).
    pub poisson_ratio: Real,
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

/// A state of the coupled system.
#[derive(Clone, Debug, PartialEq)]
pub struct ClothOnBodyState {
    /// `#Vc` surface location of each cloth vertex.
    pub cloth: Vec<SurfaceCoord>,
    /// `#Vb` body vertex positions (m), fixed ones included.
    pub body: Vec<Vec3>,
}

/// What [`ClothOnBody::hessian`] evaluates besides the Hessian.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// `U` (J).
    pub energy: Real,
    /// Unbalanced force norm (N), as [`ClothOnBody::force_residual`].
    pub force_residual: Real,
    /// `‖∂U_cloth/∂x‖₂` (N), as [`ClothOnBody::cloth_force_norm`].
    pub cloth_force_norm: Real,
    /// The damping metric `D` (`#q`), as [`ClothOnBody::damping_metric`].
    pub damping_metric: Vec<Real>,
}

/// The body surface evaluated at every cloth vertex of one state (points, tangents, stencils): computed once
/// per state with [`ClothOnBody::frames_at`] and shared by [`ClothOnBody::structure`] and
/// [`ClothOnBody::hessian_at`].
pub struct SurfaceFrames(Frames);

/// Surface points and stencils of all cloth vertices at one state.
struct Frames {
    points: Vec<SurfacePoint>,
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

/// Per surface face, the free body vertices of the stencils of the face and of its edge-neighbours
/// (sorted), as offsets and entries.
fn face_reach(
    surface: &(dyn LimitSurface + Send + Sync),
    surface_body_vertex: &[usize],
    body_dof: &[Option<usize>],
) -> Result<(Vec<usize>, Vec<usize>), ClothOnBodyError> {
    let nf = surface.num_faces();
    let mut support = Vec::with_capacity(nf);
    let mut stencil = Stencil::with_capacity(64);
    for f in 0..nf {
        surface.stencil(f, Vec2::new(1.0 / 3.0, 1.0 / 3.0), &mut stencil)?;
        let mut vs: Vec<usize> = stencil
            .entries
            .iter()
            .map(|e| surface_body_vertex[e.vertex])
            .filter(|&v| body_dof[v].is_some())
            .collect();
        vs.sort_unstable();
        vs.dedup();
        support.push(vs);
    }
    let topology = surface.topology();
    let mut offsets = Vec::with_capacity(nf + 1);
    let mut entries = Vec::new();
    offsets.push(0);
    let mut reach = Vec::new();
    for f in 0..nf {
        reach.clear();
        reach.extend_from_slice(&support[f]);
        for e in 0..3 {
            if let Some(twin) = topology.twin(f, e) {
                reach.extend_from_slice(&support[twin.face]);
            }
        }
        reach.sort_unstable();
        reach.dedup();
        entries.extend_from_slice(&reach);
        offsets.push(entries.len());
    }
    Ok((offsets, entries))
}

/// Numbers the vertices whose flag is `false` with `dim` consecutive DOFs each, after those already in
/// `nodes` (one node each, appended); `None` for flagged (pinned or fixed) vertices.
fn number_free(flags: &[bool], dim: usize, nodes: &mut Vec<Node>) -> Vec<Option<usize>> {
    let mut next = nodes.last().map_or(0, |n| n.first_dof + n.dim);
    flags
        .iter()
        .map(|&flagged| {
            (!flagged).then(|| {
                nodes.push(Node {
                    first_dof: next,
                    dim,
                });
                next += dim;
                next - dim
            })
        })
        .collect()
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
) -> Result<Vec<MembraneElement>, ClothOnBodyError> {
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
                .map_err(|source| ClothOnBodyError::Pattern { triangle, source })
        })
        .collect()
}

/// The numbering of the unknowns: the free cloth vertices' `(s1, s2)` first, then the free body vertices'
/// positions (see the fields of [`ClothOnBody`] of the same names).
struct Unknowns {
    cloth_dof: Vec<Option<usize>>,
    body_dof: Vec<Option<usize>>,
    nodes: Vec<Node>,
    num_dofs: usize,
}

impl Unknowns {
    fn new(pinned: &[bool], fixed: &[bool]) -> Self {
        let mut nodes = Vec::new();
        let cloth_dof = number_free(pinned, 2, &mut nodes);
        let body_dof = number_free(fixed, 3, &mut nodes);
        let num_dofs = nodes.last().map_or(0, |n: &Node| n.first_dof + n.dim);
        Self {
            cloth_dof,
            body_dof,
            nodes,
            num_dofs,
        }
    }
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
        )?;
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
        let elements = cloth_elements(&triangles, &rest, pinned.len(), thickness)?;
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

    /// The fabric's energy density.
    pub fn density(&self) -> &TensionFieldDensity {
        &self.density
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
                    .map_err(|source| ClothOnBodyError::Pattern { triangle, source })
            })
            .collect::<Result<Vec<_>, _>>()?;
        self.elements = elements;
        Ok(())
    }

    /// `J δq`: the motion of the cloth vertices (`#Vc × 3`, m) under a change `dq` (`#q`) of the unknowns,
    /// with `J = ∂x/∂q` at `state` (`δx_c = ∂x/∂s δs_c + Σ_v w_v δy_v`).
    pub fn cloth_jacobian(
        &self,
        state: &ClothOnBodyState,
        dq: &[Real],
    ) -> Result<Vec<Vec3>, ClothOnBodyError> {
        self.check_dofs(dq, "the change of unknowns")?;
        let frames = self.frames(state)?;
        Ok((0..state.cloth.len())
            .map(|c| {
                let mut dx = Vec3::zeros();
                if let Some(d) = self.cloth_dof[c] {
                    dx += frames.points[c].tangents * Vec2::new(dq[d], dq[d + 1]);
                }
                for &(v, w, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                    if let Some(d) = self.body_dof[v] {
                        dx += Vec3::new(dq[d], dq[d + 1], dq[d + 2]) * w;
                    }
                }
                dx
            })
            .collect())
    }

    /// `Jᵀ g`: a derivative with respect to the cloth vertex positions (`#Vc × 3`, units per m) carried to
    /// the unknowns (`#q`), the transpose of [`Self::cloth_jacobian`].
    pub fn cloth_jacobian_transpose(
        &self,
        state: &ClothOnBodyState,
        g: &[Vec3],
    ) -> Result<Vec<Real>, ClothOnBodyError> {
        if g.len() != self.cloth_dof.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "{} cloth vertex derivatives for {} cloth vertices",
                g.len(),
                self.cloth_dof.len()
            )));
        }
        let frames = self.frames(state)?;
        let mut out = vec![0.0; self.num_dofs];
        for (c, gc) in g.iter().enumerate() {
            self.scatter_vertex_gradient(c, &frames, gc, &mut out);
        }
        Ok(out)
    }

    /// How the surface tangents under each cloth vertex move with the body: for cloth vertex `c`, the
    /// pairs `(d, ∂w_v/∂s)` of the free body vertices `v` of its stencil (`d` = the first of `y_v`'s three
    /// unknowns; `∂w_v/∂s`, dimensionless, one entry per surface coordinate), so that a change `δy` of the
    /// body positions changes the tangents `T_c = ∂x_c/∂s_c` (`3 × 2`, m) by `δT_c = Σ_v δy_v (∂w_v/∂s)ᵀ`
    /// — the surface is linear in its control positions. Entries of one body vertex met twice are summed.
    /// `#Vc` lists, the cloth vertices' stencils at `state`.
    pub fn tangent_body_derivatives(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<Vec<(usize, Vec2)>>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        Ok((0..state.cloth.len())
            .map(|c| {
                let mut out: Vec<(usize, Vec2)> = Vec::new();
                for &(v, _, dw) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                    if let Some(d) = self.body_dof[v] {
                        let dw = Vec2::new(dw[0], dw[1]);
                        match out.iter_mut().find(|(e, _)| *e == d) {
                            Some((_, sum)) => *sum += dw,
                            None => out.push((d, dw)),
                        }
                    }
                }
                out
            })
            .collect())
    }

    /// `(∂²U/∂x∂X̄)ᵀ δx` per cloth triangle (`#Fc`, three pattern corners each, N): how the energy's
    /// derivative along the cloth motion `dx` (`#Vc × 3`, m) changes with each triangle's pattern corners —
    /// the design term `λᵀ ∂²U/∂q∂X̄` of the adjoint (Eq. 164) with `dx = J λ`.
    pub fn rest_mixed_product(
        &self,
        state: &ClothOnBodyState,
        dx: &[Vec3],
    ) -> Result<Vec<[Vec2; 3]>, ClothOnBodyError> {
        if dx.len() != self.cloth_dof.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "{} cloth vertex motions for {} cloth vertices",
                dx.len(),
                self.cloth_dof.len()
            )));
        }
        self.per_triangle(state, |t, element, x| {
            let m = element.mixed_hessian(&self.density, x)?;
            let v = Vector9::from_iterator(
                self.triangles[t]
                    .iter()
                    .flat_map(|&c| [dx[c].x, dx[c].y, dx[c].z]),
            );
            let r = m.transpose() * v;
            Ok([0, 1, 2].map(|k| Vec2::new(r[2 * k], r[2 * k + 1])))
        })
    }

    /// The cloth Jacobian `J = ∂x/∂q` at `state` as an explicit sparse matrix, `3#Vc × #q`
    /// (dimensionless: m of cloth motion per m of unknown — surface coordinates are measured so that
    /// `∂x/∂s` are the surface tangents). Row `3c + i` is coordinate `i` of cloth vertex `c`; its entries are
    /// the tangents `∂x_c/∂s_c` (columns of the vertex's surface coordinates, absent for a pinned vertex)
    /// and the stencil weights `w_v` of the free body vertices `v` under it (columns of `y_v`, one per
    /// coordinate). The same matrix as the matrix-free [`Self::cloth_jacobian`] and
    /// [`Self::cloth_jacobian_transpose`]; entries of one stencil vertex met twice are summed.
    pub fn cloth_jacobian_matrix(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<SparseColMat<usize, Real>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        let mut triplets = Vec::new();
        for c in 0..state.cloth.len() {
            if let Some(d) = self.cloth_dof[c] {
                let t = frames.points[c].tangents;
                for a in 0..2 {
                    for i in 0..3 {
                        triplets.push(Triplet::new(3 * c + i, d + a, t[(i, a)]));
                    }
                }
            }
            for &(v, w, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                if let Some(d) = self.body_dof[v] {
                    for i in 0..3 {
                        triplets.push(Triplet::new(3 * c + i, d + i, w));
                    }
                }
            }
        }
        SparseColMat::try_new_from_triplets(3 * state.cloth.len(), self.num_dofs, &triplets)
            .map_err(|e| ClothOnBodyError::Shape(format!("the cloth Jacobian: {e:?}")))
    }

    /// The mixed second derivative `K = ∂²U/∂q∂X̄` at `state` as an explicit sparse matrix,
    /// `#q × 2#Vp` (N/m: change of the generalized force per metre of pattern motion), with
    /// `K = Jᵀ M P`: `M` the cloth elements' `∂²U_e/∂x∂X̄` blocks (9 × 6 each, see
    /// [`MembraneElement::mixed_hessian`]) and `P` the scatter of each triangle's pattern corners to the
    /// pattern vertices `pattern_triangles` (`#Fc`, ids below `num_pattern_vertices`; column `2v + i` is
    /// coordinate `i` of pattern vertex `v`). The body energy does not depend on the pattern. `Kᵀ λ`
    /// equals [`Self::rest_mixed_product`] of `J λ` scattered to the pattern vertices.
    pub fn rest_mixed_matrix(
        &self,
        state: &ClothOnBodyState,
        pattern_triangles: &[[usize; 3]],
        num_pattern_vertices: usize,
    ) -> Result<SparseColMat<usize, Real>, ClothOnBodyError> {
        if pattern_triangles.len() != self.triangles.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "{} pattern triangles for {} cloth triangles",
                pattern_triangles.len(),
                self.triangles.len()
            )));
        }
        if let Some(t) = pattern_triangles
            .iter()
            .position(|t| t.iter().any(|&v| v >= num_pattern_vertices))
        {
            return Err(ClothOnBodyError::Shape(format!(
                "pattern triangle {t} names a vertex beyond the {num_pattern_vertices} pattern vertices"
            )));
        }
        let frames = self.frames(state)?;
        let blocks = self.per_triangle(state, |_, element, x| {
            element.mixed_hessian(&self.density, x)
        })?;
        let mut triplets = Vec::new();
        for (t, m) in blocks.iter().enumerate() {
            for (a, &c) in self.triangles[t].iter().enumerate() {
                // Rows of corner a (3 × 6) carried to the unknowns by J_cᵀ.
                let rows = m.fixed_rows::<3>(3 * a);
                let mut push = |dof: usize, coefficient: &dyn Fn(usize) -> Real| {
                    for (b, &v) in pattern_triangles[t].iter().enumerate() {
                        for i in 0..2 {
                            let col = 2 * b + i;
                            let value = coefficient(col);
                            triplets.push(Triplet::new(dof, 2 * v + i, value));
                        }
                    }
                };
                if let Some(d) = self.cloth_dof[c] {
                    let tg = frames.points[c].tangents;
                    for s in 0..2 {
                        push(d + s, &|col| {
                            (0..3).map(|i| tg[(i, s)] * rows[(i, col)]).sum()
                        });
                    }
                }
                for &(v, w, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                    if let Some(d) = self.body_dof[v] {
                        for i in 0..3 {
                            push(d + i, &|col| w * rows[(i, col)]);
                        }
                    }
                }
            }
        }
        SparseColMat::try_new_from_triplets(self.num_dofs, 2 * num_pattern_vertices, &triplets)
            .map_err(|e| ClothOnBodyError::Shape(format!("the mixed derivative: {e:?}")))
    }

    /// `∂U/∂X̄` per cloth triangle (`#Fc`, three pattern corners each, N) at fixed `state`.
    pub fn rest_gradient(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<[Vec2; 3]>, ClothOnBodyError> {
        self.per_triangle(state, |_, element, x| {
            let g = element.rest_gradient(&self.density, x)?;
            Ok([0, 1, 2].map(|k| Vec2::new(g[2 * k], g[2 * k + 1])))
        })
    }

    /// `f(t, element, corners)` for every cloth triangle at `state`, the surface evaluated once; an element
    /// error names its triangle.
    fn per_triangle<T>(
        &self,
        state: &ClothOnBodyState,
        f: impl Fn(usize, &MembraneElement, &[Vec3; 3]) -> Result<T, MembraneError>,
    ) -> Result<Vec<T>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        self.elements
            .iter()
            .enumerate()
            .map(|(t, element)| {
                f(t, element, &self.corners(t, &frames.points)).map_err(|source| {
                    ClothOnBodyError::Cloth {
                        triangle: t,
                        source,
                    }
                })
            })
            .collect()
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

    /// `(U_body, U_cloth)` (J). Either is `+∞` where the state is outside the energy's domain (an inverted
    /// body element, a non-finite position), never NaN.
    pub fn energies(&self, state: &ClothOnBodyState) -> Result<(Real, Real), ClothOnBodyError> {
        let frames = self.frames(state)?;
        Ok(self.energies_with(state, &frames))
    }

    /// [`Self::energies`] with the surface already evaluated at `state` (`frames` from
    /// [`Self::frames_at`], which the assembly at the same state then reuses).
    pub fn energies_at(
        &self,
        state: &ClothOnBodyState,
        frames: &SurfaceFrames,
    ) -> Result<(Real, Real), ClothOnBodyError> {
        self.check_state(state)?;
        if frames.0.points.len() != state.cloth.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "surface frames of {} cloth vertices for a state of {}",
                frames.0.points.len(),
                state.cloth.len()
            )));
        }
        Ok(self.energies_with(state, &frames.0))
    }

    fn energies_with(&self, state: &ClothOnBodyState, frames: &Frames) -> (Real, Real) {
        let mut body = 0.0;
        let material = self.body.material();
        for (t, tet) in self.tets.iter().enumerate() {
            body += self.body.elements()[t].energy(material, &tet.map(|v| state.body[v]));
        }
        let mut cloth = 0.0;
        for (t, element) in self.elements.iter().enumerate() {
            match element.energy(&self.density, &self.corners(t, &frames.points)) {
                Ok(e) => cloth += e,
                Err(_) => cloth = Real::INFINITY,
            }
        }
        if body.is_nan() {
            body = Real::INFINITY;
        }
        if cloth.is_nan() {
            cloth = Real::INFINITY;
        }
        (body, cloth)
    }

    /// `U = U_body + U_cloth` (J); `+∞` outside the domain.
    pub fn energy(&self, state: &ClothOnBodyState) -> Result<Real, ClothOnBodyError> {
        let (b, c) = self.energies(state)?;
        Ok(b + c)
    }

    /// Writes `∂U/∂q` (length `#q`) into `out` and returns `U` (J).
    pub fn gradient(
        &self,
        state: &ClothOnBodyState,
        out: &mut [Real],
    ) -> Result<Real, ClothOnBodyError> {
        self.check_dofs(out, "gradient buffer")?;
        let frames = self.frames(state)?;
        out.fill(0.0);
        let mut energy = self.body_gradient(state, out)?;
        for t in 0..self.elements.len() {
            let x = self.corners(t, &frames.points);
            let (e, g) = self.elements[t]
                .energy_gradient(&self.density, &x)
                .map_err(|source| ClothOnBodyError::Cloth {
                    triangle: t,
                    source,
                })?;
            energy += e;
            self.scatter_cloth_gradient(t, &frames, &g, out);
        }
        Ok(energy)
    }

    fn body_gradient(
        &self,
        state: &ClothOnBodyState,
        out: &mut [Real],
    ) -> Result<Real, ClothOnBodyError> {
        let mut energy = 0.0;
        for t in 0..self.tets.len() {
            energy += self.tet_gradient(t, state, out)?;
        }
        Ok(energy)
    }

    fn scatter_cloth_gradient(&self, t: usize, frames: &Frames, g: &Vector9, out: &mut [Real]) {
        for (i, &c) in self.triangles[t].iter().enumerate() {
            let gi = Vec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2]);
            self.scatter_vertex_gradient(c, frames, &gi, out);
        }
    }

    /// Adds `(∂x_c/∂q)ᵀ g` — a derivative with respect to cloth vertex `c`'s position — into `out` (`#q`).
    fn scatter_vertex_gradient(&self, c: usize, frames: &Frames, g: &Vec3, out: &mut [Real]) {
        if let Some(d) = self.cloth_dof[c] {
            let tg = frames.points[c].tangents.transpose() * g;
            out[d] += tg.x;
            out[d + 1] += tg.y;
        }
        for &(v, w, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
            if let Some(d) = self.body_dof[v] {
                for k in 0..3 {
                    out[d + k] += w * g[k];
                }
            }
        }
    }

    /// Hands the Hessian `∂²U/∂q²` (`#q × #q`) to `sink` as node blocks: one per body tetrahedron (its free
    /// corners), then one per cloth triangle (its unpinned corners' `s`, then the free body vertices of its
    /// corners' stencils in increasing order). Writes `∂U/∂q` into `gradient` and returns `U` with the force
    /// residual, cloth force norm and damping metric, all from the one evaluation of the surface.
    ///
    /// The node lists depend on the faces the cloth vertices lie in (their stencils), not on the
    /// coordinates within a face.
    pub fn hessian(
        &self,
        state: &ClothOnBodyState,
        gradient: &mut [Real],
        sink: &mut dyn NodeHessianSink,
    ) -> Result<Evaluation, ClothOnBodyError> {
        self.check_dofs(gradient, "gradient buffer")?;
        let frames = self.frames(state)?;
        self.hessian_at(state, &SurfaceFrames(frames), gradient, sink)
    }

    /// The surface at every cloth vertex of `state`, for [`Self::structure`] and [`Self::hessian_at`].
    pub fn frames_at(&self, state: &ClothOnBodyState) -> Result<SurfaceFrames, ClothOnBodyError> {
        Ok(SurfaceFrames(self.frames(state)?))
    }

    /// [`Self::hessian`] with the surface already evaluated at `state` (`frames` from [`Self::frames_at`]).
    pub fn hessian_at(
        &self,
        state: &ClothOnBodyState,
        frames: &SurfaceFrames,
        gradient: &mut [Real],
        sink: &mut dyn NodeHessianSink,
    ) -> Result<Evaluation, ClothOnBodyError> {
        self.check_dofs(gradient, "gradient buffer")?;
        let frames = &frames.0;
        gradient.fill(0.0);
        let mut energy = self.body_gradient(state, gradient)?;
        self.body_hessian(state, sink)?;
        let mut scratch = ElementScratch::default();
        let mut cloth_forces = vec![Vec3::zeros(); state.cloth.len()];
        for t in 0..self.elements.len() {
            energy += self.cloth_element(t, frames, &mut scratch, gradient, &mut cloth_forces)?;
            sink.add_node_block(&scratch.nodes, &scratch.block);
        }
        Ok(self.evaluation(frames, energy, gradient, &cloth_forces))
    }

    /// [`Self::hessian_at`] into a [`NodeBlockAssembler`] (after its `begin`) on `threads` threads (at least
    /// one): the same blocks with the same indices, each thread scattering into its own copy of the values,
    /// merged at the end. Sums are taken in another order than the sequential pass, so results agree to
    /// rounding.
    pub fn hessian_parallel(
        &self,
        state: &ClothOnBodyState,
        frames: &SurfaceFrames,
        gradient: &mut [Real],
        assembler: &mut NodeBlockAssembler,
        threads: usize,
    ) -> Result<Evaluation, ClothOnBodyError> {
        self.check_dofs(gradient, "gradient buffer")?;
        self.check_state(state)?;
        let frames = &frames.0;
        let threads = threads.max(1);
        let (nt, ne) = (self.tets.len(), self.elements.len());
        let num_body_blocks = self.tet_block.iter().flatten().count();
        let split = |len: usize, k: usize| (len * k / threads, len * (k + 1) / threads);
        let shared: &NodeBlockAssembler = assembler;
        let run =
            |k: usize| -> Result<(Real, Vec<Real>, Vec<Vec3>, AssemblyPart), ClothOnBodyError> {
                let mut share = shared.share();
                let mut g = vec![0.0; self.num_dofs];
                let mut forces = vec![Vec3::zeros(); state.cloth.len()];
                let mut energy = 0.0;
                let mut nodes = Vec::with_capacity(4);
                let mut block = Vec::with_capacity(144);
                let (t0, t1) = split(nt, k);
                for t in t0..t1 {
                    energy += self.tet_gradient(t, state, &mut g)?;
                    if let Some(b) = self.tet_block[t] {
                        self.tet_hessian_block(t, state, &mut nodes, &mut block)?;
                        share.add(b, &nodes, &block);
                    }
                }
                let mut scratch = ElementScratch::default();
                let (e0, e1) = split(ne, k);
                for t in e0..e1 {
                    // The node-pair blocks go straight into the values when the triangle's node list is
                    // the recorded one (the usual case); the dense block otherwise.
                    let (e, d) = self.cloth_element_derivatives(t, frames, &mut g, &mut forces)?;
                    energy += e;
                    let (s_node, _) = self.cloth_block_weights(t, frames, &mut scratch);
                    let nodes = std::mem::take(&mut scratch.nodes);
                    let direct = share.add_direct(num_body_blocks + t, &nodes, |slots| {
                        self.cloth_pair_blocks(
                            t,
                            frames,
                            &d.gradient,
                            &d.hessian,
                            &mut scratch,
                            s_node,
                            |a, b, h| slots.add(a, b, h),
                        );
                    });
                    scratch.nodes = nodes;
                    if !direct {
                        self.cloth_block(t, frames, &d.gradient, &d.hessian, &mut scratch);
                        share.add(num_body_blocks + t, &scratch.nodes, &scratch.block);
                    }
                }
                Ok((energy, g, forces, share.into_part()))
            };
        let results: Vec<_> = if threads == 1 {
            vec![run(0)]
        } else {
            std::thread::scope(|scope| {
                let handles: Vec<_> = (1..threads).map(|k| scope.spawn(move || run(k))).collect();
                let mut results = vec![run(0)];
                results.extend(
                    handles
                        .into_iter()
                        .map(|h| h.join().expect("assembly thread panicked")),
                );
                results
            })
        };
        gradient.fill(0.0);
        let mut energy = 0.0;
        let mut cloth_forces = vec![Vec3::zeros(); state.cloth.len()];
        let mut parts = Vec::with_capacity(threads);
        for result in results {
            let (e, g, forces, part) = result?;
            energy += e;
            for (a, b) in gradient.iter_mut().zip(&g) {
                *a += b;
            }
            for (a, b) in cloth_forces.iter_mut().zip(&forces) {
                *a += b;
            }
            parts.push(part);
        }
        assembler.merge(parts);
        Ok(self.evaluation(frames, energy, gradient, &cloth_forces))
    }

    fn evaluation(
        &self,
        frames: &Frames,
        energy: Real,
        gradient: &[Real],
        cloth_forces: &[Vec3],
    ) -> Evaluation {
        Evaluation {
            energy,
            force_residual: self.force_residual_with(frames, gradient),
            cloth_force_norm: cloth_forces
                .iter()
                .map(|f| f.norm_squared())
                .sum::<Real>()
                .sqrt(),
            damping_metric: self.damping_metric_with(frames),
        }
    }

    /// Cloth triangle `t`: adds its `∂U/∂q` into `gradient` and its Cartesian corner forces into
    /// `cloth_forces`, leaves its Hessian block in `scratch` and returns its energy.
    fn cloth_element(
        &self,
        t: usize,
        frames: &Frames,
        scratch: &mut ElementScratch,
        gradient: &mut [Real],
        cloth_forces: &mut [Vec3],
    ) -> Result<Real, ClothOnBodyError> {
        let (energy, d) = self.cloth_element_derivatives(t, frames, gradient, cloth_forces)?;
        self.cloth_block(t, frames, &d.gradient, &d.hessian, scratch);
        Ok(energy)
    }

    /// Cloth triangle `t`: adds its `∂U/∂q` into `gradient` and its Cartesian corner forces into
    /// `cloth_forces`; returns its energy and its Cartesian derivatives.
    fn cloth_element_derivatives(
        &self,
        t: usize,
        frames: &Frames,
        gradient: &mut [Real],
        cloth_forces: &mut [Vec3],
    ) -> Result<(Real, crate::MembraneDerivatives), ClothOnBodyError> {
        let x = self.corners(t, &frames.points);
        let d = self.elements[t]
            .derivatives(&self.density, &x)
            .map_err(|source| ClothOnBodyError::Cloth {
                triangle: t,
                source,
            })?;
        self.scatter_cloth_gradient(t, frames, &d.gradient, gradient);
        for (i, &c) in self.triangles[t].iter().enumerate() {
            cloth_forces[c] += Vec3::new(
                d.gradient[3 * i],
                d.gradient[3 * i + 1],
                d.gradient[3 * i + 2],
            );
        }
        Ok((d.energy, d))
    }

    /// Body tetrahedron `t`: adds its gradient into `out`, returns its energy.
    fn tet_gradient(
        &self,
        t: usize,
        state: &ClothOnBodyState,
        out: &mut [Real],
    ) -> Result<Real, ClothOnBodyError> {
        let tet = &self.tets[t];
        let material = self.body.material();
        let x = tet.map(|v| state.body[v]);
        let element = &self.body.elements()[t];
        let g = element
            .gradient(material, &x)
            .map_err(|det| ClothOnBodyError::InvertedBody { tet: t, det })?;
        for (a, &v) in tet.iter().enumerate() {
            if let Some(d) = self.body_dof[v] {
                for k in 0..3 {
                    out[d + k] += g[3 * a + k];
                }
            }
        }
        Ok(element.energy(material, &x))
    }

    /// The Hessian block of body tetrahedron `t` over its free corners into `nodes` and `block` (empty
    /// `nodes` when all four are fixed).
    fn tet_hessian_block(
        &self,
        t: usize,
        state: &ClothOnBodyState,
        nodes: &mut Vec<Node>,
        block: &mut Vec<Real>,
    ) -> Result<(), ClothOnBodyError> {
        let tet = &self.tets[t];
        nodes.clear();
        let mut local = [0usize; 4];
        for (a, &v) in tet.iter().enumerate() {
            if let Some(d) = self.body_dof[v] {
                local[nodes.len()] = a;
                nodes.push(Node {
                    first_dof: d,
                    dim: 3,
                });
            }
        }
        if nodes.is_empty() {
            return Ok(());
        }
        let h = self.body.elements()[t]
            .hessian(self.body.material(), &tet.map(|v| state.body[v]), false)
            .map_err(|det| ClothOnBodyError::InvertedBody { tet: t, det })?;
        let m = 3 * nodes.len();
        block.clear();
        block.resize(m * m, 0.0);
        for (i, &a) in local[..nodes.len()].iter().enumerate() {
            for (j, &b) in local[..nodes.len()].iter().enumerate() {
                for r in 0..3 {
                    for c in 0..3 {
                        block[(3 * i + r) * m + 3 * j + c] = h[(3 * a + r, 3 * b + c)];
                    }
                }
            }
        }
        Ok(())
    }

    fn body_hessian(
        &self,
        state: &ClothOnBodyState,
        sink: &mut dyn NodeHessianSink,
    ) -> Result<(), ClothOnBodyError> {
        let mut nodes = Vec::with_capacity(4);
        let mut block = Vec::with_capacity(144);
        for t in 0..self.tets.len() {
            self.tet_hessian_block(t, state, &mut nodes, &mut block)?;
            if !nodes.is_empty() {
                sink.add_node_block(&nodes, &block);
            }
        }
        Ok(())
    }

    /// Node list of cloth triangle `t` into `scratch.nodes` (unpinned corners' `s`, then the free body
    /// vertices of the corners' stencils, sorted, in `scratch.union`). Returns each corner's local offset
    /// (`usize::MAX` if pinned) and the local offset of the first body node.
    fn element_nodes(
        &self,
        t: usize,
        frames: &Frames,
        scratch: &mut ElementScratch,
    ) -> ([usize; 3], usize) {
        let corners = self.triangles[t];
        scratch.union.clear();
        for &c in &corners {
            for &(v, _, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                if self.body_dof[v].is_some() {
                    scratch.union.push(v);
                }
            }
        }
        scratch.union.sort_unstable();
        scratch.union.dedup();
        scratch.nodes.clear();
        let mut s_corner = [usize::MAX; 3];
        let mut off = 0;
        for (i, &c) in corners.iter().enumerate() {
            if let Some(d) = self.cloth_dof[c] {
                scratch.nodes.push(Node {
                    first_dof: d,
                    dim: 2,
                });
                s_corner[i] = off;
                off += 2;
            }
        }
        for &v in &scratch.union {
            scratch.nodes.push(Node {
                first_dof: self.body_dof[v].expect("union holds free vertices"),
                dim: 3,
            });
        }
        (s_corner, off)
    }

    /// The node lists of every Hessian block at `frames` — the same blocks, in the same order, as
    /// [`Self::hessian_at`] emits — without computing any value (to fit the sparsity pattern first).
    pub fn structure(&self, frames: &SurfaceFrames, recorder: &mut NodeBlockRecorder) {
        let mut nodes = Vec::with_capacity(4);
        for tet in &self.tets {
            nodes.clear();
            nodes.extend(tet.iter().filter_map(|&v| self.body_dof[v]).map(|d| Node {
                first_dof: d,
                dim: 3,
            }));
            if !nodes.is_empty() {
                recorder.record(&nodes);
            }
        }
        let mut scratch = ElementScratch::default();
        for t in 0..self.elements.len() {
            self.element_nodes(t, &frames.0, &mut scratch);
            recorder.record(&scratch.nodes);
        }
    }

    /// Node lists whose pairs the Hessian's sparsity pattern should hold beyond [`Self::structure`]'s:
    /// per cloth triangle, its free corners' `s` and every free body vertex within reach of its corners'
    /// faces (the stencils of each face and of its edge-neighbours). A pattern that holds them survives
    /// cloth vertices sliding one face over, so the symbolic factorization is reused (see
    /// [`NodeBlockAssembler::with_reserve`](crate::NodeBlockAssembler::with_reserve)).
    pub fn reserve_structure(&self, state: &ClothOnBodyState, recorder: &mut NodeBlockRecorder) {
        let all: Vec<usize> = (0..self.triangles.len()).collect();
        self.reserve_structure_of(state, &all, 1, recorder);
    }

    /// [`Self::reserve_structure`] for the cloth triangles `triangles` only (indices past the end are
    /// skipped), reaching `steps` edge-neighbour faces from each corner's face: 1 as
    /// [`Self::reserve_structure`] (and so does 0), 2 one face further (for triangles that have already
    /// slid out of a pattern once, where sliding goes on).
    pub fn reserve_structure_of(
        &self,
        state: &ClothOnBodyState,
        triangles: &[usize],
        steps: usize,
        recorder: &mut NodeBlockRecorder,
    ) {
        let topology = self.surface.topology();
        let support =
            |f: usize| &self.reach_entries[self.reach_offsets[f]..self.reach_offsets[f + 1]];
        let mut faces = Vec::new();
        let mut next = Vec::new();
        let mut union = Vec::new();
        let mut nodes = Vec::new();
        for &t in triangles {
            let Some(corners) = self.triangles.get(t) else {
                continue;
            };
            // Faces within `steps − 1` edge steps; each one's reach adds one more step.
            faces.clear();
            faces.extend(corners.iter().map(|&c| state.cloth[c].face));
            for _ in 1..steps {
                next.clear();
                for &f in &faces {
                    next.extend((0..3).filter_map(|e| topology.twin(f, e)).map(|tw| tw.face));
                }
                faces.append(&mut next);
                faces.sort_unstable();
                faces.dedup();
            }
            union.clear();
            for &f in &faces {
                union.extend_from_slice(support(f));
            }
            union.sort_unstable();
            union.dedup();
            nodes.clear();
            nodes.extend(
                corners
                    .iter()
                    .filter_map(|&c| self.cloth_dof[c])
                    .map(|d| Node {
                        first_dof: d,
                        dim: 2,
                    }),
            );
            nodes.extend(union.iter().map(|&v| Node {
                first_dof: self.body_dof[v].expect("reach holds free vertices"),
                dim: 3,
            }));
            recorder.record(&nodes);
        }
    }

    /// The cloth triangle whose Hessian block is block `b` of [`Self::structure`] (`None` for a body
    /// tetrahedron's block or an index past the end).
    pub fn cloth_triangle_of_block(&self, b: usize) -> Option<usize> {
        let body_blocks = self.tet_block.iter().flatten().count();
        b.checked_sub(body_blocks)
            .filter(|&t| t < self.triangles.len())
    }

    /// Dense Hessian block of cloth triangle `t` over its nodes (Eq. 156–157) into `scratch.block`, the
    /// nodes into `scratch.nodes`.
    fn cloth_block(
        &self,
        t: usize,
        frames: &Frames,
        g: &Vector9,
        h: &Matrix9,
        scratch: &mut ElementScratch,
    ) {
        let (s_node, y_start) = self.cloth_block_weights(t, frames, scratch);
        let ns = scratch.nodes.len() - scratch.union.len();
        let m = y_start + 3 * scratch.union.len();
        // Every entry is written (all node pairs, both triangles), so the block is not zeroed first.
        let mut block = std::mem::take(&mut scratch.block);
        block.resize(m * m, 0.0);
        let offset = |a: usize| {
            if a < ns {
                2 * a
            } else {
                y_start + 3 * (a - ns)
            }
        };
        let dim = |a: usize| if a < ns { 2 } else { 3 };
        self.cloth_pair_blocks(t, frames, g, h, scratch, s_node, |a, b, hb| {
            let (oa, ob, da, db) = (offset(a), offset(b), dim(a), dim(b));
            for r in 0..da {
                for c in 0..db {
                    block[(oa + r) * m + ob + c] = hb[r * db + c];
                    block[(ob + c) * m + oa + r] = hb[r * db + c];
                }
            }
        });
        scratch.block = block;
    }

    /// Node list of cloth triangle `t` into `scratch.nodes` and the stencil weights of the free body
    /// vertices (`scratch.union`) at its corners into `scratch.w`, `scratch.dw`. Returns each corner's
    /// position in the node list (`usize::MAX` if pinned) and the local offset of the first body DOF.
    fn cloth_block_weights(
        &self,
        t: usize,
        frames: &Frames,
        scratch: &mut ElementScratch,
    ) -> ([usize; 3], usize) {
        let corners = self.triangles[t];
        let (s_corner, y_start) = self.element_nodes(t, frames, scratch);
        let nu = scratch.union.len();
        scratch.w.clear();
        scratch.w.resize(nu, [0.0; 3]);
        scratch.dw.clear();
        scratch.dw.resize(nu, [[0.0; 2]; 3]);
        for (i, &c) in corners.iter().enumerate() {
            for &(v, w, dw) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
                if let Ok(u) = scratch.union.binary_search(&v) {
                    scratch.w[u][i] += w;
                    scratch.dw[u][i][0] += dw[0];
                    scratch.dw[u][i][1] += dw[1];
                }
            }
        }
        // The s nodes come first, two DOFs each.
        (
            s_corner.map(|o| if o == usize::MAX { o } else { o / 2 }),
            y_start,
        )
    }

    /// The node-pair blocks of cloth triangle `t`'s Hessian (Eq. 156–157), each pair `(a, b)`, `a ≤ b`
    /// positions in `scratch.nodes`, once, to `emit(a, b, block)` (row-major, `dim_a × dim_b`); after
    /// [`Self::cloth_block_weights`] (`s_node` is what it returned).
    #[allow(clippy::too_many_arguments)]
    fn cloth_pair_blocks(
        &self,
        t: usize,
        frames: &Frames,
        g: &Vector9,
        h: &Matrix9,
        scratch: &mut ElementScratch,
        s_node: [usize; 3],
        mut emit: impl FnMut(usize, usize, &[Real]),
    ) {
        let corners = self.triangles[t];
        let nu = scratch.union.len();
        let ns = s_node.iter().filter(|&&a| a != usize::MAX).count();
        let hik = |i: usize, k: usize| -> Mat3 { h.fixed_view::<3, 3>(3 * i, 3 * k).into_owned() };
        let tan: [Mat3x2; 3] = corners.map(|c| frames.points[c].tangents);
        let gi: [Vec3; 3] = [0, 1, 2].map(|i| Vec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2]));

        // s–s blocks.
        for i in 0..3 {
            if s_node[i] == usize::MAX {
                continue;
            }
            for k in i..3 {
                if s_node[k] == usize::MAX {
                    continue;
                }
                let mut b = tan[i].transpose() * hik(i, k) * tan[k];
                if i == k {
                    let sec = &frames.points[corners[i]].second;
                    b[(0, 0)] += gi[i].dot(&sec[0]);
                    b[(0, 1)] += gi[i].dot(&sec[1]);
                    b[(1, 0)] += gi[i].dot(&sec[1]);
                    b[(1, 1)] += gi[i].dot(&sec[2]);
                }
                emit(
                    s_node[i],
                    s_node[k],
                    &[b[(0, 0)], b[(0, 1)], b[(1, 0)], b[(1, 1)]],
                );
            }
        }
        // HW_u[i] = Σ_k H_ik w_uk.
        scratch.hw.clear();
        let h_blocks: [[Mat3; 3]; 3] = [0, 1, 2].map(|i| [0, 1, 2].map(|k| hik(i, k)));
        for u in 0..nu {
            let w = scratch.w[u];
            scratch
                .hw
                .push([0, 1, 2].map(|i| {
                    h_blocks[i][0] * w[0] + h_blocks[i][1] * w[1] + h_blocks[i][2] * w[2]
                }));
        }
        // s–y blocks.
        let mut sy = [0.0; 6];
        for i in 0..3 {
            if s_node[i] == usize::MAX {
                continue;
            }
            for u in 0..nu {
                let b = tan[i].transpose() * scratch.hw[u][i]; // 2 × 3
                for a in 0..2 {
                    let dw = scratch.dw[u][i][a];
                    for k in 0..3 {
                        sy[3 * a + k] = b[(a, k)] + dw * gi[i][k];
                    }
                }
                emit(s_node[i], ns + u, &sy);
            }
        }
        // y–y blocks.
        let mut yy = [0.0; 9];
        for u in 0..nu {
            let wu = scratch.w[u];
            for v in u..nu {
                let hv = &scratch.hw[v];
                let b = hv[0] * wu[0] + hv[1] * wu[1] + hv[2] * wu[2];
                for r in 0..3 {
                    for c in 0..3 {
                        yy[3 * r + c] = b[(r, c)];
                    }
                }
                emit(ns + u, ns + v, &yy);
            }
        }
    }

    /// The damping metric `D` (`#q`): 1 for body coordinates, `|∂x/∂s_a|²` (m²) for surface coordinates
    /// (floored at 10⁻³ of their median), so that `α D` (α in N/m) damps every unknown by about the same
    /// stiffness per metre of motion.
    pub fn damping_metric(&self, state: &ClothOnBodyState) -> Result<Vec<Real>, ClothOnBodyError> {
        Ok(self.damping_metric_with(&self.frames(state)?))
    }

    fn damping_metric_with(&self, frames: &Frames) -> Vec<Real> {
        let mut d = vec![1.0; self.num_dofs];
        let mut s_entries = Vec::new();
        for (c, dof) in self.cloth_dof.iter().enumerate() {
            if let Some(k) = *dof {
                let t = &frames.points[c].tangents;
                d[k] = t.column(0).norm_squared();
                d[k + 1] = t.column(1).norm_squared();
                s_entries.extend([d[k], d[k + 1]]);
            }
        }
        // Next to an extraordinary vertex of valence < 6 the limit surface's tangents shrink to zero at the
        // vertex; floor the metric there at 10⁻³ of the median so such a coordinate is still damped.
        if !s_entries.is_empty() {
            let mid = s_entries.len() / 2;
            let median = *s_entries
                .select_nth_unstable_by(mid, |a, b| a.total_cmp(b))
                .1;
            let floor = 1e-3 * median;
            for dof in self.cloth_dof.iter().flatten() {
                d[*dof] = d[*dof].max(floor);
                d[dof + 1] = d[dof + 1].max(floor);
            }
        }
        d
    }

    /// Unbalanced forces (N): the body gradient entries as they are, and for each cloth vertex's `∂U/∂s`
    /// the tangential force it represents, `|T (TᵀT)⁻¹ ∂U/∂s|`. Returns `‖·‖₂` over all of them.
    pub fn force_residual(
        &self,
        state: &ClothOnBodyState,
        gradient: &[Real],
    ) -> Result<Real, ClothOnBodyError> {
        Ok(self.force_residual_with(&self.frames(state)?, gradient))
    }

    fn force_residual_with(&self, frames: &Frames, gradient: &[Real]) -> Real {
        let mut sum = 0.0;
        for dof in &self.body_dof {
            if let Some(d) = *dof {
                sum += gradient[d] * gradient[d]
                    + gradient[d + 1] * gradient[d + 1]
                    + gradient[d + 2] * gradient[d + 2];
            }
        }
        for (c, dof) in self.cloth_dof.iter().enumerate() {
            if let Some(d) = *dof {
                let t = &frames.points[c].tangents;
                let gs = Vec2::new(gradient[d], gradient[d + 1]);
                let metric = t.transpose() * t;
                let f = match metric.try_inverse() {
                    Some(inv) => gs.dot(&(inv * gs)),
                    None => Real::INFINITY,
                };
                sum += f;
            }
        }
        sum.sqrt()
    }

    /// The smallest volume ratio `J = det F` over the body tetrahedra at `state`, and its tetrahedron
    /// (`(1, 0)` for a body without tetrahedra). `J ≤ 0` is an inverted element.
    pub fn min_volume_ratio(&self, state: &ClothOnBodyState) -> (Real, usize) {
        let mut best = (1.0, 0);
        for (t, tet) in self.tets.iter().enumerate() {
            let j = self.body.elements()[t]
                .deformation_gradient(&tet.map(|v| state.body[v]))
                .determinant();
            if !(j >= best.0) {
                best = (j, t);
            }
        }
        best
    }

    /// Cartesian cloth force norm `‖∂U_cloth/∂x‖₂` (N) over all cloth vertices: the forces the body must
    /// balance, used as the force scale of the convergence test.
    pub fn cloth_force_norm(&self, state: &ClothOnBodyState) -> Result<Real, ClothOnBodyError> {
        let g = self.cloth_vertex_forces(state)?;
        Ok(g.iter().map(|f| f.norm_squared()).sum::<Real>().sqrt())
    }

    /// `∂U_cloth/∂x_i` (N, `#Vc`): minus the force the cloth exerts at each cloth vertex.
    pub fn cloth_vertex_forces(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<Vec3>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        let mut out = vec![Vec3::zeros(); state.cloth.len()];
        for (t, element) in self.elements.iter().enumerate() {
            let (_, g) = element
                .energy_gradient(&self.density, &self.corners(t, &frames.points))
                .map_err(|source| ClothOnBodyError::Cloth {
                    triangle: t,
                    source,
                })?;
            for (i, &c) in self.triangles[t].iter().enumerate() {
                out[c] += Vec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2]);
            }
        }
        Ok(out)
    }

    /// Per cloth triangle: principal stretches, regime and stress.
    pub fn element_states(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<MembraneState>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        self.elements
            .iter()
            .enumerate()
            .map(|(t, e)| {
                e.state(&self.density, &self.corners(t, &frames.points))
                    .map_err(|source| ClothOnBodyError::Cloth {
                        triangle: t,
                        source,
                    })
            })
            .collect()
    }

    /// Per cloth vertex, the normal force the cloth presses onto the body, `∂U_cloth/∂x_i · n_i` (N;
    /// positive = pressing in, negative = pulling away), with `n_i` the outward surface normal.
    pub fn cloth_normal_forces(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<Real>, ClothOnBodyError> {
        let forces = self.cloth_vertex_forces(state)?;
        let points = self.cloth_surface_points(state)?;
        Ok(forces
            .iter()
            .zip(&points)
            .map(|(g, p)| p.normal().map_or(0.0, |n| g.dot(&n)))
            .collect())
    }

    /// Interface pressure per cloth triangle (Pa): the normal force of the triangle's own corner forces,
    /// `Σ_i ∂U_e/∂x_i · n_i`, over its deformed area. Positive presses onto the body; negative would lift off.
    pub fn element_pressures(
        &self,
        state: &ClothOnBodyState,
    ) -> Result<Vec<Real>, ClothOnBodyError> {
        let frames = self.frames(state)?;
        let mut out = Vec::with_capacity(self.elements.len());
        for (t, element) in self.elements.iter().enumerate() {
            let x = self.corners(t, &frames.points);
            let (_, g) = element
                .energy_gradient(&self.density, &x)
                .map_err(|source| ClothOnBodyError::Cloth {
                    triangle: t,
                    source,
                })?;
            let mut normal_force = 0.0;
            for (i, &c) in self.triangles[t].iter().enumerate() {
                if let Some(n) = frames.points[c].normal() {
                    normal_force += Vec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2]).dot(&n);
                }
            }
            let area = 0.5 * (x[1] - x[0]).cross(&(x[2] - x[0])).norm();
            out.push(if area > 0.0 { normal_force / area } else { 0.0 });
        }
        Ok(out)
    }

    /// The DOF vector of `state` (`#q`): `s` of unpinned cloth vertices, positions of free body vertices.
    pub fn dofs(&self, state: &ClothOnBodyState) -> Vec<Real> {
        let mut q = vec![0.0; self.num_dofs];
        for (c, dof) in self.cloth_dof.iter().enumerate() {
            if let Some(d) = *dof {
                q[d] = state.cloth[c].s.x;
                q[d + 1] = state.cloth[c].s.y;
            }
        }
        for (v, dof) in self.body_dof.iter().enumerate() {
            if let Some(d) = *dof {
                q[d..d + 3].copy_from_slice(state.body[v].as_slice());
            }
        }
        q
    }

    /// The state with the DOFs `q` in the faces of `template` (no walking: the coordinates are taken as
    /// they are, even outside the face — the surface clamps them). For derivative tests and small steps.
    pub fn with_dofs(&self, template: &ClothOnBodyState, q: &[Real]) -> ClothOnBodyState {
        let mut state = template.clone();
        for (c, dof) in self.cloth_dof.iter().enumerate() {
            if let Some(d) = *dof {
                state.cloth[c].s = Vec2::new(q[d], q[d + 1]);
            }
        }
        for (v, dof) in self.body_dof.iter().enumerate() {
            if let Some(d) = *dof {
                state.body[v] = Vec3::new(q[d], q[d + 1], q[d + 2]);
            }
        }
        state
    }

    /// Applies the step `dq` (`#q`): body positions are added (Eq. 146), each cloth vertex walks its `Δs`
    /// across faces on the surface of the new body positions (Eq. 147–154).
    pub fn step(
        &self,
        state: &ClothOnBodyState,
        dq: &[Real],
        walk: &WalkParams,
    ) -> Result<ClothOnBodyState, WalkError> {
        let mut next = state.clone();
        for (v, dof) in self.body_dof.iter().enumerate() {
            if let Some(d) = *dof {
                next.body[v] += Vec3::new(dq[d], dq[d + 1], dq[d + 2]);
            }
        }
        let control = self.control_positions(&next.body);
        for (c, dof) in self.cloth_dof.iter().enumerate() {
            if let Some(d) = *dof {
                let ds = Vec2::new(dq[d], dq[d + 1]);
                if ds.x != 0.0 || ds.y != 0.0 {
                    next.cloth[c] =
                        surface_walk(&*self.surface, &control, state.cloth[c], ds, walk, None)?
                            .coord;
                }
            }
        }
        Ok(next)
    }
}

#[cfg(test)]
#[path = "cloth_on_body_tests.rs"]
pub(crate) mod tests;
