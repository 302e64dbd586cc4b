//! Test helpers: a minimal OBJ reader (test-only; the real reader lives elsewhere) and small closed meshes.
#![allow(dead_code)]

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::surface::loop_subdivision::loop_subdivision;
use skintight_geometry::{Real, Topology, Vec2, Vec3};

/// A closed test mesh: positions (m) and triangles.
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub faces: Vec<[usize; 3]>,
}

/// Directory of the shared body meshes: `shared/` beside the repository root (one level further up when the
/// repository is a worktree under `wt/`).
pub fn bodies_dir() -> &'static str {
    let main = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/bodies/");
    let worktree = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../../shared/data/bodies/"
    );
    if std::path::Path::new(main).is_dir() {
        main
    } else {
        worktree
    }
}

/// Reads a body with the real reader (polygons fan-triangulated).
pub fn read_obj(name: &str) -> Mesh {
    let path = format!("{}{}", bodies_dir(), name);
    let m = skintight_geometry::mesh::io::read_mesh(std::path::Path::new(&path))
        .unwrap_or_else(|e| panic!("{path}: {e}"));
    Mesh {
        positions: m.positions,
        faces: m.faces,
    }
}

/// A bipyramid over an `n`-gon: apexes of valence `n`, equator vertices of valence 4, on the unit sphere.
pub fn bipyramid(n: usize) -> Mesh {
    let mut positions = vec![Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0)];
    for i in 0..n {
        let a = 2.0 * std::f64::consts::PI * i as Real / n as Real;
        positions.push(Vec3::new(a.cos(), a.sin(), 0.0));
    }
    let mut faces = Vec::new();
    for i in 0..n {
        let (a, b) = (2 + i, 2 + (i + 1) % n);
        faces.push([a, b, 0]);
        faces.push([b, a, 1]);
    }
    Mesh { positions, faces }
}

/// Icosahedron on the unit sphere (12 vertices of valence 5): the workspace's one icosphere at level 0.
pub fn icosahedron() -> Mesh {
    let m = skintight_geometry::test_meshes::icosphere(0, 1.0);
    Mesh {
        positions: m.positions,
        faces: m.faces,
    }
}

/// One explicit Loop subdivision step of a mesh (positions mapped by `S`).
pub fn subdivide(m: &Mesh) -> Mesh {
    let t = Topology::new(m.positions.len(), &m.faces).unwrap();
    let r = loop_subdivision(&t).unwrap();
    Mesh {
        positions: r.subdivision.apply(&m.positions),
        faces: r.faces,
    }
}

/// Positions pushed out to the unit sphere, then jittered by `noise` (seeded).
pub fn jittered(positions: &[Vec3], noise: Real, seed: u64) -> Vec<Vec3> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    positions
        .iter()
        .map(|p| {
            let j = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            p.normalize() + noise * j
        })
        .collect()
}

/// A uniformly random point strictly inside the parameter triangle.
pub fn random_s(rng: &mut ChaCha8Rng) -> Vec2 {
    loop {
        let (a, b): (Real, Real) = (rng.random_range(0.01..0.98), rng.random_range(0.01..0.98));
        if a + b < 0.99 {
            return Vec2::new(a, b);
        }
    }
}

/// `(s1, s2)` of barycentric coordinates `[b0, b1, b2]` (weights of `f[0]`, `f[1]`, `f[2]`).
pub fn s_of(b: [Real; 3]) -> Vec2 {
    Vec2::new(b[0], b[1])
}
