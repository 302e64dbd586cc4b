//! skintight: designs the sewing patterns of skintight garments for one customer's body.
//!
//! This crate holds the command-line tool, the HTTP service and the scene layers (garments: `scene`,
//! `simulate`, `design`; yarns: `knit`); the numerics live in the workspace crates (`skintight-geometry`,
//! `skintight-physics`, `skintight-knit`, …), which never depend on the web or database stack.

pub mod cli;
pub mod design;
pub mod json_input;
pub mod knit;
pub mod scene;
pub mod server;
pub mod simulate;
