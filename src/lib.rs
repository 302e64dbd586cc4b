//! skintight: designs the sewing patterns of skintight garments for one customer's body.
//!
//! This crate holds the command-line tool and the HTTP service; the numerics live in the workspace crates
//! `skintight-geometry` and `skintight-physics`, which never depend on the web or database stack.

pub mod cli;
pub mod design;
pub mod json_input;
pub mod scene;
pub mod server;
pub mod simulate;
