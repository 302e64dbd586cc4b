//! Checking a scene's values: first what cannot be right whatever the body ([`Scene::validate`], per
//! section), then what depends on the built body ([`Scene::validate_against`]). Every error names its key.

use std::collections::{HashMap, HashSet};

use skintight_geometry::math::Real;
use skintight_geometry::region::HalfSpace;

use super::build::BodyModel;
use super::error::SceneError;
use super::spec::{
    BodySource, FabricSpec, FixedSpec, GarmentSpec, PanelShapeSpec, Scene, SceneBody, SolverSpec,
};

impl Scene {
    /// Checks every value that cannot be right whatever the body, naming the first key at fault.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.body.validate()?;
        self.garment.validate()?;
        self.solver.validate()?;
        self.patterns.validate()
    }

    /// Checks what depends on the built body: panel face indices must name faces of the body surface, and no
    /// face may belong to two panels (key `garment.panels[i].faces[j]`).
    pub fn validate_against(&self, body: &BodyModel) -> Result<(), SceneError> {
        let nf = body.surface.num_faces();
        let mut owner: HashMap<usize, usize> = HashMap::new();
        for (i, panel) in self.garment.panels.iter().enumerate() {
            if let PanelShapeSpec::Faces(faces) = &panel.shape {
                for (j, &f) in faces.iter().enumerate() {
                    let key = format!("garment.panels[{i}].faces[{j}]");
                    if f >= nf {
                        return Err(SceneError::new(
                            key,
                            format!(
                                "face {f} does not exist: the body surface has {nf} faces (0 to {})",
                                nf.saturating_sub(1)
                            ),
                        ));
                    }
                    if let Some(&other) = owner.get(&f)
                        && other != i
                    {
                        return Err(SceneError::new(
                            key,
                            format!(
                                "face {f} already belongs to panel '{}'",
                                self.garment.panels[other].name
                            ),
                        ));
                    }
                    owner.insert(f, i);
                }
            }
        }
        Ok(())
    }
}

/// A value in `[lo, hi]` (or `(0, hi]` when `lo` is 0), in `unit`: the sane range of a field, so that no
/// input asks for an absurd amount of work or numbers the solver cannot handle.
pub(crate) fn in_range(
    key: &str,
    x: Real,
    lo: Real,
    hi: Real,
    unit: &str,
) -> Result<(), SceneError> {
    let ok = x.is_finite() && x <= hi && if lo == 0.0 { x > 0.0 } else { x >= lo };
    if !ok {
        let range = if lo == 0.0 {
            format!("(0, {hi}]")
        } else {
            format!("[{lo}, {hi}]")
        };
        return Err(SceneError::new(
            key,
            format!("must lie in {range} ({unit}), got {x}"),
        ));
    }
    Ok(())
}

/// A count in `[min, max]`.
pub(crate) fn count_in(key: &str, n: usize, min: usize, max: usize) -> Result<(), SceneError> {
    if n < min || n > max {
        return Err(SceneError::new(
            key,
            format!("must lie in [{min}, {max}], got {n}"),
        ));
    }
    Ok(())
}

/// Sane ranges of the scene's numbers (docs/SCENE.md, "Ranges").
pub mod ranges {
    /// Lengths of a body (radius, height; half-space offsets), m.
    pub const MAX_BODY_LENGTH: f64 = 10.0;
    /// Shell thickness of a surface-mesh body, m.
    pub const MAX_SHELL_THICKNESS: f64 = 0.5;
    /// Shell layers of a surface-mesh body.
    pub const MAX_SHELL_LAYERS: usize = 16;
    /// Cylinder `radial_segments`, `rings`, `layers`.
    pub const MAX_RADIAL_SEGMENTS: usize = 4096;
    pub const MAX_RINGS: usize = 1024;
    pub const MAX_CYLINDER_LAYERS: usize = 4096;
    /// Sphere `resolution`.
    pub const MAX_SPHERE_RESOLUTION: usize = 256;
    /// Young's modulus of the body, Pa.
    pub const BODY_YOUNGS_MODULUS: (f64, f64) = (1.0, 1e9);
    /// Young's modulus of the fabric, Pa.
    pub const FABRIC_YOUNGS_MODULUS: (f64, f64) = (1.0, 1e12);
    /// Fabric thickness, m.
    pub const MAX_FABRIC_THICKNESS: f64 = 0.05;
    /// Fabric stretch limits (dimensionless).
    pub const MAX_STRETCH: (f64, f64) = (1.0, 10.0);
    /// Interface pressure limit, Pa (1 MPa: far above anything skin bears).
    pub const MAX_PRESSURE_PA: f64 = 1e6;
    /// Cloth edge length, m.
    pub const EDGE_LENGTH: (f64, f64) = (1e-5, 1.0);
    /// Ease (dimensionless).
    pub const MAX_EASE: f64 = 1.0;
    /// Panels of a garment, half-spaces per region.
    pub const MAX_PANELS: usize = 64;
    pub const MAX_HALF_SPACES: usize = 64;
    /// Solver tolerance, N.
    pub const MAX_TOLERANCE: f64 = 1e3;
    /// Solver iterations.
    pub const MAX_SOLVER_ITERATIONS: usize = 10_000;
    /// Solver time limit, s (one day).
    pub const MAX_TIME_LIMIT_S: f64 = 86_400.0;
}

fn check_half_spaces(
    key: &str,
    half_spaces: &[HalfSpace],
    allow_empty: bool,
) -> Result<(), SceneError> {
    if half_spaces.is_empty() && !allow_empty {
        return Err(SceneError::new(key, "give at least one half-space"));
    }
    if half_spaces.len() > ranges::MAX_HALF_SPACES {
        return Err(SceneError::new(
            key,
            format!(
                "give at most {} half-spaces, got {}",
                ranges::MAX_HALF_SPACES,
                half_spaces.len()
            ),
        ));
    }
    for (h, hs) in half_spaces.iter().enumerate() {
        let n = &hs.normal;
        if !(n.x.is_finite() && n.y.is_finite() && n.z.is_finite()) {
            return Err(SceneError::new(
                format!("{key}[{h}].normal"),
                "must have finite components",
            ));
        }
        if n.norm() == 0.0 {
            return Err(SceneError::new(
                format!("{key}[{h}].normal"),
                "must not be the zero vector",
            ));
        }
        if !(hs.offset.is_finite() && hs.offset.abs() <= ranges::MAX_BODY_LENGTH) {
            return Err(SceneError::new(
                format!("{key}[{h}].offset"),
                format!(
                    "must be a finite distance (m) in [-{0}, {0}], got {1}",
                    ranges::MAX_BODY_LENGTH,
                    hs.offset
                ),
            ));
        }
    }
    Ok(())
}

fn poisson(key: &str, nu: Real, lo: Real, lo_open: bool) -> Result<(), SceneError> {
    let ok = nu.is_finite() && nu < 0.5 && if lo_open { nu > lo } else { nu >= lo };
    if !ok {
        let range = if lo_open {
            format!("({lo}, 0.5)")
        } else {
            format!("[{lo}, 0.5)")
        };
        return Err(SceneError::new(
            key,
            format!("Poisson's ratio must lie in {range}, got {nu}"),
        ));
    }
    Ok(())
}

impl SceneBody {
    /// Checks the body's values (see [`Scene::validate`]); keys start with `body.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        match &self.source {
            BodySource::SurfaceMesh {
                path,
                thickness,
                layers,
                prepare,
            } => {
                if let Some(p) = prepare {
                    p.params()?;
                }
                if path.is_empty() {
                    return Err(SceneError::new("body.source.path", "the path is empty"));
                }
                in_range(
                    "body.source.thickness",
                    *thickness,
                    0.0,
                    ranges::MAX_SHELL_THICKNESS,
                    "m",
                )?;
                count_in("body.source.layers", *layers, 1, ranges::MAX_SHELL_LAYERS)?;
            }
            BodySource::TetMesh { path } => {
                if path.is_empty() {
                    return Err(SceneError::new("body.source.path", "the path is empty"));
                }
            }
            BodySource::Cylinder(p) => {
                in_range(
                    "body.source.radius",
                    p.radius,
                    0.0,
                    ranges::MAX_BODY_LENGTH,
                    "m",
                )?;
                in_range(
                    "body.source.height",
                    p.height,
                    0.0,
                    ranges::MAX_BODY_LENGTH,
                    "m",
                )?;
                count_in(
                    "body.source.radial_segments",
                    p.radial_segments,
                    3,
                    ranges::MAX_RADIAL_SEGMENTS,
                )?;
                count_in("body.source.rings", p.rings, 1, ranges::MAX_RINGS)?;
                count_in(
                    "body.source.layers",
                    p.layers,
                    1,
                    ranges::MAX_CYLINDER_LAYERS,
                )?;
            }
            BodySource::Sphere(p) => {
                in_range(
                    "body.source.radius",
                    p.radius,
                    0.0,
                    ranges::MAX_BODY_LENGTH,
                    "m",
                )?;
                count_in(
                    "body.source.resolution",
                    p.resolution,
                    1,
                    ranges::MAX_SPHERE_RESOLUTION,
                )?;
            }
        }
        let (lo, hi) = ranges::BODY_YOUNGS_MODULUS;
        in_range(
            "body.material.youngs_modulus",
            self.material.youngs_modulus,
            lo,
            hi,
            "Pa",
        )?;
        poisson(
            "body.material.poisson_ratio",
            self.material.poisson_ratio,
            -1.0,
            true,
        )?;
        let kind = self.source.kind();
        match (&self.fixed, &self.source) {
            (Some(FixedSpec::Core { fraction: Some(_) }), BodySource::SurfaceMesh { .. }) => {
                return Err(SceneError::new(
                    "body.fixed.fraction",
                    "a surface_mesh body's core is the inner layer of its shell; leave out `fraction`",
                ));
            }
            (Some(FixedSpec::Core { .. }) | None, BodySource::TetMesh { .. }) => {
                return Err(SceneError::new(
                    "body.fixed",
                    "a tet_mesh body has no known core: give `{\"kind\": \"region\", \"half_spaces\": [...]}`",
                ));
            }
            (Some(FixedSpec::Core { fraction: Some(f) }), _)
                if !(f.is_finite() && *f > 0.0 && *f <= 1.0) =>
            {
                return Err(SceneError::new(
                    "body.fixed.fraction",
                    format!("must lie in (0, 1] (a fraction of the radius), got {f}"),
                ));
            }
            (Some(FixedSpec::Region { half_spaces }), _) => {
                check_half_spaces("body.fixed.half_spaces", half_spaces, false)?;
            }
            (Some(FixedSpec::None), BodySource::SurfaceMesh { .. }) => {}
            (Some(FixedSpec::None), _) => {
                return Err(SceneError::new(
                    "body.fixed",
                    format!(
                        "a {kind} body with `none` would have no fixed vertex (it could float away); use `core` or `region`"
                    ),
                ));
            }
            _ => {}
        }
        Ok(())
    }
}

impl GarmentSpec {
    /// Checks the garment's values (see [`Scene::validate`]); keys start with `garment.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        if let Some(t) = &self.template {
            if !self.panels.is_empty() {
                return Err(SceneError::new(
                    "garment.template",
                    "give either panels or a template, not both",
                ));
            }
            t.validate()?;
            return self.validate_cloth();
        }
        if self.panels.is_empty() {
            return Err(SceneError::new(
                "garment.panels",
                "give at least one panel (or a template)",
            ));
        }
        if self.panels.len() > ranges::MAX_PANELS {
            return Err(SceneError::new(
                "garment.panels",
                format!(
                    "give at most {} panels, got {}",
                    ranges::MAX_PANELS,
                    self.panels.len()
                ),
            ));
        }
        let mut names = HashSet::new();
        for (i, panel) in self.panels.iter().enumerate() {
            let key = format!("garment.panels[{i}]");
            if panel.name.trim().is_empty() {
                return Err(SceneError::new(
                    format!("{key}.name"),
                    "a panel needs a non-empty name",
                ));
            }
            if !names.insert(panel.name.as_str()) {
                return Err(SceneError::new(
                    format!("{key}.name"),
                    format!("two panels are named '{}'", panel.name),
                ));
            }
            match &panel.shape {
                PanelShapeSpec::HalfSpaces(h) => {
                    check_half_spaces(&format!("{key}.half_spaces"), h, true)?
                }
                PanelShapeSpec::Faces(faces) => {
                    if faces.is_empty() {
                        return Err(SceneError::new(
                            format!("{key}.faces"),
                            "give at least one face",
                        ));
                    }
                    let mut seen = HashSet::new();
                    for (j, &f) in faces.iter().enumerate() {
                        if !seen.insert(f) {
                            return Err(SceneError::new(
                                format!("{key}.faces[{j}]"),
                                format!("face {f} is listed twice"),
                            ));
                        }
                    }
                }
            }
        }
        self.validate_cloth()
    }

    /// Checks the cloth settings (edge length, ease, fabric, pinned region).
    fn validate_cloth(&self) -> Result<(), SceneError> {
        let (lo, hi) = ranges::EDGE_LENGTH;
        in_range("garment.edge_length", self.edge_length, lo, hi, "m")?;
        if !(self.ease.is_finite() && self.ease > -1.0 && self.ease <= ranges::MAX_EASE) {
            return Err(SceneError::new(
                "garment.ease",
                format!(
                    "must be a finite number in (-1, {}] (e.g. -0.1 for 10 % shorter), got {}",
                    ranges::MAX_EASE,
                    self.ease
                ),
            ));
        }
        self.fabric.validate()?;
        let limits = &self.fabric.limits;
        let (lo, hi) = ranges::MAX_STRETCH;
        in_range(
            "garment.fabric.limits.max_stretch.wale",
            limits.max_stretch.wale,
            lo,
            hi,
            "dimensionless stretch",
        )?;
        in_range(
            "garment.fabric.limits.max_stretch.course",
            limits.max_stretch.course,
            lo,
            hi,
            "dimensionless stretch",
        )?;
        in_range(
            "garment.fabric.limits.max_pressure_pa",
            limits.max_pressure_pa,
            0.0,
            ranges::MAX_PRESSURE_PA,
            "Pa",
        )?;
        let q = limits.min_pattern_quality;
        if !(q.is_finite() && (0.0..1.0).contains(&q)) {
            return Err(SceneError::new(
                "garment.fabric.limits.min_pattern_quality",
                format!("must lie in [0, 1) (1 is an equilateral triangle), got {q}"),
            ));
        }
        if let Some(p) = &self.pinned {
            check_half_spaces("garment.pinned.half_spaces", &p.half_spaces, true)?;
        }
        Ok(())
    }
}

impl SolverSpec {
    /// Checks the solver's values (see [`Scene::validate`]); keys start with `solver.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        in_range(
            "solver.tolerance",
            self.tolerance,
            0.0,
            ranges::MAX_TOLERANCE,
            "N",
        )?;
        count_in(
            "solver.max_iterations",
            self.max_iterations,
            1,
            ranges::MAX_SOLVER_ITERATIONS,
        )?;
        in_range(
            "solver.time_limit_s",
            self.time_limit_s,
            0.0,
            ranges::MAX_TIME_LIMIT_S,
            "s",
        )
    }
}

impl FabricSpec {
    /// Checks the fabric (see [`Scene::validate`]); keys start with `garment.fabric.`: the isotropic
    /// moduli, or the curves (given or named) as a tension law, never both.
    pub fn validate(&self) -> Result<(), SceneError> {
        let curve_key = match (&self.curves, &self.name) {
            (Some(_), Some(_)) => {
                return Err(SceneError::new(
                    "garment.fabric.name",
                    "give either `name` (a library fabric) or `curves`, not both",
                ));
            }
            (Some(_), None) => Some("curves"),
            (None, Some(_)) => Some("name"),
            (None, None) => None,
        };
        if let Some(curve_key) = curve_key {
            for (key, given) in [
                ("youngs_modulus", self.youngs_modulus.is_some()),
                ("poisson_ratio", self.poisson_ratio.is_some()),
                ("thickness", curve_key == "name" && self.thickness.is_some()),
            ] {
                if given {
                    return Err(SceneError::new(
                        format!("garment.fabric.{key}"),
                        format!(
                            "cannot be combined with `{curve_key}`: a curve fabric's stiffness is its curves \
                             (and a named fabric brings its thickness); remove one of the two"
                        ),
                    ));
                }
            }
        }
        if let Some(name) = &self.name
            && super::fabric_library::named_fabric(name).is_none()
        {
            return Err(SceneError::new(
                "garment.fabric.name",
                format!(
                    "unknown fabric `{name}`; the library (fabrics/) has {}",
                    super::fabric_library::fabric_names().join(", ")
                ),
            ));
        }
        in_range(
            "garment.fabric.thickness",
            self.thickness(),
            0.0,
            ranges::MAX_FABRIC_THICKNESS,
            "m",
        )?;
        match self.resolved_curves() {
            Some((c, t)) => {
                skintight_physics::orthotropic_density::OrthotropicDensity::new(
                    &c.course, &c.wale, &c.shear, t,
                )
                .map_err(|e| curve_error(curve_key.unwrap_or("curves"), e))?;
            }
            None => {
                let (lo, hi) = ranges::FABRIC_YOUNGS_MODULUS;
                in_range(
                    "garment.fabric.youngs_modulus",
                    self.youngs_modulus(),
                    lo,
                    hi,
                    "Pa",
                )?;
                poisson(
                    "garment.fabric.poisson_ratio",
                    self.poisson_ratio(),
                    0.0,
                    false,
                )?;
            }
        }
        Ok(())
    }
}

/// The scene error of a curve that is not a tension law: `garment.fabric.curves.course[2]` for a point,
/// `garment.fabric.curves.course` for the whole curve (`garment.fabric.name` for a library fabric).
fn curve_error(
    curve_key: &str,
    e: skintight_physics::orthotropic_density::OrthotropicError,
) -> SceneError {
    use skintight_physics::orthotropic_density::OrthotropicError as O;
    use skintight_physics::tension_curve::CurveError as C;
    let message = e.to_string();
    let key = match (&e, curve_key) {
        (_, "name") => "garment.fabric.name".to_string(),
        (O::Curve { key, source }, _) => match source {
            C::NotFinite { index }
            | C::NegativeElongation { index, .. }
            | C::NotMonotone { index } => format!("garment.fabric.curves.{key}[{index}]"),
            C::TooFewPoints(_) => format!("garment.fabric.curves.{key}"),
        },
        (O::NotConvex { key, .. }, _) => format!("garment.fabric.curves.{key}"),
        (O::Thickness(_), _) => "garment.fabric.thickness".to_string(),
    };
    SceneError::new(key, message)
}
