//! A sequential colour map for result meshes: dark blue (low) through teal and green to yellow (high),
//! linear interpolation between eight anchors sampled from a perceptually uniform ramp. Colours are linear
//! RGB in `[0, 1]` as glTF's `COLOR_0` expects.

/// Anchors of the ramp at `t = 0, 1/7, …, 1` (linear RGB).
const ANCHORS: [[f32; 3]; 8] = [
    [0.070, 0.004, 0.100],
    [0.090, 0.030, 0.330],
    [0.035, 0.120, 0.420],
    [0.020, 0.240, 0.400],
    [0.025, 0.380, 0.330],
    [0.120, 0.540, 0.180],
    [0.450, 0.700, 0.040],
    [0.950, 0.850, 0.020],
];

/// The colour of `value` on a ramp from `lo` (first anchor) to `hi` (last anchor); values outside are
/// clamped, a non-finite value or an empty range gives the middle colour.
pub fn color(value: f64, lo: f64, hi: f64) -> [f32; 3] {
    let t = if value.is_finite() && hi > lo {
        ((value - lo) / (hi - lo)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let x = t * (ANCHORS.len() - 1) as f64;
    let i = (x.floor() as usize).min(ANCHORS.len() - 2);
    let f = (x - i as f64) as f32;
    let (a, b) = (ANCHORS[i], ANCHORS[i + 1]);
    [0, 1, 2].map(|k| a[k] + f * (b[k] - a[k]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_ends_clamping_and_bad_values() {
        assert_eq!(color(0.0, 0.0, 1.0), ANCHORS[0]);
        assert_eq!(color(1.0, 0.0, 1.0), ANCHORS[7]);
        assert_eq!(color(-5.0, 0.0, 1.0), ANCHORS[0]);
        assert_eq!(color(9.0, 0.0, 1.0), ANCHORS[7]);
        let mid = color(f64::NAN, 0.0, 1.0);
        assert!(mid.iter().all(|c| c.is_finite() && (0.0..=1.0).contains(c)));
        assert_eq!(color(3.0, 2.0, 2.0), mid);
        // Monotone brightness along the ramp.
        let lum = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        for k in 0..20 {
            assert!(
                lum(color(k as f64 / 20.0, 0.0, 1.0))
                    <= lum(color((k + 1) as f64 / 20.0, 0.0, 1.0)) + 1e-6
            );
        }
    }
}
