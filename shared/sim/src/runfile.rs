//! The run file: the JSON document of one simulated run. `video2track sim --json` and `v2t-sim-ecu
//! --out` write it; `render`, `export xosc`, the run reports and the demo read it. One type both
//! ways: a writer serializes a [`RunFile`], a reader deserializes one.
//!
//! What every run has — its result, its agents and its trace — is required: a file without it is
//! refused, the error naming the missing field. What only some runs have is an `Option`, `None`
//! when the file lacks it: the layout (files written before runs kept it), the realism (no human
//! reference given), the regulator's decisions (BVs that follow their references), the simulated
//! ECU's frame counts and the actuation gate's changes (runs outside the onboard runtime). Fields
//! the type does not know are ignored: a newer writer's additions do not make a file unreadable.

use serde::{Deserialize, Deserializer, Serialize};
use v2t_model::validate::{Validate, ValidationError, plausible, shown};

use crate::realism::RunRealism;
use crate::runner::{RunLayout, RunOutcome, RunResult, TraceSample};

/// A run as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunFile {
    /// What the run measured.
    pub result: RunResult,
    /// Agent ids in trace order: the VUT, then the BVs.
    pub agent_ids: Vec<String>,
    /// The recorded trace.
    pub trace: Vec<TraceSample>,
    /// The vehicles' footprints, the conflict zones and the routes; `None` in files written before
    /// runs kept them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layout: Option<RunLayout>,
    /// How human each vehicle's motion was; `None` (written as `null`) when no human reference was
    /// given.
    #[serde(default)]
    pub realism: Option<RunRealism>,
    /// Each regulated BV's decisions over the run; `None` when no BV regulated (or its decisions
    /// were not recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub regulator: Option<Vec<Vec<PlanRecord>>>,
    /// What the simulated drive-by-wire ECU saw of the commands; runs through the onboard runtime
    /// only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ecu: Option<EcuStats>,
    /// The actuation gate's state at every change; runs through the onboard runtime only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gate: Option<Vec<GateRecord>>,
}

impl RunFile {
    /// The file of `outcome` alone: its result, agents, trace and layout, nothing else measured.
    pub fn of(outcome: &RunOutcome) -> Self {
        Self {
            result: outcome.result.clone(),
            agent_ids: outcome.agent_ids.clone(),
            trace: outcome.trace.clone(),
            layout: Some(outcome.layout.clone()),
            realism: None,
            regulator: None,
            ecu: None,
            gate: None,
        }
    }
}

impl Validate for RunFile {
    /// What every reader of a run relies on: 1 to [`plausible::MAX_AGENTS`] agents, a trace of at
    /// least one sample whose times are finite and increasing, every sample holding every agent
    /// with a finite state, and each vehicle's motion plausible ([`plausible::motion`]) and
    /// kinematically consistent ([`plausible::kinematics`]: speeds ≥ 0, positions that move as the
    /// speeds say, headings along the motion). The error names `trace[k]…`.
    fn validate(&self) -> Result<(), ValidationError> {
        let n = self.agent_ids.len();
        if n == 0 || n > plausible::MAX_AGENTS {
            return Err(ValidationError::new(
                "agent_ids",
                format!("names {n} agents, 1 to {} are accepted", plausible::MAX_AGENTS),
            ));
        }
        if self.trace.is_empty() {
            return Err(ValidationError::new("trace", "is empty"));
        }
        let mut last = f64::NEG_INFINITY;
        for (k, sample) in self.trace.iter().enumerate() {
            if !(sample.t_s.is_finite() && sample.t_s > last) {
                return Err(ValidationError::new(
                    format!("trace[{k}].t_s"),
                    format!("{}: times must be finite and increasing", shown(sample.t_s)),
                ));
            }
            last = sample.t_s;
            if sample.agents.len() != n {
                return Err(ValidationError::new(
                    format!("trace[{k}].agents"),
                    format!("holds {} agents, agent_ids names {n}", sample.agents.len()),
                ));
            }
        }
        for i in 0..n {
            let states = self.trace.iter().filter_map(move |s| s.agents.get(i).map(|a| (s.t_s, a.state)));
            plausible::track(|k| format!("trace[{k}].agents[{i}].state"), states)?;
        }
        Ok(())
    }
}

/// One decision of the BV's regulator, as the onboard runtime published it (`/plans`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanRecord {
    /// Simulated time it was seen, s.
    pub t_s: f64,
    /// The prior it regulates around.
    pub prior_id: u64,
    /// The regulator's status (`Regulating`, `Degraded`, `SafetyYield`, …).
    pub status: String,
    /// Where the plan starts along the BV's path, m.
    pub s_m: f64,
    /// The BV's speed it starts from, m/s.
    pub v_mps: f64,
    /// The acceleration it commands now, m/s².
    pub accel_mps2: f64,
    /// The PET it predicts, s.
    pub predicted_pet_s: Option<f64>,
    /// Why it reports τ out of the VUT's reach (`VutWaits`, `Campaign`, `OrderRefused`); `None`:
    /// nothing says so.
    #[serde(default)]
    pub below_reach: Option<String>,
    /// With `below_reach`: the PET the VUT allows as far as known, s.
    #[serde(default)]
    pub pet_bound_s: Option<f64>,
    /// How the VUT is identified to react to the BV so far this run: the probability that it
    /// reacts at all (`None`: the regulator's follower does not react).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vut_reacts_p: Option<f64>,
    /// With `vut_reacts_p`: the gap the VUT is identified to accept (expected over the reacting
    /// hypotheses), s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vut_gap_s: Option<f64>,
    /// With `vut_reacts_p`: its standard deviation, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vut_gap_sd_s: Option<f64>,
    /// How long the decision took, µs.
    pub solve_us: f64,
}

/// What the simulated drive-by-wire ECU saw of the commands.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct EcuStats {
    /// Command frames accepted.
    pub frames_ok: u64,
    /// Frames rejected (checksum, counter, range, unknown id).
    pub frames_rejected: u64,
    /// Plant steps during which the ECU's own command timeout braked.
    pub timeout_steps: u64,
    /// Plant steps that started late by more than one step (real-time overruns).
    pub late_steps: u64,
}

/// A change of the actuation gate's state seen on the CAN bus.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GateRecord {
    /// Simulated time, s.
    pub t_s: f64,
    /// The state (`Disengaged`, `Engaged`, `MinimalRiskStop`, `Fault`, or `code N` for a code
    /// this build does not know).
    pub state: String,
}

/// Reads a number that JSON writers put down as `null` when it is not finite, as +∞: the smallest
/// distance of a run with fewer than two vehicles.
pub(crate) fn infinite_if_null<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

    use super::*;
    use crate::bv::{BvController, ReferenceFollower};
    use crate::runner::run;
    use crate::scenario::Scenario;
    use crate::vut::VutModel;
    use v2t_files::parse_toml;
    use v2t_model::kinematics::State;

    fn outcome() -> RunOutcome {
        let card = parse_toml(include_str!("../../../config/scenarios/left_turn_basic.toml"), "card").unwrap();
        let settings = parse_toml(include_str!("../../../config/sim/default.toml"), "sim").unwrap();
        let vut = parse_toml(include_str!("../../../config/vehicles/vut_sedan.toml"), "vut").unwrap();
        let bv = parse_toml(include_str!("../../../config/vehicles/bv_sedan.toml"), "bv").unwrap();
        let scenario = Scenario::from_card(&card, settings, vut, vec![bv]).unwrap();
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
        run(&scenario, &mut bvs, VutModel::IdmNormal.driver().as_mut(), 1).unwrap()
    }

    /// Every shipped card against every builtin VUT model gives a run that is motion; a trace that
    /// is not (reversing, standing while its speed says it drives, driving against its heading,
    /// time running back, a vehicle missing) is refused naming the sample.
    #[test]
    fn a_run_is_motion_and_a_broken_trace_is_named() {
        let settings: crate::config::SimSettings =
            parse_toml(include_str!("../../../config/sim/default.toml"), "sim").unwrap();
        let vut: v2t_model::vehicle::VehicleConfig =
            parse_toml(include_str!("../../../config/vehicles/vut_sedan.toml"), "vut").unwrap();
        let bv: v2t_model::vehicle::VehicleConfig =
            parse_toml(include_str!("../../../config/vehicles/bv_sedan.toml"), "bv").unwrap();
        let cards = [
            include_str!("../../../config/scenarios/cut_in_basic.toml"),
            include_str!("../../../config/scenarios/left_turn_basic.toml"),
            include_str!("../../../config/scenarios/left_turn_vut.toml"),
        ];
        for card in cards {
            let card = parse_toml(card, "card").unwrap();
            let scenario = Scenario::from_card(&card, settings.clone(), vut.clone(), vec![bv.clone()]).unwrap();
            for model in VutModel::ALL {
                let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
                let run = run(&scenario, &mut bvs, model.driver().as_mut(), 3).unwrap();
                RunFile::of(&run).validate().unwrap_or_else(|e| panic!("{} against {model:?}: {e}", scenario.name));
            }
        }
        let good = RunFile::of(&outcome());
        let broken = |edit: &dyn Fn(&mut RunFile)| {
            let mut f = good.clone();
            edit(&mut f);
            f.validate().unwrap_err()
        };
        let e = broken(&|f| f.trace[40].agents[1].state.speed_mps = -2.0);
        assert_eq!(e.field, "trace[40].agents[1].state.speed_mps");
        let e = broken(&|f| {
            let still = f.trace[10].agents[0].state;
            f.trace.iter_mut().for_each(|s| s.agents[0].state = State { speed_mps: 12.5, ..still });
        });
        assert!(e.field == "trace[10].agents[0].state" && e.problem.contains("say 12.50 to 12.50 m"), "{e}");
        let e = broken(&|f| f.trace.iter_mut().for_each(|s| s.agents[1].state.theta_rad += std::f64::consts::PI));
        assert!(e.field.starts_with("trace[") && e.problem.contains("away from its heading"), "{e}");
        let e = broken(&|f| f.trace[5].t_s = f.trace[4].t_s);
        assert_eq!(e.field, "trace[5].t_s");
        let e = broken(&|f| f.trace[7].agents.truncate(1));
        assert_eq!(e.field, "trace[7].agents");
        let e = broken(&|f| f.trace[3].agents[0].state.px = f64::NAN);
        assert_eq!(e.field, "trace[3].agents[0].state");
    }

    /// What a writer writes, a reader reads back as it was; a file without the parts only some
    /// runs have still reads, and one without a part every run has is refused naming the field.
    #[test]
    fn a_run_file_reads_back_what_was_written() {
        let mut file = RunFile::of(&outcome());
        file.gate = Some(vec![GateRecord { t_s: 0.5, state: "Engaged".into() }]);
        file.ecu = Some(EcuStats { frames_ok: 3, ..EcuStats::default() });
        let text = serde_json::to_string_pretty(&file).unwrap();
        assert_eq!(serde_json::from_str::<RunFile>(&text).unwrap(), file);
        // Older and smaller files: no layout, no realism, nothing of the onboard runtime.
        let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
        for part in ["layout", "realism", "ecu", "gate"] {
            doc.as_object_mut().unwrap().remove(part);
        }
        let read: RunFile = serde_json::from_value(doc.clone()).unwrap();
        assert!(read.layout.is_none() && read.realism.is_none() && read.gate.is_none() && read.ecu.is_none());
        assert_eq!(read.trace, file.trace);
        // A writer's addition this reader does not know is ignored.
        doc["future"] = serde_json::json!(1);
        assert!(serde_json::from_value::<RunFile>(doc.clone()).is_ok());
        doc["result"].as_object_mut().unwrap().remove("vut_model");
        let e = serde_json::from_value::<RunFile>(doc).unwrap_err().to_string();
        assert!(e.contains("missing field `vut_model`"), "{e}");
    }

    /// A smallest distance that is not a number (fewer than two vehicles) is written as `null`
    /// and read back as infinite.
    #[test]
    fn an_infinite_distance_survives_the_file() {
        let mut file = RunFile::of(&outcome());
        file.result.min_distance_m = f64::INFINITY;
        let text = serde_json::to_string(&file).unwrap();
        assert!(text.contains("\"min_distance_m\":null"));
        assert_eq!(serde_json::from_str::<RunFile>(&text).unwrap().result.min_distance_m, f64::INFINITY);
    }

    /// A run's result and its measurement setup keep the target as the two keys `style` and
    /// `tau_s` where they always were: a file reads and writes back byte for byte, and a τ out of
    /// range is refused naming `tau_s`.
    #[test]
    fn the_target_is_written_as_style_and_tau_s_and_checked_as_it_is_read() {
        let result = concat!(
            r#"{"scenario":"left_turn_basic","vut_model":"idm-normal","bv_controller":"reference","seed":1,"#,
            r#""style":"rush","tau_s":2.0,"duration_s":12.5,"completed":true,"conflicts":[],"pet_min_s":null,"#,
            r#""min_distance_m":null,"min_distance_t_s":0.0,"min_ttc_s":null,"collision":null,"zone_overlap":false}"#
        );
        let r: RunResult = serde_json::from_str(result).unwrap();
        assert_eq!(
            (r.target.tau_s(), r.target.style(), r.min_distance_m),
            (2.0, v2t_model::Style::Rush, f64::INFINITY)
        );
        assert_eq!(serde_json::to_string(&r).unwrap(), result);
        let newer = result.replace(r#""seed":1,"#, r#""seed":1,"future":[1],"#);
        assert_eq!(serde_json::from_str::<RunResult>(&newer).unwrap(), r);
        let setup = concat!(
            r#"{"scenario":"s","vut_model":"m","bv_controller":"c","seed":7,"style":"yield","tau_s":3.5,"#,
            r#""conflicts":[],"ttc_every":10}"#
        );
        let m: crate::measure::MeasureSetup = serde_json::from_str(setup).unwrap();
        assert_eq!(m.target, v2t_model::Target::new(3.5, v2t_model::Style::Yield).unwrap());
        assert_eq!(serde_json::to_string(&m).unwrap(), setup);
        for bad in ["0.0", "30.5", "-1.0"] {
            let tau = format!(r#""tau_s":{bad}"#);
            let e = serde_json::from_str::<RunResult>(&result.replace(r#""tau_s":2.0"#, &tau)).unwrap_err().to_string();
            assert!(e.contains("`tau_s`") && e.contains("[0.1, 30]"), "{e}");
            let e = serde_json::from_str::<crate::measure::MeasureSetup>(&setup.replace(r#""tau_s":3.5"#, &tau));
            let e = e.unwrap_err().to_string();
            assert!(e.contains("`tau_s`") && e.contains("[0.1, 30]"), "{e}");
        }
        // A whole run file written by the runner reads back and writes the same text.
        let text = serde_json::to_string_pretty(&RunFile::of(&outcome())).unwrap();
        assert!(
            text.contains("\"seed\": 1,\n    \"style\": \"rush\",\n    \"tau_s\": 2.0,\n    \"duration_s\""),
            "{text}"
        );
        assert_eq!(serde_json::to_string_pretty(&serde_json::from_str::<RunFile>(&text).unwrap()).unwrap(), text);
    }
}
