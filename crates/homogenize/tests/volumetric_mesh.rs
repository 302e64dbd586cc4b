//! The volumetric mesh (issue 43, deliverable 1) on the shared knit patterns: stockinette and rib tiled into
//! 8 × 8 patches (`shared/data/yarns` beside the repository, as the knit crate's tests read it). The mesh must
//! be one connected solid of positive tetrahedra, embed every yarn vertex with barycentric weights in
//! `[−1e-12, 1 + 1e-12]` summing to 1, give back the yarn at rest through V2Y, and carry the yarn's mass.
//! Prints the report (`cargo test -p skintight-homogenize --release --test volumetric_mesh -- --nocapture`
//! for the figures of docs/BENCHMARKS.md, "Volumetric mesh (issue 43)").

use std::path::PathBuf;
use std::time::Instant;

use skintight_homogenize::volumetric_mesh::{RestYarns, VolumetricMesh, VolumetricMeshParams};
use skintight_knit::PeriodicPattern;
use skintight_knit::tile::tile;
use skintight_knit::yarn_params::YarnParams;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/yarns")
}

fn patch(name: &str, cells: usize) -> RestYarns {
    let pattern = PeriodicPattern::read(&dir().join(name).join("pattern.pyp")).unwrap();
    let patch = tile(&pattern, cells, cells).unwrap();
    RestYarns::from_patch(&patch, YarnParams::default().linear_density(patch.radius))
}

fn check(name: &str, params: &VolumetricMeshParams) {
    let yarns = patch(name, 8);
    let estimate = VolumetricMesh::estimate(&yarns, params).unwrap();
    let start = Instant::now();
    let mesh = VolumetricMesh::build(&yarns, params).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let r = mesh.report(&yarns, params);
    println!(
        "{name} 8x8 voxel {:.2} mm: yarn DOFs {}, mesh DOFs {}, elements {}, voxels {}, ratio {:.3}, \
         components {}, build {:.3} s; estimate ≤ {} voxels, ≤ {} nodes; mass {:.6e} vs {:.6e} kg, \
         weights [{:.2e}, {:.6}], |Σw − 1| ≤ {:.1e}, patch {:.1} mm",
        1e3 * r.voxel_m,
        r.yarn_dofs,
        r.mesh_dofs,
        r.elements,
        r.voxels,
        r.ratio,
        r.components,
        seconds,
        estimate.voxels,
        estimate.nodes,
        r.mesh_mass_kg,
        r.yarn_mass_kg,
        r.weight_range[0],
        r.weight_range[1],
        r.weight_sum_error,
        1e3 * r.patch_size_m,
    );
    mesh.validate().unwrap();
    assert_eq!(r.yarn_vertices, yarns.positions.len());
    assert_eq!(
        r.components, 1,
        "{name}: the mesh is not one connected solid"
    );
    let h = r.voxel_m;
    assert!(
        (r.min_tet_volume_m3 - h.powi(3) / 6.0).abs() < 1e-9 * h.powi(3),
        "{name}: a tetrahedron is not positive with volume h³/6: {}",
        r.min_tet_volume_m3
    );
    assert!(r.weight_range[0] >= -1e-12 && r.weight_range[1] <= 1.0 + 1e-12);
    assert!(r.weight_sum_error <= 1e-12);
    assert!(
        (r.mesh_mass_kg - r.yarn_mass_kg).abs() <= 1e-12 * r.yarn_mass_kg,
        "{name}: mass {} vs {}",
        r.mesh_mass_kg,
        r.yarn_mass_kg
    );
    assert!(mesh.node_mass.iter().all(|&m| m >= 0.0));
    // The estimate bounds what was built.
    assert!(
        estimate.voxels >= r.voxels && estimate.nodes >= r.nodes && estimate.tets >= r.elements
    );
    // V2Y at rest gives back the yarn vertices.
    let y = mesh.v2y(&mesh.rest).unwrap();
    let worst = y
        .iter()
        .zip(&yarns.positions)
        .map(|(a, b)| (0..3).map(|d| (a[d] - b[d]).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    assert!(worst < 1e-15, "{name}: V2Y at rest is off by {worst} m");
    // Every tetrahedron of the mesh holds a piece of yarn or shares its voxel with one that does: the
    // voxels are exactly those of the walk, so each voxel holds some yarn mass at its nodes.
    let mut voxel_has_mass = vec![false; r.voxels];
    for (t, tet) in mesh.tets.iter().enumerate() {
        if tet.iter().any(|&n| mesh.node_mass[n] > 0.0) {
            voxel_has_mass[t / 6] = true;
        }
    }
    assert!(voxel_has_mass.iter().all(|&b| b));
}

#[test]
fn stockinette_8x8_mesh_is_sound() {
    check("stock_9", &VolumetricMeshParams::default());
}

#[test]
fn rib_8x8_mesh_is_sound() {
    check("rib_9", &VolumetricMeshParams::default());
}

#[test]
fn the_mesh_file_of_a_small_patch_opens_as_vtu() {
    let yarns = patch("stock_9", 2);
    let params = VolumetricMeshParams::default();
    let mesh = VolumetricMesh::build(&yarns, &params).unwrap();
    let gamma = vec![1.0; mesh.tets.len()];
    let text = mesh
        .vtu(&[skintight_geometry::body::tet_io::VtuArray::Scalars(
            "gamma_s".into(),
            gamma,
        )])
        .unwrap();
    assert!(text.contains(&format!(
        "NumberOfPoints=\"{}\" NumberOfCells=\"{}\"",
        mesh.rest.len(),
        mesh.tets.len()
    )));
    assert!(text.contains("Name=\"gamma_s\""));
}

#[test]
fn a_sequence_frame_gives_the_same_rest_yarns_as_its_patch() {
    use skintight_knit::frame_sequence::{FORMAT, SequenceMeta, Units, VERSION};
    let pattern = PeriodicPattern::read(&dir().join("stock_9").join("pattern.pyp")).unwrap();
    let patch = tile(&pattern, 2, 2).unwrap();
    let rho = YarnParams::default().linear_density(patch.radius);
    let from_patch = RestYarns::from_patch(&patch, rho);
    let meta = SequenceMeta {
        format: FORMAT.into(),
        version: VERSION,
        pattern: "stock_9".into(),
        cells: [2, 2],
        scenario: "hang".into(),
        units: Units::default(),
        yarn_radius_m: patch.radius,
        linear_density_kg_per_m: rho,
        dt_s: 1e-3,
        frame_interval_s: 1e-2,
        vertex_count: from_patch.positions.len(),
        frame_count: 1,
        yarns: from_patch.yarns.clone(),
        frames: vec![],
        loads: None,
    };
    let frame: Vec<[f64; 4]> = from_patch
        .positions
        .iter()
        .map(|p| [p[0], p[1], p[2], 0.25])
        .collect();
    let from_frame = RestYarns::from_frame(&meta, &frame);
    assert_eq!(from_frame, from_patch);
    let params = VolumetricMeshParams::default();
    assert_eq!(
        VolumetricMesh::build(&from_frame, &params).unwrap(),
        VolumetricMesh::build(&from_patch, &params).unwrap()
    );
}
