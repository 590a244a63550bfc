//! The condition `c` of the denoiser: what it knows about the scenario.
//!
//! Per agent slot, in the agent's **start frame** (origin at its first position, x along its
//! first heading): whether the slot is used, the start speed, its route ahead (20 points 8 m apart
//! from the foot point of the start on the route, extended straight beyond the route's end), its
//! conflict anchor (position and time, if any) and whether it passes the conflict first or second.
//! For the scenario: the interaction kind (one-hot). Positions are divided by 50 m, speeds by
//! 10 m/s, times by the horizon. Time-aligned features, one row per patch: a Gaussian bump
//! (σ 0.5 s) at each slot's anchor time, and the patch's position (`t/T`, `sin`, `cos` of `2πt/T`).
//!
//! Slots: 0 and 1 are the two vehicles of the conflict (0 the one that moves into the other's
//! path: the cutter, the left turner, the merging vehicle of the synthetic corpus; the BV of a
//! grounded scenario), 2 a third vehicle.

use v2t_model::geometry::Point2;
use v2t_model::kinematics::State;
use v2t_model::path::ReferencePath;

use crate::denoiser::{DenoiserConfig, INTERACTION_KINDS};

/// Route points per slot.
pub const ROUTE_POINTS: usize = 20;
/// Their spacing along the route, m.
pub const ROUTE_SPACING_M: f64 = 8.0;
/// Condition numbers per slot: used, speed, route points, anchor (used, x, y, t), order.
pub const SLOT_FEATURES: usize = 2 + 2 * ROUTE_POINTS + 4 + 1;
/// Time-aligned channels per slot (the anchor-time bump).
pub const TIME_FEATURES_PER_SLOT: usize = 1;
/// Time-aligned channels of the patch position.
pub const TIME_POSITION_FEATURES: usize = 3;

const POSITION_SCALE_M: f64 = 50.0;
const SPEED_SCALE_MPS: f64 = 10.0;
const ANCHOR_BUMP_S: f64 = 0.5;

/// The interaction kinds the condition distinguishes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KindClass {
    /// A vehicle changes into the other's lane (cut-in, lane change).
    CutIn,
    /// Paths cross (left turn, crossing, right turn).
    LeftTurn,
    /// Lanes join.
    Merge,
}

impl KindClass {
    fn index(self) -> usize {
        match self {
            Self::CutIn => 0,
            Self::LeftTurn => 1,
            Self::Merge => 2,
        }
    }

    /// The class of a semantic interaction type.
    pub fn of_interaction(t: v2t_model::semantics::InteractionType) -> Self {
        use v2t_model::semantics::InteractionType as I;
        match t {
            I::CutIn | I::LaneChange => Self::CutIn,
            I::Merge => Self::Merge,
            _ => Self::LeftTurn,
        }
    }

    /// The class of a mined interaction.
    pub fn of_mined(k: crate::mining::InteractionKind) -> Self {
        use crate::mining::InteractionKind as K;
        match k {
            K::CutIn | K::LaneChange => Self::CutIn,
            K::Merge => Self::Merge,
            K::LeftTurn | K::Crossing => Self::LeftTurn,
        }
    }
}

/// Who passes the conflict first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PassingOrder {
    /// This slot passes first.
    First,
    /// This slot passes second.
    Second,
}

/// What the condition says about one agent.
#[derive(Debug, Clone, PartialEq)]
pub struct SlotCondition {
    /// Its state at the start of the horizon (track frame).
    pub start: State,
    /// Its route ahead, [`ROUTE_POINTS`] points in its start frame.
    pub route_local: Vec<Point2>,
    /// The conflict point (track frame) and when it passes it, s from the horizon's start.
    pub anchor: Option<(Point2, f64)>,
    /// Whether it passes first or second, if it has a conflict.
    pub order: Option<PassingOrder>,
}

/// The whole condition of one sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Condition {
    /// One entry per slot, `None` for an empty slot.
    pub slots: Vec<Option<SlotCondition>>,
    /// The interaction kind.
    pub kind: KindClass,
}

/// `p` (track frame) in the frame of `start`.
pub fn to_local(start: &State, p: Point2) -> Point2 {
    let d = p.sub(start.position());
    let (s, c) = start.theta_rad.sin_cos();
    Point2::new(c * d.x + s * d.y, -s * d.x + c * d.y)
}

/// The point at arc length `s` of `route`, which goes on straight beyond its end.
pub fn point_on_route(route: &ReferencePath, s: f64) -> Point2 {
    let len = route.length();
    if s <= len {
        route.point_at(s)
    } else {
        route.point_at(len).add(Point2::from_heading(route.heading_at(len)).scale(s - len))
    }
}

/// [`ROUTE_POINTS`] points of `route` ahead of the foot point of `start`, in its start frame.
pub fn route_ahead(route: &ReferencePath, start: &State) -> Vec<Point2> {
    let s0 = route.project(start.position()).map_or(0.0, |f| f.s_m.max(0.0));
    (0..ROUTE_POINTS).map(|j| to_local(start, point_on_route(route, s0 + j as f64 * ROUTE_SPACING_M))).collect()
}

impl Condition {
    /// The condition vector, `cfg.condition_len()` numbers.
    pub fn features(&self, cfg: &DenoiserConfig) -> Vec<f32> {
        let mut out = Vec::with_capacity(cfg.condition_len());
        for slot in 0..cfg.slots {
            match self.slots.get(slot).and_then(Option::as_ref) {
                None => out.extend(std::iter::repeat_n(0.0f32, SLOT_FEATURES)),
                Some(s) => {
                    out.push(1.0);
                    out.push((s.start.speed_mps / SPEED_SCALE_MPS) as f32);
                    for j in 0..ROUTE_POINTS {
                        let p = s.route_local.get(j).copied().unwrap_or_default();
                        out.push((p.x / POSITION_SCALE_M) as f32);
                        out.push((p.y / POSITION_SCALE_M) as f32);
                    }
                    match s.anchor {
                        Some((p, t)) => {
                            let local = to_local(&s.start, p);
                            out.push(1.0);
                            out.push((local.x / POSITION_SCALE_M) as f32);
                            out.push((local.y / POSITION_SCALE_M) as f32);
                            out.push((t / horizon_s(cfg)) as f32);
                        }
                        None => out.extend([0.0f32; 4]),
                    }
                    out.push(match s.order {
                        Some(PassingOrder::First) => 1.0,
                        Some(PassingOrder::Second) => -1.0,
                        None => 0.0,
                    });
                }
            }
        }
        let mut kind = [0.0f32; INTERACTION_KINDS];
        if let Some(k) = kind.get_mut(self.kind.index()) {
            *k = 1.0;
        }
        out.extend(kind);
        out
    }

    /// The time-aligned features, `[channel][patch]` (`cfg.time_channels() × cfg.patches()`).
    pub fn time_features(&self, cfg: &DenoiserConfig) -> Vec<f32> {
        let l = cfg.patches();
        let horizon = horizon_s(cfg);
        let patch_s = horizon / l as f64;
        let centre = |j: usize| (j as f64 + 0.5) * patch_s;
        let mut out = Vec::with_capacity(cfg.time_channels() * l);
        for slot in 0..cfg.slots {
            let anchor_t = self.slots.get(slot).and_then(Option::as_ref).and_then(|s| s.anchor).map(|(_, t)| t);
            for j in 0..l {
                out.push(match anchor_t {
                    Some(t) => (-0.5 * ((centre(j) - t) / ANCHOR_BUMP_S).powi(2)).exp() as f32,
                    None => 0.0,
                });
            }
        }
        for j in 0..l {
            out.push((centre(j) / horizon) as f32);
        }
        for j in 0..l {
            out.push((std::f64::consts::TAU * centre(j) / horizon).sin() as f32);
        }
        for j in 0..l {
            out.push((std::f64::consts::TAU * centre(j) / horizon).cos() as f32);
        }
        out
    }
}

/// The horizon `T · 0.1 s`.
pub fn horizon_s(cfg: &DenoiserConfig) -> f64 {
    cfg.steps as f64 * crate::synth::DT_S
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_frame_and_route_ahead() {
        let start = State { px: 10.0, py: 5.0, theta_rad: std::f64::consts::FRAC_PI_2, speed_mps: 8.0 };
        let p = to_local(&start, Point2::new(10.0, 15.0));
        assert!((p.x - 10.0).abs() < 1e-12 && p.y.abs() < 1e-12);
        let route = ReferencePath::from_points(&[Point2::new(12.0, 0.0), Point2::new(12.0, 50.0)]).unwrap();
        let ahead = route_ahead(&route, &start);
        assert_eq!(ahead.len(), ROUTE_POINTS);
        // The route lies 2 m to the right, starting at the foot point (y = 5).
        assert!(ahead[0].x.abs() < 1e-9 && (ahead[0].y + 2.0).abs() < 1e-9);
        assert!((ahead[1].x - ROUTE_SPACING_M).abs() < 1e-9);
        // Beyond the end (45 m ahead) the route goes on straight.
        assert!((ahead[10].x - 80.0).abs() < 1e-9 && (ahead[10].y + 2.0).abs() < 1e-9);
    }

    #[test]
    fn feature_lengths_match_the_config() {
        let cfg = DenoiserConfig::default();
        let start = State { speed_mps: 10.0, ..State::default() };
        let slot = SlotCondition {
            start,
            route_local: vec![Point2::default(); ROUTE_POINTS],
            anchor: Some((Point2::new(30.0, 0.0), 3.0)),
            order: Some(PassingOrder::First),
        };
        let c = Condition { slots: vec![Some(slot), None], kind: KindClass::Merge };
        let f = c.features(&cfg);
        assert_eq!(f.len(), cfg.condition_len());
        assert_eq!(f[0], 1.0);
        assert_eq!(f[SLOT_FEATURES], 0.0);
        assert_eq!(f[f.len() - 1], 1.0);
        let t = c.time_features(&cfg);
        assert_eq!(t.len(), cfg.time_channels() * cfg.patches());
        // The bump peaks at the patch holding 3 s.
        let bump = &t[..cfg.patches()];
        let peak = bump.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap().0;
        assert_eq!(peak, 7);
    }
}
