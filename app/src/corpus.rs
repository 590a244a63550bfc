//! `video2track corpus import|stats`: recordings of human driving (CommonRoad XML of both published
//! formats, INTERACTION/highD-style CSV) → the recorded corpus that `train` and `realism` read, with
//! every episode's source file and licence tag; and the counts of a corpus.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use v2t_diffusion::dedup::VehicleIndex;
use v2t_diffusion::import::{commonroad, csv};
use v2t_diffusion::lanes::LaneletNetwork;
use v2t_diffusion::mining::MiningOptions;
use v2t_diffusion::recorded::{self, ImportOptions, RecordedCorpus, RecordedStats};
use v2t_files::{out, outln};

use crate::Usage;

/// `corpus` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum CorpusCommand {
    /// Import recordings (files or directories of `.xml`/`.csv`): mine their interactions, turn
    /// the vehicles' tracks into controls and routes, write the corpus as JSON lines. Nothing is
    /// written unless every file imports.
    Import(ImportArgs),
    /// Counts of recorded corpora: tracks per dataset, episodes per interaction kind, PET histogram.
    Stats(StatsArgs),
    /// Human reference distributions per manoeuvre class (straight through, left turn, lane
    /// change) from recorded corpora: the file the realism of a run is measured against.
    Reference(ReferenceArgs),
}

/// `corpus reference`'s arguments.
#[derive(Debug, clap::Args)]
pub struct ReferenceArgs {
    /// Recorded corpus files (every episode at one sampling period).
    #[arg(required = true)]
    corpora: Vec<PathBuf>,
    /// Recordings (files or directories, as `import` reads them) whose vehicles turning left by at
    /// least 60° make the left-turn class, each vehicle once across the files (matched as
    /// `import --dedup` matches them), whether or not an interaction was mined around it (a CSV
    /// file without `timestamp_ms` is read at 10 Hz). Without it the left-turn class is the actors
    /// of the corpora's mined left turns.
    #[arg(long = "left-turns", num_args = 1.., requires_all = ["left_turns_dataset", "left_turns_licence"])]
    left_turns: Vec<PathBuf>,
    /// What the `--left-turns` recordings are.
    #[arg(long)]
    left_turns_dataset: Option<String>,
    /// Their licence tag.
    #[arg(long)]
    left_turns_licence: Option<String>,
    /// Position noise of the `--left-turns` recordings for the smoother, m (as `import`'s).
    #[arg(long, default_value_t = 0.1)]
    position_noise: f64,
    /// Output file (JSON).
    #[arg(long, short)]
    out: PathBuf,
}

/// `corpus import`'s arguments.
#[derive(Debug, clap::Args)]
pub struct ImportArgs {
    /// Recording files (CommonRoad `.xml`, or `.csv` as `import::csv` reads them) or directories
    /// searched for them (sorted by name).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// What the recordings are (e.g. "NGSIM US-101"): one name for all inputs.
    #[arg(long)]
    dataset: String,
    /// The data's licence tag, kept with every episode (e.g. "NGSIM: US DOT public data;
    /// CommonRoad conversion BSD-3-Clause").
    #[arg(long)]
    licence: String,
    /// Position noise of the recordings for the smoother, m.
    #[arg(long, default_value_t = 0.1)]
    position_noise: f64,
    /// Frame rate of CSV files without a `timestamp_ms` column, Hz (INTERACTION 10, highD 25).
    #[arg(long, default_value_t = 10.0)]
    csv_frame_rate: f64,
    /// Resample tracks to this period before inverse kinematics, s (e.g. 0.1 for 0.2 s
    /// recordings such as MONA or inD: the model works at 0.1 s; Catmull–Rom between samples).
    #[arg(long)]
    resample: Option<f64>,
    /// Count each vehicle once across the files: a track whose vehicle an earlier file (in name
    /// order) already held is counted as a duplicate, and an interaction between two vehicles an
    /// earlier file already gave is dropped (CommonRoad cuts one recording into overlapping
    /// scenarios, each shifted and renumbered: vehicles are matched on footprint and speeds,
    /// `v2t_diffusion::dedup`). The tracks stay in every file's mining: a duplicate vehicle is
    /// still the other vehicle of a new one's interaction.
    #[arg(long)]
    dedup: bool,
    /// Output corpus (JSON lines).
    #[arg(long, short)]
    out: PathBuf,
}

/// `corpus stats`'s arguments.
#[derive(Debug, clap::Args)]
pub struct StatsArgs {
    /// Recorded corpus files.
    #[arg(required = true)]
    corpora: Vec<PathBuf>,
    /// Write the counts as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// Runs a `corpus` subcommand.
pub fn run(command: CorpusCommand) -> anyhow::Result<()> {
    match command {
        CorpusCommand::Import(a) => import(a),
        CorpusCommand::Stats(a) => stats(a),
        CorpusCommand::Reference(a) => reference(a),
    }
}

/// The human reference of recorded corpora: the actor of a left turn is a left turn (or, with
/// `--left-turns`, every vehicle of those recordings that turns left by at least 60°), the actor of
/// a cut-in or lane change a lane change unless it turns into the lane, the other vehicle of any
/// interaction straight through when its path is straight
/// ([`v2t_model::realism::ManoeuvreClass::of_states`]); each vehicle once per class (across the
/// cuts of one `import --dedup` by its vehicle number).
fn reference(a: ReferenceArgs) -> anyhow::Result<()> {
    use v2t_diffusion::mining::InteractionKind as K;
    use v2t_model::realism::{
        HumanReference, LANE_CHANGE_MAX_TURN_RAD, ManoeuvreClass, heading_change_rad, motion_samples,
    };
    let mut vehicles = Vec::new();
    let mut seen = std::collections::HashSet::new();
    let mut sources: Vec<String> = Vec::new();
    let mut dt: Option<f64> = None;
    for (n, path) in a.corpora.iter().enumerate() {
        let c = recorded::read_file(path).map_err(|e| crate::named(path, e))?;
        for s in &c.sources {
            let tag = format!("{} [{}]", s.dataset, s.licence);
            if !sources.contains(&tag) {
                sources.push(tag);
            }
        }
        for e in &c.episodes {
            match dt {
                None => dt = Some(e.dt_s),
                Some(d) if (d - e.dt_s).abs() > 1e-9 => {
                    return Err(Usage(format!(
                        "{}: episode {} is sampled at {} s, the others at {d} s: import with --resample to one period",
                        path.display(),
                        e.id,
                        e.dt_s
                    ))
                    .into());
                }
                Some(_) => {}
            }
            for (k, agent) in e.agents.iter().enumerate() {
                let class = match (k, e.mined.kind) {
                    (0, K::LeftTurn) if a.left_turns.is_empty() => ManoeuvreClass::LeftTurn,
                    (0, K::LeftTurn) => continue,
                    // A vehicle that turns into the other's lane is no lane change (Lankershim's
                    // junctions give such "cut-ins").
                    (0, K::CutIn | K::LaneChange)
                        if heading_change_rad(&agent.states).abs() < LANE_CHANGE_MAX_TURN_RAD =>
                    {
                        ManoeuvreClass::LaneChange
                    }
                    (1, _) if ManoeuvreClass::of_states(&agent.states) == ManoeuvreClass::Straight => {
                        ManoeuvreClass::Straight
                    }
                    _ => continue,
                };
                // One vehicle once per class: across the cuts of one `import --dedup` by its
                // number, else by recording and id.
                let who = match agent.vehicle {
                    Some(v) => (format!("corpus {n}"), format!("vehicle {v}")),
                    None => (e.recording.clone(), agent.id.clone()),
                };
                if seen.insert((who, class)) {
                    let (acc, jerk, yaw) = motion_samples(&agent.states, e.dt_s);
                    vehicles.push((class, acc, jerk, yaw));
                }
            }
        }
    }
    let Some(dt) = dt else { return Err(Usage("no episode in the corpora".into()).into()) };
    let mut left = String::new();
    if !a.left_turns.is_empty() {
        let (turners, files) = left_turners(&a, dt)?;
        let dataset = a.left_turns_dataset.as_deref().unwrap_or_default();
        let licence = a.left_turns_licence.as_deref().unwrap_or_default();
        let n = turners.len();
        left = if sources == [format!("{dataset} [{licence}]")] {
            format!("; left turns: the {n} vehicles of its {files} recordings turning left by at least 60°, each once")
        } else {
            format!(
                "; left turns: the {n} vehicles turning left by at least 60° in {files} recordings of {dataset} [{licence}], each once"
            )
        };
        vehicles.extend(turners.into_iter().map(|(acc, jerk, yaw)| (ManoeuvreClass::LeftTurn, acc, jerk, yaw)));
    }
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let provenance = format!("recorded human driving: {}{left}; made by `{command}`", sources.join(", "));
    let r = HumanReference::from_vehicles(provenance, dt, &vehicles);
    r.validate().map_err(|e| Usage(format!("the reference: {e}")))?;
    for c in &r.classes {
        outln!("{:?}: {} vehicles, {} samples", c.class, c.vehicles, c.samples)?;
    }
    crate::write_json(&a.out, &r)
}

/// Acceleration, jerk and yaw-rate samples of one vehicle.
type Motion = (Vec<f64>, Vec<f64>, Vec<f64>);

/// The motion of every vehicle turning left in `corpus reference --left-turns`' recordings, each
/// vehicle once across the files (the first file in name order that holds its turn), and how many
/// files were read. Every recording must be sampled at `dt_s`.
fn left_turners(a: &ReferenceArgs, dt_s: f64) -> anyhow::Result<(Vec<Motion>, usize)> {
    if !(a.position_noise.is_finite() && (0.0..=2.0).contains(&a.position_noise)) {
        return Err(Usage(format!("--position-noise {}: must lie in [0, 2] m", a.position_noise)).into());
    }
    for (field, value) in
        [("--left-turns-dataset", &a.left_turns_dataset), ("--left-turns-licence", &a.left_turns_licence)]
    {
        if value.as_deref().is_none_or(|v| v.trim().is_empty()) {
            return Err(Usage(format!("{field} is empty: say what the recordings are and under which licence")).into());
        }
    }
    let options = v2t_diffusion::inverse::InverseOptions { position_noise_m: a.position_noise, ..Default::default() };
    let files = recording_files(&a.left_turns)?;
    let mut index = VehicleIndex::new();
    let mut counted: HashSet<usize> = HashSet::new();
    let mut out = Vec::new();
    for file in &files {
        let (episode, _, _) = read_recording(file, 10.0)?;
        if (episode.dt_s - dt_s).abs() > 1e-9 {
            return Err(Usage(format!(
                "{}: sampled at {} s, the corpora at {dt_s} s: the reference needs one period",
                file.display(),
                episode.dt_s
            ))
            .into());
        }
        let ids = index.identify(&episode.tracks);
        for (track, id) in episode.tracks.iter().zip(&ids) {
            if counted.contains(&id.vehicle) {
                continue;
            }
            if let Some(states) = recorded::left_turn_states(track, &options) {
                counted.insert(id.vehicle);
                out.push(v2t_model::realism::motion_samples(&states, dt_s));
            }
        }
    }
    Ok((out, files.len()))
}

/// The recording files under `inputs`, in the order given (directories sorted by name).
fn recording_files(inputs: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let mut found = Vec::new();
            let mut stack = vec![input.clone()];
            while let Some(dir) = stack.pop() {
                let entries = std::fs::read_dir(&dir).map_err(|e| Usage(format!("{}: {e}", dir.display())))?;
                for entry in entries {
                    let path = entry.map_err(|e| Usage(format!("{}: {e}", dir.display())))?.path();
                    if path.is_dir() {
                        stack.push(path);
                    } else if matches!(path.extension().and_then(|e| e.to_str()), Some("xml" | "csv")) {
                        found.push(path);
                    }
                }
            }
            found.sort();
            if found.is_empty() {
                return Err(Usage(format!("{}: no .xml or .csv file in it", input.display())).into());
            }
            out.extend(found);
        } else if input.is_file() {
            out.push(input.clone());
        } else {
            return Err(Usage(format!("{}: no such file or directory", input.display())).into());
        }
    }
    Ok(out)
}

fn import(a: ImportArgs) -> anyhow::Result<()> {
    if !(a.position_noise.is_finite() && (0.0..=2.0).contains(&a.position_noise)) {
        return Err(Usage(format!("--position-noise {}: must lie in [0, 2] m", a.position_noise)).into());
    }
    if !(a.csv_frame_rate.is_finite() && (1.0..=100.0).contains(&a.csv_frame_rate)) {
        return Err(Usage(format!("--csv-frame-rate {}: must lie in [1, 100] Hz", a.csv_frame_rate)).into());
    }
    if let Some(dt) = a.resample
        && !(dt.is_finite() && (0.01..=1.0).contains(&dt))
    {
        return Err(Usage(format!("--resample {dt}: must lie in [0.01, 1] s")).into());
    }
    for (field, value) in [("--dataset", &a.dataset), ("--licence", &a.licence)] {
        if value.trim().is_empty() {
            return Err(Usage(format!("{field} is empty: say what the data is and under which licence")).into());
        }
    }
    let options = ImportOptions {
        dataset: a.dataset.clone(),
        licence: a.licence.clone(),
        mining: MiningOptions { position_noise_m: a.position_noise, ..MiningOptions::default() },
        inverse: v2t_diffusion::inverse::InverseOptions { position_noise_m: a.position_noise, ..Default::default() },
        resample_s: a.resample,
    };
    let files = recording_files(&a.inputs)?;
    let mut corpus = RecordedCorpus::default();
    let mut index = VehicleIndex::new();
    let mut pairs: HashSet<(usize, usize)> = HashSet::new();
    let mut turned_left: HashSet<usize> = HashSet::new();
    for file in &files {
        let (episode, lanes, format) = read_recording(file, a.csv_frame_rate)?;
        let (mut source, mut episodes) =
            recorded::import_scenario(&episode, &lanes, &file.display().to_string(), &format, &options);
        if a.dedup {
            let ids = index.identify(&episode.tracks);
            let vehicle_of: HashMap<&str, usize> =
                episode.tracks.iter().zip(&ids).map(|(t, i)| (t.id.as_str(), i.vehicle)).collect();
            source.duplicate_vehicles =
                episode.tracks.iter().zip(&ids).filter(|(t, i)| t.kind.is_vehicle() && i.seen_before).count();
            source.left_turning_vehicles = episode
                .tracks
                .iter()
                .zip(&ids)
                .filter(|(t, i)| recorded::turns_left(t) && turned_left.insert(i.vehicle))
                .count();
            let before = episodes.len();
            episodes.retain(|e| {
                let mut v: Vec<Option<usize>> =
                    e.agents.iter().map(|g| vehicle_of.get(g.id.as_str()).copied()).collect();
                v.sort_unstable();
                match v[..] {
                    [Some(a), Some(b)] => pairs.insert((a, b)),
                    _ => true,
                }
            });
            source.duplicate_episodes = before - episodes.len();
            for agent in episodes.iter_mut().flat_map(|e| e.agents.iter_mut()) {
                agent.vehicle = vehicle_of.get(agent.id.as_str()).copied();
            }
            source.kept = episodes.len();
        }
        eprintln!(
            "{}: {} tracks ({} vehicles already in an earlier file), {} interactions mined, {} kept ({} without a lane, {} without controls, {} not an interaction on the lanes, {} already in an earlier file)",
            file.display(),
            source.tracks,
            source.duplicate_vehicles,
            source.mined,
            source.kept,
            source.no_route,
            source.no_controls,
            source.not_interaction,
            source.duplicate_episodes
        );
        corpus.sources.push(source);
        corpus.episodes.extend(episodes);
    }
    recorded::write_file(&corpus, &a.out)?;
    let s = corpus.stats();
    outln!(
        "imported {} files: {} tracks ({} vehicles, {} of them already in an earlier file), {} interaction episodes; wrote {}",
        files.len(),
        s.tracks,
        s.vehicles,
        s.duplicate_vehicles,
        s.episodes,
        a.out.display()
    )?;
    Ok(())
}

/// A recording's tracks, lane network (empty for CSV: its vehicles' routes are then their driven
/// paths) and format name.
fn read_recording(
    file: &Path,
    csv_frame_rate_hz: f64,
) -> anyhow::Result<(v2t_diffusion::tracks::Episode, LaneletNetwork, String)> {
    match file.extension().and_then(|e| e.to_str()) {
        Some("xml") => {
            let s = commonroad::parse_scenario_file(file).map_err(|e| Usage(format!("{}: {e}", file.display())))?;
            let version = if s.version.is_empty() { "unversioned".to_owned() } else { s.version.clone() };
            if s.lanes.is_empty() {
                return Err(Usage(format!(
                    "{}: no lanelet: the routes of its vehicles cannot be found (CommonRoad files carry their lanes)",
                    file.display()
                ))
                .into());
            }
            Ok((s.episode, s.lanes, format!("CommonRoad {version}")))
        }
        Some("csv") => {
            let text = v2t_files::bounds::read_text_within(file, v2t_files::bounds::DRIVING_DATA)
                .map_err(|e| Usage(format!("{}: {e}", file.display())))?;
            let stem = file.file_stem().map_or_else(|| "csv".to_owned(), |s| s.to_string_lossy().into_owned());
            let options = csv::CsvOptions { frame_rate_hz: Some(csv_frame_rate_hz) };
            let parsed = csv::parse(&text, &stem, &options).map_err(|e| Usage(format!("{}: {e}", file.display())))?;
            let bound = commonroad::MAX_COORDINATE_M;
            for t in &parsed.episode.tracks {
                if let Some(s) = t.samples.iter().find(|s| s.x_m.abs() > bound || s.y_m.abs() > bound) {
                    return Err(Usage(format!(
                        "{}: track {} at {} s: position ({:e}, {:e}) outside ±{bound:e} m",
                        file.display(),
                        t.id,
                        s.t_s,
                        s.x_m,
                        s.y_m
                    ))
                    .into());
                }
            }
            Ok((parsed.episode, LaneletNetwork::default(), "CSV".to_owned()))
        }
        _ => Err(Usage(format!("{}: not a .xml (CommonRoad) or .csv recording", file.display())).into()),
    }
}

fn stats(a: StatsArgs) -> anyhow::Result<()> {
    let mut all = RecordedCorpus::default();
    for path in &a.corpora {
        let c = recorded::read_file(path).map_err(|e| crate::named(path, e))?;
        all.sources.extend(c.sources);
        all.episodes.extend(c.episodes);
    }
    let s = all.stats();
    out!("{}", stats_table(&s))?;
    if let Some(path) = a.json {
        crate::write_json(&path, &s)?;
    }
    Ok(())
}

/// The counts as markdown.
fn stats_table(s: &RecordedStats) -> String {
    let mut out = String::from(
        "| dataset | licence | files | tracks | vehicles | of them seen before | vehicles turning left | period | cut-in | lane change | left turn | crossing | merge | dropped | dropped as seen before |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for d in &s.datasets {
        let periods: Vec<String> = d.periods_s.iter().map(|p| format!("{p} s")).collect();
        let kinds: Vec<String> = d.kinds.iter().map(|(_, n)| n.to_string()).collect();
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            d.dataset,
            d.licences.join("; "),
            d.files,
            d.tracks,
            d.vehicles,
            d.duplicate_vehicles,
            d.left_turning_vehicles,
            periods.join(", "),
            kinds.join(" | "),
            d.dropped,
            d.duplicate_episodes
        ));
    }
    out.push_str(&format!(
        "\ntotal: {} tracks ({} vehicles, {} distinct), {} interaction episodes\n\nPET of the episodes (s):\n\n| dataset |",
        s.tracks,
        s.vehicles,
        s.vehicles - s.duplicate_vehicles,
        s.episodes
    ));
    let Some(first) = s.datasets.first() else { return out };
    let bins = first.pet.counts.len();
    let width = (first.pet.hi - first.pet.lo) / bins.max(1) as f64;
    for k in 0..bins {
        out.push_str(&format!(
            " {:.1}–{:.1} |",
            first.pet.lo + width * k as f64,
            first.pet.lo + width * (k + 1) as f64
        ));
    }
    out.push_str(" < 0 | ≥ 6 |\n|---|");
    out.push_str(&"---|".repeat(bins + 2));
    out.push('\n');
    for d in &s.datasets {
        out.push_str(&format!("| {} |", d.dataset));
        for c in &d.pet.counts {
            out.push_str(&format!(" {c} |"));
        }
        out.push_str(&format!(" {} | {} |\n", d.pet.underflow, d.pet.overflow));
    }
    out
}
