//! Test support: a raw scan made from a clean body, as a scanning booth or a phone would deliver it —
//! densely triangulated, noisy, open at the soles and the crown, with floating islands and non-manifold
//! spots, in millimetres, +z up (facing −y).
//!
//! Units: the clean body in metres (+y up, facing +z); the scan in millimetres.
//!
//! Method: Loop subdivision (Loop 1987) or midpoint subdivision of the clean body to scan density, Gaussian noise of the vertices
//! (Box–Muller on a SplitMix64 stream, so no random-number crate is needed in the library), removal of the
//! faces near the lowest and highest points, small tetrahedra floating beside the body, one "fin" (a third
//! face on an edge) and one "bow-tie" (a face touching the surface at one vertex), then a proper rotation to
//! +z up and the scale to millimetres.

use crate::math::{Real, Vec3};
use crate::mesh::TriMesh;
use crate::mesh::io::{MeshFormat, PlyEncoding, WriteParams, write_mesh_bytes};
use crate::mesh::topology::Topology;
use crate::surface::loop_subdivision::loop_subdivision;

/// How to damage the clean body.
#[derive(Clone, Copy, Debug)]
pub struct RawScanParams {
    /// Subdivision steps (each ×4 faces): 2 makes a 12k body ≈ 400 k triangles.
    pub subdivisions: usize,
    /// Loop subdivision (smooth, moves off the clean polyhedron by up to millimetres where the clean mesh
    /// is coarse and curved, e.g. fingertips) when true; midpoint subdivision (the scan samples the clean
    /// surface exactly, before noise) when false.
    pub smooth: bool,
    /// Standard deviation of the noise per coordinate (m).
    pub noise_m: Real,
    /// Faces with a corner this close to the lowest point are removed (soles) (m).
    pub sole_cut_m: Real,
    /// Faces with a corner this close to the highest point are removed (crown) (m).
    pub crown_cut_m: Real,
    /// Floating islands.
    pub islands: usize,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for RawScanParams {
    fn default() -> Self {
        Self {
            subdivisions: 2,
            smooth: true,
            noise_m: 0.0005,
            sole_cut_m: 0.008,
            crown_cut_m: 0.02,
            islands: 4,
            seed: 1,
        }
    }
}

struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e3779b97f4a7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> Real {
        ((self.next() >> 11) as Real + 0.5) / (1u64 << 53) as Real
    }
    fn normal(&mut self) -> Real {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// The clean body (closed, metres, +y up) subdivided and damaged as described; still metres, +y up.
pub fn damaged_body(clean: &TriMesh, params: &RawScanParams) -> TriMesh {
    let mut positions = clean.positions.clone();
    let mut faces = clean.faces.clone();
    for _ in 0..params.subdivisions {
        let topo = Topology::new(positions.len(), &faces).expect("a closed clean body");
        let r = loop_subdivision(&topo).expect("a closed clean body");
        positions = if params.smooth {
            r.subdivision.apply(&positions)
        } else {
            // Midpoints: the two 3/8 weights of each edge row.
            (0..r.num_vertices)
                .map(|i| {
                    if i < positions.len() {
                        positions[i]
                    } else {
                        let ends: Vec<usize> = r
                            .subdivision
                            .row(i)
                            .filter(|&(_, w)| w == 0.375)
                            .map(|(j, _)| j)
                            .collect();
                        ends.iter().map(|&j| positions[j]).sum::<Vec3>() / ends.len() as Real
                    }
                })
                .collect()
        };
        faces = r.faces;
    }
    let mut rng = SplitMix(params.seed);
    for p in &mut positions {
        *p += params.noise_m * Vec3::new(rng.normal(), rng.normal(), rng.normal());
    }
    let lo = positions
        .iter()
        .map(|p| p.y)
        .fold(Real::INFINITY, Real::min);
    let hi = positions
        .iter()
        .map(|p| p.y)
        .fold(Real::NEG_INFINITY, Real::max);
    faces.retain(|f| {
        !f.iter().any(|&v| {
            positions[v].y < lo + params.sole_cut_m || positions[v].y > hi - params.crown_cut_m
        })
    });
    let mut mesh = TriMesh::new(positions, faces);
    // Islands: small tetrahedra beside the body.
    let (bl, bh) = mesh.bounding_box().expect("a body");
    for i in 0..params.islands {
        let t = (i as Real + 0.5) / params.islands.max(1) as Real;
        let c = Vec3::new(bh.x + 0.05 + 0.02 * t, bl.y + t * (bh.y - bl.y), 0.1 * t);
        let s = 0.005 + 0.005 * rng.uniform();
        let base = mesh.positions.len();
        mesh.positions.extend([
            c,
            c + Vec3::new(s, 0.0, 0.0),
            c + Vec3::new(0.0, s, 0.0),
            c + Vec3::new(0.0, 0.0, s),
        ]);
        mesh.faces.extend(
            [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]].map(|f: [usize; 3]| f.map(|v| v + base)),
        );
    }
    // A fin on the edge of a face near mid-height, and a bow-tie at a vertex of another.
    let mid = mesh.faces.len() / 2;
    let [a, b, _] = mesh.faces[mid];
    let n = mesh.face_area_normal(mid).normalize();
    let tip = 0.5 * (mesh.positions[a] + mesh.positions[b]) + 0.004 * n;
    mesh.positions.push(tip);
    let t = mesh.positions.len() - 1;
    mesh.faces.push([b, a, t]);
    let other = mesh.faces.len() / 3;
    let v = mesh.faces[other][0];
    let n = mesh.face_area_normal(other).normalize();
    let p = mesh.positions[v];
    let e = n.cross(&Vec3::x()).normalize();
    mesh.positions
        .extend([p + 0.004 * n + 0.003 * e, p + 0.004 * n - 0.003 * e]);
    let k = mesh.positions.len();
    mesh.faces.push([v, k - 2, k - 1]);
    mesh
}

/// The damaged body in scan conventions: millimetres, +z up, facing −y (a proper rotation about x).
pub fn raw_scan(clean: &TriMesh, params: &RawScanParams) -> TriMesh {
    let mut m = damaged_body(clean, params);
    for p in &mut m.positions {
        *p = Vec3::new(p.x, -p.z, p.y) * 1000.0;
    }
    m
}

/// [`raw_scan`] as a binary little-endian PLY file.
pub fn raw_scan_ply(clean: &TriMesh, params: &RawScanParams) -> Vec<u8> {
    let params_w = WriteParams {
        ply_encoding: PlyEncoding::BinaryLittleEndian,
        ..Default::default()
    };
    write_mesh_bytes(&raw_scan(clean, params), MeshFormat::Ply, &params_w)
        .expect("finite positions")
}
