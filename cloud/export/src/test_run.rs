//! Run files for the tests: a result that measured nothing and samples of given states.

use v2t_model::kinematics::State;
use v2t_model::{Style, Target};
use v2t_sim::plant::ActuationRequest;
use v2t_sim::runfile::RunFile;
use v2t_sim::runner::{AgentSample, RunResult, TraceSample};

/// A run of `scenario` (τ 2 s, rush) with `agent_ids` and one sample per `(t, states)`.
pub(crate) fn run(scenario: &str, agent_ids: &[&str], samples: &[(f64, Vec<State>)]) -> RunFile {
    let result = RunResult {
        scenario: scenario.to_owned(),
        vut_model: "idm-normal".into(),
        bv_controller: "reference".into(),
        seed: 1,
        target: Target::new(2.0, Style::Rush).unwrap(),
        duration_s: samples.last().map_or(0.0, |s| s.0),
        completed: true,
        conflicts: Vec::new(),
        pet_min_s: None,
        min_distance_m: 3.0,
        min_distance_t_s: 0.0,
        min_ttc_s: None,
        collision: None,
        zone_overlap: false,
    };
    let sample = |(t_s, states): &(f64, Vec<State>)| TraceSample {
        t_s: *t_s,
        agents: states
            .iter()
            .map(|state| AgentSample {
                state: *state,
                s_m: 0.0,
                l_m: 0.0,
                accel_mps2: 0.0,
                steer_rad: 0.0,
                request: ActuationRequest::default(),
            })
            .collect(),
        predicted_pet_s: Vec::new(),
    };
    RunFile {
        result,
        agent_ids: agent_ids.iter().map(|s| (*s).to_owned()).collect(),
        trace: samples.iter().map(sample).collect(),
        layout: None,
        realism: None,
        regulator: None,
        ecu: None,
        gate: None,
    }
}
