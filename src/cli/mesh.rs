//! `skintight mesh …`: inspect and convert mesh files (OBJ, PLY, STL, glTF binary).

use std::path::{Path, PathBuf};

use clap::Subcommand;
use serde::Serialize;
use skintight_geometry::mesh::io::{
    MeshFormat, MeshIoError, PlyEncoding, WriteParams, read_mesh, write_mesh,
};
use skintight_geometry::{MeshCheckParams, MeshReport, TriMesh, body_surface, mesh_report};

use super::CliError;

/// The `mesh` subcommands.
#[derive(Debug, Subcommand)]
pub enum MeshCommand {
    /// Prints a JSON report on a mesh file (counts, closedness, manifoldness, genus, components, area in m²,
    /// volume in m³, every problem found). Exits 0 when the mesh can serve as a body, 1 (after the report,
    /// with the first problem on standard error) when it cannot, 2 when the file cannot be read.
    #[command(after_help = super::EXIT_MESH)]
    Inspect {
        /// The mesh file: .obj, .ply, .stl or .glb.
        file: PathBuf,
    },
    /// Converts a mesh file to another format, chosen by the output's extension (.obj, .ply, .stl, .glb).
    #[command(after_help = super::EXIT_MESH)]
    Convert {
        /// The mesh file to read.
        input: PathBuf,
        /// The file to write.
        output: PathBuf,
        /// Write PLY as text instead of binary little-endian.
        #[arg(long)]
        ascii: bool,
    },
}

/// Runs one `mesh` subcommand.
pub fn run(command: MeshCommand) -> Result<(), CliError> {
    match command {
        MeshCommand::Inspect { file } => inspect(&file),
        MeshCommand::Convert {
            input,
            output,
            ascii,
        } => convert(&input, &output, ascii),
    }
}

/// A face group and its size.
#[derive(Serialize)]
struct Group<'a> {
    name: &'a str,
    faces: usize,
}

/// What `mesh inspect` prints.
#[derive(Serialize)]
struct Inspection<'a> {
    file: String,
    format: MeshFormat,
    #[serde(flatten)]
    report: &'a MeshReport,
    groups: Vec<Group<'a>>,
    usable_as_body: bool,
    /// Repairs that loading it as a body would make.
    warnings: Vec<String>,
}

fn read(path: &Path) -> Result<TriMesh, CliError> {
    read_mesh(path).map_err(|e| {
        CliError::Input(match e {
            MeshIoError::Read { .. } | MeshIoError::UnknownFormat { .. } => e.to_string(),
            _ => format!("{}: {e}", path.display()),
        })
    })
}

fn inspect(path: &Path) -> Result<(), CliError> {
    let mesh = read(path)?;
    let format = MeshFormat::from_path(path).expect("read_mesh accepted the extension");
    let params = MeshCheckParams::default();
    let report = mesh_report(&mesh, &params);
    let mut groups: Vec<Group<'_>> = mesh
        .group_names
        .iter()
        .map(|name| Group { name, faces: 0 })
        .collect();
    for &g in &mesh.face_groups {
        if let Some(group) = groups.get_mut(g as usize) {
            group.faces += 1;
        }
    }
    let body = body_surface(mesh.clone(), &params);
    let inspection = Inspection {
        file: path.display().to_string(),
        format,
        report: &report,
        groups,
        usable_as_body: body.is_ok(),
        warnings: body
            .as_ref()
            .map(|b| b.warnings.clone())
            .unwrap_or_default(),
    };
    let json = serde_json::to_string_pretty(&inspection)
        .map_err(|e| CliError::Failed(format!("cannot write the report as JSON: {e}")))?;
    println!("{json}");
    match body {
        Ok(_) => Ok(()),
        Err(issue) => Err(CliError::Failed(format!(
            "{}: cannot serve as a body: {issue}",
            path.display()
        ))),
    }
}

fn convert(input: &Path, output: &Path, ascii: bool) -> Result<(), CliError> {
    if MeshFormat::from_path(output).is_none() {
        return Err(CliError::Input(format!(
            "cannot tell the format to write from {:?}: use .obj, .ply, .stl or .glb",
            output.display().to_string()
        )));
    }
    let mesh = read(input)?;
    let params = WriteParams {
        ply_encoding: if ascii {
            PlyEncoding::Ascii
        } else {
            PlyEncoding::BinaryLittleEndian
        },
        ..Default::default()
    };
    write_mesh(output, &mesh, &params).map_err(|e| match e {
        MeshIoError::Unwritable { .. } => CliError::Input(format!("{}: {e}", input.display())),
        _ => CliError::Failed(e.to_string()),
    })?;
    println!(
        "wrote {}: {} vertices, {} triangles",
        output.display(),
        mesh.num_vertices(),
        mesh.num_faces()
    );
    Ok(())
}
