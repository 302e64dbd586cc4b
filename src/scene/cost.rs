//! Admission costing: the size of a job estimated from its spec before anything is built, and the limits
//! a job must stay within ([`Limits`]; the service takes them from its `[jobs]` configuration, the CLI
//! uses [`Limits::default`], the same values as `config/default.toml`).
//!
//! The estimate is an upper bound of the usual case, cheap to compute (no mesh is built):
//!
//! - **cloth triangles** `≈ 4 A / h²` with `A` the area of the whole body surface (m², an upper bound of the
//!   garment's area: panels do not overlap) and `h` = `garment.edge_length` (m) — twice the count of
//!   equilateral triangles of side `h`, which is what the remesher's graded meshes measure;
//! - **boundary samples** `≈ P / h`, `P` an upper bound of the panels' boundary length: `2π D` per
//!   half-space of each panel (`D` the body's bounding-box diagonal, m) and three edges of the mean body
//!   face per listed face;
//! - **cloth vertices** `≈ triangles / 2 + samples`; **body vertices and tetrahedra** exactly for the
//!   procedural bodies, `vertices · (layers + 1)` and `3 · faces · layers` for a surface-mesh shell;
//! - **unknowns** `2 · cloth vertices + 3 · body vertices` (surface coordinates of the cloth, positions of
//!   the body);
//! - **memory** (bytes) `64 MiB + 10 kB · n · max(1, (n / 10⁴)^{1/3})` for `n` unknowns: measured 57 MB peak
//!   for the 4650 unknowns of `examples/cylinder.json`, with the growth of a sparse Cholesky factor of a
//!   3D mesh;
//! - **Newton iteration budget**: `solver.max_iterations` per equilibrium, times the design iterations
//!   plus one for a design job.
//!
//! [`Estimate::check`] compares each figure with its limit and names the spec field that drives it
//! (`garment.edge_length` for the cloth, the body's resolution field for the body) and the limit's
//! configuration key.

use serde::Serialize;

use skintight_geometry::body::tet_io::read_tet_mesh;
use skintight_geometry::mesh::io::read_mesh;
use skintight_geometry::{TriMesh, outer_boundary_surface};

use super::error::SceneError;
use super::resolve::PathResolver;
use super::spec::{BodySource, PanelShapeSpec, Scene};

/// The largest job a server (or the CLI) accepts; every figure of an [`Estimate`] must stay within its
/// limit. Keys of the service's `[jobs]` configuration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Limits {
    /// `jobs.max_cloth_triangles`.
    pub max_cloth_triangles: u64,
    /// `jobs.max_boundary_samples`.
    pub max_boundary_samples: u64,
    /// `jobs.max_body_tets`.
    pub max_body_tets: u64,
    /// `jobs.max_unknowns`.
    pub max_unknowns: u64,
    /// `jobs.max_estimated_memory_bytes` (estimated peak memory, bytes).
    pub max_estimated_memory_bytes: u64,
    /// `jobs.max_newton_iterations` (the whole job's Newton iteration budget).
    pub max_newton_iterations: u64,
    /// The memory limit of the process the job runs in, bytes: `jobs.max_memory_bytes` where jobs run in
    /// their own process (`jobs.isolation = "process"`, `RLIMIT_AS`), `u64::MAX` where nothing limits it
    /// (the CLI, jobs on threads). A job estimated above it would only be killed `out_of_memory`.
    pub max_process_memory_bytes: u64,
}

impl Default for Limits {
    /// The defaults of `config/default.toml`.
    fn default() -> Self {
        Limits {
            max_cloth_triangles: 1_000_000,
            max_boundary_samples: 200_000,
            max_body_tets: 2_000_000,
            max_unknowns: 2_000_000,
            max_estimated_memory_bytes: 8 << 30,
            max_newton_iterations: 1_000_000,
            max_process_memory_bytes: u64::MAX,
        }
    }
}

/// What is known of the body surface before the body is built: its area (m²), bounding-box diagonal (m),
/// vertex and face counts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SurfaceSize {
    pub area: f64,
    pub diameter: f64,
    pub vertices: u64,
    pub faces: u64,
    /// The body's vertex and tetrahedron counts where they are known without building it (a tetrahedral
    /// mesh file).
    pub known_body: Option<(u64, u64)>,
}

impl SurfaceSize {
    /// The size of a surface mesh.
    pub fn of_mesh(mesh: &TriMesh) -> SurfaceSize {
        let diameter = mesh.bounding_box().map_or(0.0, |(lo, hi)| (hi - lo).norm());
        SurfaceSize {
            area: mesh.area(),
            diameter,
            vertices: mesh.num_vertices() as u64,
            faces: mesh.num_faces() as u64,
            known_body: None,
        }
    }

    /// The size of the surface a raw scan will be prepared into: the scan's area and diameter in metres
    /// (its units as declared or detected; as read when they cannot be told) and 1.5 × `target_faces` faces
    /// (preparation grades the edges by curvature after a uniform remesh of `target_faces`: measured
    /// 1.28–1.38 × on the 12k bodies' scans, so the estimate stays an upper bound).
    pub fn of_prepared(scan: &TriMesh, spec: &crate::scene::spec::PrepareSpec) -> SurfaceSize {
        use skintight_geometry::scan::units_and_up::{LengthUnit, SignedAxis, detect_frame};
        let units = LengthUnit::parse(&spec.units);
        let up = SignedAxis::parse(&spec.up);
        let scale = detect_frame(&scan.positions, &scan.faces, units, up).map_or(1.0, |f| f.scale);
        let raw = SurfaceSize::of_mesh(scan);
        let faces = (spec.target_faces as u64).saturating_mul(3) / 2;
        SurfaceSize {
            area: raw.area * scale * scale,
            diameter: raw.diameter * scale,
            vertices: faces / 2 + 2,
            faces,
            known_body: None,
        }
    }

    /// The size of a procedural body's surface from its parameters; `None` for bodies read from files.
    pub fn of_procedural(source: &BodySource) -> Option<SurfaceSize> {
        use std::f64::consts::PI;
        match source {
            BodySource::Cylinder(p) => {
                let (r, h) = (p.radius, p.height);
                let rim = p.radial_segments.max(3) as f64;
                let disk = (p.radial_segments as f64 + 3.0) * (p.rings as f64 + 1.0) + 1.0;
                Some(SurfaceSize {
                    area: 2.0 * PI * r * h + 2.0 * PI * r * r,
                    diameter: (4.0 * r * r + h * h).sqrt(),
                    vertices: (rim * (p.layers as f64 + 1.0) + 2.0 * disk) as u64,
                    faces: (2.0 * rim * p.layers as f64 + 4.0 * disk) as u64,
                    known_body: None,
                })
            }
            BodySource::Sphere(p) => {
                let n = p.resolution as f64;
                Some(SurfaceSize {
                    area: 4.0 * PI * p.radius * p.radius,
                    diameter: 2.0 * p.radius,
                    vertices: (6.0 * n * n + 2.0) as u64,
                    faces: (12.0 * n * n) as u64,
                    known_body: None,
                })
            }
            BodySource::SurfaceMesh { .. } | BodySource::TetMesh { .. } => None,
        }
    }
}

impl Scene {
    /// The size of the body surface: from the parameters of a procedural body, or read from the body's
    /// file through `resolver` (a mesh is read, nothing is built). Errors name `body.source.path`.
    pub fn body_size(&self, resolver: &dyn PathResolver) -> Result<SurfaceSize, SceneError> {
        const KEY: &str = "body.source.path";
        match &self.body.source {
            BodySource::SurfaceMesh { path, prepare, .. } => {
                let file = resolver.resolve(KEY, path)?;
                let mesh = read_mesh(&file)
                    .map_err(|e| SceneError::new(KEY, format!("cannot read {path}: {e}")))?;
                Ok(match prepare {
                    Some(spec) => SurfaceSize::of_prepared(&mesh, spec),
                    None => SurfaceSize::of_mesh(&mesh),
                })
            }
            BodySource::TetMesh { path } => {
                let file = resolver.resolve(KEY, path)?;
                let mesh = read_tet_mesh(&file)
                    .map_err(|e| SceneError::new(KEY, format!("cannot read {path}: {e}")))?;
                let b = outer_boundary_surface(&mesh).map_err(|e| {
                    SceneError::new(
                        KEY,
                        format!("cannot extract the body's boundary surface: {e}"),
                    )
                })?;
                let mut size = SurfaceSize::of_mesh(&b.mesh);
                size.known_body = Some((mesh.num_vertices() as u64, mesh.num_tets() as u64));
                Ok(size)
            }
            source => SurfaceSize::of_procedural(source)
                .ok_or_else(|| SceneError::new("body.source", "unknown body source")),
        }
    }
}

/// The estimated size of a job (see the module documentation for the formulas). Counts are `f64` so
/// that absurd inputs cannot overflow.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Estimate {
    pub cloth_triangles: f64,
    pub boundary_samples: f64,
    pub cloth_vertices: f64,
    pub body_vertices: f64,
    pub body_tets: f64,
    pub unknowns: f64,
    /// Bytes.
    pub memory_bytes: f64,
    pub newton_iterations: f64,
    /// The spec field that sets the body's size (`body.source.layers`, `body.source.resolution`, …).
    #[serde(skip)]
    pub body_field: &'static str,
}

/// The body's vertex and tetrahedron counts and the field that drives them.
fn body_size(source: &BodySource, surface: &SurfaceSize) -> (f64, f64, &'static str) {
    match source {
        BodySource::Cylinder(p) => {
            let disk_v = (p.radial_segments as f64 + 3.0) * (p.rings as f64 + 1.0) + 1.0;
            let disk_t = p.radial_segments as f64 * p.rings as f64;
            let layers = p.layers as f64;
            // The field furthest above its default (24, 4, 16) is the one to change.
            let field = [
                (
                    p.radial_segments as f64 / 24.0,
                    "body.source.radial_segments",
                ),
                (p.rings as f64 / 4.0, "body.source.rings"),
                (layers / 16.0, "body.source.layers"),
            ]
            .into_iter()
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map_or("body.source", |(_, f)| f);
            (disk_v * (layers + 1.0), 3.0 * disk_t * layers, field)
        }
        BodySource::Sphere(p) => {
            let n = p.resolution as f64;
            ((n + 1.0).powi(3), 6.0 * n.powi(3), "body.source.resolution")
        }
        BodySource::SurfaceMesh { layers, .. } => {
            let l = *layers as f64;
            (
                surface.vertices as f64 * (l + 1.0),
                3.0 * surface.faces as f64 * l,
                "body.source.layers",
            )
        }
        // Read from a file: its size is what the file holds.
        BodySource::TetMesh { .. } => {
            let (v, t) = surface
                .known_body
                .unwrap_or((surface.vertices, surface.faces));
            (v as f64, t as f64, "body.source.path")
        }
    }
}

impl Estimate {
    /// The estimate of a scene on a body surface of size `surface`, with `equilibria` equilibrium solves
    /// (1 for a simulation; design iterations + 1 for a design).
    pub fn of_scene(scene: &Scene, surface: &SurfaceSize, equilibria: f64) -> Estimate {
        let h = scene.garment.edge_length;
        let cloth_triangles = 4.0 * surface.area / (h * h);
        let mean_edge = if surface.faces > 0 {
            (4.0 * surface.area / (3f64.sqrt() * surface.faces as f64)).sqrt()
        } else {
            0.0
        };
        let perimeter: f64 = scene
            .garment
            .panels
            .iter()
            .map(|p| match &p.shape {
                PanelShapeSpec::HalfSpaces(hs) => {
                    hs.len().max(1) as f64 * 2.0 * std::f64::consts::PI * surface.diameter
                }
                PanelShapeSpec::Faces(f) => f.len() as f64 * 3.0 * mean_edge,
            })
            .sum::<f64>()
            // A template resolves into two panels of about eight half-spaces each.
            + if scene.garment.template.is_some() {
                2.0 * 8.0 * 2.0 * std::f64::consts::PI * surface.diameter
            } else {
                0.0
            };
        let boundary_samples = perimeter / h;
        let cloth_vertices = cloth_triangles / 2.0 + boundary_samples;
        let (body_vertices, body_tets, body_field) = body_size(&scene.body.source, surface);
        let unknowns = 2.0 * cloth_vertices + 3.0 * body_vertices;
        let memory_bytes = 64.0 * 1048576.0 + 1.0e4 * unknowns * (unknowns / 1.0e4).cbrt().max(1.0);
        Estimate {
            cloth_triangles,
            boundary_samples,
            cloth_vertices,
            body_vertices,
            body_tets,
            unknowns,
            memory_bytes,
            newton_iterations: scene.solver.max_iterations as f64 * equilibria,
            body_field,
        }
    }

    /// Checks every figure against `limits`; the error names the spec field to change and, in its message,
    /// the estimate and the limit's configuration key.
    pub fn check(&self, limits: &Limits) -> Result<(), SceneError> {
        let cloth = "garment.edge_length";
        // Which side dominates the unknowns (and the memory).
        let unknowns_field = if 2.0 * self.cloth_vertices >= 3.0 * self.body_vertices {
            cloth
        } else {
            self.body_field
        };
        let fix = |field: &str| {
            if field == cloth {
                "use a larger garment.edge_length".to_string()
            } else {
                format!("use a smaller {field}")
            }
        };
        let checks: [(&str, &str, f64, u64, &str); 7] = [
            (
                self.body_field,
                "body tetrahedra",
                self.body_tets,
                limits.max_body_tets,
                "jobs.max_body_tets",
            ),
            (
                cloth,
                "cloth triangles",
                self.cloth_triangles,
                limits.max_cloth_triangles,
                "jobs.max_cloth_triangles",
            ),
            (
                cloth,
                "pattern boundary samples",
                self.boundary_samples,
                limits.max_boundary_samples,
                "jobs.max_boundary_samples",
            ),
            (
                unknowns_field,
                "unknowns",
                self.unknowns,
                limits.max_unknowns,
                "jobs.max_unknowns",
            ),
            (
                unknowns_field,
                "bytes of memory",
                self.memory_bytes,
                limits.max_estimated_memory_bytes,
                "jobs.max_estimated_memory_bytes",
            ),
            (
                unknowns_field,
                "bytes of memory",
                self.memory_bytes,
                limits.max_process_memory_bytes,
                "jobs.max_memory_bytes, the memory limit of a job's process",
            ),
            (
                "solver.max_iterations",
                "Newton iterations in all",
                self.newton_iterations,
                limits.max_newton_iterations,
                "jobs.max_newton_iterations",
            ),
        ];
        for (field, what, value, limit, key) in checks {
            // NaN (an estimate of nonsense) is refused too.
            if value.is_nan() || value > limit as f64 {
                return Err(SceneError::new(
                    field,
                    format!(
                        "the job would need about {value:.3e} {what}, more than the limit of {limit} \
                         ({key}); {}",
                        fix(field)
                    ),
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    fn cylinder() -> Scene {
        Scene::from_json(
            &std::fs::read_to_string(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/examples/cylinder.json"
            ))
            .unwrap(),
        )
        .unwrap()
    }

    #[test]
    fn the_cylinder_example_is_within_the_defaults_and_bounds_its_real_size() {
        let scene = cylinder();
        let surface = SurfaceSize::of_procedural(&scene.body.source).unwrap();
        let e = Estimate::of_scene(&scene, &surface, 1.0);
        e.check(&Limits::default()).unwrap();
        // The real job: 2651 cloth triangles, 4608 tetrahedra, 4650 unknowns, 57 MB peak.
        assert!((2651.0..4.0 * 2651.0).contains(&e.cloth_triangles), "{e:?}");
        assert_eq!(e.body_tets, 4608.0);
        assert!((4650.0..4.0 * 4650.0).contains(&e.unknowns), "{e:?}");
        assert!((57e6..1e9).contains(&e.memory_bytes), "{e:?}");
    }

    #[test]
    fn a_tiny_edge_length_is_refused_naming_it_and_the_limit() {
        let mut scene = cylinder();
        scene.garment.edge_length = 1e-4;
        let surface = SurfaceSize::of_procedural(&scene.body.source).unwrap();
        let err = Estimate::of_scene(&scene, &surface, 1.0)
            .check(&Limits::default())
            .unwrap_err();
        assert_eq!(err.key, "garment.edge_length");
        assert!(err.message.contains("jobs.max_cloth_triangles"), "{err}");
    }

    #[test]
    fn a_fine_body_is_refused_naming_its_resolution_field() {
        let mut scene = cylinder();
        if let BodySource::Cylinder(p) = &mut scene.body.source {
            p.layers = 4000;
            p.radial_segments = 400;
        }
        let surface = SurfaceSize::of_procedural(&scene.body.source).unwrap();
        let err = Estimate::of_scene(&scene, &surface, 1.0)
            .check(&Limits::default())
            .unwrap_err();
        assert_eq!(err.key, "body.source.layers", "{err}");
        assert!(err.message.contains("jobs.max_body_tets"), "{err}");
    }

    #[test]
    fn the_iteration_budget_counts_every_equilibrium() {
        let scene = cylinder();
        let surface = SurfaceSize::of_procedural(&scene.body.source).unwrap();
        let limits = Limits {
            max_newton_iterations: 1000,
            ..Limits::default()
        };
        Estimate::of_scene(&scene, &surface, 5.0)
            .check(&limits)
            .unwrap();
        let err = Estimate::of_scene(&scene, &surface, 6.0)
            .check(&limits)
            .unwrap_err();
        assert_eq!(err.key, "solver.max_iterations");
    }

    #[test]
    fn the_process_memory_limit_refuses_what_the_estimate_limit_allows() {
        let scene = cylinder();
        let surface = SurfaceSize::of_procedural(&scene.body.source).unwrap();
        let e = Estimate::of_scene(&scene, &surface, 1.0);
        let limits = Limits {
            max_process_memory_bytes: (e.memory_bytes * 0.5) as u64,
            ..Limits::default()
        };
        let err = e.check(&limits).unwrap_err();
        assert!(err.message.contains("jobs.max_memory_bytes"), "{err}");
        assert_eq!(err.key, "garment.edge_length", "{err}");
    }
}
