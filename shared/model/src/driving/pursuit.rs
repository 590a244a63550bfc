//! Pure pursuit (Coulter, 1992): the circular arc that leaves a vehicle's reference point along
//! its heading and passes through a look-ahead point has curvature `κ = 2 sin α / L`, with `α`
//! the bearing of the point off the heading and `L` its distance. A kinematic vehicle follows it
//! with the yaw rate `ω = v κ`, or a bicycle of wheelbase `l` with the road-wheel angle
//! `δ = atan(l κ)` (its reference point the rear axle).
//!
//! The simulated proving ground steers its VUTs and reference-following BVs with it, the
//! synthetic corpus's drivers and the tail of a generated prior yaw with it. How far ahead each
//! looks is its own choice (a tuning of that driver), and so is its reference point. The copies
//! this replaces floored `L` differently (1 mm twice, 1 m once); the floor only matters for a
//! target within a metre, which is no look-ahead point at all (every caller looks 3 m ahead or
//! more), and there 1 m keeps the command bounded (`|κ| ≤ 2 /m`, tighter than any vehicle turns,
//! so the caller's steering or yaw limit applies) where 1 mm asked for a radius of half a
//! millimetre.

use crate::geometry::{Point2, wrap_angle};

/// The distance to the look-ahead point is floored here, m.
pub const MIN_PURSUIT_DISTANCE_M: f64 = 1.0;

/// `gain · κ` for the pure-pursuit arc from `from`, heading `heading_rad`, through `target`
/// (`κ = 2 sin α / L`, positive turning left): the yaw rate with the speed as `gain` (rad/s),
/// the tangent of a bicycle's road-wheel angle with its wheelbase (`from` its rear axle), `κ`
/// itself with 1 (1/m). Computed as `2 · gain · sin α / L`, one rounding order for every caller.
pub fn pure_pursuit(from: Point2, heading_rad: f64, target: Point2, gain: f64) -> f64 {
    let d = target.sub(from);
    let alpha = wrap_angle(d.y.atan2(d.x) - heading_rad);
    2.0 * gain * alpha.sin() / d.norm().max(MIN_PURSUIT_DISTANCE_M)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn it_turns_toward_the_target() {
        let o = Point2::new(0.0, 0.0);
        assert!(pure_pursuit(o, 0.0, Point2::new(10.0, 1.0), 10.0) > 0.0);
        assert!(pure_pursuit(o, 0.0, Point2::new(10.0, -1.0), 10.0) < 0.0);
        assert!(pure_pursuit(o, 0.0, Point2::new(10.0, 0.0), 10.0).abs() < 1e-12);
        // Behind and to the left, across the ±π seam: still left.
        assert!(pure_pursuit(o, 3.0, Point2::new(-10.0, -1.0), 1.0) > 0.0);
        // At the target itself (no bearing): finite.
        assert!(pure_pursuit(o, 0.3, o, 10.0).is_finite());
        // A target a millimetre aside: bounded by the floor.
        assert!(pure_pursuit(o, 0.0, Point2::new(0.0, 1e-3), 1.0) <= 2.0 / MIN_PURSUIT_DISTANCE_M);
    }

    proptest! {
        #[test]
        fn the_arc_through_a_point_of_a_circle_is_that_circle(
            radius in 1.0f64..500.0, angle in 0.01f64..3.0, heading in -3.1f64..3.1, left in any::<bool>(),
            x in -100.0f64..100.0, y in -100.0f64..100.0, speed in 0.0f64..30.0,
        ) {
            // A point `angle` along a circle of `radius` tangent to the heading at (x, y).
            let side = if left { 1.0 } else { -1.0 };
            let from = Point2::new(x, y);
            let center = from.add(Point2::from_heading(heading).perp().scale(side * radius));
            let (r, phi) = (from.sub(center), side * angle);
            let target = center.add(Point2::new(r.x * phi.cos() - r.y * phi.sin(), r.x * phi.sin() + r.y * phi.cos()));
            prop_assume!(from.dist(target) >= MIN_PURSUIT_DISTANCE_M);
            let kappa = pure_pursuit(from, heading, target, 1.0);
            prop_assert!((kappa - side / radius).abs() < 1e-9, "{kappa} vs {}", side / radius);
            // The gain scales it.
            prop_assert!((pure_pursuit(from, heading, target, speed) - speed * kappa).abs() < 1e-9 * (1.0 + speed));
        }
    }
}
