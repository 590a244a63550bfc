//! The input kinds: every parser and decoder a user (files) or a network peer (frames, a VLM's
//! reply) can feed, with their seeds (the shipped files, or what the pipeline writes from them)
//! and what is run on a mutant: the reader and the consumers that loop over what it read.
//!
//! A kind's check returns `Ok` for an input it accepted and `Err` with the message for one it
//! refused: both are correct answers. Only a panic, an abort or a hang is a finding.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use ed25519_dalek::SigningKey;
use v2t_map::Map;
use v2t_model::prior::TrajectoryPrior;
use v2t_wire::link::{self, Arrival, CloudBody, CloudMessage, Receiver, Window};

use crate::mutate::Form;

/// One input kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Kind {
    /// Its name (`--kinds`, regression folder).
    pub name: &'static str,
    /// What it is, for the report.
    pub what: &'static str,
    /// Text or binary mutations.
    pub form: Form,
    /// File extension of a mutant on disk.
    pub ext: &'static str,
}

/// Every kind, in the order the harness runs them.
pub const KINDS: &[Kind] = &[
    Kind { name: "opendrive", what: "OpenDRIVE map, lane graph, topology library", form: Form::Text, ext: "xodr" },
    Kind { name: "annotations", what: "map annotations (TOML) on the topology library", form: Form::Text, ext: "toml" },
    Kind { name: "semantics", what: "scenario semantics (JSON)", form: Form::Text, ext: "json" },
    Kind {
        name: "vlm-reply",
        what: "a VLM's chat-completion reply and the semantics in it",
        form: Form::Text,
        ext: "json",
    },
    Kind { name: "card", what: "scenario card (TOML) with its paths sampled", form: Form::Text, ext: "toml" },
    Kind {
        name: "settings",
        what: "vehicle, regulator, tracker, gate, simulation, network settings (TOML)",
        form: Form::Text,
        ext: "toml",
    },
    Kind { name: "sumo-driver", what: "SUMO driver file (TOML)", form: Form::Text, ext: "toml" },
    Kind {
        name: "edge-config",
        what: "onboard runtime configuration (TOML) with every file it names",
        form: Form::Text,
        ext: "toml",
    },
    Kind { name: "human-reference", what: "human reference of motion (JSON)", form: Form::Text, ext: "json" },
    Kind {
        name: "grounded",
        what: "grounded scenario (JSON): on the map, stand-in prior, OpenSCENARIO",
        form: Form::Text,
        ext: "json",
    },
    Kind {
        name: "prior",
        what: "trajectory prior (JSON): OpenSCENARIO, the edge's upload check",
        form: Form::Text,
        ext: "json",
    },
    Kind { name: "run", what: "run file (JSON): report, video scene, OpenSCENARIO", form: Form::Text, ext: "json" },
    Kind {
        name: "campaign",
        what: "campaign memory (JSON): a test's learned aim and reach",
        form: Form::Text,
        ext: "json",
    },
    Kind { name: "mcap", what: "MCAP recording, replayed to its metrics", form: Form::Binary, ext: "mcap" },
    Kind { name: "can-frame", what: "CAN frames through the DBC decoder", form: Form::Binary, ext: "can" },
    Kind {
        name: "link-cloud",
        what: "signed cloud-to-BV frames (priors, commands, plans)",
        form: Form::Binary,
        ext: "frame",
    },
    Kind { name: "link-report", what: "BV-to-cloud frames (telemetry, heartbeats)", form: Form::Binary, ext: "frame" },
];

/// Kinds that test the harness itself, never run unless named: every mutant panics, hangs or
/// aborts the process (a harness that reported nothing here would be blind).
pub const SELF_TESTS: &[Kind] = &[
    Kind { name: "selftest-panic", what: "harness self-test: every mutant panics", form: Form::Text, ext: "txt" },
    Kind { name: "selftest-hang", what: "harness self-test: every mutant hangs", form: Form::Text, ext: "txt" },
    Kind { name: "selftest-abort", what: "harness self-test: every mutant aborts", form: Form::Text, ext: "txt" },
];

/// The seed of the self-test kinds.
const SELF_TEST_SEED: &[u8] = b"a = 1\nb = 2\n";

/// The kind named `name`.
pub fn kind(name: &str) -> Option<&'static Kind> {
    KINDS.iter().chain(SELF_TESTS).find(|k| k.name == name)
}

/// What a self-test kind does with a mutant (its seed passes).
#[allow(clippy::panic)] // the panic is what the self-test is for
fn self_test(name: &str, bytes: &[u8]) -> Result<(), String> {
    if bytes == SELF_TEST_SEED {
        return Ok(());
    }
    match name {
        "selftest-panic" => panic!("self-test panic on a mutant of {} bytes", bytes.len()),
        "selftest-hang" => loop {
            std::thread::sleep(std::time::Duration::from_millis(50));
        },
        _ => std::process::abort(),
    }
}

/// What every check shares: the repository, a scratch folder laid out like `config/`, the map,
/// the demo key pair.
#[derive(Debug)]
pub struct Context {
    /// The repository root.
    pub repo: PathBuf,
    /// Scratch folder: `work/config/` mirrors the repository's `config/` (links), with its own
    /// `scenarios/`, `edge/` and `sumo/` folders for mutants that name files relative to themselves.
    pub work: PathBuf,
    /// The proving ground.
    pub map: Map,
    key: SigningKey,
    vehicle: v2t_model::vehicle::VehicleConfig,
    checks: v2t_edge::prior::PriorChecks,
}

/// A seed: a name and the bytes.
pub type Seed = (String, Vec<u8>);

impl Context {
    /// Reads what the checks share and lays out `work`.
    pub fn new(repo: &Path, work: &Path) -> anyhow::Result<Self> {
        let config = work.join("config");
        std::fs::create_dir_all(&config).with_context(|| format!("cannot create {}", config.display()))?;
        for entry in std::fs::read_dir(repo.join("config"))? {
            let entry = entry?;
            let name = entry.file_name();
            let link = config.join(&name);
            if ["scenarios", "edge"].iter().any(|own| name == *own) {
                std::fs::create_dir_all(&link)?;
            } else if !link.exists() {
                std::os::unix::fs::symlink(entry.path().canonicalize()?, &link)
                    .with_context(|| format!("cannot link {}", link.display()))?;
            }
        }
        let map = Map::load(&repo.join(v2t_files::shipped::MAP))?;
        let secret = std::fs::read_to_string(repo.join("config/keys/demo_cloud.key"))?;
        let seed = link::key_from_hex(&secret).map_err(anyhow::Error::msg)?;
        let vehicle: v2t_model::vehicle::VehicleConfig =
            v2t_files::load_toml(&repo.join(v2t_files::shipped::BV_VEHICLE))?;
        let vut: v2t_model::vehicle::VehicleConfig = v2t_files::load_toml(&repo.join(v2t_files::shipped::VUT_VEHICLE))?;
        let area = v2t_map::drivable::DrivableArea::from_map(&map);
        let checks = v2t_edge::prior::PriorChecks::for_vehicles(&vehicle, &vut, Some(area), 2.0);
        Ok(Self {
            repo: repo.to_owned(),
            work: work.to_owned(),
            map,
            key: SigningKey::from_bytes(&seed),
            vehicle,
            checks,
        })
    }

    /// Where a mutant of `kind` is written before it is read.
    pub fn mutant_path(&self, kind: &Kind) -> PathBuf {
        let dir = match kind.name {
            "card" => "config/scenarios",
            "edge-config" => "config/edge",
            _ => ".",
        };
        self.work.join(dir).join(format!("mutant-{}.{}", kind.name, kind.ext))
    }

    fn files(&self, dir: &str, ext: &str) -> anyhow::Result<Vec<Seed>> {
        let mut out = Vec::new();
        let mut paths: Vec<PathBuf> = std::fs::read_dir(self.repo.join(dir))?
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == ext))
            .collect();
        paths.sort();
        for p in paths {
            let name = p.strip_prefix(&self.repo).unwrap_or(&p).display().to_string();
            out.push((name, std::fs::read(&p)?));
        }
        Ok(out)
    }

    /// The seeds of `kind`: the shipped files, or what the pipeline makes of them.
    pub fn seeds(&self, kind: &Kind) -> anyhow::Result<Vec<Seed>> {
        Ok(match kind.name {
            "opendrive" => {
                let mut maps = self.files("config/maps", "xodr")?;
                maps.extend(self.files("tests/data/maps", "xodr")?);
                maps
            }
            "annotations" => self.files("config/maps", "toml")?,
            "semantics" => self.files("config/examples", "json")?,
            "vlm-reply" => self.vlm_replies()?,
            "card" => self.files("config/scenarios", "toml")?,
            "settings" => {
                let mut all = Vec::new();
                for dir in [
                    "config/vehicles",
                    "config/regulator",
                    "config/track",
                    "config/can",
                    "config/sim",
                    "config/network",
                ] {
                    all.extend(self.files(dir, "toml")?);
                }
                all
            }
            "sumo-driver" => self.files("config/vut/sumo", "toml")?,
            "edge-config" => self.files("config/edge", "toml")?,
            "human-reference" => self.files("config/realism", "json")?,
            "grounded" => self
                .grounded()?
                .into_iter()
                .map(|(n, g)| Ok((n, serde_json::to_vec_pretty(&g)?)))
                .collect::<anyhow::Result<_>>()?,
            "prior" => self
                .priors()?
                .into_iter()
                .map(|(n, p)| Ok((n, serde_json::to_vec_pretty(&p)?)))
                .collect::<anyhow::Result<_>>()?,
            "run" | "mcap" => self.runs(kind.name == "mcap")?,
            "campaign" => campaign_memory()?,
            "can-frame" => can_frames()?,
            "link-cloud" => self.cloud_frames()?,
            "link-report" => report_frames()?,
            name if name.starts_with("selftest-") => vec![("self-test".into(), SELF_TEST_SEED.to_vec())],
            other => anyhow::bail!("no seeds for `{other}`"),
        })
    }

    fn vlm_replies(&self) -> anyhow::Result<Vec<Seed>> {
        let mut out = Vec::new();
        for which in ["cut_in", "left_turn", "left_turn_vut"] {
            let dir = self.repo.join("config/vlm/cassettes").join(which);
            let exchange: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("exchange_01.json"))?)?;
            let body = exchange.get("response").and_then(|r| r.get("body_json")).context("no response.body_json")?;
            out.push((format!("{which}/exchange_01.json response"), serde_json::to_vec_pretty(body)?));
        }
        Ok(out)
    }

    fn grounded(&self) -> anyhow::Result<Vec<(String, v2t_model::grounded::GroundedScenario)>> {
        let mut library = v2t_map::library::TopologyLibrary::build(&self.map);
        let notes = v2t_map::annotate::Annotations::parse(
            &std::fs::read_to_string(self.repo.join("config/maps/proving_ground.toml"))?,
            "proving_ground.toml",
        )?;
        library.annotate(&notes)?;
        let mut out = Vec::new();
        for (name, text) in self.files("config/examples", "json")? {
            let semantics = v2t_model::semantics::parse_semantics_json(&String::from_utf8_lossy(&text))?;
            let g = v2t_ground::ground(&self.map, &library, &semantics)?;
            out.push((format!("{name} grounded"), g.scenario));
        }
        Ok(out)
    }

    fn priors(&self) -> anyhow::Result<Vec<(String, TrajectoryPrior)>> {
        self.grounded()?
            .into_iter()
            .map(|(n, g)| Ok((format!("{n}, stand-in prior"), TrajectoryPrior::stand_in(&g)?)))
            .collect()
    }

    fn runs(&self, mcap: bool) -> anyhow::Result<Vec<Seed>> {
        let card = self.repo.join("config/scenarios/left_turn_basic.toml");
        let scenario = v2t_sim::files::load_scenario(&card)?;
        let vut = v2t_lab::vut::Vut::Builtin(scenario.vut.default_model);
        let outcome = v2t_lab::sim::run_reference(&scenario, &vut, 1)?;
        let name = "left_turn_basic, reference BV, seed 1".to_owned();
        if mcap {
            let path = self.work.join("seed.mcap");
            v2t_sim::recording::write(&outcome, &path)?;
            Ok(vec![(name, std::fs::read(&path)?)])
        } else {
            Ok(vec![(name, serde_json::to_vec_pretty(&v2t_sim::runfile::RunFile::of(&outcome))?)])
        }
    }

    fn cloud_frames(&self) -> anyhow::Result<Vec<Seed>> {
        let (_, prior) = self.priors()?.into_iter().next().context("no prior")?;
        let bv_agent = prior.agents.iter().find(|a| a.role == v2t_model::grounded::AgentRole::Bv).map(|a| a.id.clone());
        let now = 1_700_000_000_000u64;
        let bodies = [
            CloudBody::Prior(link::PriorUpload {
                prior_id: 7,
                bv_agent: bv_agent.unwrap_or_else(|| "bv1".into()),
                valid_from_ms: now,
                valid_until_ms: now + 600_000,
                prior,
            }),
            CloudBody::Command(link::Command::Abort),
            CloudBody::Command(link::Command::SetTarget(v2t_model::Target::new(2.0, v2t_model::Style::Rush)?)),
            CloudBody::Plan(link::CloudPlan {
                state_seq: 3,
                t0_ms: now,
                s0_m: 12.0,
                v0_mps: 8.0,
                dt_s: 0.1,
                accel_mps2: vec![0.5; 50],
                status: 0,
                predicted_pet_s: Some(2.1),
            }),
            CloudBody::Campaign(campaign_seed()?),
        ];
        let mut out = Vec::new();
        for (i, body) in bodies.into_iter().enumerate() {
            let msg =
                CloudMessage { fleet: "demo".into(), bv_id: "bv1".into(), seq: 100 + i as u64, issued_ms: now, body };
            out.push((format!("cloud frame {i}"), link::seal(&msg, &self.key)?));
        }
        Ok(out)
    }

    /// Reads `bytes` (written at `path`) as `kind`, and runs what consumes it. A file kind over the
    /// size bound its reader applies ([`size_bound`]) is refused first, as the tools refuse it: the
    /// checks below that take the text never see more than a user's file could hand them.
    pub fn check(&self, kind: &Kind, path: &Path, bytes: &[u8]) -> Result<(), String> {
        if let Some(bound) = size_bound(kind)
            && bytes.len() as u64 > bound.max_bytes
        {
            return Err(format!("{} bytes, more than the {} allowed for {}", bytes.len(), bound.max_bytes, bound.what));
        }
        let text = || String::from_utf8_lossy(bytes).into_owned();
        let s = |e: &dyn std::fmt::Display| e.to_string();
        match kind.name {
            "opendrive" => {
                let map = Map::parse(&text(), "mutant").map_err(|e| s(&e))?;
                let _ = map.extent();
                let _ = v2t_map::drivable::DrivableArea::from_map(&map);
                v2t_map::inspect(path, None).map(drop).map_err(|e| s(&e))
            }
            "annotations" => {
                let notes = v2t_map::annotate::Annotations::parse(&text(), "mutant.toml").map_err(|e| s(&e))?;
                v2t_map::library::TopologyLibrary::build(&self.map).annotate(&notes).map_err(|e| s(&e))
            }
            "semantics" => v2t_model::semantics::parse_semantics_json(&text()).map(drop).map_err(|e| s(&e)),
            "vlm-reply" => {
                let reply = v2t_vlm::answer::parse_reply(&text()).map_err(|e| s(&e))?;
                let source = v2t_model::semantics::SourceMetadata {
                    video: "mutant.mp4".into(),
                    dataset: None,
                    duration_s: Some(10.0),
                    frames_used: Some(8),
                    model: None,
                    prompt_version: None,
                };
                v2t_vlm::answer::check_answer(&reply.content, 2.9, &source).map(drop).map_err(|e| s(&e))
            }
            "card" => v2t_sim::files::load_scenario(path).map(drop).map_err(|e| s(&e)),
            "settings" => settings(&text()),
            "sumo-driver" => v2t_lab::sumo::SumoDriver::load(path).map(drop).map_err(|e| s(&e)),
            "edge-config" => v2t_edge::config::load(path).map(drop).map_err(|e| s(&e)),
            "human-reference" => v2t_files::read_human_reference(path).map(drop).map_err(|e| s(&e)),
            "grounded" => {
                let g = v2t_files::read_grounded(path).map_err(|e| s(&e))?;
                self.map.check_scenario(&g).map_err(|e| s(&e))?;
                let _ = TrajectoryPrior::stand_in(&g).map_err(|e| s(&e))?;
                self.xosc(&text())
            }
            "prior" => {
                let prior = v2t_files::read_prior(path).map_err(|e| s(&e))?;
                let bv_agent = prior.agents.iter().find(|a| a.role == v2t_model::grounded::AgentRole::Bv);
                let bv_agent = bv_agent.map_or_else(|| "bv1".to_owned(), |a| a.id.clone());
                let now = 1_700_000_000_000u64;
                let up =
                    link::PriorUpload { prior_id: 1, bv_agent, valid_from_ms: now, valid_until_ms: now + 1000, prior };
                let _ = v2t_edge::prior::from_upload(&up, now, &self.checks, 0);
                self.xosc(&text())
            }
            "run" => {
                // The one typed reader of run files; whatever it reads, the report draws without a
                // panic.
                let run: v2t_sim::runfile::RunFile = serde_json::from_str(&text()).map_err(|e| s(&e))?;
                let input = v2t_lab::report::run::RunInput {
                    id: "run".into(),
                    title: "run".into(),
                    run: &run,
                    map: None,
                    ground: String::new(),
                    links: Vec::new(),
                    facts: Vec::new(),
                };
                let _ = v2t_lab::report::run::section(&input);
                let scene = v2t_export::video::Scene::from_run_json(&text(), path).map_err(|e| s(&e))?;
                let _ = scene.frame_count(10);
                let _ = scene.view(320, 180);
                self.xosc(&text())
            }
            "mcap" => v2t_sim::recording::replay(path).map(drop).map_err(|e| s(&e)),
            "campaign" => {
                let memory = v2t_lab::campaign::memory_from_json(&text())?;
                // What the next run asks of it: the aim and the reach of every case it holds.
                for target in [2.0, 4.0].map(|tau| v2t_model::Target::new(tau, v2t_model::Style::Rush)) {
                    let target = target.map_err(|e| s(&e))?;
                    let _ = memory.aim("left_turn_basic", 0, target);
                }
                Ok(())
            }
            "can-frame" => {
                // 13 bytes a frame: id (LE), DLC, 8 data bytes; the decoder keeps its counters
                // across the frames, as on the bus. Accepted: every frame decoded.
                let mut decoder = v2t_can::codec::Decoder::default();
                let mut refused = None;
                for chunk in bytes.chunks(13) {
                    let id = u32::from_le_bytes([0, 1, 2, 3].map(|i| chunk.get(i).copied().unwrap_or(0)));
                    let len = chunk.get(4).copied().unwrap_or(0);
                    let data = [0, 1, 2, 3, 4, 5, 6, 7].map(|i| chunk.get(5 + i).copied().unwrap_or(0));
                    if let Err(e) = decoder.decode(&v2t_can::codec::CanFrame { id, len, data }) {
                        refused.get_or_insert(e.to_string());
                    }
                }
                refused.map_or(Ok(()), Err)
            }
            "link-cloud" => {
                let mut receiver = Receiver::new(self.key.verifying_key(), "demo", "bv1", Window::default());
                let now = 1_700_000_000_000u64;
                for arrival in [Arrival::Prior, Arrival::Command, Arrival::Plan] {
                    if let Ok(msg) = receiver.open(bytes, arrival, now) {
                        // What a BV does next with campaign knowledge: the regulator's checks.
                        if let CloudBody::Campaign(up) = &msg.body {
                            return v2t_edge::campaign::Learned::from_upload(up).map(drop).map_err(|e| s(&e));
                        }
                        return Ok(());
                    }
                }
                Err("refused on every topic".into())
            }
            "link-report" => link::read_report(bytes).map(drop).map_err(|e| s(&e)),
            name if name.starts_with("selftest-") => self_test(name, bytes),
            other => Err(format!("unknown kind `{other}`")),
        }
    }

    /// The OpenSCENARIO export of a prior, grounded scenario or run, as `export xosc` writes it.
    fn xosc(&self, text: &str) -> Result<(), String> {
        let scenario = v2t_export::xosc::parse_input(text).map_err(|e| e.to_string())?;
        let opts = v2t_export::xosc::XoscOptions {
            source: "mutant.json",
            map_path: "proving_ground.xodr",
            date: "2026-11-26T00:00:00",
            vut_vehicle: &self.vehicle,
            bv_vehicle: &self.vehicle,
        };
        let _ = v2t_export::xosc::to_xosc(&scenario, &opts);
        Ok(())
    }
}

/// The size bound the reader of a file kind applies before parsing (`v2t_files::bounds`); `None`
/// for what is not a file: a VLM's reply (bounded by the HTTP client at 32 MiB, above the largest
/// mutant), CAN frames (fixed 13 bytes each) and link frames (the link's own 1 MiB bound, checked
/// by the reader itself).
pub fn size_bound(kind: &Kind) -> Option<v2t_files::bounds::SizeBound> {
    use v2t_files::bounds;
    Some(match kind.name {
        "opendrive" => bounds::MAP,
        "annotations" | "card" | "settings" | "sumo-driver" | "edge-config" => bounds::CONFIG,
        "semantics" => bounds::SEMANTICS,
        "human-reference" => bounds::HUMAN_REFERENCE,
        "grounded" => bounds::GROUNDED,
        "prior" => bounds::PRIOR,
        "run" => bounds::RUN,
        "campaign" => bounds::CAMPAIGN_MEMORY,
        "mcap" => bounds::RECORDING,
        _ => return None,
    })
}

/// A settings file of any of the shipped kinds: each type is tried (the mutant may have become
/// another's shape; what matters is that none panics or hangs).
fn settings(text: &str) -> Result<(), String> {
    use v2t_files::parse_toml;
    let results = [
        parse_toml::<v2t_model::vehicle::VehicleConfig>(text, "mutant.toml").map(drop),
        parse_toml::<v2t_game::regulator::RegulatorParams>(text, "mutant.toml").map(drop),
        parse_toml::<v2t_track::TrackerConfig>(text, "mutant.toml").map(drop),
        parse_toml::<v2t_can::gate::GateConfig>(text, "mutant.toml").map(drop),
        parse_toml::<v2t_sim::config::SimSettings>(text, "mutant.toml").map(drop),
        parse_toml::<v2t_sim::network::NetworkSettings>(text, "mutant.toml").map(drop),
    ];
    if results.iter().any(Result::is_ok) {
        Ok(())
    } else {
        Err(results.into_iter().filter_map(Result::err).map(|e| e.to_string()).next().unwrap_or_default())
    }
}

/// A memory of four runs of one test, as `sim --campaign` writes it.
fn campaign_memory() -> anyhow::Result<Vec<Seed>> {
    use v2t_game::campaign::{CampaignMemory, RunRecord};
    let mut memory = CampaignMemory::new("idm-normal", "builtin");
    let target = v2t_model::Target::new(2.0, v2t_model::Style::Rush)?;
    for (aim_s, pet_s) in [(2.0, 2.6), (1.6, 2.3), (1.3, 2.05), (1.25, 2.0)] {
        let run = RunRecord {
            aim_s,
            pet_s: Some(pet_s),
            order_ok: true,
            collision: false,
            learned_route: false,
            reaction_prior: false,
        };
        memory.case_mut("left_turn_basic", 0, target).record(target, run);
    }
    Ok(vec![("left_turn_basic rush τ 2 s, four runs".into(), serde_json::to_vec_pretty(&memory)?)])
}

fn can_frames() -> anyhow::Result<Vec<Seed>> {
    use v2t_can::codec::{AccelCmd, ControlState, DbwFeedback, Encoder, Message, SteerCmd};
    let mut encoder = Encoder::default();
    let mut bytes = Vec::new();
    for _ in 0..3 {
        for msg in [
            Message::Accel(AccelCmd { accel_mps2: -1.5, enable: true }),
            Message::Steer(SteerCmd { steer_rad: 0.1, ..SteerCmd::default() }),
            Message::Control(ControlState { gate_state: 1, engage_request: true, heartbeat: 3 }),
            Message::Feedback(DbwFeedback { wheel_speed_mps: 10.0, yaw_rate_radps: 0.1, steer_rad: 0.05, mode: 1 }),
        ] {
            let f = encoder.encode(&msg)?;
            bytes.extend(f.id.to_le_bytes());
            bytes.push(f.len);
            bytes.extend(f.data);
        }
    }
    Ok(vec![("12 frames of the four DBC messages".into(), bytes)])
}

fn report_frames() -> anyhow::Result<Vec<Seed>> {
    let telemetry = link::Telemetry {
        bv_id: "bv1".into(),
        seq: 5,
        stamp_ms: 1_700_000_000_000,
        prior_id: 7,
        px_m: -120.5,
        py_m: 33.0,
        theta_rad: 1.2,
        speed_mps: 9.5,
        plan_status: 0,
        predicted_pet_s: Some(2.2),
        below_reach: 0,
        pet_bound_s: None,
        gate_state: 1,
        gate_reason: 0,
        vut_reaction: Some(link::VutReaction { reacts_p: 0.8, gap_s: 2.1, gap_sd_s: 0.4 }),
    };
    let heartbeat = link::Heartbeat { bv_id: "bv1".into(), seq: 6, stamp_ms: 1_700_000_000_000, healthy: true };
    let seed = campaign_seed()?;
    let learned = link::RunLearned {
        bv_id: "bv1".into(),
        prior_id: 7,
        stamp_ms: 1_700_000_000_000,
        aim: seed.aim,
        started_with_route: true,
        started_with_reaction: false,
        route: seed.route,
        reaction: seed.reaction,
    };
    Ok(vec![
        ("telemetry".into(), link::telemetry_frame(&telemetry)?),
        ("heartbeat".into(), link::heartbeat_frame(&heartbeat)?),
        ("run learned".into(), link::learned_frame(&learned)?),
    ])
}

/// A campaign upload as a test's memory makes one after a few runs: a learned route, a posterior
/// of the VUT's reaction, a reach verdict.
fn campaign_seed() -> anyhow::Result<link::CampaignUpload> {
    use v2t_game::reaction::{HYPOTHESES, ReactionPosterior};
    use v2t_game::regulator::{BelowReach, BelowReachCause};
    use v2t_game::route_speed::RouteSpeed;
    // Half on the VUT that does not react (the first hypothesis), half spread over the others.
    let probabilities = (0..HYPOTHESES).map(|i| if i == 0 { 0.5 } else { 0.5 / (HYPOTHESES - 1) as f64 }).collect();
    let learned = v2t_edge::campaign::Learned {
        known: Some(BelowReach { cause: BelowReachCause::Campaign, pet_bound_s: Some(2.3) }),
        route: Some(RouteSpeed {
            step_m: 2.0,
            speeds_mps: (0..40).map(|i| 8.0 - 0.1 * f64::from(i)).collect(),
            runs: 3,
        }),
        reaction: Some(ReactionPosterior { probabilities, informative_cycles: 250 }),
    };
    Ok(learned.upload(7, v2t_model::Target::new(2.0, v2t_model::Style::Rush)?))
}
