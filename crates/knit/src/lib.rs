//! Yarn-level knitwear for skintight (issue 19, part 1): periodic yarn patterns as discrete elastic rods,
//! their tiling into patches, the rod and contact energies with exact derivatives, and the quasi-static
//! solve of one periodic cell under a prescribed in-plane deformation, compared with the published
//! yarn-level displacements of MADYPG/HYLC (Sperl et al. 2020, 2021).
//!
//! Units: SI throughout — positions and lengths in m, angles in rad, energies in J, forces in N, torques in
//! N·m, stiffnesses as stated on each quantity.
//!
//! Layout:
//! - [`pyp`]: the `.pyp` periodic pattern reader; [`npy`] and [`published_response`]: the published
//!   displacement table (`data.npy`, `axes.txt`) and its interpolation;
//! - [`tile`]: tiling a pattern into an `nx × ny` patch of continuous yarns, OBJ polylines;
//! - [`jet`]: second-order forward automatic differentiation; [`frames`]: rod frames and strains;
//! - energies, one per file: [`stretching`], [`bending`], [`twisting`] (both at once: [`rod_vertex`]),
//!   [`contact`] (with
//!   [`segment_distance`] and the candidate search [`spatial_hash`]), [`yarn_friction`] (a time step's
//!   friction on the contact's point pairs; over a whole patch: [`patch_friction`], a term of
//!   [`implicit_euler`]'s steps);
//! - [`yarn_params`]: the yarn's material parameters and their sources;
//! - [`periodic_cell`]: the energy of one periodic cell under a macro deformation, [`newton`]: the damped
//!   Newton solve, [`cell_check`]: the comparison with the published displacements;
//! - finite patches in time: [`patch`] (the energy of a tiled patch with [`gravity`], a
//!   [`sphere_contact`] obstacle and the bonds of its [`edge_finish`]), [`implicit_euler`] (backward Euler as incremental-potential
//!   minimisation with clamped and moving vertices), [`frame_sequence`] (the simulated frames on disk),
//!   [`sequence_compare`] (two sequences of one patch compared frame by frame in time), [`tubes`]
//!   (yarns as tube meshes for `.glb`);
//! - measured fabrics: [`measured_stretch`] (the vendored uniaxial force–extension curves of Singal et
//!   al. 2024 and a simulated curve compared with them; the pull itself is the app's `knit stretch-test`).
//!
//! The scenes of `skintight knit simulate-yarn` (their JSON, set-up, run, outputs and checkpoints) are app
//! code: the app crate's `src/knit/`, as the garment scenes are its `src/scene/` and `src/simulate/`.

// Index loops over small fixed-size arrays (3-vectors, stencil unknowns) read like the equations.
#![allow(clippy::needless_range_loop)]

pub mod bending;
pub mod cell_check;
pub mod contact;
pub mod edge_finish;
pub mod fitted_sheet_energy;
pub mod frame_sequence;
pub mod frames;
pub mod gravity;
pub mod implicit_euler;
pub mod jet;
pub mod measured_stretch;
pub mod newton;
pub mod npy;
pub mod patch;
pub mod patch_friction;
pub mod periodic_cell;
pub mod published_response;
pub mod pyp;
pub mod rod_vertex;
pub mod segment_distance;
pub mod sequence_compare;
pub mod spatial_hash;
pub mod sphere_contact;
pub mod stencil_energy;
pub mod stretching;
pub mod tile;
pub mod tubes;
pub mod twisting;
pub mod yarn_friction;
pub mod yarn_params;

#[cfg(test)]
pub(crate) mod test_support;

pub use pyp::{PeriodicEdge, PeriodicPattern, PypError};
