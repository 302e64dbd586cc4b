//! Meshes generated for tests: icosphere, open cylinder, planar grid, and a tiny OBJ reader for the bodies.

use std::collections::HashMap;

use crate::math::{Real, Vec3};
use crate::mesh::TriMesh;

/// Unit icosahedron subdivided `levels` times, vertices projected onto the sphere of `radius` (m),
/// outward-oriented. `20 · 4^levels` faces.
pub fn icosphere(levels: usize, radius: Real) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3::new(p[0], p[1], p[2]).normalize())
    .collect();
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
        let mut next = Vec::with_capacity(faces.len() * 4);
        for &[a, b, c] in &faces {
            let mut m = |u: usize, v: usize| -> usize {
                *mid.entry((u.min(v), u.max(v))).or_insert_with(|| {
                    positions.push(((positions[u] + positions[v]) * 0.5).normalize());
                    positions.len() - 1
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    for p in &mut positions {
        *p *= radius;
    }
    TriMesh::new(positions, faces)
}

/// Open cylinder of `radius` and `height` (m) about the z axis, `segments` around and `rings` along,
/// outward-oriented. Covers the angle range `[0, sweep]` (rad); a full `2π` sweep closes the tube.
pub fn cylinder(radius: Real, height: Real, segments: usize, rings: usize, sweep: Real) -> TriMesh {
    let full = (sweep - std::f64::consts::TAU).abs() < 1e-12;
    let columns = if full { segments } else { segments + 1 };
    let mut positions = Vec::new();
    for j in 0..=rings {
        for i in 0..columns {
            let a = sweep * i as Real / segments as Real;
            positions.push(Vec3::new(
                radius * a.cos(),
                radius * a.sin(),
                height * j as Real / rings as Real,
            ));
        }
    }
    let id = |i: usize, j: usize| j * columns + (i % columns);
    let mut faces = Vec::new();
    for j in 0..rings {
        for i in 0..segments {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            faces.push([a, b, c]);
            faces.push([a, c, d]);
        }
    }
    TriMesh::new(positions, faces)
}

/// Closed cylinder of `radius` and `height` (m) about the z axis from z = 0 to `height`: the full tube of
/// [`cylinder`] with a fan of triangles closing each end, outward-oriented.
pub fn capped_cylinder(radius: Real, height: Real, segments: usize, rings: usize) -> TriMesh {
    let tube = cylinder(radius, height, segments, rings, std::f64::consts::TAU);
    let mut positions = tube.positions;
    let mut faces = tube.faces;
    let bottom = positions.len();
    positions.push(Vec3::zeros());
    positions.push(Vec3::new(0.0, 0.0, height));
    let top = bottom + 1;
    let id = |i: usize, j: usize| j * segments + (i % segments);
    for i in 0..segments {
        faces.push([bottom, id(i + 1, 0), id(i, 0)]);
        faces.push([top, id(i, rings), id(i + 1, rings)]);
    }
    TriMesh::new(positions, faces)
}

/// Planar `nx × ny` grid of squares of side `size / n` (m) in the plane z = 0, each split in two, with
/// the interior vertices jittered by `jitter` (fraction of a cell) in a fixed pattern.
pub fn grid(nx: usize, ny: usize, size: Real, jitter: Real) -> TriMesh {
    let mut positions = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            let interior = i > 0 && j > 0 && i < nx && j < ny;
            let (dx, dy) = if interior {
                let k = (i * 7 + j * 13) as Real;
                (jitter * (k * 0.37).sin(), jitter * (k * 0.53).cos())
            } else {
                (0.0, 0.0)
            };
            positions.push(Vec3::new(
                size * (i as Real + dx) / nx as Real,
                size * (j as Real + dy) / ny as Real,
                0.0,
            ));
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut faces = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriMesh::new(positions, faces)
}

/// Reads a test body with the real reader (polygons fan-triangulated).
pub fn read_obj(path: &str) -> TriMesh {
    crate::mesh::io::read_mesh(std::path::Path::new(path))
        .unwrap_or_else(|e| panic!("reading {path}: {e}"))
}

/// Path of a body mesh in the shared data folder, which sits beside the repository root
/// (`<root>/../shared/data/bodies`). A worktree one level deeper (`/work/wt/<name>`) falls back to the
/// folder two levels up.
pub fn body_path(name: &str) -> String {
    let primary = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/bodies/");
    let worktree = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../../shared/data/bodies/"
    );
    let dir = if std::path::Path::new(primary).is_dir() {
        primary
    } else {
        worktree
    };
    format!("{dir}{name}")
}

/// Path of one sample body file, e.g. `body("regular_1k.obj")` (see [`body_path`]).
pub fn body(name: &str) -> std::path::PathBuf {
    body_path(name).into()
}

/// An outward octahedron with two face groups and distinctive (non-round) coordinates.
pub fn octahedron() -> TriMesh {
    let s = 0.123456789012345;
    let positions = vec![
        Vec3::new(s, 0.0, 0.0),
        Vec3::new(-s, 0.0, 0.0),
        Vec3::new(0.0, s, 0.0),
        Vec3::new(0.0, -s, 0.0),
        Vec3::new(0.0, 0.0, s),
        Vec3::new(0.0, 0.0, -s) + Vec3::new(1e-9, 3e-7, 0.0),
    ];
    let faces = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    TriMesh {
        positions,
        faces,
        face_groups: vec![0, 0, 0, 0, 1, 1, 1, 1],
        group_names: vec!["top".into(), "bottom half".into()],
    }
}
