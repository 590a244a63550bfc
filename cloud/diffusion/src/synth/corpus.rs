//! Generating synthetic episodes and corpora.

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use serde::{Deserialize, Serialize};
use v2t_map::Map;
use v2t_map::library::{Fragment, TopologyLibrary};
use v2t_model::grounded::AgentRole;
use v2t_model::kinematics::{Control, State};
use v2t_model::metrics::Dimensions;
use v2t_model::prior::AgentTrajectory;

use super::driver::{DriverParams, uniform};
use super::scene;
use super::sim::simulate;
use crate::mining::{Interaction, InteractionKind, MiningOptions, pair};
use crate::stats::{ControlHistograms, ControlSamples, Histogram};
use crate::tracks::{AgentKind, Episode, Track, TrackSample};

/// Time step of the synthetic corpus, s.
pub const DT_S: f64 = 0.1;
/// Longest episode, steps (20 s).
const MAX_STEPS: usize = 200;
/// Shortest episode kept, steps (5 s).
const MIN_STEPS: usize = 50;
/// Draws per episode before giving up.
const MAX_TRIES: u32 = 60;

/// What can keep a corpus from being generated.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SynthError {
    /// The map has no fragment with a scene the generator knows.
    #[error("map `{0}` has no intersection left turn, multi-lane segment or merge to simulate on")]
    NoFragments(String),
    /// Every draw for one episode was rejected.
    #[error("episode {index} ({kind:?}): all {tries} draws rejected (no interaction or a collision)")]
    TooManyRejections {
        /// Episode index.
        index: u64,
        /// Scene kind.
        kind: InteractionKind,
        /// Draws made.
        tries: u32,
    },
}

/// One simulated agent of a synthetic episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SyntheticAgent {
    /// Role in the scene: `turner`/`crossing` (`crossing_2` behind), `cutter`/`follower` (`lead`
    /// ahead in the target lane), `merging`/`through` (`through_2` behind). The first is the
    /// actor of the scene's interaction.
    pub id: String,
    /// Maneuver of the topology library it drove.
    pub route_id: String,
    /// Footprint.
    pub dims: Dimensions,
    /// Its sampled driver.
    pub driver: DriverParams,
    /// States at `k · dt`, one more than controls.
    pub states: Vec<State>,
    /// Controls as applied by the simulation.
    pub controls: Vec<Control>,
}

/// One synthetic episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SyntheticEpisode {
    /// `synthetic-<seed>-<index>`.
    pub id: String,
    /// Corpus seed.
    pub seed: u64,
    /// Index in the corpus; with the seed it reproduces the episode alone.
    pub index: u64,
    /// Fragment of the topology library.
    pub fragment_id: String,
    /// The scene simulated.
    pub interaction: InteractionKind,
    /// The interaction as measured on the simulated tracks.
    pub mined: Interaction,
    /// Time step, s.
    pub dt_s: f64,
    /// The agents.
    pub agents: Vec<SyntheticAgent>,
}

impl SyntheticEpisode {
    /// The measured PET, s.
    pub fn pet_s(&self) -> f64 {
        self.mined.pet_s
    }

    /// The agents as trajectories of `v2t-model` (role BV: no VUT in human driving).
    pub fn trajectories(&self) -> Vec<AgentTrajectory> {
        self.agents
            .iter()
            .map(|a| AgentTrajectory {
                id: a.id.clone(),
                role: AgentRole::Bv,
                states: a.states.clone(),
                controls: a.controls.clone(),
            })
            .collect()
    }

    /// The agents as tracks (velocity along the heading), for mining and statistics.
    pub fn to_episode(&self) -> Episode {
        let tracks = self
            .agents
            .iter()
            .map(|a| Track {
                id: a.id.clone(),
                dt_s: self.dt_s,
                kind: AgentKind::Car,
                dims: Some(a.dims),
                samples: a
                    .states
                    .iter()
                    .enumerate()
                    .map(|(k, x)| TrackSample {
                        t_s: k as f64 * self.dt_s,
                        x_m: x.px,
                        y_m: x.py,
                        vx_mps: Some(x.speed_mps * x.theta_rad.cos()),
                        vy_mps: Some(x.speed_mps * x.theta_rad.sin()),
                        psi_rad: Some(x.theta_rad),
                    })
                    .collect(),
            })
            .collect();
        Episode::from_tracks(self.id.clone(), tracks)
    }
}

/// Draws rejected while generating, by reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rejections {
    /// The scene could not be set up on the fragment drawn.
    pub scene: u64,
    /// Shorter than 5 s.
    pub short: u64,
    /// Two footprints overlapped, or both vehicles were in the conflict zone at once (PET < 0).
    pub collision: u64,
    /// The intended interaction did not happen (or its PET exceeded the mining limit).
    pub no_interaction: u64,
}

impl Rejections {
    fn add(&mut self, o: Self) {
        self.scene += o.scene;
        self.short += o.short;
        self.collision += o.collision;
        self.no_interaction += o.no_interaction;
    }

    /// All rejected draws.
    pub fn total(&self) -> u64 {
        self.scene + self.short + self.collision + self.no_interaction
    }
}

/// A synthetic corpus.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticCorpus {
    /// Map name.
    pub map: String,
    /// Corpus seed.
    pub seed: u64,
    /// The episodes, by index.
    pub episodes: Vec<SyntheticEpisode>,
    /// Draws rejected on the way.
    pub rejections: Rejections,
}

/// What a synthetic corpus holds, for realism reports: episodes per scene kind, the PET
/// histogram and the control histograms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CorpusSummary {
    /// Episodes.
    pub episodes: usize,
    /// Episodes per (scene kind, mined kind).
    pub by_kind: Vec<(InteractionKind, InteractionKind, usize)>,
    /// Measured PET, 0–6 s in 0.25 s bins.
    pub pet_s: Histogram,
    /// Acceleration, jerk and yaw rate of every agent.
    pub controls: ControlHistograms,
}

impl SyntheticCorpus {
    /// Counts and histograms of the corpus.
    pub fn summary(&self) -> CorpusSummary {
        let mut by_kind: Vec<(InteractionKind, InteractionKind, usize)> = Vec::new();
        let mut pet = Histogram { lo: 0.0, hi: 6.0, counts: vec![0; 24], underflow: 0, overflow: 0, non_finite: 0 };
        for e in &self.episodes {
            pet.add(e.pet_s());
            match by_kind.iter_mut().find(|(k, m, _)| *k == e.interaction && *m == e.mined.kind) {
                Some(entry) => entry.2 += 1,
                None => by_kind.push((e.interaction, e.mined.kind, 1)),
            }
        }
        CorpusSummary {
            episodes: self.episodes.len(),
            by_kind,
            pet_s: pet,
            controls: self.control_samples().histograms(),
        }
    }

    /// Acceleration, jerk and yaw-rate samples of every agent, for realism statistics.
    pub fn control_samples(&self) -> ControlSamples {
        let mut out = ControlSamples::default();
        for e in &self.episodes {
            for a in &e.agents {
                out.add_sequence(&a.controls, e.dt_s);
            }
        }
        out
    }
}

/// Fragments offering each scene kind, in a fixed order.
fn candidates(lib: &TopologyLibrary) -> Vec<(InteractionKind, Vec<&Fragment>)> {
    let mut out: Vec<(InteractionKind, Vec<&Fragment>)> = Vec::new();
    for kind in [InteractionKind::LeftTurn, InteractionKind::CutIn, InteractionKind::Merge] {
        let frags: Vec<&Fragment> = lib.fragments.iter().filter(|f| scene::kinds_of(f).contains(&kind)).collect();
        if !frags.is_empty() {
            out.push((kind, frags));
        }
    }
    out
}

fn accepts(kind: InteractionKind, mined: InteractionKind) -> bool {
    match kind {
        InteractionKind::LeftTurn => mined == InteractionKind::LeftTurn,
        InteractionKind::CutIn => mined == InteractionKind::CutIn,
        _ => matches!(mined, InteractionKind::Merge | InteractionKind::CutIn | InteractionKind::LaneChange),
    }
}

/// Episode `index` of the corpus with `seed` on `lib`, and the draws rejected for it.
pub fn generate_episode(
    lib: &TopologyLibrary,
    seed: u64,
    index: u64,
) -> Result<(SyntheticEpisode, Rejections), SynthError> {
    let cands = candidates(lib);
    let n_kinds = cands.len().max(1) as u64;
    let Some((kind, frags)) = cands.get((index % n_kinds) as usize) else {
        return Err(SynthError::NoFragments(lib.map.clone()));
    };
    let kind = *kind;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    let mut rejected = Rejections::default();
    let opts = MiningOptions::default();
    for _ in 0..MAX_TRIES {
        let k = (uniform(&mut rng, 0.0, frags.len() as f64).floor() as usize).min(frags.len().saturating_sub(1));
        let Some(fragment) = frags.get(k) else { break };
        let setup = match kind {
            InteractionKind::LeftTurn => scene::left_turn(fragment, &mut rng),
            InteractionKind::CutIn => scene::cut_in(fragment, &mut rng),
            _ => scene::merge(fragment, &mut rng),
        };
        let Some(setup) = setup else {
            rejected.scene += 1;
            continue;
        };
        let out = simulate(&setup, DT_S, MAX_STEPS, &mut rng);
        if out.controls.iter().map(Vec::len).min().unwrap_or(0) < MIN_STEPS {
            rejected.short += 1;
            continue;
        }
        if out.collided {
            rejected.collision += 1;
            continue;
        }
        let agents: Vec<SyntheticAgent> = setup
            .iter()
            .zip(out.states.into_iter().zip(out.controls))
            .map(|(a, (states, controls))| SyntheticAgent {
                id: a.name.to_owned(),
                route_id: a.route_id.clone(),
                dims: a.dims,
                driver: a.driver,
                states,
                controls,
            })
            .collect();
        let mut episode = SyntheticEpisode {
            id: format!("synthetic-{seed}-{index}"),
            seed,
            index,
            fragment_id: fragment.id.clone(),
            interaction: kind,
            mined: Interaction {
                kind,
                actor: String::new(),
                other: String::new(),
                first: String::new(),
                conflict_point: Default::default(),
                conflict_time_s: 0.0,
                pet_s: 0.0,
            },
            dt_s: DT_S,
            agents,
        };
        // The interaction of the scene is the actor's (its first agent) most critical one: the
        // smallest PET with any other agent among the kinds the scene stands for.
        let tracks = episode.to_episode().tracks;
        let actor = setup.first().map_or("", |a| a.name);
        let found = tracks
            .iter()
            .find(|t| t.id == actor)
            .map(|a| {
                tracks
                    .iter()
                    .filter(|b| b.id != actor)
                    .flat_map(|b| pair(a, b, &opts))
                    .filter(|x| accepts(kind, x.kind) && (x.actor == actor || kind == InteractionKind::LeftTurn))
                    .min_by(|x, y| x.pet_s.total_cmp(&y.pet_s))
            })
            .unwrap_or_default();
        let Some(mined) = found else {
            rejected.no_interaction += 1;
            continue;
        };
        if mined.pet_s < 0.0 {
            rejected.collision += 1;
            continue;
        }
        episode.mined = mined;
        return Ok((episode, rejected));
    }
    Err(SynthError::TooManyRejections { index, kind, tries: MAX_TRIES })
}

/// `n` synthetic episodes on the topology library of `map`, deterministic from `seed`.
pub fn generate_corpus(map: &Map, n: usize, seed: u64) -> Result<SyntheticCorpus, SynthError> {
    let lib = TopologyLibrary::build(map);
    if candidates(&lib).is_empty() {
        return Err(SynthError::NoFragments(lib.map.clone()));
    }
    let mut episodes = Vec::with_capacity(n);
    let mut rejections = Rejections::default();
    for index in 0..n as u64 {
        let (e, r) = generate_episode(&lib, seed, index)?;
        rejections.add(r);
        episodes.push(e);
    }
    Ok(SyntheticCorpus { map: lib.map.clone(), seed, episodes, rejections })
}
