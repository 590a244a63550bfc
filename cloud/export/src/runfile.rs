//! The part of a run file (`video2track sim --json`, `v2t-sim-ecu --out`) that `render` and
//! `export xosc` read. Other fields are ignored: this reads a subset of a document another command
//! writes, not a configuration.

use serde::Deserialize;
use v2t_model::Style;
use v2t_model::kinematics::State;

/// A run as written.
#[derive(Debug, Deserialize)]
pub(crate) struct RunFile {
    pub(crate) result: RunFileResult,
    pub(crate) agent_ids: Vec<String>,
    pub(crate) trace: Vec<RunFileSample>,
}

/// Its measured result, as far as it is read (`render` needs only the name).
#[derive(Debug, Deserialize)]
pub(crate) struct RunFileResult {
    pub(crate) scenario: String,
    #[serde(default)]
    pub(crate) tau_s: Option<f64>,
    #[serde(default)]
    pub(crate) style: Option<Style>,
}

/// One 10 Hz sample.
#[derive(Debug, Deserialize)]
pub(crate) struct RunFileSample {
    pub(crate) t_s: f64,
    pub(crate) agents: Vec<RunFileAgent>,
}

/// One vehicle in a sample.
#[derive(Debug, Deserialize)]
pub(crate) struct RunFileAgent {
    pub(crate) state: State,
}
