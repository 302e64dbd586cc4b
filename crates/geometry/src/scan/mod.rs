//! Scan preparation: a customer's raw body scan (any units and up axis, open at the soles and crown, noise
//! islands, non-manifold spots, 100 k–1 M triangles) made into a body surface skintight accepts — closed,
//! 2-manifold, outward, genus 0, metres, +y up, facing +z, at a working resolution — with a report of what
//! changed and how far the result lies from the scan.
//!
//! Units: the input in its own units (mm, cm or m, declared or detected); the output in metres; the
//! report's deviations in millimetres.
//!
//! The pipeline of [`prepare_scan`], one algorithm per module:
//! 1. drop invalid faces; split the soup into components ([`largest_component`]); refuse two bodies of
//!    similar size; keep the largest;
//! 2. find units, up axis and facing and bring the scan into the body frame ([`units_and_up`]); refuse a
//!    height no reading fits and a shape that is not a standing body (see [`PrepareError::NotABody`]);
//! 3. repair non-manifold edges and vertices and orient the faces ([`non_manifold_repair`]), keep the
//!    largest component again;
//! 4. close every hole with a fan ([`hole_filling`]) and refuse a surface of genus other than 0;
//! 5. remesh isotropically to the target edge length on the filled scan ([`isotropic_remeshing`]), then
//!    again with edges shortened where the body is curved more tightly than a 50 mm radius
//!    ([`curvature_sizing`]: wrists, ankles, fingers keep the chord error of the rest; ≈ 30–40 % more
//!    faces than `target_faces` on an adult), then
//!    fair the hole patches to a thin-plate surface; move the other vertices along their normals so that
//!    the coarse surface straddles the scan instead of lying inside it as chords do ([`unbiased_fit`]);
//! 6. smooth away any self-intersection the remesh made, orient outward, check the result, and measure its
//!    deviation from the scan ([`surface_deviation`]).
//!
//! Limits: at most [`PrepareParams::max_faces`] input faces (5 M by default); [`read_scan`] refuses a larger
//! file from its header before reading the faces.

pub mod curvature_sizing;
pub mod hole_filling;
pub mod isotropic_remeshing;
pub mod largest_component;
pub mod non_manifold_repair;
#[cfg(any(test, feature = "test-support"))]
pub mod raw_scan;
pub mod surface_deviation;
pub mod unbiased_fit;
pub mod units_and_up;

use std::path::Path;

use serde::Serialize;

use crate::math::{Real, Vec3};
use crate::mesh::TriMesh;
use crate::mesh::check::{MeshCheckParams, mesh_report};
use crate::mesh::io::{MeshFormat, MeshIoError, read_mesh_bytes};
use crate::mesh::self_intersection::{mean_edge_length, self_intersections};
use curvature_sizing::{SizingParams, curvature_sizing};
use hole_filling::{FilledHole, fair, fill_holes_with_fans};
use isotropic_remeshing::{IsotropicRemeshParams, adaptive_remesh, isotropic_remesh};
use largest_component::{components, keep_faces};
use non_manifold_repair::{RepairSummary, repair_non_manifold};
use surface_deviation::{ClosestPointGrid, deviation_of_points, vertex_areas};
use unbiased_fit::{FitParams, unbiased_fit};
use units_and_up::{FrameError, LengthUnit, SignedAxis, apply_frame, detect_frame};

/// Default largest accepted scan, in faces.
pub const DEFAULT_MAX_FACES: usize = 5_000_000;
/// Default target face count: near the triangulated 12k sample bodies (≈ 24.5 k triangles, mean edge
/// ≈ 12 mm).
pub const DEFAULT_TARGET_FACES: usize = 24_000;

/// Least volume a closed body surface may enclose (m³): 5 L, far below a 1 m child's ≈ 15 L.
pub const MIN_BODY_VOLUME_M3: Real = 0.005;

/// Settings of [`prepare_scan`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrepareParams {
    /// Units of the scan; `None` detects them from the height.
    pub units: Option<LengthUnit>,
    /// Up axis of the scan; `None` detects it (longest extent, sign by the area centroid).
    pub up: Option<SignedAxis>,
    /// Faces of the uniform remesh (its edge length `√(4 A / (√3 target_faces))` for the scan's area `A`);
    /// curvature grading then adds faces where the body is tightly curved (≈ 30–40 % on an adult body).
    pub target_faces: usize,
    /// Largest accepted input, in faces.
    pub max_faces: usize,
    /// Remeshing rounds.
    pub iterations: usize,
    /// A second component at least this fraction of the largest one's area means two bodies.
    pub second_body_ratio: Real,
}

impl Default for PrepareParams {
    fn default() -> Self {
        Self {
            units: None,
            up: None,
            target_faces: DEFAULT_TARGET_FACES,
            max_faces: DEFAULT_MAX_FACES,
            iterations: 5,
            second_body_ratio: 0.2,
        }
    }
}

/// Everything preparation changed and found. Serialises to the JSON `skintight body prepare` prints.
#[derive(Clone, Debug, Serialize)]
pub struct PrepareReport {
    /// The result is closed (every edge has two faces).
    pub closed: bool,
    /// The result is a 2-manifold.
    pub manifold: bool,
    /// Genus of the result (0 for a body).
    pub genus: i64,
    /// Faces of the result.
    pub faces: usize,
    /// Vertices of the result.
    pub vertices: usize,
    /// Faces of the scan as read.
    pub input_faces: usize,
    /// Vertices of the scan as read.
    pub input_vertices: usize,
    /// Components dropped besides the body (noise islands, small debris).
    pub components_removed: usize,
    /// Faces in those components.
    pub island_faces_removed: usize,
    /// Holes closed.
    pub holes_filled: usize,
    /// Each hole: boundary edges and rim length (m).
    pub holes: Vec<FilledHole>,
    /// Non-manifold and orientation repairs.
    pub repairs: RepairSummary,
    /// Area-weighted mean signed distance of the remeshed surface from the scan before the unbiased fit
    /// (negative: inside; the chords of a remeshed convex surface lie inside it) (mm).
    pub fit_signed_mean_before_mm: Real,
    /// The same after the fit (mm).
    pub fit_signed_mean_after_mm: Real,
    /// Largest move of a vertex in the fit (mm).
    pub fit_max_displacement_mm: Real,
    /// Self-intersecting face pairs found after remeshing and smoothed away.
    pub self_intersections_removed: usize,
    /// Mean distance from the scan to the result, sampled at the scan's vertices weighted by their share of
    /// the scan's area (mm).
    pub mean_deviation_mm: Real,
    /// Largest distance between the scan and the result, both ways, sampled at vertices; the hole
    /// patches, where the scan has no data, are left out (mm).
    pub hausdorff_mm: Real,
    /// Units of the scan (`mm`, `cm`, `m`).
    pub units: &'static str,
    /// Whether they were detected (not declared).
    pub units_detected: bool,
    /// Up axis of the scan (`+z`, …).
    pub up: String,
    /// Whether it was detected.
    pub up_detected: bool,
    /// Forward direction of the scan, in its coordinates.
    pub facing: [Real; 3],
    /// Whether the forward direction was found from the feet (else the up axis's convention).
    pub facing_detected: bool,
    /// Height of the body (m).
    pub height_m: Real,
    /// Target edge length (mm).
    pub target_edge_mm: Real,
    /// Mean edge length of the result (mm).
    pub mean_edge_mm: Real,
    /// Wall time of each stage (s): `components_and_frame`, `repair_and_fill`, `remesh`,
    /// `fair_fit_and_check`, `deviation`.
    pub timing_s: std::collections::BTreeMap<&'static str, Real>,
}

/// Why a scan cannot be prepared. Each message is one line naming the problem.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PrepareError {
    #[error("the scan is empty: it has no faces")]
    Empty,
    #[error("the scan has {faces} faces, above the limit of {limit}")]
    TooManyFaces { faces: usize, limit: usize },
    #[error("{0}")]
    Read(String),
    #[error(
        "the scan holds two bodies of similar size (the second has {ratio:.0} % of the first's area): scan one person at a time"
    )]
    TwoBodies { ratio: Real },
    #[error("{0}")]
    Frame(#[from] FrameError),
    #[error("the scan is not a standing human body: {0}")]
    NotABody(String),
    #[error(
        "the body surface has genus {genus} (handles, e.g. arms touching the torso): rescan with the arms apart"
    )]
    NotGenusZero { genus: i64 },
    #[error("{0}")]
    Failed(String),
}

/// Faces a mesh file declares, told from its header where the format has one (PLY, binary STL) or by
/// counting face records (OBJ, ASCII STL); `None` for glTF binary.
pub fn declared_faces(bytes: &[u8], format: MeshFormat) -> Option<usize> {
    match format {
        MeshFormat::Ply => {
            let head = &bytes[..bytes.len().min(1 << 16)];
            let text = String::from_utf8_lossy(head);
            for line in text.lines() {
                let mut w = line.split_whitespace();
                if w.next() == Some("element") && w.next() == Some("face") {
                    return w.next().and_then(|n| n.parse().ok());
                }
                if line.trim() == "end_header" {
                    break;
                }
            }
            None
        }
        MeshFormat::Stl => {
            if bytes.len() >= 84 && !bytes.starts_with(b"solid") {
                Some(u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize)
            } else {
                Some(bytes.windows(5).filter(|w| w == b"facet").count())
            }
        }
        MeshFormat::Obj => Some(
            bytes
                .split(|&c| c == b'\n')
                .filter(|l| l.starts_with(b"f ") || l.starts_with(b"f\t"))
                .count(),
        ),
        MeshFormat::Glb => None,
    }
}

/// Reads a scan file, refusing an empty file and one of more than `max_faces` faces before reading its
/// faces.
pub fn read_scan(path: &Path, max_faces: usize) -> Result<TriMesh, PrepareError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| {
        PrepareError::Read(
            MeshIoError::UnknownFormat {
                name: path.display().to_string(),
            }
            .to_string(),
        )
    })?;
    let bytes = std::fs::read(path)
        .map_err(|e| PrepareError::Read(format!("cannot read {}: {e}", path.display())))?;
    read_scan_bytes(&bytes, format, max_faces)
}

/// [`read_scan`] on the bytes of a file.
pub fn read_scan_bytes(
    bytes: &[u8],
    format: MeshFormat,
    max_faces: usize,
) -> Result<TriMesh, PrepareError> {
    if bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return Err(PrepareError::Empty);
    }
    if let Some(n) = declared_faces(bytes, format).filter(|&n| n > max_faces) {
        return Err(PrepareError::TooManyFaces {
            faces: n,
            limit: max_faces,
        });
    }
    let mesh = read_mesh_bytes(bytes, format).map_err(|e| PrepareError::Read(e.to_string()))?;
    if mesh.num_faces() > max_faces {
        return Err(PrepareError::TooManyFaces {
            faces: mesh.num_faces(),
            limit: max_faces,
        });
    }
    Ok(mesh)
}

/// Prepares a raw scan as a body surface; see the module documentation.
pub fn prepare_scan(
    scan: &TriMesh,
    params: &PrepareParams,
) -> Result<(TriMesh, PrepareReport), PrepareError> {
    if scan.num_faces() == 0 {
        return Err(PrepareError::Empty);
    }
    if scan.num_faces() > params.max_faces {
        return Err(PrepareError::TooManyFaces {
            faces: scan.num_faces(),
            limit: params.max_faces,
        });
    }
    if params.target_faces < 100 || params.target_faces > 2_000_000 {
        return Err(PrepareError::Failed(format!(
            "target_faces must be within 100–2000000, got {}",
            params.target_faces
        )));
    }
    let mut timing = std::collections::BTreeMap::new();
    let mut clock = std::time::Instant::now();
    let mut lap = |name: &'static str,
                   timing: &mut std::collections::BTreeMap<&'static str, Real>| {
        timing.insert(name, clock.elapsed().as_secs_f64());
        clock = std::time::Instant::now();
    };
    // 1. Valid faces, components.
    let nv = scan.num_vertices();
    let valid = |f: &[usize; 3]| {
        f.iter()
            .all(|&v| v < nv && scan.positions[v].iter().all(|x| x.is_finite()))
    };
    let cleaned = keep_faces(scan, |f| valid(&scan.faces[f]));
    if cleaned.num_faces() == 0 {
        return Err(PrepareError::Empty);
    }
    let comps = components(&cleaned);
    if comps.areas.len() > 1 && comps.areas[1] >= params.second_body_ratio * comps.areas[0] {
        return Err(PrepareError::TwoBodies {
            ratio: 100.0 * comps.areas[1] / comps.areas[0],
        });
    }
    let mut components_removed = comps.areas.len() - 1;
    let mut island_faces_removed: usize = comps.faces[1..].iter().sum();
    let mut body = keep_faces(&cleaned, |f| comps.face_component[f] == 0);
    // 2. Frame.
    let frame = detect_frame(&body.positions, &body.faces, params.units, params.up)?;
    apply_frame(&mut body.positions, &frame);
    let (lo, hi) = body.bounding_box().ok_or(PrepareError::Empty)?;
    let ext = hi - lo;
    let (h, w, d) = (ext.y, ext.x, ext.z);
    if d > 0.4 * h {
        return Err(PrepareError::NotABody(format!(
            "it is {:.2} m deep front to back for {:.2} m tall (a standing body is at most 0.4 × its height deep)",
            d, h
        )));
    }
    if w > 1.1 * h {
        return Err(PrepareError::NotABody(format!(
            "it is {:.2} m wide for {:.2} m tall (a standing body is at most 1.1 × its height wide)",
            w, h
        )));
    }
    lap("components_and_frame", &mut timing);
    // 3. Manifold repair.
    let (repaired, repairs) = repair_non_manifold(&body);
    let comps = components(&repaired);
    if comps.areas.is_empty() {
        return Err(PrepareError::Empty);
    }
    components_removed += comps.areas.len() - 1;
    island_faces_removed += comps.faces[1..].iter().sum::<usize>();
    let mut filled = keep_faces(&repaired, |f| comps.face_component[f] == 0);
    // 4. Holes.
    let scan_vertices = filled.num_vertices();
    let (holes, first_patch_face) = fill_holes_with_fans(&mut filled);
    let report0 = mesh_report(&filled, &MeshCheckParams::default());
    if !report0.closed || !report0.manifold {
        return Err(PrepareError::Failed(format!(
            "the repaired scan is not a closed manifold: {}",
            report0.problems.first().cloned().unwrap_or_default()
        )));
    }
    let genus = (2 - report0.euler_characteristic) / 2;
    if genus != 0 {
        return Err(PrepareError::NotGenusZero { genus });
    }
    if filled.signed_volume() < 0.0 {
        filled.flip_orientation();
    }
    let volume = filled.signed_volume();
    if !(volume.is_finite() && volume >= MIN_BODY_VOLUME_M3) {
        return Err(PrepareError::NotABody(format!(
            "once closed it encloses {:.1} L (a standing body encloses at least {:.0} L)",
            1e3 * volume,
            1e3 * MIN_BODY_VOLUME_M3
        )));
    }
    lap("repair_and_fill", &mut timing);
    // 5. Remesh on the filled scan.
    let area = filled.area();
    let target_edge = (4.0 * area / (3f64.sqrt() * params.target_faces as Real)).sqrt();
    if !(target_edge.is_finite() && target_edge >= 1e-3) {
        return Err(PrepareError::Failed(format!(
            "the target edge length {:.2} mm is below 1 mm: lower target_faces",
            1e3 * target_edge
        )));
    }
    let cell = 2.0 * mean_edge_length(&filled.positions, &filled.faces);
    let reference = ClosestPointGrid::new(&filled.positions, &filled.faces, cell);
    let remesh = IsotropicRemeshParams {
        target_edge,
        iterations: 2.min(params.iterations),
        max_collapse_error: 0.1 * target_edge,
        max_faces: 8 * params.target_faces + filled.num_faces(),
    };
    let uniform = isotropic_remesh(&filled, &reference, &remesh);
    // Then graded by curvature: shorter edges where the body bends sharply (wrists, ankles, fingers), so
    // that tape-measure girths there are not those of a coarse polygon.
    // (Flat parts keep the uniform length: a field scaled to keep the face count coarsens the soles, whose
    // faired hole patch then bulges further below the scan, moving the floor of every landmark height.)
    let sizes = curvature_sizing(&uniform.mesh, &SizingParams::for_edge_length(target_edge));
    let out = adaptive_remesh(
        &uniform.mesh,
        &reference,
        &IsotropicRemeshParams {
            iterations: params.iterations.saturating_sub(2).max(1),
            ..remesh
        },
        &sizes,
    );
    lap("remesh", &mut timing);
    let mut result = out.mesh;
    let on_patch: Vec<bool> = out
        .reference_face
        .iter()
        .map(|&f| f != u32::MAX as usize && f >= first_patch_face)
        .collect();
    fair(&mut result.positions, &result.faces, &on_patch, 500);
    // The scan without the hole patches: the unbiased fit and the deviation measure against it.
    let scan_grid =
        ClosestPointGrid::new(&filled.positions, &filled.faces[..first_patch_face], cell);
    let fit = unbiased_fit(
        &mut result,
        &scan_grid,
        &on_patch,
        &FitParams::for_edge_length(target_edge),
    );
    // 6. Self-intersections (a coarse triangle cutting through a thin part, e.g. the nose): smoothed away
    // by Laplacian smoothing of the faces involved and their neighbours, a growing number of steps.
    let mut self_intersections_removed = 0;
    for round in 0..12 {
        let pairs = self_intersections(&result.positions, &result.faces, 0.0);
        if round == 0 {
            self_intersections_removed = pairs.len();
        }
        if pairs.is_empty() {
            break;
        }
        if round == 11 {
            return Err(PrepareError::Failed(format!(
                "the remeshed body still intersects itself at {} face pairs",
                pairs.len()
            )));
        }
        let mut free = vec![false; result.num_vertices()];
        for (f, g) in pairs {
            for v in result.faces[f].iter().chain(&result.faces[g]) {
                free[*v] = true;
            }
        }
        // Grow by one ring, then Laplacian smoothing of the marked vertices.
        let mut grown = free.clone();
        for f in &result.faces {
            if f.iter().any(|&v| free[v]) {
                for &v in f {
                    grown[v] = true;
                }
            }
        }
        laplacian_smooth(&mut result, &grown, 3 + round);
    }
    if result.signed_volume() < 0.0 {
        result.flip_orientation();
    }
    let r = mesh_report(&result, &MeshCheckParams::default());
    let genus = r.genus.unwrap_or(-1);
    if !r.closed || !r.manifold || genus != 0 {
        return Err(PrepareError::Failed(format!(
            "the remeshed body is not a closed genus-0 manifold: {}",
            r.problems.first().cloned().unwrap_or_default()
        )));
    }
    lap("fair_fit_and_check", &mut timing);
    // Deviation: scan vertices → result; result vertices off the patches → scan.
    let result_grid = ClosestPointGrid::new(&result.positions, &result.faces, 2.0 * target_edge);
    let scan_area = vertex_areas(&filled.positions, &filled.faces[..first_patch_face]);
    let scan_to_result = deviation_of_points(
        &filled.positions,
        |v| if v < scan_vertices { scan_area[v] } else { 0.0 },
        &result_grid,
    );
    let result_to_scan = deviation_of_points(
        &result.positions,
        |v| if on_patch[v] { 0.0 } else { 1.0 },
        &scan_grid,
    );
    lap("deviation", &mut timing);
    let report = PrepareReport {
        closed: r.closed,
        manifold: r.manifold,
        genus,
        faces: result.num_faces(),
        vertices: result.num_vertices(),
        input_faces: scan.num_faces(),
        input_vertices: scan.num_vertices(),
        components_removed,
        island_faces_removed,
        holes_filled: holes.len(),
        holes,
        repairs,
        fit_signed_mean_before_mm: 1e3 * fit.signed_mean_before,
        fit_signed_mean_after_mm: 1e3 * fit.signed_mean_after,
        fit_max_displacement_mm: 1e3 * fit.max_displacement,
        self_intersections_removed,
        mean_deviation_mm: 1e3 * scan_to_result.mean,
        hausdorff_mm: 1e3 * scan_to_result.max.max(result_to_scan.max),
        units: frame.units.name(),
        units_detected: frame.units_detected,
        up: frame.up.name(),
        up_detected: frame.up_detected,
        facing: [frame.front.x, frame.front.y, frame.front.z],
        facing_detected: frame.facing_detected,
        height_m: frame.height_m,
        target_edge_mm: 1e3 * target_edge,
        mean_edge_mm: 1e3 * mean_edge_length(&result.positions, &result.faces),
        timing_s: timing,
    };
    Ok((result, report))
}

/// Uniform Laplacian smoothing of the marked vertices (λ = 0.5).
fn laplacian_smooth(mesh: &mut TriMesh, free: &[bool], iterations: usize) {
    let nv = mesh.num_vertices();
    for _ in 0..iterations {
        let mut sum = vec![Vec3::zeros(); nv];
        let mut count = vec![0usize; nv];
        for f in &mesh.faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                if free[a] {
                    sum[a] += mesh.positions[b];
                    count[a] += 1;
                }
                if free[b] {
                    sum[b] += mesh.positions[a];
                    count[b] += 1;
                }
            }
        }
        for v in 0..nv {
            if free[v] && count[v] > 0 {
                let q = sum[v] / count[v] as Real;
                let d = q - mesh.positions[v];
                mesh.positions[v] += 0.5 * d;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::icosphere;

    #[test]
    fn empty_and_huge_files_are_refused_before_reading() {
        assert_eq!(
            read_scan_bytes(b"", MeshFormat::Ply, 10),
            Err(PrepareError::Empty)
        );
        let header = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 10000000\nproperty list uchar int vertex_indices\nend_header\n";
        let e = read_scan_bytes(header, MeshFormat::Ply, DEFAULT_MAX_FACES).unwrap_err();
        assert!(
            e.to_string().contains("10000000 faces, above the limit"),
            "{e}"
        );
        assert_eq!(
            prepare_scan(&TriMesh::default(), &PrepareParams::default()).unwrap_err(),
            PrepareError::Empty
        );
    }

    /// Random triangle soups and a torn, stretched sphere end in a result or an error, never a panic.
    #[test]
    fn junk_never_panics() {
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as Real) / ((1u64 << 53) as Real)
        };
        for n in [1usize, 3, 50, 400] {
            let positions: Vec<Vec3> = (0..3 * n)
                .map(|_| Vec3::new(0.5 * next(), 1.7 * next(), 0.3 * next()))
                .collect();
            let faces: Vec<[usize; 3]> = (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
            let _ = prepare_scan(&TriMesh::new(positions, faces), &PrepareParams::default());
        }
        let mut m = icosphere(3, 1.0);
        for p in &mut m.positions {
            *p = Vec3::new(0.2 * p.x, 0.85 * p.y, 0.12 * p.z);
        }
        let nf = m.faces.len();
        m.faces.retain(|_| next() > 0.05);
        assert!(m.faces.len() < nf);
        m.positions.push(Vec3::new(Real::NAN, 0.0, 0.0));
        let nan = m.positions.len() - 1;
        m.faces.push([0, 1, nan]);
        m.faces.push([0, 0, 1]);
        if let Ok((body, report)) = prepare_scan(&m, &PrepareParams::default()) {
            assert!(report.closed && report.genus == 0);
            assert!(
                body.positions
                    .iter()
                    .all(|p| p.iter().all(|x| x.is_finite()))
            );
            assert!(report.mean_deviation_mm.is_finite() && report.hausdorff_mm.is_finite());
        }
    }

    #[test]
    fn a_ball_is_not_a_body() {
        let m = icosphere(2, 0.9);
        let e = prepare_scan(&m, &PrepareParams::default()).unwrap_err();
        assert!(e.to_string().contains("not a standing human body"), "{e}");
    }

    #[test]
    fn two_people_are_refused() {
        let body =
            crate::mesh::io::read_mesh(&crate::test_meshes::body("regular_370.obj")).unwrap();
        let mut two = body.clone();
        let n = two.num_vertices();
        two.positions
            .extend(body.positions.iter().map(|p| p + Vec3::new(1.2, 0.0, 0.0)));
        two.faces
            .extend(body.faces.iter().map(|f| f.map(|v| v + n)));
        let e = prepare_scan(&two, &PrepareParams::default()).unwrap_err();
        assert!(matches!(e, PrepareError::TwoBodies { .. }), "{e}");
    }
}
