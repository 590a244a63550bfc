//! The guidance context of a [`GroundedScenario`].

use v2t_model::grounded::{AgentRole, GroundedScenario};

use super::{Anchor, ConflictWindow, GuidanceContext, GuidanceError};

/// Planned passage times of one grounded conflict (the grounded scenario has the conflict point but
/// not when each vehicle passes it; the planner that fixes the PET provides them).
#[derive(Debug, Clone, PartialEq)]
pub struct ConflictTiming {
    /// The BV of the conflict (`GroundedConflict::bv_id`).
    pub bv_id: String,
    /// When the VUT passes the conflict point, s from scenario start.
    pub vut_time_s: f64,
    /// When the BV passes it, s from scenario start.
    pub bv_time_s: f64,
}

impl GuidanceContext {
    /// Anchors and conflict windows of `scenario`, agents indexed in `scenario.agents` order
    /// (time 0 is the scenario start, the first state of the horizon):
    ///
    /// - every start and goal anchor that has a `time_s` becomes an anchor of its agent (those
    ///   without a time are not used: the paper's anchors are `(position, time)` pairs);
    /// - for every conflict with an entry in `timings`, the conflict point becomes an anchor of the
    ///   VUT at `vut_time_s` and of the BV at `bv_time_s`, and the clearance term is off for that
    ///   pair over `[min − pad, max + pad]` of the two times;
    /// - for a conflict without timing, the clearance term is off for that pair over the whole
    ///   horizon (the interaction is intended but its time is unknown).
    ///
    /// `boundaries` are the solid lane boundaries of the map fragment (e.g. from `v2t-map`).
    pub fn from_grounded(
        scenario: &GroundedScenario,
        timings: &[ConflictTiming],
        window_pad_s: f64,
        boundaries: Vec<Vec<v2t_model::geometry::Point2>>,
    ) -> Result<Self, GuidanceError> {
        let mut anchors = Vec::new();
        for (i, a) in scenario.agents.iter().enumerate() {
            for anchor in [&a.start, &a.goal] {
                if let Some(t) = anchor.time_s {
                    anchors.push(Anchor { agent: i, position: anchor.position, time_s: t });
                }
            }
        }
        let index_of = |id: &str| {
            scenario.agents.iter().position(|a| a.id == id).ok_or_else(|| GuidanceError::UnknownAgent(id.to_owned()))
        };
        let vut = scenario
            .agents
            .iter()
            .position(|a| a.role == AgentRole::Vut)
            .ok_or_else(|| GuidanceError::UnknownAgent("vut".to_owned()))?;
        let mut conflict_windows = Vec::new();
        for c in &scenario.conflicts {
            let bv = index_of(&c.bv_id)?;
            match timings.iter().find(|t| t.bv_id == c.bv_id) {
                Some(t) => {
                    anchors.push(Anchor { agent: vut, position: c.point, time_s: t.vut_time_s });
                    anchors.push(Anchor { agent: bv, position: c.point, time_s: t.bv_time_s });
                    conflict_windows.push(ConflictWindow {
                        agent_a: vut,
                        agent_b: bv,
                        from_s: t.vut_time_s.min(t.bv_time_s) - window_pad_s,
                        to_s: t.vut_time_s.max(t.bv_time_s) + window_pad_s,
                    });
                }
                None => conflict_windows.push(ConflictWindow {
                    agent_a: vut,
                    agent_b: bv,
                    from_s: f64::NEG_INFINITY,
                    to_s: f64::INFINITY,
                }),
            }
        }
        Ok(Self { anchors, boundaries, conflict_windows, boundary_sides: Vec::new(), previous_accel_mps2: Vec::new() })
    }
}
