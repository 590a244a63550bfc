//! The formulas of driving that the simulated VUTs, the synthetic corpus's drivers and the BV's
//! regulator share, each written once (one home per formula: two copies drift, and then two
//! experiments measure two different things):
//!
//! - [`Idm`]: the Intelligent Driver Model and its enhanced variant (car following);
//! - [`curve_speed`] and [`curve_speed_ahead`]: the speed a path's curves allow, at a point and as
//!   a braking preview;
//! - [`pure_pursuit`]: steering toward a look-ahead point.
//!
//! They are pure and allocation-free. Every parameter a caller may choose (a driver's headway, the
//! regulator's share of the lateral-acceleration limit, a look-ahead distance) is an argument; the
//! constants here only keep the formulas finite.
//!
//! ```
//! use v2t_model::driving::{CURVE_HALF_WINDOW_M, curve_speed};
//! use v2t_model::path::PathBuilder;
//! let path = PathBuilder::new(0.0, 0.0, 0.0).line(20.0).arc(25.0, 1.5).build(0.5).unwrap();
//! // In the arc, 2 m/s² of lateral acceleration allow √(2 · 25) ≈ 7.07 m/s.
//! let v = curve_speed(&path, 40.0, CURVE_HALF_WINDOW_M, 2.0);
//! assert!((v - 50f64.sqrt()).abs() < 0.01, "{v}");
//! assert_eq!(curve_speed(&path, 5.0, CURVE_HALF_WINDOW_M, 2.0), f64::INFINITY);
//! ```

mod curve;
mod idm;
mod pursuit;

pub use curve::{CURVE_HALF_WINDOW_M, CurvePreview, braking_envelope, curve_speed, curve_speed_ahead};
pub use idm::{COOLNESS, Idm, MIN_DESIRED_SPEED_MPS, MIN_GAP_M, Obstacle, travel_time};
pub use pursuit::{MIN_PURSUIT_DISTANCE_M, pure_pursuit};
