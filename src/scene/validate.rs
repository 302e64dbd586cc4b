//! Checking a scene's values: first what cannot be right whatever the body ([`Scene::validate`], per
//! section), then what depends on the built body ([`Scene::validate_against`]). Every error names its key.

use std::collections::{HashMap, HashSet};

use skintight_geometry::math::Real;
use skintight_geometry::region::HalfSpace;

use super::build::BodyModel;
use super::error::SceneError;
use super::spec::{
    BodySource, FixedSpec, GarmentSpec, PanelShapeSpec, Scene, SceneBody, SolverSpec,
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

fn positive(key: &str, x: Real, unit: &str) -> Result<(), SceneError> {
    if !x.is_finite() || x <= 0.0 {
        return Err(SceneError::new(
            key,
            format!("must be a finite number greater than 0 ({unit}), got {x}"),
        ));
    }
    Ok(())
}

fn at_least(key: &str, n: usize, min: usize) -> Result<(), SceneError> {
    if n < min {
        return Err(SceneError::new(
            key,
            format!("must be at least {min}, got {n}"),
        ));
    }
    Ok(())
}

fn check_half_spaces(
    key: &str,
    half_spaces: &[HalfSpace],
    allow_empty: bool,
) -> Result<(), SceneError> {
    if half_spaces.is_empty() && !allow_empty {
        return Err(SceneError::new(key, "give at least one half-space"));
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
        if !hs.offset.is_finite() {
            return Err(SceneError::new(
                format!("{key}[{h}].offset"),
                "must be a finite distance (m)",
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
            } => {
                if path.is_empty() {
                    return Err(SceneError::new("body.source.path", "the path is empty"));
                }
                positive("body.source.thickness", *thickness, "m")?;
                at_least("body.source.layers", *layers, 1)?;
            }
            BodySource::TetMesh { path } => {
                if path.is_empty() {
                    return Err(SceneError::new("body.source.path", "the path is empty"));
                }
            }
            BodySource::Cylinder(p) => {
                positive("body.source.radius", p.radius, "m")?;
                positive("body.source.height", p.height, "m")?;
                at_least("body.source.radial_segments", p.radial_segments, 3)?;
                at_least("body.source.rings", p.rings, 1)?;
                at_least("body.source.layers", p.layers, 1)?;
            }
            BodySource::Sphere(p) => {
                positive("body.source.radius", p.radius, "m")?;
                at_least("body.source.resolution", p.resolution, 1)?;
            }
        }
        positive(
            "body.material.youngs_modulus",
            self.material.youngs_modulus,
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
        if self.panels.is_empty() {
            return Err(SceneError::new("garment.panels", "give at least one panel"));
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
        positive("garment.edge_length", self.edge_length, "m")?;
        if !(self.ease.is_finite() && self.ease > -1.0) {
            return Err(SceneError::new(
                "garment.ease",
                format!(
                    "must be a finite number greater than -1 (e.g. -0.1 for 10 % shorter), got {}",
                    self.ease
                ),
            ));
        }
        positive(
            "garment.fabric.youngs_modulus",
            self.fabric.youngs_modulus,
            "Pa",
        )?;
        poisson(
            "garment.fabric.poisson_ratio",
            self.fabric.poisson_ratio,
            0.0,
            false,
        )?;
        positive("garment.fabric.thickness", self.fabric.thickness, "m")?;
        if let Some(p) = &self.pinned {
            check_half_spaces("garment.pinned.half_spaces", &p.half_spaces, true)?;
        }
        Ok(())
    }
}

impl SolverSpec {
    /// Checks the solver's values (see [`Scene::validate`]); keys start with `solver.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        positive("solver.tolerance", self.tolerance, "N")?;
        at_least("solver.max_iterations", self.max_iterations, 1)?;
        positive("solver.time_limit_s", self.time_limit_s, "s")
    }
}
