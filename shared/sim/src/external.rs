//! A VUT driven by another simulator (SUMO in the lab's co-simulation): the simulated proving
//! ground keeps its own plants, sensing and measurement for the BVs, and takes the VUT's true state
//! from the other simulator every control period.
//!
//! The contract is one call per control tick: the other simulator is told where every BV truly is
//! now, advances by one control period (its drivers react to those BVs as they would to any
//! vehicle), and answers with the VUT's true state at the end of that period. Between two answers
//! the VUT's state is interpolated at the plant rate, so PET, distances and collisions are measured
//! exactly as in the builtin world.

use v2t_model::geometry::wrap_angle;
use v2t_model::kinematics::State;

/// The VUT of another simulator.
pub trait ExternalVut {
    /// Short name for reports (the world and the driver, e.g. `sumo:krauss`).
    fn name(&self) -> &str;
    /// At control tick `t_s`, with every BV's true state at `t_s` (scenario order): advances the
    /// other simulator by `period_s` and returns the VUT's true state at `t_s + period_s`.
    fn advance(&mut self, t_s: f64, period_s: f64, bvs: &[State]) -> Result<State, ExternalVutError>;
}

/// The other simulator failed or its VUT left it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{world} at t = {t_s}: {message}")]
pub struct ExternalVutError {
    /// Which world.
    pub world: String,
    /// Simulated time of the failure, s (formatted).
    pub t_s: String,
    /// What happened.
    pub message: String,
}

impl ExternalVutError {
    /// An error of `world` at `t_s`.
    pub fn new(world: impl Into<String>, t_s: f64, message: impl Into<String>) -> Self {
        Self { world: world.into(), t_s: format!("{t_s:.2} s"), message: message.into() }
    }
}

/// The VUT between two answers of the other simulator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Segment {
    pub t0_s: f64,
    pub from: State,
    pub t1_s: f64,
    pub to: State,
}

impl Segment {
    /// The state at `t_s` (clamped to the segment), the acceleration over the segment and the
    /// road-wheel angle a bicycle of `wheelbase_m` needs for its yaw rate.
    pub fn at(&self, t_s: f64, wheelbase_m: f64, max_steer_rad: f64) -> (State, f64, f64) {
        let span = self.t1_s - self.t0_s;
        let f = if span > 0.0 { ((t_s - self.t0_s) / span).clamp(0.0, 1.0) } else { 1.0 };
        let dtheta = wrap_angle(self.to.theta_rad - self.from.theta_rad);
        let state = State {
            px: self.from.px + f * (self.to.px - self.from.px),
            py: self.from.py + f * (self.to.py - self.from.py),
            theta_rad: wrap_angle(self.from.theta_rad + f * dtheta),
            speed_mps: self.from.speed_mps + f * (self.to.speed_mps - self.from.speed_mps),
        };
        if span <= 0.0 {
            return (state, 0.0, 0.0);
        }
        let accel = (self.to.speed_mps - self.from.speed_mps) / span;
        let v = 0.5 * (self.from.speed_mps + self.to.speed_mps);
        let steer = if v > 0.5 { (wheelbase_m * dtheta / span / v).atan() } else { 0.0 };
        (state, accel, steer.clamp(-max_steer_rad, max_steer_rad))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_segment_interpolates_position_heading_across_pi_and_speed() {
        let from = State { px: 0.0, py: 0.0, theta_rad: 3.1, speed_mps: 10.0 };
        let to = State { px: -1.0, py: 0.1, theta_rad: -3.1, speed_mps: 9.0 };
        let seg = Segment { t0_s: 2.0, from, t1_s: 2.1, to };
        let (mid, accel, steer) = seg.at(2.05, 2.8, 0.6);
        assert!((mid.px + 0.5).abs() < 1e-12 && (mid.py - 0.05).abs() < 1e-12);
        // Halfway from 3.1 to −3.1 the short way round is ±π, not 0.
        assert!((mid.theta_rad.abs() - std::f64::consts::PI).abs() < 1e-9, "{}", mid.theta_rad);
        assert!((mid.speed_mps - 9.5).abs() < 1e-12);
        assert!((accel + 10.0).abs() < 1e-9);
        assert!(steer > 0.0, "turning left: {steer}");
        assert_eq!(seg.at(5.0, 2.8, 0.6).0, to);
        assert_eq!(seg.at(0.0, 2.8, 0.6).0, from);
    }
}
