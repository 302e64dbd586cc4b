//! Material parameters of the yarn and of yarn–yarn contact, with where each number comes from.
//!
//! The rod is an isotropic elastic rod of circular cross-section of the pattern's radius `r` (the `.pyp`
//! `radius`, from MADYPG/HYLC's data):
//! - axial stiffness `k_s = E π r²` (N), bending stiffness `k_b = E π r⁴/4` (N·m²), twisting stiffness
//!   `k_t = G π r⁴/2` with `G = E/(2(1 + ν))` (N·m²) — the standard elastic-rod constants (Bergou et al.
//!   2008 §4.2);
//! - contact stiffness `k_c = c E r` (J/m²) with the dimensionless factor `c`
//!   ([`YarnParams::contact_factor`]), so that every force of the model scales as `E r²` and the cell's
//!   displacements depend only on `ν`, `c` and the geometry, not on `E` or the size of the pattern.
//!
//! **Sources.** HYLC's own yarn solver constants (Young's modulus, contact stiffness and exact contact law)
//! could not be read: the HYLC repository (git.ista.ac.at/gsperl/HYLC) is not mirrored in the sources this
//! work could reach, and the MADYPG repository (github kamleshbhalui/MADYPG) only consumes the precomputed
//! data. The defaults are therefore this crate's own choices, stated here: `E = 1 MPa` (irrelevant for the
//! displacements, see above), `ν = 0.5` (incompressible fibre material), `c = 1000` (the softest factor of
//! 10, 100, 1000, 10⁴ for which every shared pattern's own rest equilibrium keeps its centrelines at least
//! 0.95 diameters apart — `tests/rest_state.rs`; the published rest states themselves come as close as
//! 0.88 diameters, so HYLC's contact was softer), contact exclusion along the yarn below `π r` of arclength (the arclength of the
//! tightest U-turn, a half circle of diameter `2r`: segments closer along the yarn cannot touch without
//! folding the yarn).
//!
//! **Mass** (for gravity and inertia, [`YarnParams::linear_density`]): `μ = φ ρ π r²` (kg/m), the yarn's
//! cross-section times its fibre volume fraction `φ` times the fibre density `ρ`. Defaults for a typical
//! compression-wear yarn, polyamide 6.6 wrapped around elastane: `ρ = 1140 kg/m³` (polyamide 6.6, the
//! handbook value 1.13–1.15 g/cm³; elastane is 1.15–1.25 g/cm³, so a blend is within 5 % of it) and
//! `φ = 0.6` (the fibre packing fraction of twisted yarns, typically 0.5–0.7: Hearle, Grosberg & Backer,
//! *Structural Mechanics of Fibers, Yarns, and Fabrics*, 1969, ch. 2). For the shared patterns' radius
//! `r = 1 mm` that is `μ = 2.15 g/m` (2150 tex) — the patterns are scaled-up yarns (real hosiery yarns are
//! 2–20 tex at `r` ≈ 0.05–0.15 mm), and the density scales with `r²` as the stiffnesses do.

use serde::{Deserialize, Serialize};

use crate::contact::ContactKernel;

/// Yarn material and contact parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct YarnParams {
    /// Young's modulus `E` of the yarn (Pa).
    pub young_modulus: f64,
    /// Poisson ratio `ν` (dimensionless), for the shear modulus of twisting.
    pub poisson_ratio: f64,
    /// Bending and twisting stiffness relative to a solid elastic rod of the yarn's radius (dimensionless):
    /// `k_b = f E π r⁴/4`, `k_t = f G π r⁴/2`. A yarn is a bundle of fibres that slide on each other when it
    /// bends, so its bending stiffness is far below a solid rod's.
    pub bending_factor: f64,
    /// Contact stiffness factor `c` (dimensionless): `k_c = c E r` (J/m²).
    pub contact_factor: f64,
    /// Contact distance as a multiple of the yarn diameter `2r` (dimensionless; 1 = touching surfaces).
    pub contact_distance_factor: f64,
    /// The contact kernel `φ` ([`crate::contact`]).
    pub contact_kernel: ContactKernel,

    /// Segments of one yarn closer than this arclength gap along the yarn, in radii, never contact
    /// (dimensionless).
    pub contact_exclusion_radii: f64,
    /// Density of the fibre material `ρ` (kg/m³).
    pub fibre_density: f64,
    /// Fibre volume fraction of the yarn's cross-section `φ` (dimensionless, in (0, 1]).
    pub packing_fraction: f64,
}

impl Default for YarnParams {
    fn default() -> Self {
        Self {
            young_modulus: 1.0e6,
            poisson_ratio: 0.5,
            bending_factor: 1.0,
            contact_factor: 1000.0,
            contact_distance_factor: 1.0,
            contact_kernel: ContactKernel::Smooth,
            contact_exclusion_radii: std::f64::consts::PI,
            fibre_density: 1140.0,
            packing_fraction: 0.6,
        }
    }
}

/// The rod and contact stiffnesses for a yarn of radius `r`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RodStiffness {
    /// Axial stiffness `k_s` (N).
    pub stretching: f64,
    /// Bending stiffness `k_b` (N·m²).
    pub bending: f64,
    /// Twisting stiffness `k_t` (N·m²).
    pub twisting: f64,
    /// Contact stiffness `k_c` (J/m²).
    pub contact: f64,
    /// Contact distance `D` (m).
    pub contact_distance: f64,
    /// The contact kernel.
    pub contact_kernel: ContactKernel,
    /// Contact exclusion arclength along a yarn (m).
    pub contact_exclusion: f64,
}

impl YarnParams {
    /// The constants with which MADYPG's generator computed the published `stocktiny`/`stocktiniest`
    /// responses (`generate_yarnmodels/generate.py`, `make_settings`, in github.com/kamleshbhalui/MADYPG,
    /// read 2026-12): Young's modulus `yE = 1e6` Pa, shear modulus `G = 4e5` Pa (so
    /// `ν = yE/(2G) − 1 = 0.25`), contact stiffness `kc` (J/m²; the script sets `1e2`, and `2e2` for its
    /// stretch tests), density `1.2e3` kg/m³ (taken as the whole cross-section's, packing fraction 1),
    /// with Kaldor et al.'s contact kernel. For a yarn of radius `r` (m) the contact factor is
    /// `kc/(yE r)`. The script leaves HYLC's slide constraint on; its form could not be read and this
    /// crate's cell has none (see [`crate::cell_check`] for how the comparison treats sliding). Not in the script, so this crate's: the bending factor 1 (solid rod), the contact
    /// distance `2r` and the exclusion arclength `π r`. The script also sets `gamma = 1`, `extpx = 1.6`,
    /// `extpy = 1.8`, whose meaning lives in HYLC's solver, not readable here.
    pub fn madypg_generator(radius: f64, contact_stiffness: f64) -> Self {
        let (young, shear) = (1.0e6, 4.0e5);
        Self {
            young_modulus: young,
            poisson_ratio: young / (2.0 * shear) - 1.0,
            bending_factor: 1.0,
            contact_factor: contact_stiffness / (young * radius),
            contact_kernel: ContactKernel::Kaldor,
            fibre_density: 1.2e3,
            packing_fraction: 1.0,
            ..Self::default()
        }
    }

    /// The stiffnesses for yarn radius `r` (m).
    pub fn stiffness(&self, r: f64) -> RodStiffness {
        let e = self.young_modulus;
        let g = e / (2.0 * (1.0 + self.poisson_ratio));
        let pi = std::f64::consts::PI;
        RodStiffness {
            stretching: e * pi * r * r,
            bending: self.bending_factor * e * pi * r.powi(4) / 4.0,
            twisting: self.bending_factor * g * pi * r.powi(4) / 2.0,
            contact: self.contact_factor * e * r,
            contact_distance: self.contact_distance_factor * 2.0 * r,
            contact_kernel: self.contact_kernel,
            contact_exclusion: self.contact_exclusion_radii * r,
        }
    }

    /// Mass per unit length `μ = φ ρ π r²` (kg/m) of a yarn of radius `r` (m).
    pub fn linear_density(&self, r: f64) -> f64 {
        self.packing_fraction * self.fibre_density * std::f64::consts::PI * r * r
    }

    /// Checks that every parameter is finite and in range; the message says which is not.
    pub fn validate(&self) -> Result<(), String> {
        let checks = [
            (
                "young_modulus",
                self.young_modulus,
                self.young_modulus > 0.0,
            ),
            (
                "poisson_ratio",
                self.poisson_ratio,
                self.poisson_ratio > -1.0 && self.poisson_ratio <= 0.5,
            ),
            (
                "contact_factor",
                self.contact_factor,
                self.contact_factor >= 0.0,
            ),
            (
                "contact_distance_factor",
                self.contact_distance_factor,
                self.contact_distance_factor > 0.0,
            ),
            (
                "contact_exclusion_radii",
                self.contact_exclusion_radii,
                self.contact_exclusion_radii >= 0.0,
            ),
            (
                "fibre_density",
                self.fibre_density,
                self.fibre_density > 0.0,
            ),
            (
                "packing_fraction",
                self.packing_fraction,
                self.packing_fraction > 0.0 && self.packing_fraction <= 1.0,
            ),
        ];
        for (name, v, ok) in checks {
            if !v.is_finite() || !ok {
                return Err(format!("yarn parameter {name} = {v} is out of range"));
            }
        }
        Ok(())
    }
}
