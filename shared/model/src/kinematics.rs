//! The paper's discrete vehicle model (eq. 4–5) and its adjoint.
//!
//! State `x = [px, py, θ, v]`, control `u = [a, ω]`, explicit Euler with step `dt`:
//! `px += v cosθ dt, py += v sinθ dt, θ += ω dt, v += a dt`. The model is kept exactly as written
//! (speed is not clamped) so that it stays differentiable; limits are the job of the guidance
//! energies and of the plant.
//!
//! ```
//! use v2t_model::kinematics::{rollout, rollout_vjp, Control, State};
//! let x0 = State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 };
//! let u = vec![Control { accel_mps2: 1.0, yaw_rate_radps: 0.1 }; 20];
//! let xs = rollout(x0, &u, 0.1);
//! assert_eq!(xs.len(), 21);
//! // Gradient of the final x position with respect to every control.
//! let mut seed = vec![State::default(); xs.len()];
//! seed[20].px = 1.0;
//! let grad = rollout_vjp(&xs, &u, 0.1, &seed).unwrap();
//! assert!(grad[0].accel_mps2 > 0.0);
//! ```

use serde::{Deserialize, Serialize};

/// Vehicle state `[px, py, θ, v]` in the track frame.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, schemars::JsonSchema)]
pub struct State {
    /// East position, m.
    pub px: f64,
    /// North position, m.
    pub py: f64,
    /// Heading, rad, counter-clockwise from east.
    pub theta_rad: f64,
    /// Speed along the heading, m/s.
    pub speed_mps: f64,
}

impl State {
    /// All four components finite.
    pub fn is_finite(&self) -> bool {
        self.px.is_finite() && self.py.is_finite() && self.theta_rad.is_finite() && self.speed_mps.is_finite()
    }

    /// The position as a point.
    pub fn position(&self) -> crate::geometry::Point2 {
        crate::geometry::Point2::new(self.px, self.py)
    }
}

/// Control `[a, ω]`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Control {
    /// Longitudinal acceleration, m/s².
    pub accel_mps2: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: f64,
}

impl Control {
    /// Both components finite.
    pub fn is_finite(&self) -> bool {
        self.accel_mps2.is_finite() && self.yaw_rate_radps.is_finite()
    }
}

/// Shapes of the arrays given to [`rollout_vjp`] do not agree.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "rollout adjoint: {states} states, {controls} controls and {seeds} state gradients (need states = controls + 1 = gradients)"
)]
pub struct ShapeError {
    /// Number of states given.
    pub states: usize,
    /// Number of controls given.
    pub controls: usize,
    /// Number of state gradients given.
    pub seeds: usize,
}

/// One step of the discrete model.
pub fn step(x: State, u: Control, dt_s: f64) -> State {
    let (s, c) = x.theta_rad.sin_cos();
    State {
        px: x.px + x.speed_mps * c * dt_s,
        py: x.py + x.speed_mps * s * dt_s,
        theta_rad: x.theta_rad + u.yaw_rate_radps * dt_s,
        speed_mps: x.speed_mps + u.accel_mps2 * dt_s,
    }
}

/// Rolls `controls` out from `x0`; writes `controls.len() + 1` states into `out` (cleared first).
pub fn rollout_into(x0: State, controls: &[Control], dt_s: f64, out: &mut Vec<State>) {
    out.clear();
    out.reserve(controls.len() + 1);
    let mut x = x0;
    out.push(x);
    for u in controls {
        x = step(x, *u, dt_s);
        out.push(x);
    }
}

/// Rolls `controls` out from `x0`: `controls.len() + 1` states, `x0` first.
pub fn rollout(x0: State, controls: &[Control], dt_s: f64) -> Vec<State> {
    let mut out = Vec::new();
    rollout_into(x0, controls, dt_s, &mut out);
    out
}

/// Vector-Jacobian product of the rollout with respect to the controls.
///
/// Given the rolled-out `states` (from [`rollout`] with the same `controls` and `dt_s`) and the
/// gradient of a scalar objective with respect to every state, `dL/dx_t` in `state_grads`
/// (same length as `states`; the entry for `x_0` is ignored because `x_0` does not depend on the
/// controls), returns `dL/du_t` for every control. This is the reverse-mode (adjoint) sweep
/// `λ_T = g_T`, `λ_t = g_t + (∂f/∂x_t)ᵀ λ_{t+1}`, `dL/du_t = (∂f/∂u_t)ᵀ λ_{t+1}`.
pub fn rollout_vjp(
    states: &[State],
    controls: &[Control],
    dt_s: f64,
    state_grads: &[State],
) -> Result<Vec<Control>, ShapeError> {
    let mut out = vec![Control::default(); controls.len()];
    rollout_vjp_into(states, controls, dt_s, state_grads, &mut out)?;
    Ok(out)
}

/// [`rollout_vjp`] writing into a caller-owned buffer of `controls.len()` entries.
pub fn rollout_vjp_into(
    states: &[State],
    controls: &[Control],
    dt_s: f64,
    state_grads: &[State],
    out: &mut [Control],
) -> Result<(), ShapeError> {
    let n = controls.len();
    if states.len() != n + 1 || state_grads.len() != n + 1 || out.len() != n {
        return Err(ShapeError { states: states.len(), controls: n, seeds: state_grads.len() });
    }
    // λ_{t+1}, starting at λ_T = g_T.
    let mut lam = state_grads.last().copied().unwrap_or_default();
    for t in (0..n).rev() {
        let (Some(x), Some(g), Some(o)) = (states.get(t), state_grads.get(t), out.get_mut(t)) else {
            continue;
        };
        *o = Control { accel_mps2: lam.speed_mps * dt_s, yaw_rate_radps: lam.theta_rad * dt_s };
        let (s, c) = x.theta_rad.sin_cos();
        let v = x.speed_mps;
        lam = State {
            px: g.px + lam.px,
            py: g.py + lam.py,
            theta_rad: g.theta_rad + lam.theta_rad + dt_s * v * (c * lam.py - s * lam.px),
            speed_mps: g.speed_mps + lam.speed_mps + dt_s * (c * lam.px + s * lam.py),
        };
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A smooth nonlinear objective of the whole trajectory and its gradient per state.
    fn objective(xs: &[State], w: &[[f64; 4]]) -> f64 {
        xs.iter()
            .zip(w)
            .map(|(x, w)| {
                w[0] * x.px
                    + w[1] * x.py * x.py * 0.01
                    + w[2] * x.theta_rad.sin()
                    + w[3] * x.speed_mps * x.speed_mps * 0.1
            })
            .sum()
    }

    fn objective_grad(xs: &[State], w: &[[f64; 4]]) -> Vec<State> {
        xs.iter()
            .zip(w)
            .map(|(x, w)| State {
                px: w[0],
                py: w[1] * 2.0 * x.py * 0.01,
                theta_rad: w[2] * x.theta_rad.cos(),
                speed_mps: w[3] * 2.0 * x.speed_mps * 0.1,
            })
            .collect()
    }

    fn controls_strategy(n: usize) -> impl Strategy<Value = Vec<Control>> {
        prop::collection::vec((-3.0f64..3.0, -0.5f64..0.5), n)
            .prop_map(|v| v.into_iter().map(|(a, w)| Control { accel_mps2: a, yaw_rate_radps: w }).collect())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn adjoint_matches_central_finite_differences(
            u in controls_strategy(25),
            w in prop::collection::vec(prop::array::uniform4(-1.0f64..1.0), 26),
            v0 in 0.0f64..20.0, th0 in -3.0f64..3.0, dt in 0.05f64..0.2,
        ) {
            let x0 = State { px: 3.0, py: -2.0, theta_rad: th0, speed_mps: v0 };
            let xs = rollout(x0, &u, dt);
            let grad = rollout_vjp(&xs, &u, dt, &objective_grad(&xs, &w)).unwrap();
            let h = 1e-5;
            let mut fd = Vec::new();
            for t in 0..u.len() {
                for ch in 0..2 {
                    let mut up = u.clone();
                    let mut dn = u.clone();
                    if ch == 0 { up[t].accel_mps2 += h; dn[t].accel_mps2 -= h; }
                    else { up[t].yaw_rate_radps += h; dn[t].yaw_rate_radps -= h; }
                    let d = (objective(&rollout(x0, &up, dt), &w) - objective(&rollout(x0, &dn, dt), &w)) / (2.0 * h);
                    fd.push(d);
                }
            }
            let an: Vec<f64> = grad.iter().flat_map(|g| [g.accel_mps2, g.yaw_rate_radps]).collect();
            let diff = an.iter().zip(&fd).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
            let scale = fd.iter().map(|b| b * b).sum::<f64>().sqrt().max(1e-3);
            prop_assert!(diff / scale < 1e-6, "relative error {}", diff / scale);
        }
    }

    #[test]
    fn straight_constant_speed_rollout_is_exact() {
        let x0 = State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 };
        let xs = rollout(x0, &[Control::default(); 10], 0.1);
        assert!((xs[10].px - 10.0).abs() < 1e-12);
        assert_eq!(xs[10].py, 0.0);
    }

    #[test]
    fn shape_mismatch_is_an_error_not_a_panic() {
        let xs = rollout(State::default(), &[Control::default(); 3], 0.1);
        assert!(rollout_vjp(&xs, &[Control::default(); 2], 0.1, &xs).is_err());
    }
}
