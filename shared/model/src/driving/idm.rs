//! The Intelligent Driver Model (Treiber, Hennecke & Helbing, 2000):
//! `a = a_max [1 − (v/v0)^δ − (s*/s)²]` with `s* = s0 + max(0, v T + v Δv / (2 √(a_max b)))`,
//! `Δv` the closing speed on the obstacle; and the enhanced IDM (Kesting, Treiber & Helbing, 2010)
//! that blends it with the constant-acceleration heuristic, so that a close cut-in of a vehicle
//! no slower than the driver does not trigger the plain IDM's emergency braking.
//!
//! The simulated VUTs (`v2t-sim`, δ from their configuration) and the synthetic corpus's drivers
//! (`v2t-diffusion`, δ = 4) both drive with it. The two copies this replaces differed in one
//! detail: the corpus wrote `(v/v0)⁴` as `powi(4)` (two roundings) where the VUTs took the
//! configured δ with `powf`; δ is a parameter of the model, so `powf` of the driver's δ it is (for
//! δ = 4 the two agree to the last bit or one unit in the last place).

/// Never aim below this desired speed (keeps `v/v0` finite), m/s.
pub const MIN_DESIRED_SPEED_MPS: f64 = 0.5;
/// Smallest gap used in the interaction term and the heuristic (keeps them finite), m.
pub const MIN_GAP_M: f64 = 0.1;
/// Coolness of the enhanced IDM: the weight of the constant-acceleration heuristic.
pub const COOLNESS: f64 = 0.99;
/// Smallest `a_max · b` under the square root of `s*`, m²/s⁴.
const MIN_ACCEL_PRODUCT: f64 = 1e-6;
/// Smallest comfortable deceleration of the enhanced IDM's blend, m/s².
const MIN_COMFORT_DECEL_MPS2: f64 = 0.1;

/// A driver's IDM parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Idm {
    /// Desired time headway `T`, s.
    pub time_gap_s: f64,
    /// Standstill gap `s0`, m.
    pub min_gap_m: f64,
    /// Maximum acceleration `a_max`, m/s².
    pub max_accel_mps2: f64,
    /// Comfortable deceleration `b`, m/s².
    pub comfort_decel_mps2: f64,
    /// Free-road exponent `δ` (4 in the original model).
    pub accel_exponent: f64,
}

/// What a driver follows or stops behind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obstacle {
    /// Bumper-to-bumper gap along the driver's path, m.
    pub gap_m: f64,
    /// Its speed along the driver's path, m/s: 0 for a standing obstacle or a stop point.
    pub speed_mps: f64,
}

impl Idm {
    /// IDM acceleration at `speed_mps` (below 0 counts as standing) toward `desired_mps` (at least
    /// [`MIN_DESIRED_SPEED_MPS`]), behind `obstacle` if any, m/s².
    pub fn accel(&self, speed_mps: f64, desired_mps: f64, obstacle: Option<Obstacle>) -> f64 {
        let v = speed_mps.max(0.0);
        let free = 1.0 - (v / desired_mps.max(MIN_DESIRED_SPEED_MPS)).powf(self.accel_exponent);
        let interaction = obstacle.map_or(0.0, |o| {
            let sqrt_ab = (self.max_accel_mps2 * self.comfort_decel_mps2).max(MIN_ACCEL_PRODUCT).sqrt();
            let dynamic = v * self.time_gap_s + v * (v - o.speed_mps) / (2.0 * sqrt_ab);
            ((self.min_gap_m + dynamic.max(0.0)) / o.gap_m.max(MIN_GAP_M)).powi(2)
        });
        self.max_accel_mps2 * (free - interaction)
    }

    /// Enhanced-IDM acceleration behind `lead` (its acceleration unknown, taken as 0), m/s²: the
    /// IDM where it brakes no harder than the constant-acceleration heuristic
    /// `−(v − v_lead)² / (2 s)`; otherwise softened toward the heuristic with coolness
    /// [`COOLNESS`], `(1 − c) a_IDM + c [a_CAH + b tanh((a_IDM − a_CAH) / b)]`.
    pub fn enhanced_accel(&self, speed_mps: f64, desired_mps: f64, lead: Obstacle) -> f64 {
        let v = speed_mps.max(0.0);
        let idm = self.accel(v, desired_mps, Some(lead));
        let cah =
            if v <= lead.speed_mps { 0.0 } else { -(v - lead.speed_mps).powi(2) / (2.0 * lead.gap_m.max(MIN_GAP_M)) };
        if idm >= cah {
            return idm;
        }
        let b = self.comfort_decel_mps2.max(MIN_COMFORT_DECEL_MPS2);
        (1.0 - COOLNESS) * idm + COOLNESS * (cah + b * ((idm - cah) / b).tanh())
    }
}

/// Time to cover `d_m` from `v_mps`, accelerating at `a_mps2` up to `vmax_mps` (then constant);
/// constant speed when already at or above `vmax_mps` or without acceleration. Infinite when it
/// never arrives, 0 when already there. How a driver judging a gap times its own way to a zone
/// (the simulated IDM VUT, the regulator's model of a VUT that reacts to the BV).
#[must_use]
pub fn travel_time(d_m: f64, v_mps: f64, a_mps2: f64, vmax_mps: f64) -> f64 {
    if d_m <= 0.0 {
        return 0.0;
    }
    let v = v_mps.max(0.0);
    if a_mps2 <= 0.0 || v >= vmax_mps {
        return if v > 1e-6 { d_m / v } else { f64::INFINITY };
    }
    let d_accel = (vmax_mps * vmax_mps - v * v) / (2.0 * a_mps2);
    if d_m <= d_accel {
        ((v * v + 2.0 * a_mps2 * d_m).sqrt() - v) / a_mps2
    } else {
        (vmax_mps - v) / a_mps2 + (d_m - d_accel) / vmax_mps
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A typical driver.
    fn driver() -> Idm {
        Idm { time_gap_s: 1.5, min_gap_m: 2.0, max_accel_mps2: 1.5, comfort_decel_mps2: 2.0, accel_exponent: 4.0 }
    }

    fn standing(gap_m: f64) -> Option<Obstacle> {
        Some(Obstacle { gap_m, speed_mps: 0.0 })
    }

    #[test]
    fn free_at_low_speed_zero_at_the_desired_speed_and_brakes_when_close() {
        let d = driver();
        assert!((d.accel(0.0, 12.0, None) - d.max_accel_mps2).abs() < 1e-12);
        assert!(d.accel(12.0, 12.0, None).abs() < 1e-12);
        assert!(d.accel(14.0, 12.0, None) < 0.0);
        assert!(d.accel(10.0, 12.0, standing(5.0)) < -d.comfort_decel_mps2);
        // A negative speed counts as standing; a desired speed of 0 as the floor.
        assert_eq!(d.accel(-1.0, 12.0, standing(30.0)), d.accel(0.0, 12.0, standing(30.0)));
        assert!(d.accel(0.0, 0.0, None).is_finite());
        // At standstill `s0` from an obstacle, it does not move.
        assert!(d.accel(0.0, 12.0, standing(d.min_gap_m)).abs() < 1e-12);
    }

    #[test]
    fn the_enhanced_idm_softens_a_close_cut_in_without_closing_speed() {
        let d = driver();
        // A vehicle cut in 6 m ahead at the same speed: the IDM brakes hard, the enhanced IDM gently.
        let lead = Obstacle { gap_m: 6.0, speed_mps: 15.0 };
        let (idm, eidm) = (d.accel(15.0, 15.0, Some(lead)), d.enhanced_accel(15.0, 15.0, lead));
        assert!(
            idm < -d.comfort_decel_mps2 && eidm > idm && eidm >= -d.comfort_decel_mps2 + 0.01 * idm - 1e-9,
            "{idm} {eidm}"
        );
        // Closing fast on a near obstacle it still brakes at least as the kinematics need.
        let need = -(10.0f64 * 10.0) / (2.0 * 20.0);
        assert!(d.enhanced_accel(10.0, 15.0, Obstacle { gap_m: 20.0, speed_mps: 0.0 }) <= need + 0.5);
        // The IDM itself where it is not braking.
        let far = Obstacle { gap_m: 200.0, speed_mps: 15.0 };
        assert_eq!(d.enhanced_accel(5.0, 15.0, far), d.accel(5.0, 15.0, Some(far)));
    }

    proptest! {
        #[test]
        fn closer_brakes_harder_and_the_enhanced_idm_never_brakes_harder_than_the_idm(
            t in 0.8f64..2.2, s0 in 1.0f64..4.0, a in 0.5f64..3.0, b in 1.0f64..3.5, delta in 1.0f64..6.0,
            v in 0.0f64..25.0, v0 in 1.0f64..30.0, lead in 0.0f64..25.0, gap in 0.2f64..100.0, closer in 0.0f64..1.0,
        ) {
            let d = Idm { time_gap_s: t, min_gap_m: s0, max_accel_mps2: a, comfort_decel_mps2: b, accel_exponent: delta };
            let far = Obstacle { gap_m: gap, speed_mps: lead };
            let near = Obstacle { gap_m: gap * closer, ..far };
            let (a_far, a_near) = (d.accel(v, v0, Some(far)), d.accel(v, v0, Some(near)));
            prop_assert!(a_near <= a_far, "{a_near} > {a_far}");
            prop_assert!(a_far <= d.accel(v, v0, None));
            // A slower lead at the same gap: harder braking.
            let slower = Obstacle { speed_mps: lead * closer, ..far };
            prop_assert!(d.accel(v, v0, Some(slower)) <= a_far);
            // The enhanced IDM: never harder than the IDM, closer still brakes at least as hard.
            let (e_far, e_near) = (d.enhanced_accel(v, v0, far), d.enhanced_accel(v, v0, near));
            prop_assert!(e_far >= a_far && e_near >= a_near);
            prop_assert!(e_near <= e_far + 1e-9, "{e_near} > {e_far}");
            prop_assert!(e_far <= a + 1e-12);
        }
    }
}
