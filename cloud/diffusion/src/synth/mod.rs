//! The **synthetic** human-driving corpus: episodes simulated on the fragments of a map's topology
//! library with heterogeneous driver models, for training the diffusion prior before (and beside)
//! real data. Every name here says *synthetic*: these are not recordings.
//!
//! For each episode a scene kind is chosen in turn among those the map offers — unprotected
//! **left turns** at intersections, **cut-ins** on multi-lane segments, **merges** at on-ramps and
//! lane drops — then a fragment, two drivers ([`DriverParams::sample`]: IDM `v0, T, a, b, s0`,
//! critical gap, reaction delay, actuation lag, curve lateral acceleration, minimum-jerk lane-change
//! duration, process noise) and a start that brings both to the conflict within a few seconds of
//! each other. The simulation runs the kinematic model of `v2t-model` at 0.1 s; its applied
//! controls are stored with its states. The interaction is then measured by [`crate::mining`]
//! (PET, who went first, conflict point); episodes without the intended interaction or with a
//! collision are drawn again. Everything follows from the corpus seed and the episode index.

mod corpus;
pub mod driver;
mod format;
mod scene;
mod sim;

pub use corpus::{
    DT_S, Rejections, SynthError, SyntheticAgent, SyntheticCorpus, SyntheticEpisode, generate_corpus, generate_episode,
};
pub use driver::DriverParams;
pub use format::{CorpusHeader, CorpusIoError, FORMAT, VERSION, from_jsonl, read_jsonl_file, to_jsonl};
