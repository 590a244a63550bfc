//! Latency compensation: where the vehicle will be when the request being computed takes effect.
//!
//! A request reaches the wheels a loop latency `T` after the instant its state describes
//! (localization delay, transport delay, actuator lag). Over that window the wheels execute the
//! requests of the last `T` seconds, so the vehicle is predicted with exactly those: the kinematic
//! bicycle about the footprint centre at constant speed, driven through the recent steering
//! requests as they were held (a Smith-predictor-like model of the dead time). Predicting with the
//! last request alone over the whole window would feed each request straight back into the next
//! and make the steering alternate from cycle to cycle.

use v2t_model::geometry::wrap_angle;
use v2t_model::kinematics::State;

use crate::lateral::SteeringModel;

/// Requests remembered (covers 0.64 s at 100 Hz, 6.4 s at 10 Hz).
const CAPACITY: usize = 64;
/// Longest integration step of the prediction, s.
const MAX_STEP_S: f64 = 0.05;

/// One request as the actuators received it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Request {
    /// Acceleration, m/s².
    pub(crate) accel_mps2: f64,
    /// Road-wheel angle, rad.
    pub(crate) steer_rad: f64,
}

/// The recent requests, newest first, each with how long it was held.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RequestHistory {
    /// `(request, held_s)`; the newest entry's hold time is still open.
    entries: [(Request, f64); CAPACITY],
    len: usize,
    /// What the actuators did before the oldest remembered request.
    before: Request,
}

impl RequestHistory {
    /// No requests yet; the actuators are at `now`.
    pub(crate) fn new(now: Request) -> Self {
        Self { entries: [(Request::default(), 0.0); CAPACITY], len: 0, before: now }
    }

    /// Records a request made now; the previous request was held for `held_s`.
    pub(crate) fn push(&mut self, request: Request, held_s: f64) {
        if let Some(newest) = self.entries.first_mut().filter(|_| self.len > 0) {
            newest.1 = held_s;
        }
        if self.len == CAPACITY
            && let Some(oldest) = self.entries.last()
        {
            self.before = oldest.0;
        }
        self.entries.copy_within(0..CAPACITY - 1, 1);
        if let Some(first) = self.entries.first_mut() {
            *first = (request, 0.0);
        }
        self.len = (self.len + 1).min(CAPACITY);
    }

    /// Visits the requests of the window of `horizon_s` that ends now, oldest first, with the time
    /// each was in force inside the window; the newest request has been held for `newest_held_s`.
    fn window(&self, horizon_s: f64, newest_held_s: f64, mut visit: impl FnMut(&Request, f64)) {
        if horizon_s <= 0.0 {
            return;
        }
        let held = |i: usize, h: f64| if i == 0 { newest_held_s } else { h };
        let mut covered = 0.0;
        let mut used = 0;
        for (i, (_, h)) in self.entries.iter().take(self.len).enumerate() {
            covered += held(i, *h);
            used = i + 1;
            if covered >= horizon_s {
                break;
            }
        }
        if covered < horizon_s {
            // The window reaches back past the oldest remembered request.
            visit(&self.before, horizon_s - covered);
        }
        // The oldest request used may have started before the window.
        let excess = (covered - horizon_s).max(0.0);
        for i in (0..used).rev() {
            let Some((request, h)) = self.entries.get(i) else { continue };
            visit(request, if i + 1 == used { held(i, *h) - excess } else { held(i, *h) });
        }
    }

    /// The pose `horizon_s` after `state`: the kinematic bicycle at constant speed through the
    /// steering requests of the last `horizon_s`.
    pub(crate) fn predict_pose(
        &self,
        state: &State,
        model: &SteeringModel,
        horizon_s: f64,
        newest_held_s: f64,
    ) -> State {
        let mut x = *state;
        self.window(horizon_s, newest_held_s, |r, d| x = drive(x, r.steer_rad, d, model));
        x.theta_rad = wrap_angle(x.theta_rad);
        x
    }

    /// Speed and distance covered `horizon_s` after a speed of `speed_mps`, through the
    /// acceleration requests of the last `horizon_s` (the vehicle stops, it does not reverse).
    pub(crate) fn predict_speed(&self, speed_mps: f64, horizon_s: f64, newest_held_s: f64) -> (f64, f64) {
        let (mut v, mut dist) = (speed_mps, 0.0);
        self.window(horizon_s, newest_held_s, |r, d| {
            let v_next = v + r.accel_mps2 * d;
            let (v_end, moving) = if v >= 0.0 && v_next < 0.0 { (0.0, v / -r.accel_mps2) } else { (v_next, d) };
            dist += 0.5 * (v + v_end) * moving;
            v = v_end;
        });
        (v, dist)
    }
}

/// The kinematic bicycle about the footprint centre at constant speed and road-wheel angle
/// `steer_rad` for `duration_s`.
pub(crate) fn drive(mut x: State, steer_rad: f64, duration_s: f64, model: &SteeringModel) -> State {
    if duration_s <= 0.0 {
        return x;
    }
    let tan_d = steer_rad.tan();
    let beta = (model.center_to_rear_axle_m / model.wheelbase_m * tan_d).atan();
    let v = x.speed_mps;
    let yaw_rate = v / model.wheelbase_m * beta.cos() * tan_d;
    let n = (duration_s / MAX_STEP_S).ceil().clamp(1.0, 100.0);
    let h = duration_s / n;
    for _ in 0..n as u32 {
        let theta_mid = x.theta_rad + 0.5 * yaw_rate * h;
        x.px += v * (theta_mid + beta).cos() * h;
        x.py += v * (theta_mid + beta).sin() * h;
        x.theta_rad += yaw_rate * h;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> SteeringModel {
        SteeringModel { wheelbase_m: 2.85, center_to_rear_axle_m: 1.45, max_steer_rad: 0.55, max_steer_rate_radps: 0.6 }
    }

    fn steer(steer_rad: f64) -> Request {
        Request { accel_mps2: 0.0, steer_rad }
    }

    fn start() -> State {
        State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 }
    }

    #[test]
    fn straight_wheels_predict_a_straight_line() {
        let h = RequestHistory::new(Request::default());
        let x = h.predict_pose(&start(), &model(), 0.3, 0.1);
        assert!((x.px - 3.0).abs() < 1e-12 && x.py == 0.0 && x.theta_rad == 0.0);
    }

    #[test]
    fn the_window_uses_the_requests_as_they_were_held() {
        // 0.2 rad held for 0.1 s, then 0.0 held for 0.1 s so far; horizon 0.3 s: the first 0.1 s
        // come from before the history (straight), then 0.1 s at 0.2 rad, then 0.1 s straight.
        let mut h = RequestHistory::new(Request::default());
        h.push(steer(0.2), 0.1);
        h.push(steer(0.0), 0.1);
        let x = h.predict_pose(&start(), &model(), 0.3, 0.1);
        let m = model();
        let expected = drive(drive(drive(start(), 0.0, 0.1, &m), 0.2, 0.1, &m), 0.0, 0.1, &m);
        assert!((x.px - expected.px).abs() < 1e-12 && (x.py - expected.py).abs() < 1e-12);
        let turned = 10.0 / 2.85 * (1.45 / 2.85 * 0.2f64.tan()).atan().cos() * 0.2f64.tan() * 0.1;
        assert!((x.theta_rad - turned).abs() < 1e-12, "{} vs {turned}", x.theta_rad);
        // A window shorter than the newest hold sees only the newest request.
        let y = h.predict_pose(&start(), &model(), 0.05, 0.1);
        assert_eq!(y.theta_rad, 0.0);
    }

    #[test]
    fn an_overflowing_history_keeps_the_newest_requests() {
        let mut h = RequestHistory::new(Request::default());
        for k in 0..(CAPACITY + 10) {
            h.push(steer(if k < 10 { 0.3 } else { 0.1 }), 0.01);
        }
        assert_eq!(h.len, CAPACITY);
        assert_eq!(h.before.steer_rad, 0.3, "the last request dropped");
        let x = h.predict_pose(&start(), &model(), 2.0, 0.01);
        assert!(x.theta_rad > 0.0 && x.is_finite());
    }

    #[test]
    fn the_speed_follows_the_acceleration_requests_and_stops_at_zero() {
        let mut h = RequestHistory::new(Request::default());
        h.push(Request { accel_mps2: -2.0, steer_rad: 0.0 }, 0.1);
        h.push(Request { accel_mps2: 1.0, steer_rad: 0.0 }, 0.1);
        // 0.1 s at 0 (before), 0.1 s at −2, 0.05 s at +1.
        let (v, d) = h.predict_speed(10.0, 0.25, 0.05);
        assert!((v - (10.0 - 0.2 + 0.05)).abs() < 1e-12, "{v}");
        assert!((d - (1.0 + 0.99 + 0.5 * (9.8 + 9.85) * 0.05)).abs() < 1e-12, "{d}");
        let (v, d) = h.predict_speed(0.1, 0.25, 0.05);
        assert!(v >= 0.0 && (0.0..0.1 * 0.25).contains(&d), "{v} {d}");
    }
}
