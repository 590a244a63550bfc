//! # video2track — the operator's command line
//!
//! The library half holds what the commands do, so that workspace tests and later commands (the
//! demo, the experiments) reuse it: [`files`] loads configuration files with errors that name the
//! file, [`sim`] runs and reports a scenario in the simulated proving ground, [`render`] draws such a
//! run as a bird's-eye video, and [`abstract_cmd`] turns a driving video into scenario semantics
//! with `v2t-vlm`; [`xosc`] writes a prior, a grounded scenario or a run as OpenSCENARIO 1.2, and
//! [`export`] is its file shell.

pub mod abstract_cmd;
pub mod demo;
pub mod experiment;
pub mod export;
pub mod generate;
pub mod ground;
pub mod link;
pub mod map;
pub mod methods;
pub mod render;
/// Loading configuration files (lives in `v2t-sim`, shared with the onboard runtime).
pub use v2t_sim::files;
/// MCAP recordings of runs (lives in `v2t-sim`, shared with the simulated ECU).
pub use v2t_sim::recording;
mod runfile;
pub mod serve;
pub mod sim;
pub mod train;
pub mod xosc;
