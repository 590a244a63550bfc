//! The **synthetic** human-driving corpus: episodes simulated on the fragments of a map's topology
//! library with heterogeneous driver models, for training the diffusion prior before (and beside)
//! real data. Every name here says *synthetic*: these are not recordings.
//!
//! For each episode a scene kind is chosen in turn among those the map offers — unprotected
//! **left turns** at intersections, **cut-ins** on multi-lane segments, **merges** at on-ramps and
//! lane drops — then a fragment, two drivers ([`DriverParams::sample`]: IDM `v0, T, a, b, s0`,
//! critical gap, reaction delay, actuation lag, curve lateral acceleration, minimum-jerk lane-change
//! duration, process noise) and a start that brings both to the conflict within a few seconds of
//! each other; half the time a third vehicle joins (a second crossing or through vehicle behind
//! the first, or a lead in the cut-in's target lane). The simulation runs the kinematic model of
//! `v2t-model` at 0.1 s; its applied controls are stored with its states. The interaction is then measured by [`crate::mining`]
//! (PET, who went first, conflict point; the actor's most critical one); episodes without the
//! intended interaction, with a collision or with a negative PET are drawn again. Everything
//! follows from the corpus seed and the episode index.
//!
//! ```
//! let map = v2t_map::Map::load(std::path::Path::new(concat!(
//!     env!("CARGO_MANIFEST_DIR"),
//!     "/../../config/maps/proving_ground.xodr"
//! )))
//! .unwrap();
//! let corpus = v2t_diffusion::synth::generate_corpus(&map, 3, 1).unwrap();
//! assert_eq!(corpus.episodes.len(), 3);
//! let text = v2t_diffusion::synth::to_jsonl(&corpus).unwrap();
//! assert_eq!(v2t_diffusion::synth::from_jsonl(&text).unwrap(), corpus);
//! ```

mod corpus;
pub mod driver;
mod format;
mod scene;
mod sim;

pub use corpus::{
    CorpusSummary, DT_S, Rejections, SynthError, SyntheticAgent, SyntheticCorpus, SyntheticEpisode, generate_corpus,
    generate_episode,
};
pub use driver::DriverParams;
pub use format::{CorpusHeader, CorpusIoError, FORMAT, VERSION, from_jsonl, read_jsonl_file, to_jsonl};
