//! Interface pressure as a pressure probe reads it: the cloth's pressure averaged over a disk.
//!
//! A triangle's own pressure (its normal force over its deformed area, Pa) varies from triangle to triangle
//! by more than the garment's real pressure does — the discrete normal force of a membrane on a curved
//! surface is noisy at the scale of one element, most near free edges. What a fitter measures, and what
//! compression limits refer to, is the pressure under a probe: the PicoPress sensor used to measure
//! compression garments on the leg is a flat bladder of 5 cm diameter. So for every cloth triangle `t`
//! with centroid `c_t` (m) this computes
//!
//! `p̄_t = Σ_{s : |c_s − c_t| ≤ r} A_s p_s / Σ_{s : |c_s − c_t| ≤ r} A_s`   (Pa),
//!
//! the area-weighted mean of the pressures `p_s` (Pa) of the triangles `s` (deformed areas `A_s`, m²) whose
//! centroids lie within `r` = [`PROBE_RADIUS`] of `c_t` (3D distance: on a limb, a 2.5 cm ball cuts the
//! surface in nearly the probe's disk). Neighbours are found through a uniform grid of cell `r`, so the
//! cost is linear in the number of triangles.

use std::collections::HashMap;

use skintight_geometry::Vec3;

/// Radius of the probe's disk (m): 2.5 cm, the PicoPress sensor's 5 cm diameter.
pub const PROBE_RADIUS: f64 = 0.025;

/// `#F` probe pressures (Pa) of triangles with centroids `centroids` (m), pressures `pressure` (Pa) and
/// deformed areas `area` (m²), averaged within `radius` (m, > 0). A triangle whose neighbourhood has no
/// area keeps its own pressure.
pub fn probe_pressure(centroids: &[Vec3], pressure: &[f64], area: &[f64], radius: f64) -> Vec<f64> {
    let cell = |p: &Vec3| {
        [
            (p.x / radius).floor() as i64,
            (p.y / radius).floor() as i64,
            (p.z / radius).floor() as i64,
        ]
    };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (s, c) in centroids.iter().enumerate() {
        if c.iter().all(|x| x.is_finite()) {
            grid.entry(cell(c)).or_default().push(s);
        }
    }
    let r2 = radius * radius;
    centroids
        .iter()
        .enumerate()
        .map(|(t, c)| {
            if !c.iter().all(|x| x.is_finite()) {
                return pressure[t];
            }
            let [i, j, k] = cell(c);
            let (mut force, mut total) = (0.0, 0.0);
            for di in -1..=1 {
                for dj in -1..=1 {
                    for dk in -1..=1 {
                        let Some(list) = grid.get(&[i + di, j + dj, k + dk]) else {
                            continue;
                        };
                        for &s in list {
                            if (centroids[s] - c).norm_squared() <= r2 {
                                force += area[s] * pressure[s];
                                total += area[s];
                            }
                        }
                    }
                }
            }
            if total > 0.0 {
                force / total
            } else {
                pressure[t]
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A brute-force average agrees with the grid's, and a uniform field stays uniform.
    #[test]
    fn averages_within_the_radius_only() {
        let mut centroids = Vec::new();
        let mut pressure = Vec::new();
        let mut area = Vec::new();
        for i in 0..20 {
            for j in 0..20 {
                centroids.push(Vec3::new(
                    0.01 * i as f64,
                    0.013 * j as f64,
                    0.002 * (i * j) as f64,
                ));
                pressure.push(((i * 7 + j * 3) % 11) as f64 * 100.0);
                area.push(1e-4 * (1.0 + (i % 3) as f64));
            }
        }
        let got = probe_pressure(&centroids, &pressure, &area, PROBE_RADIUS);
        for (t, c) in centroids.iter().enumerate() {
            let (mut f, mut a) = (0.0, 0.0);
            for s in 0..centroids.len() {
                if (centroids[s] - c).norm() <= PROBE_RADIUS {
                    f += area[s] * pressure[s];
                    a += area[s];
                }
            }
            assert!(
                (got[t] - f / a).abs() <= 1e-9 * (f / a).abs().max(1.0),
                "triangle {t}"
            );
        }
        let uniform = probe_pressure(&centroids, &vec![1234.5; 400], &area, PROBE_RADIUS);
        assert!(uniform.iter().all(|p| (p - 1234.5).abs() < 1e-9));
        // A spike on one triangle is diluted by its neighbours.
        let mut spiky = vec![1000.0; 400];
        spiky[210] = 1e6;
        let smoothed = probe_pressure(&centroids, &spiky, &area, PROBE_RADIUS);
        assert!(smoothed[210] < 2e5 && smoothed[210] > 1000.0);
    }
}
