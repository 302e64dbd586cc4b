//! The compression prescription verdict (`result.json`'s `prescription`): the garment's measured band
//! pressures ([`super::regions`]) against a compression class and its pressure profile.

use serde::{Deserialize, Serialize};
use skintight_geometry::anthropometry::Side;

/// The verdict of a garment against its prescription.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PrescriptionVerdict {
    /// The standard (`RAL-GZ 387`, `BS 6612`, `ASQUAL`), or `custom`.
    pub standard: String,
    /// The compression class (1–4).
    pub class: u8,
    /// The class window at the ankle, point `B` (mmHg), `[low, high]`.
    pub window_mmhg: [f64; 2],
    /// The measured pressure at `B` (band mean, mmHg); `null` when the garment does not reach `B`.
    pub measured_b_mmhg: Option<f64>,
    /// Every prescribed band, from the ankle up.
    pub bands: Vec<BandVerdict>,
    /// Whether `B` is inside the class window and every band inside its profile window.
    pub pass: bool,
}

/// One prescribed band.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BandVerdict {
    /// The landmark's name (`B`, `B1`, `C`, `D`, `E`, `F`, `G`).
    pub name: String,
    /// The leg.
    pub side: Option<Side>,
    /// The measured band mean (mmHg); `null` when the garment does not cover the band.
    pub measured_mmhg: Option<f64>,
    /// The prescribed window (mmHg), `[low, high]`: the class window at `B`, elsewhere the profile's
    /// percentages of the measured `B` pressure.
    pub window_mmhg: [f64; 2],
    /// Whether the measured value lies in the window.
    pub pass: bool,
}
