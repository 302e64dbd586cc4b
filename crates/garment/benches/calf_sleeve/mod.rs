//! The calf sleeve of `examples/calf_sleeve.json` on the regular body (`../shared/data/bodies/regular_1k.obj`):
//! two panels, two seams, free hems — the garment the garment benchmarks run on.

use skintight_garment::garment::{Garment, GarmentParams, PanelShape, PanelSpec, garment};
use skintight_geometry::region::HalfSpace;

/// The regular body's surface and the sleeve's two panels.
pub fn body_and_panels() -> (skintight_geometry::TriMesh, Vec<PanelSpec>) {
    let main = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/bodies/regular_1k.obj"
    );
    let wt = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../../shared/data/bodies/regular_1k.obj"
    );
    let path = if std::path::Path::new(main).is_file() {
        main
    } else {
        wt
    };
    let body = skintight_geometry::mesh::io::read_mesh(std::path::Path::new(path))
        .expect("regular_1k.obj");
    let panel = |name: &str, side: f64| PanelSpec {
        name: name.into(),
        shape: PanelShape::Region(vec![
            HalfSpace::new([-1.0, 0.0, 0.0], 0.0),
            HalfSpace::new([0.0, 0.0, side], 0.03 * side),
            HalfSpace::new([0.0, 1.0, 0.0], -0.35),
            HalfSpace::new([0.0, -1.0, 0.0], 0.5),
        ]),
    };
    (body, vec![panel("front", -1.0), panel("back", 1.0)])
}

/// The sleeve sewn at cloth edge length `edge_length` (m), ease −0.1, seams as flattened.
pub fn garment_at(edge_length: f64) -> Garment {
    let (body, specs) = body_and_panels();
    garment(
        &body,
        &specs,
        &GarmentParams {
            edge_length,
            ease: -0.1,
            ..Default::default()
        },
    )
    .expect("the calf sleeve")
}
