//! The state node: GNSS/INS fixes and drive-by-wire feedback → the BV state every other node uses.
//! It wakes on every new fix and publishes at once (the start of the control path).

use std::time::Duration;

use iceoryx2::service::Service;
use v2t_wire::{BvState, Code, DbwMode, Header, Localization, NodeKind, VehicleFeedback, services};

use crate::clock::now_ns;
use crate::config::Loaded;
use crate::error::EdgeError;
use crate::heart::Heart;
use crate::ports::{Bus, latest, send, wait_wake};

/// Feedback older than this is not used for speed, yaw rate and steering, s.
const FEEDBACK_FRESH_S: f64 = 0.1;

/// Why a fix was not turned into a state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejected {
    /// A number is NaN or infinite.
    NonFinite,
    /// The source marked the fix invalid.
    Invalid,
    /// Older than (or as old as) the last fix used.
    OutOfOrder,
}

/// Fuses fixes and feedback. Pure: time comes in as arguments.
#[derive(Debug, Clone, Default)]
pub struct StateFusion {
    header: Header,
    feedback: Option<VehicleFeedback>,
    last_fix_stamp_ns: u64,
    /// Fixes rejected so far.
    pub rejected: u64,
}

impl StateFusion {
    /// Keeps the newest finite feedback (a non-finite one is counted and dropped).
    pub fn feedback(&mut self, fb: VehicleFeedback) {
        let finite = fb.wheel_speed_mps.is_finite() && fb.yaw_rate_radps.is_finite() && fb.steer_rad.is_finite();
        if finite && DbwMode::from_code(fb.mode).is_ok() {
            self.feedback = Some(fb);
        } else {
            self.rejected += 1;
        }
    }

    /// The BV state from `fix`, received at `now_ns`.
    pub fn fuse(&mut self, fix: &Localization, now_ns: u64) -> Result<BvState, Rejected> {
        let result = self.check(fix);
        if result.is_err() {
            self.rejected += 1;
        }
        result?;
        self.last_fix_stamp_ns = fix.header.stamp_ns;
        let fresh = self.feedback.filter(|fb| fb.header.age_s(fix.header.stamp_ns) <= FEEDBACK_FRESH_S);
        self.header.seq += 1;
        self.header.stamp_ns = fix.header.stamp_ns;
        Ok(BvState {
            header: self.header,
            px_m: fix.px_m,
            py_m: fix.py_m,
            theta_rad: fix.theta_rad,
            speed_mps: fresh.map_or(fix.speed_mps, |fb| fb.wheel_speed_mps.max(0.0)),
            yaw_rate_radps: fresh.map_or(0.0, |fb| fb.yaw_rate_radps),
            steer_rad: fresh.map_or(0.0, |fb| fb.steer_rad),
            received_ns: now_ns,
            feedback_stamp_ns: fresh.map_or(0, |fb| fb.header.stamp_ns),
            dbw_mode: self.feedback.map_or(DbwMode::Manual.code(), |fb| fb.mode),
        })
    }

    fn check(&self, fix: &Localization) -> Result<(), Rejected> {
        if !fix.is_finite() {
            return Err(Rejected::NonFinite);
        }
        if fix.valid == 0 {
            return Err(Rejected::Invalid);
        }
        if fix.header.stamp_ns <= self.last_fix_stamp_ns {
            return Err(Rejected::OutOfOrder);
        }
        Ok(())
    }
}

/// Runs the state node until termination.
pub fn run<S: Service>(cfg: &Loaded) -> Result<(), EdgeError> {
    let bus = Bus::<S>::new("state", &cfg.edge.namespace)?;
    let fixes = bus.subscriber::<Localization>(services::LOCALIZATION)?;
    let fix_wake = bus.listener(services::WAKE_STATE)?;
    let feedback = bus.subscriber::<VehicleFeedback>(services::FEEDBACK)?;
    let out = bus.publisher::<BvState>(services::STATE)?;
    let out_wake = bus.notifier(services::WAKE_TRACKER)?;
    let mut heart = Heart::new(&bus, NodeKind::State, cfg.edge.timing.heartbeat_period_s)?;
    let mut fusion = StateFusion::default();
    let mut last_ok_ns = 0;
    let timeout = Duration::from_secs_f64(cfg.edge.timing.heartbeat_period_s / 2.0);
    loop {
        wait_wake(&fix_wake, timeout)?;
        if bus.terminating() {
            return Ok(());
        }
        let start = now_ns();
        if let Some(fb) = latest(&feedback)? {
            fusion.feedback(fb);
        }
        // Every fix in order: none is skipped silently; rejected ones are counted.
        while let Some(fix) = fixes.receive().map_err(|e| EdgeError::ipc("receive", services::LOCALIZATION, e))? {
            let fix = *fix;
            if let Ok(state) = fusion.fuse(&fix, start) {
                send(&out, Some(&out_wake), state)?;
                last_ok_ns = start;
            }
        }
        let now = now_ns();
        heart.cycle(now - start, (cfg.edge.timing.heartbeat_period_s * 1e9) as u64);
        let ok = crate::clock::secs_between(last_ok_ns, now) <= cfg.edge.timing.state_timeout_s;
        heart.tick(now, ok)?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix(seq: u64, stamp_ns: u64) -> Localization {
        Localization {
            header: Header { seq, stamp_ns },
            px_m: 1.0,
            py_m: 2.0,
            theta_rad: 0.3,
            speed_mps: 5.0,
            valid: 1,
        }
    }

    #[test]
    fn wheel_speed_replaces_gnss_speed_while_fresh() {
        let mut f = StateFusion::default();
        f.feedback(VehicleFeedback {
            header: Header { seq: 1, stamp_ns: 1_000_000_000 },
            wheel_speed_mps: 5.5,
            yaw_rate_radps: 0.1,
            steer_rad: 0.02,
            mode: DbwMode::Auto.code(),
        });
        let s = f.fuse(&fix(1, 1_050_000_000), 1_051_000_000).unwrap();
        assert_eq!((s.speed_mps, s.yaw_rate_radps, s.steer_rad), (5.5, 0.1, 0.02));
        assert_eq!(s.dbw_mode, DbwMode::Auto.code());
        assert_eq!((s.header.seq, s.header.stamp_ns, s.received_ns), (1, 1_050_000_000, 1_051_000_000));
        // 300 ms later the feedback is stale: speed from the fix, no yaw rate or steering.
        let s = f.fuse(&fix(2, 1_300_000_000), 1_301_000_000).unwrap();
        assert_eq!((s.speed_mps, s.yaw_rate_radps, s.feedback_stamp_ns), (5.0, 0.0, 0));
    }

    #[test]
    fn bad_fixes_are_rejected_and_counted() {
        let mut f = StateFusion::default();
        let mut nan = fix(1, 10);
        nan.px_m = f64::NAN;
        assert_eq!(f.fuse(&nan, 11), Err(Rejected::NonFinite));
        let mut invalid = fix(1, 10);
        invalid.valid = 0;
        assert_eq!(f.fuse(&invalid, 11), Err(Rejected::Invalid));
        assert!(f.fuse(&fix(2, 20), 21).is_ok());
        assert_eq!(f.fuse(&fix(3, 20), 22), Err(Rejected::OutOfOrder));
        assert_eq!(f.rejected, 3);
        let mut fb = VehicleFeedback { wheel_speed_mps: f64::INFINITY, ..VehicleFeedback::default() };
        f.feedback(fb);
        fb.wheel_speed_mps = 1.0;
        fb.mode = 77;
        f.feedback(fb);
        assert_eq!(f.rejected, 5);
    }
}
