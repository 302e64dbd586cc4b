//! `skintight knit homogenize`: one patch's yarn-level sequences homogenized into a tetrahedral mesh with a
//! fitted material (`skintight_homogenize::homogenization`), written as a *material folder*:
//! `material.json` (the summary, every pose's error and the fit's stages), `mesh.vtu` (`gamma_s`, `gamma_v`
//! in Pa as cell data, for ParaView) and the mesh and material as NumPy arrays that [`read_material`] reads
//! back for `knit simulate` (`mesh_nodes.npy` `#V × 3` m, `mesh_tets.npy` `#T × 4`, `mesh_node_mass.npy`
//! `#V` kg, `embedding.npy` `#Y × 5` (tetrahedron, four barycentric weights), `gamma.npy` `#T × 2` Pa), and
//! `gamma_s.glb`, `gamma_v.glb`: the mesh's boundary coloured by each parameter with its legend
//! ([`gamma_glb`]); `fit_error.svg`: each pose's error, fitted and held out ([`fit_error_svg`]).
//! Fields: docs/OUTPUTS.md, "Homogenizing sequences".

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use serde_json::{Value, json};
use skintight_geometry::body::tet_io::vtu::VtuArray;
use skintight_homogenize::homogenization::{
    FrameFit, HomogenizationError, HomogenizationParams, HomogenizationProgress, LoadedSequence,
    homogenize,
};
use skintight_homogenize::volumetric_mesh::{Embedded, VolumetricMesh};
use skintight_knit::npy::{read_npy, write_npy_f64};

/// Why `knit homogenize` or `knit simulate` failed.
#[derive(Debug, thiserror::Error)]
pub enum KnitHomogenizeError {
    /// The input (a scene, a sequence, a material folder, a setting) cannot be used; the message names it.
    #[error("{0}")]
    Input(String),
    /// A file could not be written; the message names it.
    #[error("{0}")]
    Output(String),
    /// The method failed (a fit, an equilibrium, a time step).
    #[error("{0}")]
    Failed(String),
}

impl From<HomogenizationError> for KnitHomogenizeError {
    fn from(e: HomogenizationError) -> Self {
        match e {
            HomogenizationError::Method(_) => Self::Failed(e.to_string()),
            _ => Self::Input(e.to_string()),
        }
    }
}

/// The mesh's boundary (faces of one tetrahedron only, oriented outwards), each face flat-coloured by
/// component `c` of `γ` (0: `γˢ`, 1: `γᵛ`) of its tetrahedron on the ramp from the smallest to the largest
/// value, the legend (Pa) in the glTF's `extras`: the paper's Fig. 10 (right), viewable in any glTF viewer.
pub fn gamma_glb(
    mesh: &VolumetricMesh,
    gamma: &[[f64; 2]],
    c: usize,
) -> Result<Vec<u8>, KnitHomogenizeError> {
    use skintight_geometry::mesh::io::{WriteParams, write_glb};
    use skintight_geometry::{TriMesh, Vec3};
    let mut faces: std::collections::HashMap<[usize; 3], (usize, [usize; 3])> =
        std::collections::HashMap::new();
    for (t, tet) in mesh.tets.iter().enumerate() {
        for skip in 0..4 {
            let face: Vec<usize> = (0..4).filter(|&k| k != skip).map(|k| tet[k]).collect();
            let p = |n: usize| Vec3::from(mesh.rest[n]);
            let normal = (p(face[1]) - p(face[0])).cross(&(p(face[2]) - p(face[0])));
            let inward = normal.dot(&(p(tet[skip]) - p(face[0]))) > 0.0;
            let oriented = if inward {
                [face[0], face[2], face[1]]
            } else {
                [face[0], face[1], face[2]]
            };
            let mut key = oriented;
            key.sort_unstable();
            if faces.remove(&key).is_none() {
                faces.insert(key, (t, oriented));
            }
        }
    }
    let mut boundary: Vec<(usize, [usize; 3])> = faces.into_values().collect();
    boundary.sort_unstable();
    let values: Vec<f64> = gamma.iter().map(|g| g[c]).collect();
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut positions = Vec::with_capacity(3 * boundary.len());
    let mut colors = Vec::with_capacity(3 * boundary.len());
    let mut triangles = Vec::with_capacity(boundary.len());
    for (t, face) in &boundary {
        let color = crate::simulate::colormap::color(values[*t], lo, hi);
        triangles.push([positions.len(), positions.len() + 1, positions.len() + 2]);
        for &n in face {
            positions.push(Vec3::new(mesh.rest[n][0], mesh.rest[n][1], mesh.rest[n][2]));
            colors.push(color);
        }
    }
    let name = ["gamma_s", "gamma_v"][c.min(1)];
    let quantity = [
        "γˢ, the stiffness against rotation-free strain (Eq. 7)",
        "γᵛ, the stiffness against volume change (Eq. 7)",
    ][c.min(1)];
    let extras = crate::simulate::result::legend(quantity, "Pa", lo, hi);
    write_glb(
        &TriMesh::new(positions, triangles),
        &WriteParams {
            colors: Some(&colors),
            name: Some(name),
            extras: Some(&extras),
            ..Default::default()
        },
    )
    .map_err(|e| KnitHomogenizeError::Failed(format!("{name}.glb: {e}")))
}

/// `fit_error.svg`: each pose's mean error (mm) against its time, fitted poses as filled dots and held-out
/// ones as rings, with the Y2V floor (the error of the fitted shape itself) as a grey line.
pub fn fit_error_svg(frames: &[FrameFit]) -> String {
    use std::fmt::Write;
    let (w, h, left, bottom, top, right) = (640.0, 360.0, 64.0, 44.0, 28.0, 150.0);
    let t_max = frames
        .iter()
        .map(|f| f.time_s)
        .fold(0.0_f64, f64::max)
        .max(1e-9);
    let e_max = frames
        .iter()
        .map(|f| f.mean_error_m.max(f.shape_error_m))
        .fold(0.0_f64, f64::max)
        .max(1e-12)
        * 1e3
        * 1.1;
    let x = |t: f64| left + (w - left - right) * t / t_max;
    let y = |mm: f64| h - bottom - (h - bottom - top) * mm / e_max;
    let mut svg = format!(
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">
<title>Homogenized mesh: mean yarn error per pose</title>
<rect width="{w}" height="{h}" fill="white"/>
<line x1="{left}" y1="{yb}" x2="{xr}" y2="{yb}" stroke="black"/>
<line x1="{left}" y1="{top}" x2="{left}" y2="{yb}" stroke="black"/>
<text x="{xm}" y="{yt}" text-anchor="middle">time (s), 0 … {t_max:.3}</text>
<text x="14" y="{ym}" transform="rotate(-90 14 {ym})" text-anchor="middle">mean error (mm), 0 … {e_max:.3}</text>
"##,
        yb = h - bottom,
        xr = w - right,
        xm = left + 0.5 * (w - left - right),
        yt = h - 12.0,
        ym = top + 0.5 * (h - bottom - top),
    );
    let floor: Vec<String> = frames
        .iter()
        .map(|f| format!("{:.1},{:.1}", x(f.time_s), y(f.shape_error_m * 1e3)))
        .collect();
    let _ = writeln!(
        svg,
        r##"<polyline points="{}" fill="none" stroke="#999" stroke-width="1.5"/>"##,
        floor.join(" ")
    );
    for f in frames {
        let (fill, r) = if f.training {
            ("#1f5fa8", 4.0)
        } else {
            ("white", 4.5)
        };
        let _ = writeln!(
            svg,
            r##"<circle cx="{:.1}" cy="{:.1}" r="{r}" fill="{fill}" stroke="#1f5fa8" stroke-width="1.5"><title>frame {} ({}): {:.3} mm</title></circle>"##,
            x(f.time_s),
            y(f.mean_error_m * 1e3),
            f.frame,
            if f.training { "fitted" } else { "held out" },
            f.mean_error_m * 1e3
        );
    }
    let lx = w - right + 16.0;
    let _ = write!(
        svg,
        r##"<circle cx="{lx}" cy="40" r="4" fill="#1f5fa8"/><text x="{tx}" y="44">fitted</text>
<circle cx="{lx}" cy="60" r="4.5" fill="white" stroke="#1f5fa8" stroke-width="1.5"/><text x="{tx}" y="64">held out</text>
<line x1="{l0}" y1="80" x2="{l1}" y2="80" stroke="#999" stroke-width="1.5"/><text x="{tx}" y="84">Y2V floor</text>
</svg>
"##,
        tx = lx + 10.0,
        l0 = lx - 6.0,
        l1 = lx + 6.0,
    );
    svg
}

/// The NumPy arrays of a material folder: `(file, shape, data)`.
fn material_arrays(
    mesh: &VolumetricMesh,
    gamma: &[[f64; 2]],
) -> Vec<(&'static str, Vec<usize>, Vec<f64>)> {
    let (v, t, y) = (mesh.rest.len(), mesh.tets.len(), mesh.embedding.len());
    vec![
        (
            "mesh_nodes.npy",
            vec![v, 3],
            mesh.rest.iter().flatten().copied().collect(),
        ),
        (
            "mesh_tets.npy",
            vec![t, 4],
            mesh.tets.iter().flatten().map(|&i| i as f64).collect(),
        ),
        ("mesh_node_mass.npy", vec![v], mesh.node_mass.clone()),
        (
            "embedding.npy",
            vec![y, 5],
            mesh.embedding
                .iter()
                .flat_map(|e| {
                    [
                        e.tet as f64,
                        e.weights[0],
                        e.weights[1],
                        e.weights[2],
                        e.weights[3],
                    ]
                })
                .collect(),
        ),
        (
            "gamma.npy",
            vec![t, 2],
            gamma.iter().flatten().copied().collect(),
        ),
    ]
}

/// Reads the mesh and `γ` (`#T × 2`, Pa) of a material folder written by `knit homogenize`; errors name the
/// file.
pub fn read_material(dir: &Path) -> Result<(VolumetricMesh, Vec<[f64; 2]>), KnitHomogenizeError> {
    let read = |name: &str, columns: usize| -> Result<Vec<Vec<f64>>, KnitHomogenizeError> {
        let path = dir.join(name);
        let bad = |why: String| {
            KnitHomogenizeError::Input(format!(
                "{}: {why} (a material folder is written by `skintight knit homogenize`)",
                path.display()
            ))
        };
        let a = read_npy(&path).map_err(|e| bad(e.to_string()))?;
        let per = a.shape.iter().skip(1).product::<usize>().max(1);
        if per != columns || a.data.len() % columns != 0 {
            return Err(bad(format!(
                "has shape {:?}, expected (n, {columns})",
                a.shape
            )));
        }
        if let Some(i) = a.data.iter().position(|x| !x.is_finite()) {
            return Err(bad(format!("entry {i} is not finite")));
        }
        Ok(a.data.chunks_exact(columns).map(<[f64]>::to_vec).collect())
    };
    let nodes = read("mesh_nodes.npy", 3)?;
    let index = |x: f64, n: usize, what: &str| -> Result<usize, KnitHomogenizeError> {
        if x >= 0.0 && x.fract() == 0.0 && (x as usize) < n {
            Ok(x as usize)
        } else {
            Err(KnitHomogenizeError::Input(format!(
                "{}: {what} index {x} is not one of the {n} {what}s",
                dir.display()
            )))
        }
    };
    let tets = read("mesh_tets.npy", 4)?
        .iter()
        .map(|t| {
            Ok([
                index(t[0], nodes.len(), "node")?,
                index(t[1], nodes.len(), "node")?,
                index(t[2], nodes.len(), "node")?,
                index(t[3], nodes.len(), "node")?,
            ])
        })
        .collect::<Result<Vec<_>, KnitHomogenizeError>>()?;
    let node_mass: Vec<f64> = read("mesh_node_mass.npy", 1)?
        .into_iter()
        .map(|m| m[0])
        .collect();
    let embedding = read("embedding.npy", 5)?
        .iter()
        .map(|e| {
            Ok(Embedded {
                tet: index(e[0], tets.len(), "tetrahedron")?,
                weights: [e[1], e[2], e[3], e[4]],
            })
        })
        .collect::<Result<Vec<_>, KnitHomogenizeError>>()?;
    let gamma: Vec<[f64; 2]> = read("gamma.npy", 2)?.iter().map(|g| [g[0], g[1]]).collect();
    if node_mass.len() != nodes.len() || gamma.len() != tets.len() {
        return Err(KnitHomogenizeError::Input(format!(
            "{}: {} node masses for {} nodes, {} material rows for {} tetrahedra",
            dir.display(),
            node_mass.len(),
            nodes.len(),
            gamma.len(),
            tets.len()
        )));
    }
    let mesh = VolumetricMesh {
        rest: nodes.iter().map(|p| [p[0], p[1], p[2]]).collect(),
        tets,
        node_mass,
        embedding,
    };
    mesh.validate()
        .map_err(|e| KnitHomogenizeError::Input(format!("{}: {e}", dir.display())))?;
    Ok((mesh, gamma))
}

/// Homogenizes the sequences in `dirs` with `params` into the folder `out` (created), calling `progress`
/// at every Gauss-Newton iteration; returns the summary it also writes at the top of `material.json`.
pub fn homogenize_sequences(
    dirs: &[PathBuf],
    out: &Path,
    params: &HomogenizationParams,
    progress: impl FnMut(&HomogenizationProgress) -> ControlFlow<()>,
) -> Result<Value, KnitHomogenizeError> {
    let sequences = dirs
        .iter()
        .map(|d| LoadedSequence::read(d))
        .collect::<Result<Vec<_>, _>>()?;
    let fit = homogenize(&sequences, params, progress)?;
    let failed = |path: &Path, e: &dyn std::fmt::Display| {
        KnitHomogenizeError::Output(format!("{}: {e}", path.display()))
    };
    std::fs::create_dir_all(out).map_err(|e| failed(out, &e))?;
    let cells = |c: usize, name: &str| {
        VtuArray::Scalars(name.into(), fit.gamma.iter().map(|g| g[c]).collect())
    };
    for (name, shape, data) in material_arrays(&fit.mesh, &fit.gamma) {
        let path = out.join(name);
        write_npy_f64(&path, &shape, &data).map_err(|e| failed(&path, &e))?;
    }
    for c in 0..2 {
        let path = out.join(["gamma_s.glb", "gamma_v.glb"][c]);
        let bytes = gamma_glb(&fit.mesh, &fit.gamma, c)?;
        std::fs::write(&path, bytes).map_err(|e| failed(&path, &e))?;
    }
    let plot = out.join("fit_error.svg");
    std::fs::write(&plot, fit_error_svg(&fit.frames)).map_err(|e| failed(&plot, &e))?;
    let vtu = out.join("mesh.vtu");
    fit.mesh
        .write_vtu(&vtu, &[cells(0, "gamma_s"), cells(1, "gamma_v")])
        .map_err(|e| failed(&vtu, &e))?;
    let mean = |c: usize| fit.gamma.iter().map(|g| g[c]).sum::<f64>() / fit.gamma.len() as f64;
    let summary = json!({
        "pattern": sequences[0].meta.pattern,
        "sequences": dirs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
        "yarn_dofs": fit.report.yarn_dofs,
        "mesh_dofs": fit.report.mesh_dofs,
        "elements": fit.report.elements,
        "ratio": fit.report.ratio,
        "voxel_m": fit.report.voxel_m,
        "patch_size_m": fit.report.patch_size_m,
        "train_every": params.train_every,
        "ranks": params.ranks,
        "per_element": params.per_element,
        "gamma_mean_pa": [mean(0), mean(1)],
        "gauss_newton_iterations": fit.gauss_newton_iterations(),
        "fit_seconds": fit.fit_seconds,
        "seconds": fit.seconds,
        "mean_error_training_m": fit.mean_error(true),
        "mean_error_held_out_m": fit.mean_error(false),
    });
    let mut material = summary.clone();
    material["frames"] = json!(fit.frames);
    material["stages"] = json!(fit.stages);
    let path = out.join("material.json");
    let text = serde_json::to_string_pretty(&material).map_err(|e| failed(&path, &e))?;
    std::fs::write(&path, text).map_err(|e| failed(&path, &e))?;
    Ok(summary)
}
