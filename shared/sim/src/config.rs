//! Simulation settings and scenario cards, as written in TOML under `config/sim/` and
//! `config/scenarios/` (read with `v2t-files`, which names the file, line and field of every error).

use serde::{Deserialize, Serialize};
use v2t_model::path::PathSpec;
use v2t_model::validate::plausible::MAX_SCENARIO_TIME_S;
use v2t_model::validate::{Validate, ValidationError, in_range, positive};
use v2t_model::{Style, Target};

/// Global settings of the simulated proving ground.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimSettings {
    /// Integration step of the vehicle plants, s.
    pub plant_dt_s: f64,
    /// Period at which controllers (BV and VUT) run, s; a multiple of `plant_dt_s`.
    pub control_period_s: f64,
    /// Period of the recorded trace, s; a multiple of `plant_dt_s`.
    pub record_period_s: f64,
    /// Whether localization noise is applied.
    pub noise_enabled: bool,
    /// Extra age of the VUT state when it reaches a BV (V2X or cloud relay), s.
    pub v2x_delay_s: f64,
    /// Extra age of BV states when the VUT perceives them (sensing pipeline), s.
    pub perception_delay_s: f64,
}

impl SimSettings {
    /// Plant steps per control period.
    pub fn control_every(&self) -> usize {
        ((self.control_period_s / self.plant_dt_s).round() as usize).max(1)
    }

    /// Plant steps per recorded sample.
    pub fn record_every(&self) -> usize {
        ((self.record_period_s / self.plant_dt_s).round() as usize).max(1)
    }
}

fn multiple_of(field: &str, value: f64, base: f64) -> Result<(), ValidationError> {
    let k = (value / base).round();
    if k >= 1.0 && (value - k * base).abs() < 1e-9 {
        Ok(())
    } else {
        Err(ValidationError::new(field, format!("must be a whole multiple of plant_dt_s = {base}, got {value}")))
    }
}

impl Validate for SimSettings {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("plant_dt_s", self.plant_dt_s, 1e-4, 0.1)?;
        in_range("control_period_s", self.control_period_s, 1e-3, 1.0)?;
        multiple_of("control_period_s", self.control_period_s, self.plant_dt_s)?;
        in_range("record_period_s", self.record_period_s, 1e-3, 1.0)?;
        multiple_of("record_period_s", self.record_period_s, self.plant_dt_s)?;
        in_range("v2x_delay_s", self.v2x_delay_s, 0.0, 2.0)?;
        in_range("perception_delay_s", self.perception_delay_s, 0.0, 2.0)
    }
}

/// A scenario card: the geometry, vehicles and references of one test scenario. Its file is
/// `ScenarioCardFile`'s layout: the target as the two keys `tau_s` and `style`, range-checked as
/// the file is read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "ScenarioCardFile", into = "ScenarioCardFile")]
pub struct ScenarioCard {
    /// Short name.
    pub name: String,
    /// What the scenario is, for the report.
    pub description: String,
    /// Settings file, relative to the card.
    pub sim: String,
    /// Simulated duration, s.
    pub duration_s: f64,
    /// Target PET τ (for the regulator and for reporting) and intended passing order.
    pub target: Target,
    /// The vehicle under test.
    pub vut: VutCard,
    /// One or two background vehicles.
    pub bvs: Vec<BvCard>,
}

/// The file form of a [`ScenarioCard`]: its fields in the same order, the target written as
/// `tau_s` (s) and `style`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScenarioCardFile {
    name: String,
    description: String,
    sim: String,
    duration_s: f64,
    tau_s: f64,
    style: Style,
    vut: VutCard,
    bvs: Vec<BvCard>,
}

impl TryFrom<ScenarioCardFile> for ScenarioCard {
    type Error = ValidationError;

    fn try_from(f: ScenarioCardFile) -> Result<Self, Self::Error> {
        Ok(Self {
            name: f.name,
            description: f.description,
            sim: f.sim,
            duration_s: f.duration_s,
            target: Target::from_keys(f.tau_s, f.style)?,
            vut: f.vut,
            bvs: f.bvs,
        })
    }
}

impl From<ScenarioCard> for ScenarioCardFile {
    fn from(c: ScenarioCard) -> Self {
        Self {
            name: c.name,
            description: c.description,
            sim: c.sim,
            duration_s: c.duration_s,
            tau_s: c.target.tau_s(),
            style: c.target.style(),
            vut: c.vut,
            bvs: c.bvs,
        }
    }
}

/// The VUT of a card.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VutCard {
    /// Vehicle file, relative to the card.
    pub vehicle: String,
    /// Driver model used unless the command line says otherwise (see [`crate::vut::VutModel`]).
    pub model: String,
    /// Route.
    pub path: PathSpec,
    /// Speed at the start, m/s.
    pub initial_speed_mps: f64,
    /// Speed the driver wants to keep, m/s.
    pub desired_speed_mps: f64,
}

/// A BV of a card.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BvCard {
    /// Unique id (`bv1`, `bv2`).
    pub id: String,
    /// Vehicle file, relative to the card.
    pub vehicle: String,
    /// Reference path.
    pub path: PathSpec,
    /// Speed at the start, m/s.
    pub initial_speed_mps: f64,
    /// Reference speed over time: `[t_s, speed_mps]` points, linear in between, held after the last.
    pub speed_profile: Vec<[f64; 2]>,
    /// Where the path enters the junction of its conflict, m along it, read off the map (a test
    /// holds each shipped card to its map): a BV that gives way stops before it. Absent: no
    /// junction, or a card on no map.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub junction_entry_m: Option<f64>,
}

/// Most points of a BV's speed profile.
pub const MAX_PROFILE_POINTS: usize = 10_000;

impl Validate for VutCard {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.vehicle.trim().is_empty() {
            return Err(ValidationError::new("vehicle", "must name a vehicle file"));
        }
        if self.model.parse::<crate::vut::VutModel>().is_err() {
            return Err(ValidationError::new(
                "model",
                format!("unknown VUT model `{}`; one of: {}", self.model, crate::vut::VutModel::names().join(", ")),
            ));
        }
        self.path.validate().map_err(|e| e.within("path"))?;
        in_range("initial_speed_mps", self.initial_speed_mps, 0.0, 70.0)?;
        in_range("desired_speed_mps", self.desired_speed_mps, 0.5, 70.0)
    }
}

impl Validate for BvCard {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.id.trim().is_empty() {
            return Err(ValidationError::new("id", "must not be empty"));
        }
        if self.vehicle.trim().is_empty() {
            return Err(ValidationError::new("vehicle", "must name a vehicle file"));
        }
        self.path.validate().map_err(|e| e.within("path"))?;
        in_range("initial_speed_mps", self.initial_speed_mps, 0.0, 70.0)?;
        if self.speed_profile.is_empty() {
            return Err(ValidationError::new("speed_profile", "needs at least one [t_s, speed_mps] point"));
        }
        if self.speed_profile.len() > MAX_PROFILE_POINTS {
            return Err(ValidationError::new(
                "speed_profile",
                format!("has {} points, at most {MAX_PROFILE_POINTS} are accepted", self.speed_profile.len()),
            ));
        }
        let mut last_t = f64::NEG_INFINITY;
        for (i, [t, v]) in self.speed_profile.iter().enumerate() {
            in_range(&format!("speed_profile[{i}][0]"), *t, 0.0, MAX_SCENARIO_TIME_S)?;
            in_range(&format!("speed_profile[{i}][1]"), *v, 0.0, 70.0)?;
            if *t <= last_t {
                return Err(ValidationError::new(format!("speed_profile[{i}][0]"), "times must increase"));
            }
            last_t = *t;
        }
        if let Some(entry) = self.junction_entry_m {
            in_range("junction_entry_m", entry, 0.0, v2t_model::path::MAX_COORDINATE_M)?;
        }
        Ok(())
    }
}

impl Validate for ScenarioCard {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.name.trim().is_empty() {
            return Err(ValidationError::new("name", "must not be empty"));
        }
        positive("duration_s", self.duration_s)?;
        in_range("duration_s", self.duration_s, 0.1, 600.0)?;
        self.vut.validate().map_err(|e| e.within("vut"))?;
        if !(1..=2).contains(&self.bvs.len()) {
            return Err(ValidationError::new("bvs", format!("needs 1 or 2 BVs, got {}", self.bvs.len())));
        }
        self.bvs.validate().map_err(|e| e.within("bvs"))?;
        for (i, b) in self.bvs.iter().enumerate() {
            if b.id == "vut" || self.bvs.iter().skip(i + 1).any(|o| o.id == b.id) {
                return Err(ValidationError::new(format!("bvs[{i}].id"), format!("`{}` is not unique", b.id)));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2t_files::{ConfigError, parse_toml};

    const SETTINGS: &str = r#"
plant_dt_s = 0.01
control_period_s = 0.1
record_period_s = 0.1
noise_enabled = true
v2x_delay_s = 0.1
perception_delay_s = 0.1
"#;

    #[test]
    fn settings_parse_and_derive_their_step_counts() {
        let s: SimSettings = parse_toml(SETTINGS, "default.toml").unwrap();
        assert_eq!(s.control_every(), 10);
        assert_eq!(s.record_every(), 10);
    }

    #[test]
    fn errors_name_the_file_the_field_and_the_problem() {
        let unknown = parse_toml::<SimSettings>(&format!("{SETTINGS}\ncolour = 3\n"), "a.toml").unwrap_err();
        let text = unknown.to_string();
        assert!(text.starts_with("a.toml: ") && text.contains("colour"), "{text}");

        let nan = parse_toml::<SimSettings>(&SETTINGS.replace("plant_dt_s = 0.01", "plant_dt_s = nan"), "b.toml");
        let err = nan.unwrap_err();
        assert!(matches!(&err, ConfigError::Invalid { source, .. } if source.field == "plant_dt_s"), "{err}");

        let odd = parse_toml::<SimSettings>(
            &SETTINGS.replace("control_period_s = 0.1", "control_period_s = 0.015"),
            "c.toml",
        );
        assert!(odd.unwrap_err().to_string().contains("control_period_s"));

        let broken = parse_toml::<SimSettings>("plant_dt_s = [", "d.toml").unwrap_err();
        assert!(matches!(broken, ConfigError::Parse { .. }));
    }

    #[test]
    fn every_shipped_card_loads_and_its_file_keeps_tau_and_style_as_two_keys() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/scenarios");
        let mut cards = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_none_or(|e| e != "toml") {
                continue;
            }
            let text = std::fs::read_to_string(&path).unwrap();
            let card: ScenarioCard = parse_toml(&text, "card.toml").unwrap();
            let key = |k: &str| text.lines().find_map(|l| l.strip_prefix(&format!("{k} = "))).unwrap().to_owned();
            assert_eq!(card.target.tau_s(), key("tau_s").parse::<f64>().unwrap(), "{}", path.display());
            assert_eq!(format!("\"{}\"", card.target.style()), key("style"), "{}", path.display());
            // Written back: the same two keys in the same place, and read back the same card.
            let toml = toml::to_string(&card).unwrap();
            let (tau, style) = (card.target.tau_s(), card.target.style());
            let expected = format!("duration_s = {:?}\ntau_s = {tau:?}\nstyle = \"{style}\"\n", card.duration_s);
            assert!(toml.contains(&expected), "{toml}");
            assert_eq!(parse_toml::<ScenarioCard>(&toml, "again.toml").unwrap(), card);
            let json = serde_json::to_string(&card).unwrap();
            let expected = format!(r#","duration_s":{:?},"tau_s":{tau:?},"style":"{style}","vut":{{"#, card.duration_s);
            assert!(json.contains(&expected), "{json}");
            assert_eq!(serde_json::to_string(&serde_json::from_str::<ScenarioCard>(&json).unwrap()).unwrap(), json);
            cards += 1;
        }
        assert!(cards >= 3, "{cards} cards in {}", dir.display());
    }

    #[test]
    fn a_card_with_tau_out_of_range_is_refused_naming_tau_s_and_the_range() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/scenarios/left_turn_basic.toml");
        let text = std::fs::read_to_string(path).unwrap();
        for bad in ["tau_s = 0.05", "tau_s = 31.0", "tau_s = nan"] {
            let e = parse_toml::<ScenarioCard>(&text.replace("tau_s = 2.0", bad), "card.toml").unwrap_err().to_string();
            assert!(e.starts_with("card.toml: ") && e.contains("`tau_s`") && e.contains("[0.1, 30]"), "{bad}: {e}");
        }
        let e = parse_toml::<ScenarioCard>(&text.replace("style = \"rush\"", "style = \"fast\""), "card.toml");
        let e = e.unwrap_err().to_string();
        assert!(e.contains("style") && e.contains("fast"), "{e}");
    }
}
