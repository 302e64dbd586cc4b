//! A real garment and pattern for the pattern model's and the writers' tests: a bulged tube (two panels, two
//! open seams, two openings each), and its pattern, seams trued, with order text that exercises escaping.

use crate::garment::{Garment, GarmentParams, PanelShape, PanelSpec, garment};
use crate::math::Vec3;
use crate::pattern::{OrderLabels, Pattern, PatternParams, pattern};
use crate::plane_cut::HalfSpace;
use crate::seam_truing::{SeamTruingParams, true_seams};
use skintight_geometry::mesh::TriMesh;
use skintight_geometry::test_meshes::cylinder;

/// A tube about z, 0.3 m long, its radius bulging from 0.08 m at the ends to 0.12 m in the middle (not
/// developable, so its flattened seam sides differ), cut into two panels of different widths by the plane
/// y = 0.02: two open seams, two openings per panel. Seams as flattened.
pub(crate) fn bulged_tube() -> Garment {
    let tube = cylinder(1.0, 0.3, 32, 12, std::f64::consts::TAU);
    let positions = tube
        .positions
        .iter()
        .map(|p| {
            let r = 0.08 + 0.04 * (std::f64::consts::PI * p.z / 0.3).sin();
            Vec3::new(r * p.x, r * p.y, p.z)
        })
        .collect();
    let body = TriMesh::new(positions, tube.faces.clone());
    let specs = vec![
        PanelSpec {
            name: "front".into(),
            shape: PanelShape::Region(vec![HalfSpace::new([0.0, -1.0, 0.0], -0.02)]),
        },
        PanelSpec {
            name: "back".into(),
            shape: PanelShape::Region(vec![HalfSpace::new([0.0, 1.0, 0.0], 0.02)]),
        },
    ];
    garment(
        &body,
        &specs,
        &GarmentParams {
            edge_length: 0.015,
            ..Default::default()
        },
    )
    .unwrap()
}

/// The [`bulged_tube`], seams trued, made into a pattern with order text (including non-ASCII and control
/// characters, which every writer must carry or drop without breaking its file).
pub(crate) fn bulged_tube_pattern() -> Pattern {
    let mut g = bulged_tube();
    true_seams(&mut g, &SeamTruingParams::default()).unwrap();
    let labels = OrderLabels {
        order_id: "A-17".into(),
        customer: "Zoë Müller\u{3}\u{7}".into(),
        template: "bulged tube".into(),
        size: "class II".into(),
        fabric: "powernet 20 %".into(),
        date: "2026-12-01".into(),
        software: "skintight test".into(),
    };
    pattern(
        &g,
        &PatternParams {
            up: Vec3::z(),
            ..Default::default()
        },
        labels,
    )
    .unwrap()
}
