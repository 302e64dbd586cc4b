//! The scene description: one JSON document saying which body to dress, with which garment, and how to solve
//! for the equilibrium. The command-line tool reads it from a file (paths relative to that file); the HTTP
//! service takes the same document as a job spec, with asset ids in place of paths (see [`PathResolver`]).
//! docs/SCENE.md describes the format field by field.
//!
//! Units are SI: lengths in metres (m), moduli in pascals (Pa), times in seconds (s).
//!
//! Reading a scene has three steps, each naming the key at fault in a [`SceneError`]
//! (e.g. `garment.fabric.poisson_ratio`, `garment.panels[2].faces[5]`):
//! 1. [`Scene::from_json`] parses the document (unknown keys, wrong types and missing fields are errors) and
//!    runs [`Scene::validate`] (impossible values: a negative modulus, ν ≥ 0.5, an empty panel list, …);
//! 2. [`SceneBody::build`] reads or generates the body: a tetrahedral mesh with its fixed vertices, and the
//!    body surface the garment lies on ([`BodyModel`]);
//! 3. [`Scene::validate_against`] checks what depends on that body (panel face indices).
//!
//! Before step 2, a job's size is estimated from the document and checked against [`Limits`]
//! ([`Estimate`], in `cost`), so that no input asks for more memory or time than it may use.
//!
//! Files: `spec` (the document's types, their defaults and JSON forms), `patterns` (the `patterns`
//! section: allowances, notches, paper, the order's text), `json` (reading and writing the document,
//! through [`crate::json_input`]), `validate` (steps 1 and 3), `build` (step 2), `cost` (admission
//! costing), `resolve` (file references), `error` ([`SceneError`]), `template` (garment templates anchored
//! to body landmarks, resolved into panels once the body is built).

mod build;
mod cost;
mod error;
pub mod fabric_library;
mod json;
mod patterns;
mod resolve;
mod spec;
pub mod template;
mod validate;

pub use build::{BodyModel, BodyReport};
pub use cost::{Estimate, Limits, SurfaceSize};
pub use error::SceneError;
pub use fabric_library::FabricCurves;
pub use patterns::{
    CornerSpec, NotchSpec, OrderSpec, PaperSpec, PatternsSpec, SeamAllowanceSpec, today_utc,
};
pub use resolve::{FileResolver, PathResolver};
pub use spec::{
    Anchor, BodyMaterial, BodySource, DEFAULT_CORE_FRACTION, DEFAULT_SHELL_LAYERS,
    DEFAULT_SHELL_THICKNESS, FabricLimits, FabricSpec, FixedSpec, GarmentSpec, PanelShapeSpec,
    PinnedSpec, Scene, SceneBody, ScenePanel, SolverSpec, SurfaceKind, TemplateOptions,
    TemplateSpec,
};

#[cfg(test)]
mod tests;
