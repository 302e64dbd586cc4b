//! The scene document's types (docs/SCENE.md), with their defaults, and the flat JSON forms of the tagged
//! ones (read field by field, so that a wrong type names its exact key, then checked for the fields of
//! their kind).

use serde::{Deserialize, Serialize};
use skintight_geometry::body::procedural_body::{CylinderParams, SphereParams};
use skintight_geometry::math::Real;
use skintight_geometry::region::HalfSpace;
use skintight_physics::HessianForm;

use super::fabric_library::FabricCurves;

pub use super::patterns::PatternsSpec;

/// A whole scene: the body, the garment on it and the solver settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The deformable body.
    pub body: SceneBody,
    /// The garment: its panels, cloth resolution, ease and fabric.
    pub garment: GarmentSpec,
    /// Equilibrium solver settings (all defaulted when left out).
    #[serde(default)]
    pub solver: SolverSpec,
    /// The pattern files: allowances, notches, paper, seam truing and the order's text (all defaulted).
    #[serde(default)]
    pub patterns: PatternsSpec,
}

/// The body: where its geometry comes from, its material and which vertices are fixed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneBody {
    /// Where the body's geometry comes from.
    pub source: BodySource,
    /// The body's Neo-Hookean material (defaults: E = 24.78 kPa, ν = 0.49).
    #[serde(default)]
    pub material: BodyMaterial,
    /// Which vertices are fixed (do not move), in addition to those the source fixes itself (the inner layer
    /// of a surface mesh's shell). Left out: the default of the source kind (see [`FixedSpec`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixed: Option<FixedSpec>,
}

/// Where the body's geometry comes from. JSON: an object with `"kind"` and the fields of that kind.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawSource", into = "RawSource")]
pub enum BodySource {
    /// `"surface_mesh"`: a closed body surface (OBJ, PLY, STL or .glb, in metres), filled with a shell of
    /// tetrahedra whose innermost layer is fixed. The surface itself, with its face order, is the surface the
    /// garment lies on.
    SurfaceMesh {
        /// The file (a path relative to the scene file, or an asset id in the HTTP service).
        path: String,
        /// Largest shell thickness (m), reduced locally where the body is thin; default 0.02.
        thickness: Real,
        /// Tetrahedral layers through the thickness (≥ 1); default 2.
        layers: usize,
        /// When present, the file is a raw scan made a body surface first (`skintight body prepare`):
        /// units and up axis found or declared, holes closed, remeshed to `target_faces`. The body's
        /// surface is then the prepared one, so panel `faces` refer to its faces, not the file's.
        prepare: Option<PrepareSpec>,
    },
    /// `"tet_mesh"`: a tetrahedral mesh file (Gmsh `.msh`, MEDIT `.mesh`, TetGen `.node`/`.ele`, in metres).
    /// Its outer boundary surface is the surface the garment lies on. Needs a `fixed` region.
    TetMesh {
        /// The file (a path relative to the scene file, or an asset id in the HTTP service).
        path: String,
    },
    /// `"cylinder"`: a procedural solid cylinder along +y centred at the origin (fields as
    /// [`CylinderParams`]: `radius` m, `height` m, `radial_segments`, `rings`, `layers`; defaults
    /// 0.05, 0.2, 24, 4, 16).
    Cylinder(CylinderParams),
    /// `"sphere"`: a procedural solid ball centred at the origin (fields as [`SphereParams`]: `radius` m,
    /// `resolution`; defaults 0.1, 8).
    Sphere(SphereParams),
}

impl BodySource {
    /// The `kind` of the source as written in JSON (`surface_mesh`, `tet_mesh`, `cylinder`, `sphere`).
    pub fn kind(&self) -> &'static str {
        match self {
            BodySource::SurfaceMesh { .. } => "surface_mesh",
            BodySource::TetMesh { .. } => "tet_mesh",
            BodySource::Cylinder(_) => "cylinder",
            BodySource::Sphere(_) => "sphere",
        }
    }
}

/// Scan preparation of a `surface_mesh` body. JSON: `{"units": "auto", "up": "auto", "target_faces": 24000}`,
/// every field optional.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PrepareSpec {
    /// `mm`, `cm`, `m` or `auto` (from the height, 1.0–2.1 m).
    #[serde(default = "auto")]
    pub units: String,
    /// `x`, `y`, `z`, `-x`, `-y`, `-z` or `auto` (the longest extent).
    #[serde(default = "auto")]
    pub up: String,
    /// Faces of the prepared surface (about), 100–2000000.
    #[serde(default = "default_target_faces")]
    pub target_faces: usize,
}

impl PrepareSpec {
    /// The geometry's settings; errors name `body.source.prepare.<field>`.
    pub fn params(
        &self,
    ) -> Result<skintight_geometry::scan::PrepareParams, super::error::SceneError> {
        use super::error::SceneError;
        use skintight_geometry::scan::units_and_up::{LengthUnit, SignedAxis};
        let units = match self.units.as_str() {
            "auto" => None,
            u => Some(LengthUnit::parse(u).ok_or_else(|| {
                SceneError::new(
                    "body.source.prepare.units",
                    format!("units must be mm, cm, m or auto, got {u:?}"),
                )
            })?),
        };
        let up = match self.up.as_str() {
            "auto" => None,
            u => Some(SignedAxis::parse(u).ok_or_else(|| {
                SceneError::new(
                    "body.source.prepare.up",
                    format!("up must be x, y, z, -x, -y, -z or auto, got {u:?}"),
                )
            })?),
        };
        if !(100..=2_000_000).contains(&self.target_faces) {
            return Err(SceneError::new(
                "body.source.prepare.target_faces",
                format!("must lie in [100, 2000000], got {}", self.target_faces),
            ));
        }
        Ok(skintight_geometry::scan::PrepareParams {
            units,
            up,
            target_faces: self.target_faces,
            ..Default::default()
        })
    }
}

fn auto() -> String {
    "auto".into()
}

fn default_target_faces() -> usize {
    skintight_geometry::scan::DEFAULT_TARGET_FACES
}

/// Default shell thickness of a surface-mesh body (m).
pub const DEFAULT_SHELL_THICKNESS: Real = 0.02;
/// Default number of shell layers of a surface-mesh body.
pub const DEFAULT_SHELL_LAYERS: usize = 2;
/// Default core fraction of procedural bodies (dimensionless).
pub const DEFAULT_CORE_FRACTION: Real = 0.5;

/// Which body vertices are fixed. JSON: `{"kind": "core"}`, `{"kind": "core", "fraction": 0.5}`,
/// `{"kind": "region", "half_spaces": [...]}` or `{"kind": "none"}`.
///
/// The rule adds to what the source fixes itself (the shell's inner layer of a `surface_mesh` body); after
/// it, at least one body vertex must be fixed. Default when `fixed` is left out: `core` for `surface_mesh`
/// (the shell's inner layer), `core` with fraction 0.5 for `cylinder` and `sphere`; a `tet_mesh` body has no
/// default and needs a `region`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawFixed", into = "RawFixed")]
pub enum FixedSpec {
    /// The body's core. `surface_mesh`: the shell's inner layer (no `fraction`). `cylinder`: every vertex
    /// within `fraction · radius` of the axis; `sphere`: within `fraction · radius` of the centre (fraction
    /// dimensionless in (0, 1], default 0.5). Not available for `tet_mesh`.
    Core {
        /// Fraction of the radius (dimensionless, (0, 1]); `None` for the default.
        fraction: Option<Real>,
    },
    /// Every vertex inside the intersection of the half-spaces `n·x ≤ d` (at least one).
    Region {
        /// The half-spaces (`normal` dimensionless, `offset` m).
        half_spaces: Vec<HalfSpace>,
    },
    /// Nothing beyond what the source fixes (allowed only where that is something: `surface_mesh`).
    None,
}

/// The body's compressible Neo-Hookean material.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyMaterial {
    /// Young's modulus E (Pa), finite and > 0; default 24 780 (the thesis body).
    #[serde(default = "default_body_youngs_modulus")]
    pub youngs_modulus: Real,
    /// Poisson's ratio ν (dimensionless), in (−1, 0.5); default 0.49.
    #[serde(default = "default_body_poisson_ratio")]
    pub poisson_ratio: Real,
}

fn default_body_youngs_modulus() -> Real {
    24.78e3
}
fn default_body_poisson_ratio() -> Real {
    0.49
}

impl Default for BodyMaterial {
    fn default() -> Self {
        Self {
            youngs_modulus: default_body_youngs_modulus(),
            poisson_ratio: default_body_poisson_ratio(),
        }
    }
}

/// The garment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GarmentSpec {
    /// The panels (at least one; names unique), or none when `template` is given. Panels must not overlap on
    /// the body surface.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub panels: Vec<ScenePanel>,
    /// A garment template anchored to the body's landmarks, resolved into `panels` once the body is built
    /// (see [`super::template`]); exactly one of `panels` and `template`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub template: Option<TemplateSpec>,
    /// Target edge length of the cloth mesh (m), finite and > 0; should be finer than the body surface.
    pub edge_length: Real,
    /// Uniform scaling of the flattened patterns by `1 + ease` (dimensionless, finite, > −1); default −0.1
    /// (every length 10 % shorter, so no element starts slack).
    #[serde(default = "default_ease")]
    pub ease: Real,
    /// The fabric (defaults: E = 5.4 MPa, ν = 0.33, t = 0.1 mm).
    #[serde(default)]
    pub fabric: FabricSpec,
    /// Optional region whose free-boundary cloth vertices keep their place on the body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pinned: Option<PinnedSpec>,
}

fn default_ease() -> Real {
    -0.1
}

/// One garment panel: a name and the part of the body surface it covers. JSON: `{"name": …, "half_spaces":
/// […]}` or `{"name": …, "faces": […]}` (exactly one of the two).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawPanel", into = "RawPanel")]
pub struct ScenePanel {
    /// Name, unique within the garment, non-empty.
    pub name: String,
    /// The part of the body surface it covers.
    pub shape: PanelShapeSpec,
}

/// The part of the body surface a panel covers.
#[derive(Clone, Debug, PartialEq)]
pub enum PanelShapeSpec {
    /// `"half_spaces"`: the surface inside the intersection of these half-spaces `n·x ≤ d` (the surface is
    /// cut exactly along the planes). An empty list is all of space.
    HalfSpaces(Vec<HalfSpace>),
    /// `"faces"`: these faces of the body surface (indices into the surface mesh's faces, 0-based; for a
    /// `surface_mesh` body, the faces of the input file in file order). At least one, no repeats.
    Faces(Vec<usize>),
}

/// The fabric of every panel: a tension-field Saint-Venant–Kirchhoff membrane (`youngs_modulus`,
/// `poisson_ratio`), or an orthotropic fabric from its test curves (`curves`) or from the fabric library
/// (`name`, the files of `fabrics/`). The isotropic keys and the curve keys do not mix.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FabricSpec {
    /// Young's modulus E (Pa), finite and > 0; default 5.4e6 (read it with [`FabricSpec::youngs_modulus`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub youngs_modulus: Option<Real>,
    /// Poisson's ratio ν (dimensionless), in [0, 0.5); default 0.33. (The tension-field membrane needs
    /// ν ≥ 0.)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub poisson_ratio: Option<Real>,
    /// Thickness t (m), finite and > 0; default 1e-4 (0.1 mm), or the library fabric's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thickness: Option<Real>,
    /// The fabric's test curves (docs/SCENE.md, "Fabric from test curves").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub curves: Option<FabricCurves>,
    /// A fabric of the library shipped in `fabrics/` (see [`crate::scene::fabric_library`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// What the fabric and the wearer can bear; a result beyond them is reported `admissible: false` with
    /// its violations (docs/OUTPUTS.md, "Admissibility").
    #[serde(default)]
    pub limits: FabricLimits,
}

impl FabricSpec {
    /// Young's modulus (Pa): the given one or 5.4e6; for a curve fabric, the isotropic equivalent
    /// `T'(0) / t` of its course curve (what scales the solver's force floor).
    pub fn youngs_modulus(&self) -> Real {
        match self.resolved_curves() {
            Some((curves, t)) => {
                let first = curves.course.iter().find(|p| p[0] > 0.0);
                first.map_or(default_fabric_youngs_modulus(), |p| p[1] / p[0] / t)
            }
            None => self
                .youngs_modulus
                .unwrap_or_else(default_fabric_youngs_modulus),
        }
    }

    /// Poisson's ratio: the given one or 0.33; 0 for a curve fabric (its curves couple no directions).
    pub fn poisson_ratio(&self) -> Real {
        if self.resolved_curves().is_some() {
            return 0.0;
        }
        self.poisson_ratio
            .unwrap_or_else(default_fabric_poisson_ratio)
    }

    /// Thickness (m): the given one, the library fabric's, or 1e-4.
    pub fn thickness(&self) -> Real {
        if let Some(t) = self.thickness {
            return t;
        }
        self.name
            .as_deref()
            .and_then(crate::scene::fabric_library::named_fabric)
            .map_or_else(default_fabric_thickness, |f| f.thickness_m)
    }

    /// The stretch limits the designs and the verdict read (dimensionless, along the wales and the
    /// courses): `limits.max_stretch`, and for a curve fabric no more than where each curve ends
    /// (`1 + ` its last elongation: beyond it the law is an extrapolation nobody measured).
    pub fn stretch_limits(&self) -> StretchLimits {
        let stated = self.limits.max_stretch;
        match self.resolved_curves() {
            Some((c, _)) => {
                let end =
                    |curve: &[[Real; 2]]| 1.0 + curve.iter().map(|p| p[0]).fold(0.0, Real::max);
                StretchLimits {
                    wale: stated.wale.min(end(&c.wale)),
                    course: stated.course.min(end(&c.course)),
                }
            }
            None => stated,
        }
    }

    /// The curves and thickness of a curve fabric (given, or the library's for `name`); `None` for the
    /// isotropic membrane or an unknown name.
    pub fn resolved_curves(&self) -> Option<(FabricCurves, Real)> {
        if let Some(c) = &self.curves {
            return Some((c.clone(), self.thickness()));
        }
        let f = crate::scene::fabric_library::named_fabric(self.name.as_deref()?)?;
        Some((f.curves, f.thickness_m))
    }
}

/// The limits a worn garment must respect to be admissible.
///
/// Defaults: stretch 2.0 along the wales and the courses — the largest in-plane stretch at which the
/// published yarn-level responses of knits were sampled (HYLC / MADYPG, `data/yarns`: `sx`, `sy` up to 1,
/// i.e. λ = 2), beyond which no material law we have is backed by data; interface pressure 60 mmHg
/// (7999 Pa), above the top of RAL-GZ 387 class III (46 mmHg at the ankle) with margin — an order for class
/// IV states its own; pattern triangle shape quality 0.1, below which the simulation mesh is too distorted
/// for its stresses to be trusted.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FabricLimits {
    /// Largest principal-direction stretch along the fabric's wale and course directions (dimensionless,
    /// 1 = unstretched).
    #[serde(default)]
    pub max_stretch: StretchLimits,
    /// Largest interface pressure (Pa) on any cloth triangle; default 7999.32 (60 mmHg).
    #[serde(default = "default_max_pressure_pa")]
    pub max_pressure_pa: Real,
    /// Smallest shape quality `4√3·A / Σ ℓ²` of a pattern triangle (dimensionless, in [0, 1)); default 0.1.
    #[serde(default = "default_min_pattern_quality")]
    pub min_pattern_quality: Real,
}

/// Largest stretch along the fabric's two knit directions (dimensionless, ≥ 1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StretchLimits {
    /// Along the wales: the grain line, which runs along the body (the limb's length); default 2.0.
    #[serde(default = "default_max_stretch")]
    pub wale: Real,
    /// Along the courses: across the grain line (around the limb); default 2.0.
    #[serde(default = "default_max_stretch")]
    pub course: Real,
}

fn default_max_stretch() -> Real {
    2.0
}
fn default_max_pressure_pa() -> Real {
    60.0 * skintight_physics::PA_PER_MMHG
}
fn default_min_pattern_quality() -> Real {
    0.1
}

impl Default for StretchLimits {
    fn default() -> Self {
        Self {
            wale: default_max_stretch(),
            course: default_max_stretch(),
        }
    }
}

impl Default for FabricLimits {
    fn default() -> Self {
        Self {
            max_stretch: StretchLimits::default(),
            max_pressure_pa: default_max_pressure_pa(),
            min_pattern_quality: default_min_pattern_quality(),
        }
    }
}

fn default_fabric_youngs_modulus() -> Real {
    5.4e6
}
fn default_fabric_poisson_ratio() -> Real {
    0.33
}
fn default_fabric_thickness() -> Real {
    1e-4
}

impl Default for FabricSpec {
    fn default() -> Self {
        Self {
            youngs_modulus: None,
            poisson_ratio: None,
            thickness: None,
            curves: None,
            name: None,
            limits: FabricLimits::default(),
        }
    }
}

/// A region of space whose free-boundary cloth vertices stay where they start on the body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinnedSpec {
    /// The half-spaces `n·x ≤ d` whose intersection is the region; an empty list is all of space, which
    /// pins the whole free boundary (both cuffs of a sleeve, say).
    pub half_spaces: Vec<HalfSpace>,
}

/// Which limit surface of the body the cloth slides on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SurfaceKind {
    /// `"loop"`: the Loop subdivision limit surface of the body surface (smooth; the default).
    Loop,
    /// `"linear"`: the flat triangles of the body surface.
    Linear,
}

/// Equilibrium solver settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// The surface the cloth slides on; default `"loop"`.
    #[serde(default = "default_surface")]
    pub surface: SurfaceKind,
    /// Convergence tolerance on the norm of the unbalanced forces (N), finite and > 0; default 1e-6.
    #[serde(default = "default_tolerance")]
    pub tolerance: Real,
    /// Most Newton iterations (≥ 1); default 200.
    #[serde(default = "default_max_iterations")]
    pub max_iterations: usize,
    /// Wall-clock limit of the solve (s), finite and > 0; default 600.
    #[serde(default = "default_time_limit_s")]
    pub time_limit_s: Real,
    /// The matrix Newton factors: `"covariant"` (default; the Hessian without the surface chart's
    /// Christoffel term, equal to it at equilibrium) or `"coordinate"` (the Hessian in the face
    /// coordinates), [`skintight_physics::HessianForm`].
    #[serde(default)]
    pub hessian: HessianForm,
}

fn default_surface() -> SurfaceKind {
    SurfaceKind::Loop
}
fn default_tolerance() -> Real {
    1e-6
}
fn default_max_iterations() -> usize {
    200
}
fn default_time_limit_s() -> Real {
    600.0
}

impl Default for SolverSpec {
    fn default() -> Self {
        Self {
            surface: default_surface(),
            tolerance: default_tolerance(),
            max_iterations: default_max_iterations(),
            time_limit_s: default_time_limit_s(),
            hessian: HessianForm::default(),
        }
    }
}

// ----------------------------------------------------------------------------------------------------------
// The JSON forms of the tagged types: flat objects read field by field (so a wrong type names its exact key),
// then checked for the fields of their kind.

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
enum SourceKind {
    SurfaceMesh,
    TetMesh,
    Cylinder,
    Sphere,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSource {
    kind: Option<SourceKind>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    path: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    thickness: Option<Real>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    layers: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    prepare: Option<PrepareSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    radius: Option<Real>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    height: Option<Real>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    radial_segments: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rings: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    resolution: Option<usize>,
}

/// The message of a field that does not belong to a kind (same shape as serde's, so the key gets the name).
fn not_for_kind(field: &str, kind: &str, allowed: &[&str]) -> String {
    format!(
        "unknown field `{field}`: a `{kind}` takes only {}",
        allowed
            .iter()
            .map(|f| format!("`{f}`"))
            .collect::<Vec<_>>()
            .join(", ")
    )
}

impl TryFrom<RawSource> for BodySource {
    type Error = String;

    fn try_from(r: RawSource) -> Result<Self, String> {
        let kind = r.kind.ok_or(
            "missing field `kind` (one of `surface_mesh`, `tet_mesh`, `cylinder`, `sphere`)",
        )?;
        let given: [(&str, bool); 9] = [
            ("path", r.path.is_some()),
            ("prepare", r.prepare.is_some()),
            ("thickness", r.thickness.is_some()),
            ("layers", r.layers.is_some()),
            ("radius", r.radius.is_some()),
            ("height", r.height.is_some()),
            ("radial_segments", r.radial_segments.is_some()),
            ("rings", r.rings.is_some()),
            ("resolution", r.resolution.is_some()),
        ];
        let (name, allowed): (&str, &[&str]) = match kind {
            SourceKind::SurfaceMesh => {
                ("surface_mesh", &["path", "thickness", "layers", "prepare"])
            }
            SourceKind::TetMesh => ("tet_mesh", &["path"]),
            SourceKind::Cylinder => (
                "cylinder",
                &["radius", "height", "radial_segments", "rings", "layers"],
            ),
            SourceKind::Sphere => ("sphere", &["radius", "resolution"]),
        };
        if let Some((field, _)) = given
            .iter()
            .find(|(f, present)| *present && !allowed.contains(f))
        {
            return Err(not_for_kind(field, name, allowed));
        }
        Ok(match kind {
            SourceKind::SurfaceMesh => BodySource::SurfaceMesh {
                path: r.path.ok_or("missing field `path`")?,
                thickness: r.thickness.unwrap_or(DEFAULT_SHELL_THICKNESS),
                layers: r.layers.unwrap_or(DEFAULT_SHELL_LAYERS),
                prepare: r.prepare,
            },
            SourceKind::TetMesh => BodySource::TetMesh {
                path: r.path.ok_or("missing field `path`")?,
            },
            SourceKind::Cylinder => {
                let d = CylinderParams::default();
                BodySource::Cylinder(CylinderParams {
                    radius: r.radius.unwrap_or(d.radius),
                    height: r.height.unwrap_or(d.height),
                    radial_segments: r.radial_segments.unwrap_or(d.radial_segments),
                    rings: r.rings.unwrap_or(d.rings),
                    layers: r.layers.unwrap_or(d.layers),
                })
            }
            SourceKind::Sphere => {
                let d = SphereParams::default();
                BodySource::Sphere(SphereParams {
                    radius: r.radius.unwrap_or(d.radius),
                    resolution: r.resolution.unwrap_or(d.resolution),
                })
            }
        })
    }
}

impl From<BodySource> for RawSource {
    fn from(s: BodySource) -> Self {
        match s {
            BodySource::SurfaceMesh {
                path,
                thickness,
                layers,
                prepare,
            } => RawSource {
                kind: Some(SourceKind::SurfaceMesh),
                path: Some(path),
                thickness: Some(thickness),
                layers: Some(layers),
                prepare,
                ..RawSource::default()
            },
            BodySource::TetMesh { path } => RawSource {
                kind: Some(SourceKind::TetMesh),
                path: Some(path),
                ..RawSource::default()
            },
            BodySource::Cylinder(p) => RawSource {
                kind: Some(SourceKind::Cylinder),
                radius: Some(p.radius),
                height: Some(p.height),
                radial_segments: Some(p.radial_segments),
                rings: Some(p.rings),
                layers: Some(p.layers),
                ..RawSource::default()
            },
            BodySource::Sphere(p) => RawSource {
                kind: Some(SourceKind::Sphere),
                radius: Some(p.radius),
                resolution: Some(p.resolution),
                ..RawSource::default()
            },
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
enum FixedKind {
    Core,
    Region,
    None,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFixed {
    kind: Option<FixedKind>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fraction: Option<Real>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    half_spaces: Option<Vec<HalfSpace>>,
}

impl TryFrom<RawFixed> for FixedSpec {
    type Error = String;

    fn try_from(r: RawFixed) -> Result<Self, String> {
        let kind = r
            .kind
            .ok_or("missing field `kind` (one of `core`, `region`, `none`)")?;
        match kind {
            FixedKind::Core => {
                if r.half_spaces.is_some() {
                    return Err(not_for_kind("half_spaces", "core", &["fraction"]));
                }
                Ok(FixedSpec::Core {
                    fraction: r.fraction,
                })
            }
            FixedKind::Region => {
                if r.fraction.is_some() {
                    return Err(not_for_kind("fraction", "region", &["half_spaces"]));
                }
                Ok(FixedSpec::Region {
                    half_spaces: r.half_spaces.ok_or("missing field `half_spaces`")?,
                })
            }
            FixedKind::None => {
                if r.fraction.is_some() {
                    return Err(not_for_kind("fraction", "none", &[]));
                }
                if r.half_spaces.is_some() {
                    return Err(not_for_kind("half_spaces", "none", &[]));
                }
                Ok(FixedSpec::None)
            }
        }
    }
}

impl From<FixedSpec> for RawFixed {
    fn from(f: FixedSpec) -> Self {
        match f {
            FixedSpec::Core { fraction } => RawFixed {
                kind: Some(FixedKind::Core),
                fraction,
                half_spaces: None,
            },
            FixedSpec::Region { half_spaces } => RawFixed {
                kind: Some(FixedKind::Region),
                fraction: None,
                half_spaces: Some(half_spaces),
            },
            FixedSpec::None => RawFixed {
                kind: Some(FixedKind::None),
                fraction: None,
                half_spaces: None,
            },
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPanel {
    name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    half_spaces: Option<Vec<HalfSpace>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    faces: Option<Vec<usize>>,
}

impl TryFrom<RawPanel> for ScenePanel {
    type Error = String;

    fn try_from(r: RawPanel) -> Result<Self, String> {
        let shape = match (r.half_spaces, r.faces) {
            (Some(h), None) => PanelShapeSpec::HalfSpaces(h),
            (None, Some(f)) => PanelShapeSpec::Faces(f),
            (None, None) => {
                return Err(format!(
                    "missing field `half_spaces`: panel '{}' needs either `half_spaces` (a region of space) or `faces` (body surface faces)",
                    r.name
                ));
            }
            (Some(_), Some(_)) => {
                return Err(format!(
                    "unknown field `faces`: panel '{}' gives both `half_spaces` and `faces`; give exactly one",
                    r.name
                ));
            }
        };
        Ok(ScenePanel {
            name: r.name,
            shape,
        })
    }
}

impl From<ScenePanel> for RawPanel {
    fn from(p: ScenePanel) -> Self {
        let (half_spaces, faces) = match p.shape {
            PanelShapeSpec::HalfSpaces(h) => (Some(h), None),
            PanelShapeSpec::Faces(f) => (None, Some(f)),
        };
        RawPanel {
            name: p.name,
            half_spaces,
            faces,
        }
    }
}

/// `garment.template` in a scene: which template, on which side, with which options.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TemplateSpec {
    /// The template's name (`knee_high`, `thigh_high`, `leggings`, `calf_sleeve`, `arm_sleeve`, or a shop's).
    pub name: String,
    /// `left` (+x) or `right` for a one-limb template; absent (or `null`) for `legs` templates.
    #[serde(default)]
    pub side: Option<skintight_geometry::anthropometry::Side>,
    /// Overrides of the template's anchors and the bounding margin.
    #[serde(default)]
    pub options: TemplateOptions,
}

/// Options of a template in a scene.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TemplateOptions {
    /// Replaces the template's lower anchor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bottom: Option<Anchor>,
    /// Replaces the template's upper anchor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub top: Option<Anchor>,
    /// Clearance of the bounding planes outside the limb (m), default 0.02.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub margin_m: Option<f64>,
}

/// A position on the limb: the landmark `landmark`, moved `fraction` of the way towards `toward` (if
/// given) and then `offset_m` along the limb axis towards the trunk.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Anchor {
    /// A landmark name of `body measure` (`B`, `B1`, `C`, `D`, `E`, `F`, `G`; `wrist`, `forearm`, `elbow`,
    /// `upper_arm`, `armpit`; for the top of `legs` templates `crotch`, `hip`, `waist`).
    pub landmark: String,
    /// A second landmark of the same limb.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub toward: Option<String>,
    /// Fraction of the way from `landmark` to `toward` (0 = at `landmark`).
    #[serde(default)]
    pub fraction: f64,
    /// Shift along the axis towards the trunk (m; upward for torso landmarks).
    #[serde(default)]
    pub offset_m: f64,
}
