//! The tracker node: wakes on every new BV state, follows the newest regulated plan along the
//! prior's path with PID + Stanley (`v2t-track`), and hands the request to the gateway at once.

use std::time::Duration;

use iceoryx2::service::Service;
use v2t_model::kinematics::State;
use v2t_track::{PlanSample, Tracker};
use v2t_wire::{ActivePrior, ActuationCommand, BvState, Header, NodeKind, RegulatedPlan, services};

use crate::clock::{now_ns, secs_between};
use crate::config::Loaded;
use crate::error::EdgeError;
use crate::heart::Heart;
use crate::ports::{Bus, latest, send, wait_wake};
use crate::prior::PriorContext;

/// Where the plan puts the BV at `stamp_ns`: the plan holds its acceleration from its own stamp
/// (speed never below zero).
pub fn plan_sample(plan: &RegulatedPlan, stamp_ns: u64) -> PlanSample {
    let dt = secs_between(plan.header.stamp_ns, stamp_ns).max(0.0);
    let (v0, a) = (plan.v0_mps.max(0.0), plan.accel_mps2);
    // Time until the plan's speed reaches zero (braking), after which it stands still.
    let t_move = if a < 0.0 { (v0 / -a).min(dt) } else { dt };
    let v = (v0 + a * t_move).max(0.0);
    let s = plan.s0_m + v0 * t_move + 0.5 * a * t_move * t_move;
    PlanSample { s_m: s, v_mps: v, a_mps2: if a < 0.0 && t_move < dt { 0.0 } else { a } }
}

/// The tracker with the path of the active prior. Pure: time comes in as arguments.
#[derive(Debug)]
pub struct Tracking {
    tracker: Tracker,
    prior: Option<PriorContext>,
    last_stamp_ns: Option<u64>,
    header: Header,
}

impl Tracking {
    /// A tracker for the BV of `cfg`.
    pub fn new(cfg: &Loaded) -> Self {
        Self {
            tracker: Tracker::new(cfg.tracker.clone(), &cfg.vehicle),
            prior: None,
            last_stamp_ns: None,
            header: Header::default(),
        }
    }

    /// Takes a new prior (a broken one is refused and the active one stays).
    pub fn set_prior(&mut self, prior: &ActivePrior) -> Result<(), EdgeError> {
        if self.prior.as_ref().is_some_and(|p| p.prior_id == prior.prior_id) {
            return Ok(());
        }
        self.prior = Some(PriorContext::new(prior)?);
        self.tracker.reset();
        self.last_stamp_ns = None;
        Ok(())
    }

    /// The command for BV state `bv` following `plan`, computed at `now_ns`; `None` without a
    /// prior, a plan for it, or a usable state (the gateway's timeout then stops the BV).
    pub fn step(&mut self, bv: &BvState, plan: Option<&RegulatedPlan>, now_ns: u64) -> Option<ActuationCommand> {
        let ctx = self.prior.as_ref()?;
        let plan = plan.filter(|p| p.prior_id == ctx.prior_id)?;
        if !bv.is_finite() {
            return None;
        }
        let dt = self.last_stamp_ns.map_or(0.02, |t| secs_between(t, bv.header.stamp_ns)).clamp(1e-3, 0.2);
        self.last_stamp_ns = Some(bv.header.stamp_ns);
        let state = State { px: bv.px_m, py: bv.py_m, theta_rad: bv.theta_rad, speed_mps: bv.speed_mps };
        let sample = plan_sample(plan, bv.header.stamp_ns);
        let out = self.tracker.step(&state, &ctx.bv_path, &sample, dt).ok()?;
        self.header.seq += 1;
        self.header.stamp_ns = now_ns;
        Some(ActuationCommand {
            header: self.header,
            plan_seq: plan.header.seq,
            state_seq: bv.header.seq,
            state_stamp_ns: bv.header.stamp_ns,
            state_received_ns: bv.received_ns,
            accel_mps2: out.accel_mps2,
            steer_rad: out.steer_rad,
            cross_track_m: out.cross_track_m,
            speed_error_mps: out.speed_error_mps,
        })
    }
}

/// Runs the tracker node until termination.
pub fn run<S: Service>(cfg: &Loaded) -> Result<(), EdgeError> {
    let bus = Bus::<S>::new("tracker", &cfg.edge.namespace)?;
    let states = bus.subscriber::<BvState>(services::STATE)?;
    let state_wake = bus.listener(services::WAKE_TRACKER)?;
    let plans = bus.subscriber::<RegulatedPlan>(services::PLAN)?;
    let priors = bus.subscriber::<ActivePrior>(services::PRIOR)?;
    let out = bus.publisher::<ActuationCommand>(services::ACTUATION)?;
    let out_wake = bus.notifier(services::WAKE_GATEWAY)?;
    let t = cfg.edge.timing;
    let mut heart = Heart::new(&bus, NodeKind::Tracker, t.heartbeat_period_s)?;
    let mut tracking = Tracking::new(cfg);
    let mut plan: Option<RegulatedPlan> = None;
    let timeout = Duration::from_secs_f64(t.heartbeat_period_s / 2.0);
    let mut last_cmd_ns = 0;
    loop {
        wait_wake(&state_wake, timeout)?;
        if bus.terminating() {
            return Ok(());
        }
        let start = now_ns();
        while let Some(p) = priors.receive().map_err(|e| EdgeError::ipc("receive", services::PRIOR, e))? {
            if let Err(e) = tracking.set_prior(&p) {
                eprintln!("tracker: prior {} refused: {e}", p.prior_id);
            }
        }
        plan = latest(&plans)?.or(plan);
        let fresh_plan = plan.filter(|p| secs_between(p.header.stamp_ns, start) <= t.plan_timeout_s);
        if let Some(state) = latest(&states)?
            && let Some(cmd) = tracking.step(&state, fresh_plan.as_ref(), start)
        {
            send(&out, Some(&out_wake), cmd)?;
            last_cmd_ns = start;
            heart.cycle(now_ns() - start, (t.heartbeat_period_s * 1e9) as u64);
        }
        let now = now_ns();
        heart.tick(now, secs_between(last_cmd_ns, now) <= t.state_timeout_s)?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_sample_integrates_the_held_acceleration_and_stops_at_zero_speed() {
        let plan = RegulatedPlan {
            header: Header { seq: 1, stamp_ns: 1_000_000_000 },
            s0_m: 10.0,
            v0_mps: 4.0,
            accel_mps2: 1.0,
            ..RegulatedPlan::default()
        };
        let p = plan_sample(&plan, 1_500_000_000);
        assert!((p.s_m - (10.0 + 2.0 + 0.125)).abs() < 1e-9 && (p.v_mps - 4.5).abs() < 1e-9);
        let braking = RegulatedPlan { accel_mps2: -2.0, ..plan };
        let p = plan_sample(&braking, 4_000_000_000);
        assert!((p.s_m - 14.0).abs() < 1e-9, "stops after 2 s and 4 m: {p:?}");
        assert_eq!((p.v_mps, p.a_mps2), (0.0, 0.0));
        // A state older than the plan reads the plan's start.
        let p = plan_sample(&plan, 900_000_000);
        assert_eq!((p.s_m, p.v_mps), (10.0, 4.0));
    }
}
