//! # v2t-export — scenarios and runs for other tools
//!
//! What a proving ground's other tools read: [`xosc`] writes a trajectory prior, a grounded
//! scenario or a simulated run as an OpenSCENARIO 1.2 file (the BVs follow their trajectories, the
//! VUT gets its start and its route, never a trajectory), and [`mod@file`] is its shell (vehicle files,
//! the map's path relative to the output, the date); [`video`] draws a run as a bird's-eye video
//! through `ffmpeg`. The writers are pure (text or pixels out); only the shells touch files and
//! processes.
//!
//! ```
//! use v2t_export::xosc::escape;
//! assert_eq!(escape("a<b"), "a&lt;b");
//! ```

pub mod file;
#[cfg(test)]
mod test_run;
pub mod video;
pub mod xosc;
