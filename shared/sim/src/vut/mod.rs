//! VUT driver models: stand-ins for the ADS under test. Each is a different algorithm from the
//! game's follower model (a QP-MPC), so that the regulator is never tested against itself:
//!
//! - [`idm::IdmDriver`]: Intelligent Driver Model car following with gap acceptance at conflict
//!   zones, in cautious / normal / aggressive parameter sets;
//! - [`reactive::ReactiveDriver`]: a cruise driver that reacts to predicted conflicts after a
//!   perception-reaction delay;
//! - [`sampling::SamplingPlanner`]: a sampling-based speed planner that scores candidate
//!   acceleration profiles against constant-velocity predictions of the BVs.
//!
//! All follow their route laterally with pure pursuit. Their parameters come from
//! `config/vut/builtin/<name>.toml`, compiled in (a bad file fails the build).

mod builtin;
pub(crate) mod common;
pub mod idm;
pub mod reactive;
pub mod sampling;

use std::fmt;
use std::str::FromStr;

use crate::observation::VutObservation;
use crate::plant::ActuationRequest;

/// Decides the VUT's actuation every control period.
pub trait VutDriver {
    /// Short name for reports.
    fn name(&self) -> &str;
    /// The request for this control period.
    fn control(&mut self, obs: &VutObservation<'_>) -> ActuationRequest;
}

/// The VUT driver models, by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum VutModel {
    /// IDM with cautious gap acceptance.
    #[serde(rename = "idm-cautious")]
    IdmCautious,
    /// IDM with normal gap acceptance.
    #[serde(rename = "idm-normal")]
    IdmNormal,
    /// IDM with aggressive gap acceptance.
    #[serde(rename = "idm-aggressive")]
    IdmAggressive,
    /// Reactive driver with a perception-reaction delay.
    #[serde(rename = "reactive")]
    Reactive,
    /// Sampling-based speed planner.
    #[serde(rename = "sampling")]
    Sampling,
}

impl VutModel {
    /// Every model.
    pub const ALL: [Self; 5] =
        [Self::IdmCautious, Self::IdmNormal, Self::IdmAggressive, Self::Reactive, Self::Sampling];

    /// The model's name as written in cards and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::IdmCautious => "idm-cautious",
            Self::IdmNormal => "idm-normal",
            Self::IdmAggressive => "idm-aggressive",
            Self::Reactive => "reactive",
            Self::Sampling => "sampling",
        }
    }

    /// One line on the model and its parameters (from its file, `config/vut/builtin/<name>.toml`).
    pub fn description(self) -> &'static str {
        match self {
            Self::IdmCautious => builtin::IDM_CAUTIOUS_DESCRIPTION,
            Self::IdmNormal => builtin::IDM_NORMAL_DESCRIPTION,
            Self::IdmAggressive => builtin::IDM_AGGRESSIVE_DESCRIPTION,
            Self::Reactive => builtin::REACTIVE_DESCRIPTION,
            Self::Sampling => builtin::SAMPLING_DESCRIPTION,
        }
    }

    /// Every model's name.
    pub fn names() -> Vec<&'static str> {
        Self::ALL.iter().map(|m| m.as_str()).collect()
    }

    /// A fresh driver of this model.
    pub fn driver(self) -> Box<dyn VutDriver> {
        match self {
            Self::IdmCautious => Box::new(idm::IdmDriver::new(idm::IdmParams::cautious())),
            Self::IdmNormal => Box::new(idm::IdmDriver::new(idm::IdmParams::normal())),
            Self::IdmAggressive => Box::new(idm::IdmDriver::new(idm::IdmParams::aggressive())),
            Self::Reactive => Box::new(reactive::ReactiveDriver::new(reactive::ReactiveParams::default())),
            Self::Sampling => Box::new(sampling::SamplingPlanner::new(sampling::SamplingParams::default())),
        }
    }
}

impl fmt::Display for VutModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for VutModel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|m| m.as_str() == s)
            .ok_or_else(|| format!("unknown VUT model `{s}`; one of: {}", Self::names().join(", ")))
    }
}
