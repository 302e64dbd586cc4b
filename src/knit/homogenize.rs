//! `skintight knit homogenize`: one patch's yarn-level sequences homogenized into a tetrahedral mesh with a
//! fitted material (`skintight_homogenize::homogenization`), written as a *material folder*:
//! `material.json` (the summary, every pose's error and the fit's stages), `mesh.vtu` (`gamma_s`, `gamma_v`
//! in Pa as cell data, for ParaView) and the mesh and material as NumPy arrays that [`read_material`] reads
//! back for `knit simulate` (`mesh_nodes.npy` `#V × 3` m, `mesh_tets.npy` `#T × 4`, `mesh_node_mass.npy`
//! `#V` kg, `embedding.npy` `#Y × 5` (tetrahedron, four barycentric weights), `gamma.npy` `#T × 2` Pa).
//! Fields: docs/OUTPUTS.md, "Homogenizing sequences".

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use serde_json::{Value, json};
use skintight_geometry::body::tet_io::vtu::VtuArray;
use skintight_homogenize::homogenization::{
    HomogenizationError, HomogenizationParams, HomogenizationProgress, LoadedSequence, homogenize,
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
