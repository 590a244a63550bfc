//! MCAP recordings of runs (feature `mcap`), and replaying them: `video2track sim … --mcap run.mcap`
//! and `v2t-sim-ecu … --mcap run.mcap` write every
//! channel a test engineer looks at in Foxglove, and `video2track replay run.mcap` measures the run
//! again from the recorded truth with the same code the run was measured with.
//!
//! Channels (JSON messages, `jsonschema` schemas, log time = simulated time):
//! - `/truth` (`v2t.Truth`, plant rate): every vehicle's true state, arc length along its route and
//!   delivered acceleration — what every metric is computed from;
//! - `/scene` (`foxglove.SceneUpdate`, 10 Hz): each vehicle as a cube with its footprint, for the 3D panel;
//! - `/commands` (`v2t.Commands`, 10 Hz): every vehicle's last actuation request (acceleration, steering);
//! - `/pet` (`v2t.PredictedPet`, 10 Hz): the constant-velocity predicted PET of every conflict;
//! - `/plans` (`v2t.Plan`, 10 Hz, runs through the onboard runtime): every regulator decision.
//!
//! Metadata `video2track.run` holds the measurement setup (conflict zones, style, τ, seed, models)
//! and the result the run reported.

mod layout;

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::measure::{AgentTruth, MeasureSetup, TruthLog, measure};
use crate::runner::RunOutcome;
use serde::{Deserialize, Serialize};
use serde_json::json;
use v2t_model::kinematics::State;

/// A regulator decision as recorded: the one type of the run file and the recording.
pub use crate::runfile::PlanRecord;

/// Name of the metadata record with the setup and the reported result.
pub const RUN_METADATA: &str = "video2track.run";

/// A recording that cannot be written or read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// File system.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The MCAP container.
    #[error("{path}: MCAP: {message}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// A record that is not what a video2track recording holds.
    #[error("{path}: {message}")]
    Content {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
}

/// One `/truth` message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct TruthMessage {
    t_s: f64,
    agents: Vec<TruthSample>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct TruthSample {
    id: String,
    state: State,
    s_m: f64,
    accel_mps2: f64,
}

/// Static facts of each vehicle, in the metadata.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct AgentInfo {
    id: String,
    dims: v2t_model::metrics::Dimensions,
    route_length_m: f64,
}

const TRUTH_SCHEMA: &str = r#"{"type":"object","title":"v2t.Truth","properties":{"t_s":{"type":"number"},"agents":{"type":"array","items":{"type":"object","properties":{"id":{"type":"string"},"state":{"type":"object","properties":{"px":{"type":"number"},"py":{"type":"number"},"theta_rad":{"type":"number"},"speed_mps":{"type":"number"}}},"s_m":{"type":"number"},"accel_mps2":{"type":"number"}}}}}}"#;
const COMMANDS_SCHEMA: &str = r#"{"type":"object","title":"v2t.Commands","properties":{"t_s":{"type":"number"},"agents":{"type":"array","items":{"type":"object","properties":{"id":{"type":"string"},"accel_mps2":{"type":"number"},"steer_rad":{"type":"number"},"delivered_accel_mps2":{"type":"number"},"delivered_steer_rad":{"type":"number"}}}}}}"#;
const PET_SCHEMA: &str = r#"{"type":"object","title":"v2t.PredictedPet","properties":{"t_s":{"type":"number"},"tau_s":{"type":"number"},"conflicts":{"type":"array","items":{"type":"object","properties":{"bv_id":{"type":"string"},"predicted_pet_s":{"type":["number","null"]}}}}}}"#;
/// The subset of Foxglove's `SceneUpdate` the recording uses (cubes in the `map` frame).
const SCENE_SCHEMA: &str = r#"{"type":"object","title":"foxglove.SceneUpdate","properties":{"deletions":{"type":"array","items":{"type":"object"}},"entities":{"type":"array","items":{"type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_id":{"type":"string"},"id":{"type":"string"},"lifetime":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_locked":{"type":"boolean"},"metadata":{"type":"array","items":{"type":"object"}},"cubes":{"type":"array","items":{"type":"object","properties":{"pose":{"type":"object"},"size":{"type":"object"},"color":{"type":"object"}}}}}}}}}"#;

fn ns(t_s: f64) -> u64 {
    (t_s * 1e9).round().max(0.0) as u64
}

fn stamp(t_s: f64) -> serde_json::Value {
    let n = ns(t_s);
    json!({"sec": n / 1_000_000_000, "nsec": n % 1_000_000_000})
}

const PLAN_SCHEMA: &str = r#"{"type":"object","title":"v2t.Plan","properties":{"t_s":{"type":"number"},"prior_id":{"type":"integer"},"status":{"type":"string"},"s_m":{"type":"number"},"v_mps":{"type":"number"},"accel_mps2":{"type":"number"},"predicted_pet_s":{"type":["number","null"]},"below_reach":{"type":["string","null"]},"pet_bound_s":{"type":["number","null"]},"vut_reacts_p":{"type":["number","null"]},"vut_gap_s":{"type":["number","null"]},"vut_gap_sd_s":{"type":["number","null"]},"solve_us":{"type":"number"}}}"#;

/// Writes `run` as an MCAP file at `path`.
pub fn write(run: &RunOutcome, path: &Path) -> Result<(), RecordingError> {
    write_with_plans(run, &[], path)
}

/// [`write()`] with the regulator's decisions on `/plans` (`v2t.Plan`), in time order with the rest.
pub fn write_with_plans(run: &RunOutcome, plans: &[PlanRecord], path: &Path) -> Result<(), RecordingError> {
    let io = |source| RecordingError::Io { path: path.to_owned(), source };
    let mc = |e: mcap::McapError| RecordingError::Mcap { path: path.to_owned(), message: e.to_string() };
    let file = std::fs::File::create(path).map_err(io)?;
    let opts = mcap::WriteOptions::new().compression(None).profile("video2track").library("video2track");
    let mut w = opts.create(BufWriter::new(file)).map_err(mc)?;
    let none = BTreeMap::new();
    let mut channel = |name: &str, schema: &str, topic: &str| -> Result<u16, RecordingError> {
        let id = w.add_schema(name, "jsonschema", schema.as_bytes()).map_err(mc)?;
        w.add_channel(id, topic, "json", &none).map_err(mc)
    };
    let truth_ch = channel("v2t.Truth", TRUTH_SCHEMA, "/truth")?;
    let scene_ch = channel("foxglove.SceneUpdate", SCENE_SCHEMA, "/scene")?;
    let cmd_ch = channel("v2t.Commands", COMMANDS_SCHEMA, "/commands")?;
    let pet_ch = channel("v2t.PredictedPet", PET_SCHEMA, "/pet")?;
    let plan_ch = if plans.is_empty() { None } else { Some(channel("v2t.Plan", PLAN_SCHEMA, "/plans")?) };
    let mut seq = 0u32;
    let mut put = |w: &mut mcap::Writer<BufWriter<std::fs::File>>, ch: u16, t_s: f64, v: &serde_json::Value| {
        seq = seq.wrapping_add(1);
        let header =
            mcap::records::MessageHeader { channel_id: ch, sequence: seq, log_time: ns(t_s), publish_time: ns(t_s) };
        w.write_to_known_channel(&header, v.to_string().as_bytes()).map_err(mc)
    };
    let log = &run.truth;
    let dims: BTreeMap<&str, v2t_model::metrics::Dimensions> =
        log.agents.iter().map(|a| (a.id.as_str(), a.dims)).collect();
    let bv_ids: Vec<String> = run.result.conflicts.iter().map(|c| c.bv_id.clone()).collect();
    // In time order: each 10 Hz sample's messages before the plant step at the same instant.
    let mut samples = run.trace.iter().peekable();
    let mut decisions = plans.iter().peekable();
    let plan_json = |p: &PlanRecord| serde_json::to_value(p).unwrap_or_default();
    for (k, t) in log.times.iter().enumerate() {
        if let Some(ch) = plan_ch {
            while let Some(p) = decisions.next_if(|p| p.t_s <= *t) {
                put(&mut w, ch, p.t_s, &plan_json(p))?;
            }
        }
        while let Some(sample) = samples.next_if(|s| s.t_s <= *t) {
            for (ch, msg) in sample_messages(sample, &run.agent_ids, &dims, &bv_ids, run.result.target.tau_s())
                .into_iter()
                .zip([scene_ch, cmd_ch, pet_ch])
                .map(|(m, ch)| (ch, m))
            {
                put(&mut w, ch, sample.t_s, &msg)?;
            }
        }
        let agents: Vec<TruthSample> = log
            .agents
            .iter()
            .filter_map(|a| {
                Some(TruthSample {
                    id: a.id.clone(),
                    state: *a.states.get(k)?,
                    s_m: *a.s_m.get(k)?,
                    accel_mps2: *a.accel_mps2.get(k)?,
                })
            })
            .collect();
        let msg = serde_json::to_value(TruthMessage { t_s: *t, agents })
            .map_err(|e| RecordingError::Content { path: path.to_owned(), message: e.to_string() })?;
        put(&mut w, truth_ch, *t, &msg)?;
    }
    if let Some(ch) = plan_ch {
        for p in decisions {
            put(&mut w, ch, p.t_s, &plan_json(p))?;
        }
    }
    let agents: Vec<AgentInfo> = log
        .agents
        .iter()
        .map(|a| AgentInfo { id: a.id.clone(), dims: a.dims, route_length_m: a.route_length_m })
        .collect();
    let text = |v: serde_json::Result<String>| {
        v.map_err(|e| RecordingError::Content { path: path.to_owned(), message: e.to_string() })
    };
    let mut meta = BTreeMap::new();
    meta.insert("setup".to_owned(), text(serde_json::to_string(&run.setup))?);
    meta.insert("agents".to_owned(), text(serde_json::to_string(&agents))?);
    meta.insert("result".to_owned(), text(serde_json::to_string(&run.result))?);
    w.write_metadata(&mcap::records::Metadata { name: RUN_METADATA.to_owned(), metadata: meta }).map_err(mc)?;
    w.finish().map_err(mc)?;
    Ok(())
}

/// What `replay` found.
#[derive(Debug, Clone, PartialEq)]
pub struct Replay {
    /// The result the run reported when it was recorded (JSON).
    pub recorded: serde_json::Value,
    /// The result measured again from the recorded truth (JSON).
    pub recomputed: serde_json::Value,
    /// Messages per channel.
    pub channels: BTreeMap<String, usize>,
    /// Plant steps in the truth.
    pub steps: usize,
}

impl Replay {
    /// Whether the recomputed metrics equal the recorded ones exactly.
    pub fn matches(&self) -> bool {
        self.recorded == self.recomputed
    }
}

/// The `/scene`, `/commands` and `/pet` messages of one 10 Hz sample.
fn sample_messages(
    sample: &crate::runner::TraceSample,
    ids: &[String],
    dims: &BTreeMap<&str, v2t_model::metrics::Dimensions>,
    bv_ids: &[String],
    tau_s: f64,
) -> [serde_json::Value; 3] {
    let t = sample.t_s;
    let mut entities = Vec::new();
    let mut commands = Vec::new();
    for (id, a) in ids.iter().zip(&sample.agents) {
        let d =
            dims.get(id.as_str()).copied().unwrap_or(v2t_model::metrics::Dimensions { length_m: 4.8, width_m: 1.85 });
        let (half, st) = (a.state.theta_rad / 2.0, &a.state);
        let color = if id == "vut" {
            json!({"r": 0.1, "g": 0.45, "b": 0.9, "a": 1.0})
        } else {
            json!({"r": 0.9, "g": 0.3, "b": 0.1, "a": 1.0})
        };
        entities.push(json!({
            "timestamp": stamp(t), "frame_id": "map", "id": id, "lifetime": {"sec": 0, "nsec": 0},
            "frame_locked": false, "metadata": [{"key": "speed_mps", "value": format!("{:.2}", st.speed_mps)}],
            "cubes": [{
                "pose": {"position": {"x": st.px, "y": st.py, "z": 0.75},
                         "orientation": {"x": 0.0, "y": 0.0, "z": half.sin(), "w": half.cos()}},
                "size": {"x": d.length_m, "y": d.width_m, "z": 1.5},
                "color": color
            }]
        }));
        commands.push(json!({
            "id": id, "accel_mps2": a.request.accel_mps2, "steer_rad": a.request.steer_rad,
            "delivered_accel_mps2": a.accel_mps2, "delivered_steer_rad": a.steer_rad
        }));
    }
    let conflicts: Vec<_> = bv_ids
        .iter()
        .zip(sample.predicted_pet_s.iter().chain(std::iter::repeat(&None)))
        .map(|(bv, p)| json!({"bv_id": bv, "predicted_pet_s": p}))
        .collect();
    [
        json!({"deletions": [], "entities": entities}),
        json!({"t_s": t, "agents": commands}),
        json!({"t_s": t, "tau_s": tau_s, "conflicts": conflicts}),
    ]
}

/// Reads a recording and measures it again.
pub fn replay(path: &Path) -> Result<Replay, RecordingError> {
    let bytes = v2t_files::bounds::read_bytes_within(path, v2t_files::bounds::RECORDING)
        .map_err(|source| RecordingError::Io { path: path.to_owned(), source })?;
    // The layout first: the reader allocates what a length prefix claims.
    layout::check(&bytes).map_err(|message| RecordingError::Mcap { path: path.to_owned(), message })?;
    let mc = |e: mcap::McapError| RecordingError::Mcap { path: path.to_owned(), message: e.to_string() };
    let bad = |message: String| RecordingError::Content { path: path.to_owned(), message };
    let mut meta = None;
    let mut chunk = 0;
    for record in mcap::read::LinearReader::new(&bytes).map_err(mc)? {
        match record.map_err(mc)? {
            mcap::records::Record::Metadata(m) if m.name == RUN_METADATA => meta = Some(m.metadata),
            // Every chunk's CRC (0: none written), before a single message is read from it.
            mcap::records::Record::Chunk { header, data } => {
                chunk += 1;
                if header.compression.is_empty() && header.uncompressed_crc != 0 {
                    let computed = crc32fast::hash(&data);
                    if computed != header.uncompressed_crc {
                        return Err(RecordingError::Mcap {
                            path: path.to_owned(),
                            message: format!(
                                "chunk {chunk} (messages {:.2}–{:.2} s) is corrupt: CRC 0x{:08x} written, 0x{computed:08x} read",
                                header.message_start_time as f64 / 1e9,
                                header.message_end_time as f64 / 1e9,
                                header.uncompressed_crc
                            ),
                        });
                    }
                }
            }
            _ => {}
        }
    }
    let meta = meta.ok_or_else(|| bad(format!("no `{RUN_METADATA}` metadata: not a video2track recording")))?;
    let field = |k: &str| meta.get(k).ok_or_else(|| bad(format!("metadata `{RUN_METADATA}` has no `{k}`")));
    let setup: MeasureSetup = serde_json::from_str(field("setup")?).map_err(|e| bad(format!("setup: {e}")))?;
    let infos: Vec<AgentInfo> = serde_json::from_str(field("agents")?).map_err(|e| bad(format!("agents: {e}")))?;
    let recorded: serde_json::Value =
        serde_json::from_str(field("result")?).map_err(|e| bad(format!("result: {e}")))?;
    let mut log = TruthLog {
        times: Vec::new(),
        agents: infos
            .iter()
            .map(|i| AgentTruth {
                id: i.id.clone(),
                dims: i.dims,
                route_length_m: i.route_length_m,
                states: Vec::new(),
                s_m: Vec::new(),
                accel_mps2: Vec::new(),
            })
            .collect(),
    };
    let mut channels = BTreeMap::new();
    for message in mcap::MessageStream::new(&bytes).map_err(mc)? {
        let message = message.map_err(mc)?;
        *channels.entry(message.channel.topic.clone()).or_insert(0) += 1;
        if message.channel.topic != "/truth" {
            continue;
        }
        let m: TruthMessage =
            serde_json::from_slice(&message.data).map_err(|e| bad(format!("/truth #{}: {e}", message.sequence)))?;
        if m.agents.len() != log.agents.len() {
            return Err(bad(format!(
                "/truth at {} s: {} vehicles, the run had {}",
                m.t_s,
                m.agents.len(),
                log.agents.len()
            )));
        }
        log.times.push(m.t_s);
        for (a, s) in log.agents.iter_mut().zip(m.agents) {
            if a.id != s.id {
                return Err(bad(format!("/truth at {} s: vehicle `{}` where `{}` was expected", m.t_s, s.id, a.id)));
            }
            a.states.push(s.state);
            a.s_m.push(s.s_m);
            a.accel_mps2.push(s.accel_mps2);
        }
    }
    if log.times.is_empty() {
        return Err(bad("no /truth messages".into()));
    }
    // The recorded truth must be motion, as a run file's trace must (`RunFile::validate`).
    for a in &log.agents {
        let samples = log.times.iter().copied().zip(a.states.iter().copied());
        v2t_model::validate::plausible::track(|k| format!("/truth #{k} (vehicle `{}`)", a.id), samples)
            .map_err(|e| bad(e.to_string()))?;
    }
    let recomputed = serde_json::to_value(measure(&setup, &log)).map_err(|e| bad(e.to_string()))?;
    Ok(Replay { recorded, recomputed, channels, steps: log.times.len() })
}

/// What `replay` prints: the channels, then every metric recorded and recomputed.
pub fn report(path: &Path, r: &Replay) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "recording {}: {} plant steps", path.display(), r.steps);
    for (topic, n) in &r.channels {
        let _ = writeln!(s, "  {topic}: {n} messages");
    }
    let keys = [
        "pet_min_s",
        "min_distance_m",
        "min_distance_t_s",
        "min_ttc_s",
        "collision",
        "zone_overlap",
        "completed",
        "duration_s",
    ];
    let _ = writeln!(s, "{:<18} {:>22} {:>22}", "metric", "recorded", "recomputed");
    for k in keys {
        let show = |v: &serde_json::Value| v.get(k).map_or_else(|| "-".to_owned(), |x| x.to_string());
        let _ = writeln!(s, "{k:<18} {:>22} {:>22}", show(&r.recorded), show(&r.recomputed));
    }
    let conflicts = |v: &serde_json::Value| v.get("conflicts").cloned().unwrap_or_default();
    let same = conflicts(&r.recorded) == conflicts(&r.recomputed);
    let _ = writeln!(s, "conflicts (PET, passages, order): {}", if same { "identical" } else { "DIFFERENT" });
    let _ = writeln!(s, "{}", if r.matches() { "replay: every metric identical" } else { "replay: DIFFERENT" });
    s
}
