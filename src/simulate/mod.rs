//! The forward simulation job: a scene in, the garment worn on the body at equilibrium out.
//!
//! [`prepare`] builds the body (tetrahedra, material, fixed core) and its smooth surface, constructs the
//! garment (cut, flatten, remesh, ease, sew), embeds every cloth vertex on the surface and sets up the coupled
//! system; [`run`] solves for the equilibrium ([`fn@skintight_physics::equilibrium`]); [`SimulationResult`] and
//! [`artifacts`] turn the final state into `result.json` (with the pressure per landmark band, [`regions`]),
//! `garment.glb`, `garment-pressure.glb`, `body.glb`, the pattern files ([`pattern_files`]: seams trued before
//! the solve, the cut-ready pattern drawn after it) and the fitter's `report.html` ([`report`]).
//! The CLI (`skintight simulate`) and the service's `simulate` job kind both go through here.

pub mod admissibility;
pub mod colormap;
pub mod pattern_files;
pub mod prescription;
pub mod probe_pressure;
pub mod regions;
pub mod report;
pub mod result;

use std::ops::ControlFlow;
use std::sync::Arc;
use std::time::Instant;

use skintight_garment::garment::{Garment, GarmentParams, PanelShape, PanelSpec, garment};
use skintight_garment::pattern_remesh::RemeshParams;
use skintight_garment::plane_cut::PlaneCutParams;
use skintight_garment::sliver_flip::{SliverFlipParams, sliver_flip};
use skintight_geometry::anthropometry::{MeasureError, Measurements, measure_body};
use skintight_geometry::surface::closest_point::{ClosestPointParams, closest_point_from};
use skintight_geometry::{LinearSurface, LoopSurface, SurfaceCoord, Vec2};
use skintight_physics::cloth_on_body::{
    BodySpec, ClothOnBody, ClothOnBodyState, ClothSpec, SharedSurface,
};
use skintight_physics::equilibrium::{
    EquilibriumParams, EquilibriumReport, EquilibriumWorkspace, IterationInfo, SolveProgress,
    StopReason, equilibrium_resumable,
};
use skintight_physics::tension_field_density::TensionFieldParams;

use crate::scene::{BodyModel, PanelShapeSpec, PathResolver, Scene, SurfaceKind};

pub use result::SimulationResult;

/// Why a simulation could not be set up or run.
///
/// `key` names the scene field at fault when there is one (`garment.panels[1]`, `body.source.path`), so the
/// CLI can print one line and the service can answer with the field.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}{message}", key.as_ref().map(|k| format!("{k}: ")).unwrap_or_default())]
pub struct SimulateError {
    /// The scene field at fault, if any.
    pub key: Option<String>,
    /// What went wrong, for the person who wrote the scene.
    pub message: String,
    /// Whether the input is at fault (a bad scene) rather than the computation.
    pub input: bool,
}

impl SimulateError {
    pub fn input(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            key: Some(key.into()),
            message: message.into(),
            input: true,
        }
    }

    pub fn failed(message: impl Into<String>) -> Self {
        Self {
            key: None,
            message: message.into(),
            input: false,
        }
    }
}

impl From<crate::scene::SceneError> for SimulateError {
    fn from(e: crate::scene::SceneError) -> Self {
        Self::input(e.key, e.message)
    }
}

/// A body tetrahedron compressed below this volume ratio (`det F`) at the end of a solve means the garment
/// crushes the body (a nearly incompressible body, ν ≈ 0.5, never gets there under a wearable garment).
pub const CRUSHED_VOLUME_RATIO: f64 = 0.2;

/// A prepared simulation: the body, the garment, the coupled system and its current state.
pub struct Simulation {
    /// The scene it came from.
    pub scene: Scene,
    /// The body.
    pub body: BodyModel,
    /// The garment (patterns, cloth triangles, seams).
    pub garment: Garment,
    /// The coupled system.
    pub system: ClothOnBody,
    /// The current state (the start state until [`run`]).
    pub state: ClothOnBodyState,
    /// The start state.
    pub initial_state: ClothOnBodyState,
    /// `#Vc` pinned flags.
    pub pinned: Vec<bool>,
    /// What seam truing changed in the patterns (zeros when `patterns.true_seams` is off).
    pub seam_truing: skintight_garment::seam_truing::SeamTruingReport,
    /// Seconds spent in [`prepare`]: body, garment, surface.
    pub setup_s: SetupTimings,
    /// The garment template `scene` was resolved from (its panels are the template's on this body), if any.
    pub template: Option<crate::scene::TemplateSpec>,
    /// The body's landmarks and girths (measured once, at rest), or why the body cannot be measured (not a
    /// standing human body: the procedural cylinder, a sphere). The landmark bands of `result.json`
    /// ([`regions`]) and the report's measurements come from these.
    pub measurements: Result<Measurements, MeasureError>,
}

/// Times of the set-up steps (s).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SetupTimings {
    /// Building the body (tetrahedralization included).
    pub body_s: f64,
    /// Cutting, flattening, remeshing and sewing the garment.
    pub garment_s: f64,
    /// Building the limit surface and embedding the cloth.
    pub surface_s: f64,
}

/// The limit surface of kind `kind` over the body surface mesh.
fn limit_surface(
    body: &BodyModel,
    kind: SurfaceKind,
) -> Result<(SharedSurface, Option<Arc<LoopSurface>>), SimulateError> {
    let nv = body.surface.num_vertices();
    let faces = &body.surface.faces;
    match kind {
        SurfaceKind::Linear => {
            let s = LinearSurface::new(nv, faces).map_err(|e| {
                SimulateError::input(
                    "body",
                    format!("the body surface cannot carry the garment: {e}"),
                )
            })?;
            Ok((Arc::new(s), None))
        }
        SurfaceKind::Loop => {
            let s = LoopSurface::new(nv, faces)
                .or_else(|_| LoopSurface::with_preprocessing_subdivision(nv, faces))
                .map_err(|e| {
                    SimulateError::input(
                        "body",
                        format!("the body surface has no Loop limit surface: {e}"),
                    )
                })?;
            let s = Arc::new(s);
            Ok((s.clone(), Some(s)))
        }
    }
}

/// Who is at fault where the garment cannot be cut, sewn or flattened on the body.
enum CutFault {
    /// The job's own panels: its key (`garment`, `garment.panels`), exit 2.
    Job,
    /// A template's panels cut on this body: the body (its description), exit 1.
    Body(String),
}

impl CutFault {
    /// The fault of a garment from `template` (if any) on the body from `source`.
    fn of(
        source: &crate::scene::BodySource,
        template: Option<&crate::scene::TemplateSpec>,
    ) -> Self {
        let Some(t) = template else {
            return CutFault::Job;
        };
        let body = match source {
            crate::scene::BodySource::SurfaceMesh { path, .. }
            | crate::scene::BodySource::TetMesh { path } => format!("the body '{path}'"),
            other => format!("the {} body", other.kind()),
        };
        CutFault::Body(format!("template '{}' on {body}", t.name))
    }

    /// The error `message` at `key` (a job's fault) or about the body.
    fn error(&self, key: &str, message: String) -> SimulateError {
        match self {
            CutFault::Job => SimulateError::input(key, message),
            CutFault::Body(what) => SimulateError::failed(format!(
                "the garment cannot be made on this body: {what}: {message}. The body mesh passed its \
                 checks but its surface does not carry this cut here; a body prepared at another \
                 resolution (`skintight body prepare --target-faces`) may"
            )),
        }
    }
}

/// Replaces every panel's pattern by the least squares conformal flattening of its cloth triangles at
/// `positions` (`#Vc`, m), its slivers repaired by edge flips ([`sliver_flip`]; the garment's cloth
/// triangles follow), scaled by `1 + ease` about its area centroid.
fn reflatten(
    garment: &mut Garment,
    positions: &[skintight_geometry::Vec3],
    ease: f64,
    fault: &CutFault,
) -> Result<(), SimulateError> {
    for panel in &mut garment.panels {
        let mesh = skintight_geometry::TriMesh::new(
            panel.cloth_vertex.iter().map(|&c| positions[c]).collect(),
            panel.faces.clone(),
        );
        let flat = skintight_garment::lscm::lscm(&mesh).map_err(|e| {
            fault.error(
                "garment.panels",
                format!(
                    "panel '{}' cannot be flattened on the smooth body surface: {e}",
                    panel.name
                ),
            )
        })?;
        if flat.flipped > 0 {
            return Err(fault.error(
                "garment.panels",
                format!(
                    "panel '{}' folds over when flattened on the smooth body surface ({} triangles flipped); \
                     use a smaller edge_length or split the panel",
                    panel.name, flat.flipped
                ),
            ));
        }
        let mut pattern = flat.positions;
        // Slivers the smooth surface made of ear triangles at kinks of the cut line: flipped away
        // (same vertices, boundary and seams; the cloth triangles follow their pattern triangles).
        let flips = sliver_flip(&pattern, &mut panel.faces, &SliverFlipParams::default());
        if flips > 0 {
            for (f, tri) in panel.faces.iter().enumerate() {
                garment.faces[panel.cloth_face[f]] = tri.map(|v| panel.cloth_vertex[v]);
            }
        }
        skintight_garment::ease::ease(&mut pattern, &panel.faces, ease)
            .map_err(|e| SimulateError::input("garment.ease", e.to_string()))?;
        panel.pattern = pattern;
    }
    Ok(())
}

/// A cloth vertex exactly at an extraordinary vertex of the Loop surface (a panel corner where several
/// panels meet on a body vertex, say) has degenerate surface coordinates there: the limit surface's tangents
/// `∂x/∂s` vanish (valence < 6) or blow up (valence > 6) at the vertex itself. Such a location is moved
/// 10⁻³ of the way toward the face centre (a few µm on the body), where the surface derivative is regular.
fn off_corner(surface: &LoopSurface, c: SurfaceCoord) -> SurfaceCoord {
    if !surface.is_irregular(c.face) {
        return c;
    }
    let b = c.barycentric();
    if b.iter().any(|&w| w > 1.0 - 1e-6) {
        let centre = Vec2::new(1.0 / 3.0, 1.0 / 3.0);
        SurfaceCoord {
            face: c.face,
            s: c.s + (centre - c.s) * 1e-3,
        }
    } else {
        c
    }
}

/// Builds everything the solve needs from `scene`, resolving mesh paths with `resolver`.
pub fn prepare(scene: &Scene, resolver: &dyn PathResolver) -> Result<Simulation, SimulateError> {
    scene.validate()?;
    let t0 = Instant::now();
    let body = scene.body.build(resolver)?;
    // The body measured once: for the template's anchors and the landmark bands of the result.
    let measurements = measure_body(&body.surface);
    // A garment template becomes ordinary panels on this body; the simulation keeps the resolved scene.
    let resolved;
    let template = scene.garment.template.clone();
    let scene = match &template {
        Some(t) => {
            let mut r = scene.clone();
            r.garment.panels = crate::scene::template::resolve_template_measured(
                t,
                &body.surface,
                measurements.as_ref(),
            )?;
            r.garment.template = None;
            r.validate()?;
            resolved = r;
            &resolved
        }
        None => scene,
    };
    scene.validate_against(&body)?;
    let body_s = t0.elapsed().as_secs_f64();

    let t0 = Instant::now();
    let g = &scene.garment;
    let specs: Vec<PanelSpec> = g
        .panels
        .iter()
        .map(|p| PanelSpec {
            name: p.name.clone(),
            shape: match &p.shape {
                PanelShapeSpec::HalfSpaces(h) => PanelShape::Region(h.clone()),
                PanelShapeSpec::Faces(f) => PanelShape::Faces(f.clone()),
            },
        })
        .collect();
    let params = GarmentParams {
        edge_length: g.edge_length,
        ease: g.ease,
        remesh: RemeshParams::default(),
        cut: PlaneCutParams::default(),
    };
    // A template's panels are this body's cut: where they cannot be cut, sewn or flattened, the body (a
    // mesh `body prepare` and `mesh inspect` accept) is at fault, not a key of the job (exit 1, naming
    // the body). Panels the job gave itself are the job's (exit 2, naming `garment`).
    let cut_fault = CutFault::of(&scene.body.source, template.as_ref());
    let mut garment = garment(&body.surface, &specs, &params)
        .map_err(|e| cut_fault.error("garment", e.to_string()))?;
    let garment_s = t0.elapsed().as_secs_f64();

    let t0 = Instant::now();
    let (surface, loop_surface) = limit_surface(&body, scene.solver.surface)?;
    // Embedding: a cloth vertex starts at the point of the smooth surface closest to where the garment was
    // cut on the flat body mesh. (Reusing the flat barycentric coordinates as surface coordinates would be
    // badly distorted near extraordinary vertices, where Stam's parametrization is far from uniform.)
    let control: Vec<skintight_geometry::Vec3> = body
        .surface_tet_vertex
        .iter()
        .map(|&v| body.tets.positions[v])
        .collect();
    let projection = ClosestPointParams::default();
    let coords: Vec<SurfaceCoord> = garment
        .vertex_body
        .iter()
        .zip(&garment.positions)
        .map(|(p, &flat)| {
            let s = Vec2::new(p.bary[0], p.bary[1]);
            let start = match &loop_surface {
                Some(l) => l.coord_in_original_face(p.face, s)?,
                None => return Ok(SurfaceCoord { face: p.face, s }),
            };
            let l = loop_surface.as_ref().expect("Loop surface");
            // A projection that fails (it should not: the surface is millimetres away) keeps the start.
            let found = closest_point_from(&**l, &control, flat, start, &projection)
                .map_or(start, |pr| pr.coord);
            Ok(off_corner(l, found))
        })
        .collect::<Result<_, skintight_geometry::SurfaceError>>()
        .map_err(|e| {
            SimulateError::failed(format!(
                "embedding the cloth on the body surface failed: {e}"
            ))
        })?;
    // The patterns: each panel flattened again from the cloth as it lies on the surface the simulation uses
    // (the limit surface sits a few millimetres off the flat body mesh the garment was cut from, which
    // would otherwise show up as spurious stretch in the small triangles along cut lines), then eased.
    let start_positions = {
        let mut scratch = skintight_geometry::Stencil::with_capacity(64);
        coords
            .iter()
            .map(|c| {
                surface
                    .point_with(&control, c.face, c.s, &mut scratch)
                    .map(|p| p.position)
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| {
                SimulateError::failed(format!("evaluating the body surface failed: {e}"))
            })?
    };
    reflatten(&mut garment, &start_positions, g.ease, &cut_fault)?;
    // Seams that sew: both sides of every seam equally long (before the solve, so the simulated garment is
    // the one that will be cut), and the pattern files drawable (allowances, notches) — refused now rather
    // than after the solve.
    let seam_truing = pattern_files::true_seams_of(scene, &mut garment)?;
    let pattern = pattern_files::pattern_of(scene, &garment)?;
    pattern_files::marker_fits(scene, &pattern)?;

    // Pinned: free-boundary cloth vertices inside the pinned region.
    let pinned: Vec<bool> = match &g.pinned {
        None => vec![false; garment.num_vertices()],
        Some(region) => {
            let planes: Vec<_> = region
                .half_spaces
                .iter()
                .map(|h| (h.normal / h.normal.norm(), h.offset / h.normal.norm()))
                .collect();
            garment
                .positions
                .iter()
                .zip(&garment.free_boundary)
                .map(|(p, &free)| free && planes.iter().all(|(n, d)| n.dot(p) <= *d + 1e-9))
                .collect()
        }
    };
    if g.pinned.is_some() && !pinned.iter().any(|&p| p) {
        return Err(SimulateError::input(
            "garment.pinned",
            "the pinned region contains no vertex of the garment's free boundary",
        ));
    }

    let triangles = garment.faces.clone();
    let rest: Vec<[Vec2; 3]> = (0..garment.num_faces())
        .map(|f| garment.rest_triangle(f))
        .collect();
    let system = ClothOnBody::new(
        BodySpec {
            rest_positions: body.tets.positions.clone(),
            tets: body.tets.tets.clone(),
            fixed: body.tets.fixed.clone(),
            material: body.material,
            surface,
            surface_body_vertex: body.surface_tet_vertex.clone(),
        },
        ClothSpec {
            triangles,
            rest,
            youngs_modulus: g.fabric.youngs_modulus,
            poisson_ratio: g.fabric.poisson_ratio,
            thickness: g.fabric.thickness,
            tension_field: TensionFieldParams::default(),
            pinned: pinned.clone(),
            orthotropic: None,
            grain: Vec::new(),
        },
    )
    .map_err(|e| cut_fault.error("garment", e.to_string()))?;
    let state = system
        .rest_state(coords)
        .map_err(|e| SimulateError::failed(e.to_string()))?;
    let surface_s = t0.elapsed().as_secs_f64();
    Ok(Simulation {
        scene: scene.clone(),
        body,
        garment,
        system,
        initial_state: state.clone(),
        state,
        pinned,
        seam_truing,
        setup_s: SetupTimings {
            body_s,
            garment_s,
            surface_s,
        },
        template,
        measurements,
    })
}

/// The solver settings of the scene.
pub fn equilibrium_params(scene: &Scene) -> EquilibriumParams {
    EquilibriumParams {
        tolerance: scene.solver.tolerance,
        max_iterations: scene.solver.max_iterations,
        time_limit_s: scene.solver.time_limit_s,
        hessian: scene.solver.hessian,
        ..Default::default()
    }
}

/// Solves for the equilibrium from the current state; `on_iteration` sees every Newton iteration and may
/// stop the solve. A solve that cannot keep the body from inverting is an error naming the problem.
pub fn run(
    sim: &mut Simulation,
    on_iteration: &mut dyn FnMut(&IterationInfo) -> ControlFlow<()>,
) -> Result<EquilibriumReport, SimulateError> {
    run_resumable(sim, None, &mut |info, _, _| on_iteration(info))
}

/// [`run`] that can be checkpointed and resumed: `on_iteration` also sees the state after each iteration
/// and the solve's progress; with `resume`, the solve continues from `sim.state` (a checkpointed state) as
/// the interrupted one would have ([`equilibrium_resumable`]).
pub fn run_resumable(
    sim: &mut Simulation,
    resume: Option<SolveProgress>,
    on_iteration: &mut dyn FnMut(
        &IterationInfo,
        &ClothOnBodyState,
        &SolveProgress,
    ) -> ControlFlow<()>,
) -> Result<EquilibriumReport, SimulateError> {
    let params = equilibrium_params(&sim.scene);
    let report = equilibrium_resumable(
        &sim.system,
        &mut sim.state,
        &params,
        resume,
        on_iteration,
        &mut EquilibriumWorkspace::default(),
    )
    .map_err(|e| SimulateError::failed(e.to_string()))?;
    // A garment the body cannot bear: the equilibrium crushes body tetrahedra, or the solve could not go on
    // without turning one inside out (such steps are refused).
    let (min_j, tet) = sim.system.min_volume_ratio(&sim.state);
    if min_j < CRUSHED_VOLUME_RATIO
        || (report.stop == StopReason::NoProgress && report.figures.rejected_inversions > 0)
    {
        let c = sim.system.tets()[tet]
            .iter()
            .map(|&v| sim.state.body[v])
            .sum::<skintight_geometry::Vec3>()
            / 4.0;
        return Err(SimulateError::failed(format!(
            "the garment would invert the body: after {} iterations body tetrahedron {tet} near ({:.3}, {:.3}, \
             {:.3}) m is crushed to {:.1} % of its volume and {} steps that would have turned tetrahedra inside \
             out were refused. Loosen the ease (garment.ease closer to 0) or stiffen the body \
             (body.material.youngs_modulus)",
            report.iterations,
            c.x,
            c.y,
            c.z,
            100.0 * min_j.max(0.0),
            report.figures.rejected_inversions
        )));
    }
    Ok(report)
}

/// A named output file.
#[derive(Clone, Debug)]
pub struct ArtifactFile {
    /// File name (`result.json`, `garment.glb`, …).
    pub name: &'static str,
    /// MIME type.
    pub content_type: &'static str,
    /// Contents.
    pub data: Vec<u8>,
}

/// `result.json` of a finished simulation: the [`SimulationResult`] plus the pattern's seam table
/// (`seams`), what seam truing changed (`seam_truing`) and the marker (`marker`).
pub fn result_json(
    sim: &Simulation,
    result: &SimulationResult,
    pattern: &skintight_garment::pattern::Pattern,
    marker: &skintight_garment::marker::Marker,
) -> Result<serde_json::Value, SimulateError> {
    let mut json =
        serde_json::to_value(result).map_err(|e| SimulateError::failed(e.to_string()))?;
    if let Some(obj) = json.as_object_mut() {
        for (key, value) in pattern_files::result_fields(pattern, &sim.seam_truing, marker) {
            obj.insert(key.into(), value);
        }
    }
    Ok(json)
}

/// The files of a finished simulation: `result.json`, `garment.glb`, `garment-pressure.glb`, `body.glb`, the
/// pattern files ([`pattern_files::pattern_artifacts`]) and the fitter's `report.html` ([`report`]).
pub fn artifacts(
    sim: &Simulation,
    result: &SimulationResult,
) -> Result<Vec<ArtifactFile>, SimulateError> {
    let pattern = pattern_files::pattern_of(&sim.scene, &sim.garment)?;
    let marker = pattern_files::marker_of(&sim.scene, &pattern)?;
    let mut out = vec![ArtifactFile {
        name: "result.json",
        content_type: "application/json",
        data: serde_json::to_vec_pretty(&result_json(sim, result, &pattern, &marker)?)
            .map_err(|e| SimulateError::failed(e.to_string()))?,
    }];
    out.push(ArtifactFile {
        name: "garment.glb",
        content_type: "model/gltf-binary",
        data: result::garment_glb(sim, result)?,
    });
    out.push(ArtifactFile {
        name: "garment-pressure.glb",
        content_type: "model/gltf-binary",
        data: result::garment_pressure_glb(sim, result)?,
    });
    out.push(ArtifactFile {
        name: "body.glb",
        content_type: "model/gltf-binary",
        data: result::body_glb(sim)?,
    });
    out.extend(pattern_files::pattern_artifacts(sim, &pattern, &marker)?);
    out.push(ArtifactFile {
        name: "report.html",
        content_type: "text/html",
        data: report::report_html(sim, result, &pattern, result.prescription.as_ref()).into_bytes(),
    });
    if sim.template.is_some() {
        // The template's panels on this body, as an ordinary scene: the same job without the template
        // (file references as in the submitted scene).
        out.push(ArtifactFile {
            name: "resolved_scene.json",
            content_type: "application/json",
            data: serde_json::to_vec_pretty(&sim.scene)
                .map_err(|e| SimulateError::failed(e.to_string()))?,
        });
    }
    Ok(out)
}
