//! The model of a yarn scene: the tiled patch, its start state and its grips.
//!
//! **Start state.** The published rest geometry (`*Q`) is not an equilibrium of the yarn model (its rest
//! curvatures and twists are balanced by HYLC's own contact law; `crates/knit/tests/rest_state.rs`), so a
//! patch tiled from it would first spring into another shape. [`patch_model`] therefore solves the periodic
//! cell at zero strain without gravity (`skintight_knit::periodic_cell`, damped Newton) and tiles that
//! equilibrium (its positions, angles, reference frames and reference twists); the run (`run.rs`) then
//! relaxes the cut patch with its held vertices, without gravity — the border, which lost the tension and
//! moments the periodic neighbours carried, curls and settles — and frame 0 is that relaxed state, at rest.
//! The scenario's loads and grips act from there.
//!
//! **Grips** (the vertices in a band of `clamp_band_cells` cell periods at a side of the bounding box):
//! - `hang`: the top band (largest y) is clamped; the patch hangs under gravity.
//! - `stretch_uniaxial`: the left band is clamped, the right band moves by `strain · W` along +x over
//!   `ramp_time_s` (`W` the patch width, m), then holds.
//! - `stretch_biaxial`: all four bands move to `c + (1 + strain)(X − c)` in x and y (`c` the box centre),
//!   i.e. an equibiaxial stretch of the border.
//! - `shear`: the bottom band is clamped, the top band moves by `strain · H` along +x (`H` the height; the
//!   shear `tan γ = strain`).
//! - `drape_sphere`: the patch is turned flat (its normal along +y), centred above a rigid sphere of radius
//!   `sphere_radius_m` (default 0.3 × the smaller side) whose top is one yarn radius below it, and falls on
//!   it under gravity, nothing held.
//!
//! **Edges** (`edges`, `skintight_knit::edge_finish`): `bonded` (the default) fuses every cut yarn end to
//! the nearest vertex of another yarn, as the laser- or ultrasound-cut edge of a synthetic knit or an
//! overlocked edge holds it; `cut` leaves the ends free, and with frictionless contact the border then
//! unravels, a motion with no nearby equilibrium (the Newton counts of both are in docs/BENCHMARKS.md).
//!
//! Units: SI (m, s, Pa).

use skintight_knit::PeriodicPattern;
use skintight_knit::edge_finish::EdgeFinish;
use skintight_knit::implicit_euler::Prescribed;
use skintight_knit::newton::{NewtonParams, minimize};
use skintight_knit::patch::{PatchLoads, PatchModel, transform_patch};
use skintight_knit::periodic_cell::{CellState, PeriodicCell};
use skintight_knit::sphere_contact::SphereObstacle;
use skintight_knit::tile::{Patch, tile};

use super::error::YarnSceneError;
use super::spec::{Scenario, YarnScene};

/// The model and boundary conditions (held and moving vertices) of a scene on its pattern.
pub fn patch_model(
    scene: &YarnScene,
    pattern: &PeriodicPattern,
) -> Result<(PatchModel, Vec<Prescribed>), YarnSceneError> {
    let [nx, ny] = scene.cells;
    let mut patch = tile(pattern, nx, ny).map_err(|e| YarnSceneError::Input(e.to_string()))?;
    periodic_rest_start(&mut patch, pattern, scene)?;
    let r = pattern.radius;
    let gravity = [0.0, -scene.gravity_m_s2, 0.0];
    let mut sphere = None;
    if scene.scenario == Scenario::DrapeSphere {
        // Flat: (x, y, z) ↦ (x, z, −y), centred on the y axis.
        let rot = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]];
        let turned = transform_patch(&patch, rot, [0.0; 3]);
        let (lo, hi) = bounds(turned.yarns.iter().flat_map(|y| y.positions.iter()));
        let centre = [-(lo[0] + hi[0]) / 2.0, 0.0, -(lo[2] + hi[2]) / 2.0];
        patch = transform_patch(
            &turned,
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            centre,
        );
        let radius = scene
            .sphere_radius_m
            .unwrap_or(0.3 * (hi[0] - lo[0]).min(hi[2] - lo[2]));
        sphere = Some(SphereObstacle {
            center: [0.0, lo[1] - 2.0 * r - radius, 0.0],
            radius,
            stiffness: scene.sphere_stiffness_pa,
        });
    }
    let mut model = PatchModel::new(&patch, &scene.yarn, PatchLoads { gravity, sphere })
        .map_err(|e| YarnSceneError::Input(e.to_string()))?;
    if scene.edges == EdgeFinish::Bonded {
        model.bond_cut_ends();
    }
    let x = model.initial_state();
    let prescribed = grips(scene, pattern, &PatchModel::positions(&x));
    Ok((model, prescribed))
}

/// The held and moving vertices of the scenario among `points` (the start positions, m).
fn grips(scene: &YarnScene, pattern: &PeriodicPattern, points: &[[f64; 3]]) -> Vec<Prescribed> {
    let (lo, hi) = bounds(points.iter());
    let (bx, by) = (
        scene.clamp_band_cells * pattern.period[0],
        scene.clamp_band_cells * pattern.period[1],
    );
    let ramp = scene.ramp_time_s.unwrap_or(scene.duration_s);
    let s = scene.strain;
    let (cx, cy) = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
    let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
    let mut prescribed = Vec::new();
    for (v, p) in points.iter().enumerate() {
        let left = p[0] < lo[0] + bx;
        let right = p[0] > hi[0] - bx;
        let bottom = p[1] < lo[1] + by;
        let top = p[1] > hi[1] - by;
        let end = match scene.scenario {
            Scenario::Hang => top.then_some(*p),
            Scenario::StretchUniaxial => {
                if left {
                    Some(*p)
                } else if right {
                    Some([p[0] + s * w, p[1], p[2]])
                } else {
                    None
                }
            }
            Scenario::StretchBiaxial => (left || right || top || bottom).then(|| {
                [
                    cx + (1.0 + s) * (p[0] - cx),
                    cy + (1.0 + s) * (p[1] - cy),
                    p[2],
                ]
            }),
            Scenario::Shear => {
                if bottom {
                    Some(*p)
                } else if top {
                    Some([p[0] + s * h, p[1], p[2]])
                } else {
                    None
                }
            }
            Scenario::DrapeSphere => None,
        };
        if let Some(end) = end {
            prescribed.push(Prescribed {
                vertex: v,
                start: *p,
                end,
                ramp_time: ramp,
            });
        }
    }
    prescribed
}

/// Replaces the tiled published rest state of `patch` by the periodic cell's own equilibrium at zero strain
/// without gravity, tiled: positions, edge angles, reference directors and reference twists.
fn periodic_rest_start(
    patch: &mut Patch,
    pattern: &PeriodicPattern,
    scene: &YarnScene,
) -> Result<(), YarnSceneError> {
    let mut cell = PeriodicCell::new(pattern, &scene.yarn, [0.0, 0.0, 0.0])
        .map_err(|e| YarnSceneError::Input(e.to_string()))?;
    let mut x = cell.affine_state().to_vector();
    let newton = NewtonParams {
        tolerance: 1e-10,
        max_iterations: 400,
        max_factorizations: 2000,
        trace: false,
        ..NewtonParams::default()
    };
    let report = minimize(&mut cell, &mut x, &newton).map_err(|e| {
        YarnSceneError::Output(format!(
            "the periodic rest state of the pattern failed: {e}"
        ))
    })?;
    if !report.converged {
        // Not converged: start from the published rest state instead (the relaxation absorbs it).
        return Ok(());
    }
    let state = CellState::from_vector(&x);
    cell.rebase_frames(&state, 0.0);
    let (frames, hints) = cell.frames();
    for y in &mut patch.yarns {
        for (i, &(v, c)) in y.source.iter().enumerate() {
            let o = pattern.shift_offset(c);
            let q = state.positions[v];
            y.positions[i] = [q[0] + o[0], q[1] + o[1], q[2] + o[2]];
            if i < y.twist.len() {
                y.twist[i] = state.twist[v];
                y.reference_director[i] = frames[v].director;
            }
            if y.reference_twist[i].is_some() {
                y.reference_twist[i] = Some(hints[v]);
            }
        }
    }
    Ok(())
}

/// The bounding box `(lo, hi)` of `points` (m).
pub(super) fn bounds<'a>(points: impl Iterator<Item = &'a [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}
