//! The garment's pressure by landmark band (`result.json`'s `regions`): what a fitter measures with a
//! pressure probe at each measuring point of the body (`B`, `B1`, `C`, … on a leg; see
//! `skintight_geometry::anthropometry::landmarks` for where each point lies).
//!
//! A band is the part of the worn garment within [`BAND_HALF_WIDTH`] (m) of a landmark's girth plane,
//! along its normal (the limb axis for a limb landmark, `+y` for the torso), on that landmark's limb or on
//! the torso. Its pressure statistics are over the garment triangles whose centroid lies in the band:
//! `mean` is the area-weighted mean of the triangles' interface pressure (`elements.pressure`, normal
//! force over deformed area, Pa); `min` and `max` are the extremes of the probe pressure
//! (`elements.probe_pressure`) over those triangles — what a 5 cm probe placed anywhere around that girth
//! would read.

use serde::{Deserialize, Serialize};
use skintight_geometry::anthropometry::Side;

/// Half the height of a landmark band along its normal (m): a 5 cm probe centred on the girth.
pub const BAND_HALF_WIDTH: f64 = 0.025;

/// The garment's pressure at one landmark band.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Region {
    /// The landmark's name (`B`, `B1`, `C`, `D`, `E`, `F`, `G`, `crotch`, `hip`, `waist`, `wrist`,
    /// `forearm`, `elbow`, `upper_arm`, `armpit`).
    pub name: String,
    /// The limb's side, `null` for the torso.
    pub side: Option<Side>,
    /// Height of the landmark above the floor (m).
    pub height_m: f64,
    /// The body's girth at the landmark (m).
    pub girth_m: f64,
    /// Deformed garment area in the band (m²).
    pub area_m2: f64,
    /// Interface pressure in the band (Pa).
    pub pressure_pa: PressureRange,
    /// The same in mmHg.
    pub pressure_mmhg: PressureRange,
}

/// Mean, smallest and largest pressure of a band (unit given by the field holding it).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PressureRange {
    /// Area-weighted mean of the triangles' interface pressure.
    pub mean: f64,
    /// Smallest probe pressure in the band.
    pub min: f64,
    /// Largest probe pressure in the band.
    pub max: f64,
}
