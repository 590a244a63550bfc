//! `--world builtin|sumo` and `--sumo-driver`: which simulator drives the VUT (`sim`, `experiment
//! steerability`).

use std::path::{Path, PathBuf};

use v2t_files::shipped;
use v2t_lab::sumo::{DEFAULT_DRIVER, DRIVERS_DIR, SumoDriver, SumoWorld};
use v2t_lab::vut::World;

use crate::Usage;

/// The options that choose the VUT's world.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct WorldArgs {
    /// Which world drives the VUT: `builtin` (this project's driver models) or `sumo` (Eclipse
    /// SUMO's drivers on the network converted from the same map; needs SUMO: scripts/install-sumo).
    #[arg(long, default_value = "builtin", value_parser = clap::builder::PossibleValuesParser::new(["builtin", "sumo"]))]
    pub(crate) world: String,
    /// With --world sumo: SUMO driver files (default: `sim` config/vut/sumo/krauss.toml, SUMO's
    /// defaults; `experiment` every file in config/vut/sumo/; repeat the option for more).
    #[arg(long = "sumo-driver")]
    pub(crate) sumo_drivers: Vec<PathBuf>,
}

/// A started SUMO world and its drivers.
pub(crate) struct Sumo {
    pub(crate) world: SumoWorld,
    pub(crate) drivers: Vec<SumoDriver>,
}

impl WorldArgs {
    /// The world asked for.
    pub(crate) fn world(&self) -> anyhow::Result<World> {
        self.world.parse::<World>().map_err(|e| Usage(e).into())
    }

    /// With `--world sumo`: the drivers (validated first: bad input before SUMO starts) and the
    /// world on the shipped map; `None` for the builtin world. `--sumo-driver` without `--world
    /// sumo` is a usage error.
    pub(crate) fn sumo(&self, default_all: bool) -> anyhow::Result<Option<Sumo>> {
        if self.world()? != World::Sumo {
            if !self.sumo_drivers.is_empty() {
                return Err(Usage("--sumo-driver applies with --world sumo".to_owned()).into());
            }
            return Ok(None);
        }
        let drivers = if self.sumo_drivers.is_empty() && default_all {
            SumoDriver::load_dir(Path::new(DRIVERS_DIR))?
        } else if self.sumo_drivers.is_empty() {
            vec![SumoDriver::load(Path::new(DEFAULT_DRIVER))?]
        } else {
            self.sumo_drivers.iter().map(|p| SumoDriver::load(p)).collect::<Result<Vec<_>, _>>()?
        };
        if drivers.is_empty() {
            return Err(Usage(format!("no SUMO driver files (*.toml) in {DRIVERS_DIR}")).into());
        }
        let map = Path::new(shipped::MAP);
        if !map.is_file() {
            // netconvert would say only that it cannot read it, and exit 1.
            return Err(Usage(format!(
                "{}: not found in {}: the SUMO world converts the shipped map, which is found from the \
                 repository root; run there",
                map.display(),
                std::env::current_dir()
                    .map_or_else(|_| "the working directory".to_owned(), |d| d.display().to_string())
            ))
            .into());
        }
        let world = SumoWorld::new(map)?;
        Ok(Some(Sumo { world, drivers }))
    }
}
