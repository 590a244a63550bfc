//! The VUT a lab run faces, and the world it lives in: one of this project's driver models in the
//! builtin simulated proving ground, or one of SUMO's drivers (a file under `config/vut/sumo/`) in
//! the SUMO co-simulation ([`crate::sumo`]). Every experiment and report names both, so a figure
//! measured against a driver this project wrote is never mistaken for one measured against a
//! driver it did not.

use std::fmt;
use std::str::FromStr;

use v2t_sim::bv::BvController;
use v2t_sim::runner::{RunError, RunOutcome, run};
use v2t_sim::scenario::Scenario;
use v2t_sim::vut::VutModel;

use crate::sumo::{SumoDriver, SumoWorld};

/// Which world drives the VUT.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum World {
    /// The simulated proving ground with this project's VUT driver models.
    #[default]
    Builtin,
    /// SUMO drives the VUT on the network converted from the same map; the BVs are ours.
    Sumo,
}

impl World {
    /// The name on the command line and in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Builtin => "builtin",
            Self::Sumo => "sumo",
        }
    }

    /// Where a run took place, in a run's one-line report.
    pub fn place(self) -> &'static str {
        match self {
            Self::Builtin => "simulated proving ground",
            Self::Sumo => "simulated proving ground, VUT driven by SUMO",
        }
    }

    /// One line on where the figures come from.
    pub fn provenance(self) -> &'static str {
        match self {
            Self::Builtin => "simulated proving ground; VUT driver models written by this project",
            Self::Sumo => {
                "SUMO co-simulation: the VUT driven by Eclipse SUMO's driver models (not written by this \
                 project) on the proving ground's network; the BVs, sensing and measurement are the simulated \
                 proving ground's"
            }
        }
    }
}

impl fmt::Display for World {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for World {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "builtin" => Ok(Self::Builtin),
            "sumo" => Ok(Self::Sumo),
            _ => Err(format!("unknown world `{s}`; one of: builtin, sumo")),
        }
    }
}

/// The VUT of a run.
#[derive(Debug, Clone, Copy)]
pub enum Vut<'a> {
    /// A builtin driver model.
    Builtin(VutModel),
    /// A SUMO driver in a running SUMO world.
    Sumo {
        /// The world (SUMO processes, the converted network).
        world: &'a SumoWorld,
        /// The driver.
        driver: &'a SumoDriver,
    },
}

impl Vut<'_> {
    /// The driver's name (`idm-normal`, `sumo-krauss`, …).
    pub fn name(&self) -> String {
        match self {
            Self::Builtin(m) => m.to_string(),
            Self::Sumo { driver, .. } => driver.name.clone(),
        }
    }

    /// Its world.
    pub fn world(&self) -> World {
        match self {
            Self::Builtin(_) => World::Builtin,
            Self::Sumo { .. } => World::Sumo,
        }
    }

    /// One run of `scenario` against this VUT, deterministic for a `seed` (SUMO's drivers draw
    /// their imperfection from the same seed).
    pub fn run(
        &self,
        scenario: &Scenario,
        bvs: &mut [Box<dyn BvController>],
        seed: u64,
    ) -> Result<RunOutcome, RunError> {
        match self {
            Self::Builtin(m) => run(scenario, bvs, m.driver().as_mut(), seed),
            Self::Sumo { world, driver } => world.run(driver, scenario, bvs, seed),
        }
    }
}
