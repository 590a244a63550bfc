//! # v2t-model
//!
//! The domain of Video2Track, as types and pure math with no IO and no clock:
//!
//! - [`semantics`]: what the vision-language model must extract from a video (paper eq. 2), with its
//!   JSON Schema;
//! - [`grounded`] and [`prior`]: a scenario grounded on the track map, and the trajectory priors the
//!   diffusion model produces for it;
//! - [`kinematics`]: the discrete vehicle model, its rollout and the rollout's adjoint;
//! - [`driving`]: the formulas of driving every driver and the regulator share: the IDM, the curve
//!   speed of a path, pure pursuit;
//! - [`path`]: arc-length parameterised reference paths with a robust Frenet projection;
//! - [`metrics`]: conflict zones, post-encroachment time (PET), time to collision, distances;
//! - [`vehicle`]: vehicle geometry and limits;
//! - [`target`]: the test target, τ and style, with its one range;
//! - [`text`]: the one escape of the XML and HTML the project writes;
//! - [`validate`]: range checks that name the field at fault.
//!
//! ```
//! use v2t_model::path::{PathBuilder, ReferencePath};
//! let path: ReferencePath = PathBuilder::new(0.0, 0.0, 0.0).line(50.0).arc(20.0, 1.5708).build(0.5).unwrap();
//! let q = path.to_cartesian(30.0, 1.0);
//! let f = path.project(q).unwrap();
//! assert!((f.s_m - 30.0).abs() < 1e-6 && (f.l_m - 1.0).abs() < 1e-6);
//! ```

pub mod driving;
pub mod geometry;
pub mod grounded;
pub mod kinematics;
pub mod metrics;
pub mod path;
pub mod prior;
pub mod realism;
pub mod semantics;
pub mod target;
pub mod text;
pub mod validate;
pub mod vehicle;

pub use target::{Style, Target, TargetError};
