//! Shell tetrahedralization of the real bodies in `shared/data/bodies`.

use std::time::Instant;

use skintight_geometry::mesh::io::read_mesh;
use skintight_geometry::{ShellParams, TriMesh, shell_tetrahedralization};

const BODIES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/bodies/");
const SHAPES: [&str; 5] = ["regular", "male", "athletic", "overweight", "kid"];

/// The bodies folder: `<repo root>/../shared/data/bodies`, or the nearest ancestor's `shared/data/bodies`
/// (a git worktree may sit deeper than the main checkout).
fn bodies_dir() -> std::path::PathBuf {
    let conventional = std::path::PathBuf::from(BODIES);
    if conventional.is_dir() {
        return conventional;
    }
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join("shared/data/bodies"))
        .find(|p| p.is_dir())
        .unwrap_or(conventional)
}

/// Reads a body with the real reader (polygons fan-triangulated).
fn load_obj(name: &str) -> TriMesh {
    let path = bodies_dir().join(name);
    read_mesh(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn check(name: &str) {
    let surface = load_obj(name);
    let start = Instant::now();
    let body = shell_tetrahedralization(&surface, &ShellParams::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let r = &body.report;
    eprintln!("{name}: {:.3} s {r:?}", start.elapsed().as_secs_f64());
    assert_eq!(r.inverted, 0, "{name}");
    assert!(r.surface_preserved, "{name}");
    assert_eq!(r.self_intersections, 0, "{name}");
    assert!(r.min_quality > 0.0, "{name}");
    assert_eq!(r.fixed_vertices, surface.num_vertices());
    // The shell is pinched to zero thickness only at a few sharp folds and tips; everywhere else it is open.
    assert!(r.thickness_max <= 0.02);
    assert!(
        r.pinched_vertices * 20 < surface.num_vertices(),
        "{name}: {} pinched vertices",
        r.pinched_vertices
    );
    let open = body.thickness.iter().filter(|&&h| h > 0.0).count();
    assert_eq!(open + r.pinched_vertices, surface.num_vertices(), "{name}");
    body.mesh.validate(0.0).unwrap();
}

// A handful of fold vertices of the real bodies (nose, lips, toe and finger tips: no direction sees their whole
// fan from inside) are pinched to zero thickness; this pins that the rest of the shell stays valid around them.
#[test]
fn all_1k_bodies_give_valid_shells_that_keep_the_surface() {
    for shape in SHAPES {
        check(&format!("{shape}_1k.obj"));
    }
}

#[test]
fn coarse_370_and_600_bodies_give_valid_shells() {
    for shape in SHAPES {
        check(&format!("{shape}_370.obj"));
        if shape != "kid" {
            check(&format!("{shape}_600.obj"));
        }
    }
}

// KNOWN FAILURE: at a tip of kid_600 all three corners of one face are fold vertices; the face is pinched
// whole, has no tetrahedron under it and drops out of the outer boundary (surface_preserved false).
#[test]
#[ignore = "known failure: a whole face of kid_600 is pinched out of the boundary"]
fn kid_600_gives_a_valid_shell_that_keeps_the_surface() {
    check("kid_600.obj");
}

#[test]
#[ignore = "about 4 s each in the debug profile; run with --ignored"]
fn male_athletic_overweight_kid_12k_give_valid_shells_that_keep_the_surface() {
    for shape in ["male", "athletic", "overweight", "kid"] {
        check(&format!("{shape}_12k.obj"));
    }
}

// KNOWN FAILURE: regular_12k has two coincident vertices at a toe tip (12138 and 12148), so face 24492 is
// degenerate and all three of its corners are fold vertices; the shell is pinched there and that face has no
// tetrahedron under it, so the outer boundary misses it (surface_preserved false; no inversion, no crossing).
#[test]
#[ignore = "known failure: degenerate toe-tip face of regular_12k is pinched out of the boundary"]
fn regular_12k_gives_a_valid_shell_that_keeps_the_surface() {
    check("regular_12k.obj");
}

#[test]
fn input_crossings_are_counted_on_the_real_bodies() {
    // regular_1k has none; male_1k crosses itself at two triangle pairs (touching body parts).
    let count = |name: &str| {
        let s = load_obj(name);
        skintight_geometry::mesh::self_intersection::self_intersections(&s.positions, &s.faces, 0.0)
            .len()
    };
    assert_eq!(count("regular_1k.obj"), 0);
    assert_eq!(count("male_1k.obj"), 2);
}
