//! What a controller knows at a control tick: its own localization, the other vehicles as they
//! reach it (older and noisier), and the scenario (map, routes, conflict zones).

use v2t_model::kinematics::State;

use crate::scenario::Scenario;

/// A vehicle as some controller perceives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Perceived {
    /// Measured state (track frame).
    pub state: State,
    /// Arc length of the measured position along that vehicle's own route, m.
    pub s_m: f64,
    /// Lateral offset from that route, m.
    pub l_m: f64,
    /// Age of the measurement: time since the true state it describes, s.
    pub age_s: f64,
}

/// Input of a BV controller.
#[derive(Debug, Clone, Copy)]
pub struct BvObservation<'a> {
    /// Simulation time, s.
    pub t_s: f64,
    /// Control period, s.
    pub dt_s: f64,
    /// Which BV this is (index into `scenario.bvs`).
    pub bv_index: usize,
    /// The BV's own localization.
    pub own: Perceived,
    /// The VUT as it reaches the BV (V2X or cloud relay).
    pub vut: Perceived,
    /// Everything static.
    pub scenario: &'a Scenario,
}

/// Input of a VUT driver model.
#[derive(Debug, Clone, Copy)]
pub struct VutObservation<'a> {
    /// Simulation time, s.
    pub t_s: f64,
    /// Control period, s.
    pub dt_s: f64,
    /// The VUT's own localization.
    pub own: Perceived,
    /// Every BV as the VUT's sensing perceives it (`s_m`, `l_m` along the BV's own route), in
    /// `scenario.bvs` order.
    pub bvs: &'a [Perceived],
    /// Everything static (the VUT knows the map: routes and conflict zones).
    pub scenario: &'a Scenario,
}
