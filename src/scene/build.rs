//! Building the body of a scene: reading or generating the tetrahedral mesh, fixing its vertices, and finding
//! the body surface the garment lies on.

use serde::Serialize;
use skintight_geometry::body::procedural_body::{
    Core, ProceduralBodyError, fix_core, fix_region, solid_cylinder, solid_sphere,
};
use skintight_geometry::body::shell_tetrahedralization::ShellParams;
use skintight_geometry::body::tet_io::read_tet_mesh;
use skintight_geometry::math::Real;
use skintight_geometry::mesh::io::read_mesh;
use skintight_geometry::region::Region;
use skintight_geometry::{
    MeshCheckParams, ShellError, ShellReport, TetMesh, TriMesh, body_surface, mesh_report,
    outer_boundary_surface, shell_tetrahedralization,
};
use skintight_physics::NeoHookeanParams;

use super::error::SceneError;
use super::resolve::PathResolver;
use super::spec::{BodySource, DEFAULT_CORE_FRACTION, FixedSpec, SceneBody};

/// A body ready for simulation.
#[derive(Clone, Debug)]
pub struct BodyModel {
    /// The tetrahedral mesh: rest positions (m), positively oriented tetrahedra, and the fixed flags after
    /// the scene's `fixed` rule.
    pub tets: TetMesh,
    /// The body surface the garment lies on: outward oriented, closed, and the control mesh of the limit
    /// surface. For a `surface_mesh` body it is the input mesh with its face order unchanged (so panel face
    /// indices refer to the faces of the input file; faces of an inward mesh are flipped in place and unused
    /// vertices dropped, see [`BodyReport::warnings`]). For `tet_mesh`, `cylinder` and `sphere` bodies it is
    /// the outer boundary surface of the tetrahedral mesh.
    pub surface: TriMesh,
    /// `#Vs` the tetrahedral-mesh vertex of each surface vertex; positions are identical (checked).
    pub surface_tet_vertex: Vec<usize>,
    /// The body's Neo-Hookean material (from `body.material`; other settings at their defaults).
    pub material: NeoHookeanParams,
    /// What was built.
    pub report: BodyReport,
}

/// What a body build produced, for the user.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BodyReport {
    /// The source kind (`surface_mesh`, `tet_mesh`, `cylinder`, `sphere`).
    pub source: String,
    /// Number of tetrahedra.
    pub tets: usize,
    /// Number of tetrahedral-mesh vertices.
    pub vertices: usize,
    /// Number of fixed vertices.
    pub fixed: usize,
    /// Number of body surface vertices.
    pub surface_vertices: usize,
    /// Number of body surface faces.
    pub surface_faces: usize,
    /// Rest volume of the body (m³).
    pub volume: Real,
    /// Smallest mean-ratio tetrahedron quality (1 = regular).
    pub min_quality: Real,
    /// Whether the input surface was oriented inward and had its faces flipped (`surface_mesh` only).
    pub flipped: bool,
    /// Surface vertices where the shell is pinched to zero thickness and fixed (`surface_mesh` only).
    pub pinched_vertices: usize,
    /// The shell tetrahedralization's statistics (`surface_mesh` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shell: Option<ShellReport>,
    /// Repairs and remarks (a flipped surface, dropped unused vertices).
    pub warnings: Vec<String>,
}

const PATH_KEY: &str = "body.source.path";

/// The key of a procedural-body parameter error.
fn procedural_error(e: ProceduralBodyError, fixed: bool) -> SceneError {
    let key = match &e {
        ProceduralBodyError::BadParam { field, .. }
        | ProceduralBodyError::TooLarge { field, .. } => {
            if fixed {
                format!("body.fixed.{field}")
            } else {
                format!("body.source.{field}")
            }
        }
        ProceduralBodyError::BadHalfSpace { half_space, .. } => {
            format!("body.fixed.half_spaces[{half_space}]")
        }
        _ if fixed => "body.fixed".to_string(),
        _ => "body.source".to_string(),
    };
    SceneError::new(key, e.to_string())
}

fn shell_error(e: ShellError) -> SceneError {
    let key = match &e {
        ShellError::BadParam { name, .. } if matches!(*name, "thickness" | "layers") => {
            format!("body.source.{name}")
        }
        _ => PATH_KEY.to_string(),
    };
    SceneError::new(key, format!("cannot fill the body with a shell: {e}"))
}

impl SceneBody {
    /// Builds the body: reads (through `resolver`) or generates the tetrahedral mesh, applies the `fixed`
    /// rule, and finds the body surface. Runs [`SceneBody::validate`] first. Errors name the key at fault:
    /// `body.source.path` for a file that is missing, unreadable or unusable as a body, `body.fixed` when no
    /// vertex ends up fixed.
    pub fn build(&self, resolver: &dyn PathResolver) -> Result<BodyModel, SceneError> {
        self.validate()?;
        let mut report = BodyReport {
            source: self.source.kind().to_string(),
            tets: 0,
            vertices: 0,
            fixed: 0,
            surface_vertices: 0,
            surface_faces: 0,
            volume: 0.0,
            min_quality: 0.0,
            flipped: false,
            pinched_vertices: 0,
            shell: None,
            warnings: Vec::new(),
        };
        let (mut tets, surface, surface_tet_vertex) = match &self.source {
            BodySource::SurfaceMesh {
                path,
                thickness,
                layers,
                prepare,
            } => {
                let file = resolver.resolve(PATH_KEY, path)?;
                let mesh = match prepare {
                    None => read_mesh(&file).map_err(|e| {
                        SceneError::new(PATH_KEY, format!("cannot read {path}: {e}"))
                    })?,
                    Some(spec) => {
                        let params = spec.params()?;
                        let scan = skintight_geometry::scan::read_scan(&file, params.max_faces)
                            .map_err(|e| SceneError::new(PATH_KEY, format!("{path}: {e}")))?;
                        let (mesh, prepared) =
                            skintight_geometry::scan::prepare_scan(&scan, &params)
                                .map_err(|e| SceneError::new(PATH_KEY, format!("{path}: {e}")))?;
                        report.warnings.push(format!(
                            "prepared from a raw scan: {} faces, {} holes filled, {} components removed, \
                             mean deviation {:.2} mm, Hausdorff {:.1} mm",
                            prepared.faces,
                            prepared.holes_filled,
                            prepared.components_removed,
                            prepared.mean_deviation_mm,
                            prepared.hausdorff_mm
                        ));
                        mesh
                    }
                };
                let body = body_surface(mesh, &MeshCheckParams::default()).map_err(|issue| {
                    SceneError::new(PATH_KEY, format!("{path} cannot serve as a body: {issue}"))
                })?;
                report.flipped = body.flipped;
                report.warnings.extend(body.warnings);
                let params = ShellParams {
                    thickness: *thickness,
                    layers: *layers,
                    ..ShellParams::default()
                };
                let shell = shell_tetrahedralization(&body.mesh, &params).map_err(shell_error)?;
                report.pinched_vertices = shell.report.pinched_vertices;
                report.shell = Some(shell.report);
                // The shell keeps the surface's vertices as its first vertices, with the same ids.
                let n = body.mesh.num_vertices();
                (shell.mesh, body.mesh, (0..n).collect::<Vec<_>>())
            }
            BodySource::TetMesh { path } => {
                let file = resolver.resolve(PATH_KEY, path)?;
                let mesh = read_tet_mesh(&file)
                    .map_err(|e| SceneError::new(PATH_KEY, format!("cannot read {path}: {e}")))?;
                let (surface, map) = boundary(&mesh, PATH_KEY)?;
                (mesh, surface, map)
            }
            BodySource::Cylinder(p) => {
                let mesh = solid_cylinder(p).map_err(|e| procedural_error(e, false))?;
                let (surface, map) = boundary(&mesh, "body.source")?;
                (mesh, surface, map)
            }
            BodySource::Sphere(p) => {
                let mesh = solid_sphere(p).map_err(|e| procedural_error(e, false))?;
                let (surface, map) = boundary(&mesh, "body.source")?;
                (mesh, surface, map)
            }
        };
        self.apply_fixed(&mut tets)?;
        check_surface_map(&tets, &surface, &surface_tet_vertex)?;
        let quality = tets.quality_stats();
        report.tets = tets.num_tets();
        report.vertices = tets.num_vertices();
        report.fixed = tets.num_fixed();
        report.surface_vertices = surface.num_vertices();
        report.surface_faces = surface.num_faces();
        report.volume = tets.volume();
        report.min_quality = quality.min;
        Ok(BodyModel {
            tets,
            surface,
            surface_tet_vertex,
            material: NeoHookeanParams {
                youngs_modulus: self.material.youngs_modulus,
                poisson_ratio: self.material.poisson_ratio,
                ..NeoHookeanParams::default()
            },
            report,
        })
    }

    /// Applies the `fixed` rule (adding to what the source fixed) and checks that some vertex is fixed.
    fn apply_fixed(&self, tets: &mut TetMesh) -> Result<(), SceneError> {
        let core = match self.source {
            BodySource::Cylinder(_) => Some(Core::Axis),
            BodySource::Sphere(_) => Some(Core::Centre),
            _ => None,
        };
        match (&self.fixed, core) {
            (Some(FixedSpec::Core { fraction }), Some(core)) => {
                let fraction = fraction.unwrap_or(DEFAULT_CORE_FRACTION);
                fix_core(tets, core, fraction).map_err(|e| procedural_error(e, true))?;
            }
            (None, Some(core)) => {
                fix_core(tets, core, DEFAULT_CORE_FRACTION)
                    .map_err(|e| procedural_error(e, true))?;
            }
            (Some(FixedSpec::Region { half_spaces }), _) => {
                let region = Region {
                    label: "body.fixed".to_string(),
                    half_spaces: half_spaces.clone(),
                };
                fix_region(tets, &region).map_err(|e| procedural_error(e, true))?;
            }
            // A surface mesh's core was fixed by the shell; `none` adds nothing; a tet mesh without a region
            // was refused by `validate`.
            _ => {}
        }
        if tets.num_fixed() == 0 {
            return Err(SceneError::new(
                "body.fixed",
                "no body vertex is fixed (the region contains none), so the body could float away; fix a region that contains some vertices",
            ));
        }
        Ok(())
    }
}

/// The outer boundary surface of a tetrahedral mesh and its vertex map, accepted only when it can carry a
/// garment (closed, oriented, one component, manifold, no degenerate face).
fn boundary(mesh: &TetMesh, key: &str) -> Result<(TriMesh, Vec<usize>), SceneError> {
    let b = outer_boundary_surface(mesh).map_err(|e| {
        SceneError::new(
            key,
            format!("cannot extract the body's boundary surface: {e}"),
        )
    })?;
    let check = mesh_report(&b.mesh, &MeshCheckParams::default());
    if let Some(issue) = check.first_blocking() {
        return Err(SceneError::new(
            key,
            format!("the body's boundary surface cannot carry a garment: {issue}"),
        ));
    }
    Ok((b.mesh, b.tet_vertex))
}

/// Checks that every surface vertex names a tetrahedral vertex at the identical position.
fn check_surface_map(tets: &TetMesh, surface: &TriMesh, map: &[usize]) -> Result<(), SceneError> {
    let bad = |msg: String| SceneError::new("body", format!("internal error: {msg}"));
    if map.len() != surface.num_vertices() {
        return Err(bad(format!(
            "{} surface vertices but {} entries in their map to the tetrahedral mesh",
            surface.num_vertices(),
            map.len()
        )));
    }
    for (s, &t) in map.iter().enumerate() {
        match tets.positions.get(t) {
            Some(p) if *p == surface.positions[s] => {}
            Some(_) => {
                return Err(bad(format!(
                    "surface vertex {s} and tetrahedral vertex {t} are at different positions"
                )));
            }
            None => {
                return Err(bad(format!(
                    "surface vertex {s} maps to tetrahedral vertex {t}, which does not exist"
                )));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
