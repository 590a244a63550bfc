//! The closed-loop simulation of one synthetic episode: every agent drives the kinematic model of
//! `v2t-model` with an acceleration from its IDM (free road, the vehicle ahead in its lane or
//! drifting into it — with the enhanced IDM's softening —, a stop
//! before a conflict it gives way at) through an actuation lag plus process noise, and a yaw rate
//! from pure pursuit of its route (shifted sideways along a minimum-jerk profile during a lane
//! change) plus noise. Others are perceived with the driver's reaction delay. The applied controls
//! are recorded with the states, so the pair is dynamically consistent by construction.

use rand_chacha::ChaCha8Rng;
use v2t_model::driving::{Obstacle, pure_pursuit};
use v2t_model::geometry::OrientedBox;
use v2t_model::kinematics::{Control, State, step};
use v2t_model::metrics::{Dimensions, OccupancyInterval};
use v2t_model::path::ReferencePath;

use super::driver::{DriverParams, OuNoise, min_jerk_offset, normal};

/// Half the width of a lane for "is in my lane", m.
const LANE_HALF_WIDTH_M: f64 = 1.8;
/// A vehicle drifting into the lane is followed as soon as it will be in it this long from now, s.
const ANTICIPATION_S: f64 = 1.0;
/// Vehicles ahead are looked for this far, m.
const LOOK_AHEAD_M: f64 = 120.0;
/// A driver stops this far before a conflict it gives way at, m.
const STOP_MARGIN_M: f64 = 1.0;
/// A lane change accepts a lag gap of this fraction of the critical gap as time headway of the
/// vehicle behind (accepted lag gaps are shorter than accepted crossing gaps)…
const LAG_GAP_FRACTION: f64 = 0.35;
/// … plus this many seconds of the closing speed, s.
const LAG_CLOSING_S: f64 = 1.5;
/// How far an agent may drive beyond its route's end before the episode ends, m.
pub(crate) const RUN_OUT_M: f64 = 30.0;
/// Hardest braking, m/s².
const MAX_DECEL_MPS2: f64 = 8.0;
/// A decision to go is kept unless the gap shrinks by more than this, s.
const HYSTERESIS_S: f64 = 0.3;

/// How an agent deals with the interaction of its scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Behavior {
    /// Drives its route, following whoever is ahead in its lane.
    Free,
    /// Gap acceptance against the agents `others` (one route, in driving order) at a conflict:
    /// `own` is the zone along its own route, `theirs` along theirs.
    GiveWay { others: [Option<usize>; 2], own: OccupancyInterval, theirs: OccupancyInterval },
    /// Starts at the route's lateral offset `start_offset_m` (a neighbouring lane) and changes onto
    /// the route after `intent_s` once agent `behind` leaves a large enough gap, unless
    /// `give_up_s` passed first.
    LaneChange { behind: usize, intent_s: f64, give_up_s: f64 },
}

/// One agent of a scene, as it starts.
#[derive(Debug, Clone)]
pub(crate) struct AgentSetup {
    pub name: &'static str,
    pub route_id: String,
    pub route: ReferencePath,
    pub start_s: f64,
    pub start_speed_mps: f64,
    pub start_offset_m: f64,
    pub driver: DriverParams,
    pub dims: Dimensions,
    pub behavior: Behavior,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Decision {
    Undecided,
    Go,
    Yield,
    Committed,
}

/// Running state of one agent.
#[derive(Debug, Clone)]
struct Agent {
    s_m: f64,
    l_m: f64,
    accel_mps2: f64,
    accel_noise: OuNoise,
    yaw_noise: OuNoise,
    decision: Decision,
    lane_change_from_s: Option<f64>,
    delay_steps: usize,
}

/// Recorded states (one more than controls) per agent.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SimOutput {
    pub states: Vec<Vec<State>>,
    pub controls: Vec<Vec<Control>>,
    /// Whether two footprints ever overlapped.
    pub collided: bool,
}

/// Time to cover `d` m from speed `v` accelerating at `a` up to `v_max`.
fn time_to_cover(d: f64, v: f64, a: f64, v_max: f64) -> f64 {
    if d <= 0.0 {
        return 0.0;
    }
    let v = v.max(0.0);
    let v_max = v_max.max(v).max(0.5);
    let a = a.max(0.1);
    let t_acc = (v_max - v) / a;
    let d_acc = v * t_acc + 0.5 * a * t_acc * t_acc;
    if d <= d_acc { (-v + (v * v + 2.0 * a * d).sqrt()) / a } else { t_acc + (d - d_acc) / v_max }
}

fn footprint(x: &State, d: Dimensions) -> OrientedBox {
    OrientedBox { center: x.position(), heading_rad: x.theta_rad, length_m: d.length_m, width_m: d.width_m }
}

/// Simulates `agents` for up to `steps` steps of `dt_s`, stopping early once every agent is within
/// 5 m of its route's end or one has driven [`RUN_OUT_M`] beyond it (the route is extended
/// straight past its end, so that an agent that gave way can still pass the conflict).
pub(crate) fn simulate(agents: &[AgentSetup], dt_s: f64, steps: usize, rng: &mut ChaCha8Rng) -> SimOutput {
    let mut states: Vec<Vec<State>> = agents
        .iter()
        .map(|a| {
            let p = a.route.to_cartesian(a.start_s, a.start_offset_m);
            vec![State { px: p.x, py: p.y, theta_rad: a.route.heading_at(a.start_s), speed_mps: a.start_speed_mps }]
        })
        .collect();
    let mut controls: Vec<Vec<Control>> = vec![Vec::with_capacity(steps); agents.len()];
    let mut run: Vec<Agent> = agents
        .iter()
        .map(|a| Agent {
            s_m: a.start_s,
            l_m: a.start_offset_m,
            accel_mps2: 0.0,
            accel_noise: OuNoise { value: 0.0, sigma: a.driver.accel_noise_mps2 },
            yaw_noise: OuNoise { value: 0.0, sigma: a.driver.yaw_noise_radps },
            decision: Decision::Undecided,
            lane_change_from_s: None,
            delay_steps: (a.driver.reaction_delay_s / dt_s).round() as usize,
        })
        .collect();
    let mut collided = false;
    for k in 0..steps {
        let t = k as f64 * dt_s;
        let now: Vec<State> = states.iter().map(|h| h.last().copied().unwrap_or_default()).collect();
        let past = |d: f64| agents.iter().zip(&run).map(move |(a, r)| r.s_m > a.route.length() + d);
        if past(-5.0).all(|p| p) || past(RUN_OUT_M).any(|p| p) {
            break;
        }
        for (i, a) in agents.iter().enumerate() {
            let (Some(x), Some(r)) = (now.get(i).copied(), run.get(i).cloned()) else { continue };
            let delay = r.delay_steps;
            let seen = |j: usize| -> Option<State> {
                let h = states.get(j)?;
                h.get(k.saturating_sub(delay)).or(h.last()).copied()
            };
            let (u, r) = decide(agents, i, a, x, r, t, dt_s, &seen, rng);
            if let Some(slot) = run.get_mut(i) {
                *slot = r;
            }
            if let Some(c) = controls.get_mut(i) {
                c.push(u);
            }
        }
        for (i, h) in states.iter_mut().enumerate() {
            let (Some(x), Some(u)) = (h.last().copied(), controls.get(i).and_then(|c| c.last()).copied()) else {
                continue;
            };
            h.push(step(x, u, dt_s));
        }
        for (i, a) in agents.iter().enumerate() {
            let Some(x) = states.get(i).and_then(|h| h.last()) else { continue };
            if let Some(f) = a.route.project_near(x.position(), run.get(i).map_or(0.0, |r| r.s_m), 20.0)
                && let Some(r) = run.get_mut(i)
            {
                r.s_m = f.s_m;
                r.l_m = f.l_m;
            }
        }
        let last: Vec<(State, Dimensions)> =
            states.iter().zip(agents).filter_map(|(h, a)| h.last().map(|x| (*x, a.dims))).collect();
        for (i, (x, d)) in last.iter().enumerate() {
            for (y, e) in last.iter().skip(i + 1) {
                collided |= footprint(x, *d).overlaps(&footprint(y, *e));
            }
        }
    }
    SimOutput { states, controls, collided }
}

/// The control of agent `i` at time `t` and its updated running state.
#[allow(clippy::too_many_arguments)]
fn decide(
    agents: &[AgentSetup],
    i: usize,
    a: &AgentSetup,
    x: State,
    mut r: Agent,
    t: f64,
    dt_s: f64,
    seen: &dyn Fn(usize) -> Option<State>,
    rng: &mut ChaCha8Rng,
) -> (Control, Agent) {
    let d = &a.driver;
    let v = x.speed_mps;
    let v0 = d.curve_capped_speed(&a.route, r.s_m, v);
    let idm = d.idm();
    // Lanes the driver watches: where it is, and the route's lane once a lane change has begun.
    let mut lanes = vec![r.l_m];
    if r.lane_change_from_s.is_some() {
        lanes.push(0.0);
    }
    let mut accel = idm.accel(v, v0, None);
    for (j, o) in agents.iter().enumerate() {
        if j == i {
            continue;
        }
        let Some(xo) = seen(j) else { continue };
        let Some(f) = a.route.project_near(xo.position(), r.s_m, LOOK_AHEAD_M) else { continue };
        let ahead = f.s_m - r.s_m;
        // A vehicle moving sideways counts where it will be after the anticipation time.
        let route_heading = a.route.heading_at(f.s_m);
        let lateral_v = xo.speed_mps * (xo.theta_rad - route_heading).sin();
        let l_soon = f.l_m + lateral_v * ANTICIPATION_S;
        let in_lane = |l_other: f64| lanes.iter().any(|l| (l_other - l).abs() < LANE_HALF_WIDTH_M);
        if ahead <= 0.0 || ahead > LOOK_AHEAD_M || !(in_lane(f.l_m) || in_lane(l_soon)) {
            continue;
        }
        let gap = ahead - 0.5 * (a.dims.length_m + o.dims.length_m);
        let lead_v = xo.speed_mps * (xo.theta_rad - route_heading).cos();
        accel = accel.min(idm.enhanced_accel(v, v0, Obstacle { gap_m: gap, speed_mps: lead_v }));
    }
    match a.behavior {
        Behavior::Free => {}
        Behavior::GiveWay { others, own, theirs } => {
            let watched: Vec<(&AgentSetup, State)> =
                others.iter().flatten().filter_map(|&j| Some((agents.get(j)?, seen(j)?))).collect();
            r.decision = give_way(a, &r, x, v0, &watched, &own, &theirs);
            if r.decision == Decision::Yield {
                let gap = own.enter_s_m - r.s_m - STOP_MARGIN_M;
                accel = accel.min(idm.accel(v, v0, Some(Obstacle { gap_m: gap, speed_mps: 0.0 })));
            }
        }
        Behavior::LaneChange { behind, intent_s, give_up_s } => {
            if r.lane_change_from_s.is_none() && t >= intent_s && t <= give_up_s {
                let watched = if behind == i { None } else { seen(behind).zip(agents.get(behind)) };
                let accepted = watched.is_none_or(|(xb, b)| {
                    let sb =
                        a.route.project_near(xb.position(), r.s_m, LOOK_AHEAD_M).map_or(f64::NEG_INFINITY, |f| f.s_m);
                    let lag_gap = r.s_m - sb - 0.5 * (a.dims.length_m + b.dims.length_m);
                    let closing = (xb.speed_mps - v).max(0.0);
                    lag_gap
                        >= d.min_gap_m
                            + closing * LAG_CLOSING_S
                            + xb.speed_mps.max(0.0) * LAG_GAP_FRACTION * d.critical_gap_s
                });
                if accepted {
                    r.lane_change_from_s = Some(t);
                }
            }
        }
    }
    let lag = d.accel_lag_s.max(dt_s);
    r.accel_mps2 += (accel.clamp(-MAX_DECEL_MPS2, d.max_accel_mps2) - r.accel_mps2) * dt_s / lag;
    let mut a_cmd = r.accel_mps2 + r.accel_noise.step(dt_s, normal(rng));
    if v + a_cmd * dt_s < 0.0 {
        a_cmd = -v / dt_s;
    }
    // Lateral: pure pursuit of the route shifted by the lane-change profile.
    let look = (0.8 * v).max(4.0);
    let offset_at = |tt: f64| match (a.behavior, r.lane_change_from_s) {
        (Behavior::LaneChange { .. }, Some(t0)) => {
            min_jerk_offset(a.start_offset_m, 0.0, d.lane_change_duration_s, tt - t0)
        }
        (Behavior::LaneChange { .. }, None) => a.start_offset_m,
        _ => 0.0,
    };
    let target = a.route.to_cartesian(r.s_m + look, offset_at(t + look / v.max(1.0)));
    let yaw_noise = r.yaw_noise.step(dt_s, normal(rng)) * (v / 2.0).min(1.0);
    let limit = (5.0 / v.max(1.0)).min(1.0);
    let yaw_rate = pure_pursuit(x.position(), x.theta_rad, target, x.speed_mps.max(0.0));
    let omega = (yaw_rate + yaw_noise).clamp(-limit, limit);
    (Control { accel_mps2: a_cmd, yaw_rate_radps: omega }, r)
}

/// Gap acceptance at a conflict (see [`Behavior::GiveWay`]) against the `watched` vehicles (all on
/// one route, each with its perceived state): go if the driver clears its zone at least the
/// critical gap before the first of them that has not passed yet arrives.
fn give_way(
    a: &AgentSetup,
    r: &Agent,
    x: State,
    v0: f64,
    watched: &[(&AgentSetup, State)],
    own: &OccupancyInterval,
    theirs: &OccupancyInterval,
) -> Decision {
    let d = &a.driver;
    let v = x.speed_mps.max(0.0);
    if r.decision == Decision::Committed || r.s_m >= own.enter_s_m {
        return Decision::Committed;
    }
    let mut arrive = f64::INFINITY;
    for (o, xo) in watched {
        let so = o.route.project_near(xo.position(), theirs.enter_s_m, 300.0).map_or(f64::NEG_INFINITY, |f| f.s_m);
        if so > theirs.exit_s_m {
            continue;
        }
        let vo = xo.speed_mps;
        let t = if so >= theirs.enter_s_m {
            0.0
        } else if vo > 0.5 {
            (theirs.enter_s_m - so) / vo
        } else {
            f64::INFINITY
        };
        arrive = arrive.min(t);
    }
    let clear = time_to_cover(own.exit_s_m - r.s_m, v, d.max_accel_mps2, v0);
    let threshold = d.critical_gap_s - if r.decision == Decision::Go { HYSTERESIS_S } else { 0.0 };
    if arrive - clear >= threshold {
        let stopping = v * v / (2.0 * d.comfort_decel_mps2) + 2.0;
        if r.s_m >= own.enter_s_m - stopping { Decision::Committed } else { Decision::Go }
    } else {
        Decision::Yield
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_chacha::rand_core::SeedableRng;
    use v2t_model::path::PathBuilder;

    #[test]
    fn covering_distance_takes_the_expected_time() {
        assert!((time_to_cover(100.0, 10.0, 1.0, 10.0) - 10.0).abs() < 1e-9);
        assert!((time_to_cover(50.0, 0.0, 1.0, 100.0) - 10.0).abs() < 1e-9);
        assert_eq!(time_to_cover(-1.0, 3.0, 1.0, 5.0), 0.0);
    }

    fn driver() -> DriverParams {
        DriverParams {
            desired_speed_mps: 12.0,
            time_headway_s: 1.5,
            max_accel_mps2: 1.5,
            comfort_decel_mps2: 2.0,
            min_gap_m: 2.0,
            critical_gap_s: 2.0,
            reaction_delay_s: 0.5,
            accel_lag_s: 0.3,
            max_lateral_accel_mps2: 2.0,
            lane_change_duration_s: 5.0,
            accel_noise_mps2: 0.1,
            yaw_noise_radps: 0.005,
        }
    }

    #[test]
    fn a_follower_keeps_its_distance_and_stays_on_its_lane() {
        let route = PathBuilder::new(0.0, 0.0, 0.0).line(400.0).build(1.0).unwrap();
        let dims = Dimensions { length_m: 4.5, width_m: 1.8 };
        let mut lead = AgentSetup {
            name: "lead",
            route_id: "r".into(),
            route: route.clone(),
            start_s: 40.0,
            start_speed_mps: 8.0,
            start_offset_m: 0.0,
            driver: DriverParams { desired_speed_mps: 8.0, ..driver() },
            dims,
            behavior: Behavior::Free,
        };
        lead.driver.accel_noise_mps2 = 0.0;
        let follower =
            AgentSetup { name: "follower", start_s: 0.0, start_speed_mps: 12.0, driver: driver(), ..lead.clone() };
        let out = simulate(&[lead, follower], 0.1, 300, &mut ChaCha8Rng::seed_from_u64(1));
        assert!(!out.collided);
        let (a, b) = (out.states[0].last().unwrap(), out.states[1].last().unwrap());
        assert!(a.px - b.px > 6.5, "gap {}", a.px - b.px);
        assert!(b.py.abs() < 0.5 && (b.speed_mps - 8.0).abs() < 1.5, "{b:?}");
        assert_eq!(out.controls[0].len() + 1, out.states[0].len());
    }

    #[test]
    fn a_lane_change_ends_on_the_route() {
        let route = PathBuilder::new(0.0, 0.0, 0.0).line(400.0).build(1.0).unwrap();
        let dims = Dimensions { length_m: 4.5, width_m: 1.8 };
        let cutter = AgentSetup {
            name: "cutter",
            route_id: "r".into(),
            route,
            start_s: 0.0,
            start_speed_mps: 10.0,
            start_offset_m: -3.5,
            driver: driver(),
            dims,
            behavior: Behavior::LaneChange { behind: 0, intent_s: 1.0, give_up_s: 10.0 },
        };
        let out = simulate(&[cutter], 0.1, 150, &mut ChaCha8Rng::seed_from_u64(2));
        let end = out.states[0].last().unwrap();
        assert!(end.py.abs() < 0.3, "{end:?}");
        assert!(out.states[0][5].py < -3.0);
    }
}
